"""The figures of the centrifuge's Monte Carlo study (docs/centrifuge-model.md §7-11): the
generic ones of :mod:`platcal.study.plots` with the centrifuge's groups, labels and the paper's
numbers, and the paper's Table 2 against the Monte Carlo (:func:`paper_vs_montecarlo`); the
figure rule's body (:func:`figures_job`). File names: :data:`.report.FIGURES`. Apart from
:mod:`.report` so that the tables, report and claims jobs import no figure library (issue 22
item 4).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ...log import job_logger
from ...model.instruments import NAMES, unit_of
from ...study.nees_figure import nees_histogram
from ...study.plots import boxplot_rel_err, convergence, correlation_heatmap, plt, rms_vs_noise, save, styled
from .catalogue import load_catalogue
from .report import CONVERGENCE_STATES, GROUP_TITLES, NOISE, resolve_cell
from .study import check_study


def figures_job(cfg, coef_path, runs_path, t2mc_path, single_dir, out: dict, log_path=None) -> None:
    """Rule body: every figure."""
    lg = job_logger(log_path)
    cfg = check_study(cfg)
    single_dir = Path(single_dir)
    coef = pd.read_parquet(coef_path)
    runs = pd.read_parquet(runs_path)
    t2mc = pd.read_csv(t2mc_path)
    hist = pd.read_parquet(single_dir / "history.parquet")
    cov = pd.read_csv(single_dir / "covariance.csv", index_col=0)
    info = json.loads((single_dir / "run.json").read_text())
    est = pd.read_csv(single_dir / "estimates.csv")
    truth = dict(zip(est["name"], est["truth"]))
    paper = resolve_cell(cfg, "paper")
    for k, p in out.items():
        lg.info("figure %s -> %s", k, p)
    all_figures(coef, runs, t2mc, hist, cov, info, truth, paper, out)
    lg.info("done")


@styled
def paper_vs_montecarlo(t2mc: pd.DataFrame, path, title: str = ""):
    """The paper's relative error against our Monte Carlo mean +- std, per coefficient."""
    fig, axes = plt.subplots(2, 1, figsize=(14, 8))
    for ax, grp in zip(axes, GROUP_TITLES):
        d = t2mc[t2mc["group"] == grp]
        x = np.arange(len(d))
        ax.errorbar(x - 0.1, d["mean_rel_err_pct"], yerr=d["std_rel_err_pct"].fillna(0), fmt="o", markersize=3,
                    capsize=2, label="this study: Monte Carlo mean +- 1 std")
        ax.plot(x + 0.1, d["paper_rel_err_pct"], "r*", markersize=7, label="paper (Table 2)")
        ax.axhline(0, color="grey", linewidth=0.5)
        ax.set_xticks(x, d["coefficient"], rotation=90)
        ax.set_ylabel("relative error, %")
        ax.set_title(f"{GROUP_TITLES[grp]} coefficients")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title or "The paper's relative error against our Monte Carlo mean +- std")
    fig.tight_layout()
    save(fig, path)


def all_figures(coef, runs, t2mc, history, cov, single_info: dict, truth: dict, paper: dict, out: dict) -> None:
    """Every figure of the study; ``out`` maps figure key -> path."""
    cat = load_catalogue().frame().set_index("name")
    by_group = {g: [n for n in NAMES if cat.loc[n, "group"] == g] for g in GROUP_TITLES}
    boxplot_rel_err(coef, paper["sigma_a_ug"], paper["estimator"], out["boxplot"], by_group, GROUP_TITLES,
                    f"Relative error (eq. 28) per coefficient by scheme: sigma_a = {paper['sigma_a_ug']:g} ug, "
                    f"estimator {paper['estimator']}",
                    reference=cat["paper_rel_err_pct"].to_dict(), reference_label="paper (Table 2, one run)")
    rms_vs_noise(coef, out["rms_vs_noise"], GROUP_TITLES, NOISE.label)
    convergence(history, truth, {s: unit_of(s) for s in CONVERGENCE_STATES}, single_info["dwell_s"],
                single_info["n_positions"], out["convergence"], CONVERGENCE_STATES,
                title=(f"Convergence, one run: scheme {single_info['scheme']}, sigma_a = {single_info['sigma_a_ug']:g} ug, "
                       f"{single_info['estimator']} ({single_info['passes']} pass(es)); red: truth"))
    correlation_heatmap(cov, out["correlation"], len(cov) - 3,
                        title=f"|correlation| of the final covariance (scheme {single_info['scheme']}, one run)")
    nees_histogram(runs, out["nees"])
    paper_vs_montecarlo(t2mc, out["paper_vs_mc"],
                        title=(f"Paper vs this study: scheme {paper['scheme']}, sigma_a = {paper['sigma_a_ug']:g} ug, "
                               f"estimator {paper['estimator']}"))
