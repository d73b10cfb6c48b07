"""Increments (delta-theta, delta-v per sample) as rates and specific force (issue 21, item 4).

Strapdown IMUs and INS computers log, per sample, the angle and velocity increments over the
sample's interval rather than rates and specific force. With ``record.kind: increments`` a rig
whose record holds rates and specific force reads its rate and specific-force columns as
increments (units of angle and of velocity, e.g. ``rad``, ``arcsec``, ``m/s``) and converts them
exactly over each interval: the increment of row k covers the interval from ``t[k]`` to
``t[k + 1]`` (the last row the median step), the interval over which the rig's navigation holds
sample k, so ``rate[k] * dt[k]`` is the increment and nothing is lost or smeared.
"""

from __future__ import annotations

import numpy as np

KINDS = ("samples", "increments")


def sample_intervals(t: np.ndarray) -> np.ndarray:
    """(N,) the interval each sample covers, s: ``t[k + 1] - t[k]``, the last one the median step."""
    return np.r_[np.diff(t), float(np.median(np.diff(t)))]


def increment_units(units: dict, columns: tuple[str, ...]) -> dict:
    """The rig's column ``units`` with ``columns`` (rates, specific force) as increments: unit x s."""
    return {c: (f"({u}) * s" if c in columns else u) for c, u in units.items()}


def rates_from_increments(increments: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Increments (N, m) over the intervals of ``t`` (N,) as mean rates (N, m) over each interval."""
    return np.asarray(increments, float) / sample_intervals(np.asarray(t, float))[:, None]
