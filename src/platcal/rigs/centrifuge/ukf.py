"""An unscented Kalman filter of the centrifuge model (docs/centrifuge-model.md §9; issue 9 item 3),
batched over replicates.

Same model, state, units, timing and settings as the EKF (:mod:`.ekf`): 45 coefficients in
Table 2's engineering units (48 with ``estimate_doo``), then alpha, beta, gamma in rad; at time
0 of each position the attitude is reset to the commanded angles with variance sigma_set^2 and
no cross-covariance (the coefficients carry over); the filter then propagates from 0 to
``t[k][0]`` (nothing if ``t[k][0] == 0``), updates with ``z`` there, propagates to ``t[k][1]``,
and so on, one RK4 step per interval. Passes as in the EKF (each further pass restarts from the
previous estimate with ``P0 = 100 x`` its coefficient covariance).

Sigma points are in engineering units (deg/h, ug, arcsec, rad), drawn from the upper Cholesky
factor of P with the scaled unscented transform in the central form of
:mod:`platcal.estimation.unscented` (positive semidefinite for any spread when
``beta >= alpha^2``); the update is Joseph-safe (:func:`platcal.estimation.unscented.joseph_update`).

Three variants (option ``sigma_points``):

``"all"``: the textbook UKF over all n states, 2n + 1 sigma points (Cholesky factor in the state
    order) for the propagation and 2n + 1 redrawn ones for the measurement. The coefficients are
    constant, so their sigma points propagate unchanged and the coefficient block of P is kept as
    it is (the transform gives it back exactly); only the attitude rows are recomputed.
``"update"`` (default): the same 2n + 1 measurement update; the propagation over one filter period
    is the EKF's (the mean through RK4, P through the exact Jacobian of the RK4 map). The drift is
    linear in the gyro coefficients and the attitude moves ~1e-6 rad per 20 ms, so this changes
    the estimates by < 0.01 sigma against ``"all"`` (measured: 0.008 sigma on Table 1, 10 s per
    position) at about a third of its cost.
``"nonlinear"``: sigma points only where the measurement is nonlinear: the angles, the
    misalignments theta and k1, k2, k3, kIP (18 states, 37 sigma points, of which only the 6 that
    move the angles need trigonometry); k0 enters linearly and the gyro coefficients not at all,
    so they are added in closed form (Gaussian regression on the 18 states,
    :func:`platcal.estimation.unscented.regression_cross_into`); propagation as ``"update"``.
    This is exactly the ``"all"`` update with a Cholesky factor that orders those 18 states
    first (tests/test_ukf.py), i.e. a UKF with another, equally valid, matrix square root. The
    unscented transform is not invariant to that choice beyond second order, and here it shows:
    on 48 replicates at 10 ug the estimates differ from the state-order ``"all"`` UKF by up to
    1.15 sigma, with mean NEES 58.7 against 56.1 and 16.7 % against 12.5 % of runs beyond 80.1.
    So the default is the state-order update; ``"nonlinear"`` costs about a quarter of it
    (about 1.9 x one EKF pass) and is offered as the cheap variant (benchmarks/ukf_study.py).

Parameters of the transform: ``alpha``, ``beta``, ``kappa`` (None: ``3 - n``), with ``n`` the full
state dimension in every variant so that they use the same spread ``h = alpha sqrt(n + kappa)``.
The default ``alpha = 1, beta = 2, kappa = 3 - n`` puts the sigma points at ``sqrt(3)`` sigma
(Julier's ``n + kappa = 3``: the Gaussian's fourth moment along each axis) and weights the
central form's ``m m^T`` term by ``beta - alpha^2 = 1``; the textbook zeroth weight would be
``1 - n/3 = -15``, harmless in the central form.

Each replicate runs the same sequential kernel in its own ``prange`` iteration, so the numbers do
not depend on the batch size or the number of threads.
"""

from __future__ import annotations

import numpy as np
from ...jit import njit, parallel_chunksize, prange
from ...parallel import get_threads

from ...errors import InputError
from ...estimation.kalman import update_scratch
from ...estimation.unscented import (check_ut_params, cholesky_upper_into, joseph_update,
                                     regression_cross_into, ut_moments_into)
from .attitude import (GYRO_COLS, P_G, SHIFT_SMALL, _shift, c_rp_sc, make_step_scratch, measure_coef_sc,
                       measure_scalar, rk4_scalar, shift_small)
