"""Independent truth: the platform INS navigated at a high rate through the centrifuge's motion
(docs/lowprec-centrifuge.md §1, §2, §4, §5, §12 "Truth simulation").

This is *not* the filter's error model (§5, §7): the INS is the nonlinear local-level,
north-pointing platform mechanization on the spherical Earth of §1, integrated by classical
Runge-Kutta 4 at ``profile.truth_steps`` steps per data sample (the true motion tabulated at
twice that rate, :func:`.profile.kinematics`):

* the platform's attitude relative to the true navigation frame is a unit quaternion q
  (C_p^n = R(q), exact rotation, renormalised every step), driven by
  w_np^p = w_cmd + eps - C_n^p w_in^n: the platform is torqued at the INS's *computed*
  navigation rate w_cmd = w_ie(L_c) + w_en(V_c, L_c) while the true frame turns at w_in^n of
  the true latitude and velocity; eps = constant drift + the g-sensitive drift of the shared
  gyro model (:func:`platcal.model.instruments.gyro_drift_scalar`, its I/O/S axes, the
  specific force on the platform in g) + angle random walk;
* the accelerometers on the platform sense f^p = C_n^p f^n and output, per horizontal axis,
  f^p_i + g0 (k0 + dK a + kA |a| + k2 a^2) + white noise, a = f^p_i / g0 (§4);
* the INS integrates those outputs as if the platform were its navigation frame:
  V_E' = a_E + (2 w_ie sin L_c + V_E tan L_c / R) V_N, V_N' = a_N - (2 w_ie sin L_c + V_E tan L_c / R) V_E,
  L_c' = V_N / R, lambda_c' = V_E / (R cos L_c) (vertical channel held, §5).

Its outputs are the record's VE, VN, pE, pN (p_E = R cos L0 dlambda, p_N = R dL from the start)
and the measured specific force fE, fN (the horizontal accelerometer outputs at the sample).
White noises are held over each data interval (a rate density q gives q / sqrt(dt) per sample,
as §4's noise at the data rate). With no error the INS reproduces the true motion to the
integration tolerance (tested).
"""

from __future__ import annotations

import numba
import numpy as np

from ...model.frames import DEG_PER_HOUR
from ...model.instruments import gyro_axis_components, gyro_drift_scalar
from .config import G0, OMEGA_IE, R_EARTH


