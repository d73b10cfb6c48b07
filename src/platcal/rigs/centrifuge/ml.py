"""Batch maximum-likelihood (MAP) identification of the centrifuge test (issue 9 item 3), batched.

Parameters (``n = nc + 3 K``): the ``nc`` estimated coefficients (45, or 48 with
``estimate_doo``; docs/centrifuge-model.md §9's order and engineering units), then the initial
angles alpha, beta, gamma (rad) of each of the K positions: the attitude at time 0 of position
k, the instant of the reset (docs/centrifuge-model.md §9). Within a position the attitude follows
eq. 18 deterministically from those angles, integrated by the model's RK4 from instant to instant
(:func:`platcal.rigs.centrifuge.attitude.rk4_jac_sc`; from 0 to ``t[0]`` first, unless ``t[0] == 0``); the
prediction of each sample is eq. 13 at the propagated angles.

Prior (MAP): coefficients ``N(0, diag(p0_sigma^2))``, initial angles ``N(commanded,
sigma_set^2)`` per angle, as the EKF's initial state and resets.

Process noise, included exactly for the linearised model: the gyro angle random walk (Q =
ARW^2 per second per axis, as the EKF's) moves the true attitude away from the deterministic
trajectory by a random walk ``d`` (``d(0) = 0``: the initial angle is a parameter;
``d_m = Phi_a,m d_m-1 + w_m``), so the samples' errors ``H_a d_m + v_m`` are correlated in time.
A 3-state Kalman filter of ``d`` (measurement Jacobian ``H_a``, noise R) whitens them: its
innovations of the residual ``r = z - h(theta)`` and of every column of the residual's Jacobian
``J`` (the same linear filter, gain independent of the data) are white with covariance S, so

    N = sum_m Jt_m' S_m^-1 Jt_m,   g = sum_m Jt_m' S_m^-1 nu_m,   c = sum_m nu_m' S_m^-1 nu_m

are the Gauss-Newton normal equations of the exact likelihood of the linearised model (the
prediction-error decomposition; ``log det S`` is constant to first order and left out). With
ARW 0 the filter stays at zero and this is plain weighted least squares with R. ``c / (3 M)``
at the estimate is the mean NIS.

Sensitivities: ``d angle(t_m) / d [angle(0), gyro coef]`` are the chained per-step Jacobians of
the RK4 map (``Phi_a <- phi_a Phi_a``, ``Phi_g <- phi_a Phi_g + phi_g``), and
``J_m = [H_c + H_a Phi_g | H_a Phi_a]`` with H from :func:`platcal.rigs.centrifuge.attitude.measure_jac_sc`.

Solver: :func:`platcal.estimation.gauss_newton.solve_map` (Gauss-Newton, optionally
Levenberg-Marquardt), started from zero coefficients (``start='zero'``, the EKF's initial state)
or from a one-pass EKF's estimate (``start='ekf'``), initial angles at the commanded ones. The
covariance is the inverse of the information plus the prior's at the estimate. Cheaper variant
(``coarse=16, final='one-step'``): converge first on every 16th instant (1/16 of the cost per
step; the RK4 then steps 0.32 s, a sixth of the centrifuge's period at 180 deg/s, so keep
``coarse * period`` well below the period), then take one Gauss-Newton step on the whole record
(Le Cam's one-step estimator: from a consistent start, one Newton step is as efficient as the
converged ML), with the covariance at the preliminary estimate.

Returned :class:`~platcal.rigs.centrifuge.ekf.Estimate`: ``x`` holds the coefficients and the
**initial** angles (time 0) of the **last** position, ``P`` the matching block of the full
covariance (the other positions' angles marginalised); one "pass"; no history; ``mean_nis``
from the whitened innovations at the estimate; ``failed_updates`` counts instants whose
innovation covariance was not positive definite (none expected).

Batched over replicates: each replicate's normal equations come from one sequential kernel in its
own ``prange`` iteration and each is solved on its own, so the numbers do not depend on the batch
size or on the number of threads.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from ...jit import njit, parallel_chunksize, prange
from ...parallel import get_threads

from ...errors import InputError
from ...estimation.gauss_newton import GNResult, one_step, solve_map
from .attitude import GYRO_COLS, MEAS_COLS, P_G, make_step_scratch, measure_jac_sc, rk4_jac_sc
from ...model.frames import ARCSEC, DEG
from ...model.instruments import N_FULL
from .base import broadcast_params, specific_force_into
from .ekf import Estimate, EstimatorInput, FilterSettings, run_ekf

STARTS = ("zero", "ekf")
FINALS = ("converge", "one-step")


@dataclass
class MLInfo:
    """Solver diagnostics of :func:`solve_ml` per replicate (B,): accepted steps, evaluations of
    the normal equations, convergence, objective, Newton decrement; ``theta`` (B, n) and ``cov``
    (B, n, n) over every parameter (coefficients, then 3 initial angles per position);
    ``seconds`` wall time of the solve and ``ekf_seconds`` of the starting EKF pass (0 if none);
    ``coarse_steps`` the preliminary fit's steps (0 without one). With ``final='one-step'``,
    ``decrement`` and ``cost`` are those at the linearisation point."""

    steps: np.ndarray
    evaluations: np.ndarray
    converged: np.ndarray
    cost: np.ndarray
    decrement: np.ndarray
    theta: np.ndarray
    cov: np.ndarray
    seconds: float
    ekf_seconds: float
    coarse_steps: np.ndarray


def _structure(est_idx: np.ndarray):
    """``(gstate, pg, hstate, hsrc, hnnz)``: state index and RK4-Jacobian column of each estimated
    gyro coefficient; per accelerometer row the states its output depends on and their column in
    :func:`measure_jac_sc`'s ``hm``."""
    state_of = {int(f): k for k, f in enumerate(est_idx)}
    gyro = [(state_of[int(f)], q) for q, f in enumerate(GYRO_COLS) if int(f) in state_of]
    gstate = np.array([s for s, _ in gyro], dtype=np.int64)
    pg = np.array([q for _, q in gyro], dtype=np.int64)
    w = MEAS_COLS.shape[1]
    hstate = np.zeros((3, w), dtype=np.int64)
    hsrc = np.zeros((3, w), dtype=np.int64)
    hnnz = np.zeros(3, dtype=np.int64)
    for r in range(3):
        ent = [(state_of[int(f)], m) for m, f in enumerate(MEAS_COLS[r]) if f >= 0 and int(f) in state_of]
        hnnz[r] = len(ent)
        for k, (s, m) in enumerate(ent):
            hstate[r, k] = s
            hsrc[r, k] = m
    return gstate, pg, hstate, hsrc, hnnz