from ...model.instruments import I_K0, I_THETA, N_FULL, UG, accel_axes, accel_one
from .base import specific_force_into
from .ekf import (Estimate, EstimatorInput, FilterSettings, attitude_reset, drive_passes, filter_start,
                  propagate_attitude, store_history)

SIGMA_POINT_MODES = ("nonlinear", "update", "all")


@njit(cache=True)
def _accel_at(coef, fp, out):
    """Accelerometer outputs (g) at the platform specific force ``fp`` (g), eq. 13."""
    for j in range(3):
        aI, aP = accel_axes(coef, j, fp[0], fp[1], fp[2])
        out[j] = accel_one(coef, j, aI, aP)


@njit(cache=True)
def update_nonlinear(xb, Pb, coef, fr, g, zrow, r_var, h, w2, nl, nl_full, lin, update_x, Rnn, Dp,
                     Dm, Y, U, S, K, D, F, nu, innov, cs, a, fp0, y0, y, mz, Pzz):
    """Unscented update with sigma points over the states ``nl`` only (see the module docstring).

    ``nl`` (nl,) state indices, the three angles first; ``nl_full`` their full-coefficient
    index (-1 - i for angle i); ``lin`` (3,) the state of k0 of each axis (the linear part,
    output j = ``UG k0_j`` + the rest). ``coef`` (48,) is the full coefficient vector at the
    state (``xb``'s coefficients mapped in); ``cs`` (48,) scratch equal to ``coef`` on entry and
    exit. ``fr`` (3,) base specific force (m/s^2), ``g`` m/s^2, ``zrow`` (3,) the outputs (g).
    Returns ``(ok, nis)``; ok False (nothing changed) if P_NN or S is not positive definite.
    """
    n = xb.shape[0]
    nc = n - 3
    q = nl.shape[0]
    for i in range(q):
        for j in range(i + 1):
            Rnn[i, j] = Pb[nl[i], nl[j]]
    if not cholesky_upper_into(Rnn, Rnn):
        return False, 0.0
    sa, ca = np.sin(xb[nc]), np.cos(xb[nc])
    sb, cb = np.sin(xb[nc + 1]), np.cos(xb[nc + 1])
    sg, cg = np.sin(xb[nc + 2]), np.cos(xb[nc + 2])
    c = c_rp_sc(sa, ca, sb, cb, sg, cg)
    for r in range(3):
        fp0[r] = (c[3 * r] * fr[0] + c[3 * r + 1] * fr[1] + c[3 * r + 2] * fr[2]) / g
        a[r] = 0.0
    _accel_at(coef, fp0, y0)
    for j in range(q):
        for sgn in (1.0, -1.0):
            # a: the sigma point's angle offsets (rad); cs: its coefficients
            for i in range(j, q):
                d = sgn * h * Rnn[j, i]
                f = nl_full[i]
                if f < 0:
                    a[-1 - f] = d
                else:
                    cs[f] += d
            if j < 3:  # only the first three rows move the angles (Rnn upper triangular)
                s0, c0 = _shift(sa, ca, a[0])
                s1, c1 = _shift(sb, cb, a[1])
                s2, c2 = _shift(sg, cg, a[2])
                y[0], y[1], y[2] = measure_scalar(s0, c0, s1, c1, s2, c2, cs, fr[0], fr[1], fr[2], g)
            else:
                _accel_at(cs, fp0, y)
            dst = Dp if sgn > 0.0 else Dm
            for r in range(3):
                dst[j, r] = y[r] - y0[r]
            for i in range(j, q):
                f = nl_full[i]
                if f < 0:
                    a[-1 - f] = 0.0
                else:
                    cs[f] = coef[f]
    ut_moments_into(Dp, Dm, h, w2, mz, Pzz)
    regression_cross_into(Pb, nl, Rnn, Dp, Dm, h, Y, U)
    for r in range(3):
        lr = Pb[lin[r]]
        ur = U[r]
        for i in range(n):
            ur[i] += UG * lr[i]
    for r in range(3):
        for c in range(r + 1):
            v = UG * (U[c, lin[r]] + U[r, lin[c]]) - UG * UG * Pb[lin[r], lin[c]] + Pzz[r, c]
            S[r, c] = v
            S[c, r] = v
        S[r, r] += r_var[r]
    for r in range(3):
        innov[r] = zrow[r] - (y0[r] + mz[r]) if update_x else 0.0
    if not joseph_update(xb, Pb, U, S, innov, K, D, F, nu, update_x):
        return False, 0.0
    return True, nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]


