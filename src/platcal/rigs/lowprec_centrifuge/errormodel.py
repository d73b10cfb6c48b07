"""The platform INS error model of docs/lowprec-centrifuge.md §5 integrated along a specific force:
the coefficient responses S_k of the compensation (§8, ``platcal compensate`` on a log's own
specific force). Not the truth: the study's truth is the nonlinear INS of :mod:`.insim`.
"""

from __future__ import annotations

from ...jit import njit
from .config import G0, OMEGA_IE, R_EARTH


@njit(cache=True)
def integrate_error_model(dt, f, coef, eps, x0, acc_w, gyro_w, sin_l, cos_l, tan_l, out, phi_out):
    """Euler integration of the §5 error model for one trajectory (f (N, 2) m/s^2 at step dt s).

    coef = (k0x, k0y, dKx, dKy, kAx, k2x, kAy, k2y) dimensionless (g/g); eps rad/s; x0 =
    (dVE, dVN, pE, pN, phix, phiy, phiz); acc_w (M, 2) m/s^2 and gyro_w (M, 3) rad/s are the
    per-sample white noises (M = 0: none). out (N, 4) receives (dVE, dVN, pE, pN) at each sample,
    phi_out (N, 3) the attitude (if its length is N).
    """
    n = f.shape[0]
    noisy = acc_w.shape[0] == n
    keep_phi = phi_out.shape[0] == n
    ve, vn, pe, pn, px, py, pz = x0[0], x0[1], x0[2], x0[3], x0[4], x0[5], x0[6]
    w_s = OMEGA_IE * sin_l
    w_c = OMEGA_IE * cos_l
    for k in range(n):
        out[k, 0] = ve
        out[k, 1] = vn
        out[k, 2] = pe
        out[k, 3] = pn
        if keep_phi:
            phi_out[k, 0] = px
            phi_out[k, 1] = py
            phi_out[k, 2] = pz
        fe = f[k, 0]
        fn = f[k, 1]
        ae = fe / G0
        an = fn / G0
        nab_e = G0 * (coef[0] + coef[2] * ae + coef[4] * abs(ae) + coef[5] * ae * ae)
        nab_n = G0 * (coef[1] + coef[3] * an + coef[6] * abs(an) + coef[7] * an * an)
        wx, wy, wz = eps[0], eps[1], eps[2]
        if noisy:
            nab_e += acc_w[k, 0]
            nab_n += acc_w[k, 1]
            wx += gyro_w[k, 0]
            wy += gyro_w[k, 1]
            wz += gyro_w[k, 2]
        dve = pz * fn - py * G0 + 2 * w_s * vn + nab_e
        dvn = -pz * fe + px * G0 - 2 * w_s * ve + nab_n
        dpx = -vn / R_EARTH + w_s * py - w_c * pz + wx
        dpy = ve / R_EARTH - w_s * pn / R_EARTH - w_s * px + wy
        dpz = ve * tan_l / R_EARTH + w_c * pn / R_EARTH + w_c * px + wz
        pe += dt * (ve + 0.5 * dt * dve)
        pn += dt * (vn + 0.5 * dt * dvn)
        ve += dt * dve
        vn += dt * dvn
        px += dt * dpx
        py += dt * dpy
        pz += dt * dpz
