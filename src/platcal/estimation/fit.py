"""Does the record fit the model? A check of a run's innovations that needs no truth (issue 25).

A consistent filter's innovation ``z - h(x_pred)`` of channel i is zero-mean with the variance
``S_ii`` it predicts, and successive innovations are uncorrelated (white). From a run's
innovations and their predicted variances (or a batch estimator's residuals and their
variances) :func:`fit_check` gives, per channel, the normalised innovation ``e = innov /
sqrt(S_ii)``'s mean and RMS, its NIS per degree of freedom (``mean(e^2)``) with the chi-square
bound for the number of updates, and the lag-1 autocorrelation of ``e`` with its bound. The
convention is the same on every rig: NIS **per degree of freedom** (1 expected), per channel and
over all channels.

The verdict fails a channel when any of its three figures is beyond its bound by more than the
model tolerance (:class:`FitTolerance`; the lag-1 figure weighted by min(1, NIS per dof), so that
the correlated but negligible innovations of a noise-free record do not count): a filter is not exactly consistent (linearisation,
the first updates of every reset), so a clean record is judged with a margin, and the false-alarm
rate of the whole check is measured, not assumed (``benchmarks/fit_false_alarm.py``).

When the record does not fit, :func:`diagnose` tells apart what it can from the measurements
and the model's predictions: a unit (the measurement is the prediction times 9.80665, 57.30,
1000 or 3600, or divided by one of them), a sign (times -1), a swapped pair of channels (channel
i follows the prediction of channel j) and a clock (the innovation follows the prediction's time
derivative: an offset, or a jitter that inflates it in proportion). Nothing here names a rig.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .consistency import chi2_quantile, normal_quantile

EXIT_DOES_NOT_FIT = 3
"""Exit status of ``platcal identify`` when the record does not fit the model (0 fitted, 2 refused)."""

UNIT_SCALES = ((9.80665, "m/s^2 vs g"), (180.0 / np.pi, "deg vs rad"), (1000.0, "a factor 1000 (milli/kilo)"),
               (3600.0, "per hour vs per second"))
"""Scales a unit error leaves between a measurement and its prediction (either way round)."""


@dataclass(frozen=True)
class FitTolerance:
    """The check's false-alarm level and model tolerance.

    ``level``: false-alarm probability of the statistical bounds of the whole check (split over
    the channels and the three figures, Bonferroni). ``nis``: relative excess of NIS per dof a
    filter may show on a clean record (its linearisation and reset transients; 0.5 = 50 %).
    ``mean``: normalised mean a clean record may show beyond its bound, in sigmas (slowly
    learnt states leave a small bias in the first updates). ``lag1``: lag-1 autocorrelation a
    clean record may show beyond its bound (the states' random walks correlate successive
    innovations). ``detect``: |t| beyond which a diagnosis (scale, clock) is reported.
    """

    level: float = 0.01
    nis: float = 0.5
    mean: float = 0.2
    lag1: float = 0.3
    detect: float = 8.0


@dataclass(frozen=True)
class ChannelFit:
    """One channel's figures: ``n`` updates, normalised innovation ``mean`` and ``rms``,
    ``nis_per_dof`` (= rms^2), ``lag1`` autocorrelation, and ``score``: the largest of the three
    figures' ratios to their limits (> 1: the channel does not fit)."""

    name: str
    n: int
    mean: float
    rms: float
    nis_per_dof: float
    lag1: float
    score: float


