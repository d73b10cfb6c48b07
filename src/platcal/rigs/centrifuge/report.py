"""The centrifuge's tables and report of its Monte Carlo study.

The paper's Table 2 over one run and over the replicates, the sweep summary and
``results/centrifuge/report.md`` (docs/centrifuge-model.md §7-11); the figures, whose names
:data:`FIGURES` lists, are drawn by :mod:`.figures`, so that the tables, report and claims jobs
import no figure library (issue 22 item 4). Tables are written three ways
by :func:`platcal.study.tables.write_table`: CSV (full precision, for machines), Markdown and
HTML (for people; the HTML pages are what ``snakemake --report`` shows inline). The statistics
and the generic figures come from :mod:`platcal.study`; this module adds what is the
centrifuge's own: Table 2, the paper's numbers, the gyro/accelerometer labels and the reading.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ...estimation.consistency import nees_band
from ...errors import InputError
from ...io import atomic_to_csv, atomic_write_text, check_writable
from ...log import job_logger
from ...study.claims import ledger_section, read_ledger
from ...study.stats import per_coefficient, select_cell, summary, with_timing
from ...study.tables import frame_html, frame_markdown, write_table
from .catalogue import load_catalogue
from .compare import which_estimator
from .study import CentrifugeMonteCarlo, check_study
from .tables import table2_frame

NOISE = CentrifugeMonteCarlo.noise
GROUP_TITLES = {"gyro": "Gyro", "accel": "Accelerometer"}
"""The centrifuge's coefficient groups (``group_of``) as figure titles say them."""
CONVERGENCE_STATES = ("DF_z", "DIS_x", "DII_x", "DOS_z", "k1_z", "theta_py")
"""Weakest gyro coefficients of docs/centrifuge-model.md §11, and two accelerometer ones."""

TABLES = ("table2_single", "table2_montecarlo", "summary")
FIGURES = {
    "boxplot": "rel_err_boxplot.png",
    "rms_vs_noise": "rms_vs_noise.png",
    "convergence": "convergence.png",
    "correlation": "correlation.png",
    "nees": "nees_hist.png",
    "paper_vs_mc": "paper_vs_montecarlo.png",
}
"""Figure key -> file name under ``results/figures``."""
COMPARE_TABLES = ("compare_summary.csv", "compare_summary.md", "compare_summary.html", "compare_rms.csv")
"""The estimator comparison's tables under ``results/centrifuge/tables`` (:mod:`.compare`)."""
COMPARE_FIGURES = {"cost": "compare_cost.png", "nees": "compare_nees.png"}
"""The estimator comparison's figures under ``results/centrifuge/figures``."""

T2_FMT = {"truth": "g", "paper_estimate": "g", "paper_rel_err_pct": ".2f", "estimate": ".6g", "sigma": ".3g",
          "error": ".4g", "rel_err_pct": ".3f"}
T2MC_FMT = {"truth": "g", "mean_estimate": ".6g", "mean_rel_err_pct": ".3f", "std_rel_err_pct": ".3f",
            "rms_rel_err_pct": ".3f", "mean_sigma": ".3g", "mean_rel_sigma_pct": ".3f", "paper_rel_err_pct": ".2f",
            "paper_z": ".2f", "n": "d"}
SUMMARY_FMT = {c: ".3f" for c in ("max_rms_rel_err_pct_gyro", "median_rms_rel_err_pct_gyro",
                                  "max_rms_rel_err_pct_accel", "median_rms_rel_err_pct_accel")}
SUMMARY_FMT.update({"mean_nees": ".1f", "median_nees": ".1f", "share_in_band": ".2f", "wall_s_per_run": ".2f",
                    "sigma_a_ug": "g", "runs": "d", "nees_dof": "d", "failed_updates": "d", "failed_runs": "d",
                    "threads": "d"})


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


def resolve_cell(cfg: dict, which: str) -> dict:
    """``study.single`` or ``study.paper`` with the noise level filled in (null: noise.sigma_a_ug)."""
    c = dict(cfg["study"][which])
    if c.get("sigma_a_ug") is None:
        c["sigma_a_ug"] = float(cfg["noise"]["sigma_a_ug"])
    return c


def _named(df: pd.DataFrame) -> pd.DataFrame:
    """A study table with the generic ``noise`` column called by the centrifuge's name."""
    return df.rename(columns={"noise": NOISE.name})


