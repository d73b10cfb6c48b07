"""The open-loop run and stop (ZUPT) Kalman filters (docs/rocket-sled.md §6), batched over seeds.

Discretisation ``Φ = I + F T + (F T)²/2``, ``Q_d = diag(q)·T`` (default tuning) or
``1e-9·I`` per step (paper tuning); measurement ``z = H x + v`` with ``H = [I₄ 0]``; the update
is the shared Joseph-form update of :mod:`platcal.estimation.kalman` (exactly symmetric P; the
same numbers as §6's standard update with the covariance symmetrised, to rounding). Epoch convention: the
filter epochs are the navigation states k = m·j (m = IMU samples per filter period); the state
at j = 0 is the prior (x = 0 for the run filter), and each later epoch is a prediction over
the preceding m samples, with F from the mean computed specific force over them, then an
update with the navigation values at k = m·j.

Recorded times (§12): the epochs are the samples nearest the multiples of the filter period
(:class:`Epochs`, decimation by time); each prediction spans the actual interval T_j between its
epochs (Φ and, with the default tuning, Q_d = diag(q)·T_j), F uses the interval-weighted mean
force of the samples in between. On a clean record this is exactly the grid above.

Speed (issue 22 item 2): the filters run with the seeds in SIMD lanes (:mod:`.filter_lanes`),
each epoch's F formed in the kernel from the mean force (:class:`Dynamics`) and Φ's zero products
left out; every sum in the order of the one-seed kernel :func:`_kalman`, whose numbers it gives
bit for bit (``tests/sled/test_sled_lanes.py``; ``benchmarks/profile_sled.py``). An identify on
kernels compiled ahead of time (:mod:`.aot_kernels`) runs :func:`_kalman` itself, a seed at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ...estimation.kalman import joseph_update_sparse, propagate_sparse
from ...jit import njit
from ...rig import resolve
from .aot_kernels import run_seeds, seed_kernel
from .config import SledConfig
from .errmodel import RUN6_KIND, RUN7_KIND, STOP_KIND, kind_states, system_matrices

KALMAN_LANES = f"{__package__}.filter_lanes:kalman_lanes"
"""The JIT's filter of the seeds in SIMD lanes (:func:`.filter_lanes.kalman_lanes`), by path:
imported only when a batch runs on the JIT."""

Q_VEL = 2e-3   # m/s/sqrt(s): absorbs the unmodelled accelerometer bias and noise (§6.1, D4)
Q_ATT = 1e-7   # rad/sqrt(s)
SIG_PHI = (3e-4, 3e-4, 2e-3)   # rad, P0 of φ_x, φ_y, φ_z (§6.1)


@dataclass(frozen=True)
class Tuning:
    """P0 (n,n), Q per step (n,n) and R (4,4) of one filter (SI units, rad). ``per_step``: Q is
    per filter step whatever its length (paper tuning); otherwise it is for the nominal period
    and scales with each step's actual length."""

    P0: np.ndarray
    Qd: np.ndarray
    R: np.ndarray
    per_step: bool = False


