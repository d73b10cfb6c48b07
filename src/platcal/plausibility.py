"""Plausibility of a record from the rig's physics, before any filter runs (issue 25 item 2).

Each check compares what the record holds with what the rig's model says it must hold and, when
they disagree, raises :class:`~platcal.errors.InputError` naming the column, the measured value,
the expected one and the fix (``platcal`` exits 2, before any output is written). The rigs
supply the physics (the nominal output at the commanded angles, a clock tolerance); the checks
here name no rig.
"""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .estimation.fit import gross_errors


def refuse_recognised(z: np.ndarray, nominal: np.ndarray, columns, unit: str, fix: str,
                      field: str = "--data", source: str = "the rig's error-free model of this test") -> None:
    """InputError when a column of the record ``z`` (N, m) is a unit, sign or swap of the nominal
    model's output ``nominal`` (N, m) in the same unit (:func:`platcal.estimation.fit.gross_errors`):
    the first such column is named with its RMS, the RMS ``nominal`` has (``source`` says where
    it comes from) and ``fix``."""
    found = gross_errors(z, nominal, columns)
    if not found:
        return
    i, what = found[0]
    rms = lambda a: float(np.sqrt(np.mean(a * a)))  # noqa: E731
    raise InputError(f"{field} column {columns[i]}",
                     f"RMS {rms(z[:, i]):.4g} {unit}, expected about {rms(nominal[:, i]):.4g} {unit} from {source}; "
                     f"{what}; {fix}")


def timestamp_jitter(t: np.ndarray, step: float) -> float:
    """RMS deviation, s, of the instants ``t`` (s, increasing) from the regular grid of period
    ``step`` that fits them best (missing samples keep their grid slot)."""
    k = np.rint((t - t[0]) / step)
    if k.size < 3:
        return 0.0
    A = np.column_stack([np.ones_like(k), k])
    coef, *_ = np.linalg.lstsq(A, t, rcond=None)
    r = t - A @ coef
    return float(np.sqrt(np.mean(r * r)))
