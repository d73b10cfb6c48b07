"""Config validation against a JSON Schema that supplies the defaults; one error translator.

Every rig's configuration section is a JSON Schema (draft 2020-12) with a ``default`` on every
key, so a file holding only ``rig: NAME`` is a complete config. :func:`validate` fills the
defaults while it validates and turns the first schema error into an
:class:`~platcal.errors.InputError` naming the field (``schemes.table1.positions[2]``) and
the allowed keys where a key is unknown. Non-finite numbers (``.nan``, ``.inf``) are refused
everywhere: no rig has a use for them.
"""

from __future__ import annotations

import copy
import math
from functools import lru_cache
from importlib import resources

import jsonschema

from .errors import InputError
from .io import read_yaml


def _with_defaults(validator_class):
    """A validator that fills in ``default`` values while it validates (jsonschema FAQ recipe)."""
    validate_props = validator_class.VALIDATORS["properties"]

    def set_defaults(validator, properties, instance, sch):
        if isinstance(instance, dict):
            for prop, sub in properties.items():
                if "default" in sub and prop not in instance:
                    instance[prop] = copy.deepcopy(sub["default"])
        yield from validate_props(validator, properties, instance, sch)

    return jsonschema.validators.extend(validator_class, {"properties": set_defaults})


DefaultsValidator = _with_defaults(jsonschema.Draft202012Validator)
"""Draft 2020-12 validator that fills ``default`` values into the instance."""


def field_name(path, prefix: str = "") -> str:
    """A readable field path: ``schemes.table1.positions[2]`` (positions count from 1)."""
    parts = [prefix] if prefix else []
    for p in path:
        if isinstance(p, int):
            parts.append(f"[{p + 1}]" if parts and parts[-1].endswith("positions") else f"[{p}]")
        else:
            parts.append(("." if parts else "") + str(p))
    return "".join(parts) or "(top level)"


@lru_cache(maxsize=None)
def _parsed_schema(package: str, resource: str) -> dict:
    """The parse of a package's schema file, once per process: the pure-Python YAML parser takes
    ~25 ms for a rig's 15 kB schema, and a study's config check validates once per cell.
    Never handed out: :func:`load_schema` gives each caller its own copy."""
    return read_yaml(resources.files(package).joinpath(resource).read_text(encoding="utf-8"))


def load_schema(package: str, resource: str) -> dict:
    """A YAML schema shipped as package data (``load_schema('platcal', 'data/config.schema.yaml')``),
    read through the project's one YAML reader (:func:`platcal.io.read_yaml`) and parsed once per
    process. Each call returns a fresh deep copy (well under 1 ms), because callers extend the
    schema in place (:func:`platcal.mapping.with_mapping_schema` adds the ``record`` keys) and a
    shared parse would carry one caller's edits into the next."""
    return copy.deepcopy(_parsed_schema(package, resource))


def check_finite(obj, prefix: str = "") -> None:
    """Refuse NaN and infinity anywhere in a parsed config, naming the field."""
    if isinstance(obj, float) and not math.isfinite(obj):
        raise InputError(prefix or "(top level)", f"must be a finite number, got {obj!r}")
    if isinstance(obj, dict):
        for k, v in obj.items():
            check_finite(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            check_finite(v, f"{prefix}[{i}]")


def validate(raw, sch: dict, prefix: str = "") -> dict:
    """Validate ``raw`` against ``sch``; return a deep copy with every default filled in.

    Raises InputError naming the first bad field (``prefix`` is put in front of its path).
    """
    if not isinstance(raw, dict):
        raise InputError(prefix or "(top level)", "must be a YAML mapping")
    check_finite(raw, prefix)
    cfg = copy.deepcopy(raw)
    errors = sorted(DefaultsValidator(sch).iter_errors(cfg), key=lambda e: list(e.absolute_path))
    if errors:
        e = errors[0]
        where = field_name(e.absolute_path, prefix)
        if e.validator == "additionalProperties":
            allowed = sorted(e.schema.get("properties", {}))
            raise InputError(where, f"{e.message}; allowed keys: {allowed}")
        raise InputError(where, e.message)
    return cfg
