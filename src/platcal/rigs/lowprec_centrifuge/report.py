"""Tables, figures and the Markdown report of the rig's study (docs/lowprec-centrifuge.md §8, §11).

:func:`write_study` reads the study's tidy Monte Carlo tables (:mod:`.montecarlo`) and writes,
under one folder, ``tables/`` (CSV + Markdown + HTML), ``figures/`` (PNG, byte-stable) and
``report.md`` (tables inline, figures linked relatively, the §11 checks and the paper's claims).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ...io import atomic_write_text  # noqa: E402
from ...study.claims import ledger_markdown, ledger_note  # noqa: E402
from ...study.plots import save  # noqa: E402
from ...study.tables import frame_markdown, write_table  # noqa: E402
from .config import load_config  # noqa: E402
from .montecarlo import study_frames  # noqa: E402
from .scenario import scenarios  # noqa: E402
from .study import (PAPER_TRADITIONAL_RESIDUAL_PCT, acceptance, coefficient_table, degradation_table,  # noqa: E402
                    drop_failed, pooled, table1, y_table)
from .traces import load_trace  # noqa: E402

FMT = {"before": ".3f", "after": ".3f", "VE_before": ".2f", "VE_after": ".3f", "pE_before": ".0f", "pE_after": ".1f",
       "truth": "g", "mean": ".3f", "sd": ".3f", "mean_error": "+.3f", "mean_sigma": ".3f", "rms_z": ".2f"}


def fig_effect_vs_imprecision(deg: pd.DataFrame, meta: dict, path: Path) -> None:
    """Pooled median VE effect (X channel) against the rate and arm errors, per method."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, axis, col, unit, scale in ((axes[0], "rate", "rate_error", "relative rate error e_w (x1e-4)", 1e4),
                                       (axes[1], "arm", "arm_error_mm", "arm error dr (mm)", 1.0)):
        names = [n for n, m in meta.items() if m["axis"] in (axis, "default")]
        d = deg[deg["scenario"].isin(names)].sort_values(col)
        for meth, mk in (("proposed", "o-"), ("traditional", "s--")):
            for e, ls in (("VE", ""), ("pE", ":")):
                ax.plot(d[col] * scale, d[f"{meth}_{e}_median"], mk if not ls else mk[0] + ls,
                        label=f"{meth} {e}")
        ax.set_xlabel(unit)
        ax.set_title(f"{axis} sweep")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("pooled median effect, X channel (%)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Compensation effect against centrifuge imprecision")
    fig.tight_layout()
    save(fig, path, dpi=110, tight=False)


def fig_velocity_trace(tr: dict, path: Path) -> None:
    """dVE before and after compensation (proposed run->same run, traditional, exact coefficients),
    after = before - sum_k c_k S_k(t) along the run (the unit responses; the re-navigated INS differs
    by at most 4e-3 of before, invisible at this scale; the tables compensate about the exact floor)."""
    t = tr["t"]
    before = tr["before"][:, 0]
    sens = tr["sens"][:, :, 0]           # (4, n)
    fig, ax = plt.subplots(figsize=(9, 4.2))
    ax.plot(t, before, label="before compensation", color="k")
    for lab, c, col, ls in (("after, exact coefficients", tr["truth"], "C2", "-"),
                            ("after, traditional", tr["traditional_coeffs"], "C3", "-"),
                            ("after, proposed (run -> same run)", tr["proposed_coeffs"], "C0", "--")):
        ax.plot(t, before - c @ sens, label=lab, color=col, lw=1.2, ls=ls)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("East velocity error dVE (m/s)")
    ax.set_title(f"{tr['platform']} {tr['run']}, seed {tr['seed']}: velocity error before and after compensation")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, path, dpi=110, tight=False)


