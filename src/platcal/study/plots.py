"""Figures of a rig's Monte Carlo study (PNG, byte-stable: no timestamp or version metadata).

Each function takes the tidy tables of :mod:`platcal.study.montecarlo` / :mod:`platcal.study.stats`
and a path, and writes one figure with labelled axes (units), a legend and a title. What is a
rig's own (its groups' titles, the noise axis label, reference values such as a paper's) comes
in as arguments. The NEES histogram, which needs scipy.stats, is :mod:`platcal.study.nees_figure`.
"""

from __future__ import annotations

import functools
import os

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from ..io import atomic_path  # noqa: E402
from .stats import per_coefficient  # noqa: E402

STYLE = {"figure.dpi": 100, "savefig.dpi": 110, "font.size": 9}
"""The study figures' matplotlib settings, applied per figure (:func:`styled`), never globally:
a module that imports this one keeps matplotlib's defaults for its own figures."""


def styled(fn):
    """Draw and save the figure of ``fn`` under :data:`STYLE`."""
    @functools.wraps(fn)
    def wrapper(*args, **kw):
        with plt.rc_context(STYLE):
            return fn(*args, **kw)
    return wrapper


def save(fig, path: str | os.PathLike, dpi: float | None = None, tight: bool = True) -> None:
    """The one figure saver: PNG, atomically, without metadata (no software or time stamp, so
    reruns give identical bytes), then closed. ``dpi`` None: matplotlib's ``savefig.dpi``;
    ``tight``: trim the margins (``bbox_inches="tight"``)."""
    kw = {"bbox_inches": "tight"} if tight else {}
    if dpi is not None:
        kw["dpi"] = dpi
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None}, **kw)
    plt.close(fig)


def finish(fig, ax, path, xlabel: str, ylabel: str, title: str, legend_fontsize: float | None = 8) -> None:
    """Label the axes, title them, add the legend (none when ``legend_fontsize`` is None), lay
    the figure out and save it (:func:`save`): the common end of the study figures."""
    ax.set_ylabel(ylabel)
    ax.set_xlabel(xlabel)
    ax.set_title(title)
    if legend_fontsize is not None:
        ax.legend(fontsize=legend_fontsize)
    fig.tight_layout()
    save(fig, path)


def _scheme_colors(schemes):
    cmap = plt.get_cmap("tab10")
    return {s: cmap(i % 10) for i, s in enumerate(schemes)}


@styled
def boxplot_rel_err(coef: pd.DataFrame, noise: float, estimator: str, path, names_by_group: dict[str, list[str]],
                    group_titles: dict[str, str], title: str, reference: dict[str, float] | None = None,
                    reference_label: str = ""):
    """Relative-error box plots per quantity, one panel per group and one box per scheme, at one
    noise level and estimator; ``reference`` values (e.g. a paper's errors, %) marked."""
    df = coef[np.isclose(coef["noise"], noise) & (coef["estimator"] == estimator)]
    schemes = list(dict.fromkeys(df["scheme"]))
    colors = _scheme_colors(schemes)
    fig, axes = plt.subplots(len(names_by_group), 1, figsize=(16, 9))
    for ax, (grp, names) in zip(np.atleast_1d(axes), names_by_group.items()):
        w = 0.8 / max(len(schemes), 1)
        for j, s in enumerate(schemes):
            d = df[df["scheme"] == s]
            data = [d.loc[d["name"] == n, "rel_err_pct"].dropna().to_numpy() for n in names]
            pos = np.arange(len(names)) + (j - (len(schemes) - 1) / 2) * w
            bp = ax.boxplot(data, positions=pos, widths=w * 0.9, patch_artist=True, showfliers=True,
                            flierprops={"markersize": 2}, medianprops={"color": "k", "linewidth": 0.8})
            for b in bp["boxes"]:
                b.set_facecolor(colors[s])
                b.set_alpha(0.75)
            ax.plot([], [], "s", color=colors[s], label=s)
        if reference is not None:
            ax.plot(np.arange(len(names)), [reference[n] for n in names], "r*", markersize=8, label=reference_label)
        ax.axhline(0, color="grey", linewidth=0.5)
        ax.set_xticks(np.arange(len(names)), names, rotation=90)
        ax.set_ylabel("relative error, %")
        ax.set_title(f"{group_titles[grp]} coefficients")
        ax.legend(ncol=len(schemes) + 1, fontsize=8, loc="upper left")
        ax.grid(axis="y", alpha=0.3)
    n = df.groupby("scheme")["replicate"].nunique()
    fig.suptitle(f"{title}, {int(n.min()) if len(n) else 0} replicates per scheme")
    fig.tight_layout()
    save(fig, path)


