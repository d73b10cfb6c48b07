"""The multiposition study's tables, figures and report (docs/multiposition-1g.md §8, §13, §15).

:func:`report_job`, the body of the workflow's rule ``multiposition_report``, reads the collected
tidy tables ``results/multiposition/montecarlo/{coef,runs}.parquet`` and ``timing.csv``, the scheme
checks, the design and §13's extension results, and writes ``tables/``, ``figures/`` and
``report.md``. Apart from :mod:`.study` (the workflow's set-up) so that only this job loads the
figures' libraries.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ...estimation.consistency import chi2_quantile
from ...io import atomic_write_text
from ...study.claims import ledger_section, read_ledger
from ...study.nees_figure import nees_histogram
from ...study.plots import finish, plt, save as save_figure
from ...study.stats import CELL, select_cell, with_timing
from ...study.tables import frame_markdown, write_table
from .extension import SPEC_RANGES, spread_summary
from .study import load, spec_cell


SPEC_TABLE = {  # §15: exact rank x=0 / truth, static rank, max sigma/|truth| %
    "S8": ("27 / 27", 27, "0.63"), "SIX": ("27 / 27", 27, "0.75"), "T1": ("27 / 27", 27, "1.42"),
    "TET4": ("27 / 27", 27, "0.88"), "BETA4": ("27 / 27", 27, "0.88"), "ROLL4": ("27 / 27", 21, "185-198"),
    "ROLL8": ("27 / 27", 21, "185-198"), "CONE4": ("24 / 27", 21, "208"), "PAIR4": ("27 / 27", 15, "175"),
    "AZ4": ("24 / 24", 9, "480"),
}


def in_study_order(df: pd.DataFrame, raw: dict) -> pd.DataFrame:
    """Rows of a collected tidy table (sorted by name) in the study's order: ``study.schemes``,
    then noise level, then ``study.estimators``; the order within a run is kept."""
    st = raw["study"]
    key = pd.DataFrame({"s": df["scheme"].map({n: i for i, n in enumerate(st["schemes"])}).to_numpy(),
                        "n": df["noise"].to_numpy(),
                        "e": df["estimator"].map({n: i for i, n in enumerate(st["estimators"])}).to_numpy()})
    return df.iloc[key.sort_values(["s", "n", "e"], kind="stable").index.to_numpy()].reset_index(drop=True)


def per_replicate(coef: pd.DataFrame) -> pd.DataFrame:
    """Largest |relative error| (%) of each group (gyro, accel) per run, from the tidy ``coef`` table."""
    return (coef.assign(abs_rel=coef["rel_err_pct"].abs())
            .groupby(CELL + ["replicate", "group"], sort=False)["abs_rel"].max().unstack("group").reset_index())


def nees_bound(dof: int, level: float = 0.999) -> float:
    """The chi-square(dof) ``level`` quantile (51.18 for 24 and 99.9 %)."""
    return chi2_quantile(level, dof)


def mc_summary(coef: pd.DataFrame, runs: pd.DataFrame, timing: pd.DataFrame) -> pd.DataFrame:
    """Per scheme x noise x estimator, from the collected tidy tables (results/multiposition/
    montecarlo/): median and worst of the largest gyro / accelerometer |relative error| per run,
    mean NEES of the 24 coefficients, the share of runs above the chi-square(24) 99.9 % bound,
    failed runs, measurement linearisations per update and wall seconds per run (simulation and
    filter, at the job's threads; the only machine-dependent column)."""
    per = per_replicate(coef).merge(runs, on=CELL + ["replicate"], how="left")
    g = per.groupby(CELL, sort=False)
    bound = nees_bound(int(runs["nees_dof"].iloc[0]))
    out = pd.DataFrame({
        "passes": g["passes"].first(), "seeds": g.size(),
        "gyro_max_rel_err_median_pct": g["gyro"].median(), "gyro_max_rel_err_worst_pct": g["gyro"].max(),
        "accel_max_rel_err_median_pct": g["accel"].median(), "accel_max_rel_err_worst_pct": g["accel"].max(),
        "mean_nees_24": g["nees"].mean(),
        "share_nees_above_99.9_pct": g["nees"].apply(lambda v: float((v > bound).mean() * 100)),
        "failed_runs": g["failed"].sum().astype(int),
        "linearisations_per_update": g["linearisations"].mean(),
    }).reset_index()
    out = with_timing(out, timing).rename(columns={"wall_s_per_run": "seconds_per_run"})
    return out.rename(columns={"noise": "sigma_a_ug"})


def rank_frame(results: list[dict]) -> pd.DataFrame:
    rows = []
    for r in results:
        spec = SPEC_TABLE.get(r["scheme"], ("-", None, "-"))
        rows.append({"scheme": r["scheme"], "K": len(r["positions"]),
                     "exact rank (x=0 / truth)": f"{r['exact_rank_nominal']} / {r['exact_rank_truth']}",
                     "spec exact": spec[0], "static rank": r["static_rank"],
                     "spec static": spec[1] if spec[1] is not None else "-",
                     "max sigma/|truth| %": r["max_rel_sigma_pct"], "spec %": spec[2],
                     "weakest": r["max_rel_sigma_coefficient"], "verdict": r["verdict"]["decision"],
                     "static null space": ", ".join(r["null_space"]) or "-"})
    return pd.DataFrame(rows)


def extension_frame(sigma_rows: list[dict], centrifuge_json: str | None) -> pd.DataFrame:
    """1 g sigma/|truth| of every higher-order term beside the centrifuge's Table 1 (posterior sigma)."""
    df = pd.DataFrame(sigma_rows)[["name", "term", "truth", "sigma", "rel_sigma_pct"]]
    df = df.rename(columns={"sigma": "sigma_1g", "rel_sigma_pct": "rel_sigma_1g_pct"})
    cen = {}
    if centrifuge_json and Path(centrifuge_json).exists():
        res = json.loads(Path(centrifuge_json).read_text())
        cen = {c["name"]: c for c in res["coefficients"]}
    df["rel_sigma_centrifuge_pct"] = [cen[n]["posterior_sigma"] / abs(cen[n]["truth"]) * 100 if n in cen else np.nan
                                      for n in df["name"]]
    df["ratio_1g_over_centrifuge"] = df["rel_sigma_1g_pct"] / df["rel_sigma_centrifuge_pct"]
    return df


# ------------------------------------------------------------------ figures

def fig_ranks(rf: pd.DataFrame, path) -> None:
    fig, ax = plt.subplots(figsize=(8, 4))
    col = ["tab:green" if v == "accept" else "tab:red" for v in rf["verdict"]]
    ax.bar(rf["scheme"], rf["max sigma/|truth| %"], color=col)
    for i, (r, s) in enumerate(zip(rf["max sigma/|truth| %"], rf["static rank"])):
        ax.text(i, r * 1.15, f"static {s}", ha="center", fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("covariance-only max sigma/|truth| (%)")
    ax.set_xlabel("scheme")
    ax.set_title("Scheme check: accepted (green) and refused (red), static rank above the bars")
    ax.bar([0], [0], color="tab:green", label="accept")
    ax.bar([0], [0], color="tab:red", label="refuse")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)


def fig_montecarlo(coef: pd.DataFrame, path) -> None:
    per = per_replicate(coef)
    keys = list(per.groupby(CELL, sort=False).groups)
    fig, ax = plt.subplots(figsize=(max(8, 0.6 * len(keys)), 4.5))
    data = [select_cell(per, s, a, e)["gyro"] for s, a, e in keys]
    ax.boxplot(data)
    ax.set_xticks(range(1, len(keys) + 1), [f"{s}\n{a:g} ug\n{e}" for s, a, e in keys], fontsize=7)
    ax.axhline(1.5, color="grey", ls="--", lw=0.8, label="spec: S8 median <= 1.5 % (5 ug, 1 pass)")
    finish(fig, ax, path, "scheme / sigma_a / estimator", "largest gyro |relative error| per seed (%)",
           "Monte Carlo: largest gyro relative error per seed")


def fig_extension(ef: pd.DataFrame, path) -> None:
    fig, ax = plt.subplots(figsize=(11, 4.5))
    x = np.arange(len(ef))
    ax.bar(x - 0.2, ef["rel_sigma_1g_pct"], 0.4, label="1 g multi-position (24 random positions x 60 s)")
    ax.bar(x + 0.2, ef["rel_sigma_centrifuge_pct"], 0.4, label="centrifuge, Table 1 (6 positions x 60 s)")
    ax.set_xticks(x, ef["name"], rotation=90, fontsize=8)
    ax.set_yscale("log")
    finish(fig, ax, path, "higher-order coefficient", "covariance-only sigma/|truth| (%)",
           "Why a centrifuge: higher-order terms at 1 g vs on the centrifuge")


def fig_extension_draws(spread: pd.DataFrame, path) -> None:
    """§13's covariance-only sigma/|truth| ranges as a distribution over the study's random draws
    (``extension/spread.csv``: one row per draw and group, ``min_pct``, ``max_pct``, %): per
    group, each draw's two endpoints against the spec's one-draw range and its +-20 % band
    (docs/multiposition-1g.md §13, §15 item 6, §16)."""
    groups = list(SPEC_RANGES)
    fig, axes = plt.subplots(1, len(groups), figsize=(12, 4))
    jitter = np.random.default_rng(0).uniform(-0.08, 0.08, len(spread))  # fixed: identical bytes on rerun
    for ax, g in zip(axes, groups):
        d = spread[spread["group"] == g]
        j = jitter[: len(d)]
        ax.scatter(np.zeros(len(d)) + j, d["min_pct"], s=14, color="tab:blue", label="min over the group, per draw")
        ax.scatter(np.ones(len(d)) + j, d["max_pct"], s=14, color="tab:orange", label="max over the group, per draw")
        for x, v in zip((0, 1), SPEC_RANGES[g]):
            ax.fill_between([x - 0.3, x + 0.3], 0.8 * v, 1.2 * v, color="grey", alpha=0.25,
                            label="spec's endpoint +-20 %" if x == 0 else None)
            ax.hlines(v, x - 0.3, x + 0.3, color="k", lw=1.2, label="spec's endpoint (one draw)" if x == 0 else None)
        ax.set_xticks([0, 1], ["min", "max"])
        ax.set_xlabel("endpoint of the range")
        ax.set_title(g)
    axes[0].set_ylabel("covariance-only sigma/|truth| (%)")
    axes[-1].legend(fontsize=7, loc="best")
    n = spread["draw"].nunique()
    fig.suptitle(f"§13 sigma ranges over {n} random draws of 24 positions (each dot one draw)")
    fig.tight_layout()
    save_figure(fig, path)


def save_figures(outdir: Path, rf: pd.DataFrame, coef: pd.DataFrame, runs: pd.DataFrame, ef: pd.DataFrame,
                 spread: pd.DataFrame | None = None) -> None:
    """``ranks.png``, ``montecarlo.png``, ``nees.png`` (NEES against chi-square(24), per estimator),
    ``extension.png`` and, with ``spread``, ``extension_draws.png`` (§13 over the draws; PNG without
    metadata, written atomically)."""
    fig_ranks(rf, outdir / "ranks.png")
    fig_montecarlo(coef, outdir / "montecarlo.png")
    nees_histogram(runs, outdir / "nees.png")
    fig_extension(ef, outdir / "extension.png")
    if spread is not None:
        fig_extension_draws(spread, outdir / "extension_draws.png")


# ------------------------------------------------------------------ report

def _rank_reading(rf: pd.DataFrame) -> str:
    """Plain statements of where the ranks equal or differ from the spec's table (computed, not assumed)."""
    known = rf[rf["scheme"].isin(list(SPEC_TABLE))]
    st_ok = [r.scheme for r in known.itertuples() if r._5 == r._6]
    st_bad = [f"{r.scheme} ({r._5} vs {r._6})" for r in known.itertuples() if r._5 != r._6]
    ex_ok = [r.scheme for r in known.itertuples() if r._3 == r._4]
    ex_bad = [f"{r.scheme} ({r._3} vs {r._4})" for r in known.itertuples() if r._3 != r._4]
    full_exact_refused = [r.scheme for r in rf.itertuples() if r._3.split(" / ")[0] == "27" and r.verdict == "refuse"
                          and r._5 < 27]
    text = (f"Static rank as in the spec's table for {', '.join(st_ok) or 'none'}"
            f"{'; differs for ' + ', '.join(st_bad) if st_bad else ''}. Exact Lie rank (x = 0 / truth) as in the "
            f"spec for {', '.join(ex_ok) or 'none'}{'; differs for ' + ', '.join(ex_bad) if ex_bad else ''}.")
    if "ROLL4" in set(rf["scheme"]):
        text += f" ROLL4's static null space: {rf.set_index('scheme').loc['ROLL4', 'static null space']}."
    if full_exact_refused:
        text += (f" Full exact rank but refused (static rank short, sigma > threshold): {', '.join(full_exact_refused)}"
                 " - the Earth-rate sweep of a dwell fills the exact rank without usable information.")
    return text


def spread_lines(spread: list[dict] | None) -> list[str]:
    """Report paragraph on the §13 sigma ranges over further random draws (§16)."""
    sm = spread_summary(spread or [])
    if not sm["draws"]:
        return []
    cells = []
    for g, d in sm["groups"].items():
        lo, hi = SPEC_RANGES[g]
        cells.append(f"{g}: min {d['min']['median']:.3g} % (10-90 %: {d['min']['p10']:.3g}-{d['min']['p90']:.3g}; "
                     f"spec {lo:g}), max {d['max']['median']:.3g} % ({d['max']['p10']:.3g}-{d['max']['p90']:.3g}; "
                     f"spec {hi:g})")
    return [f"Over {sm['draws']} further draws of 24 positions (same settings, seeds {spread[0]['seed']}-"
            f"{spread[-1]['seed']}), median of each endpoint and its 10-90 % range: " + "; ".join(cells) + ". "
            f"Draws with all eight endpoints within 20 % of the spec's: {sm['share_all_within_20pct'] * 100:.0f} %; "
            f"the medians over the draws {'are all' if sm['medians_within_20pct'] else 'are NOT all'} within 20 % of "
            f"the spec's endpoints (largest deviation: {sm['largest_median_dev'][0]} {sm['largest_median_dev'][1]:+.0%}). "
            "The spec's ranges are one unstated draw's and the spread is the draw's: the ledger judges section 15 "
            "item 6 on the medians over the draws (claims ext_*_min, ext_*_max) and on the share of single draws "
            "(ext_draws_within_20pct) (docs/multiposition-1g.md §16).", "",
            "![the §13 sigma ranges over the draws](figures/extension_draws.png)", ""]


def estimator_lines(summ: pd.DataFrame) -> list[str]:
    """Report paragraph: mean NEES and cost of every estimator variant per scheme at the lowest
    noise level (issue 9 item 5), computed from the summary."""
    if summ.empty or summ["estimator"].nunique() < 2:
        return []
    lo = summ[summ.sigma_a_ug == summ.sigma_a_ug.min()]
    parts = []
    for sc, d in lo.groupby("scheme", sort=False):
        base = d["seconds_per_run"].iloc[0]
        parts.append(f"{sc}: " + ", ".join(f"{r.estimator} {r.mean_nees_24:.1f} (x{r.seconds_per_run / base:.1f})"
                                           for r in d.itertuples()))
    return [f"Estimators at {lo.sigma_a_ug.iloc[0]:g} ug, mean NEES of the 24 coefficients (24 expected) and wall "
            f"time per run (simulation included) relative to the first variant: " + "; ".join(parts) + ". The one-pass EKF's excess NEES on "
            "skew schemes is its early linearisation (docs/multiposition-1g.md §16); a second pass removes it, the "
            "iterated update does not.", ""]


def summary_formats(summ: pd.DataFrame) -> dict[str, str]:
    """Three significant digits for the summary's statistics, linearisations and seconds."""
    return {c: ".3g" for c in summ.columns if c.endswith("pct") or c.startswith("mean")
            or c in ("linearisations_per_update", "seconds_per_run")}


def item4_lines(summ: pd.DataFrame, cell: tuple[str, float, str | None]) -> list[str]:
    """Report paragraph: spec §15 item 4 (S8, 5 ug, the one-pass EKF, 20 seeds) on the sweep's
    cell, or why it cannot be; the ledger (data/claims.yaml) judges it against the bounds."""
    scheme, level, est = cell
    row = summ[(summ.scheme == scheme) & np.isclose(summ.sigma_a_ug, level) & (summ.estimator == est)]
    if est is None or row.empty:
        return [f"Spec section 15 item 4 (S8 at {level:g} ug, the one-pass EKF) is not checked: that cell is not in "
                "this study's sweep (study.schemes, study.sigma_a_ug, study.estimators).", ""]
    r = row.iloc[0]
    seeds = "" if int(r.seeds) == 20 else f" (the spec's check is over 20 seeds; this study has {int(r.seeds)})"
    return [f"S8 at {r.sigma_a_ug:g} ug, {est} (EKF, one pass), {int(r.seeds)} seeds: largest gyro error median "
            f"{r.gyro_max_rel_err_median_pct:.2f} % (worst {r.gyro_max_rel_err_worst_pct:.2f} %), largest "
            f"accelerometer error worst {r.accel_max_rel_err_worst_pct:.3f} %, mean NEES {r.mean_nees_24:.1f} "
            f"(spec's implementation: 1.06 % median, 0.66-1.80 %, <= 0.141 %, NEES 28.9). The spec's bounds of "
            f"section 15 item 4 (1.5 %, 2.5 %, 0.2 %, NEES 20-35) are the claims s8_gyro_median, s8_gyro_worst, "
            f"s8_accel_worst and s8_mean_nees of the ledger{seeds}.", ""]


def write_report(out: Path, rf, summ, design, ext_ranks, ef, seconds_note: str = "", spread=None,
                 item4_cell: tuple[str, float, str | None] = ("S8", 5.0, "ekf1"),
                 claims: pd.DataFrame | None = None) -> None:
    """``report.md``: the multiposition section of the study report, opening on the rig's claims
    ledger rows (``claims``, from :func:`platcal.study.claims.evaluate_rig`; none: no section).
    ``item4_cell``: the cell of spec §15 item 4 (:func:`spec_cell`)."""
    fm = {"max sigma/|truth| %": ".3g"}
    lines = ["# Rig 2: 1 g multi-position self-test (docs/multiposition-1g.md)", "",
             "A three-gimbal platform (|beta| <= 30 deg) turned to K positions at 1 g, a 27-state EKF on three "
             "accelerometers and three gimbal angle sensors, and a rank + covariance check that accepts or refuses "
             "a scheme before the test. Defaults of spec section 10. " + seconds_note, ""]
    if claims is not None:
        lines += [ledger_section(claims), ""]
    lines += ["## Scheme check: ranks and covariance-only sigma", "",
             frame_markdown(rf, fm), "", "![scheme check](figures/ranks.png)", "",
             _rank_reading(rf), "",
             "## Monte Carlo (seeds x schemes x noise x estimators)", "",
             "Largest |relative error| of each group per run (median and worst over the seeds), mean NEES of the 24 "
             "coefficients (24 expected) and the share of runs above the chi-square(24) 99.9 % bound "
             f"({nees_bound(24):.1f}); seconds per run is the cell's wall time (simulation and filter) per replicate "
             "at the job's threads. Every cell is a job of the generic Monte Carlo runner; replicate r of a scheme "
             "and noise level is the same record for every estimator (docs/multiposition-1g.md §16).", "",
             frame_markdown(summ, summary_formats(summ)), "",
             "![Monte Carlo](figures/montecarlo.png) ![NEES](figures/nees.png)", ""]
    lines += item4_lines(summ, item4_cell)
    lines += estimator_lines(summ)
    lines += ["## GA design (A-optimal) against S8 and TET4", "",
              frame_markdown(design, {"A": ".4g", "rms_rel_sigma_pct": ".3g", "max_rel_sigma_pct": ".3g"}), "",
              "The GA searches the grid of the design section inside the gimbal range; the comparison is at the "
              "spec's 0.1 s covariance step.", "",
              "## Section 13: the centrifuge's motivation, measured", "",
              frame_markdown(ext_ranks.drop(columns=["static_null_vectors"])), "",
              frame_markdown(ef, {c: ".3g" for c in ef.columns if c not in ("name", "term")}), "",
              "![section 13](figures/extension.png)", ""]
    gy = ef[ef.term.isin(["DII", "DSS", "DIO", "DIS", "DOS"])]
    rng = lambda d: f"{d.min():.3g}-{d.max():.3g} %"  # noqa: E731
    lines += [f"At 1 g with 24 random positions x 60 s: gyro g^2 terms {rng(gy.rel_sigma_1g_pct)} (spec one draw: "
              f"10-26 %), k3 {rng(ef[ef.term == 'k3'].rel_sigma_1g_pct)} (11-16 %), k2 "
              f"{rng(ef[ef.term == 'k2'].rel_sigma_1g_pct)} (1.1-1.5 %), kIP {rng(ef[ef.term == 'kIP'].rel_sigma_1g_pct)} "
              f"(4.4-4.9 %); the centrifuge's Table 1: gyro {rng(gy.rel_sigma_centrifuge_pct)}, accelerometer "
              f"{rng(ef[~ef.term.isin(gy.term)].rel_sigma_centrifuge_pct)}. The ranges depend on the random draw "
              "(the spec's positions are not given): the ledger's ext_* claims judge the ranks and the ranges, the "
              "latter over the draws below. With DOO the null vector is DII = DOO = DSS per gyro (CM eq. 22).", ""]
    lines += spread_lines(spread)
    atomic_write_text(out, "\n".join(lines) + "\n")


def save_tables(outdir: Path, rf, summ, design, ext_ranks, ef) -> None:
    write_table(rf, outdir / "ranks", "Scheme check: Lie ranks, static rank, covariance-only sigma, verdict",
                "docs/multiposition-1g.md §8, §15", {"max sigma/|truth| %": ".3g"})
    write_table(summ, outdir / "montecarlo_summary", "Monte Carlo summary", "largest |relative error| per seed",
                summary_formats(summ))
    write_table(design, outdir / "design", "A-optimal GA design vs S8 and TET4", "covariance-only at 0.1 s")
    write_table(ext_ranks.drop(columns=["static_null_vectors"]), outdir / "extension_ranks",
                "Section 13 ranks (order 1)", "static (Omega = 0) and exact, at x = 0")
    write_table(ef, outdir / "extension_sigma", "Section 13: 1 g vs centrifuge Table 1",
                "covariance-only sigma/|truth|", {c: ".3g" for c in ef.columns if c not in ("name", "term")})


def report_job(inp, out_report, config: dict, log=print) -> None:
    """The report rule's body: ``inp`` has ``obs`` (observability.json files), the collected tidy
    tables ``coef``, ``runs`` (Parquet) and ``timing`` (CSV), ``design`` (compare.csv), the §13
    ``ext_ranks``, ``ext_sigma``, ``ext_spread`` and ``centrifuge`` (the Table 1 json, or none);
    ``config`` the rig's config content; tables, figures and ``report.md`` go next to ``out_report``;
    ``inp.claims``: the rig's ledger (``results/multiposition/claims.csv``), whose rows open the report."""
    out = Path(out_report).parent
    cfg = load(config)
    rf = rank_frame([json.loads(Path(p).read_text()) for p in inp.obs])
    coef, runs, timing = (in_study_order(t, cfg.raw) for t in (pd.read_parquet(inp.coef), pd.read_parquet(inp.runs),
                                                               pd.read_csv(inp.timing)))
    summ, design = mc_summary(coef, runs, timing), pd.read_csv(inp.design)
    ext_ranks = pd.DataFrame(json.loads(Path(inp.ext_ranks).read_text()))
    ef = extension_frame(pd.read_csv(inp.ext_sigma).to_dict("records"), inp.centrifuge[0] if len(inp.centrifuge) else None)
    save_tables(out / "tables", rf, summ, design, ext_ranks, ef)
    spread = pd.read_csv(inp.ext_spread)
    save_figures(out / "figures", rf, coef, runs, ef, spread)
    write_report(out_report, rf, summ, design, ext_ranks, ef, spread=spread.to_dict("records"),
                 item4_cell=spec_cell(cfg), claims=read_ledger(inp.claims))
    log(f"report -> {out_report} ({len(runs)} Monte Carlo runs in {len(summ)} cells)")