@njit(parallel=True, cache=True)
def _normal_equations(rows, theta, z, t, offs, est_idx, coef_fixed, params, r_var, q_rate, gstate, pg,
                      hstate, hsrc, hnnz, N, g, stats):
    """Normal equations of the replicates ``rows`` (see :func:`_replicate`), one per thread
    iteration; ``theta`` (Ba, n) is row-aligned with ``rows``, outputs too."""
    for i in prange(rows.shape[0]):
        b = rows[i]
        _replicate(theta[i], z[b], t, offs, est_idx, coef_fixed[b], params[b], r_var, q_rate, gstate,
                   pg, hstate, hsrc, hnnz, N[i], g[i], stats[i])


@njit(cache=True, inline="always")
def mul3_into(A, B, out):
    """``out = A B`` for a (3, 3) ``A`` and a (3, m) ``B``, each sum in the order of the index."""
    for r in range(3):
        for j in range(B.shape[1]):
            out[r, j] = A[r, 0] * B[0, j] + A[r, 1] * B[1, j] + A[r, 2] * B[2, j]


@njit(cache=True, inline="always")
def mul3t_into(A, B, out):
    """``out = A B^T`` for (3, 3) ``A`` and ``B``."""
    for r in range(3):
        for j in range(3):
            out[r, j] = A[r, 0] * B[j, 0] + A[r, 1] * B[j, 1] + A[r, 2] * B[j, 2]


