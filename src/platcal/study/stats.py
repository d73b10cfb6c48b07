"""Monte Carlo statistics of any rig: per quantity over replicates, the sweep summary, NEES.

Inputs are the tidy tables of :mod:`platcal.study.montecarlo` (one row per run x quantity, one
row per run; a cell is ``scheme, noise, estimator``). Relative errors are (estimate - truth) /
truth in percent (docs/centrifuge-model.md eq. 28); sigmas are the filter's predicted 1-sigma in
the quantity's unit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..estimation.consistency import nees_band

CELL = ["scheme", "noise", "estimator"]


def rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def select_cell(df: pd.DataFrame, scheme: str, noise: float, estimator: str) -> pd.DataFrame:
    """Rows of one (scheme, noise level, estimator) cell."""
    m = (df["scheme"] == scheme) & np.isclose(df["noise"], noise) & (df["estimator"] == estimator)
    return df[m]


def per_coefficient(coef: pd.DataFrame) -> pd.DataFrame:
    """Per cell and coefficient: mean estimate, mean / std / RMS relative error (%), mean sigma.

    ``std_rel_err_pct`` is the sample standard deviation over replicates (ddof = 1; NaN for one
    replicate); ``mean_rel_sigma_pct`` is the predicted 1-sigma relative to |truth|, %.
    """
    df = coef.copy()
    df["rel_sigma_pct"] = df["sigma"] / df["truth"].abs() * 100.0
    df["_order"] = df.groupby(CELL + ["replicate"], sort=False).cumcount()
    g = df.groupby(CELL + ["name"], sort=False)
    out = g.agg(group=("group", "first"), unit=("unit", "first"), order=("_order", "first"),
                truth=("truth", "first"), n=("replicate", "size"), mean_estimate=("estimate", "mean"),
                mean_rel_err_pct=("rel_err_pct", "mean"), std_rel_err_pct=("rel_err_pct", "std"),
                rms_rel_err_pct=("rel_err_pct", rms), mean_sigma=("sigma", "mean"),
                mean_rel_sigma_pct=("rel_sigma_pct", "mean"))
    return out.reset_index().sort_values(CELL + ["order"], kind="stable").drop(columns="order").reset_index(drop=True)


def summary(coef: pd.DataFrame, runs: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """Per scheme x noise level x estimator: the largest and median RMS relative error (%) of
    each group of quantities (in the order they first appear), the mean NEES and the share of
    runs inside the ``level`` chi-square band (dof = the number of quantities). Deterministic
    (no wall time)."""
    pc = per_coefficient(coef)
    groups = list(dict.fromkeys(pc["group"]))
    rows = []
    for key, g in pc.groupby(CELL, sort=False):
        r = dict(zip(CELL, key))
        for grp in groups:
            v = g.loc[g["group"] == grp, "rms_rel_err_pct"]
            r[f"max_rms_rel_err_pct_{grp}"] = float(v.max())
            r[f"median_rms_rel_err_pct_{grp}"] = float(v.median())
            worst = g.loc[g["group"] == grp].sort_values("rms_rel_err_pct").iloc[-1]["name"] if len(v) else ""
            r[f"worst_{grp}"] = worst
        rows.append(r)
    out = pd.DataFrame(rows)
    if "failed" not in runs:  # tables of cells written before runs were flagged
        runs = runs.assign(failed=runs["failed_updates"] > 0)
    ru = runs.groupby(CELL, sort=False)
    dof = int(runs["nees_dof"].iloc[0])
    lo, hi = nees_band(dof, level)
    nees_stats = ru.agg(runs=("replicate", "size"), mean_nees=("nees", "mean"),
                        median_nees=("nees", "median"),
                        share_in_band=("nees", lambda x: float(np.mean((x >= lo) & (x <= hi)))),
                        failed_updates=("failed_updates", "sum"),
                        failed_runs=("failed", "sum")).reset_index()
    out = out.merge(nees_stats, on=CELL, how="left")
    out["nees_dof"] = dof
    return out.sort_values(CELL, kind="stable").reset_index(drop=True)


def with_timing(summ: pd.DataFrame, timing: pd.DataFrame) -> pd.DataFrame:
    """The summary with the wall time per run (s) of each cell (machine-dependent)."""
    t = timing[CELL + ["wall_s_per_run", "threads"]].copy()
    return summ.merge(t, on=CELL, how="left")