@njit(cache=True)
def _full_sqrt(Pb, perm, Rp, Sf):
    """Square root ``Sf`` (n, n) of P (``P = Sf^T Sf``; rows: sigma directions, in state order)
    from the upper Cholesky factor ``Rp`` of P with its states permuted by ``perm``
    (``Sf[j, perm[i]] = Rp[j, i]``); False if P is not PD."""
    n = Pb.shape[0]
    identity = True
    for i in range(n):
        identity = identity and perm[i] == i
    if identity:
        return cholesky_upper_into(Pb, Sf)
    for i in range(n):
        for j in range(i + 1):
            Rp[i, j] = Pb[perm[i], perm[j]]
    if not cholesky_upper_into(Rp, Rp):
        return False
    for j in range(n):
        for i in range(n):
            Sf[j, perm[i]] = Rp[j, i]
    return True


@njit(cache=True)
def _sigma_coef(xb, Sf, j, step, est_idx, coef, cs, a):
    """The coefficients ``cs`` (48,) and angles ``a`` of the sigma point ``x + step Sf[j]``."""
    nc = xb.shape[0] - 3
    sj = Sf[j]
    for k in range(nc):
        cs[est_idx[k]] = coef[est_idx[k]] + step * sj[k]
    for r in range(3):
        a[r] = xb[nc + r] + step * sj[nc + r]


@njit(cache=True)
def propagate_all(xb, Pb, coef, fr3, dt, pb, q_var, h, w2, perm, est_idx, Rp, Sf, Dp, Dm, cs, a,
                  a0, y, mz, blk):
    """Unscented propagation over ``dt`` s with sigma points over all n states.

    The coefficients are constant: their sigma points map to themselves, so the transform returns
    P's coefficient block unchanged (algebra) and only the attitude rows are recomputed:
    ``P'_ai = (1/2h) sum_j Sf[j, i] (Dp[j, a] - Dm[j, a])`` for a coefficient i, the central-form
    moments for the angle block, plus ``q_var`` (rad^2) on the angles' diagonal.
    Returns False (nothing changed) if P is not positive definite.
    """
    n = xb.shape[0]
    nc = n - 3
    if not _full_sqrt(Pb, perm, Rp, Sf):
        return False
    for r in range(3):
        a[r] = xb[nc + r]
    rk4_scalar(a, coef, fr3, dt, pb, a0)
    for j in range(n):
        for sgn in (1.0, -1.0):
            _sigma_coef(xb, Sf, j, sgn * h, est_idx, coef, cs, a)
            rk4_scalar(a, cs, fr3, dt, pb, y)
            dst = Dp if sgn > 0.0 else Dm
            for r in range(3):
                dst[j, r] = y[r] - a0[r]
    for k in range(nc):
        cs[est_idx[k]] = coef[est_idx[k]]
    ut_moments_into(Dp, Dm, h, w2, mz, blk)
    i2h = 0.5 / h
    for r in range(3):
        for i in range(nc):
            v = 0.0
            for j in range(n):
                v += Sf[j, i] * (Dp[j, r] - Dm[j, r])
            Pb[nc + r, i] = i2h * v
            Pb[i, nc + r] = i2h * v
    for r in range(3):
        for c in range(3):
            Pb[nc + r, nc + c] = blk[r, c] + (q_var if r == c else 0.0)
        xb[nc + r] = a0[r] + mz[r]
    return True


@njit(cache=True)
def _sigma_point_outputs(sa, ca, sb, cb, sg, cg, Sf, j, step, mstates, est_idx, coef, cs, fr, g):
    """Accelerometer outputs (g) at the sigma point ``x + step Sf[j]`` (``sa, ca, ...``: sin and cos
    of the mean's angles); ``cs`` (48,) takes the point's coefficients (``mstates``: the states
    the measurement reads) and must be restored by the caller."""
    nc = Sf.shape[0] - 3
    for q in range(mstates.shape[0]):
        k = mstates[q]
        cs[est_idx[k]] = coef[est_idx[k]] + step * Sf[j, k]
    # the sigma point's angles: sin/cos by exact-to-rounding shifts from the mean's
    s0, c0 = _shift(sa, ca, step * Sf[j, nc])
    s1, c1 = _shift(sb, cb, step * Sf[j, nc + 1])
    s2, c2 = _shift(sg, cg, step * Sf[j, nc + 2])
    return measure_scalar(s0, c0, s1, c1, s2, c2, cs, fr[0], fr[1], fr[2], g)