def write_tables(cfg: dict, coef: pd.DataFrame, runs: pd.DataFrame, timing: pd.DataFrame,
                 single_estimates: pd.DataFrame, single_info: dict, out_dir) -> dict[str, pd.DataFrame]:
    """``table2_single``, ``table2_montecarlo`` and ``summary`` as CSV, Markdown and HTML.

    ``summary.csv`` holds no wall time (it is identical whatever the machine or --cores);
    the wall time per run is in ``summary_timing.csv`` and in the Markdown and HTML versions.
    """
    out = Path(out_dir)
    paper = resolve_cell(cfg, "paper")
    t2 = table2_frame(single_estimates)
    write_table(t2, out / "table2_single",
           f"Table 2, one run: scheme {single_info['scheme']}, sigma_a = {single_info['sigma_a_ug']:g} ug, "
           f"{single_info['estimator']}, replicate {single_info['replicate']}",
           "Relative error is eq. 28, (estimate - truth) / truth x 100 %. Paper: Xu & Zhang (2017), Table 2. "
           f"sigma: the filter's 1-sigma. NEES of this run {single_info['nees']:.1f} (45 dof).", T2_FMT)
    t2mc = table2_montecarlo(coef, paper["scheme"], paper["sigma_a_ug"], paper["estimator"])
    n = int(t2mc["n"].min())
    write_table(t2mc, out / "table2_montecarlo",
           f"Table 2 over {n} replicates: scheme {paper['scheme']}, sigma_a = {paper['sigma_a_ug']:g} ug, "
           f"{paper['estimator']}",
           "Relative errors in %, over replicates; mean_sigma: mean predicted 1-sigma (coefficient's unit); "
           "mean_rel_sigma_pct: it relative to |truth|; paper_z = (paper rel. err. - our mean) / our std.",
           T2MC_FMT)
    summ = summary(coef, runs)
    timed = _named(with_timing(summ, timing))
    summ = _named(summ)
    atomic_to_csv(summ, out / "summary.csv")
    atomic_to_csv(timed[["scheme", NOISE.name, "estimator", "wall_s_per_run", "threads"]],
                  out / "summary_timing.csv")
    lo, hi = nees_band(int(runs["nees_dof"].iloc[0]))
    note = (f"RMS relative error (%) over replicates, largest and median over the group's coefficients; "
            f"NEES of the 45 coefficient errors, share_in_band: runs inside the 95 % chi-square(45) band "
            f"[{lo:.1f}, {hi:.1f}]; wall_s_per_run: wall time per replicate (machine-dependent).")
    shown = timed.drop(columns=["nees_dof"])
    atomic_write_text(out / "summary.md", "# Summary per scheme x noise level x estimator\n\n" + note + "\n\n"
                      + frame_markdown(shown, SUMMARY_FMT))
    atomic_write_text(out / "summary.html", frame_html(shown, "Summary per scheme x noise level x estimator",
                                                       note, SUMMARY_FMT))
    return {"table2_single": t2, "table2_montecarlo": t2mc, "summary": summ, "summary_timed": timed}


