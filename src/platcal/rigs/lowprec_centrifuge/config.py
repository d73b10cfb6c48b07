"""Configuration of the low-precision centrifuge rig (docs/lowprec-centrifuge.md §10).

:func:`load_config` validates a raw mapping against ``data/config.schema.yaml`` (which fills every
default) and returns a :class:`Study`. Cross-field checks the schema cannot express raise an
:class:`~platcal.errors.InputError` naming the field: every platform has runs, the traditional
levels rise (the level-to-level ramp climbs at +J), the true arm stays positive, and every level
is reachable by the jerk-limited spin-up within :data:`MAX_SPINUP_S`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from ...errors import InputError
from ...mapping_keys import with_mapping_schema
from ...schema import load_schema, validate

G0 = 9.80665
"""Standard gravity and the unit g, m/s^2 (§1)."""
OMEGA_IE = 7.292115e-5
"""Earth rate, rad/s (§1)."""
R_EARTH = 6378137.0
"""Single Earth radius R = R_M = R_N, m (§1)."""
MAX_SPINUP_S = 1800.0
"""[D] Longest spin-up (A_L / J) accepted: a level the jerk limit cannot reach within 30 min is refused."""
COEFFS = ("kA_x", "k2_x", "kA_y", "k2_y")
"""The identified coefficients (ug/g, ug/g^2, ug/g, ug/g^2), in the order of states 8-11 (§7)."""


@dataclass(frozen=True)
class Centrifuge:
    """Nominal arm (m) and imprecision (§2)."""

    arm_m: float = 3.0
    rate_error: float = 3.0e-4
    arm_error_mm: float = 2.0
    stretch_mm_per_g: float = 0.02
    jerk_g_s: float = 0.25
    alpha_max_rad_s2: float = 0.3

    def with_imprecision(self, rate_error=None, arm_error_mm=None, stretch_mm_per_g=None) -> "Centrifuge":
        """A copy with other imprecision values (the sweep of §2); None keeps a value."""
        kw = {k: v for k, v in (("rate_error", rate_error), ("arm_error_mm", arm_error_mm),
                                ("stretch_mm_per_g", stretch_mm_per_g)) if v is not None}
        return dataclasses.replace(self, **kw)


@dataclass(frozen=True)
class Study:
    """A validated configuration; ``raw`` keeps the defaults-filled mapping."""

    raw: dict
    latitude_deg: float
    centrifuge: Centrifuge
    platforms: dict          # name -> {kA_x, k2_x, kA_y, k2_y}
    runs: dict               # platform -> {run name -> [A1, A2]}
    profile: dict
    traditional: dict
    residuals: dict
    study: dict
    seed: int

    @property
    def rate_hz(self) -> float:
        return float(self.profile["rate_hz"])

    def platform_names(self) -> list[str]:
        return list(self.platforms)

    def run_names(self, platform: str) -> list[str]:
        """Proposed runs of ``platform`` then ``traditional``."""
        return list(self.runs[platform]) + ["traditional"]

    def platform_index(self, platform: str) -> int:
        """1-based position of the platform in the config (the rng key of §9)."""
        return self.platform_names().index(platform) + 1

    def run_index(self, platform: str, run: str) -> int:
        """[D] rng key of a run (§9): proposed runs 1, 2, ... in config order; traditional 0."""
        return 0 if run == "traditional" else list(self.runs[platform]).index(run) + 1

    def with_centrifuge(self, cen: Centrifuge) -> "Study":
        return dataclasses.replace(self, centrifuge=cen)


def _check_level(field: str, level: float, cen: Centrifuge) -> None:
    t_up = level / cen.jerk_g_s
    if t_up > MAX_SPINUP_S:
        raise InputError(field, f"{level:g} g needs {t_up:.0f} s of spin-up at the jerk limit "
                                f"centrifuge.jerk_g_s = {cen.jerk_g_s:g} g/s, more than {MAX_SPINUP_S:.0f} s: "
                                "lower the level or raise the jerk limit")


def load_config(raw) -> Study:
    """Validate ``raw`` (a mapping; defaults filled from the schema) and return a :class:`Study`."""
    cfg = validate(raw, with_mapping_schema(load_schema("platcal.rigs.lowprec_centrifuge", "data/config.schema.yaml")))
    cen = Centrifuge(**cfg["centrifuge"])
    if cen.arm_m + cen.arm_error_mm * 1e-3 <= 0:
        raise InputError("centrifuge.arm_error_mm", "the true arm arm_m + arm_error_mm must be positive")
    for p in cfg["platforms"]:
        if p not in cfg["runs"]:
            raise InputError(f"runs.{p}", f"platform {p!r} has no runs; give e.g. {{run1: [13, 30]}}")
    for p in cfg["runs"]:
        if p not in cfg["platforms"]:
            raise InputError(f"runs.{p}", f"no platform {p!r} in platforms ({sorted(cfg['platforms'])})")
        for r, lv in cfg["runs"][p].items():
            for i, a in enumerate(lv):
                _check_level(f"runs.{p}.{r}[{i}]", a, cen)
    tl = cfg["traditional"]["levels_g"]
    for i, a in enumerate(tl):
        _check_level(f"traditional.levels_g[{i}]", a, cen)
    if not tl[1] > tl[0]:
        raise InputError("traditional.levels_g[1]", "the second level must be above the first: the "
                                                    "level-to-level ramp climbs at the jerk limit")
    for k in ("worst", "gross"):
        arm = cfg["study"][k].get("arm_error_mm", 0.0)
        if cen.arm_m - abs(arm) * 1e-3 <= 0:
            raise InputError(f"study.{k}.arm_error_mm", "the true arm must stay positive")
    if not math.isfinite(cfg["site"]["latitude_deg"]):
        raise InputError("site.latitude_deg", "must be finite")
    return Study(raw=cfg, latitude_deg=float(cfg["site"]["latitude_deg"]), centrifuge=cen,
                 platforms={k: dict(v) for k, v in cfg["platforms"].items()},
                 runs={k: {r: list(map(float, lv)) for r, lv in v.items()} for k, v in cfg["runs"].items()},
                 profile=dict(cfg["profile"]), traditional=dict(cfg["traditional"]),
                 residuals=dict(cfg["residuals"]), study=dict(cfg["study"]), seed=int(cfg["seed"]))
