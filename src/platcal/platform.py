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
from .instruments import I_DOO, N_FULL, accel_output_into, gyro_drift_into


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