@dataclass(frozen=True)
class FitCheck:
    """The fit of one run: channels, the bounds they were judged by, the verdict and diagnosis."""

    channels: tuple[ChannelFit, ...]
    n_updates: int
    nis_per_dof: float
    nis_bound: float
    mean_bound: float
    lag1_bound: float
    tolerance: FitTolerance
    passed: bool
    worst: tuple[str, ...]
    diagnosis: tuple[str, ...] = field(default_factory=tuple)

    def as_dict(self) -> dict:
        """The ``fit`` block of a summary (plain numbers; ``verdict`` "passed" or "failed")."""
        return {
            "verdict": "passed" if self.passed else "failed",
            "convention": "normalised innovation e = innov / sqrt(S_ii); NIS per degree of freedom = mean(e^2), 1 expected",
            "n_updates": self.n_updates,
            "nis_per_dof": self.nis_per_dof,
            "bounds": {"nis_per_dof": self.nis_bound, "abs_mean": self.mean_bound, "abs_lag1": self.lag1_bound},
            "tolerance": asdict(self.tolerance),
            "worst_channels": list(self.worst),
            "diagnosis": list(self.diagnosis),
            "channels": [asdict(c) for c in self.channels],
        }

    def message(self) -> str:
        """One line for people: the worst channels and the diagnosis."""
        worst = ", ".join(f"{c.name} (NIS/dof {c.nis_per_dof:.3g}, mean {c.mean:+.3g}, lag-1 {c.lag1:+.3g})"
                          for c in self.channels if c.name in self.worst)
        diag = "; ".join(self.diagnosis) if self.diagnosis else "no unit, sign, swap or clock error recognised"
        return (f"the record does not fit the model: NIS per dof {self.nis_per_dof:.4g} (bound "
                f"{self.nis_bound:.4g} x {1 + self.tolerance.nis:g}); worst channels: {worst}; diagnosis: {diag}")