@njit(cache=True)
def _replicate(theta, z, t, offs, est_idx, coef_fixed, params, r_var, q_rate, gstate, pg, hstate, hsrc,
               hnnz, N, gv, stats):
    """One replicate's ``N = Jt'S^-1 Jt``, ``g = Jt'S^-1 nu``, ``stats = (c, 0, bad instants)``.

    ``z`` (M, 3) g at the instants ``t`` (M,) s, position k's at ``offs[k]:offs[k + 1]``;
    ``params`` (K, 5); ``r_var`` (3,) g^2; ``q_rate`` rad^2/s per axis.
    """
    n = theta.shape[0]
    nc = est_idx.shape[0]
    K = offs.shape[0] - 1
    nl = nc + 3
    ng = gstate.shape[0]
    coef = coef_fixed.copy()
    for k in range(nc):
        coef[est_idx[k]] = theta[k]
    for i in range(n):
        gv[i] = 0.0
        for j in range(n):
            N[i, j] = 0.0
    stats[0] = 0.0
    stats[1] = 0.0
    stats[2] = 0.0
    scratch, ang_new, pa, pgyro = make_step_scratch()
    ang = np.empty(3)
    Phi_a = np.empty((3, 3))
    Phi_g = np.empty((3, ng))
    tmp3 = np.empty((3, 3))
    tmpg = np.empty(3)
    X = np.empty((3, nl + 1))       # random-walk filter's estimate per column (J columns, residual)
    tmpX = np.empty((3, nl + 1))
    W = np.empty((3, nl + 1))       # [J | r] row block, then its innovation, then whitened
    Pd = np.empty((3, 3))
    HP = np.empty((3, 3))
    S = np.empty((3, 3))
    Kg = np.empty((3, 3))
    IKH = np.empty((3, 3))
    fr3 = np.empty((3, 3))
    fr_now = np.empty(3)
    fr_mid = np.empty(3)
    out = np.empty(3)
    hm = np.zeros((3, MEAS_COLS.shape[1]))
    ha = np.empty((3, 3))
    loc = np.empty(nl, dtype=np.int64)
    for j in range(nc):
        loc[j] = j
    g = params[0, P_G]
    for kp in range(K):
        o0, o1 = offs[kp], offs[kp + 1]
        pb = params[kp]
        g = pb[P_G]
        for i in range(3):
            loc[nc + i] = nc + 3 * kp + i
            ang[i] = theta[nc + 3 * kp + i]
            for j in range(3):
                Phi_a[i, j] = 1.0 if i == j else 0.0
                Pd[i, j] = 0.0
            for j in range(ng):
                Phi_g[i, j] = 0.0
            for j in range(nl + 1):
                X[i, j] = 0.0
        t_prev = 0.0
        specific_force_into(t_prev, pb, fr_now)
        for m in range(o0, o1):
            tm = t[m]
            h = tm - t_prev
            if h > 0.0:
                # the start-of-step force is fr_now, the one at t_prev (the previous instant or the
                # reset), computed once; the end-of-step force is the one measured at tm; scratch
                # vectors, not row views of fr3 (reference counts, issue 22)
                specific_force_into(t_prev + 0.5 * h, pb, fr_mid)
                for r in range(3):
                    fr3[0, r] = fr_now[r]
                    fr3[1, r] = fr_mid[r]
                specific_force_into(tm, pb, fr_now)
                for r in range(3):
                    fr3[2, r] = fr_now[r]
                rk4_jac_sc(ang, coef, fr3, h, pb, ang_new, pa, pgyro, scratch)
                # chain the sensitivities: Phi_g <- pa Phi_g + phi_g, Phi_a <- pa Phi_a
                for q in range(ng):
                    for r in range(3):
                        tmpg[r] = pa[r, 0] * Phi_g[0, q] + pa[r, 1] * Phi_g[1, q] + pa[r, 2] * Phi_g[2, q]
                    for r in range(3):
                        Phi_g[r, q] = tmpg[r] + pgyro[r, pg[q]]
                mul3_into(pa, Phi_a, tmp3)
                for r in range(3):
                    for j in range(3):
                        Phi_a[r, j] = tmp3[r, j]
                    ang[r] = ang_new[r]
                # random-walk filter: predict (the gyro noise over h)
                mul3_into(pa, X, tmpX)
                for r in range(3):
                    for j in range(nl + 1):
                        X[r, j] = tmpX[r, j]
                mul3_into(pa, Pd, tmp3)
                mul3t_into(tmp3, pa, Pd)
                for r in range(3):
                    Pd[r, r] += q_rate * h
            else:
                specific_force_into(tm, pb, fr_now)
            t_prev = tm
            measure_jac_sc(ang, coef, fr_now[0], fr_now[1], fr_now[2], g, out, hm, ha)
            # the row block [J | r]: J = [H_c + H_a Phi_g | H_a Phi_a]
            for r in range(3):
                for j in range(nl + 1):
                    W[r, j] = 0.0
                for kk in range(hnnz[r]):
                    W[r, hstate[r, kk]] = hm[r, hsrc[r, kk]]
                for q in range(ng):
                    W[r, gstate[q]] += ha[r, 0] * Phi_g[0, q] + ha[r, 1] * Phi_g[1, q] + ha[r, 2] * Phi_g[2, q]
                for j in range(3):
                    W[r, nc + j] = ha[r, 0] * Phi_a[0, j] + ha[r, 1] * Phi_a[1, j] + ha[r, 2] * Phi_a[2, j]
                W[r, nl] = z[m, r] - out[r]
            # innovations of the random-walk filter: W <- W - H_a X; S = H_a Pd H_a' + R
            for r in range(3):
                for j in range(nl + 1):
                    W[r, j] -= ha[r, 0] * X[0, j] + ha[r, 1] * X[1, j] + ha[r, 2] * X[2, j]
            mul3_into(ha, Pd, HP)
            mul3t_into(HP, ha, S)
            for r in range(3):
                S[r, r] += r_var[r]
            # Cholesky S = L L' (lower, in place)
            l00 = S[0, 0]
            if not l00 > 0.0:
                stats[2] += 1.0
                continue
            l00 = np.sqrt(l00)
            l10 = 0.5 * (S[1, 0] + S[0, 1]) / l00
            l20 = 0.5 * (S[2, 0] + S[0, 2]) / l00
            d11 = S[1, 1] - l10 * l10
            if not d11 > 0.0:
                stats[2] += 1.0
                continue
            l11 = np.sqrt(d11)
            l21 = (0.5 * (S[2, 1] + S[1, 2]) - l20 * l10) / l11
            d22 = S[2, 2] - l20 * l20 - l21 * l21
            if not d22 > 0.0:
                stats[2] += 1.0
                continue
            l22 = np.sqrt(d22)
            if q_rate > 0.0:
                # gain Kg = Pd H_a' S^-1 (S^-1 through L), update X and Pd (Joseph form)
                for r in range(3):
                    y0 = HP[0, r] / l00
                    y1 = (HP[1, r] - l10 * y0) / l11
                    y2 = (HP[2, r] - l20 * y0 - l21 * y1) / l22
                    x2 = y2 / l22
                    x1 = (y1 - l21 * x2) / l11
                    x0 = (y0 - l10 * x1 - l20 * x2) / l00
                    Kg[r, 0] = x0
                    Kg[r, 1] = x1
                    Kg[r, 2] = x2
                for r in range(3):
                    for j in range(nl + 1):
                        X[r, j] += Kg[r, 0] * W[0, j] + Kg[r, 1] * W[1, j] + Kg[r, 2] * W[2, j]
                for r in range(3):
                    for j in range(3):
                        IKH[r, j] = (1.0 if r == j else 0.0) - (Kg[r, 0] * ha[0, j] + Kg[r, 1] * ha[1, j]
                                                                 + Kg[r, 2] * ha[2, j])
                mul3_into(IKH, Pd, tmp3)
                for r in range(3):
                    for j in range(r + 1):
                        s = (tmp3[r, 0] * IKH[j, 0] + tmp3[r, 1] * IKH[j, 1] + tmp3[r, 2] * IKH[j, 2]
                             + Kg[r, 0] * Kg[j, 0] * r_var[0] + Kg[r, 1] * Kg[j, 1] * r_var[1]
                             + Kg[r, 2] * Kg[j, 2] * r_var[2])
                        Pd[r, j] = s
                        Pd[j, r] = s
            # whiten: W <- L^-1 W
            for j in range(nl + 1):
                w0 = W[0, j] / l00
                w1 = (W[1, j] - l10 * w0) / l11
                w2 = (W[2, j] - l20 * w0 - l21 * w1) / l22
                W[0, j] = w0
                W[1, j] = w1
                W[2, j] = w2
            stats[0] += W[0, nl] * W[0, nl] + W[1, nl] * W[1, nl] + W[2, nl] * W[2, nl]
            # accumulate the lower triangle of N and g (loc is increasing, so i >= j maps to gi >= gj)
            for i in range(nl):
                a0, a1, a2 = W[0, i], W[1, i], W[2, i]
                if a0 == 0.0 and a1 == 0.0 and a2 == 0.0:
                    continue
                gi = loc[i]
                gv[gi] += a0 * W[0, nl] + a1 * W[1, nl] + a2 * W[2, nl]
                # the coefficient columns (loc[j] = j) as one contiguous run, which LLVM
                # vectorises, then the position's 3 angle columns through loc; 2-D indexing, not a
                # row view (a view per row costs two atomic reference counts; issue 22); each
                # entry the same operations, so the same numbers
                for j in range(min(i + 1, nc)):
                    N[gi, j] += a0 * W[0, j] + a1 * W[1, j] + a2 * W[2, j]
                for j in range(nc, i + 1):
                    N[gi, loc[j]] += a0 * W[0, j] + a1 * W[1, j] + a2 * W[2, j]
    for i in range(n):
        for j in range(i):
            N[j, i] = N[i, j]


