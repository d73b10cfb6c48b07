"""Monte Carlo study of the rig (docs/lowprec-centrifuge.md §2 sweep, §8 metrics, §11 checks).

One *scenario* is a centrifuge imprecision (rate, arm, stretch); in it every platform runs its
proposed runs and the traditional run for every seed (common random numbers across scenarios,
§9), as cells of the generic Monte Carlo runner (:mod:`.montecarlo`, whose
:func:`~.montecarlo.study_frames` turns the tidy tables into the cross-validation table: scenario,
seed, platform, method, calibration run, evaluated run, channel, error, before, after, effect %,
nonlinear-part effect %, failed; and the coefficient table: scenario, seed, platform, method, run,
coefficient, estimate, sigma, truth, failed). The aggregation functions here build the Table-1
analogue, the coefficient and degradation tables and the §11 acceptance checks from those.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


PAPER_TABLE1 = pd.DataFrame(
    [("P1", "run1", "run1", -3.96, 84.1, -1428, 93.4), ("P1", "run1", "run2", -13.26, 96.3, -6517, 94.5),
     ("P1", "run2", "run1", -3.96, 76.2, -1428, 86.4), ("P1", "run2", "run2", -13.26, 96.4, -6517, 98.8),
     ("P2", "run1", "run1", 13.83, 88.8, 3280, 91.5), ("P2", "run1", "run2", 20.29, 95.3, 8338, 96.9),
     ("P2", "run2", "run1", 13.83, 91.2, 3280, 94.7), ("P2", "run2", "run2", 20.29, 95.8, 8338, 94.8)],
    columns=["platform", "cal_run", "eval_run", "paper_VE_before", "paper_VE_effect", "paper_pE_before",
             "paper_pE_effect"])
"""The paper's Table 1 (tests 1-4 = P1 run1, P1 run2, P2 run1, P2 run2; X accelerometer)."""
PAPER_TRADITIONAL_RESIDUAL_PCT = {"VE": 50.2, "VN": 71.0, "pN": 51.2, "pE": 71.4}
"""Paper §2: after the traditional compensation the final errors are these % of the errors before
(east velocity, north velocity, latitude, longitude), i.e. effects 29-50 %."""


def drop_failed(cross: pd.DataFrame, coeffs: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, int]:
    """The rows of runs that did not fail, and the number of failed identification runs
    (seed x platform x method x run); tables written before this column existed pass through."""
    if "failed" not in coeffs:
        return cross, coeffs, 0
    n = int(coeffs[coeffs["failed"]].groupby([c for c in ("scenario", "seed", "platform", "method", "run")
                                              if c in coeffs]).ngroups)
    return cross[~cross["failed"]], coeffs[~coeffs["failed"]], n


# ---------------------------------------------------------------- aggregation

def _x(cross: pd.DataFrame) -> pd.DataFrame:
    return cross[cross["channel"] == "X"]


def table1(cross: pd.DataFrame) -> pd.DataFrame:
    """Table-1 analogue: per platform and cell, before (median), effect median and worst seed, beside the paper."""
    rows = []
    for (p, m, i, j), g in _x(cross).groupby(["platform", "method", "cal_run", "eval_run"], sort=False):
        r = {"platform": p, "method": m, "cell": f"{i}->{j}", "cal_run": i, "eval_run": j}
        for e in ("VE", "pE"):
            ge = g[g["error"] == e]
            r[f"{e}_before"] = ge["before"].median()
            r[f"{e}_after"] = ge["after"].median()
            r[f"{e}_effect_median"] = ge["effect_pct"].median()
            r[f"{e}_effect_worst"] = ge["effect_pct"].min()
            r[f"{e}_nonlinear_median"] = ge["nonlinear_effect_pct"].median()
        rows.append(r)
    df = pd.DataFrame(rows).merge(PAPER_TABLE1, on=["platform", "cal_run", "eval_run"], how="left")
    order = {"proposed": 0, "traditional": 1, "truth": 2}
    df = df.sort_values(["platform", "method"], key=lambda s: s.map(order) if s.name == "method" else s,
                        kind="stable")
    return df.drop(columns=["cal_run", "eval_run"]).reset_index(drop=True)