class FitSums:
    """The running sums the fit check's figures come from, so a run's innovations can be judged
    block by block (a streamed record) with the figures of the whole series: per channel the
    count, the sums of ``e`` and ``e^2`` and the lag-1 pair sums (pairs within a segment, across
    block boundaries too). :func:`fit_check` is its one-block case."""

    def __init__(self, m: int):
        z = lambda: np.zeros(m)  # noqa: E731
        self.n, self.se, self.see = 0, z(), z()
        self.na, self.sa, self.sb, self.saa, self.sbb, self.sab = 0, z(), z(), z(), z(), z()
        self.last_e: np.ndarray | None = None
        self.last_seg = None

    def add(self, innov: np.ndarray, s_var: np.ndarray, segment: np.ndarray | None = None) -> np.ndarray:
        """Add a block of innovations (N, m) and predicted variances (N, m) (rows with a
        non-finite or non-positive variance left out) with their segment labels (N,); returns
        the mask of rows used."""
        innov = np.asarray(innov, float)
        s_var = np.asarray(s_var, float)
        ok = np.all(np.isfinite(innov) & np.isfinite(s_var) & (s_var > 0), axis=1)
        e = innov[ok] / np.sqrt(s_var[ok])
        if e.shape[0] == 0:
            return ok
        seg = np.zeros(e.shape[0], int) if segment is None else np.asarray(segment)[ok]
        self.n += e.shape[0]
        self.se += e.sum(axis=0)
        self.see += (e * e).sum(axis=0)
        if self.last_e is not None:
            e_all, seg_all = np.vstack([self.last_e[None], e]), np.r_[self.last_seg, seg]
        else:
            e_all, seg_all = e, seg
        same = seg_all[1:] == seg_all[:-1]
        a, b = e_all[:-1][same], e_all[1:][same]
        self.na += a.shape[0]
        self.sa += a.sum(axis=0)
        self.sb += b.sum(axis=0)
        self.saa += (a * a).sum(axis=0)
        self.sbb += (b * b).sum(axis=0)
        self.sab += (a * b).sum(axis=0)
        self.last_e, self.last_seg = e[-1].copy(), seg[-1]
        return ok

    def lag1(self) -> np.ndarray:
        """(m,) lag-1 autocorrelation of ``e`` over the pairs within a segment (each pair's
        members centred on their own mean)."""
        na = max(self.na, 1)
        cov = self.sab - self.sa * self.sb / na
        den = np.sqrt(np.maximum(self.saa - self.sa * self.sa / na, 0.0) * np.maximum(self.sbb - self.sb * self.sb / na, 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, cov / np.where(den > 0, den, 1.0), 0.0)

    def check(self, names, tolerance: "FitTolerance" = None, diagnosis: tuple[str, ...] = ()) -> "FitCheck":
        """The verdict from the sums (see :func:`fit_check`); ``diagnosis`` is attached when the
        check fails."""
        tol = FitTolerance() if tolerance is None else tolerance
        n, m = self.n, self.se.size
        # Bonferroni: the check's false-alarm level is split over m channels x 3 figures
        lv = tol.level / (3 * m)
        nis_bound = chi2_quantile(1.0 - lv, n) / n if n else np.inf
        zq = normal_quantile(1.0 - lv / 2)
        mean_bound = zq / np.sqrt(max(n, 1))
        lag1_bound = zq / np.sqrt(max(n - 1, 1))
        mean = self.se / n if n else np.zeros(m)
        nis_c = self.see / n if n else np.zeros(m)
        lag1 = self.lag1() if n > 2 else np.zeros(m)
        # innovations far smaller than predicted (a noise-free record) are correlated but harmless:
        # the lag-1 figure counts in proportion to their share of the predicted variance
        score = np.maximum.reduce([nis_c / (nis_bound * (1 + tol.nis)), np.abs(mean) / (mean_bound + tol.mean),
                                   np.abs(lag1) * np.minimum(1.0, nis_c) / (lag1_bound + tol.lag1)])
        channels = tuple(ChannelFit(str(nm), n, float(mean[i]), float(np.sqrt(nis_c[i])), float(nis_c[i]),
                                    float(lag1[i]), float(score[i])) for i, nm in enumerate(names))
        passed = bool(n > 0 and np.all(score <= 1.0))
        order = np.argsort(-score, kind="stable")
        worst = tuple(str(names[i]) for i in order[:3] if score[i] > 1.0)
        return FitCheck(channels, n, float(nis_c.mean()) if n else float("nan"), nis_bound, mean_bound, lag1_bound,
                        tol, passed, worst, () if passed else tuple(diagnosis))


def lag1_autocorrelation(e: np.ndarray, segment: np.ndarray | None = None) -> np.ndarray:
    """(m,) lag-1 autocorrelation of each column of ``e`` (N, m), pairs taken only within a
    segment (``segment`` (N,) labels, e.g. the position; None: one segment)."""
    sums = FitSums(e.shape[1])
    sums.add(e, np.ones_like(e), segment)
    return sums.lag1()


def fit_check(innov: np.ndarray, s_var: np.ndarray, names, *, predicted: np.ndarray | None = None,
              nominal: np.ndarray | None = None, t: np.ndarray | None = None, segment: np.ndarray | None = None,
              tolerance: FitTolerance = FitTolerance()) -> FitCheck:
    """Per-channel fit statistics and the verdict of one run.

    ``innov`` (N, m): innovations (measurement minus prediction) in the measurement's unit;
    ``s_var`` (N, m): their predicted variances (the diagonal of S; a batch estimator: the
    residual variances); rows with a non-finite or non-positive variance (skipped updates) are
    left out. ``names`` (m,): the channels. ``predicted`` (N, m), ``t`` (N,) s and ``segment``
    (N,) labels (e.g. position) are optional: with ``predicted`` (the filter's prediction, so the
    measurement is ``innov + predicted``) the failed check is diagnosed (:func:`diagnose`), with
    ``t`` too a clock error can be recognised; ``segment`` keeps the autocorrelation and the time
    derivative within a segment. ``nominal`` (N, m): the model's output with the nominal (prior)
    coefficients, which the diagnosis regresses the measurement on instead of ``predicted``: a
    filter fed data that do not fit diverges, and its predictions then follow the data.
    The figures are those of :class:`FitSums` over the whole series at once.
    """
    innov = np.asarray(innov, float)
    s_var = np.asarray(s_var, float)
    sums = FitSums(innov.shape[1])
    ok = sums.add(innov, s_var, segment)
    fit = sums.check(names, tolerance)
    if not fit.passed and predicted is not None:
        seg = None if segment is None else np.asarray(segment)[ok]
        pred = np.asarray(predicted, float)[ok]
        ref = pred if nominal is None else np.asarray(nominal, float)[ok]
        diagnosis = tuple(diagnose(innov[ok] + pred, ref, s_var[ok], names, None if t is None else np.asarray(t)[ok],
                                   seg, tolerance.detect, innov[ok]))
        fit = replace(fit, diagnosis=diagnosis)
    return fit


def time_derivative(y: np.ndarray, t: np.ndarray, segment: np.ndarray | None = None) -> np.ndarray:
    """dy/dt of each column of ``y`` (N, m) at the instants ``t`` (N,), s, within each segment
    (central differences; 0 in a segment of one instant)."""
    out = np.zeros_like(y)
    seg = np.zeros(len(t), int) if segment is None else segment
    bounds = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1], True])
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a > 1 and np.all(np.diff(t[a:b]) > 0):
            out[a:b] = np.gradient(y[a:b], t[a:b], axis=0)
    return out