class _Problem:
    """The record and settings of a batch, and the normal equations' callable for the solver."""

    def __init__(self, z, t, cmd_deg, centrifuge_params, settings: FilterSettings):
        K = len(t)
        if len(z) != K:
            raise ValueError(f"z has {len(z)} positions, t has {K}")
        self.B = int(np.asarray(z[0]).shape[0])
        self.K = K
        cmd = np.asarray(cmd_deg, float)
        if cmd.ndim == 2:
            cmd = np.broadcast_to(cmd, (self.B,) + cmd.shape)
        if cmd.shape != (self.B, K, 3):
            raise ValueError(f"cmd_deg must be (K, 3) or (B, K, 3) with K = {K}, B = {self.B}; got {cmd.shape}")
        self.cmd_rad = np.ascontiguousarray(cmd * DEG)
        self.settings = settings
        self.est_idx = settings.coef_index
        self.nc = int(self.est_idx.size)
        self.n = self.nc + 3 * K
        p0 = np.asarray(settings.p0_sigma, float)
        if p0.shape != (self.nc,):
            raise ValueError(f"p0_sigma has {p0.shape} entries, the estimator has {self.nc} coefficients")
        if not np.all(p0 > 0):
            raise InputError("filter.p0", "every coefficient's prior sigma must be > 0")
        if not settings.sigma_a_ug > 0:
            raise InputError("filter.sigma_a_ug", "the estimator's measurement noise must be > 0 "
                             "(set noise.sigma_a_ug > 0 or filter.sigma_a_ug)")
        if settings.sigma_set_arcsec < 0 or settings.arw_deg_rth < 0:
            raise InputError("filter.sigma_set_arcsec" if settings.sigma_set_arcsec < 0 else "filter.arw_deg_rth",
                             "must be >= 0")
        self.p0 = p0
        sizes = [len(tk) for tk in t]
        self.offs = np.zeros(K + 1, dtype=np.int64)
        self.offs[1:] = np.cumsum(sizes)
        self.m_total = int(self.offs[-1])
        self.t_all = np.ascontiguousarray(np.concatenate([np.asarray(tk, float) for tk in t]))
        for k, tk in enumerate(t):
            tk = np.asarray(tk, float)
            if tk.size and (tk[0] < 0 or np.any(np.diff(tk) <= 0)):
                raise ValueError(f"t[{k}] must be >= 0 and increasing")
            if np.shape(z[k]) != (self.B, tk.size, 3):
                raise ValueError(f"z[{k}] must be (B, M, 3) = ({self.B}, {tk.size}, 3), got {np.shape(z[k])}")
        self.z_all = np.ascontiguousarray(np.concatenate([np.asarray(zk, float) for zk in z], axis=1))
        self.params = broadcast_params(centrifuge_params, self.B, K)
        self.coef_fixed = np.zeros((self.B, N_FULL))
        self.r_var = np.full(3, (settings.sigma_a_ug * 1e-6) ** 2)
        self.q_rate = (settings.arw_deg_rth * DEG / 60.0) ** 2
        self.structure = _structure(self.est_idx)
        set_sigma = settings.sigma_set_arcsec * ARCSEC
        self.prior_mean = np.zeros((self.B, self.n))
        self.prior_mean[:, self.nc:] = self.cmd_rad.reshape(self.B, -1)
        self.prior_sigma = np.concatenate([p0, np.full(3 * K, set_sigma)])
        self.stats = np.zeros((self.B, 3))
        self.stats_theta = np.full((self.B, self.n), np.nan)

    def evaluate(self, theta: np.ndarray, rows: np.ndarray):
        """Data part of the normal equations of replicates ``rows`` at ``theta`` (Ba, n)."""
        rows = np.ascontiguousarray(rows, dtype=np.int64)
        Ba = rows.size
        N = np.empty((Ba, self.n, self.n))
        g = np.empty((Ba, self.n))
        stats = np.zeros((Ba, 3))
        theta = np.ascontiguousarray(theta, float)
        if Ba == 1 or get_threads() == 1:
            # replicate by replicate from here: a compiled serial loop would link and optimise the
            # replicate kernel's whole module again (~2.5 s of a cold compile) to save a few us each
            for i, b in enumerate(rows):
                _replicate(theta[i], self.z_all[b], self.t_all, self.offs, self.est_idx, self.coef_fixed[b],
                           self.params[b], self.r_var, self.q_rate, *self.structure, N[i], g[i], stats[i])
        else:
            with parallel_chunksize(1):
                _normal_equations(rows, theta, self.z_all, self.t_all, self.offs, self.est_idx,
                                  self.coef_fixed, self.params, self.r_var, self.q_rate, *self.structure, N, g, stats)
        # each replicate's latest statistics and where they were taken (diagnostics of the estimate)
        self.stats[rows] = stats
        self.stats_theta[rows] = theta
        return N, g, stats[:, 0]

    def start(self, coef: np.ndarray) -> np.ndarray:
        """(B, n) starting point: these coefficients (B, nc), the commanded angles."""
        theta = self.prior_mean.copy()
        theta[:, : self.nc] = coef
        return theta


