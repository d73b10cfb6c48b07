"""Filter consistency: NEES of a batch of estimates and the chi-square bands it is judged by.

A consistent filter's NEES over n states is chi-square(n) distributed (mean n); its NIS over
an m-dimensional measurement is chi-square(m) per update. Both are the checks every rig's study
reports (docs/centrifuge-model.md §11 for the centrifuge).
"""

from __future__ import annotations

import numpy as np
from scipy import stats as sps


def nees(estimate: np.ndarray, cov: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ``e^T P^-1 e`` for a batch: (B, n), (B, n, n), (B|1, n)."""
    e = estimate - truth
    L = np.linalg.cholesky(cov)
    y = np.linalg.solve(L, e[..., None])[..., 0]
    return np.einsum("bi,bi->b", y, y)


def nees_band(dof: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` band of a chi-square(dof) NEES (for 45: 28.4 .. 65.4)."""
    a = (1.0 - level) / 2.0
    return float(sps.chi2.ppf(a, dof)), float(sps.chi2.ppf(1.0 - a, dof))