@njit(cache=True)
def _sigma_outputs_all(sa, ca, sb, cb, sg, cg, Sf, h, mstates, coef, fr, g, y0, T, Dp, Dm):
    """Deviations ``Dp[j, r]``, ``Dm[j, r]`` (g) of the outputs at the sigma points ``x +- h Sf[j]``
    from ``y0``, every point with the Taylor shift of the angles (:func:`shift_small`; the caller
    redoes the points whose angle step is not small). ``mstates`` (18,): the states of the
    coefficients ``coef[I_K0:I_THETA + 3]`` in that order; ``T`` (21, n) scratch.

    The same operations as :func:`_sigma_point_outputs` (hence the same numbers), without its
    per-point costs (issue 22): the columns of ``Sf`` that the measurement reads are copied to
    contiguous rows of ``T`` once, and the loop over the points calls no function, takes no branch
    and writes no coefficient through the state map (about 3x faster than point by point).
    """
    n = Sf.shape[0]
    nc = n - 3
    for q in range(18):
        k = mstates[q]
        for j in range(n):
            T[q, j] = Sf[j, k]
    for r in range(3):
        for j in range(n):
            T[18 + r, j] = Sf[j, nc + r]
    fr0, fr1, fr2 = fr[0], fr[1], fr[2]
    y00, y01, y02 = y0[0], y0[1], y0[2]
    for sgn in (1.0, -1.0):
        step = sgn * h
        G = Dp if sgn > 0.0 else Dm
        for j in range(n):
            s0, c0 = shift_small(sa, ca, step * T[18, j])
            s1, c1 = shift_small(sb, cb, step * T[19, j])
            s2, c2 = shift_small(sg, cg, step * T[20, j])
            o0, o1, o2 = measure_coef_sc(
                s0, c0, s1, c1, s2, c2, fr0, fr1, fr2, g,
                coef[I_K0] + step * T[0, j], coef[I_K0 + 1] + step * T[1, j], coef[I_K0 + 2] + step * T[2, j],
                coef[I_K0 + 3] + step * T[3, j], coef[I_K0 + 4] + step * T[4, j],
                coef[I_K0 + 5] + step * T[5, j], coef[I_K0 + 6] + step * T[6, j],
                coef[I_K0 + 7] + step * T[7, j], coef[I_K0 + 8] + step * T[8, j],
                coef[I_K0 + 9] + step * T[9, j], coef[I_K0 + 10] + step * T[10, j],
                coef[I_K0 + 11] + step * T[11, j], coef[I_K0 + 12] + step * T[12, j],
                coef[I_K0 + 13] + step * T[13, j], coef[I_K0 + 14] + step * T[14, j],
                coef[I_K0 + 15] + step * T[15, j], coef[I_K0 + 16] + step * T[16, j],
                coef[I_K0 + 17] + step * T[17, j])
            G[j, 0] = o0 - y00
            G[j, 1] = o1 - y01
            G[j, 2] = o2 - y02


@njit(cache=True, inline="always")
def _sigma_deviations(sa, ca, sb, cb, sg, cg, Sf, h, mstates, est_idx, coef, cs, fr, g, y0, T, Dp, Dm):
    """``Dp[j, r]``, ``Dm[j, r]``: output r at the sigma points ``x +- h Sf[j]`` less ``y0`` (g).

    All at once (:func:`_sigma_outputs_all`) when the states read by the measurement are its 18
    coefficients in order; the points whose angle step is not below :data:`SHIFT_SMALL` (or not
    finite), and every point otherwise, one by one (:func:`_sigma_point_outputs`): the same
    numbers either way."""
    n = Sf.shape[0]
    nc = n - 3
    nm = mstates.shape[0]
    together = nm == 18
    for q in range(nm):
        together = together and est_idx[mstates[q]] == I_K0 + q
    if together:
        _sigma_outputs_all(sa, ca, sb, cb, sg, cg, Sf, h, mstates, coef, fr, g, y0, T, Dp, Dm)
    for j in range(n):
        small = True
        for r in range(3):
            small = small and abs(h * Sf[j, nc + r]) < SHIFT_SMALL  # = |-h Sf[j, nc + r]|
        if together and small:
            continue
        for sgn in (1.0, -1.0):
            y = _sigma_point_outputs(sa, ca, sb, cb, sg, cg, Sf, j, sgn * h, mstates, est_idx, coef, cs, fr, g)
            G = Dp if sgn > 0.0 else Dm
            for r in range(3):
                G[j, r] = y[r] - y0[r]
        for q in range(nm):
            k = mstates[q]
            cs[est_idx[k]] = coef[est_idx[k]]