def solve_ml(data: EstimatorInput, settings: FilterSettings, *, max_iter: int = 20,
             tol: float = 1e-2, start="zero", damping: bool = False, coarse: int = 1,
             final: str = "converge") -> tuple[Estimate, MLInfo]:
    """:func:`run_ml` with the solver's diagnostics: ``(Estimate, MLInfo)``.

    ``start`` may also be a (B, nc) array of starting coefficients (e.g. an EKF estimate at hand).
    """
    given = not isinstance(start, str)
    if not given and start not in STARTS:
        raise InputError("start", f"must be one of {', '.join(STARTS)} (or an array of starting coefficients), "
                                  f"not {start!r}")
    if int(max_iter) != max_iter or max_iter < 0:
        raise InputError("max_iter", f"must be a whole number >= 0, not {max_iter!r}")
    if not (np.isfinite(tol) and tol > 0):
        raise InputError("tol", f"must be a number > 0 (Newton decrement in posterior sigmas), not {tol!r}")
    if int(coarse) != coarse or coarse < 1:
        raise InputError("coarse", f"must be a whole number >= 1 (1: no preliminary fit), not {coarse!r}")
    if final not in FINALS:
        raise InputError("final", f"must be one of {', '.join(FINALS)}, not {final!r}")
    coarse = int(coarse)
    z, t, cmd_deg, centrifuge_params = data.z, data.t, data.cmd_deg, data.centrifuge_params
    prob = _Problem(z, t, cmd_deg, centrifuge_params, settings)
    nc, B = prob.nc, prob.B
    ekf_s = 0.0
    if given:
        coef0 = np.asarray(start, float)
        if coef0.shape != (B, nc):
            raise ValueError(f"start must be (B, nc) = ({B}, {nc}), got {coef0.shape}")
    elif start == "ekf":
        t0 = time.perf_counter()
        ekf = run_ekf(data, replace(settings, passes=1, history_every_s=None))
        ekf_s = time.perf_counter() - t0
        coef0 = ekf.coef
    else:
        coef0 = np.zeros((B, nc))
    t0 = time.perf_counter()
    theta0 = prob.start(coef0)
    coarse_steps = np.zeros(B, dtype=np.int64)
    if coarse > 1:
        # preliminary fit on every coarse-th instant (the first kept): a cheap consistent start
        zc = [np.asarray(zk, float)[:, ::coarse] for zk in z]
        tc = [np.asarray(tk, float)[::coarse] for tk in t]
        pc = _Problem(zc, tc, cmd_deg, centrifuge_params, settings)
        rc = solve_map(pc.evaluate, theta0, pc.prior_mean, pc.prior_sigma, max_iter=int(max_iter), tol=float(tol),
                       damping=bool(damping))
        theta0, coarse_steps = rc.theta, rc.steps
    if final == "one-step":
        N, g, c = prob.evaluate(theta0, np.arange(B))
        res: GNResult = one_step(N, g, c, theta0, prob.prior_mean, prob.prior_sigma)
        stats = prob.stats  # at the linearisation point: nothing is evaluated after the step
    else:
        res = solve_map(prob.evaluate, theta0, prob.prior_mean, prob.prior_sigma,
                        max_iter=int(max_iter), tol=float(tol), damping=bool(damping))
        # diagnostics at the returned estimate: the solver's last evaluation, unless a rejected step
        stale = np.flatnonzero(np.any(prob.stats_theta != res.theta, axis=1))
        if stale.size:
            prob.evaluate(res.theta[stale], stale)
        stats = prob.stats
    secs = time.perf_counter() - t0
    keep = np.r_[np.arange(nc), prob.n - 3 + np.arange(3)]
    x = res.theta[:, keep]
    P = res.cov[:, keep[:, None], keep[None, :]]
    est = Estimate(
        names=settings.state_names,
        x=x,
        P=P,
        history_t=np.zeros(0),
        history_x=np.zeros((B, 0, nc + 3)),
        history_sigma=np.zeros((B, 0, nc + 3)),
        pass_x=x[None, :, :nc].copy(),
        pass_P=P[None, :, :nc, :nc].copy(),
        mean_nis=stats[:, 0] / max(prob.m_total, 1),
        failed_updates=stats[:, 2].astype(np.int64),
    )
    info = MLInfo(steps=res.steps, evaluations=res.evaluations, converged=res.converged, cost=res.cost,
                  decrement=res.decrement, theta=res.theta, cov=res.cov, seconds=secs, ekf_seconds=ekf_s,
                  coarse_steps=coarse_steps)
    return est, info


