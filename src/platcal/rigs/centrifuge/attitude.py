"""Platform attitude dynamics and accelerometer measurement on a moving base
(docs/centrifuge-model.md §5-6; eqs. 16-18).

The base motion enters only through the base specific force ``f_r`` (m/s^2, base frame r) that
the caller passes in, and the site constants in the packed parameter vector (``params[P_G]``,
``params[P_OMEGA_N]``, ``params[P_OMEGA_U]``; slots before :data:`P_G` belong to the rig's base
motion), so any rig whose base frame is held level and north-pointing can use these kernels.

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
from ...jit import njit

from ...model.frames import ARCSEC, DEG_PER_HOUR, c_rp_into, euler_t_into
from ...model.instruments import (GYRO_AXES, I_DOO, I_K0, I_THETA, N_FULL, UG, accel_axes, accel_axes_sc,
                          accel_one, accel_out, accel_output_into, accel_slopes, gyro_axis_components,
                          gyro_drift_into, gyro_drift_scalar, gyro_drift_slopes)

P_G, P_OMEGA_N, P_OMEGA_U = 2, 3, 4
"""Indices of g (m/s^2) and the Earth rate's north and up components (rad/s) in the packed
parameter vector the kernels take; the slots before P_G are the rig's base-motion parameters."""


@njit(cache=True)
def make_work():
    """Scratch arrays for one replicate: (C, dC, T, dT, fr, f, eps, deps_df, reg, u, v3, m33)."""
    return (
        np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3)),
        np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 10)),
        np.empty(3), np.empty(3), np.empty((3, 3)),
    )


@njit(cache=True)
def attitude_rate_into(ang, coef, fr_in, params, rate, jac_a, jac_c, want_jac, work):
    """Euler-angle rates of eq. 18 at the base specific force ``fr_in`` (3,) m/s^2.

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
    for r in range(3):
        fr[r] = fr_in[r]
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
def rk4_step_jac(ang, coef, fr3, h, params, out, phi_a, phi_c, work, scratch):
    """RK4 step of eq. 18 and its exact Jacobian (the derivative of the RK4 map itself).

    ``fr3`` (3, 3): the base specific force (m/s^2) at the step's start, middle and end.

    Writes the new angles into ``out``, ``phi_a = d out / d ang`` (3, 3) and
    ``phi_c = d out / d coef`` (3, 48). ``scratch`` comes from :func:`make_rk4_scratch`.
    """
    k, ja, jc, ka, kc, da, dc, xs = scratch
    for s in range(4):
        fr = fr3[0] if s == 0 else (fr3[1] if s < 3 else fr3[2])
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
        attitude_rate_into(xs, coef, fr, params, k[s], ja, jc, True, work)
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
def measure_into(ang, coef, fr_in, params, out, h_coef, h_ang, work):
    """Accelerometer outputs (g) at angles ``ang`` (rad) and base specific force ``fr_in`` (m/s^2), eq. 13.

    ``h_coef`` (3, 48) receives ``d out / d coef`` and ``h_ang`` (3, 3) ``d out / d ang``.
    """
    C, dC, T, dT, fr, f, eps, deps_df, reg, u, v3, dA_df = work
    c_rp_into(ang[0], ang[1], ang[2], C, dC)
    for r in range(3):
        fr[r] = fr_in[r]
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

def attitude_rate(ang, coef, fr, params):
    """Euler-angle rates (rad/s) and Jacobians ``(rate, d/d ang (3,3), d/d coef (3,48))``."""
    rate, ja, jc = np.empty(3), np.empty((3, 3)), np.zeros((3, N_FULL))
    attitude_rate_into(np.asarray(ang, float), np.asarray(coef, float), np.asarray(fr, float), params,
                       rate, ja, jc, True, make_work())
    return rate, ja, jc


def rk4(ang, coef, fr3, h, params):
    """One RK4 step of eq. 18 with its Jacobian: ``(ang_next, d/d ang, d/d coef)``; ``fr3`` (3, 3)
    the base specific force (m/s^2) at the step's start, middle and end."""
    out, pa, pc = np.empty(3), np.empty((3, 3)), np.empty((3, N_FULL))
    rk4_step_jac(np.asarray(ang, float), np.asarray(coef, float), np.asarray(fr3, float), float(h), params,
                 out, pa, pc, make_work(), make_rk4_scratch())
    return out, pa, pc