def y_table(cross: pd.DataFrame) -> pd.DataFrame:
    """Y channel (VN, pN): median effect per platform and cell."""
    g = cross[cross["channel"] == "Y"].groupby(["platform", "method", "cal_run", "eval_run", "error"], sort=False)
    df = g.agg(before=("before", "median"), effect_median=("effect_pct", "median"),
               effect_worst=("effect_pct", "min"), nonlinear_median=("nonlinear_effect_pct", "median")).reset_index()
    return df


def coefficient_table(coeffs: pd.DataFrame) -> pd.DataFrame:
    """Per platform, method, run and coefficient: truth, mean, sd, mean error, RMS normalised error."""
    rows = []
    for (p, m, r, c), g in coeffs.groupby(["platform", "method", "run", "coefficient"], sort=False):
        err = g["estimate"] - g["truth"]
        z = err / g["sigma"]
        rows.append({"platform": p, "method": m, "run": r, "coefficient": c, "truth": g["truth"].iloc[0],
                     "mean": g["estimate"].mean(), "sd": g["estimate"].std(ddof=1), "mean_error": err.mean(),
                     "mean_sigma": g["sigma"].mean(), "rms_z": float(np.sqrt((z**2).mean())) if z.notna().all()
                     else np.nan, "n": len(g)})
    return pd.DataFrame(rows)


def pooled(cross: pd.DataFrame, method: str, error: str, col: str = "effect_pct") -> pd.Series:
    g = cross[(cross["method"] == method) & (cross["error"] == error)]
    return g[col]


def degradation_table(cross_all: pd.DataFrame, coeffs_all: pd.DataFrame, meta: dict) -> pd.DataFrame:
    """Per scenario: imprecision, pooled median effects (X channel) per method, and the shift from ``perfect``."""
    rows = []
    base = "perfect" if "perfect" in meta else "default"
    cmeans = coeffs_all.groupby(["scenario", "platform", "method", "run", "coefficient"])["estimate"].mean()
    for name, m in meta.items():
        c = cross_all[cross_all["scenario"] == name]
        if c.empty:
            continue
        cen = m["centrifuge"]
        r = {"scenario": name, "rate_error": cen.rate_error, "arm_error_mm": cen.arm_error_mm,
             "stretch_mm_per_g": cen.stretch_mm_per_g}
        for meth in ("proposed", "traditional"):
            for e in ("VE", "pE"):
                r[f"{meth}_{e}_median"] = pooled(c, meth, e).median()
            r[f"{meth}_VE_nonlinear_median"] = pooled(c, meth, "VE", "nonlinear_effect_pct").median()
            d = (cmeans.loc[name].xs(meth, level="method") - cmeans.loc[base].xs(meth, level="method")).abs()
            r[f"{meth}_max_coef_shift"] = d.max()
        rows.append(r)
    df = pd.DataFrame(rows)
    b = df[df["scenario"] == base].iloc[0]
    for meth in ("proposed", "traditional"):
        for e in ("VE", "pE"):
            df[f"{meth}_{e}_shift_pp"] = df[f"{meth}_{e}_median"] - b[f"{meth}_{e}_median"]
    return df


