"""Config of the multi-position rig: schema defaults, named schemes and the gimbal range.

docs/multiposition-1g.md §10 (defaults), §11 (schemes), §3 (|beta| <= beta_max). The schema
``data/config.schema.yaml`` gives every key a default; :func:`load_config` validates a raw
mapping (InputError naming the field) and returns a :class:`Config`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ...errors import InputError
from ...mapping_keys import with_mapping_schema
from ...schema import load_schema, validate
from ...scheme import TABLE1_POSITIONS, Scheme
from .estimators import check_estimator, choice_from_filter
from .model import Site, coef_names, p0_vector, truth_vector

ROLL = lambda step: tuple((float(a), 0.0, 0.0) for a in range(0, 360, step))  # noqa: E731

NAMED_POSITIONS = {
    "S8": ((0, 0, 0), (180, 0, 0), (90, 0, 0), (270, 0, 0), (90, 0, 90), (270, 0, 90), (45, 0, 45),
           (135, 0, 300)),
    "SIX": ((0, 0, 0), (180, 0, 0), (90, 0, 0), (270, 0, 0), (90, 0, 90), (270, 0, 90)),
    "T1": TABLE1_POSITIONS,
    "TET4": ((0, 0, 0), (109.47, 0, 0), (109.47, 0, 120), (109.47, 0, 240)),
    "BETA4": ((0, 0, 0), (100, 20, 0), (110, -25, 120), (120, 15, 240)),
    "ROLL4": ROLL(90),
    "ROLL8": ROLL(45),
    "AZ4": ((0, 0, 0), (0, 0, 90), (0, 0, 180), (0, 0, 270)),
    "CONE4": ((60, 0, 0), (60, 0, 90), (60, 0, 180), (60, 0, 270)),
    "PAIR4": ((60, 0, 30), (300, 0, 210), (120, 0, 100), (240, 0, 280)),
}
"""The named schemes of §11 (alpha, beta, gamma in deg), 60 s per position."""


@dataclass(frozen=True)
class Config:
    """A validated multiposition config (engineering units as named)."""

    raw: dict
    site: Site
    beta_max_deg: float
    beta_margin_deg: float
    ts: float
    n_sub: int
    sigma_a_ug: float
    sigma_an_arcsec: float
    arw_deg_rth: float
    sigma_set_arcsec: float
    truth_overrides: dict
    p0_terms: dict
    passes: int
    estimator: str
    rank_rtol: float
    lie_order: int
    cov_step_s: float
    max_rel_sigma_pct: float
    seed: int
    default_scheme: str
    schemes: dict = field(default_factory=dict)

    def truth(self, ext: int = 0) -> np.ndarray:
        return truth_vector(ext, {k: v for k, v in self.truth_overrides.items() if k in coef_names(ext)})

    def p0(self, ext: int = 0) -> np.ndarray:
        return p0_vector(ext, self.p0_terms)

    @property
    def arw_rad(self) -> float:
        """ARW in rad/sqrt(s)."""
        return self.arw_deg_rth * math.pi / 180.0 / 60.0

    @property
    def sigma_set_rad(self) -> float:
        return self.sigma_set_arcsec * math.pi / 180.0 / 3600.0

    def scheme(self, name: str | None) -> Scheme:
        """A scheme by name (config or built-in); InputError ``--scheme`` otherwise."""
        name = name or self.default_scheme
        if name not in self.schemes:
            raise InputError("--scheme", f"unknown scheme {name!r}; the config has {sorted(self.schemes)}")
        return self.schemes[name]

    def filter_choice(self):
        """The config's estimator, passes and options (:class:`.estimators.FilterChoice`)."""
        return choice_from_filter({**self.raw["filter"], "estimator": self.estimator, "passes": self.passes})

    def with_noise(self, **kw) -> "Config":
        return replace(self, **kw)