def measure(ang, coef, fr, params):
    """Accelerometer outputs (g) and Jacobians ``(A, d/d coef (3,48), d/d ang (3,3))``."""
    out, hc, ha = np.empty(3), np.empty((3, N_FULL)), np.empty((3, 3))
    measure_into(np.asarray(ang, float), np.asarray(coef, float), np.asarray(fr, float), params,
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
def c_rp_sc(sa, ca, sb, cb, sg, cg):
    """``C_r^p = Mz(gamma) My(beta) Mx(alpha)`` (row-major 9-tuple) from the sines and cosines of
    alpha, beta, gamma (docs/centrifuge-model.md §3): the scalar kernels' one copy of it."""
    return (cg * cb, cg * sb * sa + sg * ca, -cg * sb * ca + sg * sa,
            -sg * cb, -sg * sb * sa + cg * ca, sg * sb * ca + cg * sa,
            sb, -cb * sa, cb * ca)


@njit(cache=True)
def _force_p(c00, c01, c02, c10, c11, c12, c20, c21, c22, fr0, fr1, fr2, g):
    """The platform specific force ``f_p = C_r^p f_r / g`` (g) from the base's (m/s^2)."""
    return ((c00 * fr0 + c01 * fr1 + c02 * fr2) / g, (c10 * fr0 + c11 * fr1 + c12 * fr2) / g,
            (c20 * fr0 + c21 * fr1 + c22 * fr2) / g)


@njit(cache=True)
def _drift(coef, j, f0, f1, f2):
    """Drift of gyro j (deg/h) at the platform specific force (g), eqs. 11-12."""
    aI, aO, aS = gyro_axis_components(j, f0, f1, f2)
    return gyro_drift_scalar(coef, j, aI, aO, aS)


SHIFT_SMALL = 1e-4
"""rad: below it :func:`_shift` takes the Taylor form :func:`shift_small`."""


@njit(cache=True)
def _shift(s, c, d):
    """``(sin(a + d), cos(a + d))`` from ``s = sin a``, ``c = cos a``.

    An RK4 stage moves the angles by ``d ~ 1e-9 rad``, so the Taylor forms of ``sin d``, ``cos d``
    are exact to rounding (truncation below 1e-20 relative) and save three quarters of the
    trigonometric calls; a large ``d`` (:data:`SHIFT_SMALL` or more) falls back to the direct functions.
    """
    if abs(d) < SHIFT_SMALL:
        return shift_small(s, c, d)
    return s * np.cos(d) + c * np.sin(d), c * np.cos(d) - s * np.sin(d)


@njit(cache=True)
def shift_small(s, c, d):
    """:func:`_shift` for ``|d| <`` :data:`SHIFT_SMALL` rad: the Taylor forms, no branch and no call
    (what a loop over sigma points vectorises)."""
    d2 = d * d
    cd = 1.0 - 0.5 * d2
    sd = d - d * d2 * (1.0 / 6.0)
    return s * cd + c * sd, c * cd - s * sd


# rate_scalar, _stage, rk4_scalar_sc and measure_scalar are inlined into their callers (the
# simulator, the UKF): a call between compiled functions takes two atomic reference counts per
# array argument, 45 % of the simulator's time before (issue 22); the arithmetic is unchanged.
@njit(cache=True, inline="always")
def rate_scalar(sa, ca, sb, cb, sg, cg, coef, fr0, fr1, fr2, g, wn, wu):
    """Eq. 18 without Jacobians on scalars: (alpha', beta', gamma') in rad/s from the sines and
    cosines of the angles and the base specific force (m/s^2). Same model as :func:`attitude_rate_into`."""
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_rp_sc(sa, ca, sb, cb, sg, cg)
    f0, f1, f2 = _force_p(c00, c01, c02, c10, c11, c12, c20, c21, c22, fr0, fr1, fr2, g)
    # the axis as an int64, not a literal 0, 1, 2: a literal argument makes numba compile the
    # callee (and what it calls) once per value, on top of the int64 version other callers use
    j0, j1, j2 = np.int64(0), np.int64(1), np.int64(2)
    u0 = _drift(coef, j0, f0, f1, f2) * DEG_PER_HOUR + c01 * wn + c02 * wu
    u1 = _drift(coef, j1, f0, f1, f2) * DEG_PER_HOUR + c11 * wn + c12 * wu
    u2 = _drift(coef, j2, f0, f1, f2) * DEG_PER_HOUR + c21 * wn + c22 * wu
    ib = 1.0 / cb
    tb = sb * ib
    r0 = -(cg * ib * u0 - sg * ib * u1)
    r1 = -(sg * u0 + cg * u1)
    r2 = -(-tb * cg * u0 + tb * sg * u1 + u2)
    return r0, r1, r2


@njit(cache=True, inline="always")
def _stage(sa, ca, sb, cb, sg, cg, d0, d1, d2, coef, fr0, fr1, fr2, g, wn, wu):
    """Attitude rate at the angles moved by (d0, d1, d2) rad from those whose sin/cos are given;
    ``fr*`` the base specific force (m/s^2) at the stage's time."""
    s0, c0 = _shift(sa, ca, d0)
    s1, c1 = _shift(sb, cb, d1)
    s2, c2 = _shift(sg, cg, d2)
    return rate_scalar(s0, c0, s1, c1, s2, c2, coef, fr0, fr1, fr2, g, wn, wu)


@njit(cache=True)
def rk4_scalar(ang, coef, fr3, h, params, out):
    """One RK4 step of eq. 18 over ``h`` s (the map of :func:`rk4_step_jac`), on scalars (no scratch).

    Writes the new angles (rad) into ``out``; ``fr3`` (3, 3) is the base specific force (m/s^2)
    at the step's start, middle and end.
    """
    return rk4_scalar_sc(np.sin(ang[0]), np.cos(ang[0]), np.sin(ang[1]), np.cos(ang[1]),
                         np.sin(ang[2]), np.cos(ang[2]), ang, coef, fr3, h, params, out)


# Scalar rate-and-Jacobian kernel for the filter's RK4 map ---------------------------------
# Numba passes arrays between compiled functions as reference-counted structs; in a kernel
# called 72 000 times per replicate those calls cost more than the arithmetic. This version
# keeps C_r^p, T and their partials in registers and writes one flat result vector.

V_RATE, V_JA, V_T, V_A, V_U, V_DU = 0, 3, 12, 21, 30, 33
"""Layout of the result vector of :func:`rate_jac_sc` (42 entries): rate (3, rad/s), jac_a
(3x3 row-major, 1/s), T (3x3 row-major), aI, aO, aS of gyros x, y, z (g); then scratch."""


@njit(cache=True, inline="always")
def rate_jac_sc(sa, ca, sb, cb, sg, cg, coef, fr0, fr1, fr2, g, wn, wu, v):
    """Eq. 18 and its angle Jacobian from the sines and cosines of the angles and the base
    specific force (m/s^2); results into ``v`` (42,) laid out as :data:`V_RATE` ... :data:`V_A`.

    Same model and closed forms as :func:`attitude_rate_into`; the coefficient Jacobian follows from T
    and the gyro axis components: ``d rate_r / d coef[3 m + j] = -T[r, j] deg/h reg_jm``.
    """
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_rp_sc(sa, ca, sb, cb, sg, cg)
    # d C / d beta
    b00 = -cg * sb
    b01 = cg * cb * sa
    b02 = -cg * cb * ca
    b10 = sg * sb
    b11 = -sg * cb * sa
    b12 = sg * cb * ca
    b20 = cb
    b21 = sb * sa
    b22 = -sb * ca
    f0, f1, f2 = _force_p(c00, c01, c02, c10, c11, c12, c20, c21, c22, fr0, fr1, fr2, g)
    # d f / d angle: alpha turns columns 1, 2 of C; gamma rotates rows 0, 1
    fa0 = (-c02 * fr1 + c01 * fr2) / g
    fa1 = (-c12 * fr1 + c11 * fr2) / g
    fa2 = (-c22 * fr1 + c21 * fr2) / g
    fb0 = (b00 * fr0 + b01 * fr1 + b02 * fr2) / g
    fb1 = (b10 * fr0 + b11 * fr1 + b12 * fr2) / g
    fb2 = (b20 * fr0 + b21 * fr1 + b22 * fr2) / g
    fg0 = f1
    fg1 = -f0
    fg2 = 0.0
    ib = 1.0 / cb
    tb = sb * ib
    t00, t01 = cg * ib, -sg * ib
    t10, t11 = sg, cg
    t20, t21 = -tb * cg, tb * sg
    for j in range(3):
        # gyro j's axis components of f and of its angle derivatives
        aI, aO, aS = gyro_axis_components(j, f0, f1, f2)
        v[V_A + 3 * j] = aI
        v[V_A + 3 * j + 1] = aO
        v[V_A + 3 * j + 2] = aS
        e = gyro_drift_scalar(coef, j, aI, aO, aS)
        gI, gO, gS = gyro_drift_slopes(coef, j, aI, aO, aS)
        # deps_j / d angle_i = (gI e_I + gO e_O + gS e_S) . d f / d angle_i   (deg/h per rad)
        d0 = gI * GYRO_AXES[j, 0, 0] + gO * GYRO_AXES[j, 1, 0] + gS * GYRO_AXES[j, 2, 0]
        d1 = gI * GYRO_AXES[j, 0, 1] + gO * GYRO_AXES[j, 1, 1] + gS * GYRO_AXES[j, 2, 1]
        d2 = gI * GYRO_AXES[j, 0, 2] + gO * GYRO_AXES[j, 1, 2] + gS * GYRO_AXES[j, 2, 2]
        # u_j and du_j / d angle parked in the tail of v (scratch, no allocation)
        v[V_U + j] = e * DEG_PER_HOUR
        v[V_DU + 3 * j] = DEG_PER_HOUR * (d0 * fa0 + d1 * fa1 + d2 * fa2)
        v[V_DU + 3 * j + 1] = DEG_PER_HOUR * (d0 * fb0 + d1 * fb1 + d2 * fb2)
        v[V_DU + 3 * j + 2] = DEG_PER_HOUR * (d0 * fg0 + d1 * fg1 + d2 * fg2)
    u0 = v[V_U] + c01 * wn + c02 * wu
    u1 = v[V_U + 1] + c11 * wn + c12 * wu
    u2 = v[V_U + 2] + c21 * wn + c22 * wu
    # du (3 x 3, row-major) is indexed in v itself: a reshaped view would cost a call and two
    # atomic reference-count updates per stage (issue 22)
    # Earth-rate terms of du: d C[r, 1:3] / d angle
    v[V_DU] += -c02 * wn + c01 * wu
    v[V_DU + 3] += -c12 * wn + c11 * wu
    v[V_DU + 6] += -c22 * wn + c21 * wu
    v[V_DU + 1] += b01 * wn + b02 * wu
    v[V_DU + 4] += b11 * wn + b12 * wu
    v[V_DU + 7] += b21 * wn + b22 * wu
    v[V_DU + 2] += c11 * wn + c12 * wu
    v[V_DU + 5] += -c01 * wn - c02 * wu
    v[V_RATE] = -(t00 * u0 + t01 * u1)
    v[V_RATE + 1] = -(t10 * u0 + t11 * u1)
    v[V_RATE + 2] = -(t20 * u0 + t21 * u1 + u2)
    # d T / d beta rows: [cg tb ib, -sg tb ib, 0], 0, [-cg ib^2, sg ib^2, 0]; d T / d gamma rows:
    # [-sg ib, -cg ib, 0], [cg, -sg, 0], [tb sg, tb cg, 0]; d T / d alpha = 0
    dtb0 = cg * tb * ib * u0 - sg * tb * ib * u1
    dtb2 = -cg * ib * ib * u0 + sg * ib * ib * u1
    dtg0 = -sg * ib * u0 - cg * ib * u1
    dtg1 = cg * u0 - sg * u1
    dtg2 = tb * sg * u0 + tb * cg * u1
    for i in range(3):
        v[V_JA + i] = -(t00 * v[V_DU + i] + t01 * v[V_DU + 3 + i])
        v[V_JA + 3 + i] = -(t10 * v[V_DU + i] + t11 * v[V_DU + 3 + i])
        v[V_JA + 6 + i] = -(t20 * v[V_DU + i] + t21 * v[V_DU + 3 + i] + v[V_DU + 6 + i])
    v[V_JA + 1] -= dtb0
    v[V_JA + 7] -= dtb2
    v[V_JA + 2] -= dtg0
    v[V_JA + 5] -= dtg1
    v[V_JA + 8] -= dtg2
    v[V_T] = t00
    v[V_T + 1] = t01
    v[V_T + 2] = 0.0
    v[V_T + 3] = t10
    v[V_T + 4] = t11
    v[V_T + 5] = 0.0
    v[V_T + 6] = t20
    v[V_T + 7] = t21
    v[V_T + 8] = 1.0


@njit(cache=True, inline="always")
def rk4_jac_sc(ang, coef, fr3, h, params, out, phi_a, phi_g, scratch):
    """RK4 step of eq. 18 and the exact Jacobian of the RK4 map, like :func:`rk4_step_jac`,
    built on :func:`rate_jac_sc`. ``scratch`` from :func:`make_sc_rk4_scratch`.

    Writes ``out`` (3,) rad, ``phi_a`` (3, 3) and ``phi_g`` (3, 30) over :data:`GYRO_COLS`.
    """
    k, ka, kg, v = scratch
    g = params[P_G]
    wn = params[P_OMEGA_N]
    wu = params[P_OMEGA_U]
    sa, ca = np.sin(ang[0]), np.cos(ang[0])
    sb, cb = np.sin(ang[1]), np.cos(ang[1])
    sg, cg = np.sin(ang[2]), np.cos(ang[2])
    for s in range(4):
        fs = 0 if s == 0 else (1 if s < 3 else 2)
        if s == 0:
            step = 0.0
            s0, c0, s1, c1, s2, c2 = sa, ca, sb, cb, sg, cg
        else:
            step = 0.5 * h if s < 3 else h
            s0, c0 = _shift(sa, ca, step * k[s - 1, 0])
            s1, c1 = _shift(sb, cb, step * k[s - 1, 1])
            s2, c2 = _shift(sg, cg, step * k[s - 1, 2])
        # one call site: rate_jac_sc is inlined, and each site is a copy of its code that numba
        # types and lowers and LLVM optimises in every kernel that inlines this step
        rate_jac_sc(s0, c0, s1, c1, s2, c2, coef, fr3[fs, 0], fr3[fs, 1], fr3[fs, 2], g, wn, wu, v)
        for r in range(3):
            k[s, r] = v[V_RATE + r]
        for r in range(3):
            j0, j1, j2 = v[V_JA + 3 * r], v[V_JA + 3 * r + 1], v[V_JA + 3 * r + 2]
            for i in range(3):
                d = v[V_JA + 3 * r + i]
                if s > 0:
                    d += step * (j0 * ka[s - 1, 0, i] + j1 * ka[s - 1, 1, i] + j2 * ka[s - 1, 2, i])
                ka[s, r, i] = d
            for j in range(3):
                tj = -v[V_T + 3 * r + j] * DEG_PER_HOUR
                aI, aO, aS = v[V_A + 3 * j], v[V_A + 3 * j + 1], v[V_A + 3 * j + 2]
                kg[s, r, j] = tj
                kg[s, r, 3 + j] = tj * aI
                kg[s, r, 6 + j] = tj * aO
                kg[s, r, 9 + j] = tj * aS
                kg[s, r, 12 + j] = tj * (aI * aI)
                kg[s, r, 15 + j] = tj * (aS * aS)
                kg[s, r, 18 + j] = tj * (aI * aO)
                kg[s, r, 21 + j] = tj * (aI * aS)
                kg[s, r, 24 + j] = tj * (aO * aS)
                kg[s, r, 27 + j] = tj * (aO * aO)
            if s > 0:
                for i in range(N_GYRO):
                    kg[s, r, i] += step * (j0 * kg[s - 1, 0, i] + j1 * kg[s - 1, 1, i]
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
def make_sc_rk4_scratch():
    """Scratch for :func:`rk4_jac_sc`: (k (4, 3), ka (4, 3, 3), kg (4, 3, 30), v (42,))."""
    return np.empty((4, 3)), np.empty((4, 3, 3)), np.empty((4, 3, N_GYRO)), np.empty(42)


@njit(cache=True)
def make_step_scratch():
    """Scratch of one attitude step with its Jacobians (the EKF, UKF and ML kernels): the
    :func:`make_sc_rk4_scratch` tuple, the new angles (3,), the attitude block (3, 3) and the
    gyro-coefficient block (3, N_GYRO)."""
    return make_sc_rk4_scratch(), np.empty(3), np.empty((3, 3)), np.empty((3, N_GYRO))


@njit(cache=True, inline="always")
def measure_scalar(sa, ca, sb, cb, sg, cg, coef, fr0, fr1, fr2, g):
    """Accelerometer outputs x, y, z (g), no Jacobians, from the sines and cosines of the
    angles and the base specific force (m/s^2): the simulator's measurement (eq. 13)."""
    return measure_coef_sc(sa, ca, sb, cb, sg, cg, fr0, fr1, fr2, g,
                           coef[I_K0], coef[I_K0 + 1], coef[I_K0 + 2], coef[I_K0 + 3], coef[I_K0 + 4],
                           coef[I_K0 + 5], coef[I_K0 + 6], coef[I_K0 + 7], coef[I_K0 + 8], coef[I_K0 + 9],
                           coef[I_K0 + 10], coef[I_K0 + 11], coef[I_K0 + 12], coef[I_K0 + 13],
                           coef[I_K0 + 14], coef[I_THETA], coef[I_THETA + 1], coef[I_THETA + 2])


@njit(cache=True, inline="always")
def measure_coef_sc(sa, ca, sb, cb, sg, cg, fr0, fr1, fr2, g, k0x, k0y, k0z, k1x, k1y, k1z, k2x, k2y,
                    k2z, k3x, k3y, k3z, kpx, kpy, kpz, t_py, t_pz, t_oz):
    """:func:`measure_scalar` with the 18 coefficients it reads as scalars, in the full vector's
    order (``coef[I_K0:I_THETA + 3]``: k0, k1, k2, k3, kIP of x, y, z, then theta_py, theta_pz,
    theta_oz; units of :mod:`platcal.model.instruments`): no array, so a loop over the UKF's sigma
    points vectorises (issue 22)."""
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_rp_sc(sa, ca, sb, cb, sg, cg)
    f0, f1, f2 = _force_p(c00, c01, c02, c10, c11, c12, c20, c21, c22, fr0, fr1, fr2, g)
    j0, j1, j2 = np.int64(0), np.int64(1), np.int64(2)  # int64, not literals (see rate_scalar)
    aI0, aP0 = accel_axes_sc(j0, f0, f1, f2, t_py, t_pz, t_oz)
    aI1, aP1 = accel_axes_sc(j1, f0, f1, f2, t_py, t_pz, t_oz)
    aI2, aP2 = accel_axes_sc(j2, f0, f1, f2, t_py, t_pz, t_oz)
    return (accel_out(k0x, k1x, k2x, k3x, kpx, aI0, aP0), accel_out(k0y, k1y, k2y, k3y, kpy, aI1, aP1),
            accel_out(k0z, k1z, k2z, k3z, kpz, aI2, aP2))


@njit(cache=True, inline="always")
def rk4_scalar_sc(sa, ca, sb, cb, sg, cg, ang, coef, fr3, h, params, out):
    """:func:`rk4_scalar` with the sines and cosines of ``ang`` already at hand."""
    g = params[P_G]
    wn = params[P_OMEGA_N]
    wu = params[P_OMEGA_U]
    a0, a1, a2 = ang[0], ang[1], ang[2]
    k10, k11, k12 = rate_scalar(sa, ca, sb, cb, sg, cg, coef, fr3[0, 0], fr3[0, 1], fr3[0, 2],
                                g, wn, wu)
    hh = 0.5 * h
    # the stage forces as scalars: a row view per stage costs atomic reference counts (issue 22)
    k20, k21, k22 = _stage(sa, ca, sb, cb, sg, cg, hh * k10, hh * k11, hh * k12, coef, fr3[1, 0],
                           fr3[1, 1], fr3[1, 2], g, wn, wu)
    k30, k31, k32 = _stage(sa, ca, sb, cb, sg, cg, hh * k20, hh * k21, hh * k22, coef, fr3[1, 0],
                           fr3[1, 1], fr3[1, 2], g, wn, wu)
    k40, k41, k42 = _stage(sa, ca, sb, cb, sg, cg, h * k30, h * k31, h * k32, coef, fr3[2, 0],
                           fr3[2, 1], fr3[2, 2], g, wn, wu)
    h6 = h / 6.0
    out[0] = a0 + h6 * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
    out[1] = a1 + h6 * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
    out[2] = a2 + h6 * (k12 + 2.0 * k22 + 2.0 * k32 + k42)


@njit(cache=True, inline="always")
def measure_jac_sc(ang, coef, fr0, fr1, fr2, g, out, hm, ha):
    """Accelerometer outputs (g) and their Jacobians for the filter, on scalars.

    ``out`` (3,) g; ``hm`` (3, 7): ``hm[j, m] = d out_j / d coef[MEAS_COLS[j, m]]`` (g per
    coefficient unit; the only nonzero coefficient columns); ``ha`` (3, 3) = d out / d ang (g/rad).
    Same model as :func:`measure_into` (eq. 13 with eq. 10); ``fr*`` is the base specific force,
    m/s^2, ``g`` m/s^2.
    """
    sa, ca = np.sin(ang[0]), np.cos(ang[0])
    sb, cb = np.sin(ang[1]), np.cos(ang[1])
    sg, cg = np.sin(ang[2]), np.cos(ang[2])
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_rp_sc(sa, ca, sb, cb, sg, cg)
    f0, f1, f2 = _force_p(c00, c01, c02, c10, c11, c12, c20, c21, c22, fr0, fr1, fr2, g)
    # d f / d alpha, d f / d beta; d f / d gamma = (f1, -f0, 0)
    fa0 = (-c02 * fr1 + c01 * fr2) / g
    fa1 = (-c12 * fr1 + c11 * fr2) / g
    fa2 = (-c22 * fr1 + c21 * fr2) / g
    fb0 = (-cg * sb * fr0 + cg * cb * sa * fr1 - cg * cb * ca * fr2) / g
    fb1 = (sg * sb * fr0 - sg * cb * sa * fr1 + sg * cb * ca * fr2) / g
    fb2 = (cb * fr0 + sb * sa * fr1 - sb * ca * fr2) / g
    tpy = coef[I_THETA] * ARCSEC
    tpz = coef[I_THETA + 1] * ARCSEC
    toz = coef[I_THETA + 2] * ARCSEC
    for j in range(3):
        aI, aP = accel_axes(coef, j, f0, f1, f2)
        out[j] = accel_one(coef, j, aI, aP)
        hm[j, 0] = UG
        hm[j, 1] = UG * aI
        hm[j, 2] = UG * aI * aI
        hm[j, 3] = UG * aI * aI * aI
        hm[j, 4] = UG * aI * aP
        gI, gP = accel_slopes(coef, j, aI, aP)
        if j == 0:
            d0, d1, d2 = gI, gP, 0.0
        elif j == 1:
            d0, d1, d2 = gI * tpy, gI, -gP
            hm[1, 5] = gI * f0 * ARCSEC
        else:
            d0, d1, d2 = gI * tpz, gI * toz + gP, gI - gP * toz
            hm[2, 5] = gI * f0 * ARCSEC
            hm[2, 6] = (gI * f1 - gP * f2) * ARCSEC
        ha[j, 0] = d0 * fa0 + d1 * fa1 + d2 * fa2
        ha[j, 1] = d0 * fb0 + d1 * fb1 + d2 * fb2
        ha[j, 2] = d0 * f1 - d1 * f0