@njit(cache=True, inline="always")
def _cross_covariance(Sf, Dp, Dm, h, upper, U):
    """Cross-covariance ``U[r] = (1/2h) sum_j (Dp[j, r] - Dm[j, r]) Sf[j]`` of the states with the
    three outputs, each entry summed in the order j = 0, 1, ... (docs/centrifuge-model.md §9).

    With ``upper`` (``Sf`` the upper factor in the state order: ``Sf[j, i] = +0`` for i < j) row j
    starts at its diagonal: a finite g times +0 adds +-0 to a sum that is never -0, i.e. nothing,
    so the terms skipped change no bit; where a g is not finite the row takes every column, so
    that NaN and inf spread as ever.
    """
    n = Sf.shape[0]
    i2h = 0.5 / h
    for r in range(3):
        for i in range(n):
            U[r, i] = 0.0
    for j in range(n):
        g0 = i2h * (Dp[j, 0] - Dm[j, 0])
        g1 = i2h * (Dp[j, 1] - Dm[j, 1])
        g2 = i2h * (Dp[j, 2] - Dm[j, 2])
        finite = abs(g0) < np.inf and abs(g1) < np.inf and abs(g2) < np.inf
        for i in range(j if upper and finite else 0, n):
            sji = Sf[j, i]
            U[0, i] += g0 * sji
            U[1, i] += g1 * sji
            U[2, i] += g2 * sji


@njit(cache=True, inline="always")
def update_all(xb, Pb, coef, fr, g, zrow, r_var, h, w2, perm, mstates, est_idx, update_x, Rp, Sf,
               Dp, Dm, T, U, S, K, D, F, nu, innov, cs, y0, mz, Pzz):
    """Unscented update with 2n + 1 sigma points over all states (the reference). Returns
    ``(ok, nis)``; ok False (nothing changed) if P or S is not positive definite.

    ``mstates``: the coefficient states the measurement reads (k0 ... kIP, theta); every sigma
    point moves every state, but the others cannot change the outputs, so only these are set.
    ``Dp``, ``Dm`` (n, 3) and ``T`` (21, n): scratch of :func:`_sigma_deviations`.
    """
    n = xb.shape[0]
    nc = n - 3
    if not _full_sqrt(Pb, perm, Rp, Sf):
        return False, 0.0
    sa, ca = np.sin(xb[nc]), np.cos(xb[nc])
    sb, cb = np.sin(xb[nc + 1]), np.cos(xb[nc + 1])
    sg, cg = np.sin(xb[nc + 2]), np.cos(xb[nc + 2])
    y0[0], y0[1], y0[2] = measure_scalar(sa, ca, sb, cb, sg, cg, coef, fr[0], fr[1], fr[2], g)
    _sigma_deviations(sa, ca, sb, cb, sg, cg, Sf, h, mstates, est_idx, coef, cs, fr, g, y0, T, Dp, Dm)
    ut_moments_into(Dp, Dm, h, w2, mz, Pzz)
    upper = True
    for i in range(n):
        upper = upper and perm[i] == i
    _cross_covariance(Sf, Dp, Dm, h, upper, U)
    for r in range(3):
        for c in range(3):
            S[r, c] = Pzz[r, c]
        S[r, r] += r_var[r]
        innov[r] = zrow[r] - (y0[r] + mz[r]) if update_x else 0.0
    if not joseph_update(xb, Pb, U, S, innov, K, D, F, nu, update_x):
        return False, 0.0
    return True, nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]


