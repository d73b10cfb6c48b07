"""Studies of scheme design: criteria against Monte Carlo accuracy, number of positions,
1 g against the centrifuge, and the two-g-level scheme that identifies D_OO.

Each function returns tables (pandas) that :mod:`workflow/scripts/design_*.py` write; the
numbers come from covariance-only runs (:mod:`platcal.observability`) and small Monte Carlo
runs of the study's own EKF. Monte Carlo runs use common random numbers: replicate r of every
scheme draws from ``SeedSequence(seed).spawn(R)[r]``, so scheme differences are not draw noise.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from ...io import atomic_to_csv, atomic_write_text  # noqa: E402
from ...study.plots import save as save_figure  # noqa: E402
from ...log import job_logger  # noqa: E402
from ...model.instruments import FULL_NAMES, INDEX, N_IDENTIFIED, NAMES  # noqa: E402
from ...study.tables import write_table  # noqa: E402
from .design import SchemeEvaluator, design_config, design_study_of  # noqa: E402
from .ekf import default_p0_sigma  # noqa: E402
from .identify import simulate_identify  # noqa: E402
from .observability import (CRITERIA, InfoCache, correlation, monte_carlo_errors,  # noqa: E402
                            observability_matrix, posterior_covariance, relative_scale, rms_relative_error,
                            setup_from_study)
from ...scheme import Scheme, check_scheme, load_scheme_file  # noqa: E402
from .study import classical_scheme, random_schemes  # noqa: E402

def _kind(name: str) -> str:
    if name.startswith("ga_"):
        return "GA"
    if name.startswith("random_"):
        return "random"
    return name


def compare_schemes(study, schemes: list[Scheme], replicates: int, passes: int | None = None,
                    log=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Criteria (covariance-only) and Monte Carlo accuracy of each scheme.

    Returns ``(summary, per_coefficient)``: one row per scheme with J, A, D, maxrel, the
    predicted RMS relative sigma and the Monte Carlo RMS relative error over the 45
    coefficients (pooled over replicates), and the per-coefficient MC RMS relative errors.
    """
    fs = replace(study.filter, history_every_s=None)
    if passes is not None:
        fs = replace(fs, passes=int(passes))
    rows, coef_rows = [], []
    evals: dict[float, SchemeEvaluator] = {}
    truth = study.truth[:N_IDENTIFIED]
    for s in schemes:
        t0 = time.perf_counter()
        ev = evals.setdefault(s.dwell_s, SchemeEvaluator(study, s.dwell_s, estimate_doo=False))
        crit = {k: float(v[0]) for k, v in ev.evaluate(s.angles_deg, s.g_levels).items()}
        err = monte_carlo_errors(study, s, replicates, filter_settings=fs)[:, :N_IDENTIFIED]
        rel = err / truth[None] * 100.0
        row = {"scheme": s.name, "kind": _kind(s.name), "n_positions": s.n_positions, "dwell_s": s.dwell_s,
               **crit, "mc_rms_rel_pct": rms_relative_error(err, truth),
               "mc_median_max_abs_rel_pct": float(np.median(np.abs(rel).max(axis=1))),
               "mc_replicates": replicates, "passes": fs.passes, "seconds": time.perf_counter() - t0}
        rows.append(row)
        for name, v in zip(NAMES, np.sqrt((rel**2).mean(axis=0))):
            coef_rows.append({"scheme": s.name, "name": name, "mc_rms_rel_pct": float(v)})
        if log:
            log(f"{s.name:>12s}: J {crit['J']:7.2f}  A {crit['A']:.3g}  maxrel {crit['maxrel']:.3g} %  "
                f"MC RMS rel {row['mc_rms_rel_pct']:.3f} %  ({row['seconds']:.0f} s)")
    return pd.DataFrame(rows), pd.DataFrame(coef_rows)


