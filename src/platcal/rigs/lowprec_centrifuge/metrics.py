"""Compensation and the Table-1 metrics (docs/lowprec-centrifuge.md §8).

Errors are ordered (dVE, dVN, pE, pN); coefficients (kA_x, k2_x, kA_y, k2_y). Channel X is the
paper's Table 1 (VE, pE), channel Y its North counterpart (VN, pN). The "before" errors are the
true INS errors at the last sample of the run (the state, not the noisy output).
"""

from __future__ import annotations

import numpy as np

ERRORS = ("VE", "VN", "pE", "pN")
CHANNEL = {"VE": "X", "pE": "X", "VN": "Y", "pN": "Y"}


def compensate(before: np.ndarray, sens: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """e_after = e_before - sum_k c_k S_k (§8): before (S, 4), sens (4 coeffs, 4 errors), coeffs (S, 4).

    Summed per seed (not a BLAS product, whose rounding depends on the batch size), so a seed's
    numbers do not depend on the batch it runs in."""
    return before - (np.asarray(coeffs)[:, :, None] * sens[None]).sum(axis=1)


def effect(before, after) -> np.ndarray:
    """Effect = 1 - |after| / |before|, in % (paper's definition; can be negative)."""
    return 100.0 * (1.0 - np.abs(after) / np.abs(before))


def nonlinear_effect(before, after, after_truth) -> np.ndarray:
    """Nonlinear-part effect = 1 - |after - after_truth| / |before - after_truth|, in % (§8)."""
    return 100.0 * (1.0 - np.abs(after - after_truth) / np.abs(before - after_truth))