def fig_windows(tr: dict, path: Path) -> None:
    """The unwrapped heading around the first spin start with the filter's window boundaries."""
    t, psi = tr["head_t"], np.degrees(tr["head_psi"])
    fig, ax = plt.subplots(figsize=(9, 4.2))
    ax.plot(t, psi, color="k", lw=1, label="heading - gamma_0 (unwrapped)")
    sel = (tr["win_te"] >= t[0]) & (tr["win_ts"] <= t[-1])
    for a, s in zip(tr["win_ts"][sel], tr["win_spin"][sel]):
        ax.axvline(a, color="C0" if s else "C1", lw=0.8, alpha=0.8,
                   label="window start (revolution)" if s else "window start (static, 1 s)")
    for k in range(1, int(psi.max() // 360) + 1):
        ax.axhline(360 * k, color="0.7", lw=0.6, ls=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("heading - gamma_0 (deg)")
    ax.set_title("Variable-period windows: 1 s at rest, one per revolution while spinning")
    h, lab = ax.get_legend_handles_labels()
    uniq = dict(zip(lab, h))
    ax.legend(uniq.values(), uniq.keys(), fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, path, dpi=110, tight=False)


def write_study(cfg: dict, coef_path, runs_path, trace_path, out: Path, claims=None) -> None:
    """All tables, figures and report.md of the study under ``out``, from the tidy Monte Carlo
    tables (``coef.parquet``, ``runs.parquet``) and the traces of :func:`.traces.write_trace`; the report
    opens on ``claims``, the rig's ledger rows (:func:`platcal.study.claims.evaluate_rig`)."""
    out = Path(out)
    study = load_config(cfg)
    meta = scenarios(study)
    seeds = int(study.study["seeds"])
    cross_all, coeffs_all = study_frames(study, list(meta), pd.read_parquet(coef_path), pd.read_parquet(runs_path))
    cross_all, coeffs_all, n_failed = drop_failed(cross_all, coeffs_all)
    cross = cross_all[cross_all["scenario"] == "default"].drop(columns="scenario")
    coeffs = coeffs_all[coeffs_all["scenario"] == "default"].drop(columns="scenario")
    tabs = out / "tables"
    write_table(cross_all, tabs / "cross_validation", "Cross-validation, every scenario (tidy)",
                "One row per seed, platform, method, calibration run, evaluated run and final error.")
    t1 = table1(cross)
    write_table(t1, tabs / "table1", "Table-1 analogue (default scenario, X channel)",
                "Median over seeds; worst = the lowest effect of any seed; paper_* = the paper's Table 1.", FMT)
    ty = y_table(cross)
    write_table(ty, tabs / "table1_y", "Y channel (VN, pN), default scenario", "Median over seeds.", FMT)
    ct = coefficient_table(coeffs)
    write_table(ct, tabs / "coefficients", "Coefficients: proposed vs traditional vs truth (default scenario)",
                "Mean and sd over seeds; rms_z = RMS((estimate - truth)/sigma) (proposed only).", FMT)
    deg = degradation_table(cross_all, coeffs_all, meta)
    write_table(deg, tabs / "degradation", "Degradation with centrifuge imprecision",
                "Pooled medians over seeds and cells (X channel); shifts relative to the perfect centrifuge.",
                {c: ".3f" for c in deg.columns if c not in ("scenario",)})
    sub = {k: cross_all[cross_all["scenario"] == k].drop(columns="scenario") for k in ("perfect", "worst")}
    subc = {k: coeffs_all[coeffs_all["scenario"] == k].drop(columns="scenario") for k in ("perfect", "worst")}
    have = all(not v.empty for v in sub.values())
    acc = acceptance(cross, coeffs, sub["perfect"] if have else None, subc["perfect"] if have else None,
                     sub["worst"] if have else None, subc["worst"] if have else None)
    write_table(acc, tabs / "acceptance", "Spec section 11 checks", "Default scenario; item 5: perfect vs worst.")
    figs = out / "figures"
    fig_effect_vs_imprecision(deg, meta, figs / "effect_vs_imprecision.png")
    tr = load_trace(trace_path)
    fig_velocity_trace(tr, figs / "velocity_trace.png")
    fig_windows(tr, figs / "windows_heading.png")
    atomic_write_text(out / "report.md", report_md(t1, ty, ct, deg, acc, cross, seeds, n_failed, claims))


def report_md(t1, ty, ct, deg, acc, cross, seeds: int, n_failed: int = 0, claims=None) -> str:
    prop_ve = pooled(cross, "proposed", "VE").median()
    trad_ve = pooled(cross, "traditional", "VE").median()
    prop_pe = pooled(cross, "proposed", "pE").median()
    trad_pe = pooled(cross, "traditional", "pE").median()
    tr = t1[t1["method"] == "traditional"]
    pr = t1[t1["method"] == "proposed"]
    ctt = ct[(ct["method"] == "traditional")]
    kax = ctt[ctt["coefficient"] == "kA_x"]
    prv = pr["VE_effect_median"]
    ppe = pr["pE_effect_median"]
    dg = deg.set_index("scenario")
    shift_p = dg["proposed_VE_shift_pp"].abs().max()
    shift_t = dg["traditional_VE_shift_pp"].abs().max()
    n_ok, n_all = int(acc["pass"].sum()), len(acc)
    acc = acc.assign(**{"pass": acc["pass"].map({True: "yes", False: "**NO**"})})
    trad_res = ", ".join(f"{k} {v:g} %" for k, v in PAPER_TRADITIONAL_RESIDUAL_PCT.items())
    show_t1 = t1[["platform", "method", "cell", "VE_before", "VE_effect_median", "VE_effect_worst", "pE_before",
                  "pE_effect_median", "pE_effect_worst", "paper_VE_before", "paper_VE_effect", "paper_pE_before",
                  "paper_pE_effect"]]
    show_deg = deg[["scenario", "rate_error", "arm_error_mm", "stretch_mm_per_g", "proposed_VE_median",
                    "proposed_pE_median", "traditional_VE_median", "traditional_pE_median",
                    "proposed_max_coef_shift", "traditional_max_coef_shift"]]
    fmt1 = {c: ".1f" for c in show_t1.columns if "effect" in c}
    fmt1.update({"VE_before": ".2f", "pE_before": ".0f", "paper_VE_before": ".2f", "paper_pE_before": ".0f"})
    lines = [
        "# Rig 4: low-precision centrifuge (accelerometer nonlinearity)", "",
        f"Spec: `docs/lowprec-centrifuge.md`. Default scenario and the centrifuge-imprecision sweep of §2, "
        f"{seeds} seeds per scenario, 2 platforms x (2 proposed runs + 1 traditional run). Effect = 1 - |after|/|before| "
        "of the final error (paper's definition); nonlinear-part effect = 1 - |after - after_exact| / "
        "|before - after_exact| (§8).", "",
        "Truth: the platform INS navigated by RK4 at `profile.truth_steps` x the data rate through the table's "
        "motion (nonlinear mechanization on the sphere, exact platform rotation, accelerometer errors and the "
        "gyros' g-sensitive drift on the drifting platform; `insim.py`), not the filter's model; the filter's "
        "regressors come from the record's measured specific force (§12).", "",
        f"Failed identification runs (non-finite estimate, covariance not positive definite), counted and left out "
        f"of every table: {n_failed}.", "",
        "## The paper's claims", "",
        *([ledger_note(claims), "", ledger_markdown(claims), ""] if claims is not None else []),
        "What the numbers behind them say:", "",
        f"* **Proposed method compensates > 75 % of the final errors (paper: 'errors after < 25 % of before', "
        f"Table 1 effects 76-96 % velocity, 86-99 % position)**. Cell medians {prv.min():.1f}-"
        f"{prv.max():.1f} % (VE) and {ppe.min():.1f}-{ppe.max():.1f} % (pE); pooled medians {prop_ve:.1f} % / "
        f"{prop_pe:.1f} %; the exact-coefficient floor (the effect with the true coefficients) is in the table below.",
        f"* **The traditional method only reaches about 50 %** (paper §2: residual {trad_res} of the errors "
        f"before, i.e. effects 29-50 %). Eq. (2) on the simulated traditional run reaches "
        f"{tr['VE_effect_median'].min():.1f}-{tr['VE_effect_median'].max():.1f} % (VE) and "
        f"{tr['pE_effect_median'].min():.1f}-{tr['pE_effect_median'].max():.1f} % (pE); pooled {trad_ve:.1f} % "
        f"/ {trad_pe:.1f} %. The gap to the proposed method is {prop_ve - trad_ve:.1f} pp (VE); the paper's is "
        "~40 pp. How far centrifuge imprecision of the stated size moves either method: the degradation "
        "table below.",
        "* **The traditional coefficients** (mean over seeds): "
        + "; ".join(f"{r.platform} kA_x {r.mean:.1f} (truth {r.truth:g})" for r in kax.itertuples())
        + ". Eq. (2) ignores the Schuler/tilt feedback; a biased pair can still reproduce the rectified bias over "
        "13-40 g, which the effect metric does not see and the nonlinear-part effect does (table below).",
        f"* **The proposed method does not need a precise centrifuge**. Across every scenario (perfect to "
        f"gross) the proposed pooled VE median moves at most {shift_p:.2f} pp (traditional {shift_t:.2f} pp), "
        f"the proposed coefficient means at most {dg.loc[[i for i in dg.index if i != 'gross' and i != 'gross-neg'], 'proposed_max_coef_shift'].max():.3f} "
        "ug/g over the §2 sweep (perfect to worst).",
        "* Y channel (not in the paper's Table 1): compare the proposed effects with the exact-coefficient floor "
        "(table below); where |before| is within a few times the floor the effect metric is dominated by the "
        "other error sources.", "",
        f"## Spec §11 checks: {n_ok}/{n_all} pass", "", frame_markdown(acc), "",
        "## Table-1 analogue (default scenario, X channel)", "",
        "Median over seeds [worst seed in the *_worst columns]; `paper_*` = the paper's Table 1 (its tests 1-4 = "
        "P1 run1, P1 run2, P2 run1, P2 run2). The paper's before-values come from real platforms; ours from the "
        "spec's coefficients.", "", frame_markdown(show_t1, fmt1), "",
        "## Coefficients: proposed vs traditional vs truth", "", frame_markdown(ct, FMT), "",
        "## Degradation with centrifuge imprecision", "",
        "Pooled medians (X channel, % effect) and the largest shift of a coefficient mean from the perfect "
        "centrifuge (ug/g or ug/g^2).", "", frame_markdown(show_deg, {c: ".4g" for c in show_deg.columns}), "",
        "## Y channel (default scenario)", "", frame_markdown(ty, {c: ".2f" for c in ty.columns}), "",
        "## Figures", "",
        "![effect against centrifuge imprecision](figures/effect_vs_imprecision.png)", "",
        "![velocity error before and after compensation](figures/velocity_trace.png)", "",
        "![revolution windows on the heading](figures/windows_heading.png)", "",
        "Tables as CSV/HTML: `tables/` (the tidy cross-validation of every scenario is "
        "`tables/cross_validation.csv`).", ""]
    return "\n".join(lines)
