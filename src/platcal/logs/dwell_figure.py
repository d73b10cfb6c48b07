"""The figure of the dwells found in a continuous log (:mod:`.dwells`), for the user to check
the segmentation. Apart from the rule itself so that reading a log does not import matplotlib
(issue 22 item 3); a command draws it through :func:`platcal.rig.resolve` of
:data:`platcal.logs.dwells.DWELL_FIGURE`, loading it only when a log was segmented.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ..study.plots import save
from .dwells import Dwell, columns
from .summary import GAP_FACTOR


def dwell_figure(t: np.ndarray, signals: np.ndarray, dwells: list[Dwell], path,
                 names: tuple[str, ...] = ("alpha_m", "beta_m", "gamma_m"), ylabel: str = "angle sensors, deg") -> None:
    """The log's ``signals`` (N, m) (named ``names``, in ``ylabel``'s unit) against time with the
    dwells shaded and numbered, saved (PNG, atomically, the one figure saver) at ``path`` so the
    user can check the segmentation."""
    fig, ax = plt.subplots(figsize=(9, 3.2))
    signals = columns(signals)
    # a slew missing from the log is drawn as a break, not as a line across it
    step = np.diff(t)
    gaps = np.flatnonzero(step > GAP_FACTOR * np.median(step)) + 1 if step.size else np.array([], int)
    tt, ss = np.insert(np.asarray(t, float), gaps, np.nan), np.insert(signals, gaps, np.nan, axis=0)
    for i, name in enumerate(names):
        ax.plot(tt, ss[:, i], lw=0.8, label=name)
    for d in dwells:
        ax.axvspan(t[d.start], t[d.stop - 1], color="0.85", zorder=0)
        ax.text(0.5 * (t[d.start] + t[d.stop - 1]), 1.0, str(d.position), transform=ax.get_xaxis_transform(),
                ha="center", va="bottom", fontsize=7)
    ax.set_xlabel("t, s")
    ax.set_ylabel(ylabel)
    ax.legend(loc="upper right", fontsize=7)
    save(fig, path)
