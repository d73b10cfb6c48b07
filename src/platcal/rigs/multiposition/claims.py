"""The patent's and the spec's claims (docs/multiposition-1g.md §8, §13, §15) as measures on the
study's results; the claims are data (``data/claims.yaml``), evaluated by :mod:`platcal.study.claims`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims
from .extension import SPEC_RANGES


def static_rank(results: Path, cfg: dict, scheme: str) -> Evidence | None:
    """The static rank of ``scheme`` (§8; the rank table of the study), one deterministic value."""
    f = Path(results) / "tables" / "ranks.csv"
    if not f.exists():
        return None
    r = pd.read_csv(f)
    r = r[r["scheme"] == scheme]
    return Evidence(r["static rank"].to_numpy(float), f"scheme {scheme}, covariance-only at x = 0")


def accepted(results: Path, cfg: dict, scheme: str) -> Evidence | None:
    """1 when the scheme check accepts ``scheme`` (rank and covariance rule, §8), else 0."""
    f = Path(results) / "tables" / "ranks.csv"
    if not f.exists():
        return None
    r = pd.read_csv(f)
    r = r[r["scheme"] == scheme]
    return Evidence((r["verdict"] == "accept").to_numpy(float), f"scheme {scheme}, the study's scheme check")


def _cell(results: Path, table: str, scheme: str, noise: float, estimator: str):
    f = Path(results) / "montecarlo" / f"{table}.parquet"
    if not f.exists():
        return None
    d = pd.read_parquet(f)
    return d[(d["scheme"] == scheme) & np.isclose(d["noise"], noise) & (d["estimator"] == estimator)]


def max_rel_err(results: Path, cfg: dict, group: str, scheme: str = "S8", noise: float = 5.0,
                estimator: str = "ekf1") -> Evidence | None:
    """Per replicate, the largest |relative error| (%) of ``group`` in the Monte Carlo cell (§15 item 4)."""
    c = _cell(results, "coef", scheme, noise, estimator)
    if c is None:
        return None
    settings = f"scheme {scheme}, sigma_a {noise:g} ug, estimator {estimator}"
    c = c[c["group"] == group]
    per = c.assign(a=c["rel_err_pct"].abs()).groupby("replicate")["a"].max()
    return Evidence(per.to_numpy(float), f"{settings}, {len(per)} replicates")


def nees(results: Path, cfg: dict, scheme: str = "S8", noise: float = 5.0, estimator: str = "ekf1") -> Evidence | None:
    """NEES of each replicate of the Monte Carlo cell (24 coefficients, §15 item 4)."""
    r = _cell(results, "runs", scheme, noise, estimator)
    if r is None:
        return None
    return Evidence(r["nees"].to_numpy(float), f"scheme {scheme}, sigma_a {noise:g} ug, estimator {estimator}, "
                                                f"{len(r)} replicates")


def range_within_20pct(results: Path, cfg: dict) -> Evidence | None:
    """Per random draw of 24 positions (§13), 1 when all eight endpoints of the sigma/|truth| ranges
    lie within 20 % of the spec's (the distribution over the study's draws), else 0."""
    f = Path(results) / "extension" / "spread.csv"
    if not f.exists():
        return None
    d = pd.read_csv(f)
    ok = [abs(r.min_pct / SPEC_RANGES[r.group][0] - 1) <= 0.2 and abs(r.max_pct / SPEC_RANGES[r.group][1] - 1) <= 0.2
          for r in d.itertuples()]
    per_draw = d.assign(ok=ok).groupby("draw")["ok"].all()
    return Evidence(per_draw.to_numpy(float), f"{len(per_draw)} random draws of 24 positions x 60 s, covariance-only")


MEASURES = {"static_rank": static_rank, "accepted": accepted, "max_rel_err": max_rel_err, "nees": nees,
            "range_within_20pct": range_within_20pct}


def claims():
    return load_claims("multiposition", resources.files(__package__).joinpath("data/claims.yaml").read_text())
