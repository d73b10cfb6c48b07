"""Tang et al.'s claims (docs/lowprec-centrifuge.md §8, §11) as measures on the study's
cross-validations, read from the tidy Monte Carlo tables (results/lowprec_centrifuge/montecarlo/);
the claims are data (``data/claims.yaml``), evaluated by :mod:`platcal.study.claims`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims
from .config import load_config
from .montecarlo import study_frames


def _frames(results: Path, cfg: dict, scenario: str) -> tuple[pd.DataFrame, pd.DataFrame] | None:
    """The cross-validations and coefficients of ``scenario`` (:func:`.montecarlo.study_frames`)
    from the study's tidy tables ``<results>/montecarlo/{coef,runs}.parquet``, failed runs left
    out; None when the study did not run the scenario."""
    folder = Path(results) / "montecarlo"
    if not (folder / "runs.parquet").exists() or not (folder / "coef.parquet").exists():
        return None
    runs = pd.read_parquet(folder / "runs.parquet")
    if scenario not in set(runs["scheme"]):
        return None
    cross, coeffs = study_frames(load_config(cfg), [scenario], pd.read_parquet(folder / "coef.parquet"), runs)
    return cross[~cross["failed"].astype(bool)], coeffs[~coeffs["failed"].astype(bool)]


def _cross(results: Path, cfg: dict, scenario: str) -> pd.DataFrame | None:
    f = _frames(results, cfg, scenario)
    return None if f is None else f[0]


def effect(results: Path, cfg: dict, method: str, error: str, channel: str = "X",
           scenario: str = "default") -> Evidence | None:
    """Per seed x platform x calibration run x evaluated run, the compensation effect (%) of
    ``method`` on ``error`` (VE, VN, pE, pN) of the ``channel`` accelerometer (§8)."""
    d = _cross(results, cfg, scenario)
    if d is None:
        return None
    d = d[(d["method"] == method) & (d["error"] == error) & (d["channel"] == channel)]
    return Evidence(d["effect_pct"].to_numpy(float), f"scenario {scenario}, {method}, {error} of {channel}, "
                                                     f"{d['seed'].nunique()} seeds, {len(d)} cross-validations")


def effect_shift(results: Path, cfg: dict, error: str, a: str = "perfect", b: str = "worst",
                 method: str = "proposed", channel: str = "X") -> Evidence | None:
    """Per seed, |median effect in scenario ``b`` - in ``a``| (percentage points) of ``method``:
    how much the centrifuge's imprecision moves the result (§2)."""
    da, db = _cross(results, cfg, a), _cross(results, cfg, b)
    if da is None or db is None:
        return None

    def per_seed(d):
        d = d[(d["method"] == method) & (d["error"] == error) & (d["channel"] == channel)]
        return d.groupby("seed")["effect_pct"].median()

    sa, sb = per_seed(da), per_seed(db)
    common = sa.index.intersection(sb.index)
    return Evidence(np.abs(sb[common] - sa[common]).to_numpy(float),
                    f"scenarios {a} vs {b}, {method}, {error} of {channel}, {len(common)} seeds")


def effect_gap(results: Path, cfg: dict, error: str, channel: str = "X", scenario: str = "default") -> Evidence | None:
    """Per seed, median effect (%) of the proposed method minus the traditional one's (points)."""
    d = _cross(results, cfg, scenario)
    if d is None:
        return None
    d = d[(d["error"] == error) & (d["channel"] == channel)]
    med = d.groupby(["seed", "method"])["effect_pct"].median().unstack("method")
    gap = (med["proposed"] - med["traditional"]).dropna()
    return Evidence(gap.to_numpy(float), f"scenario {scenario}, proposed - traditional, {error} of {channel}, "
                                         f"{len(gap)} seeds")


def normalised_errors(results: Path, cfg: dict, scenario: str = "default") -> Evidence | None:
    """Per seed x platform x run x coefficient, (estimate - truth) / sigma of the proposed filter
    (§11 item 6), pooled over the coefficients."""
    f = _frames(results, cfg, scenario)
    if f is None:
        return None
    c = f[1][f[1]["method"] == "proposed"]
    z = ((c["estimate"] - c["truth"]) / c["sigma"]).to_numpy(float)
    return Evidence(z, f"scenario {scenario}, proposed, {c.groupby(['platform', 'run', 'coefficient']).ngroups} "
                       f"coefficients x {c['seed'].nunique()} seeds")


MEASURES = {"effect": effect, "effect_shift": effect_shift, "effect_gap": effect_gap,
            "normalised_errors": normalised_errors}


def claims():
    return load_claims("lowprec_centrifuge", resources.files(__package__).joinpath("data/claims.yaml").read_text())
