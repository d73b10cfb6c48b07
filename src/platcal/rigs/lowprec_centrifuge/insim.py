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

from dataclasses import dataclass

import numpy as np

from ...jit import njit
from ...model.frames import DEG_PER_HOUR
from ...model.instruments import I_DOO, N_FULL, gyro_axis_components, gyro_drift_terms
from .config import G0, OMEGA_IE, R_EARTH


C0, G0W = 8, 16
E0 = G0W + N_FULL
AW0, GW0 = E0 + 3, E0 + 5
ROWS = GW0 + 3
"""Rows of a block of lanes' input (:func:`_stage`): the state (8), coef (8), gcoef (48), eps (3),
the accelerometer noises (2) and the gyro noises (3)."""
W = 16
"""Lanes per block: one AVX-512 vector of float64. Blocks are flat arrays (block, row, lane) whose
row offsets are compile-time constants, so the compiler sees that the rows do not overlap and
vectorises the loop over a block's lanes without run-time alias checks."""


@njit(cache=True, error_model="numpy")
def _stage(L, nb, tr, dy, fm):
    """Every lane's INS state derivative at one instant into ``dy`` (8, K) and its measured
    horizontal specific force into ``fm`` (2, K), m/s^2, K = nb W lanes in nb blocks, each array
    flat (block, row, lane). L (ROWS rows): per lane the state
    (dV_E, dV_N, dL, dlambda, q0..q3): the INS's velocity (m/s), latitude and longitude (rad)
    *minus the truth's* (the exact nonlinear mechanization written about the analytic true
    motion, so that the true motion's jumps of w' need no quadrature) and the attitude
    quaternion, then its coef, gcoef and eps (:func:`_navigate`) and noises of this interval
    (rows :data:`ROWS`); ``tr`` the truth at this instant: f^n (E, N, U) m/s^2, V (E, N) m/s,
    sin L, cos L, w_in^n (3) rad/s, then the truth's own navigation terms k V_N, k V_E (m/s^2)
    and lambda' = V_E / (R cos L) (rad/s), tabulated once per run (:class:`FineTruth`) rather
    than at every RK4 stage.

    Lanes are independent: the loop over them is vectorised (no call with an array argument in
    it, no division check: error_model numpy; the same IEEE operations in the same order as one
    lane alone), where one INS alone is a chain of dependent operations."""
    fe, fn, fu, vte, vtn, slt, clt = tr[0], tr[1], tr[2], tr[3], tr[4], tr[5], tr[6]
    t7, t8, t9, t10, t11, t12 = tr[7], tr[8], tr[9], tr[10], tr[11], tr[12]
    for blk in range(nb):
        ob, od, of = blk * ROWS * W, blk * 8 * W, blk * 2 * W
        for i in range(W):
            ln = ob + i
            dve, dvn, dl = L[ln + W * 0], L[ln + W * 1], L[ln + W * 2]
            a, b, c, d = L[ln + W * 4], L[ln + W * 5], L[ln + W * 6], L[ln + W * 7]
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
            ee = de + G0 * (L[ln + W * C0] + L[ln + W * (C0 + 2)] * ax + L[ln + W * (C0 + 4)] * abs(ax)
                            + L[ln + W * (C0 + 5)] * ax * ax) + L[ln + W * AW0]
            en = dn + G0 * (L[ln + W * (C0 + 1)] + L[ln + W * (C0 + 3)] * ay + L[ln + W * (C0 + 6)] * abs(ay)
                            + L[ln + W * (C0 + 7)] * ay * ay) + L[ln + W * (AW0 + 1)]
            e0 = L[ln + W * E0] + L[ln + W * GW0]
            e1 = L[ln + W * (E0 + 1)] + L[ln + W * (GW0 + 1)]
            e2 = L[ln + W * (E0 + 2)] + L[ln + W * (GW0 + 2)]
            aI, aO, aS = gyro_axis_components(0, ax, ay, az)
            g = ln + W * (G0W)    # gyro 0's coefficients: rows G0W + 0 + 3 m (m = 0..8), then DOO
            e0 += gyro_drift_terms(L[g], L[g + W * 3], L[g + W * 6], L[g + W * 9], L[g + W * 12], L[g + W * 15],
                                   L[g + W * 18], L[g + W * 21], L[g + W * 24], L[ln + W * (G0W + I_DOO)],
                                   aI, aO, aS) * DEG_PER_HOUR
            aI, aO, aS = gyro_axis_components(1, ax, ay, az)
            g = ln + W * (G0W + 1)    # gyro 1's coefficients: rows G0W + 1 + 3 m (m = 0..8), then DOO
            e1 += gyro_drift_terms(L[g], L[g + W * 3], L[g + W * 6], L[g + W * 9], L[g + W * 12], L[g + W * 15],
                                   L[g + W * 18], L[g + W * 21], L[g + W * 24], L[ln + W * (G0W + I_DOO + 1)],
                                   aI, aO, aS) * DEG_PER_HOUR
            aI, aO, aS = gyro_axis_components(2, ax, ay, az)
            g = ln + W * (G0W + 2)    # gyro 2's coefficients: rows G0W + 2 + 3 m (m = 0..8), then DOO
            e2 += gyro_drift_terms(L[g], L[g + W * 3], L[g + W * 6], L[g + W * 9], L[g + W * 12], L[g + W * 15],
                                   L[g + W * 18], L[g + W * 21], L[g + W * 24], L[ln + W * (G0W + I_DOO + 2)],
                                   aI, aO, aS) * DEG_PER_HOUR
            # the INS's latitude L_c = L + dL: sin/cos by Taylor in dL (|dL| < 1e-2 rad: error below 1e-12)
            dl2 = dl * dl
            cd = 1.0 - dl2 / 2.0 + dl2 * dl2 / 24.0
            sd = dl - dl * dl2 / 6.0 + dl * dl2 * dl2 / 120.0
            sl = slt * cd + clt * sd
            cl = clt * cd - slt * sd
            ve = vte + dve
            vn = vtn + dvn
            # w_np^p = w_cmd + eps - C_n^p w_in^n; w_cmd the INS's computed navigation rate
            tl = ve * sl / (cl * R_EARTH)
            wc0 = -vn / R_EARTH
            wc1 = OMEGA_IE * cl + ve / R_EARTH
            wc2 = OMEGA_IE * sl + tl
            w0 = wc0 + e0 - (r00 * t7 + r10 * t8 + r20 * t9)
            w1 = wc1 + e1 - (r01 * t7 + r11 * t8 + r21 * t9)
            w2 = wc2 + e2 - (r02 * t7 + r12 * t8 + r22 * t9)
            # V_c' - V' with V' = f^n + k V_N, -k V_E (the truth's own navigation equation, t10, t11)
            kc = 2.0 * OMEGA_IE * sl + tl
            dy[od + W * 0 + i] = ee + kc * vn - t10
            dy[od + W * 1 + i] = en - kc * ve + t11
            dy[od + W * 2 + i] = dvn / R_EARTH
            dy[od + W * 3 + i] = ve / (R_EARTH * cl) - t12
            dy[od + W * 4 + i] = 0.5 * (-b * w0 - c * w1 - d * w2)
            dy[od + W * 5 + i] = 0.5 * (a * w0 + c * w2 - d * w1)
            dy[od + W * 6 + i] = 0.5 * (a * w1 + d * w0 - b * w2)
            dy[od + W * 7 + i] = 0.5 * (a * w2 + b * w1 - c * w0)
            fm[of + W * 0 + i] = fe + ee
            fm[of + W * 1 + i] = fn + en