def scale_meaning(a: float, rel: float = 0.05) -> str | None:
    """What a measurement/prediction ratio ``a`` means (a unit, a sign) or None when it is near 1."""
    for s, label in UNIT_SCALES:
        for v, how in ((s, "times"), (1.0 / s, "divided by")):
            if abs(abs(a) / v - 1.0) < rel:
                sign = ", sign flipped" if a < 0 else ""
                return f"unit: measured = {how} {s:.6g} x predicted ({label}){sign}"
    if abs(a + 1.0) < 0.2:
        return "sign: measured = -predicted (sign flipped)"
    return None


def gross_errors(z: np.ndarray, predicted: np.ndarray, names) -> list[tuple[int, str]]:
    """``(channel, what)`` for each channel of ``z`` (N, m) that is a recognisable transform of the
    model's ``predicted`` (N, m): regressed on every channel's prediction (no constant: a bias is
    small beside a unit, a sign or a swap), a coefficient near one of :data:`UNIT_SCALES` (or its
    inverse) on its own prediction is a unit, near -1 a sign, near +-1 on another channel's
    prediction with its own near 0 a swap. Only channels whose prediction is not negligible (RMS
    above 5 % of the largest) are judged or used as regressors; when their predictions are
    collinear each channel is compared with its own prediction only (no swap)."""
    return gross_errors_moments(Moments.of(z, predicted), names)


@dataclass
class Moments:
    """Sums of a record's channels ``z`` (N, m) against the model's predictions ``p`` (N, m):
    ``n``, ``pp`` = sum p p^T, ``pz`` = sum p z^T (m, m), ``zz`` = sum z^2 (m,); the regression of
    :func:`gross_errors` needs no more, so a streamed record adds them block by block."""

    n: int
    pp: np.ndarray
    pz: np.ndarray
    zz: np.ndarray

    @classmethod
    def zero(cls, m: int) -> "Moments":
        return cls(0, np.zeros((m, m)), np.zeros((m, m)), np.zeros(m))

    @classmethod
    def of(cls, z: np.ndarray, p: np.ndarray) -> "Moments":
        out = cls.zero(np.asarray(z).shape[1])
        out.add(z, p)
        return out

    def add(self, z: np.ndarray, p: np.ndarray) -> None:
        z, p = np.asarray(z, float), np.asarray(p, float)
        self.n += z.shape[0]
        self.pp += p.T @ p
        self.pz += p.T @ z
        self.zz += (z * z).sum(axis=0)

    def rms(self) -> tuple[np.ndarray, np.ndarray]:
        """(RMS of each channel of z, of p)."""
        n = max(self.n, 1)
        return np.sqrt(self.zz / n), np.sqrt(np.diag(self.pp) / n)


