"""Relative error of an estimate against its truth: the tidy tables' ``rel_err_pct`` column.

Apart from :mod:`platcal.estimation.consistency` (NEES and its chi-square quantiles, which need
``scipy.special``): a Monte Carlo cell computes this column and loads no scipy for it (issue 22
item 4).
"""

from __future__ import annotations

import numpy as np


def rel_err_pct(estimate, truth):
    """Relative error (estimate - truth) / truth in percent (NaN where the truth is zero;
    docs/centrifuge-model.md eq. 28, every rig's tables)."""
    estimate = np.asarray(estimate, float)
    truth = np.asarray(truth, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(truth != 0, (estimate - truth) / truth * 100.0, np.nan)