def reading(cfg: dict, t2: pd.DataFrame, t2mc: pd.DataFrame, summ: pd.DataFrame) -> str:
    """A short reading of the results, generated from the numbers (no hand-written claims)."""
    paper = resolve_cell(cfg, "paper")
    lines = []
    g = t2[t2["coefficient"].str.startswith("D")]
    a = t2[~t2["coefficient"].str.startswith("D")]
    lines.append(
        f"- **One run** (Table 2 layout): largest |relative error| gyro {g['rel_err_pct'].abs().max():.2f} % "
        f"(paper {g['paper_rel_err_pct'].abs().max():.2f} %), accelerometer {a['rel_err_pct'].abs().max():.3f} % "
        f"(paper {a['paper_rel_err_pct'].abs().max():.2f} %).")
    gm = t2mc[t2mc["group"] == "gyro"].sort_values("rms_rel_err_pct", ascending=False)
    am = t2mc[t2mc["group"] == "accel"].sort_values("rms_rel_err_pct", ascending=False)
    lines.append(
        f"- **Monte Carlo** ({int(t2mc['n'].min())} replicates, scheme {paper['scheme']}, sigma_a = "
        f"{paper['sigma_a_ug']:g} ug, {paper['estimator']}): the weakest gyro coefficients by RMS relative error "
        f"are {', '.join(f'{r.coefficient} ({r.rms_rel_err_pct:.2f} %)' for r in gm.head(4).itertuples())}; "
        f"the weakest accelerometer ones "
        f"{', '.join(f'{r.coefficient} ({r.rms_rel_err_pct:.3f} %)' for r in am.head(3).itertuples())}.")
    z = t2mc["paper_z"].replace([np.inf, -np.inf], np.nan).dropna()
    if len(z):
        lines.append(
            f"- **Paper against our spread**: {int((z.abs() <= 2).sum())} of {len(z)} paper relative errors lie "
            f"within 2 of our standard deviations of our mean; the largest |z| is {z.abs().max():.1f} "
            f"({t2mc.loc[z.abs().idxmax(), 'coefficient']}). The paper's errors are one run each, and the paper "
            "does not give its dwell time or noise levels (spec section 8), so this is a plausibility check.")
    cell = summ[(summ["scheme"] == paper["scheme"]) & np.isclose(summ["sigma_a_ug"], paper["sigma_a_ug"])]
    for r in cell.itertuples():
        lines.append(f"- **{r.estimator}** at that cell: mean NEES {r.mean_nees:.1f} (45 expected), "
                     f"{100 * r.share_in_band:.0f} % of runs inside the 95 % chi-square(45) band.")
    best = summ.sort_values("max_rms_rel_err_pct_gyro").groupby(["sigma_a_ug", "estimator"], sort=False).head(1)
    best = best[np.isclose(best["sigma_a_ug"], paper["sigma_a_ug"])]
    for r in best.itertuples():
        lines.append(f"- **Schemes** ({r.estimator}, sigma_a = {r.sigma_a_ug:g} ug): the smallest largest-gyro RMS "
                     f"relative error is {r.scheme}'s, {r.max_rms_rel_err_pct_gyro:.2f} %; "
                     + ", ".join(f"{s.scheme} {s.max_rms_rel_err_pct_gyro:.2f} %"
                                 for s in summ[(summ['estimator'] == r.estimator)
                                               & np.isclose(summ['sigma_a_ug'], r.sigma_a_ug)].itertuples()) + ".")
    hi_noise = summ["sigma_a_ug"].max()
    lo_noise = summ["sigma_a_ug"].min()
    if hi_noise > lo_noise:
        s = summ[summ["scheme"] == paper["scheme"]]
        for e in dict.fromkeys(s["estimator"]):
            d = s[s["estimator"] == e].set_index("sigma_a_ug")
            lines.append(f"- **Noise** ({paper['scheme']}, {e}): largest gyro RMS relative error "
                         + ", ".join(f"{v:.2f} % at {k:g} ug" for k, v in d["max_rms_rel_err_pct_gyro"].items())
                         + "; mean NEES " + ", ".join(f"{v:.0f}" for v in d["mean_nees"]) + ".")
    return "\n".join(lines) + "\n"


