"""The figure of the dwells found in a continuous log (:mod:`.dwells`), for the user to check
the segmentation. Apart from the rule itself so that reading a log does not import matplotlib
(issue 22 item 3); a command draws it through :func:`platcal.rig.resolve` of its path
(``platcal.logs.dwell_figure:dwell_figure``), loading it only when a log was segmented.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

from ..study.plots import save
from .dwells import Dwell

def dwell_figure(t: np.ndarray, angles_deg: np.ndarray, dwells: list[Dwell], path) -> None:
    """The log's angle sensors against time with the dwells shaded and numbered, saved (PNG,
    atomically) at ``path`` so the user can check the segmentation."""
    fig, ax = plt.subplots(figsize=(9, 3.2))
    for i, name in enumerate(("alpha_m", "beta_m", "gamma_m")):
        ax.plot(t, angles_deg[:, i], lw=0.8, label=name)
    for d in dwells:
        ax.axvspan(t[d.start], t[d.stop - 1], color="0.85", zorder=0)
        ax.text(0.5 * (t[d.start] + t[d.stop - 1]), 1.0, str(d.position), transform=ax.get_xaxis_transform(),
                ha="center", va="bottom", fontsize=7)
    ax.set_xlabel("t, s")
    ax.set_ylabel("angle sensors, deg")
    ax.legend(loc="upper right", fontsize=7)
    save(fig, path)