@numba.njit(cache=True)
def _rates(y, tr, coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, dy):
    """Derivative of the INS state into ``dy``; returns the measured horizontal specific force
    (m/s^2). y = (dV_E, dV_N, dL, dlambda, q0..q3): the INS's velocity (m/s), latitude and longitude
    (rad) *minus the truth's* (the exact nonlinear mechanization written about the analytic true
    motion, so that the true motion's jumps of w' need no quadrature), and the attitude quaternion;
    ``tr`` the truth at this instant: f^n (E, N, U) m/s^2, V (E, N) m/s, sin L, cos L, w_in^n (3)."""
    dve, dvn, dl = y[0], y[1], y[2]
    a, b, c, d = y[4], y[5], y[6], y[7]
    fe, fn, fu, vte, vtn, slt, clt = tr[0], tr[1], tr[2], tr[3], tr[4], tr[5], tr[6]
    # C_p^n = R(q); f^p - f^n = (R^T - I) f^n, kept apart from the large f^n for precision
    r00 = a * a + b * b - c * c - d * d
    r01 = 2.0 * (b * c - a * d)
    r02 = 2.0 * (b * d + a * c)
    r10 = 2.0 * (b * c + a * d)
    r11 = a * a - b * b + c * c - d * d
    r12 = 2.0 * (c * d - a * b)
    r20 = 2.0 * (b * d - a * c)
    r21 = 2.0 * (c * d + a * b)
    r22 = a * a - b * b - c * c + d * d
    de = (r00 - 1.0) * fe + r10 * fn + r20 * fu
    dn = r01 * fe + (r11 - 1.0) * fn + r21 * fu
    fp2 = r02 * fe + r12 * fn + r22 * fu
    ax = (fe + de) / G0
    ay = (fn + dn) / G0
    az = fp2 / G0
    # accelerometer output minus the true f^n (§4 error model on the platform's axes)
    ee = de + G0 * (coef[0] + coef[2] * ax + coef[4] * abs(ax) + coef[5] * ax * ax) + aw0
    en = dn + G0 * (coef[1] + coef[3] * ay + coef[6] * abs(ay) + coef[7] * ay * ay) + aw1
    e0 = eps[0] + gw0
    e1 = eps[1] + gw1
    e2 = eps[2] + gw2
    aI, aO, aS = gyro_axis_components(0, ax, ay, az)
    e0 += gyro_drift_scalar(gcoef, 0, aI, aO, aS) * DEG_PER_HOUR
    aI, aO, aS = gyro_axis_components(1, ax, ay, az)
    e1 += gyro_drift_scalar(gcoef, 1, aI, aO, aS) * DEG_PER_HOUR
    aI, aO, aS = gyro_axis_components(2, ax, ay, az)
    e2 += gyro_drift_scalar(gcoef, 2, aI, aO, aS) * DEG_PER_HOUR
    # the INS's latitude L_c = L + dL: sin/cos by Taylor in dL (|dL| < 1e-2 rad: error below 1e-12)
    dl2 = dl * dl
    cd = 1.0 - dl2 / 2.0 + dl2 * dl2 / 24.0
    sd = dl - dl * dl2 / 6.0 + dl * dl2 * dl2 / 120.0
    sl = slt * cd + clt * sd
    cl = clt * cd - slt * sd
    ve = vte + dve
    vn = vtn + dvn
    # w_np^p = w_cmd + eps - C_n^p w_in^n; w_cmd the INS's computed navigation rate
    wc0 = -vn / R_EARTH
    wc1 = OMEGA_IE * cl + ve / R_EARTH
    wc2 = OMEGA_IE * sl + ve * sl / (cl * R_EARTH)
    w0 = wc0 + e0 - (r00 * tr[7] + r10 * tr[8] + r20 * tr[9])
    w1 = wc1 + e1 - (r01 * tr[7] + r11 * tr[8] + r21 * tr[9])
    w2 = wc2 + e2 - (r02 * tr[7] + r12 * tr[8] + r22 * tr[9])
    # V_c' - V' with V' = f^n + k V_N, -k V_E (the truth's own navigation equation)
    kc = 2.0 * OMEGA_IE * sl + ve * sl / (cl * R_EARTH)
    kt = 2.0 * OMEGA_IE * slt + vte * slt / (clt * R_EARTH)
    dy[0] = ee + kc * vn - kt * vtn
    dy[1] = en - kc * ve + kt * vte
    dy[2] = dvn / R_EARTH
    dy[3] = ve / (R_EARTH * cl) - vte / (R_EARTH * clt)
    dy[4] = 0.5 * (-b * w0 - c * w1 - d * w2)
    dy[5] = 0.5 * (a * w0 + c * w2 - d * w1)
    dy[6] = 0.5 * (a * w1 + d * w0 - b * w2)
    dy[7] = 0.5 * (a * w2 + b * w1 - c * w0)
    return fe + ee, fn + en