# inlined (with _filter_replicate) into each variant's pass kernels, where ``mode`` is a constant:
# numba prunes the branches of the other variants before typing, so their callees are not compiled
@njit(cache=True, inline="always")
def _filter_one(xb, Pb, zb, t, cmd, reset_var, est_idx, coef_fixed, pb, r_var, q_rate, update_x,
                hist_idx, hist_x, hist_s, pcols, pg, nl, nl_full, lin, mstates, h, w2, mode, perm):
    """One replicate through one position; returns (sum of NIS, number of failed steps).
    ``mode`` (an index of :data:`SIGMA_POINT_MODES`): 0 sigma points over the nonlinear states,
    1 over all states in the update only, 2 over all states in the propagation and the update.
    Every test of ``mode`` compares it with a constant (numba prunes only such branches)."""
    full_prop = mode == 2
    full = mode >= 1
    n = xb.shape[0]
    nc = n - 3
    M = t.shape[0]
    q = nl.shape[0]
    npc = pcols.shape[0]
    g = pb[P_G]
    dyn = np.arange(nc, n)
    coef = coef_fixed.copy()
    cs = coef_fixed.copy()
    scratch, ang_new, pa, pgyro = make_step_scratch()
    phi = np.empty((3, npc))
    qm = np.zeros((3, 3))
    blk = np.empty((3, 3))
    Wd = np.empty((3, n))
    nsig = n if full else q
    Rnn = np.zeros((q, q))
    Rp = np.zeros((n, n))
    Sf = np.zeros((n, n))
    Dp = np.empty((nsig, 3))
    Dm = np.empty((nsig, 3))
    T = np.empty((21, n))
    Y = np.empty((q, 3))
    U, K, D, S, F, nu = update_scratch(3, n)
    innov = np.zeros(3)
    a = np.empty(3)
    a0 = np.empty(3)
    fp0 = np.empty(3)
    y0 = np.empty(3)
    y = np.empty(3)
    mz = np.empty(3)
    Pzz = np.empty((3, 3))
    fr3 = np.empty((3, 3))
    fr_prev = np.empty(3)
    fr_now = np.empty(3)
    ang = xb[nc:]
    nis = 0.0
    bad = 0
    # attitude reset at time 0: commanded angles, variance sigma_set^2, no cross-covariance
    attitude_reset(xb, Pb, cmd, reset_var)
    t_prev = 0.0
    specific_force_into(0.0, pb, fr_prev)
    for m in range(M):
        for k in range(nc):
            coef[est_idx[k]] = xb[k]
            cs[est_idx[k]] = xb[k]
        dt = t[m] - t_prev
        specific_force_into(t[m], pb, fr_now)
        if dt > 0.0:
            for r in range(3):
                fr3[0, r] = fr_prev[r]
                fr3[2, r] = fr_now[r]
            specific_force_into(t_prev + 0.5 * dt, pb, fr3[1])
            linear = True
            if full_prop:
                linear = not propagate_all(xb, Pb, coef, fr3, dt, pb, q_rate * dt, h, w2, perm, est_idx,
                                           Rp, Sf, Dp, Dm, cs, a, a0, y, mz, blk)
                if linear:  # P's block not PD: the linear propagation instead
                    bad += 1
            # one call site: propagate_attitude is inlined (with the RK4 Jacobian's four rate
            # evaluations), and every site is a copy numba types, lowers and LLVM optimises
            if linear:
                propagate_attitude(Pb, ang, coef, fr3, dt, pb, q_rate, dyn, pcols, pg, ang_new,
                                   pa, pgyro, phi, qm, Wd, blk, scratch)
        zrow = zb[m]
        if full:
            ok, s = update_all(xb, Pb, coef, fr_now, g, zrow, r_var, h, w2, perm, mstates, est_idx,
                               update_x, Rp, Sf, Dp, Dm, T, U, S, K, D, F, nu, innov, cs, y0, mz, Pzz)
        else:
            ok, s = update_nonlinear(xb, Pb, coef, fr_now, g, zrow, r_var, h, w2, nl, nl_full, lin,
                                     update_x, Rnn, Dp, Dm, Y, U, S, K, D, F, nu, innov, cs, a,
                                     fp0, y0, y, mz, Pzz)
        if ok:
            nis += s
        else:
            bad += 1
        for r in range(3):
            fr_prev[r] = fr_now[r]
        t_prev = t[m]
        store_history(hist_idx[m], xb, Pb, hist_x, hist_s)
    return nis, bad


