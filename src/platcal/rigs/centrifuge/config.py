"""Study configuration: YAML validated against a JSON Schema that supplies the defaults.

The schema (``platcal/rigs/centrifuge/data/config.schema.yaml``) holds the defaults of
docs/centrifuge-model.md §11; this
module turns a validated mapping into a :class:`Study` of typed records. Every error is an
:class:`~platcal.errors.InputError` that names the offending field.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...io import read_config
from ...model.instruments import INDEX, term_of
from ...mapping_keys import with_mapping_schema
from ...schema import load_schema, validate
from .base import Centrifuge
from .catalogue import full_truth
from .ekf import FilterSettings, default_p0_sigma
from .estimators import check_kind, options_from_filter
from ...scheme import Scheme, check_scheme, whole_periods
from .simulate import Noise

SCHEMA_RESOURCE = "data/config.schema.yaml"
ANGLE_KEYS = ("angles", "alpha", "beta", "gamma")
"""``filter.p0`` keys for the attitude states (arcsec); they set the reset sigma."""


def schema() -> dict:
    """The configuration's JSON Schema (with defaults)."""
    return with_mapping_schema(load_schema(__package__, SCHEMA_RESOURCE))


def validate_config(raw: dict) -> dict:
    """Validate a configuration mapping and return a copy with every default filled in.

    Raises InputError naming the first bad field (schemes, coefficient names and values,
    noise levels, filter settings) before any work starts.
    """
    if not isinstance(raw, dict):
        raise InputError("(top level)", "a configuration is a YAML mapping")
    schemes = raw.get("schemes")
    if isinstance(schemes, dict):
        for name, spec in schemes.items():
            check_scheme(str(name), copy.deepcopy(spec))
    cfg = validate(raw, schema())
    for name, value in cfg["truth"].items():
        if name not in INDEX:
            raise InputError(f"truth.{name}", "unknown coefficient; use one of the 45 names of "
                             "Table 2 (DF_x ... theta_oz) or DOO_x/DOO_y/DOO_z")
    terms = {term_of(n) for n in INDEX}
    for key in cfg["filter"]["p0"]:
        if key not in INDEX and key not in terms and key not in ANGLE_KEYS:
            raise InputError(f"filter.p0.{key}", f"unknown term or coefficient; use one of {sorted(terms)} "
                             "or a coefficient name such as DF_x")
    check_kind(cfg["filter"]["estimator"])
    sample = cfg["sampling"]["sample_ms"]
    ratio = cfg["filter"]["period_ms"] / sample
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise InputError("filter.period_ms", f"must be a whole multiple of sampling.sample_ms = {sample}")
    for name, spec in cfg["schemes"].items():
        whole_periods(spec["dwell_s"], sample / 1000.0, f"schemes.{name}.dwell_s")
    return cfg


@dataclass(frozen=True)
class Study:
    """A validated configuration as typed records (config -> scheme -> data -> estimate)."""

    centrifuge: Centrifuge
    sample_s: float
    truth: np.ndarray
    noise: Noise
    filter: FilterSettings
    schemes: dict[str, Scheme]
    seed: int
    config: dict

    @property
    def keep_every(self) -> int:
        """Samples per filter period."""
        return int(round(self.filter.period_s / self.sample_s))


def filter_settings(fcfg: dict, noise: Noise) -> FilterSettings:
    """FilterSettings from the validated ``filter`` section; nulls take the truth's noise."""
    def pick(key, fallback):
        return fallback if fcfg.get(key) is None else float(fcfg[key])

    p0 = dict(fcfg["p0"])
    # P0 of the attitude states is the reset sigma (docs/centrifuge-model.md §11: "angles sigma_set")
    angle_sigma = [p0.pop(k) for k in ANGLE_KEYS if k in p0]
    reset = fcfg.get("sigma_set_arcsec")
    if reset is None and angle_sigma:
        reset = max(angle_sigma)
    return FilterSettings(
        period_s=fcfg["period_ms"] / 1000.0,
        passes=int(fcfg["passes"]),
        sigma_a_ug=pick("sigma_a_ug", noise.sigma_a_ug),
        arw_deg_rth=pick("arw_deg_rth", noise.arw_deg_rth),
        sigma_set_arcsec=noise.sigma_set_arcsec if reset is None else float(reset),
        p0_sigma=default_p0_sigma(bool(fcfg["estimate_doo"]), p0),
        estimate_doo=bool(fcfg["estimate_doo"]),
        history_every_s=float(fcfg["history_s"]),
        update_at_reset=bool(fcfg.get("update_at_reset", False)),
        estimator=str(fcfg.get("estimator", "ekf")),
        estimator_options=options_from_filter(fcfg),
    )


def check_filter(fs: FilterSettings) -> FilterSettings:
    """Refuse filter settings a filter cannot run with (InputError naming the field); return them.

    Called where a filter runs (identify, montecarlo, observability, design), not when a config
    is read: ``platcal simulate`` needs no filter, so a noise-free config (``noise:
    {sigma_a_ug: 0, arw_deg_rth: 0, sigma_set_arcsec: 0}``) simulates (issue 9 item 2).
    """
    if fs.sigma_set_arcsec <= 0:
        raise InputError("filter.sigma_set_arcsec", "the filter's attitude variance at each reset must be > 0 "
                         "(set noise.sigma_set_arcsec > 0 or filter.sigma_set_arcsec)")
    if fs.sigma_a_ug <= 0:
        raise InputError("filter.sigma_a_ug", "the filter's measurement noise must be > 0 "
                         "(set noise.sigma_a_ug > 0 or filter.sigma_a_ug)")
    return fs


def study_from_config(cfg: dict) -> Study:
    """Build a Study from a raw or validated configuration mapping."""
    cfg = validate_config(cfg)
    site, cen = cfg["site"], cfg["centrifuge"]
    noise = Noise(**{k: float(v) for k, v in cfg["noise"].items()})
    fs = filter_settings(cfg["filter"], noise)
    return Study(
        centrifuge=Centrifuge(rate_deg_s=float(cen["rate_deg_s"]), g_level=float(cen["g_level"]),
                              latitude_deg=float(site["latitude_deg"]), g=float(site["g"]),
                              earth_rate=float(site["earth_rate_rad_s"])),
        sample_s=cfg["sampling"]["sample_ms"] / 1000.0,
        truth=full_truth(cfg["truth"]),
        noise=noise,
        filter=fs,
        schemes={n: check_scheme(n, s) for n, s in cfg["schemes"].items()},
        seed=int(cfg["seed"]),
        config=cfg,
    )


def load_config(path: str | os.PathLike) -> Study:
    """Read, validate and type a YAML configuration file."""
    raw = read_config(path, str(path))
    return study_from_config(raw)
