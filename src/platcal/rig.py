"""The ``Rig`` interface and the registry: what a test rig offers the rest of platcal.

A rig is one subpackage ``platcal.rigs.<name>`` whose ``__init__`` defines ``RIG``, an instance
of :class:`Rig`. ``rig: <name>`` in a config selects it (``centrifuge`` when the key is absent).
Nothing outside ``platcal/rigs/`` names a rig: the CLI, the study layer and the workflow look a
rig up here and call what it provides.

Where do I add a rig?
---------------------
1. ``src/platcal/rigs/<name>/``: its config schema (``data/config.schema.yaml``, a default for
   every key), model, simulator, estimators, record columns and tables; ``__init__.py`` defines
   ``RIG = Rig(...)`` below.
2. Its name in :data:`RIG_MODULES`.
3. ``docs/<spec>.md`` (its spec), ``config/<name>.yaml``, ``tests/<name>/``,
   ``benchmarks/bench_<name>.py``, ``workflow/rules/<name>.smk`` (its study; results under
   ``results/<name>/``, ending in ``results/<name>/report.md``), and its entry in the
   ``rigs:`` list of ``config/config.yaml``.

What a rig must provide (the fields of :class:`Rig`)
----------------------------------------------------
- ``name``, ``spec`` (the spec file under ``docs/``), ``title`` (one line for people).
- ``load_config(raw) -> cfg``: validate a raw mapping (``platcal.schema.validate`` against the
  rig's schema) and return the rig's typed study object; bad input raises
  :class:`~platcal.errors.InputError` naming the field.
- ``commands``: ``{"simulate": fn, "identify": fn, ...}``, each ``fn(cfg, args) -> int`` for
  the ``platcal`` sub-command of that name; ``args`` is the parsed :mod:`argparse` namespace of
  :func:`platcal.cli.build_parser` (a superset of every rig's options). A rig checks only the
  options it uses and refuses, with an InputError naming the option, one it requires and did
  not get (``--scheme``) or one it has no use for. Sub-commands a rig lacks are refused by the
  CLI with the list of those it has.
- ``catalogue() -> DataFrame``: the identified quantities, one row per name with ``name``,
  ``group`` (e.g. gyro / accel / attitude), ``unit`` and ``truth`` (default truth; NaN where
  there is none); the study layer's tables and figures group and label by these columns.
- ``estimators``: names accepted by ``--estimator`` and ``study.estimators``.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import pandas as pd

from .errors import InputError

DEFAULT_RIG = "centrifuge"
RIG_MODULES = ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")
"""Rig subpackages under ``platcal.rigs`` (import name = value of ``rig:``)."""

Command = Callable[[object, argparse.Namespace], int]


@dataclass(frozen=True)
class Rig:
    """A test rig as the CLI, the study layer and the workflow see it (see the module docstring)."""

    name: str
    title: str
    spec: str
    load_config: Callable[[dict], object]
    commands: Mapping[str, Command]
    catalogue: Callable[[], pd.DataFrame]
    estimators: tuple[str, ...] = ()
    extras: Mapping[str, object] = field(default_factory=dict)
    """Optional capabilities by name (e.g. ``information`` for covariance-only analysis)."""


def rig_names() -> tuple[str, ...]:
    return RIG_MODULES


def get_rig(name: str) -> Rig:
    """The registered rig ``name``; InputError (field ``rig``) naming the known rigs otherwise."""
    if name not in RIG_MODULES:
        raise InputError("rig", f"unknown rig {name!r}; use one of {list(RIG_MODULES)}")
    return importlib.import_module(f"platcal.rigs.{name}").RIG


def rig_of(raw) -> Rig:
    """The rig a raw config mapping selects (``rig:``; :data:`DEFAULT_RIG` when absent)."""
    if not isinstance(raw, dict):
        raise InputError("(top level)", "a configuration is a YAML mapping")
    name = raw.get("rig", DEFAULT_RIG)
    if not isinstance(name, str):
        raise InputError("rig", f"must be a rig name, one of {list(RIG_MODULES)}")
    return get_rig(name)
