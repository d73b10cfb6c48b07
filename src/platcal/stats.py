"""Monte Carlo statistics: Table 2 over replicates, the sweep summary, NEES consistency.

Inputs are the tidy tables of :mod:`platcal.montecarlo` (one row per run x coefficient, one row
per run). Relative errors are eq. 28 in percent; sigmas are the filter's predicted 1-sigma in
the coefficient's unit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats as sps

from .instruments import load_catalogue

CELL = ["scheme", "sigma_a_ug", "estimator"]


def nees_band(dof: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` band of a chi-square(dof) NEES (for 45: 28.4 .. 65.4)."""
    a = (1.0 - level) / 2.0
    return float(sps.chi2.ppf(a, dof)), float(sps.chi2.ppf(1.0 - a, dof))


def rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def select_cell(df: pd.DataFrame, scheme: str, sigma_a_ug: float, estimator: str) -> pd.DataFrame:
    """Rows of one (scheme, noise level, estimator) cell."""
    m = (df["scheme"] == scheme) & np.isclose(df["sigma_a_ug"], sigma_a_ug) & (df["estimator"] == estimator)
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


def table2_montecarlo(coef: pd.DataFrame, scheme: str, sigma_a_ug: float, estimator: str) -> pd.DataFrame:
    """Table 2 over the replicates of one cell, with the paper's relative error and its z-score.

    ``paper_z = (paper_rel_err - our mean rel_err) / our std rel_err``: how many of our
    replicate-to-replicate standard deviations the paper's single error lies from our mean.
    """
    cell = select_cell(coef, scheme, sigma_a_ug, estimator)
    if cell.empty:
        raise ValueError(f"no Monte Carlo rows for scheme={scheme}, sigma_a={sigma_a_ug}, estimator={estimator}")
    pc = per_coefficient(cell)
    cat = load_catalogue().frame().set_index("name")
    pc = pc[pc["name"].isin(cat.index)].copy()
    pc["paper_rel_err_pct"] = cat.loc[pc["name"], "paper_rel_err_pct"].to_numpy()
    with np.errstate(divide="ignore", invalid="ignore"):
        pc["paper_z"] = (pc["paper_rel_err_pct"] - pc["mean_rel_err_pct"]) / pc["std_rel_err_pct"]
    cols = ["name", "group", "unit", "truth", "n", "mean_estimate", "mean_rel_err_pct", "std_rel_err_pct",
            "rms_rel_err_pct", "mean_sigma", "mean_rel_sigma_pct", "paper_rel_err_pct", "paper_z"]
    return pc[cols].rename(columns={"name": "coefficient"}).reset_index(drop=True)


def summary(coef: pd.DataFrame, runs: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """Per scheme x noise level x estimator: the largest and median RMS relative error (%) of
    the gyro and accelerometer groups, the mean NEES and the share of runs inside the ``level``
    chi-square band (dof = the number of coefficients). Deterministic (no wall time)."""
    pc = per_coefficient(coef)
    rows = []
    for key, g in pc.groupby(CELL, sort=False):
        r = dict(zip(CELL, key))
        for grp in ("gyro", "accel"):
            v = g.loc[g["group"] == grp, "rms_rel_err_pct"]
            r[f"max_rms_rel_err_pct_{grp}"] = float(v.max())
            r[f"median_rms_rel_err_pct_{grp}"] = float(v.median())
            worst = g.loc[g["group"] == grp].sort_values("rms_rel_err_pct").iloc[-1]["name"] if len(v) else ""
            r[f"worst_{grp}"] = worst
        rows.append(r)
    out = pd.DataFrame(rows)
    ru = runs.groupby(CELL, sort=False)
    dof = int(runs["nees_dof"].iloc[0])
    lo, hi = nees_band(dof, level)
    nees_stats = ru.agg(runs=("replicate", "size"), mean_nees=("nees", "mean"),
                        median_nees=("nees", "median"),
                        share_in_band=("nees", lambda x: float(np.mean((x >= lo) & (x <= hi)))),
                        failed_updates=("failed_updates", "sum")).reset_index()
    out = out.merge(nees_stats, on=CELL, how="left")
    out["nees_dof"] = dof
    return out.sort_values(CELL, kind="stable").reset_index(drop=True)


def with_timing(summ: pd.DataFrame, timing: pd.DataFrame) -> pd.DataFrame:
    """The summary with the wall time per run (s) of each cell (machine-dependent)."""
    t = timing[CELL + ["wall_s_per_run", "threads"]].copy()
    return summ.merge(t, on=CELL, how="left")


# ---------------------------------------------------------------------------------------------
# rendering


def _fmt(v, spec):
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return format(v, spec)


def frame_markdown(df: pd.DataFrame, formats: dict[str, str] | None = None) -> str:
    """A DataFrame as a Markdown table (no tabulate dependency); ``formats`` by column."""
    formats = formats or {}
    cols = list(df.columns)
    lines = ["| " + " | ".join(cols) + " |",
             "|" + "|".join("---:" if pd.api.types.is_numeric_dtype(df[c]) else "---" for c in cols) + "|"]
    for _, r in df.iterrows():
        lines.append("| " + " | ".join(_fmt(r[c], formats.get(c, "g")) for c in cols) + " |")
    return "\n".join(lines) + "\n"


def frame_html(df: pd.DataFrame, title: str, note: str = "", formats: dict[str, str] | None = None) -> str:
    """A self-contained HTML page with one table (for people and ``snakemake --report``)."""
    formats = formats or {}
    shown = df.copy()
    for c in shown.columns:
        if c in formats:
            shown[c] = [_fmt(v, formats[c]) for v in shown[c]]
    body = shown.to_html(index=False, border=0, classes="t", na_rep="-")
    return ("<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>" + title + "</title>\n"
            "<style>body{font-family:sans-serif;margin:1em}table.t{border-collapse:collapse;font-size:13px}"
            "table.t td,table.t th{border-bottom:1px solid #ddd;padding:2px 8px;text-align:right}"
            "table.t th{background:#f0f0f0}</style></head><body>\n"
            f"<h2>{title}</h2>\n<p>{note}</p>\n{body}\n</body></html>\n")
