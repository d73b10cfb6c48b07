"""Plausibility of a record from the rig's physics, before any filter runs (issue 25 item 2).

Each check compares what the record holds with what the rig's model says it must hold and, when
they disagree, raises :class:`~platcal.errors.InputError` naming the column, the measured value,
the expected one and the fix (``platcal`` exits 2, before any output is written). The rigs
supply the physics (the nominal output at the commanded angles, a clock tolerance); the checks
here name no rig.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


CLOCK_RATE_SHARE = 0.3
"""The largest shift, in its own sigma, a clock-rate error may cause in the most sensitive
coefficient (0.3 sigma adds at most 9 % to its variance, the share the centrifuge's jitter tolerance uses)."""
CLOCK_RATE_Z = 3.0
"""How many standard errors of the measured rate error are granted on top of the tolerance: a
record whose stamps jitter is not refused for its jitter (0.13 % one-sided for a rate on the
tolerance's edge)."""


DIVISOR_SLACK = 0.01
"""With ``divisor``, a record whose median step is more than this (relative) off every whole
divisor of the declared period is sampled at a rate of its own, which nothing declares: no rate
error is measured (a clock 1 % off is refused by the dwell's span when a scheme is named; without
one it passes, and the summary's clock block says no rate was measured)."""
INDEX_JITTER = 0.1
"""The largest RMS scatter of the stamps about their line, in steps, for which a clock rate is
measured: beyond it (uniform jitter over more than +-0.17 step) a stamp may fall in its
neighbour's slot and bias the slope, so none is reported (the fit check sees such jitter)."""


@dataclass(frozen=True)
class ClockRate:
    """The relative rate error of a record's clock against the declared sample period, measured
    from the stamps: ``error`` = (measured step / declared step) - 1 (a clock running 1 + e fast
    stamps sample k at k step (1 + e)), its standard error ``se`` from the stamps' scatter about
    their fitted line, the declared ``step_s`` and the ``samples`` it rests on."""

    error: float
    se: float
    step_s: float
    samples: int

    @staticmethod
    def none() -> "ClockRate":
        """No measurement (too few stamps): never refused."""
        return ClockRate(0.0, np.inf, np.nan, 0)

    @staticmethod
    def combine(parts) -> "ClockRate":
        """The stretches' rate errors on one clock, weighted by their inverse variances."""
        parts = [p for p in parts if p.samples and np.isfinite(p.se) and p.se > 0]
        if not parts:
            return ClockRate.none()
        w = np.array([1.0 / p.se**2 for p in parts])
        e = np.array([p.error for p in parts])
        return ClockRate(float(w @ e / w.sum()), float(np.sqrt(1.0 / w.sum())), parts[-1].step_s,
                         sum(p.samples for p in parts))


def clock_rate(segments, step_s: float, divisor: bool = False) -> ClockRate:
    """The clock's rate error (:class:`ClockRate`) from the stamps ``segments`` (one array of
    times, s, per stretch on one clock: a position, a dwell), against the declared sample period
    ``step_s``: :func:`segment_rate` of each, combined by :meth:`ClockRate.combine`."""
    return ClockRate.combine([segment_rate(t, step_s, divisor) for t in segments])


def segment_rate(t, step_s: float, divisor: bool = False) -> ClockRate:
    """:class:`ClockRate` of one stretch of stamps ``t`` (s) on one clock: the least-squares
    slope of t on the sample index (the index from the stretch's own step, its median refined by
    the line fitted to a head of the stamps doubled until it is the whole: a missing sample keeps
    its slot and a rate error of any size is measured, not absorbed by re-indexing) against
    ``step_s``, and its standard error ``r / sqrt(sum (k - kbar)^2)`` from the RMS residual ``r`` (the jitter; floored at the float rounding of the largest stamp, so a
    record on an exact grid has a finite one). ``divisor``: the record may be sampled faster than
    ``step_s`` by a whole factor (the step compared is ``step_s / round(step_s / median step)``;
    none within :data:`DIVISOR_SLACK`: no rate measured)."""
    t = np.asarray(t, float)
    if t.size < 3:
        return ClockRate.none()
    med = float(np.median(np.diff(t)))
    if not med > 0:
        return ClockRate.none()
    step = float(step_s)
    if divisor:
        n = max(1.0, round(step / med))
        if abs(step / (n * med) - 1.0) > DIVISOR_SLACK:  # sampled at a rate of its own: none declared
            return ClockRate.none()
        step /= n
    # the index from a line fitted to a doubling head of the stamps: the median step of jittered
    # stamps errs by ~1e-3, which would slip the index by one within a thousand samples and bias
    # the slope; the fitted line's error shrinks faster than the head grows
    a, b, m = float(t[0]), med, 16
    while True:
        m = min(2 * m, t.size)
        k = np.rint((t[:m] - a) / b)
        kc = k - k.mean()
        sxx = float(kc @ kc)
        b = float(kc @ (t[:m] - t[:m].mean())) / sxx
        a = float(t[:m].mean() - b * k.mean())
        if m == t.size:
            break
    r = t - t.mean() - b * kc
    rms = max(float(np.sqrt(np.mean(r * r))), np.finfo(float).eps * float(np.max(np.abs(t))))
    if rms > INDEX_JITTER * b:  # stamps this scattered may slip the index: no rate is measured
        return ClockRate.none()
    return ClockRate(b / step - 1.0, rms / step / np.sqrt(sxx), step, int(t.size))


def _head(spill, m: int, shift: float = 0.0):
    """The first ``m`` values of a spilled column (:class:`platcal.records.ColumnSpill`), block by block."""
    return (v for _, v in spill.blocks(shift, rows=m))


def spilled_segment_rate(spill, step_s: float, med: float, divisor: bool = False, shift: float = 0.0) -> ClockRate:
    """:func:`segment_rate` of the stamps ``t - shift`` spilled to a file
    (:class:`platcal.records.ColumnSpill`; ``med``: their median step, s), by passes over it: the
    same doubling head, each line fitted from centred sums (two passes over the head), so memory
    does not grow with the stamps. The figures agree with the whole array's to rounding (the
    sums are taken in another order, exactly rounded per pass: ``math.fsum``), not bit for bit."""
    n = spill.rows
    if n < 3 or not med > 0:
        return ClockRate.none()
    step = float(step_s)
    if divisor:
        d = max(1.0, round(step / med))
        if abs(step / (d * med) - 1.0) > DIVISOR_SLACK:
            return ClockRate.none()
        step /= d
    a, b, m = spill.first - shift, med, 16
    while True:
        m = min(2 * m, n)
        sk, st = [], []
        for v in _head(spill, m, shift):
            sk.append(float(np.rint((v - a) / b).sum()))
            st.append(float(v.sum()))
        kbar, tbar = math.fsum(sk) / m, math.fsum(st) / m
        sxx, sxt = [], []
        for v in _head(spill, m, shift):
            kc = np.rint((v - a) / b) - kbar
            sxx.append(float(kc @ kc))
            sxt.append(float(kc @ (v - tbar)))
        sxx_m = math.fsum(sxx)
        a_k, b_k = a, b                 # the line the last index came from
        b = math.fsum(sxt) / sxx_m
        a = tbar - b * kbar
        if m == n:
            break
    rr = []
    for v in _head(spill, n, shift):
        r = v - tbar - b * (np.rint((v - a_k) / b_k) - kbar)
        rr.append(float(r @ r))
    big = max(abs(spill.first - shift), abs(spill.last - shift))   # increasing stamps: an end is the largest
    rms = max(math.sqrt(math.fsum(rr) / n), np.finfo(float).eps * big)
    if rms > INDEX_JITTER * b:
        return ClockRate.none()
    return ClockRate(b / step - 1.0, rms / step / np.sqrt(sxx_m), step, int(n))


def spilled_jitter(spill, step: float) -> float:
    """:func:`timestamp_jitter` of the stamps spilled to a file
    (:class:`platcal.records.ColumnSpill`), s: the line through them from centred sums (two passes)
    and the RMS residual (a third), equal to the least-squares fit's to rounding."""
    n = spill.rows
    if n < 3:
        return 0.0
    t0 = spill.first
    sk, st = [], []
    for _, v in spill.blocks():
        sk.append(float(np.rint((v - t0) / step).sum()))
        st.append(float(v.sum()))
    kbar, tbar = math.fsum(sk) / n, math.fsum(st) / n
    sxx, sxt = [], []
    for _, v in spill.blocks():
        kc = np.rint((v - t0) / step) - kbar
        sxx.append(float(kc @ kc))
        sxt.append(float(kc @ (v - tbar)))
    b = math.fsum(sxt) / math.fsum(sxx)
    rr = []
    for _, v in spill.blocks():
        r = (v - tbar) - b * (np.rint((v - t0) / step) - kbar)
        rr.append(float(r @ r))
    return float(np.sqrt(math.fsum(rr) / n))


def clock_rate_tolerance(names, estimate, sigma, per_hour, phase_rate: float = 0.0,
                         phase_gain=None) -> tuple[float, str]:
    """The relative clock-rate error that moves the most sensitive coefficient by
    :data:`CLOCK_RATE_SHARE` of its sigma, and that coefficient's name (inf, "" when none moves).

    To first order a clock running 1 + e fast moves coefficient c by e s_c: a rate (``per_hour``,
    a drift read as an angle over the record's time) is read over a time 1 + e too long, s_c =
    |c|; a rig whose model turns something at ``phase_rate`` (the same unit as the drifts, e.g. a
    centrifuge's table, deg/h) sees the turn run e phase_rate off, which a drift coefficient reads
    as an extra drift: s_c += phase_rate / ``phase_gain``_c (the largest drift one unit of c makes
    at the test's forces; 0: c does not absorb it). Tolerance = share / max_c (s_c / sigma_c).
    Formula: docs/centrifuge-model.md §13, docs/multiposition-1g.md §16."""
    est = np.abs(np.asarray(estimate, float))
    sig = np.asarray(sigma, float)
    s = np.where(np.asarray(per_hour, bool), est, 0.0)
    if phase_rate and phase_gain is not None:
        gain = np.asarray(phase_gain, float)
        s = s + np.where(gain > 0, abs(phase_rate) / np.where(gain > 0, gain, 1.0), 0.0)
    ok = np.isfinite(sig) & (sig > 0) & np.isfinite(s)
    if not ok.any() or not (s[ok] > 0).any():
        return np.inf, ""
    ratio = np.where(ok, s / np.where(ok, sig, 1.0), 0.0)
    i = int(np.argmax(ratio))
    return CLOCK_RATE_SHARE / float(ratio[i]), str(names[i])


def clock_block(rate: ClockRate, tolerance: float, coefficient: str) -> dict:
    """The clock-rate check's figures for a run's summary (``clock`` block): the measured relative
    rate error and its standard error (None when the stamps gave none), the samples, the
    tolerance and the coefficient it protects (None when nothing moves)."""
    measured = rate.samples > 0 and np.isfinite(rate.se)
    return {"rate_error": float(rate.error) if measured else None,
            "rate_error_se": float(rate.se) if measured else None,
            "samples": int(rate.samples), "tolerance": float(tolerance) if np.isfinite(tolerance) else None,
            "most_sensitive": coefficient or None, "share_of_sigma": CLOCK_RATE_SHARE}


def refuse_clock_rate(rate: ClockRate, tolerance: float, coefficient: str, period_key: str, spec: str,
                      reference: str = "", field: str = "--data column t") -> dict:
    """InputError naming column t when the record's clock runs off the declared sample period by
    more than ``tolerance`` (relative) beyond :data:`CLOCK_RATE_Z` standard errors: the measured
    rate error, its standard error, the tolerance, the coefficient it protects, the ``spec``
    section giving the tolerance's formula and the fix (stamp with the recorder's sample clock or
    ``reference``, or declare the period measured under the config key ``period_key``, ms); else
    the summary's :func:`clock_block`."""
    if not np.isfinite(rate.error) or abs(rate.error) - CLOCK_RATE_Z * rate.se <= tolerance:
        return clock_block(rate, tolerance, coefficient)
    fix = ("the record cannot tell a wrong stamp clock from a logger sampling off its declared rate: stamp with "
           f"the recorder's sample clock{reference}, or, if the stamps are the true sample times, declare the "
           f"logger's period {period_key} = {rate.step_s * 1e3 * (1 + rate.error):.9g}")
    raise InputError(field, f"the stamps run {rate.error:+.3g} (relative, +-{rate.se:.2g}) off the declared "
                     f"{rate.step_s * 1e3:g} ms sample period over {rate.samples} samples; a clock-rate error "
                     f"above {tolerance:.2g} moves {coefficient} by more than {CLOCK_RATE_SHARE:g} of its sigma "
                     f"({spec}); {fix}")
