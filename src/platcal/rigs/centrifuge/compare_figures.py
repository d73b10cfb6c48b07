"""The figures of the centrifuge's estimator comparison and the comparison rule's body
(:func:`compare_job`: the tables of :mod:`.compare`, then the figures).

- ``figures/compare_cost.png``: the largest-gyro RMS relative error against the estimator's CPU
  time per run, per estimator and noise level (:func:`error_vs_cost`);
- ``figures/compare_nees.png``: NEES histograms side by side per estimator, with the chi2(dof)
  density (:func:`nees_side_by_side`).

Apart from :mod:`.compare` so that the report, tables and claims, which read the comparison's
numbers, import neither matplotlib nor scipy.stats (issue 22 item 4).
"""

from __future__ import annotations

import matplotlib.ticker
import numpy as np
import pandas as pd
from scipy.stats import chi2

from ...log import job_logger
from ...study.plots import plt, save, styled
from .compare import NEES_LEVEL, write_compare_tables
from .compare_cells import compare_settings, with_compare_estimators
from .study import check_study


@styled
def error_vs_cost(summ: pd.DataFrame, path, title: str = ""):
    """Largest-gyro RMS relative error against CPU seconds per run, per estimator and noise level."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    levels = sorted(set(summ["sigma_a_ug"]))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "osD^v<>ph*"
    names = list(dict.fromkeys(summ["estimator"]))
    for i, e in enumerate(names):
        d = summ[summ["estimator"] == e].sort_values("sigma_a_ug")
        ax.plot(d["cpu_s_per_run"], d["max_rms_rel_err_pct_gyro"], color="0.75", linewidth=0.8, zorder=1)
        for r in d.itertuples():
            ax.scatter(r.cpu_s_per_run, r.max_rms_rel_err_pct_gyro, marker=markers[i % len(markers)],
                       color=colors[levels.index(r.sigma_a_ug) % len(colors)], s=60, zorder=2,
                       edgecolor="black" if r.meets else "none")
        last = d.iloc[-1]
        ax.annotate(e, (last["cpu_s_per_run"], last["max_rms_rel_err_pct_gyro"]), textcoords="offset points",
                    xytext=(6, 4), fontsize=8)
    for i, e in enumerate(names):
        ax.scatter([], [], marker=markers[i % len(markers)], color="0.4", label=e)
    for j, v in enumerate(levels):
        ax.scatter([], [], marker="s", color=colors[j % len(colors)], label=f"sigma_a = {v:g} ug")
    ax.scatter([], [], marker="o", facecolor="none", edgecolor="black", label="meets the issue's bounds")
    ax.set_xlabel("CPU time per run, s (the estimator alone, not the simulation)")
    ax.set_ylabel("largest gyro RMS relative error, %")
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    ax.set_title(title or "Error against cost per estimator and noise level")
    fig.tight_layout()
    save(fig, path)


@styled
def nees_side_by_side(runs: pd.DataFrame, path, order: list[str], title: str = ""):
    """NEES histograms, one panel per estimator (noise levels overlaid), with the chi2(dof) density."""
    dof = int(runs["nees_dof"].iloc[0])
    names = [e for e in order if e in set(runs["estimator"])]
    levels = sorted(set(runs["noise"]))
    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names) + 1, 3.8), sharey=True, squeeze=False)
    top = max(3 * dof, float(chi2.ppf(0.9999, dof)))
    bins = np.linspace(0, top, 41)
    xs = np.linspace(1e-3, top, 300)
    bound = float(chi2.ppf(NEES_LEVEL, dof))
    for ax, e in zip(axes[0], names):
        for v in levels:
            n = runs.loc[(runs["estimator"] == e) & np.isclose(runs["noise"], v), "nees"].to_numpy(float)
            clipped = np.clip(n, 0, top)  # the overflow lands in the last bin, not off the plot
            ax.hist(clipped, bins=bins, density=True, histtype="step", linewidth=1.3,
                    label=f"{v:g} ug (mean {n.mean():.0f})")
        ax.plot(xs, chi2.pdf(xs, dof), "k--", linewidth=1, label=f"chi2({dof})")
        ax.axvline(bound, color="red", linewidth=0.8, label=f"99.9 % point {bound:.1f}")
        ax.set_title(e)
        ax.set_xlabel(f"NEES ({dof} dof; > {top:.0f} in the last bin)")
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("density")
    fig.suptitle(title or "NEES per estimator")
    fig.tight_layout()
    save(fig, path)


def compare_job(cfg: dict, coef_path, runs_path, out: dict, log_path=None) -> None:
    """Rule body: the comparison's tables and figures (``out``: ``tables`` folder, ``cost`` and
    ``nees`` figure paths)."""
    lg = job_logger(log_path)
    cfg = with_compare_estimators(check_study(cfg))
    coef, runs = pd.read_parquet(coef_path), pd.read_parquet(runs_path)
    summ = write_compare_tables(cfg, coef, runs, out["tables"])
    c = compare_settings(cfg)
    error_vs_cost(summ, out["cost"], f"Error against cost: scheme {c['scheme']}, {int(summ['runs'].min())} runs per point")
    nees_side_by_side(runs, out["nees"], c["estimators"],
                      f"NEES per estimator: scheme {c['scheme']}, {int(summ['runs'].min())} runs per level")
    lg.info("comparison tables and figures -> %s, %s, %s", out["tables"], out["cost"], out["nees"])
