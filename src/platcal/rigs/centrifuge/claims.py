"""The centrifuge paper's claims (Xu & Zhang 2017, docs/centrifuge-model.md §12) as measures on the
study's results; the claims themselves are data (``data/claims.yaml``), evaluated by
:mod:`platcal.study.claims`."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims


def _default_cell(cfg: dict, scheme: str) -> tuple[str, float, str]:
    """The cell a Table-2 claim is read from: ``scheme`` at the config's ``noise.sigma_a_ug`` with
    the study's first estimator."""
    return scheme, float(cfg["noise"]["sigma_a_ug"]), next(iter(cfg["study"]["estimators"]))


def max_rel_err(results: Path, cfg: dict, group: str, scheme: str = "table1") -> Evidence | None:
    """Per replicate, the largest |relative error| (%) of the ``group`` coefficients (eq. 28) in
    the Monte Carlo cell of :func:`_default_cell`; None when the study did not run it."""
    f = Path(results) / "montecarlo" / "coef.parquet"
    if not f.exists():
        return None
    sch, noise, est = _default_cell(cfg, scheme)
    coef = pd.read_parquet(f)
    c = coef[(coef["scheme"] == sch) & np.isclose(coef["noise"], noise) & (coef["estimator"] == est)
             & (coef["group"] == group)]
    settings = f"scheme {sch}, sigma_a {noise:g} ug, estimator {est}"
    if c.empty:
        return Evidence(np.array([]), settings + ": cell not in the study")
    per = c.assign(a=c["rel_err_pct"].abs()).groupby("replicate")["a"].max()
    return Evidence(per.to_numpy(float), f"{settings}, {len(per)} replicates")


def mean_nees(results: Path, cfg: dict, scheme: str = "table1") -> Evidence | None:
    """NEES of each replicate of the cell of :func:`_default_cell` (45 degrees of freedom)."""
    f = Path(results) / "montecarlo" / "runs.parquet"
    if not f.exists():
        return None
    sch, noise, est = _default_cell(cfg, scheme)
    r = pd.read_parquet(f)
    r = r[(r["scheme"] == sch) & np.isclose(r["noise"], noise) & (r["estimator"] == est)]
    return Evidence(r["nees"].to_numpy(float), f"scheme {sch}, sigma_a {noise:g} ug, estimator {est}, "
                                                f"{len(r)} replicates")


MEASURES = {"max_rel_err": max_rel_err, "nees": mean_nees}


def claims():
    return load_claims("centrifuge", resources.files(__package__).joinpath("data/claims.yaml").read_text())