def run_ml(data: EstimatorInput, settings: FilterSettings, *, max_iter: int = 20,
           tol: float = 1e-2, start: str = "zero", damping: bool = False, coarse: int = 1,
           final: str = "converge") -> Estimate:
    """Batch MAP identification of a centrifuge record (module docstring), for a batch of B runs.

    Parameters
    ----------
    data : the record, commands and centrifuge parameters (:class:`~.ekf.EstimatorInput`); the
        attitude at t = 0 is the position's initial-angle parameter, the commanded angles are
        its prior means.
    settings : the filter settings (R from sigma_a_ug, Q from arw_deg_rth, the angle prior from
        sigma_set_arcsec, the coefficient prior from p0_sigma, estimate_doo); ``passes`` and
        ``history_every_s`` are not used.
    max_iter : most Gauss-Newton steps.
    tol : Newton decrement (posterior sigmas) to stop at: the estimate is then within ``tol``
        posterior sigma of the exact MAP on every parameter (Table 1: decrements 2e5, 5e2, 2e-3,
        3e-8 from a cold start, so 1e-2 stops after 2 steps).
    start : 'zero' (every coefficient 0, the EKF's initial state; the default: plain Gauss-Newton
        converges from it in as many steps as from the EKF's estimate, without the EKF pass) or
        'ekf' (one EKF pass's coefficients). The initial angles start at the commanded ones.
    damping : Levenberg-Marquardt (not needed on the centrifuge: plain Gauss-Newton converges
        from a cold start).
    coarse : > 1: first fit (to ``tol``) on every ``coarse``-th instant only, at ``1/coarse`` of
        the cost per step, and start the full fit there (1: no preliminary fit).
    final : 'converge' (iterate on the full record until the decrement is below ``tol``) or
        'one-step' (one Gauss-Newton step on the full record from the preliminary estimate, no
        evaluation after it: the one-step estimator; the covariance and mean NIS are those at
        the preliminary estimate).

    Returns
    -------
    Estimate (x: coefficients, then the last position's initial angles in rad).
    """
    return solve_ml(data, settings, max_iter=max_iter, tol=tol, start=start,
                    damping=damping, coarse=coarse, final=final)[0]