@dataclass(frozen=True)
class Epochs:
    """Filter epochs of a record: ``k`` (J+1,) sample indices (increasing, k[0] = 0), ``T`` (J,)
    the intervals between them (s), ``dts`` (N,) the interval each sample covers (s)."""

    k: np.ndarray
    T: np.ndarray
    dts: np.ndarray

    @staticmethod
    def grid(n: int, m: int, dt: float) -> "Epochs":
        """The clean grid: every m-th of n samples, dt apart."""
        k = m * np.arange((n - 1) // m + 1)
        return Epochs(k=k, T=np.full(k.size - 1, m * dt), dts=np.full(n, dt))


@dataclass(frozen=True)
class FilterOut:
    """Posterior estimates at the filter epochs: x (S,J+1,n), sigma = sqrt(diag P) (S,J+1,n), P final
    (S,n,n); mean NIS of the updates (S,) (4 degrees of freedom each) and updates skipped because
    the innovation covariance was not positive definite (S,); the innovations and their predicted
    variances per update, for the fit check (docs/rocket-sled.md §6)."""

    x: np.ndarray
    sigma: np.ndarray
    P: np.ndarray
    mean_nis: np.ndarray
    failed_updates: np.ndarray
    innov: np.ndarray | None = None   # (S,J,4) innovations z - x_pred[:4] of the updates, SI units
    s_var: np.ndarray | None = None   # (S,J,4) their predicted variances diag(S); NaN where skipped


def _R(cfg: SledConfig) -> np.ndarray:
    return np.diag([cfg.r_velocity, cfg.r_position, cfg.r_velocity, cfg.r_position]) ** 2


def run_tuning(cfg: SledConfig, states: int) -> Tuning:
    """§6.1: default tuning, or the paper's literal P0 = I, Q_d = 1e-9 I, R = 1e6 I."""
    T = cfg.period_ms / 1000.0
    if cfg.tuning == "paper":
        return Tuning(np.eye(states), 1e-9 * np.eye(states), 1e6 * np.eye(4), per_step=True)
    sphi = SIG_PHI if states == 7 else SIG_PHI[1:]
    P0 = np.diag(np.r_[[0.01] * 4, sphi] ** 2)
    q = np.r_[Q_VEL ** 2, 0.0, Q_VEL ** 2, 0.0, [Q_ATT ** 2] * (states - 4)]
    return Tuning(P0, np.diag(q) * T, _R(cfg))


def stop_tuning(cfg: SledConfig, p_run_phiy: np.ndarray) -> Tuning:
    """§6.2: P0 = diag(0.005, 0.005, 0.005, 0.001, 3e-4, sqrt(P_run,φy + 1e-8))², same q, R.

    ``p_run_phiy`` (S,) is the run filter's final φ_y variance, so P0 is per seed (S,6,6).
    """
    S = len(p_run_phiy)
    if cfg.tuning == "paper":
        return Tuning(np.broadcast_to(np.eye(6), (S, 6, 6)).copy(), 1e-9 * np.eye(6), 1e6 * np.eye(4), per_step=True)
    T = cfg.period_ms / 1000.0
    sig = np.zeros((S, 6))
    sig[:] = [0.005, 0.005, 0.005, 0.001, 3e-4, 0.0]
    sig[:, 5] = np.sqrt(p_run_phiy + 1e-4 ** 2)
    P0 = np.einsum("si,ij->sij", sig ** 2, np.eye(6))
    q = np.r_[Q_VEL ** 2, 0.0, Q_VEL ** 2, 0.0, Q_ATT ** 2, Q_ATT ** 2]
    return Tuning(P0, np.diag(q) * T, _R(cfg))


def discretise(F: np.ndarray, T) -> np.ndarray:
    """Φ = I + F T + (F T)²/2 (§6), batched; ``T`` (s) scalar or one per step (J,) for F (S,J,n,n)."""
    T = np.asarray(T, dtype=float)
    FT = F * (T[..., None, None] if T.ndim else T)
    return np.eye(F.shape[-1]) + FT + FT @ FT / 2


@njit(cache=True)
def _kalman(Fs, Ts, z, X, PP, Qd, r_var, xs, sig, acc, failed, innov_out, svar_out):
    """Predict with the dense Φ = I + F T + (F T)²/2 of each epoch's ``Fs`` (S,J,n,n) over its
    step ``Ts`` (J,) s (:func:`discretise`, formed here: every row of Φ is dynamic, the shared
    sparse propagation with all rows), then the shared Joseph-form update with ``H = [I_m 0]`` (m = 4, diagonal R), from
    the state ``X`` (S,n), ``PP`` (S,n,n), updated in place to the state after the last epoch
    (a long record's next block of epochs continues from it). ``xs``, ``sig`` (S,J,n) receive
    the posteriors. An update whose innovation covariance is not positive definite is skipped
    and counted in ``failed`` (S,); ``acc`` (S,2) sums the NIS of the updates made and counts
    them (m degrees of freedom each). ``innov_out``, ``svar_out`` (S,J,m) receive each update's
    innovation and diag(S) = diag(P_pred) + R (H = [I_m 0]); NaN variances where the update was
    skipped."""
    S, J, n = Fs.shape[0], Fs.shape[1], Fs.shape[2]
    m = z.shape[2]
    rows = np.arange(n)
    Phi = np.empty((n, n))
    FT = np.empty((n, n))
    hcols = np.arange(m).reshape(m, 1)   # row r of H is 1 at state r: z observes the first m states
    hnnz = np.ones(m, dtype=np.int64)
    hval = np.ones((m, 1))
    x = np.empty(n)
    xn = np.empty(n)
    P = np.empty((n, n))
    W = np.empty((n, n))
    blk = np.empty((n, n))
    U = np.empty((m, n))
    K = np.empty((m, n))
    D = np.empty((m, n))
    Sm = np.empty((m, m))
    Sinv = np.empty((m, m))
    nu = np.empty(m)
    innov = np.empty(m)
    for s in range(S):
        x[:] = X[s]
        P[:, :] = PP[s]
        total = acc[s, 0]
        made = acc[s, 1]
        for j in range(J):
            for a in range(n):
                for b in range(n):
                    FT[a, b] = Fs[s, j, a, b] * Ts[j]
            for a in range(n):
                for b in range(n):
                    sq = 0.0
                    for c in range(n):
                        sq += FT[a, c] * FT[c, b]
                    Phi[a, b] = ((1.0 if a == b else 0.0) + FT[a, b]) + sq / 2
            for a in range(n):
                v = 0.0
                for b in range(n):
                    v += Phi[a, b] * x[b]
                xn[a] = v
            x[:] = xn
            propagate_sparse(P, rows, rows, Phi, Qd[j], W, blk)
            for b in range(m):
                innov[b] = z[s, j, b] - x[b]
                innov_out[s, j, b] = innov[b]
                svar_out[s, j, b] = P[b, b] + r_var[b]
            if joseph_update_sparse(x, P, hcols, hnnz, hval, innov, r_var, U, K, D, Sm, Sinv, nu, True):
                for b in range(m):
                    total += nu[b] * nu[b]
                made += 1.0
            else:
                failed[s] += 1
                for b in range(m):
                    svar_out[s, j, b] = np.nan
            for i in range(n):
                xs[s, j, i] = x[i]
                sig[s, j, i] = np.sqrt(max(P[i, i], 0.0))
        X[s] = x
        PP[s] = P
        acc[s, 0] = total
        acc[s, 1] = made


@dataclass(frozen=True)
class Dynamics:
    """The system matrices of a filter's predictions given by what they are formed from
    (:func:`.errmodel.fill_F`): the ``kind`` (run with 7 or 6 states, stop), the mean computed
    specific force ``f`` (S,J,3) m/s^2 of each prediction and the rates ``w``, ``wc`` (3,) rad/s.
    The lanes kernel forms each epoch's F from these rather than reading an (S,J,n,n) array."""

    kind: int
    f: np.ndarray
    w: np.ndarray
    wc: np.ndarray

    @staticmethod
    def run(f: np.ndarray, omega_ie: np.ndarray, states: int) -> "Dynamics":
        """The run filter's (§6.1): F of :func:`.errmodel.run_F` with w = wc = ω_ie."""
        return Dynamics(RUN7_KIND if states == 7 else RUN6_KIND, f, omega_ie, omega_ie)

    @staticmethod
    def stop(f: np.ndarray, omega_ie: np.ndarray) -> "Dynamics":
        """The stop filter's (§6.2): F of :func:`.errmodel.stop_F` with w = wc = ω_ie."""
        return Dynamics(STOP_KIND, f, omega_ie, omega_ie)

    @property
    def shape(self) -> tuple[int, int, int, int]:
        n = kind_states(self.kind)
        return self.f.shape[0], self.f.shape[1], n, n

    def dense(self) -> np.ndarray:
        """F (S,J,n,n) as one array (the reference kernel's and FilterPy's input)."""
        return system_matrices(self.kind, self.f, self.w, self.wc)


@lru_cache(maxsize=None)
def _structure(kind: int) -> tuple[np.ndarray, ...]:
    """Where the matrices of ``kind`` can be nonzero (F at generic values): F's entries ``fa``,
    ``fb``; Φ = I + F T + (F T)²/2's entries ``pa``, ``pb`` with, for each, the c of the nonzero
    terms of (F T)²'s sum, ``pcs[pptr[p]:pptr[p + 1]]`` (increasing); Φ's rows, ``rcols[rptr[a]:
    rptr[a + 1]]``. Every other product or entry is zero whatever the force, so leaving it out of
    a sum changes no sum of finite numbers (a sum from 0.0 is never −0: ±0 terms leave it alone)."""
    n = kind_states(kind)
    nz = system_matrices(kind, np.array([1.1, 1.3, 1.7]), np.array([0.3, 0.5, 0.7]),
                         np.array([0.2, 0.4, 0.6])) != 0
    fa, fb = np.nonzero(nz)
    pa, pb, pptr, pcs = [], [], [0], []
    phi = np.zeros((n, n), dtype=bool)
    for a in range(n):
        for b in range(n):
            terms = [c for c in range(n) if nz[a, c] and nz[c, b]]
            if a == b or nz[a, b] or terms:
                pa.append(a)
                pb.append(b)
                pcs += terms
                pptr.append(len(pcs))
                phi[a, b] = True
    rptr = np.r_[0, np.cumsum(phi.sum(axis=1))]
    rcols = np.nonzero(phi)[1]
    return tuple(np.ascontiguousarray(v, dtype=np.int64) for v in (fa, fb, pa, pb, pptr, pcs, rptr, rcols))


class KalmanRun:
    """One open-loop linear KF (§6) stepped over blocks of epochs (:meth:`step`), its state x, P,
    the NIS sum and the skipped updates carried from block to block, so a long record's stop
    filter runs in bounded memory with the numbers of one pass (:func:`kalman` is its one-block
    case). ``x0`` (S,n) and ``tun.P0`` ((n,n) or (S,n,n)) are the state at epoch 0; ``tun.Qd``
    is for ``T_nominal`` s (None: every step's own) and scales with each step's length unless
    ``tun.per_step``; ``threads`` for the lanes kernel (None: the numba threads set)."""

    def __init__(self, x0: np.ndarray, tun: Tuning, T_nominal: float | None = None, threads: int | None = None):
        S, n = x0.shape
        self.threads = threads
        self.x = np.ascontiguousarray(x0, dtype=np.float64).copy()
        self.P = np.ascontiguousarray(np.broadcast_to(tun.P0, (S, n, n)), dtype=np.float64).copy()
        R = np.asarray(tun.R, dtype=np.float64)
        if np.count_nonzero(R - np.diag(np.diag(R))):
            raise ValueError("the sled filters' R must be diagonal (the shared update takes variances)")
        self.r_var = np.ascontiguousarray(np.diag(R))
        self.tun, self.T_nominal = tun, T_nominal
        self.acc = np.zeros((S, 2))
        self.failed = np.zeros(S, dtype=np.int64)

    def prior(self) -> tuple[np.ndarray, np.ndarray]:
        """The current state and its sigma, (S,n) each."""
        return self.x.copy(), np.sqrt(np.diagonal(self.P, axis1=1, axis2=2))

    def step(self, Fs, z: np.ndarray, T, with_prior: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                              np.ndarray]:
        """The next J epochs: ``Fs`` the system matrices per prediction, :class:`Dynamics` (the
        seeds in lanes, :func:`.filter_lanes.kalman_lanes`; a seed at a time on the dense F where the
        identify's kernels are compiled ahead of time, :mod:`.aot_kernels`) or an (S,J,n,n) array (the
        one-seed-at-a-time :func:`_kalman`; the same numbers), ``z`` (S,J,4) per update, ``T`` the step (s) or (J,)
        the record's steps. Returns the posteriors x, sigma (S,J,n) (``with_prior``: (S,J+1,n),
        the state before the step first) and the innovations and their predicted variances (S,J,4)."""
        S, J, n = Fs.shape[0], Fs.shape[1], Fs.shape[-1]
        T = np.broadcast_to(np.asarray(T, dtype=float), (J,))
        scale = np.ones(J) if self.tun.per_step or self.T_nominal is None else T / self.T_nominal
        Qs = np.ascontiguousarray(np.asarray(self.tun.Qd, dtype=np.float64)[None] * scale[:, None, None])
        m = z.shape[2]
        innov, s_var = np.empty((S, J, m)), np.empty((S, J, m))
        z = np.ascontiguousarray(z, dtype=np.float64)
        one = seed_kernel("kalman", _kalman)
        if isinstance(Fs, Dynamics) and one is None:   # the seeds in lanes: the reference's numbers
            # by path: the lanes kernel's compiler pipeline subclasses numba's, which an identify
            # on kernels compiled ahead of time does not load
            kalman_lanes = resolve(KALMAN_LANES)
            off = int(with_prior)      # the kernel writes the posteriors after the prior's slot
            xs, sig = np.empty((S, J + off, n)), np.empty((S, J + off, n))
            if with_prior:
                xs[:, 0], sig[:, 0] = self.prior()
            kalman_lanes(Fs, np.ascontiguousarray(T), z, self.x, self.P, Qs, self.r_var, xs, sig, self.acc,
                         self.failed, innov, s_var, self.threads)
            return xs, sig, innov, s_var
        if isinstance(Fs, Dynamics):   # ahead of time: the one-seed kernel, whose numbers the lanes give
            Fs = Fs.dense()
        x_prior, sig_prior = self.prior()
        xs, sig = np.empty((S, J, n)), np.empty((S, J, n))
        Fs, T = np.ascontiguousarray(Fs, dtype=np.float64), np.ascontiguousarray(T)
        if one is None:
            _kalman(Fs, T, z, self.x, self.P, Qs, self.r_var, xs, sig, self.acc, self.failed, innov, s_var)
        for s in range(S) if one is not None else ():   # a seed at a time (.aot_kernels): first-axis views
            i = slice(s, s + 1)
            one(Fs[i], T, z[i], self.x[i], self.P[i], Qs, self.r_var, xs[i], sig[i], self.acc[i], self.failed[i],
                innov[i], s_var[i])
        if with_prior:
            xs, sig = np.concatenate([x_prior[:, None], xs], axis=1), np.concatenate([sig_prior[:, None], sig], axis=1)
        return xs, sig, innov, s_var

    def mean_nis(self) -> np.ndarray:
        """(S,) mean NIS of the updates made so far (NaN: none)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.acc[:, 1] > 0, self.acc[:, 0] / np.where(self.acc[:, 1] > 0, self.acc[:, 1], 1), np.nan)


def kalman(Fs, z: np.ndarray, x0: np.ndarray, tun: Tuning, T, T_nominal: float | None = None) -> FilterOut:
    """Open-loop linear KF over epochs: ``Fs`` per prediction (:class:`Dynamics` or (S,J,n,n), as
    :meth:`KalmanRun.step` takes it), ``z`` (S,J,4) per update.

    ``x0`` (S,n) and ``tun.P0`` ((n,n) or (S,n,n)) are the state at epoch 0. ``T``: the step (s),
    or (J,) the actual steps of a record; ``tun.Qd`` is for ``T_nominal`` (default ``T``) and
    scales with each step unless ``tun.per_step``. Returns the posteriors at epochs 0 … J (one
    numba kernel looping over seeds and epochs: one :class:`KalmanRun` step).
    """
    run = KalmanRun(x0, tun, T_nominal)
    xs, sig, innov, s_var = run.step(Fs, z, T, with_prior=True)
    return FilterOut(xs, sig, run.P, run.mean_nis(), run.failed, innov, s_var)


@njit(cache=True, nogil=True)
def _pairwise(fl, s, c, dts, a, n):
    """The sum of ``fl[s, a + i, c] * dts[a + i]`` for i < n in the order of numpy's pairwise
    summation (``pairwise_sum`` of numpy/_core/src/umath/loops_utils.h: sequential below 8
    terms, 8 accumulators up to 128, halves above), which ``np.add.reduceat`` uses after a
    segment's first term: :func:`epoch_mean`'s numbers as numpy formed them."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += fl[s, a + i, c] * dts[a + i]
        return res
    if n <= 128:
        r0 = fl[s, a, c] * dts[a]
        r1 = fl[s, a + 1, c] * dts[a + 1]
        r2 = fl[s, a + 2, c] * dts[a + 2]
        r3 = fl[s, a + 3, c] * dts[a + 3]
        r4 = fl[s, a + 4, c] * dts[a + 4]
        r5 = fl[s, a + 5, c] * dts[a + 5]
        r6 = fl[s, a + 6, c] * dts[a + 6]
        r7 = fl[s, a + 7, c] * dts[a + 7]
        i = 8
        while i < n - n % 8:
            r0 += fl[s, a + i, c] * dts[a + i]
            r1 += fl[s, a + i + 1, c] * dts[a + i + 1]
            r2 += fl[s, a + i + 2, c] * dts[a + i + 2]
            r3 += fl[s, a + i + 3, c] * dts[a + i + 3]
            r4 += fl[s, a + i + 4, c] * dts[a + i + 4]
            r5 += fl[s, a + i + 5, c] * dts[a + i + 5]
            r6 += fl[s, a + i + 6, c] * dts[a + i + 6]
            r7 += fl[s, a + i + 7, c] * dts[a + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += fl[s, a + i, c] * dts[a + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise(fl, s, c, dts, a, n2) + _pairwise(fl, s, c, dts, a + n2, n - n2)



@njit(cache=True, nogil=True)
def _epoch_mean(lo, hi, fl, k, dts, den, out):
    """:func:`epoch_mean` for seeds ``lo .. hi - 1``: each segment's first term, then the
    pairwise sum of the rest (np.add.reduceat's order), over its summed intervals ``den``."""
    for s in range(lo, hi):
        for i in range(k.shape[0] - 1):
            a, b = k[i], k[i + 1]
            for c in range(3):
                out[s, i, c] = (fl[s, a, c] * dts[a] + _pairwise(fl, s, c, dts, a + 1, b - a - 1)) / den[i]


def epoch_mean(fl: np.ndarray, ep: Epochs, j0: int, j1: int) -> np.ndarray:
    """Mean computed specific force over the samples of predictions j0+1 … j1 (S, j1−j0, 3),
    each sample weighted by the interval it covers (equal weights on a clean record): the
    interval-weighted sums of ``np.add.reduceat`` over the summed intervals, formed in one
    compiled loop per seed (the seeds over the numba threads set) in numpy's order."""
    k = np.ascontiguousarray(ep.k[j0:j1 + 1], dtype=np.int64)
    dts = np.ascontiguousarray(ep.dts, dtype=np.float64)
    den = np.add.reduceat(dts[k[0]:k[-1]], k[:-1] - k[0])
    fl = np.ascontiguousarray(fl, dtype=np.float64)
    out = np.empty((fl.shape[0], k.size - 1, 3))
    run_seeds("epoch_mean", _epoch_mean, fl.shape[0], fl, k, dts, den, out)
    return out


def run_filter(cfg: SledConfig, fl: np.ndarray, v: np.ndarray, r: np.ndarray, j_stop: int,
               ep: Epochs | None = None) -> FilterOut:
    """Run filter from t = 0 to the stop epoch ``j_stop`` (§6.1), ``cfg.states`` states.

    ``v, r`` navigation states (S,N+1,3); measurements ``[v_y, r_y, v_z, r_z]`` of the nav;
    ``ep`` the record's epochs (default: the clean grid).
    """
    ep = Epochs.grid(fl.shape[1], cfg.kf_every, cfg.dt) if ep is None else ep
    T = cfg.period_ms / 1000.0
    Fs = Dynamics.run(epoch_mean(fl, ep, 0, j_stop), cfg.omega_ie, cfg.states)
    k = ep.k[1:j_stop + 1]
    z = np.stack([v[:, k, 1], r[:, k, 1], v[:, k, 2], r[:, k, 2]], axis=-1)
    x0 = np.zeros((fl.shape[0], cfg.states))
    return kalman(Fs, z, x0, run_tuning(cfg, cfg.states), ep.T[:j_stop], T)


def stop_filter(cfg: SledConfig, fl: np.ndarray, v: np.ndarray, r: np.ndarray, j_stop: int, j_end: int,
                phi_y_run: np.ndarray, p_phi_y_run: np.ndarray, ep: Epochs | None = None) -> FilterOut:
    """Stop (ZUPT) filter from ``j_stop`` to ``j_end`` (§6.2).

    z = ``[v_y, r_y, v_x, r_x − r_x(t_stop)]``; initial state from the nav values at the stop,
    δr_x = 0, φ_x = 0, φ_y = the run filter's final estimate.
    """
    ep = Epochs.grid(fl.shape[1], cfg.kf_every, cfg.dt) if ep is None else ep
    T = cfg.period_ms / 1000.0
    ks = ep.k[j_stop]
    Fs = Dynamics.stop(epoch_mean(fl, ep, j_stop, j_end), cfg.omega_ie)
    k = ep.k[j_stop + 1:j_end + 1]
    z = np.stack([v[:, k, 1], r[:, k, 1], v[:, k, 0], r[:, k, 0] - r[:, ks, None, 0]], axis=-1)
    x0 = np.zeros((fl.shape[0], 6))
    x0[:, 0], x0[:, 1], x0[:, 2] = v[:, ks, 1], r[:, ks, 1], v[:, ks, 0]
    x0[:, 5] = phi_y_run
    return kalman(Fs, z, x0, stop_tuning(cfg, p_phi_y_run), ep.T[j_stop:j_end], T)