@njit(cache=True, error_model="numpy")
def _navigate(h, m, tr, cos_lat0, coef, gcoef, eps, q0, acc_w, gyro_w, noise_of, out_err, err_row, out_phi, out_f,
              f_row, out_last):
    """RK4 navigation of K INSs (lanes) in lock-step through one run; each lane's numbers are
    those of navigating it alone (the same operations in the same order).

    h: RK4 step (s); m: steps per data sample; tr (2 m (n - 1) + 1, 13): the truth on the fine grid
    of step h/2 (:func:`_stage`); cos_lat0: cos of the centre's latitude (the p_E scale); per lane
    (last axis K): coef (8, K) (k0_x, k0_y, dK_x, dK_y, kA_x, k2_x, kA_y, k2_y) in g/g; gcoef
    (48, K) shared gyro coefficients (deg/h/g, deg/h/g^2; constant terms 0); eps (3, K) constant
    drift, rad/s; q0 (4, K) the initial attitude quaternion; acc_w (S, n, 2) m/s^2 and gyro_w
    (S, n, 3) rad/s: white noises of each data interval, lane k reads noise_of[k] (-1: none).
    Outputs (rows of the caller's arrays, :func:`_navigate_block`): out_err (R, n, 4) the INS
    errors (dV_E, dV_N m/s, dp_E, dp_N m: R cos L0 dlambda, R dL) in row err_row[k] of lane k,
    out_f (R', n, 2) the measured horizontal specific force (m/s^2) and out_phi (R', n, 3) the
    attitude error 2 q_vec / q0 (rad; 0 rows: not kept) in row f_row[k] (-1: not stored);
    out_last (K, 4) every lane's errors at the last sample.
    """
    lanes, y = _lanes_init(coef, gcoef, eps, q0)
    _navigate_block(h, m, tr, cos_lat0, lanes, y, acc_w, gyro_w, noise_of, out_err, err_row, out_phi, out_f, f_row,
                    out_last, True)


