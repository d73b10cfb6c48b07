"""The campaign file (docs: issue 23; schema ``study/data/campaign.schema.yaml``): read, validated
and typed, each rig's config read in. Apart from the planner (:mod:`platcal.study.campaign`) so
that the workflow's start validates a campaign without importing the optimiser and the plotting
(about 1.5 s of every ``snakemake`` start)."""

from __future__ import annotations

import copy
import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..io import read_config
from ..model.platform import PlatformModel, default_platform
from ..rig import Rig, get_rig, rig_config
from ..schema import load_schema, validate

SCHEMA = ("platcal.study", "data/campaign.schema.yaml")


# ------------------------------------------------------------------ the campaign file

@dataclass(frozen=True)
class RigOffer:
    """A rig of the campaign: its registry entry, typed config, costs and scheme space."""

    name: str
    rig: Rig
    cfg: object
    cost_per_hour: float
    setup_hours: float
    hours_per_test: float
    hours_per_position: float
    schemes: tuple[str, ...]
    dwells: tuple[float, ...]
    max_repeats: int


@dataclass(frozen=True)
class Campaign:
    """A validated campaign: platform (truth), prior and target sigma per coefficient (units of
    ``platform.units``), the rigs offered, reference plans, optimiser and Monte Carlo settings."""

    name: str
    platform: PlatformModel
    prior_sigma: np.ndarray
    target_sigma: np.ndarray
    rigs: tuple[RigOffer, ...]
    references: dict
    optimiser: dict
    montecarlo: dict
    raw: dict

    def truth(self) -> dict[str, float]:
        return dict(zip(self.platform.names, map(float, self.platform.truth)))

    def offer(self, name: str) -> RigOffer:
        return next(r for r in self.rigs if r.name == name)


def term_of(name: str) -> str:
    """A coefficient's term: ``DF_x`` -> ``DF``, ``theta_py`` -> ``theta``."""
    return name.rsplit("_", 1)[0]


def coefficient_rule(platform: PlatformModel, rules: Mapping[str, float], field: str) -> np.ndarray:
    """One value per coefficient from rules keyed by name, term or group (the most specific wins).

    InputError naming ``field`` for a key that is none of these or a coefficient left uncovered.
    """
    known = set(platform.names) | {term_of(n) for n in platform.names} | set(platform.groups)
    for key in rules:
        if key not in known:
            raise InputError(f"{field}.{key}", f"not a coefficient, term or group of the platform; use one of "
                             f"{sorted(known)}")
    out, missing = np.empty(len(platform.names)), []
    for i, (n, g) in enumerate(zip(platform.names, platform.groups)):
        v = rules.get(n, rules.get(term_of(n), rules.get(g)))
        if v is None:
            missing.append(n)
        else:
            out[i] = float(v)
    if missing:
        raise InputError(field, f"no value for {missing}; give each a value by name, term (e.g. "
                         f"{term_of(missing[0])}) or group (e.g. {platform.groups[platform.index(missing[0])]})")
    return out


def _offer(name: str, entry: dict) -> RigOffer:
    rig = get_rig(name)
    field = f"rigs.{name}"
    if rig.campaign is None:
        raise InputError(field, f"rig {name!r} has no campaign hooks (its tests tell nothing about the platform's "
                         "coefficient names); remove it from the campaign")
    cfg = rig.load_config(rig_config({"rigs": {name: entry["config"]}}, name))
    known = rig.campaign.schemes(cfg)
    for i, s in enumerate(entry["schemes"]):
        if s not in known:
            raise InputError(f"{field}.schemes[{i}]", f"unknown scheme {s!r} of rig {name!r}; use one of {known}")
    return RigOffer(name=name, rig=rig, cfg=cfg, cost_per_hour=float(entry["cost_per_hour"]),
                    setup_hours=float(entry["setup_hours"]), hours_per_test=float(entry["hours_per_test"]),
                    hours_per_position=float(entry["hours_per_position"]), schemes=tuple(entry["schemes"]),
                    dwells=tuple(float(d) for d in entry["dwell_s"]), max_repeats=int(entry["max_repeats"]))


def load_campaign(source) -> Campaign:
    """Validate a campaign (a file path or a raw mapping); InputError naming the field otherwise."""
    raw = read_config(source, "--campaign") if isinstance(source, (str, os.PathLike)) else source
    cfg = validate(raw, load_schema(*SCHEMA))
    base = default_platform()
    truth = base.truth.copy()
    for k, v in cfg["platform"]["truth"].items():
        if k not in base.names:
            raise InputError(f"platform.truth.{k}", f"unknown coefficient; use one of {list(base.names)}")
        truth[base.index(k)] = float(v)
    platform = PlatformModel(base.names, base.units, base.groups, truth)
    rigs = tuple(_offer(n, e) for n, e in cfg["rigs"].items())
    names = {r.name for r in rigs}
    for ref, tests in cfg["references"].items():
        for i, t in enumerate(tests):
            where = f"references.{ref}[{i}]"
            if t["rig"] not in names:
                raise InputError(f"{where}.rig", f"rig {t['rig']!r} is not in the campaign's rigs {sorted(names)}")
            known = next(r for r in rigs if r.name == t["rig"])
            if t["scheme"] not in known.rig.campaign.schemes(known.cfg):
                raise InputError(f"{where}.scheme", f"unknown scheme {t['scheme']!r} of rig {t['rig']!r}")
    return Campaign(name=cfg["name"], platform=platform,
                    prior_sigma=coefficient_rule(platform, cfg["platform"]["prior_sigma"], "platform.prior_sigma"),
                    target_sigma=coefficient_rule(platform, cfg["targets"], "targets"), rigs=rigs,
                    references=cfg["references"], optimiser=cfg["optimiser"], montecarlo=cfg["montecarlo"], raw=cfg)


def campaign_content(source) -> dict:
    """The campaign (a file path or a mapping) with each rig's config read in (a path becomes
    the mapping): everything its numbers depend on, as a workflow rule's param."""
    raw = read_config(source, "--campaign") if isinstance(source, (str, os.PathLike)) else copy.deepcopy(source)
    for name, entry in (raw.get("rigs") or {}).items() if isinstance(raw, dict) else ():
        if isinstance(entry, dict) and "config" in entry:
            entry["config"] = rig_config({"rigs": {name: entry["config"]}}, name)
    return raw