@styled
def rms_vs_noise(coef: pd.DataFrame, path, group_titles: dict[str, str], noise_label: str):
    """Largest and median RMS relative error (%) against the noise level, per group, scheme and estimator."""
    pc = per_coefficient(coef)
    agg = pc.groupby(["scheme", "noise", "estimator", "group"], sort=False)["rms_rel_err_pct"].agg(
        ["max", "median"]).reset_index()
    schemes = list(dict.fromkeys(coef["scheme"]))
    estimators = list(dict.fromkeys(coef["estimator"]))
    colors = _scheme_colors(schemes)
    styles = ["-", "--", ":", "-."]
    fig, axes = plt.subplots(2, len(group_titles), figsize=(12, 8), sharex=True, squeeze=False)
    for col, grp in enumerate(group_titles):
        for row, stat in enumerate(("max", "median")):
            ax = axes[row, col]
            for s in schemes:
                for k, e in enumerate(estimators):
                    d = agg[(agg["scheme"] == s) & (agg["estimator"] == e) & (agg["group"] == grp)]
                    d = d.sort_values("noise")
                    ax.plot(d["noise"], d[stat], styles[k % 4], marker="o", markersize=3, color=colors[s],
                            label=f"{s}, {e}")
            ax.set_xscale("log")
            ax.set_yscale("log")
            levels = sorted(set(agg["noise"]))
            ax.set_xticks(levels, [f"{v:g}" for v in levels])
            ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
            ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.set_xlabel(noise_label)
            ax.set_ylabel(f"{stat} over coefficients of RMS relative error, %")
            ax.set_title(f"{group_titles[grp]} group: {stat} RMS relative error")
            ax.grid(which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=2)
    fig.suptitle("RMS relative error against noise level (Monte Carlo over replicates)")
    fig.tight_layout()
    save(fig, path)


@styled
def convergence(history: pd.DataFrame, truth: dict[str, float], units: dict[str, str], dwell_s: float,
                n_positions: int, path, states, title: str = ""):
    """Estimates of selected quantities with +-3 sigma bands against time; position boundaries."""
    fig, axes = plt.subplots(len(states) // 2 + len(states) % 2, 2, figsize=(13, 2.6 * ((len(states) + 1) // 2)),
                             sharex=True)
    axes = np.atleast_1d(axes).ravel()
    t_end = float(history["t_s"].max()) if len(history) else 0.0
    for ax, s in zip(axes, states):
        h = history[history["state"] == s]
        t = h["t_s"].to_numpy()
        x = h["estimate"].to_numpy()
        sg = h["sigma"].to_numpy()
        ax.fill_between(t, x - 3 * sg, x + 3 * sg, color="C0", alpha=0.25, label="estimate +- 3 sigma")
        ax.plot(t, x, "C0", linewidth=1, label="estimate")
        ax.axhline(truth[s], color="r", linewidth=1, label="truth")
        tb = dwell_s
        while tb < t_end + 1e-9:
            ax.axvline(tb, color="grey", linewidth=0.5, linestyle=":")
            tb += dwell_s
        tv = truth[s]
        span = max(abs(tv) * 0.3, float(np.nanmedian(3 * sg[len(sg) // 2:])) * 3 if len(sg) else 1.0)
        ax.set_ylim(tv - span, tv + span)
        ax.set_ylabel(f"{s}, {units[s]}")
        ax.set_title(s)
        ax.grid(alpha=0.3)
    for ax in axes[len(states):]:
        ax.set_visible(False)
    for ax in axes[-2:]:
        ax.set_xlabel("time since the start of the test, s (dotted: position boundaries)")
    axes[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(title or f"Convergence of selected estimates ({n_positions} positions x {dwell_s:g} s)")
    fig.tight_layout()
    save(fig, path)


@styled
def correlation_heatmap(cov: pd.DataFrame, path, n_coef: int, title: str = ""):
    """|correlation| of the final covariance (rho_ij = P_ij / sqrt(P_ii P_jj)); the largest pair
    among the first ``n_coef`` states (the identified quantities) is named in the legend."""
    P = cov.to_numpy(float)
    d = np.sqrt(np.diag(P))
    rho = np.abs(P / np.outer(d, d))
    names = list(cov.index)
    fig, ax = plt.subplots(figsize=(11, 9.5))
    im = ax.imshow(rho, vmin=0, vmax=1, cmap="viridis", interpolation="nearest")
    ax.set_xticks(range(len(names)), names, rotation=90, fontsize=6)
    ax.set_yticks(range(len(names)), names, fontsize=6)
    ax.set_xlabel("state")
    ax.set_ylabel("state")
    cb = fig.colorbar(im, ax=ax, shrink=0.8)
    cb.set_label("|rho_ij| (dimensionless)")
    off = rho.copy()
    np.fill_diagonal(off, 0)
    nc = n_coef
    i, j = np.unravel_index(np.argmax(off[:nc, :nc]), (nc, nc))
    ax.plot([], [], " ", label=f"largest coefficient pair: |rho({names[i]}, {names[j]})| = {off[i, j]:.3f}")
    ax.legend(loc="upper right", fontsize=8, handlelength=0)
    ax.set_title(title or "|correlation| of the final covariance")
    fig.tight_layout()
    save(fig, path)
