"""The NEES histogram of a rig's Monte Carlo study against the chi-square density (the study's
consistency figure, docs/centrifuge-model.md §11 for the centrifuge). Apart from
:mod:`platcal.study.plots` because the density needs scipy.stats (about 0.5 s of a job's start):
the figure jobs that draw no NEES histogram do not import it (issue 22 item 4).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats as sps

from ..estimation.consistency import nees_band
from .plots import plt, save, styled


@styled
def nees_histogram(runs: pd.DataFrame, path):
    """NEES histogram against the chi-square(dof) density, one panel per estimator."""
    estimators = list(dict.fromkeys(runs["estimator"]))
    dof = int(runs["nees_dof"].iloc[0])
    lo, hi = nees_band(dof)
    xmax = float(sps.chi2.ppf(0.9999, dof)) * 1.6
    bins = np.linspace(0, xmax, 50)
    fig, axes = plt.subplots(1, len(estimators), figsize=(5.5 * len(estimators), 4), squeeze=False)
    xs = np.linspace(0.01, xmax, 400)
    for ax, e in zip(axes[0], estimators):
        v = runs.loc[runs["estimator"] == e, "nees"].to_numpy()
        over = int(np.sum(v > xmax))
        inside = float(np.mean((v >= lo) & (v <= hi))) if v.size else float("nan")
        ax.hist(np.clip(v, 0, xmax), bins=bins, density=True, alpha=0.6, color="C0",
                label=f"{v.size} runs (mean {np.mean(v):.1f}; {over} beyond {xmax:.0f}, piled in the last bin)")
        ax.plot(xs, sps.chi2.pdf(xs, dof), "r", label=f"chi-square({dof}) density")
        ax.axvspan(lo, hi, color="g", alpha=0.08, label=f"95 % band {lo:.1f}-{hi:.1f}: {100 * inside:.0f} % inside")
        ax.set_xlabel(f"NEES of the {dof} coefficient errors (dimensionless)")
        ax.set_ylabel("probability density")
        ax.set_title(f"estimator {e} (all schemes and noise levels)")
        ax.legend(fontsize=7)
    fig.suptitle("Filter consistency: NEES against chi-square")
    fig.tight_layout()
    save(fig, path)
