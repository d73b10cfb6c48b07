"""The sled paper's claims and the spec's checks (docs/rocket-sled.md §11) as measures on the
study's per-seed metrics; the claims are data (``data/claims.yaml``), evaluated by
:mod:`platcal.study.claims`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import pandas as pd

from ...study.claims import Evidence, load_claims


def metric(results: Path, cfg: dict, case: str, column: str, scale: float = 1.0) -> Evidence | None:
    """Per seed, ``column`` of study case ``case`` (results/sled/cases/<case>/metrics.csv) times
    ``scale``, failed seeds left out; None when the study did not run the case."""
    f = Path(results) / "cases" / case / "metrics.csv"
    if not f.exists():
        return None
    m = pd.read_csv(f)
    if "failed" in m:
        m = m[~m["failed"].astype(bool)]
    return Evidence((m[column].abs() * scale).to_numpy(float), f"case {case}, {len(m)} seeds")


MEASURES = {"metric": metric}


def claims():
    return load_claims("sled", resources.files(__package__).joinpath("data/claims.yaml").read_text())