@numba.njit(cache=True)
def _navigate(h, m, tr, cos_lat0, coef, gcoef, eps, q0, acc_w, gyro_w, out_err, out_phi, out_f):
    """RK4 navigation of one INS through one run.

    h: RK4 step (s); m: steps per data sample; tr (2 m (n - 1) + 1, 10): the truth on the fine grid
    of step h/2 (:func:`_rates`); cos_lat0: cos of the centre's latitude (the p_E scale); coef:
    (k0_x, k0_y, dK_x, dK_y, kA_x, k2_x, kA_y, k2_y) in g/g; gcoef: (48,) shared gyro coefficients
    (deg/h/g, deg/h/g^2; constant terms 0); eps: (3,) constant drift, rad/s; q0: the initial
    attitude quaternion; acc_w (n, 2) m/s^2 and gyro_w (n, 3) rad/s: the white noises of each data
    interval (0 rows: none). Outputs (n rows): out_err the INS errors (dV_E, dV_N m/s, dp_E, dp_N m:
    R cos L0 dlambda, R dL), out_phi the attitude error 2 q_vec / q0 (rad; 0 rows: not kept), out_f
    the measured horizontal specific force (m/s^2).
    """
    n = out_err.shape[0]
    noisy = acc_w.shape[0] == n
    keep_phi = out_phi.shape[0] == n
    y = np.zeros(8)
    y[4:8] = q0
    yt = np.empty(8)
    k1 = np.empty(8)
    k2 = np.empty(8)
    k3 = np.empty(8)
    k4 = np.empty(8)
    for k in range(n):
        aw0 = aw1 = gw0 = gw1 = gw2 = 0.0
        if noisy:
            aw0, aw1 = acc_w[k, 0], acc_w[k, 1]
            gw0, gw1, gw2 = gyro_w[k, 0], gyro_w[k, 1], gyro_w[k, 2]
        out_err[k, 0] = y[0]
        out_err[k, 1] = y[1]
        out_err[k, 2] = R_EARTH * cos_lat0 * y[3]
        out_err[k, 3] = R_EARTH * y[2]
        if keep_phi:
            out_phi[k, 0] = 2.0 * y[5] / y[4]
            out_phi[k, 1] = 2.0 * y[6] / y[4]
            out_phi[k, 2] = 2.0 * y[7] / y[4]
        j = 2 * m * k
        me, mn = _rates(y, tr[j], coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, k1)
        out_f[k, 0] = me
        out_f[k, 1] = mn
        if k == n - 1:
            break
        for i in range(m):
            j = 2 * (m * k + i)
            if i > 0:
                _rates(y, tr[j], coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, k1)
            for s in range(8):
                yt[s] = y[s] + 0.5 * h * k1[s]
            _rates(yt, tr[j + 1], coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, k2)
            for s in range(8):
                yt[s] = y[s] + 0.5 * h * k2[s]
            _rates(yt, tr[j + 1], coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, k3)
            for s in range(8):
                yt[s] = y[s] + h * k3[s]
            _rates(yt, tr[j + 2], coef, gcoef, eps, aw0, aw1, gw0, gw1, gw2, k4)
            for s in range(8):
                y[s] += h / 6.0 * (k1[s] + 2.0 * k2[s] + 2.0 * k3[s] + k4[s])
            qn = np.sqrt(y[4] * y[4] + y[5] * y[5] + y[6] * y[6] + y[7] * y[7])
            for s in range(4, 8):
                y[s] /= qn


def quaternion_of(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar first) of the rotation vector ``phi`` (3,) rad: C_p^n = I + [phi x]
    to first order (the platform's attitude error of §5)."""
    ang = float(np.linalg.norm(phi))
    if ang == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(ang / 2)], np.sin(ang / 2) * np.asarray(phi) / ang])


def nav_rate(kin) -> np.ndarray:
    """(N, 3) rad/s: the true navigation frame's rate w_in^n = w_ie(L) + w_en(V, L) (§1)."""
    ve, vn = kin.v[:, 0], kin.v[:, 1]
    return np.stack([-vn / R_EARTH, OMEGA_IE * np.cos(kin.lat) + ve / R_EARTH,
                     OMEGA_IE * np.sin(kin.lat) + ve * np.tan(kin.lat) / R_EARTH], axis=-1)


class FineTruth:
    """The true motion of one run on the fine grid (step dt / (2 steps)), shared by every replicate
    and variant: ``kin`` (:class:`.profile.Kinematics`) and the table ``tr`` the kernel reads."""

    def __init__(self, kin, steps: int, dt: float, lat_deg: float):
        self.kin = kin
        self.steps = int(steps)
        self.h = dt / self.steps
        self.tr = np.ascontiguousarray(np.column_stack([kin.f, kin.f_up, kin.v, np.sin(kin.lat), np.cos(kin.lat),
                                                        nav_rate(kin)]))
        self.cos_lat0 = float(np.cos(np.radians(lat_deg)))

    def navigate(self, n: int, coef: np.ndarray, gcoef: np.ndarray, eps: np.ndarray, phi0: np.ndarray,
                 acc_w: np.ndarray | None = None, gyro_w: np.ndarray | None = None, keep_phi: bool = False):
        """One INS over the run's ``n`` data samples: (errors (n, 4): dV_E, dV_N m/s, dp_E, dp_N m;
        phi (n, 3) rad or None; measured f (n, 2) m/s^2). Arguments as :func:`_navigate`; None
        noises: noise-free."""
        err, fm = np.empty((n, 4)), np.empty((n, 2))
        phi = np.empty((n, 3)) if keep_phi else np.empty((0, 3))
        _navigate(self.h, self.steps, self.tr, self.cos_lat0, np.asarray(coef, float), np.asarray(gcoef, float),
                  np.asarray(eps, float), quaternion_of(phi0),
                  np.zeros((0, 2)) if acc_w is None else acc_w, np.zeros((0, 3)) if gyro_w is None else gyro_w,
                  err, phi, fm)
        return err, (phi if keep_phi else None), fm