# inlined into the two pass kernels, and _filter_one with it: with a compiled filter kernel between
# them (one per variant, before issue 22's ukf session) each pass kernel linked, optimised and
# emitted the filter's whole code a second time (the UKF's cold compile 24 -> 20 s CPU without it)
@njit(cache=True, inline="always")
def _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                      q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, nl,
                      nl_full, lin, mstates, h, w2, mode, perm):
    """Replicate b through every position of one pass (``mode``: a constant of the pass kernel,
    which picks the variant; numba prunes the other two)."""
    for k in range(offs.shape[0] - 1):
        o0, o1 = offs[k], offs[k + 1]
        zb = z[b, o0:o1] if update_x else z[b]
        stats = _filter_one(x[b], P[b], zb, t[o0:o1], cmd[b, k], reset_var, est_idx, coef_fixed[b],
                            params[b, k], r_var, q_rate, update_x, hist_idx[o0:o1], hist_x[b],
                            hist_s[b], pcols, pg, nl, nl_full, lin, mstates, h, w2, mode, perm)
        nis_sum[b] += stats[0]
        n_bad[b] += int(stats[1])


def _pass_kernels(mode: int):
    """``(threaded, serial)`` pass kernels of one sigma-point variant (``mode``, a constant of
    their closure, an int numba's cache keys by value): every replicate of the batch through one pass."""

    @njit(parallel=True, cache=True)
    def run_pass(x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                 update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, nl, nl_full, lin,
                 mstates, h, w2, perm):
        """One replicate per ``prange`` iteration."""
        for b in prange(x.shape[0]):
            _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                              q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg,
                              nl, nl_full, lin, mstates, h, w2, mode, perm)

    @njit(cache=True)
    def run_pass_serial(x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                        update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, nl, nl_full,
                        lin, mstates, h, w2, perm):
        """``run_pass`` without threads (a batch of one, or one thread): the same kernel."""
        for b in range(x.shape[0]):
            _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                              q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg,
                              nl, nl_full, lin, mstates, h, w2, mode, perm)

    return run_pass, run_pass_serial


_PASS_KERNELS = tuple(_pass_kernels(m) for m in range(len(SIGMA_POINT_MODES)))