def gross_errors_moments(mo: Moments, names) -> list[tuple[int, str]]:
    """:func:`gross_errors` from the sums :class:`Moments` (least squares by its normal equations)."""
    names = [str(n) for n in names]
    m = mo.pp.shape[0]
    rms = mo.rms()[1]
    active = np.flatnonzero(rms > 0.05 * rms.max()) if rms.max() > 0 else np.array([], int)
    if active.size == 0:
        return []
    A = mo.pp[np.ix_(active, active)]
    coef = np.zeros((m, m))  # coef[:, i] explains channel i
    # the normal equations square the predictions' condition: collinear predictions (e.g. constant
    # columns) leave eigenvalues at rounding level, so rank is judged at 1e-12 of the largest
    # (singular values of the predictions 1e-6 apart), not at machine precision
    eig = np.linalg.eigvalsh(A)
    if eig.min() > 1e-12 * eig.max():
        coef[active] = np.linalg.solve(A, mo.pz[active])
    else:
        for i in active:
            coef[i, i] = float(mo.pz[i, i] / mo.pp[i, i])
    out = []
    for i in active:
        a = coef[:, i]
        own = a[i]
        others = [j for j in active if j != i and abs(abs(a[j]) - 1.0) < 0.2]
        if abs(own) < 0.2 and others:
            j = others[0]
            out.append((int(i), f"swap: {names[i]} follows the prediction of {names[j]} (coefficient {a[j]:+.3g}; "
                                f"its own {own:+.3g})"))
            continue
        meaning = scale_meaning(own)
        if meaning is not None:
            out.append((int(i), f"{names[i]}: {meaning} (regression coefficient {own:.5g})"))
    return out


def diagnose(z: np.ndarray, predicted: np.ndarray, s_var: np.ndarray, names, t: np.ndarray | None = None,
             segment: np.ndarray | None = None, detect: float = 8.0, innov: np.ndarray | None = None) -> list[str]:
    """What is wrong with the channels of a record that does not fit, from its measurements ``z``
    and the model's predictions ``predicted`` (N, m), their variances ``s_var`` (N, m), the
    instants ``t`` (N,) s (for a clock) and segment labels.

    Units, signs and swaps as :func:`gross_errors` finds them. Otherwise the innovation is
    regressed on the prediction's time derivative: a significant slope (|t| > ``detect``) is a clock offset, a significant growth of the squared innovation
    with the squared derivative a timestamp jitter (its RMS in s). ``innov`` (N, m): the filter's
    innovations for the clock test (default ``z - predicted``).
    """
    m = z.shape[1]
    found = gross_errors(z, predicted, names)
    out = [text for _, text in found]
    explained = {i for i, _ in found}
    if t is None or explained:
        # a filter fed a unit, sign or swap error diverges and every channel's innovation with
        # it: a clock is looked for only when nothing grosser was found
        return out
    d = time_derivative(predicted, t, segment)
    innov = z - predicted if innov is None else innov
    for i in range(m):
        di, ri, si = d[:, i], innov[:, i], s_var[:, i]
        dd = float(np.sum(di * di))
        if dd <= 0:
            continue
        tau = float(np.sum(ri * di) / dd)
        # the offset's standard error from the residuals themselves (a jitter inflates them)
        tau_se = float(np.sqrt(np.sum(ri * ri * di * di)) / dd)
        if abs(tau) > detect * tau_se:
            out.append(f"clock: {names[i]}'s innovation follows the prediction's rate of change, a time offset of "
                       f"{tau:.3g} s")
            continue
        d4 = float(np.sum(di**4))
        jit2 = float(np.sum((ri * ri - si) * di * di) / d4)
        jit_se = float(np.sqrt(np.sum(2 * si * si * di**4)) / d4)
        if jit2 > detect * jit_se:
            out.append(f"clock: {names[i]}'s innovation grows with the prediction's rate of change, a timestamp "
                       f"jitter of about {np.sqrt(jit2):.3g} s RMS")
    return out


def fit_exit_status(fit: FitCheck | None, data, out, summary_file: str = "summary.json") -> int:
    """The exit status of ``platcal identify`` from its fit check: 0 when the record fits (or no
    check ran), else :data:`EXIT_DOES_NOT_FIT` after one line on stderr naming the record
    ``data``, the worst channels and the diagnosis, and the folder ``out`` written anyway (its
    ``summary_file`` holds the fit block)."""
    if fit is None or fit.passed:
        return 0
    print(f"platcal identify: error: --data {data}: {fit.message()}. The outputs in {out} are written and marked "
          f"'fit: failed' in {summary_file}.", file=sys.stderr)
    return EXIT_DOES_NOT_FIT
