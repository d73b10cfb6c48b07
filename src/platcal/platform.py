"""Platform attitude dynamics and measurement in the centrifuge (spec sections 5-6; eqs. 16-18).

In inertial-hold mode the stable element turns at minus the gyro drift, and the base turns
with the Earth, so the Euler angles obey (eq. 18, with the spec's sign)::

    [alpha', beta', gamma'] = -T(beta, gamma) [eps_p + C_r^p w_ie]          (rad/s)

``eps_p`` is the drift of gyros x, y, z (deg/h, converted to rad/s). The measurement is the
three accelerometer outputs (g) at the platform specific force ``f_p = C_r^p f_r``.

The kernels work on one replicate and take a :class:`Work` tuple of scratch arrays so the hot
loops never allocate. ``coef`` is always the full 48-vector of :mod:`platcal.instruments`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .centrifuge import P_G, P_OMEGA_N, P_OMEGA_U, specific_force_into
from .frames import DEG_PER_HOUR, c_rp_into, euler_t_into
from .instruments import GYRO_AXES, I_DOO, N_FULL, accel_output_into, gyro_drift_into


@njit(cache=True)
def make_work():
    """Scratch arrays for one replicate: (C, dC, T, dT, fr, f, eps, deps_df, reg, u, v3, m33)."""
    return (
        np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3)),
        np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 10)),
        np.empty(3), np.empty(3), np.empty((3, 3)),
    )


@njit(cache=True)
def attitude_rate_into(ang, coef, t, params, rate, jac_a, jac_c, want_jac, work):
    """Euler-angle rates of eq. 18 at time ``t`` (s since the position's start).

    Parameters
    ----------
    ang : (3,) alpha, beta, gamma in rad.
    coef : (48,) full coefficient vector (engineering units).
    params : packed centrifuge parameters (``Centrifuge.params()``).
    rate : (3,) out, rad/s.
    jac_a : (3, 3) out, ``d rate / d ang`` (1/s), if ``want_jac``.
    jac_c : (3, 48) out, ``d rate / d coef`` (rad/s per coefficient unit), if ``want_jac``;
        only the 30 gyro columns are written, the caller keeps the others at zero.
    """
    C, dC, T, dT, fr, f, eps, deps_df, reg, u, v3, m33 = work
    c_rp_into(ang[0], ang[1], ang[2], C, dC)
    euler_t_into(ang[1], ang[2], T, dT)
    specific_force_into(t, params, fr)
    g = params[P_G]
    wn = params[P_OMEGA_N]
    wu = params[P_OMEGA_U]
    for r in range(3):
        f[r] = (C[r, 0] * fr[0] + C[r, 1] * fr[1] + C[r, 2] * fr[2]) / g
    gyro_drift_into(coef, f, eps, deps_df, reg)
    for r in range(3):
        u[r] = eps[r] * DEG_PER_HOUR + C[r, 1] * wn + C[r, 2] * wu
    for r in range(3):
        rate[r] = -(T[r, 0] * u[0] + T[r, 1] * u[1] + T[r, 2] * u[2])
    if not want_jac:
        return
    for i in range(3):
        # v3 = d f / d ang_i (g); then du_i = k deps_df v3 + dC_i w_ie
        for r in range(3):
            v3[r] = (dC[i, r, 0] * fr[0] + dC[i, r, 1] * fr[1] + dC[i, r, 2] * fr[2]) / g
        for r in range(3):
            m33[r, i] = DEG_PER_HOUR * (deps_df[r, 0] * v3[0] + deps_df[r, 1] * v3[1]
                                        + deps_df[r, 2] * v3[2]) + dC[i, r, 1] * wn + dC[i, r, 2] * wu
    for r in range(3):
        for i in range(3):
            s = 0.0
            for k in range(3):
                s += dT[i, r, k] * u[k] + T[r, k] * m33[k, i]
            jac_a[r, i] = -s
    for j in range(3):
        for m in range(9):
            col = 3 * m + j
            for r in range(3):
                jac_c[r, col] = -T[r, j] * DEG_PER_HOUR * reg[j, m]
        for r in range(3):
            jac_c[r, I_DOO + j] = -T[r, j] * DEG_PER_HOUR * reg[j, 9]


@njit(cache=True)
def rk4_step(ang, coef, t, h, params, out, work, k_all):
    """One RK4 step of eq. 18 from ``t`` to ``t + h`` (s); writes the new angles into ``out``.

    ``k_all`` is (4, 3) scratch for the stage derivatives.
    """
    dummy_a = work[11]
    jc = np.empty((0, 0))
    attitude_rate_into(ang, coef, t, params, k_all[0], dummy_a, jc, False, work)
    for r in range(3):
        out[r] = ang[r] + 0.5 * h * k_all[0, r]
    attitude_rate_into(out, coef, t + 0.5 * h, params, k_all[1], dummy_a, jc, False, work)
    for r in range(3):
        out[r] = ang[r] + 0.5 * h * k_all[1, r]
    attitude_rate_into(out, coef, t + 0.5 * h, params, k_all[2], dummy_a, jc, False, work)
    for r in range(3):
        out[r] = ang[r] + h * k_all[2, r]
    attitude_rate_into(out, coef, t + h, params, k_all[3], dummy_a, jc, False, work)
    for r in range(3):
        out[r] = ang[r] + h / 6.0 * (k_all[0, r] + 2.0 * k_all[1, r] + 2.0 * k_all[2, r] + k_all[3, r])


@njit(cache=True)
def rk4_step_jac(ang, coef, t, h, params, out, phi_a, phi_c, work, scratch):
    """RK4 step of eq. 18 and its exact Jacobian (the derivative of the RK4 map itself).

    Writes the new angles into ``out``, ``phi_a = d out / d ang`` (3, 3) and
    ``phi_c = d out / d coef`` (3, 48). ``scratch`` comes from :func:`make_rk4_scratch`.
    """
    k, ja, jc, ka, kc, da, dc, xs = scratch
    for s in range(4):
        tau = t if s == 0 else (t + 0.5 * h if s < 3 else t + h)
        step = 0.0 if s == 0 else (0.5 * h if s < 3 else h)
        # stage point xs = ang + step * k[s-1] and its derivative (da, dc)
        for r in range(3):
            if s == 0:
                xs[r] = ang[r]
                for i in range(3):
                    da[r, i] = 1.0 if r == i else 0.0
                for i in range(N_FULL):
                    dc[r, i] = 0.0
            else:
                xs[r] = ang[r] + step * k[s - 1, r]
                for i in range(3):
                    da[r, i] = (1.0 if r == i else 0.0) + step * ka[s - 1, r, i]
                for i in range(N_FULL):
                    dc[r, i] = step * kc[s - 1, r, i]
        attitude_rate_into(xs, coef, tau, params, k[s], ja, jc, True, work)
        # chain rule: K_s = J_s [D_s] with J = [ja | jc]
        for r in range(3):
            for i in range(3):
                ka[s, r, i] = ja[r, 0] * da[0, i] + ja[r, 1] * da[1, i] + ja[r, 2] * da[2, i]
            for i in range(N_FULL):
                kc[s, r, i] = jc[r, i] + ja[r, 0] * dc[0, i] + ja[r, 1] * dc[1, i] + ja[r, 2] * dc[2, i]
    for r in range(3):
        out[r] = ang[r] + h / 6.0 * (k[0, r] + 2.0 * k[1, r] + 2.0 * k[2, r] + k[3, r])
        for i in range(3):
            phi_a[r, i] = (1.0 if r == i else 0.0) + h / 6.0 * (
                ka[0, r, i] + 2.0 * ka[1, r, i] + 2.0 * ka[2, r, i] + ka[3, r, i])
        for i in range(N_FULL):
            phi_c[r, i] = h / 6.0 * (kc[0, r, i] + 2.0 * kc[1, r, i] + 2.0 * kc[2, r, i] + kc[3, r, i])


@njit(cache=True)
def make_rk4_scratch():
    """Scratch for :func:`rk4_step_jac`: (k, ja, jc, ka, kc, da, dc, xs)."""
    return (
        np.empty((4, 3)), np.empty((3, 3)), np.zeros((3, N_FULL)), np.empty((4, 3, 3)),
        np.empty((4, 3, N_FULL)), np.empty((3, 3)), np.empty((3, N_FULL)), np.empty(3),
    )


@njit(cache=True)
def measure_into(ang, coef, t, params, out, h_coef, h_ang, work):
    """Accelerometer outputs (g) at angles ``ang`` (rad) and time ``t`` (eq. 13 with eq. 10).

    ``h_coef`` (3, 48) receives ``d out / d coef`` and ``h_ang`` (3, 3) ``d out / d ang``.
    """
    C, dC, T, dT, fr, f, eps, deps_df, reg, u, v3, dA_df = work
    c_rp_into(ang[0], ang[1], ang[2], C, dC)
    specific_force_into(t, params, fr)
    g = params[P_G]
    for r in range(3):
        f[r] = (C[r, 0] * fr[0] + C[r, 1] * fr[1] + C[r, 2] * fr[2]) / g
    accel_output_into(coef, f, out, h_coef, dA_df)
    for i in range(3):
        for r in range(3):
            v3[r] = (dC[i, r, 0] * fr[0] + dC[i, r, 1] * fr[1] + dC[i, r, 2] * fr[2]) / g
        for r in range(3):
            h_ang[r, i] = dA_df[r, 0] * v3[0] + dA_df[r, 1] * v3[1] + dA_df[r, 2] * v3[2]


# Python-facing helpers (allocate; for tests and small calls) ----------------------------------

def attitude_rate(ang, coef, t, params):
    """Euler-angle rates (rad/s) and Jacobians ``(rate, d/d ang (3,3), d/d coef (3,48))``."""
    rate, ja, jc = np.empty(3), np.empty((3, 3)), np.zeros((3, N_FULL))
    attitude_rate_into(np.asarray(ang, float), np.asarray(coef, float), float(t), params,
                       rate, ja, jc, True, make_work())
    return rate, ja, jc


def rk4(ang, coef, t, h, params):
    """One RK4 step of eq. 18 with its Jacobian: ``(ang_next, d/d ang, d/d coef)``."""
    out, pa, pc = np.empty(3), np.empty((3, 3)), np.empty((3, N_FULL))
    rk4_step_jac(np.asarray(ang, float), np.asarray(coef, float), float(t), float(h), params,
                 out, pa, pc, make_work(), make_rk4_scratch())
    return out, pa, pc


def measure(ang, coef, t, params):
    """Accelerometer outputs (g) and Jacobians ``(A, d/d coef (3,48), d/d ang (3,3))``."""
    out, hc, ha = np.empty(3), np.empty((3, N_FULL)), np.empty((3, 3))
    measure_into(np.asarray(ang, float), np.asarray(coef, float), float(t), params,
                 out, hc, ha, make_work())
    return out, hc, ha


# Fast kernels for the batched simulator and EKF ---------------------------------------------
#
# Same model as above, restructured for the hot loops: the base specific force is passed in
# (so callers can tabulate or reuse it instead of recomputing cos/sin of the centrifuge phase),
# sin/cos of the Euler angles are shared by C_r^p and T, and the coefficient Jacobian of the
# attitude rate is kept only over the 30 gyro columns it can be nonzero in (eq. 18 involves no
# accelerometer term), which makes the RK4-map Jacobian 3 x (3 + 30) instead of 3 x 51.

GYRO_COLS = np.concatenate([np.arange(I_DOO - 18), np.arange(I_DOO, N_FULL)]).astype(np.int64)
"""Full-vector indices of the 30 gyro coefficients (27 identified, then DOO x/y/z): the only
coefficient columns of ``d rate / d coef`` (and of the RK4 map) that can be nonzero."""
N_GYRO = 30


def _meas_cols() -> np.ndarray:
    # accelerometer j: k0, k1, k2, k3, kIP of axis j; y adds theta_py, z adds theta_pz, theta_oz
    from .instruments import I_K0, I_THETA
    cols = -np.ones((3, 7), dtype=np.int64)
    extra = ([], [I_THETA], [I_THETA + 1, I_THETA + 2])
    for j in range(3):
        c = [I_K0 + 3 * m + j for m in range(5)] + extra[j]
        cols[j, : len(c)] = c
    return cols


MEAS_COLS = _meas_cols()
"""(3, 7) full-vector indices of the coefficients accelerometer j's output depends on (-1 pads):
the only nonzero coefficient columns of the measurement Jacobian."""


@njit(cache=True)
def make_fast_work():
    """Scratch for the fast kernels: (C, dC, T, dT, f, eps, deps_df, reg, u, v3, m33, hc, dA)."""
    return (
        np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3)),
        np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 10)),
        np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, N_FULL)), np.empty((3, 3)),
    )


@njit(cache=True)
def _rotations(ang, C, dC, T, dT, want_d):
    """``C_r^p``, ``T = E^-1`` and (if ``want_d``) their angle partials at ``ang`` (rad)."""
    _rotations_sc(np.sin(ang[0]), np.cos(ang[0]), np.sin(ang[1]), np.cos(ang[1]),
                  np.sin(ang[2]), np.cos(ang[2]), C, dC, T, dT, want_d)


@njit(cache=True)
def _rotations_sc(sa, ca, sb, cb, sg, cg, C, dC, T, dT, want_d):
    """:func:`_rotations` from the sines and cosines of alpha, beta, gamma (one set, shared).

    Same closed forms as :func:`platcal.frames.c_rp_into` and :func:`platcal.frames.euler_t_into`.
    """
    C[0, 0] = cg * cb
    C[0, 1] = cg * sb * sa + sg * ca
    C[0, 2] = -cg * sb * ca + sg * sa
    C[1, 0] = -sg * cb
    C[1, 1] = -sg * sb * sa + cg * ca
    C[1, 2] = sg * sb * ca + cg * sa
    C[2, 0] = sb
    C[2, 1] = -cb * sa
    C[2, 2] = cb * ca
    ib = 1.0 / cb
    tb = sb * ib
    T[0, 0] = cg * ib
    T[0, 1] = -sg * ib
    T[0, 2] = 0.0
    T[1, 0] = sg
    T[1, 1] = cg
    T[1, 2] = 0.0
    T[2, 0] = -tb * cg
    T[2, 1] = tb * sg
    T[2, 2] = 1.0
    if not want_d:
        return
    dC[0, 0, 0] = 0.0
    dC[0, 0, 1] = cg * sb * ca - sg * sa
    dC[0, 0, 2] = cg * sb * sa + sg * ca
    dC[0, 1, 0] = 0.0
    dC[0, 1, 1] = -sg * sb * ca - cg * sa
    dC[0, 1, 2] = -sg * sb * sa + cg * ca
    dC[0, 2, 0] = 0.0
    dC[0, 2, 1] = -cb * ca
    dC[0, 2, 2] = -cb * sa
    dC[1, 0, 0] = -cg * sb
    dC[1, 0, 1] = cg * cb * sa
    dC[1, 0, 2] = -cg * cb * ca
    dC[1, 1, 0] = sg * sb
    dC[1, 1, 1] = -sg * cb * sa
    dC[1, 1, 2] = sg * cb * ca
    dC[1, 2, 0] = cb
    dC[1, 2, 1] = sb * sa
    dC[1, 2, 2] = -sb * ca
    dC[2, 0, 0] = -sg * cb
    dC[2, 0, 1] = -sg * sb * sa + cg * ca
    dC[2, 0, 2] = sg * sb * ca + cg * sa
    dC[2, 1, 0] = -cg * cb
    dC[2, 1, 1] = -cg * sb * sa - sg * ca
    dC[2, 1, 2] = cg * sb * ca - sg * sa
    dC[2, 2, 0] = 0.0
    dC[2, 2, 1] = 0.0
    dC[2, 2, 2] = 0.0
    for r in range(3):
        for c in range(3):
            dT[0, r, c] = 0.0
    dT[1, 0, 0] = cg * tb * ib
    dT[1, 0, 1] = -sg * tb * ib
    dT[1, 0, 2] = 0.0
    dT[1, 1, 0] = 0.0
    dT[1, 1, 1] = 0.0
    dT[1, 1, 2] = 0.0
    dT[1, 2, 0] = -cg * ib * ib
    dT[1, 2, 1] = sg * ib * ib
    dT[1, 2, 2] = 0.0
    dT[2, 0, 0] = -sg * ib
    dT[2, 0, 1] = -cg * ib
    dT[2, 0, 2] = 0.0
    dT[2, 1, 0] = cg
    dT[2, 1, 1] = -sg
    dT[2, 1, 2] = 0.0
    dT[2, 2, 0] = tb * sg
    dT[2, 2, 1] = tb * cg
    dT[2, 2, 2] = 0.0


@njit(cache=True)
def rate_fast(ang, coef, fr, params, rate, jac_a, jac_g, want_jac, w):
    """Eq. 18 like :func:`attitude_rate_into`, with the base specific force ``fr`` (m/s^2) given.

    ``rate`` (3,) rad/s; ``jac_a`` (3, 3) 1/s; ``jac_g`` (3, 30) rad/s per coefficient unit over
    :data:`GYRO_COLS` (only if ``want_jac``). ``w`` from :func:`make_fast_work`.
    """
    rate_fast_sc(np.sin(ang[0]), np.cos(ang[0]), np.sin(ang[1]), np.cos(ang[1]), np.sin(ang[2]),
                 np.cos(ang[2]), coef, fr, params, rate, jac_a, jac_g, want_jac, w)


@njit(cache=True)
def rate_fast_sc(sa, ca, sb, cb, sg, cg, coef, fr, params, rate, jac_a, jac_g, want_jac, w):
    """:func:`rate_fast` from the sines and cosines of the angles."""
    C, dC, T, dT, f, eps, deps_df, reg, u, v3, m33, _, _ = w
    _rotations_sc(sa, ca, sb, cb, sg, cg, C, dC, T, dT, want_jac)
    g = params[P_G]
    wn = params[P_OMEGA_N]
    wu = params[P_OMEGA_U]
    for r in range(3):
        f[r] = (C[r, 0] * fr[0] + C[r, 1] * fr[1] + C[r, 2] * fr[2]) / g
    gyro_drift_into(coef, f, eps, deps_df, reg)
    for r in range(3):
        u[r] = eps[r] * DEG_PER_HOUR + C[r, 1] * wn + C[r, 2] * wu
    for r in range(3):
        rate[r] = -(T[r, 0] * u[0] + T[r, 1] * u[1] + T[r, 2] * u[2])
    if not want_jac:
        return
    for i in range(3):
        for r in range(3):
            v3[r] = (dC[i, r, 0] * fr[0] + dC[i, r, 1] * fr[1] + dC[i, r, 2] * fr[2]) / g
        for r in range(3):
            m33[r, i] = DEG_PER_HOUR * (deps_df[r, 0] * v3[0] + deps_df[r, 1] * v3[1]
                                        + deps_df[r, 2] * v3[2]) + dC[i, r, 1] * wn + dC[i, r, 2] * wu
    for r in range(3):
        for i in range(3):
            s = 0.0
            for k in range(3):
                s += dT[i, r, k] * u[k] + T[r, k] * m33[k, i]
            jac_a[r, i] = -s
    for j in range(3):
        for r in range(3):
            tj = -T[r, j] * DEG_PER_HOUR
            for m in range(9):
                jac_g[r, 3 * m + j] = tj * reg[j, m]
            jac_g[r, 27 + j] = tj * reg[j, 9]


@njit(cache=True)
def rk4_fast(ang, coef, fr3, h, params, out, w, k_all, xs):
    """One RK4 step of eq. 18 over ``h`` s; ``fr3`` (3, 3) is the base specific force (m/s^2) at
    the step's start, middle and end. Writes the new angles (rad) into ``out``.

    ``k_all`` (4, 3) and ``xs`` (3,) are scratch.
    """
    ja = w[10]
    jg = ja  # not written when want_jac is False
    rate_fast(ang, coef, fr3[0], params, k_all[0], ja, jg, False, w)
    for r in range(3):
        xs[r] = ang[r] + 0.5 * h * k_all[0, r]
    rate_fast(xs, coef, fr3[1], params, k_all[1], ja, jg, False, w)
    for r in range(3):
        xs[r] = ang[r] + 0.5 * h * k_all[1, r]
    rate_fast(xs, coef, fr3[1], params, k_all[2], ja, jg, False, w)
    for r in range(3):
        xs[r] = ang[r] + h * k_all[2, r]
    rate_fast(xs, coef, fr3[2], params, k_all[3], ja, jg, False, w)
    for r in range(3):
        out[r] = ang[r] + h / 6.0 * (k_all[0, r] + 2.0 * k_all[1, r] + 2.0 * k_all[2, r] + k_all[3, r])


@njit(cache=True)
def make_fast_rk4_scratch():
    """Scratch for :func:`rk4_jac_fast`: (k, ja, jg, ka, kg, da, dg, xs)."""
    return (
        np.empty((4, 3)), np.empty((3, 3)), np.empty((3, N_GYRO)), np.empty((4, 3, 3)),
        np.empty((4, 3, N_GYRO)), np.empty((3, 3)), np.empty((3, N_GYRO)), np.empty(3),
    )


@njit(cache=True)
def rk4_jac_fast(ang, coef, fr3, h, params, out, phi_a, phi_g, w, scratch):
    """RK4 step like :func:`rk4_fast` and the exact Jacobian of the RK4 map.

    ``phi_a`` (3, 3) = d out / d ang; ``phi_g`` (3, 30) = d out / d coef over :data:`GYRO_COLS`
    (every other coefficient column of the map's Jacobian is exactly zero). Stage s sits at
    ``x_s = ang + c_s h k_{s-1}``, so by the chain rule its derivatives are
    ``ka_s = J_s (I + c_s h ka_{s-1})`` and ``kg_s = Jg_s + c_s h J_s kg_{s-1}``.
    """
    k, ja, jg, ka, kg, da, dg, xs = scratch
    sa, ca = np.sin(ang[0]), np.cos(ang[0])
    sb, cb = np.sin(ang[1]), np.cos(ang[1])
    sg, cg = np.sin(ang[2]), np.cos(ang[2])
    for s in range(4):
        step = 0.0 if s == 0 else (0.5 * h if s < 3 else h)
        fr = fr3[0] if s == 0 else (fr3[1] if s < 3 else fr3[2])
        if s == 0:
            rate_fast_sc(sa, ca, sb, cb, sg, cg, coef, fr, params, k[0], ja, jg, True, w)
            for r in range(3):
                for i in range(3):
                    ka[0, r, i] = ja[r, i]
                for i in range(N_GYRO):
                    kg[0, r, i] = jg[r, i]
            continue
        s0, c0 = _shift(sa, ca, step * k[s - 1, 0])
        s1, c1 = _shift(sb, cb, step * k[s - 1, 1])
        s2, c2 = _shift(sg, cg, step * k[s - 1, 2])
        rate_fast_sc(s0, c0, s1, c1, s2, c2, coef, fr, params, k[s], ja, jg, True, w)
        for r in range(3):
            j0, j1, j2 = ja[r, 0], ja[r, 1], ja[r, 2]
            for i in range(3):
                ka[s, r, i] = ja[r, i] + step * (j0 * ka[s - 1, 0, i] + j1 * ka[s - 1, 1, i]
                                                 + j2 * ka[s - 1, 2, i])
            for i in range(N_GYRO):
                kg[s, r, i] = jg[r, i] + step * (j0 * kg[s - 1, 0, i] + j1 * kg[s - 1, 1, i]
                                                 + j2 * kg[s - 1, 2, i])
    h6 = h / 6.0
    for r in range(3):
        out[r] = ang[r] + h6 * (k[0, r] + 2.0 * k[1, r] + 2.0 * k[2, r] + k[3, r])
        for i in range(3):
            phi_a[r, i] = (1.0 if r == i else 0.0) + h6 * (
                ka[0, r, i] + 2.0 * ka[1, r, i] + 2.0 * ka[2, r, i] + ka[3, r, i])
        for i in range(N_GYRO):
            phi_g[r, i] = h6 * (kg[0, r, i] + 2.0 * kg[1, r, i] + 2.0 * kg[2, r, i] + kg[3, r, i])


@njit(cache=True)
def measure_fast(ang, coef, fr, params, out, h_ang, want_jac, w):
    """Accelerometer outputs (g) like :func:`measure_into`, with the base specific force ``fr``
    (m/s^2) given. If ``want_jac``: ``h_ang`` (3, 3) = d out / d ang, and ``w[11]`` (3, 48) holds
    d out / d coef (nonzero only in :data:`MEAS_COLS`)."""
    C, dC, T, dT, f, eps, deps_df, reg, u, v3, m33, hc, dA = w
    _rotations(ang, C, dC, T, dT, want_jac)
    g = params[P_G]
    for r in range(3):
        f[r] = (C[r, 0] * fr[0] + C[r, 1] * fr[1] + C[r, 2] * fr[2]) / g
    accel_output_into(coef, f, out, hc, dA)
    if not want_jac:
        return
    for i in range(3):
        for r in range(3):
            v3[r] = (dC[i, r, 0] * fr[0] + dC[i, r, 1] * fr[1] + dC[i, r, 2] * fr[2]) / g
        for r in range(3):
            h_ang[r, i] = dA[r, 0] * v3[0] + dA[r, 1] * v3[1] + dA[r, 2] * v3[2]


@njit(cache=True)
def _drift(coef, j, f0, f1, f2):
    """Drift of gyro j (deg/h) at the platform specific force (g); eq. 11-12 written out on
    scalars for the simulator's hot loop (same terms as :func:`gyro_drift_into`)."""
    aI = GYRO_AXES[j, 0, 0] * f0 + GYRO_AXES[j, 0, 1] * f1 + GYRO_AXES[j, 0, 2] * f2
    aO = GYRO_AXES[j, 1, 0] * f0 + GYRO_AXES[j, 1, 1] * f1 + GYRO_AXES[j, 1, 2] * f2
    aS = GYRO_AXES[j, 2, 0] * f0 + GYRO_AXES[j, 2, 1] * f1 + GYRO_AXES[j, 2, 2] * f2
    e = coef[I_DOO + j] * (aO * aO)
    e += (coef[j] + coef[3 + j] * aI + coef[6 + j] * aO + coef[9 + j] * aS
          + coef[12 + j] * (aI * aI) + coef[15 + j] * (aS * aS) + coef[18 + j] * (aI * aO)
          + coef[21 + j] * (aI * aS) + coef[24 + j] * (aO * aS))
    return e


@njit(cache=True)
def _shift(s, c, d):
    """``(sin(a + d), cos(a + d))`` from ``s = sin a``, ``c = cos a``.

    An RK4 stage moves the angles by ``d ~ 1e-9 rad``, so the Taylor forms of ``sin d``, ``cos d``
    are exact to rounding (truncation below 1e-20 relative) and save three quarters of the
    trigonometric calls; a large ``d`` falls back to the direct functions.
    """
    if abs(d) < 1e-4:
        d2 = d * d
        cd = 1.0 - 0.5 * d2
        sd = d - d * d2 * (1.0 / 6.0)
        return s * cd + c * sd, c * cd - s * sd
    return s * np.cos(d) + c * np.sin(d), c * np.cos(d) - s * np.sin(d)


@njit(cache=True)
def rate_scalar(sa, ca, sb, cb, sg, cg, coef, fr0, fr1, fr2, g, wn, wu):
    """Eq. 18 without Jacobians on scalars: (alpha', beta', gamma') in rad/s from the sines and
    cosines of the angles and the base specific force (m/s^2). Same model as :func:`rate_fast`."""
    c00 = cg * cb
    c01 = cg * sb * sa + sg * ca
    c02 = -cg * sb * ca + sg * sa
    c10 = -sg * cb
    c11 = -sg * sb * sa + cg * ca
    c12 = sg * sb * ca + cg * sa
    c20 = sb
    c21 = -cb * sa
    c22 = cb * ca
    f0 = (c00 * fr0 + c01 * fr1 + c02 * fr2) / g
    f1 = (c10 * fr0 + c11 * fr1 + c12 * fr2) / g
    f2 = (c20 * fr0 + c21 * fr1 + c22 * fr2) / g
    u0 = _drift(coef, 0, f0, f1, f2) * DEG_PER_HOUR + c01 * wn + c02 * wu
    u1 = _drift(coef, 1, f0, f1, f2) * DEG_PER_HOUR + c11 * wn + c12 * wu
    u2 = _drift(coef, 2, f0, f1, f2) * DEG_PER_HOUR + c21 * wn + c22 * wu
    ib = 1.0 / cb
    tb = sb * ib
    r0 = -(cg * ib * u0 - sg * ib * u1)
    r1 = -(sg * u0 + cg * u1)
    r2 = -(-tb * cg * u0 + tb * sg * u1 + u2)
    return r0, r1, r2


@njit(cache=True)
def _stage(sa, ca, sb, cb, sg, cg, d0, d1, d2, coef, fr, g, wn, wu):
    """Attitude rate at the angles moved by (d0, d1, d2) rad from those whose sin/cos are given."""
    s0, c0 = _shift(sa, ca, d0)
    s1, c1 = _shift(sb, cb, d1)
    s2, c2 = _shift(sg, cg, d2)
    return rate_scalar(s0, c0, s1, c1, s2, c2, coef, fr[0], fr[1], fr[2], g, wn, wu)


@njit(cache=True)
def rk4_scalar(ang, coef, fr3, h, params, out):
    """One RK4 step of eq. 18 over ``h`` s like :func:`rk4_fast`, on scalars (no scratch).

    Writes the new angles (rad) into ``out``; ``fr3`` (3, 3) is the base specific force (m/s^2)
    at the step's start, middle and end.
    """
    g = params[P_G]
    wn = params[P_OMEGA_N]
    wu = params[P_OMEGA_U]
    a0, a1, a2 = ang[0], ang[1], ang[2]
    sa, ca = np.sin(a0), np.cos(a0)
    sb, cb = np.sin(a1), np.cos(a1)
    sg, cg = np.sin(a2), np.cos(a2)
    k10, k11, k12 = rate_scalar(sa, ca, sb, cb, sg, cg, coef, fr3[0, 0], fr3[0, 1], fr3[0, 2],
                                g, wn, wu)
    hh = 0.5 * h
    k20, k21, k22 = _stage(sa, ca, sb, cb, sg, cg, hh * k10, hh * k11, hh * k12, coef, fr3[1],
                           g, wn, wu)
    k30, k31, k32 = _stage(sa, ca, sb, cb, sg, cg, hh * k20, hh * k21, hh * k22, coef, fr3[1],
                           g, wn, wu)
    k40, k41, k42 = _stage(sa, ca, sb, cb, sg, cg, h * k30, h * k31, h * k32, coef, fr3[2],
                           g, wn, wu)
    h6 = h / 6.0
    out[0] = a0 + h6 * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
    out[1] = a1 + h6 * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
    out[2] = a2 + h6 * (k12 + 2.0 * k22 + 2.0 * k32 + k42)