@njit(cache=True, error_model="numpy")
def _lanes_init(coef, gcoef, eps, q0):
    """The lanes' input L and state y (flat arrays of blocks, :func:`_navigate`) at the run's start:
    coef (8, K) g/g, gcoef (48, K), eps (3, K) rad/s, q0 (4, K) the initial attitude quaternion."""
    K = coef.shape[1]
    nb = (K + W - 1) // W
    # every lane's input in one flat array of blocks (block, row, lane); lanes past K are idle
    # INSs (no error, no noise) whose numbers are dropped
    L = np.zeros(nb * ROWS * W)
    y = np.zeros(nb * 8 * W)
    for ln in range(K):
        ob, oy, i = (ln // W) * ROWS * W, (ln // W) * 8 * W, ln % W
        for r in range(8):
            L[ob + W * (C0 + r) + i] = coef[r, ln]
        for r in range(N_FULL):
            L[ob + W * (G0W + r) + i] = gcoef[r, ln]
        for r in range(3):
            L[ob + W * (E0 + r) + i] = eps[r, ln]
        for r in range(4):
            y[oy + W * (4 + r) + i] = q0[r, ln]
    for ln in range(K, nb * W):
        y[(ln // W) * 8 * W + W * 4 + ln % W] = 1.0
    return L, y


@njit(cache=True, error_model="numpy")
def _navigate_block(h, m, tr, cos_lat0, L, y, acc_w, gyro_w, noise_of, out_err, err_row, out_phi, out_f, f_row,
                    out_last, last):
    """The lanes (input L, state y: :func:`_lanes_init`, y carried from block to block) through the
    ``n = out_err.shape[1]`` data samples of one block: outputs at each, then the RK4 steps to the
    next; ``tr`` the truth's fine rows from the block's first sample through the next block's
    first (2 m n + 1 rows), or through its own last sample when ``last`` (the run's end: no step
    after it, 2 m (n - 1) + 1 rows). acc_w, gyro_w: the noises of the block's data intervals (S, n,
    ...). Lane k's outputs go straight into the caller's arrays (:func:`_navigate`: rows
    err_row[k] of out_err, f_row[k] of out_f and out_phi, -1: not stored; out_last[k] its errors
    at the block's last sample), so that no per-lane buffer is copied out afterwards. The same
    operations in the same order as one call over the whole run (docs/lowprec-centrifuge.md §12,
    a record simulated block by block, bit-identical)."""
    K = noise_of.shape[0]
    n = out_err.shape[1]
    nb = L.shape[0] // (ROWS * W)
    keep_phi = out_phi.shape[0] > 0
    k1 = np.empty(nb * 8 * W)
    k2 = np.empty(nb * 8 * W)
    k3 = np.empty(nb * 8 * W)
    k4 = np.empty(nb * 8 * W)
    fm = np.empty(nb * 2 * W)
    for k in range(n):
        for ln in range(K):
            ob, oy, of, i = (ln // W) * ROWS * W, (ln // W) * 8 * W, (ln // W) * 2 * W, ln % W
            w = noise_of[ln]
            if w >= 0:
                L[ob + W * AW0 + i], L[ob + W * (AW0 + 1) + i] = acc_w[w, k, 0], acc_w[w, k, 1]
                L[ob + W * GW0 + i] = gyro_w[w, k, 0]
                L[ob + W * (GW0 + 1) + i] = gyro_w[w, k, 1]
                L[ob + W * (GW0 + 2) + i] = gyro_w[w, k, 2]
            e0, e1 = y[oy + i], y[oy + W + i]
            e2 = R_EARTH * cos_lat0 * y[oy + W * 3 + i]
            e3 = R_EARTH * y[oy + W * 2 + i]
            r = err_row[ln]
            if r >= 0:
                out_err[r, k, 0], out_err[r, k, 1], out_err[r, k, 2], out_err[r, k, 3] = e0, e1, e2, e3
            if k == n - 1:
                out_last[ln, 0], out_last[ln, 1], out_last[ln, 2], out_last[ln, 3] = e0, e1, e2, e3
            r = f_row[ln]
            if keep_phi and r >= 0:
                out_phi[r, k, 0] = 2.0 * y[oy + W * 5 + i] / y[oy + W * 4 + i]
                out_phi[r, k, 1] = 2.0 * y[oy + W * 6 + i] / y[oy + W * 4 + i]
                out_phi[r, k, 2] = 2.0 * y[oy + W * 7 + i] / y[oy + W * 4 + i]
        _stage_input(L, nb, y, y, 0.0)
        _stage(L, nb, tr[2 * m * k], k1, fm)
        for ln in range(K):
            r = f_row[ln]
            if r >= 0:
                of, i = (ln // W) * 2 * W, ln % W
                out_f[r, k, 0] = fm[of + i]
                out_f[r, k, 1] = fm[of + W + i]
        if last and k == n - 1:
            break
        for i in range(m):
            j = 2 * (m * k + i)
            if i > 0:
                _stage_input(L, nb, y, y, 0.0)
                _stage(L, nb, tr[j], k1, fm)
            _stage_input(L, nb, y, k1, 0.5 * h)
            _stage(L, nb, tr[j + 1], k2, fm)
            _stage_input(L, nb, y, k2, 0.5 * h)
            _stage(L, nb, tr[j + 1], k3, fm)
            _stage_input(L, nb, y, k3, h)
            _stage(L, nb, tr[j + 2], k4, fm)
            for q in range(nb * 8 * W):
                y[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
            for blk in range(nb):
                oy = blk * 8 * W
                for i2 in range(W):
                    p = oy + i2
                    qn = np.sqrt(y[p + W * 4] * y[p + W * 4] + y[p + W * 5] * y[p + W * 5]
                                 + y[p + W * 6] * y[p + W * 6] + y[p + W * 7] * y[p + W * 7])
                    for s in range(4, 8):
                        y[p + W * s] /= qn


@njit(cache=True, error_model="numpy")
def _stage_input(L, nb, y, k, c):
    """The state rows of the lanes' input ``L`` set to y + c k (c = 0: y itself, copied exactly:
    the RK4 stages' arguments, in the scalar kernel's operation order)."""
    for blk in range(nb):
        ob, oy = blk * ROWS * W, blk * 8 * W
        for s in range(8):
            for i in range(W):
                if c == 0.0:
                    L[ob + W * s + i] = y[oy + W * s + i]
                else:
                    L[ob + W * s + i] = y[oy + W * s + i] + c * k[oy + W * s + i]


def quaternion_of(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar first) of the rotation vector ``phi`` (3,) rad: C_p^n = I + [phi x]
    to first order (the platform's attitude error of §5)."""
    ang = float(np.linalg.norm(phi))
    if ang == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(ang / 2)], np.sin(ang / 2) * np.asarray(phi) / ang])


def truth_table(kin) -> np.ndarray:
    """(N, 13) the truth rows :func:`_stage` reads, from the true motion ``kin``
    (:class:`.profile.Kinematics`) on the fine grid: f^n, V, sin L, cos L, the true navigation
    frame's rate w_in^n = w_ie(L) + w_en(V, L) (§1) and the truth's own navigation terms (units as
    :func:`_stage`); row by row, so a block of the grid gives the whole table's rows. Each column
    is written into the table as it is computed (no stacked temporaries), sin L and cos L once."""
    slt, clt = np.sin(kin.lat), np.cos(kin.lat)
    vte, vtn = kin.v[:, 0], kin.v[:, 1]
    tab = np.empty((kin.lat.size, 13))
    tab[:, 0:2] = kin.f
    tab[:, 2] = kin.f_up
    tab[:, 3:5] = kin.v
    tab[:, 5] = slt
    tab[:, 6] = clt
    np.divide(-vtn, R_EARTH, out=tab[:, 7])
    np.add(OMEGA_IE * clt, vte / R_EARTH, out=tab[:, 8])
    np.add(OMEGA_IE * slt, vte * np.tan(kin.lat) / R_EARTH, out=tab[:, 9])
    # the truth's terms of _rates, computed here once in the kernel's operation order (same bits)
    kt = 2.0 * OMEGA_IE * slt + vte * slt / (clt * R_EARTH)
    np.multiply(kt, vtn, out=tab[:, 10])
    np.multiply(kt, vte, out=tab[:, 11])
    np.divide(vte, R_EARTH * clt, out=tab[:, 12])
    return tab


@dataclass(frozen=True)
class LaneOutputs:
    """Where :func:`_navigate` stores K lanes' numbers over a run's n data samples: the caller's
    arrays (C-contiguous) and each lane's row in them, -1: not stored; a batch's replicates,
    floors and variants written in place rather than through per-lane buffers copied out
    (docs/lowprec-centrifuge.md §12)."""

    err: np.ndarray        # (R, n, 4) errors dV_E, dV_N m/s, dp_E, dp_N m
    err_row: np.ndarray    # (K,) int64: lane k's row of err
    f: np.ndarray          # (R', n, 2) measured horizontal specific force, m/s^2
    phi: np.ndarray        # (R', n, 3) attitude errors, rad; (0, n, 3): not kept
    f_row: np.ndarray      # (K,) int64: lane k's row of f and phi
    last: np.ndarray       # (K, 4) every lane's errors at the last sample

    @classmethod
    def own(cls, K: int, n: int, keep_phi: bool) -> "LaneOutputs":
        """New arrays, lane k in row k of each."""
        rows = np.arange(K, dtype=np.int64)
        return cls(err=np.empty((K, n, 4)), err_row=rows, f=np.empty((K, n, 2)),
                   phi=np.empty((K if keep_phi else 0, n, 3)), f_row=rows, last=np.empty((K, 4)))


class FineTruth:
    """The true motion of one run on the fine grid (step dt / (2 steps)), shared by every replicate
    and variant: the table ``tr`` the kernel reads, from the fine grid's ``kin``
    (:class:`.profile.Kinematics`), which is not kept (the table is all the kernel needs, and a
    Monte Carlo cell holds the tables of the runs still to come)."""

    def __init__(self, kin, steps: int, dt: float, lat_deg: float):
        self.steps = int(steps)
        self.h = dt / self.steps
        self.tr = truth_table(kin)
        self.cos_lat0 = float(np.cos(np.radians(lat_deg)))

    def navigate(self, n: int, coef: np.ndarray, gcoef: np.ndarray, eps: np.ndarray, phi0: np.ndarray,
                 acc_w: np.ndarray | None = None, gyro_w: np.ndarray | None = None, keep_phi: bool = False):
        """One INS over the run's ``n`` data samples: (errors (n, 4): dV_E, dV_N m/s, dp_E, dp_N m;
        phi (n, 3) rad or None; measured f (n, 2) m/s^2). Arguments as :meth:`navigate_lanes` for
        one lane; None noises: noise-free."""
        noisy = acc_w is not None
        err, phi, fm = self.navigate_lanes(n, np.asarray(coef, float)[None], np.asarray(gcoef, float)[None],
                                           np.asarray(eps, float)[None], np.asarray(phi0, float)[None],
                                           acc_w[None] if noisy else None, gyro_w[None] if noisy else None,
                                           np.array([0 if noisy else -1]), keep_phi)
        return err[0], (phi[0] if keep_phi else None), fm[0]

    def navigate_lanes(self, n: int, coef: np.ndarray, gcoef: np.ndarray, eps: np.ndarray, phi0: np.ndarray,
                       acc_w: np.ndarray | None, gyro_w: np.ndarray | None, noise_of: np.ndarray,
                       keep_phi: bool = False, out: LaneOutputs | None = None):
        """K INSs over the run's ``n`` data samples in one kernel call (:func:`_navigate`), each
        with the numbers of navigating it alone: coef (K, 8) g/g, gcoef (K, 48) deg/h/g and
        deg/h/g^2, eps (K, 3) rad/s, phi0 (K, 3) rad; acc_w (S, n, 2) m/s^2 and gyro_w (S, n, 3)
        rad/s the noises lane k reads (noise_of[k]; -1 or None noises: noise-free). ``out``: where
        the lanes' numbers go (:class:`LaneOutputs`, a caller's arrays written in place; its phi
        decides ``keep_phi``), None: new arrays, lane k in row k. Returns ``out``'s (errors,
        phi or None, measured f): (K, n, 4), (K, n, 3), (K, n, 2) when new."""
        K = len(coef)
        out = LaneOutputs.own(K, n, keep_phi) if out is None else out
        q0 = np.stack([quaternion_of(p) for p in phi0], axis=1)
        noise_of = np.asarray(noise_of, np.int64)
        acc_w = np.zeros((0, n, 2)) if acc_w is None else acc_w
        gyro_w = np.zeros((0, n, 3)) if gyro_w is None else gyro_w
        # one block of lanes per call: the outputs written per sample stay in a few pages
        # (all lanes at once: 1.7x one at a time, a block: 2.8x; measured, 44 lanes)
        for a in range(0, K, W):
            b = min(a + W, K)
            lanes = lambda v: np.ascontiguousarray(np.asarray(v, float)[a:b].T)   # noqa: E731  (K, c) -> (c, lanes)
            _navigate(self.h, self.steps, self.tr, self.cos_lat0, lanes(coef), lanes(gcoef), lanes(eps),
                      np.ascontiguousarray(q0[:, a:b]), acc_w, gyro_w, noise_of[a:b], out.err, out.err_row[a:b],
                      out.phi, out.f, out.f_row[a:b], out.last[a:b])
        return out.err, (out.phi if out.phi.shape[0] else None), out.f
