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
from .estimation.fit import Moments, gross_errors_moments


def refuse_recognised(z: np.ndarray, nominal: np.ndarray, columns, unit: str, fix: str,
                      field: str = "--data", source: str = "the rig's error-free model of this test") -> None:
    """InputError when a column of the record ``z`` (N, m) is a unit, sign or swap of the nominal
    model's output ``nominal`` (N, m) in the same unit (:func:`platcal.estimation.fit.gross_errors`):
    the first such column is named with its RMS, the RMS ``nominal`` has (``source`` says where
    it comes from) and ``fix``."""
    refuse_recognised_moments(Moments.of(z, nominal), columns, unit, fix, field, source)


def refuse_recognised_moments(mo: Moments, columns, unit: str, fix: str, field: str = "--data",
                              source: str = "the rig's error-free model of this test") -> None:
    """:func:`refuse_recognised` from the sums of a record against the nominal output
    (:class:`platcal.estimation.fit.Moments`, added chunk by chunk for a streamed record)."""
    found = gross_errors_moments(mo, columns)
    if not found:
        return
    i, what = found[0]
    rms_z, rms_p = mo.rms()
    raise InputError(f"{field} column {columns[i]}",
                     f"RMS {rms_z[i]:.4g} {unit}, expected about {rms_p[i]:.4g} {unit} from {source}; "
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