@njit(cache=True)
def _predict_replicate(theta, t, offs, est_idx, coef_fixed, params, out):
    """Predicted outputs (g) of one replicate at ``theta``: eq. 13 along the deterministic
    attitude of each position (same RK4 steps as :func:`_replicate`)."""
    nc = est_idx.shape[0]
    coef = coef_fixed.copy()
    for k in range(nc):
        coef[est_idx[k]] = theta[k]
    scratch, ang_new, pa, pgyro = make_step_scratch()
    ang = np.empty(3)
    fr3 = np.empty((3, 3))
    fr_now = np.empty(3)
    hm = np.zeros((3, MEAS_COLS.shape[1]))
    ha = np.empty((3, 3))
    for kp in range(offs.shape[0] - 1):
        pb = params[kp]
        for i in range(3):
            ang[i] = theta[nc + 3 * kp + i]
        t_prev = 0.0
        for m in range(offs[kp], offs[kp + 1]):
            h = t[m] - t_prev
            if h > 0.0:
                specific_force_into(t_prev, pb, fr3[0])
                specific_force_into(t_prev + 0.5 * h, pb, fr3[1])
                specific_force_into(t[m], pb, fr3[2])
                rk4_jac_sc(ang, coef, fr3, h, pb, ang_new, pa, pgyro, scratch)
                for r in range(3):
                    ang[r] = ang_new[r]
            specific_force_into(t[m], pb, fr_now)
            t_prev = t[m]
            measure_jac_sc(ang, coef, fr_now[0], fr_now[1], fr_now[2], pb[P_G], out[m], hm, ha)


def predict(theta, t, centrifuge_params, settings: FilterSettings) -> list[np.ndarray]:
    """Outputs (g) the model predicts at the instants ``t`` (K arrays) for parameters ``theta``
    (B, n): coefficients, then 3 initial angles (rad) per position. Returns K arrays (B, M_k, 3)."""
    theta = np.atleast_2d(np.asarray(theta, float))
    B, K = theta.shape[0], len(t)
    est_idx = settings.coef_index
    sizes = [len(tk) for tk in t]
    offs = np.zeros(K + 1, dtype=np.int64)
    offs[1:] = np.cumsum(sizes)
    t_all = np.ascontiguousarray(np.concatenate([np.asarray(tk, float) for tk in t]))
    params = broadcast_params(centrifuge_params, B, K)
    out = np.empty((B, int(offs[-1]), 3))
    coef_fixed = np.zeros(N_FULL)
    for b in range(B):
        _predict_replicate(np.ascontiguousarray(theta[b]), t_all, offs, est_idx, coef_fixed, params[b], out[b])
    return [out[:, offs[k]:offs[k + 1]] for k in range(K)]