def write_report(cfg: dict, tables_dir, figures_dir, out_path, timing: pd.DataFrame | None = None,
                 claims: pd.DataFrame | None = None) -> None:
    """``results/report.md``: the rig's claims ledger rows first (``claims``, as the ``claims``
    rule wrote them to ``results/centrifuge/claims.csv``; none: no section), then what was run,
    the reading, tables inline, figures linked."""
    tables_dir, figures_dir, out_path = Path(tables_dir), Path(figures_dir), Path(out_path)
    t2 = pd.read_csv(tables_dir / "table2_single.csv")
    t2mc = pd.read_csv(tables_dir / "table2_montecarlo.csv")
    summ = pd.read_csv(tables_dir / "summary.csv")
    st = cfg["study"]
    rel = lambda p: os.path.relpath(p, out_path.parent)  # noqa: E731
    parts = ["# platcal Monte Carlo study: centrifuge identification of 45 platform error coefficients", "",
             "Written by the Snakemake workflow (`snakemake --cores 2`). Model: Xu & Zhang (2017) and "
             "the project's spec. All numbers below come from this run's result files.", "",
             *([ledger_section(claims), ""] if claims is not None else []),
             "## Study", "",
             f"- schemes: {', '.join(sorted(set(summ['scheme']), key=list(summ['scheme']).index))}",
             f"- accelerometer noise sigma_a: {', '.join(f'{v:g}' for v in st['sigma_a_ug'])} ug per sample; "
             f"ARW {cfg['noise']['arw_deg_rth']:g} deg/sqrt(h); sigma_set {cfg['noise']['sigma_set_arcsec']:g} arcsec",
             f"- estimators: {', '.join(f'{k} ({v})' for k, v in st['estimators'].items())}",
             f"- replicates per cell: {st['replicates']}; root seed {cfg['seed']}", ""]
    if timing is not None and len(timing):
        parts += [f"- compute: {timing['wall_s'].sum():.0f} s of job wall time over {len(timing)} cells "
                  f"({timing['wall_s_per_run'].median():.2f} s per run, median)", ""]
    parts += ["## Reading", "", reading(cfg, pd.read_csv(tables_dir / "table2_single.csv"), t2mc, summ), ""]
    compare = tables_dir / "compare_summary.csv"
    if compare.exists():  # the estimator comparison (study.compare)
        parts += [which_estimator(cfg, pd.read_csv(compare)), _body(tables_dir / "compare_summary.md")]
        for k, f in COMPARE_FIGURES.items():
            label = {"cost": "Error against cost per estimator and noise level",
                     "nees": "NEES histograms per estimator"}[k]
            parts.append(f"- [{label}]({rel(figures_dir / f)})")
        parts.append("")
    parts += ["## Figures", ""]
    captions = {
        "boxplot": "Relative error per coefficient by scheme (paper's errors: red stars)",
        "rms_vs_noise": "RMS relative error against noise level, per group, scheme and estimator",
        "convergence": "Convergence of selected estimates with +-3 sigma bands (one run)",
        "correlation": "|correlation| of the final covariance (one run)",
        "nees": "NEES histogram against the chi-square(45) density, per estimator",
        "paper_vs_mc": "The paper's relative error against our Monte Carlo mean +- std",
    }
    for k, f in FIGURES.items():
        parts.append(f"- [{captions[k]}]({rel(figures_dir / f)})")
    parts += ["", "## Table 2, one run", "", _body(tables_dir / "table2_single.md"),
              "## Table 2 over the replicates", "", _body(tables_dir / "table2_montecarlo.md"),
              "## Summary", "", _body(tables_dir / "summary.md"),
              "CSV versions (full precision) are beside the Markdown files in "
              f"`{rel(tables_dir)}/`.", ""]
    del t2
    atomic_write_text(out_path, "\n".join(parts))


def _body(md: Path) -> str:
    """A Markdown table file without its title line."""
    lines = md.read_text().splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    return "\n".join(lines).strip() + "\n"


def tables_job(cfg, coef_path, runs_path, timing_path, single_dir, out_dir, log_path=None) -> None:
    """Rule body: read the collected results and the single run; write the tables."""
    lg = job_logger(log_path)
    cfg = check_study(cfg)
    coef = pd.read_parquet(coef_path)
    runs = pd.read_parquet(runs_path)
    timing = pd.read_csv(timing_path)
    single_dir = Path(single_dir)
    est = pd.read_csv(single_dir / "estimates.csv")
    info = json.loads((single_dir / "run.json").read_text())
    lg.info("tables from %d rows (%d runs) -> %s", len(coef), len(runs), out_dir)
    write_tables(cfg, coef, runs, timing, est, info, out_dir)
    lg.info("done")


def report_from_results(cfg: dict, results) -> Path:
    """Rewrite ``<results>/report.md`` from a results folder's tables (``platcal report``), opening
    on its ``claims.csv`` when the workflow wrote one."""
    res = Path(results)
    if not res.is_dir():
        raise InputError("--results", f"no such folder: {res}; give the results folder of a finished study "
                         "(snakemake --cores 2 results/centrifuge/report.md writes one)")
    for need in (res / "montecarlo" / "timing.csv", res / "tables"):
        if not need.exists():
            raise InputError("--results", f"{res} holds no {need.relative_to(res)}: it is not the results folder "
                             "of a finished centrifuge study (snakemake --cores 2 results/centrifuge/report.md)")
    check_writable(res / "report.md", "--results")
    timing = pd.read_csv(res / "montecarlo" / "timing.csv")
    claims = read_ledger(res / "claims.csv") if (res / "claims.csv").exists() else None
    write_report(check_study(cfg), res / "tables", res / "figures", res / "report.md", timing, claims)
    return res / "report.md"