def propagation_structure(est_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(pcols, pg)``: the states where the attitude rows of the RK4 map's Jacobian may be nonzero
    (the estimated gyro coefficients, then the three angles) and, for each coefficient among
    them, its column of the compact gyro Jacobian (:data:`platcal.rigs.centrifuge.attitude.GYRO_COLS`)."""
    nc = est_idx.size
    state_of = {int(f): k for k, f in enumerate(est_idx)}
    pairs = [(state_of[int(f)], q) for q, f in enumerate(GYRO_COLS) if int(f) in state_of]
    pcols = np.array([s for s, _ in pairs] + [nc, nc + 1, nc + 2], dtype=np.int64)
    pg = np.array([q for _, q in pairs], dtype=np.int64)
    return pcols, pg


def measurement_structure(est_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(nl, nl_full, lin)`` of :func:`update_nonlinear`: the states the measurement depends on
    nonlinearly (alpha, beta, gamma, theta_py, theta_pz, theta_oz, k1, k2, k3, kIP of x, y, z),
    their full-coefficient indices (-1 - i for angle i), and the state of k0 of each axis."""
    nc = est_idx.size
    state_of = {int(f): k for k, f in enumerate(est_idx)}
    full = [I_THETA + i for i in range(3)] + [I_K0 + 3 * m + j for m in range(1, 5) for j in range(3)]
    nl = np.array([nc, nc + 1, nc + 2] + [state_of[f] for f in full], dtype=np.int64)
    nl_full = np.array([-1, -2, -3] + full, dtype=np.int64)
    lin = np.array([state_of[I_K0 + j] for j in range(3)], dtype=np.int64)
    return nl, nl_full, lin


def nonlinear_first_order(n: int, est_idx: np.ndarray) -> np.ndarray:
    """The state permutation that puts the nonlinear measurement states first, then k0, then the
    rest: with it the ``"all"`` update equals the ``"nonlinear"`` one (to rounding)."""
    nl, _, lin = measurement_structure(est_idx)
    head = list(nl) + list(lin)
    return np.array(head + [i for i in range(n) if i not in set(head)], dtype=np.int64)


def check_options(n: int, sigma_points: str, alpha: float, beta: float, kappa: float | None
                  ) -> tuple[float, float, float]:
    """Validate the UKF options (InputError naming the option); returns ``(h, w2, kappa)``."""
    if sigma_points not in SIGMA_POINT_MODES:
        raise InputError("ukf.sigma_points", f"is {sigma_points!r}; use one of {', '.join(SIGMA_POINT_MODES)}")
    kappa = 3.0 - n if kappa is None else float(kappa)
    try:
        check_ut_params(n, float(alpha), float(beta), kappa)
    except ValueError as exc:
        name = str(exc).split(" ", 1)[0]
        raise InputError(f"ukf.{name}", str(exc)) from None
    return float(alpha * np.sqrt(n + kappa)), float(beta - alpha * alpha), kappa


def run_ukf(
    data: EstimatorInput,
    settings: FilterSettings,
    *,
    sigma_points: str = "update",
    alpha: float = 1.0,
    beta: float = 2.0,
    kappa: float | None = None,
    sqrt_order: np.ndarray | None = None,
) -> Estimate:
    """Run the UKF over every position of a scheme, for a batch of B runs.

    Parameters
    ----------
    data : the record, commands and centrifuge parameters (:class:`~.ekf.EstimatorInput`; ``z``
        at the filter instants).
    settings : the filter settings (those of the EKF; ``passes`` as there).
    sigma_points : ``"update"`` (default: 2n + 1 sigma points in the measurement update, the
        EKF's propagation), ``"all"`` (2n + 1 in the propagation too; the textbook reference) or
        ``"nonlinear"`` (sigma points over the 18 states the measurement is nonlinear in, the
        rest exact; cheapest). See the module docstring for how they differ.
    alpha, beta, kappa : scaled-transform parameters (kappa None: ``3 - n``); beta >= alpha^2.
    sqrt_order : (n,) state permutation for the Cholesky factor of the ``"update"`` and ``"all"``
        variants (default: the state order); :func:`nonlinear_first_order` makes the update
        equal to ``"nonlinear"``'s (for tests).

    Returns
    -------
    Estimate (``failed_updates`` counts updates skipped because S or the sigma points' P block was
    not positive definite, and ``"all"`` propagations that fell back to the linear one for that reason).
    """
    z, t, cmd_deg, centrifuge_params = data.z, data.t, data.cmd_deg, data.centrifuge_params
    K = len(t)
    B = z[0].shape[0]
    est_idx = settings.coef_index
    n = est_idx.size + 3
    h, w2, _ = check_options(n, sigma_points, alpha, beta, kappa)
    mode = SIGMA_POINT_MODES.index(sigma_points)
    perm = np.arange(n, dtype=np.int64) if sqrt_order is None else np.asarray(sqrt_order, np.int64)
    if sorted(perm.tolist()) != list(range(n)):
        raise InputError("ukf.sqrt_order", f"must be a permutation of 0..{n - 1}")
    for k, tk in enumerate(t):
        tk = np.asarray(tk, float)
        if tk.size and (tk[0] < 0 or np.any(np.diff(tk) <= 0)):
            raise InputError(f"t[{k}]", "filter instants must be >= 0 and increasing")
    st = filter_start(cmd_deg, centrifuge_params, settings, B, K)
    coef_fixed = np.zeros((B, N_FULL))
    pcols, pg = propagation_structure(est_idx)
    nl, nl_full, lin = measurement_structure(est_idx)
    mstates = np.array([k for k, f in enumerate(est_idx) if I_K0 <= f < I_THETA + 3], dtype=np.int64)
    threaded, serial = _PASS_KERNELS[mode]
    kernel = serial if B == 1 or get_threads() == 1 else threaded

    def run_pass(x, P, z_all, t_all, offs, hidx, hist_x, hist_s, nis, n_bad):
        kernel(x, P, z_all, t_all, offs, st.cmd_rad, st.reset_var, est_idx, coef_fixed, st.params, st.r_var,
               st.q_rate, True, hidx, hist_x, hist_s, nis, n_bad, pcols, pg, nl, nl_full, lin,
               mstates, h, w2, perm)

    return drive_passes(run_pass, st.x, st.P, z, t, settings, settings.passes)