def check_positions(name: str, positions, beta_max_deg: float, where: str) -> tuple:
    """Positions as float triples; refuse |beta| > beta_max (§3) naming the position."""
    out = []
    for k, p in enumerate(positions, start=1):
        b = float(p[1])
        if abs(b) > beta_max_deg + 1e-12:
            raise InputError(f"{where}.positions[{k}]",
                             f"beta = {b:g} deg is outside the middle gimbal's range |beta| <= "
                             f"{beta_max_deg:g} deg (gimbal.beta_max_deg, docs/multiposition-1g.md §3)")
        out.append(tuple(float(a) for a in p))
    if not out:
        raise InputError(f"{where}.positions", "needs at least one position")
    return tuple(out)


def make_scheme(name: str, positions, dwell_s: float, beta_max_deg: float, where: str = "schemes") -> Scheme:
    return Scheme(name=name, positions=check_positions(name, positions, beta_max_deg, f"{where}.{name}"),
                  dwell_s=float(dwell_s))


def scheme_table(cfg: dict) -> dict[str, Scheme]:
    """The schemes of a validated config mapping: the built-in §11 schemes inside the gimbal
    range, then the config's ``schemes:`` (which replace built-ins of the same name)."""
    bmax = float(cfg["gimbal"]["beta_max_deg"])
    schemes = {n: make_scheme(n, p, 60.0, bmax, where="(built-in scheme)") for n, p in NAMED_POSITIONS.items()
               if all(abs(q[1]) <= bmax for q in p)}
    for n, s in cfg["schemes"].items():
        schemes[n] = make_scheme(n, s["positions"], s["dwell_s"], bmax)
    return schemes


def load_config(raw) -> Config:
    """Validate a raw config mapping (every default filled) into a :class:`Config`."""
    cfg = validate(raw, with_mapping_schema(load_schema("platcal.rigs.multiposition", "data/config.schema.yaml")))
    bmax = float(cfg["gimbal"]["beta_max_deg"])
    schemes = scheme_table(cfg)
    names = set(coef_names(2))
    for k in cfg["truth"]:
        if k not in names:
            raise InputError(f"truth.{k}", f"unknown coefficient; use names such as DF_x, DI_y, theta_px (§15): "
                             f"{sorted(names)}")
    check_estimator(cfg["filter"]["estimator"], "filter.estimator")
    for v, o in cfg["study"]["estimators"].items():
        if "estimator" in o:
            check_estimator(o["estimator"], f"study.estimators.{v}.estimator")
    if cfg["default_scheme"] not in schemes:
        raise InputError("default_scheme", f"unknown scheme {cfg['default_scheme']!r}; known {sorted(schemes)}")
    n, s, o = cfg["noise"], cfg["sampling"], cfg["observability"]
    return Config(raw=cfg, site=Site(cfg["site"]["latitude_deg"], cfg["site"]["earth_rate_rad_s"]),
                  beta_max_deg=bmax, beta_margin_deg=float(cfg["gimbal"]["margin_deg"]),
                  ts=float(s["ts_ms"]) / 1000.0, n_sub=int(s["n_sub"]), sigma_a_ug=float(n["sigma_a_ug"]),
                  sigma_an_arcsec=float(n["sigma_an_arcsec"]), arw_deg_rth=float(n["arw_deg_rth"]),
                  sigma_set_arcsec=float(n["sigma_set_arcsec"]), truth_overrides=dict(cfg["truth"]),
                  p0_terms=dict(cfg["filter"]["p0"]), passes=int(cfg["filter"]["passes"]),
                  estimator=cfg["filter"]["estimator"],
                  rank_rtol=float(o["rank_rtol"]), lie_order=int(o["lie_order"]), cov_step_s=float(o["cov_step_s"]),
                  max_rel_sigma_pct=float(o["max_rel_sigma_pct"]), seed=int(cfg["seed"]),
                  default_scheme=cfg["default_scheme"], schemes=schemes)