def spearman_table(summary: pd.DataFrame, target: str = "mc_rms_rel_pct") -> pd.DataFrame:
    """Spearman rank correlation of each criterion with the Monte Carlo accuracy over schemes."""

    out = []
    for c in list(CRITERIA) + ["rms_rel"]:
        r = spearmanr(summary[c], summary[target])
        out.append({"criterion": c, "spearman": float(r.statistic), "p_value": float(r.pvalue),
                    "n_schemes": int(len(summary))})
    return pd.DataFrame(out)


def static_vs_centrifuge(study, schemes: list[Scheme]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Posterior/prior sigma per coefficient with the centrifuge on and off (static 1 g).

    Returns ``(per_coefficient, summary)``; summary has the observability-matrix ranks.
    """
    per = pd.DataFrame({"name": list(NAMES)})
    summ = []
    for s in schemes:
        for label, rate in (("10g", None), ("1g", 0.0)):
            setup = setup_from_study(study, s.dwell_s)
            if rate is not None:
                setup = replace(setup, centrifuge=replace(setup.centrifuge, rate_deg_s=rate))
            cache = InfoCache(setup)
            F = cache.scheme_information(s.angles_deg, s.g_levels)[0]
            P = posterior_covariance(F[None], setup.p0)[0]
            ratio = np.sqrt(np.diag(P)) / setup.p0
            g = "10g" if rate is None else "1g"
            per[f"{s.name}_{g}"] = ratio
            om = observability_matrix(setup, s.angles_deg, s.g_levels)
            scale = relative_scale(setup.truth[:N_IDENTIFIED], setup.p0)
            summ.append({"scheme": s.name, "test": "centrifuge %g g" % setup.centrifuge.g_level if rate is None
                         else "static 1 g", "coef_rank": om.coef_rank, "rank": om.rank, "n_cols": om.n_cols,
                         "n_ratio_below_0.1": int((ratio < 0.1).sum()),
                         "n_ratio_above_0.5": int((ratio > 0.5).sum()),
                         "max_rel_sigma_pct": float((np.sqrt(np.diag(P)) / scale).max() * 100)})
    return per, pd.DataFrame(summ)


def doo_study(study, single: Scheme, two_level: Scheme, doo_truth: float = 0.05,
              replicates: int = 8) -> dict[str, pd.DataFrame]:
    """D_OO: the eq. 22 aliasing of a single-level scheme and its identification at two levels.

    * ``aliasing``: noise-free data with truth D_OO = ``doo_truth`` (each axis), 45-state EKF
      with two passes (no linearisation floor): estimate - truth for every coefficient.
    * ``noise_free_51``: the same data, 51-state filter (D_OO states), single- and two-level.
    * ``covariance``: posterior/prior sigma of D_OO, DF, DII, DSS in the 51-state filter.
    * ``monte_carlo``: MC RMS errors of the 51-state filter on the two-level scheme.
    """
    over = {f"DOO_{a}": doo_truth for a in "xyz"}
    truth = study.truth.copy()
    for k, v in over.items():
        truth[INDEX[k]] = v
    st = replace(study, truth=truth)
    fs45 = replace(study.filter, history_every_s=None, passes=2)
    fs51 = replace(fs45, estimate_doo=True, p0_sigma=default_p0_sigma(True, study.config["filter"]["p0"]))

    def noise_free(scheme, fs):
        est = simulate_identify(st, scheme, None, fs)
        return est.coef[0] - truth[fs.coef_index], est.coef_sigma[0]

    e45, _ = noise_free(single, fs45)
    alias = pd.DataFrame({"name": list(NAMES), "truth": truth[:N_IDENTIFIED], "error_45state_single": e45})
    e51s, s51s = noise_free(single, fs51)
    e51t, s51t = noise_free(two_level, fs51)
    nf = pd.DataFrame({"name": list(FULL_NAMES), "truth": truth,
                       "error_51state_single": e51s, "sigma_51state_single": s51s,
                       "error_51state_two_level": e51t, "sigma_51state_two_level": s51t})
    cov_rows = []
    for label, s in (("single-level " + single.name, single), ("two-level " + two_level.name, two_level)):
        ev = SchemeEvaluator(st, s.dwell_s, estimate_doo=True)
        P = ev.covariance(s.angles_deg, s.g_levels)[0]
        ratio = np.sqrt(np.diag(P)) / ev.setup.p0
        rho = correlation(P)
        om = observability_matrix(ev.setup, s.angles_deg, s.g_levels)
        row = {"scheme": label, "coef_rank": om.coef_rank, "n_coef": 48,
               "max_abs_rho_DOO_DF": float(max(abs(rho[INDEX[f"DOO_{a}"], INDEX[f"DF_{a}"]]) for a in "xyz"))}
        for n in ("DOO_x", "DOO_y", "DOO_z", "DF_x", "DII_x", "DSS_x"):
            row[f"{n}_post_over_prior"] = float(ratio[INDEX[n]])
            row[f"{n}_sigma"] = float(np.sqrt(P[INDEX[n], INDEX[n]]))
        cov_rows.append(row)
    out = {"aliasing": alias, "noise_free_51": nf, "covariance": pd.DataFrame(cov_rows)}
    if replicates > 0:
        err = monte_carlo_errors(st, two_level, replicates, filter_settings=replace(fs51, passes=study.filter.passes))
        err1 = monte_carlo_errors(st, single, replicates, filter_settings=replace(fs45, passes=study.filter.passes))
        mc = pd.DataFrame({"name": list(FULL_NAMES), "truth": truth,
                           "mc_rms_err_51state_two_level": np.sqrt((err**2).mean(axis=0)),
                           "mc_mean_err_51state_two_level": err.mean(axis=0),
                           "mc_mean_err_45state_single": np.r_[err1.mean(axis=0), [np.nan] * 3]})
        rel45 = lambda e: rms_relative_error(e[:, :N_IDENTIFIED], truth[:N_IDENTIFIED])
        out["monte_carlo"] = mc
        out["monte_carlo_summary"] = pd.DataFrame([
            {"filter": "45-state, single-level " + single.name, "mc_rms_rel_pct_45": rel45(err1)},
            {"filter": "51-state, two-level " + two_level.name, "mc_rms_rel_pct_45": rel45(err),
             "mc_rms_rel_pct_DOO": float(np.sqrt(np.mean((err[:, 45:] / doo_truth * 100) ** 2)))},
        ])
    return out


# ------------------------------------------------------------------ workflow jobs (thin scripts call these)

def _load(path) -> Scheme:
    return next(iter(load_scheme_file(path).values()))


def _write_table(df: pd.DataFrame, stem, title: str, floatfmt=".4g") -> None:
    """CSV (full precision), Markdown and HTML of a design table, floats as ``floatfmt``."""
    fmt = {c: floatfmt for c in df.columns if pd.api.types.is_float_dtype(df[c])}
    write_table(df, stem, title, formats=fmt)


def scatter_figure(summary: pd.DataFrame, spear: pd.DataFrame, path) -> None:
    """Criterion against Monte Carlo RMS relative error, one panel per criterion."""
    crits = list(CRITERIA)
    rows = [("mc_rms_rel_pct", "spearman", "1-pass EKF")]
    if "mc2_rms_rel_pct" in summary:
        rows.append(("mc2_rms_rel_pct", "spearman_2pass", "2-pass EKF"))
    fig, axes = plt.subplots(len(rows), len(crits), figsize=(4 * len(crits), 3.4 * len(rows)),
                             constrained_layout=True, squeeze=False)
    colours = {"table1": "tab:red", "classical": "tab:green", "GA": "tab:blue", "random": "0.55"}
    sp = spear.set_index("criterion")
    for (target, scol, label), axrow in zip(rows, axes):
        for ax, c in zip(axrow, crits):
            for kind, g in summary.groupby("kind"):
                ax.scatter(g[c], g[target], s=28 if kind != "random" else 14,
                           c=colours.get(kind, "tab:purple"), label=kind, zorder=3 if kind != "random" else 2)
                if kind == "GA":
                    for _, r in g.iterrows():
                        ax.annotate(r["scheme"].replace("ga_", ""), (r[c], r[target]), fontsize=7,
                                    xytext=(3, 3), textcoords="offset points")
            ax.set_title(f"{c}: Spearman {sp.loc[c, scol]:+.2f} ({label})", fontsize=9)
            ax.set_xlabel(c + (" (log scale)" if c in ("A", "maxrel") else ""))
            if c in ("A", "maxrel"):
                ax.set_xscale("log")
                ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_yscale("log")
            ax.grid(alpha=0.3)
        axrow[0].set_ylabel(f"MC RMS relative error, % ({label})")
    axes[0][0].legend(fontsize=8)
    save_figure(fig, path, dpi=120, tight=False)


def compare_job(config: dict, scheme_files: list, out_dir, log_path=None) -> None:
    """table1, classical, random and GA schemes: criteria, MC accuracy, Spearman, scatter."""
    st = design_config(config)["study"]
    study = design_study_of(config)
    log = job_logger(log_path).info
    dwell = study.schemes["table1"].dwell_s if "table1" in study.schemes else 60.0
    schemes = ([study.schemes["table1"]] if "table1" in study.schemes else []) + [classical_scheme(dwell)]
    schemes += random_schemes(st["random_seed"], st["random_count"], 6, dwell)
    schemes += [_load(f) for f in scheme_files]
    summary, per = compare_schemes(study, schemes, st["replicates"], log=log)
    # the same with the 2-pass filter (consistent, no linearisation floor; docs/centrifuge-model.md §11)
    two, per2 = compare_schemes(study, schemes, st["replicates"], passes=2, log=log)
    summary["mc2_rms_rel_pct"] = two["mc_rms_rel_pct"].to_numpy()
    summary["mc2_median_max_abs_rel_pct"] = two["mc_median_max_abs_rel_pct"].to_numpy()
    per["mc2_rms_rel_pct"] = per2["mc_rms_rel_pct"].to_numpy()
    spear = spearman_table(summary)
    for target, col in (("mc2_rms_rel_pct", "spearman_2pass"), ("rms_rel", "spearman_vs_predicted_rms_rel")):
        other = spearman_table(summary, target)
        spear[col] = other["spearman"].to_numpy()
        if target.startswith("mc2"):
            spear["p_value_2pass"] = other["p_value"].to_numpy()
    rnd = summary[summary["kind"] == "random"]
    if len(rnd) >= 3:  # the random schemes alone (no GA optima or symmetric schemes to spread the range)
        spear["spearman_random_only"] = spearman_table(rnd)["spearman"].to_numpy()
        spear["p_value_random_only"] = spearman_table(rnd)["p_value"].to_numpy()
        spear["spearman_2pass_random_only"] = spearman_table(rnd, "mc2_rms_rel_pct")["spearman"].to_numpy()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _write_table(summary, out / "schemes", "Schemes by criterion and Monte Carlo error")
    _write_table(spear, out / "spearman", "Spearman rank correlation of each criterion with the Monte Carlo error", ".3f")
    atomic_to_csv(per, out / "per_coefficient.csv")
    scatter_figure(summary, spear, out / "criteria_vs_accuracy.png")


def npos_job(config: dict, scheme_files: list, out_dir, log_path=None) -> None:
    """GA schemes for N = 3..8: criteria (covariance-only) and MC accuracy against N."""
    st = design_config(config)["study"]
    study = design_study_of(config)
    schemes = [_load(f) for f in scheme_files]
    summary, _ = compare_schemes(study, schemes, st["replicates"], log=job_logger(log_path).info)
    summary["criterion"] = summary["scheme"].str.extract(r"ga_([A-Za-z]+)")[0]
    summary["total_time_s"] = summary["n_positions"] * summary["dwell_s"]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _write_table(summary, out / "n_positions", "GA optimum by number of positions")
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6), constrained_layout=True)
    for crit, g in summary.groupby("criterion"):
        g = g.sort_values("n_positions")
        axes[0].plot(g["n_positions"], g["J"], "o-", label=f"GA on {crit}")
        axes[1].plot(g["n_positions"], g["rms_rel"], "o-", label=f"GA on {crit}")
        axes[2].plot(g["n_positions"], g["mc_rms_rel_pct"], "o-", label=f"GA on {crit}")
    for ax, lab in zip(axes, ["J (eq. 27)", "predicted RMS relative sigma, %", "Monte Carlo RMS relative error, %"]):
        ax.set_xlabel("positions N (60 s each)")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
    axes[1].set_yscale("log")
    axes[2].set_yscale("log")
    axes[0].legend(fontsize=8)
    save_figure(fig, out / "n_positions.png", dpi=120, tight=False)


def static_job(config: dict, scheme_files: list, out_dir, log_path=None) -> None:
    """Posterior/prior sigma with the centrifuge on and off (static 1 g), same positions."""
    study = design_study_of(config)
    schemes = ([study.schemes["table1"]] if "table1" in study.schemes else []) + [_load(f) for f in scheme_files]
    dwell = schemes[0].dwell_s if schemes else 60.0
    schemes.append(check_scheme("rich24", {"dwell_s": dwell, "positions": [list(p) for p in RICH_1G_POSITIONS]}))
    per, summ = static_vs_centrifuge(study, schemes)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    _write_table(per, out / "static_vs_centrifuge", "Posterior/prior sigma, centrifuge on and off (static 1 g)", ".3g")
    _write_table(summ, out / "static_vs_centrifuge_summary", "Static 1 g against the centrifuge: summary", ".3g")


def doo_job(config: dict, two_level_file, out_dir, log_path=None) -> None:
    """D_OO: eq. 22 aliasing of the single-level table1 and the two-level 51-state filter."""
    st = design_config(config)["study"]
    study = design_study_of(config)
    two = _load(two_level_file)
    single = study.schemes["table1"] if "table1" in study.schemes else classical_scheme(two.dwell_s)
    res = doo_study(study, single, two, st["doo_truth"], replicates=max(2, st["replicates"] // 3))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for k, df in res.items():
        _write_table(df, out / f"doo_{k}", f"D_OO: {k}", ".4g")


RICH_1G_POSITIONS = tuple((a, b, g) for a in (0, 90, 180, 270) for b in (-45, 0, 45) for g in (0, 135))
"""A 24-position static scheme over the sphere (beta = -45, 0, 45): the best case of a 1 g test."""


def _md(path, floatfmt=".4g") -> str:
    return pd.read_csv(path).to_markdown(index=False, floatfmt=floatfmt)


def report_job(config: dict, design_dir, out_md, log_path=None) -> None:
    """``results/design/report.md``: the design questions answered with the numbers on disk."""

    d = Path(design_dir)
    study = design_study_of(config)
    dcfg = design_config(config)
    lines = ["# Scheme design: observability criteria, genetic algorithm, number of positions, 1 g, D_OO", ""]
    fs = study.filter
    lines += [f"Settings: filter period {fs.period_s * 1000:g} ms, sigma_a {fs.sigma_a_ug:g} ug, ARW "
              f"{fs.arw_deg_rth:g} deg/sqrt(h), sigma_set {fs.sigma_set_arcsec:g} arcsec, P0 of the config, "
              f"centrifuge {study.centrifuge.g_level:g} g at {study.centrifuge.rate_deg_s:g} deg/s, "
              f"{fs.passes}-pass EKF in the Monte Carlo runs. GA (pymoo): population {dcfg['population']}, "
              f"{dcfg['generations']} generations, seed {dcfg['seed'] if dcfg['seed'] is not None else study.seed}.", ""]
    # J of table1
    if "table1" in study.schemes:
        t1 = study.schemes["table1"]
        j = {}
        for lab, arw in (("defaults", None), ("ARW 0", 0.0)):
            over = {} if arw is None else {"arw_deg_rth": arw}
            ev = SchemeEvaluator(study, t1.dwell_s, **over)
            j[lab] = float(ev.evaluate(t1.angles_deg)["J"][0])
        lines += ["## J of Table 1", "",
                  f"J(table1) = {j['defaults']:.2f} at these settings ({j['ARW 0']:.2f} with ARW 0); the "
                  "independent implementation of spec section 11 found 94.5 and 133.2.", ""]
    # GA runs
    rows = []
    for f in sorted(d.glob("ga_*.json")):
        s = json.loads(f.read_text())
        rows.append({"scheme": s["scheme"], "criterion": s["criterion"], "value": s["value"],
                     "J": s["criteria"]["J"], "positions": str(s["positions"]).replace(" ", ""),
                     "g_levels": "" if not s.get("g_levels") else str(s["g_levels"]).replace(" ", ""),
                     "seconds": s["seconds"], "position_runs": s["position_runs"]})
    if rows:
        lines += ["## GA schemes", "", pd.DataFrame(rows).to_markdown(index=False, floatfmt=".4g"), ""]
    cmp_ = d / "compare"
    if (cmp_ / "schemes.csv").exists():
        summ = pd.read_csv(cmp_ / "schemes.csv")
        sp = pd.read_csv(cmp_ / "spearman.csv")
        by = summ.set_index("scheme")
        lines += ["## Criteria against Monte Carlo accuracy", "",
                  f"{len(summ)} schemes, {int(summ['mc_replicates'].iloc[0])} Monte Carlo replicates each "
                  "(common random numbers); RMS relative error pooled over replicates and the 45 coefficients.", "",
                  summ[[c for c in ["scheme", "kind", "J", "A", "D", "maxrel", "rms_rel", "mc_rms_rel_pct",
                        "mc_median_max_abs_rel_pct", "mc2_rms_rel_pct"] if c in summ]].to_markdown(index=False, floatfmt=".4g"), "",
                  "(rms_rel: predicted RMS relative sigma, %; mc_*: Monte Carlo, 1-pass EKF; mc2_*: 2-pass EKF)", "",
                  "Spearman rank correlation of each criterion with the Monte Carlo RMS relative error "
                  "(and with the predicted RMS relative sigma):", "", sp.to_markdown(index=False, floatfmt=".3f"), "",
                  "![criteria against accuracy](compare/criteria_vs_accuracy.png)", ""]
        ans = []
        if "table1" in by.index and "ga_J" in by.index:
            ans.append(f"* Minimising J: ga_J has J = {by.loc['ga_J', 'J']:.2f} against {by.loc['table1', 'J']:.2f} "
                       f"for table1, and MC RMS relative error {by.loc['ga_J', 'mc_rms_rel_pct']:.3f} % against "
                       f"{by.loc['table1', 'mc_rms_rel_pct']:.3f} %.")
            nlow = int((summ.loc[summ.kind == "random", "J"] < by.loc["table1", "J"]).sum())
            ans.append(f"* {nlow} of {int((summ.kind == 'random').sum())} random schemes have a lower J than table1.")
        best = sp.iloc[sp["spearman"].abs().idxmax()] if len(sp) else None
        if best is not None:
            ans.append(f"* Best predictor of the Monte Carlo error: {best['criterion']} (Spearman "
                       f"{best['spearman']:+.2f}, p = {best['p_value']:.2g}); J: "
                       f"{sp.set_index('criterion').loc['J', 'spearman']:+.2f}.")
        ga = summ[summ.kind == "GA"].sort_values("mc_rms_rel_pct")
        if len(ga):
            ans.append("* Monte Carlo RMS relative error of each criterion's optimum: " + ", ".join(
                f"{r.scheme} {r.mc_rms_rel_pct:.3f} %" for r in ga.itertuples()) + ".")
        lines += ans + [""]
    npos = d / "npos" / "n_positions.csv"
    if npos.exists():
        lines += ["## How many positions", "", "GA optimum for each N (60 s per position, so the test gets longer "
                  "with N):", "", pd.read_csv(npos)[["scheme", "criterion", "n_positions", "J", "A", "maxrel", "rms_rel",
                                                      "mc_rms_rel_pct", "mc_median_max_abs_rel_pct"]]
                  .sort_values(["criterion", "n_positions"]).to_markdown(index=False, floatfmt=".4g"), "",
                  "![N positions](npos/n_positions.png)", ""]
        nd = pd.read_csv(npos).sort_values("n_positions")
        for crit, g in nd.groupby("criterion"):
            lines.append(f"* GA on {crit}: Monte Carlo RMS relative error " + ", ".join(
                f"N={int(r.n_positions)} {r.mc_rms_rel_pct:.3f} %" for r in g.itertuples()) + "; predicted " + ", ".join(
                f"{r.rms_rel:.3f}" for r in g.itertuples()) + " %.")
        lines += ["", "With a fixed dwell the test time grows with N, so the error would fall as "
                  "sqrt(N_old / N_new) from the data volume alone; a larger drop is the gain of the geometry.", ""]
    st = d / "static"
    if (st / "static_vs_centrifuge.csv").exists():
        per = pd.read_csv(st / "static_vs_centrifuge.csv")
        lines += ["## 1 g against the centrifuge", "",
                  "Posterior/prior sigma per coefficient, same positions with the centrifuge on (10 g) and off "
                  "(static 1 g); rich24 is a 24-position static scheme over the sphere (beta = -45, 0, 45), the "
                  "best case of a 1 g test.", "", _md(st / "static_vs_centrifuge_summary.csv", ".3g"), "",
                  per.to_markdown(index=False, floatfmt=".3g"), ""]
        c1 = [c for c in per.columns if c.endswith("_1g")]
        if "rich24_1g" in per.columns:
            weak = per.loc[per["rich24_1g"] > 0.1, "name"].tolist()
            lines += [f"Even with 24 static positions, {len(weak)} coefficients keep more than 10 % of their "
                      f"prior sigma at 1 g: {', '.join(weak)}.", ""]
    doo = d / "doo"
    if (doo / "doo_covariance.csv").exists():
        lines += ["## D_OO with two g-levels", "",
                  f"Truth D_OO = {dcfg['study']['doo_truth']:g} deg/h/g^2 on each axis. Covariance of the 51-state "
                  "filter (D_OO as states):", "", _md(doo / "doo_covariance.csv", ".3g"), "",
                  "Noise-free data, two-pass EKF: error of the 45-state filter on the single-level scheme (eq. 22 "
                  "aliasing) and of the 51-state filter on both schemes (gyro terms shown):", ""]
        al = pd.read_csv(doo / "doo_aliasing.csv")
        nf = pd.read_csv(doo / "doo_noise_free_51.csv")
        m = nf.merge(al[["name", "error_45state_single"]], on="name", how="left")
        m = m[m["name"].str.startswith("D")]
        lines += [m[["name", "truth", "error_45state_single", "error_51state_single", "error_51state_two_level",
                     "sigma_51state_two_level"]].to_markdown(index=False, floatfmt=".4g"), ""]
        if (doo / "doo_monte_carlo_summary.csv").exists():
            lines += ["Monte Carlo (noise as configured):", "", _md(doo / "doo_monte_carlo_summary.csv"), ""]
    atomic_write_text(out_md, "\n".join(lines) + "\n")
