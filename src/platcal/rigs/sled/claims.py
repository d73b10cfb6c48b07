"""The sled paper's claims and the spec's checks (docs/rocket-sled.md §11) as measures on the
study's per-replicate metrics (the Monte Carlo runs table); the claims are data (``data/claims.yaml``), evaluated by
:mod:`platcal.study.claims`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims


def metric(results: Path, cfg: dict, case: str, column: str, scale: float = 1.0) -> Evidence | None:
    """Per replicate, the metric ``column`` (§8) of study case ``case`` from the Monte Carlo runs
    table (results/sled/montecarlo/runs.parquet) times ``scale``, failed runs left out; None when
    the study did not run it."""
    f = Path(results) / "montecarlo" / "runs.parquet"
    if not f.exists():
        return None
    m = pd.read_parquet(f)
    m = m[(m["scheme"] == case) & ~m["failed"].astype(bool)]
    if m.empty or column not in m:
        return Evidence(np.array([]), f"case {case}: not in the study")
    return Evidence((m[column].abs() * scale).to_numpy(float), f"case {case}, {len(m)} replicates")


def metric_ratio(results: Path, cfg: dict, case: str, numerator: str, denominator: str) -> Evidence | None:
    """Per replicate, |``numerator``| / |``denominator``| of study case ``case`` (two §8 metrics
    of the runs table, e.g. the naive X error over the constrained one: > 1, the compensation
    helps), failed runs left out; None when the study did not run it."""
    num = metric(results, cfg, case, numerator)
    den = metric(results, cfg, case, denominator)
    if num is None or den is None or num.samples.size == 0 or den.samples.size == 0:
        return num if num is None or num.samples.size == 0 else den
    return Evidence(num.samples / den.samples, num.settings)


MEASURES = {"metric": metric, "metric_ratio": metric_ratio}


def claims():
    return load_claims("sled", resources.files(__package__).joinpath("data/claims.yaml").read_text())