def acceptance(cross: pd.DataFrame, coeffs: pd.DataFrame, cross_perfect: pd.DataFrame | None = None,
               coeffs_perfect: pd.DataFrame | None = None, cross_worst: pd.DataFrame | None = None,
               coeffs_worst: pd.DataFrame | None = None) -> pd.DataFrame:
    """The checks of §11 "What an implementation must show" (items 1-6) on the given tables."""
    rows = []

    def add(item, what, measured, ok):
        rows.append({"item": item, "check": what, "measured": measured, "pass": bool(ok)})

    ct = coefficient_table(coeffs)
    prop = ct[ct["method"] == "proposed"]
    for _, r in prop.iterrows():
        kind = r["coefficient"][:2]
        lim_m, lim_s = (1.0, 1.0) if kind == "kA" else (0.1, 0.05)
        add(1, f"{r['platform']} {r['run']} {r['coefficient']}: |mean err| <= {lim_m}, sd <= {lim_s}",
            f"mean err {r['mean_error']:+.3f}, sd {r['sd']:.3f}", abs(r["mean_error"]) <= lim_m and r["sd"] <= lim_s)
    t1 = table1(cross)
    floor = t1[t1["method"] == "truth"].set_index(["platform", "cell"])
    for _, r in t1[t1["method"] == "proposed"].iterrows():
        fl = floor.loc[(r["platform"], "truth->" + r["cell"].split("->")[1])]
        for e in ("VE", "pE"):
            med, f = r[f"{e}_effect_median"], fl[f"{e}_effect_median"]
            add(2, f"{r['platform']} proposed {r['cell']} {e}: median >= floor - 1 pp and >= 90 %",
                f"{med:.2f} % (floor {f:.2f} %)", med >= f - 1.0 and med >= 90.0)
    for e, lim in (("VE", 75.0), ("pE", 80.0)):
        mn = pooled(cross, "proposed", e).min()
        add(2, f"proposed pooled minimum {e} >= {lim:g} %", f"{mn:.2f} %", mn >= lim)
    for e in ("VE", "pE"):
        nl = pooled(cross, "proposed", e, "nonlinear_effect_pct")
        add(3, f"proposed nonlinear-part effect {e}: median >= 99.5 %, min >= 98 %",
            f"median {nl.median():.3f} %, min {nl.min():.3f} %", nl.median() >= 99.5 and nl.min() >= 98.0)
    trad = ct[(ct["method"] == "traditional") & (ct["coefficient"] == "kA_x")]
    for _, r in trad.iterrows():
        add(4, f"{r['platform']} traditional kA_x: |err| > 50 % of |truth|, too large",
            f"{r['mean']:.2f} vs truth {r['truth']:g}",
            abs(r["mean"] - r["truth"]) > 0.5 * abs(r["truth"]) and abs(r["mean"]) > abs(r["truth"]))
    for e in ("VE", "pE"):
        nl = pooled(cross, "traditional", e, "nonlinear_effect_pct").median()
        add(4, f"traditional pooled nonlinear-part effect {e} in 90-97 %", f"{nl:.2f} %", 90.0 <= nl <= 97.0)
    dp = pooled(cross, "proposed", "VE").median()
    dt_ = pooled(cross, "traditional", "VE").median()
    add(4, "proposed pooled VE median beats traditional by >= 3 pp", f"{dp:.2f} vs {dt_:.2f} % ({dp - dt_:+.2f} pp)",
        dp - dt_ >= 3.0)
    if cross_perfect is not None and cross_worst is not None:
        for e in ("VE", "pE"):
            a, b = pooled(cross_perfect, "proposed", e).median(), pooled(cross_worst, "proposed", e).median()
            add(5, f"perfect -> worst: proposed pooled {e} median moves <= 0.3 pp", f"{a:.3f} -> {b:.3f} % "
                f"({b - a:+.3f} pp)", abs(b - a) <= 0.3)
        ca = coefficient_table(coeffs_perfect)
        cb = coefficient_table(coeffs_worst)
        ca, cb = ca[ca["method"] == "proposed"], cb[cb["method"] == "proposed"]
        d = float(np.max(np.abs(ca["mean"].to_numpy() - cb["mean"].to_numpy())))
        add(5, "perfect -> worst: proposed coefficient means move <= 0.1", f"max shift {d:.4f}", d <= 0.1)
    for _, r in prop.iterrows():
        add(6, f"{r['platform']} {r['run']} {r['coefficient']}: RMS(err/sigma) in 0.5-1.5", f"{r['rms_z']:.2f}",
            0.5 <= r["rms_z"] <= 1.5)
    return pd.DataFrame(rows)
