"""The proposed variable-period Kalman filter (docs/lowprec-centrifuge.md §7).

Windows: 1 s while static; one per revolution while spinning, bounded by the crossings of
psi = gamma_0 + 2 pi k of the running max of the unwrapped heading, linearly interpolated
between samples (paper §3.4.3); the first revolution window starts at spin start (the last
static sample before the spin), the last, partial one ends at spin stop (the first static
sample after it). [D] A static stretch is cut into 1 s windows from its start; a remainder
shorter than 0.1 s joins the window before it.

Observations (eq. 5): window means over [ts, te] of the velocity and of the position relative
to the centrifuge centre minus the arm vector; integrals by cumulative trapezoid at the data
rate, boundary values by linear interpolation of the samples. [D] The record's positions are
relative to the start; the centre is put at -r_nom u(psi(t_0)) from the start.

States (14): dVE, dVN, pE, pN (m/s, m), phi_x, phi_y, phi_z (rad), kA_x, k2_x, kA_y, k2_y
(ug/g, ug/g^2), eps_x, eps_y, eps_z (deg/h). Batched over seeds on a leading axis; seeds whose
window count is smaller are padded with windows that change nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...aot import pick as aot_pick
from ...errors import InputError
from ...estimation.kalman import joseph_update_sparse
from ...jit import njit
from ...parallel import run_threaded
from .aot_kernels import KERNELS
from .config import G0, OMEGA_IE, R_EARTH
from .profile import STATIC
from .truth import ARCSEC, DEG_H

NX = 14
STATE_NAMES = ("dVE", "dVN", "pE", "pN", "phi_x", "phi_y", "phi_z", "kA_x", "k2_x", "kA_y", "k2_y",
               "eps_x", "eps_y", "eps_z")
K_SLICE = slice(7, 11)
MIN_STATIC_TAIL_S = 0.1
STATIC_WINDOW_S = 1.0

P0_STD = np.array([0.05, 0.05, 1.0, 1.0, 20 * ARCSEC, 20 * ARCSEC, 300 * ARCSEC, 100, 20, 100, 20, 0.03, 0.03, 0.03])
"""Initial standard deviations (§7)."""
R_DIAG = np.array([0.005**2, 0.005**2, 0.05**2, 0.05**2])
"""Measurement noise of the window means (§7): m^2/s^2, m^2."""


def q_density() -> np.ndarray:
    """Process-noise densities (§7): q_V = (10 ug g0)^2/Hz, q_phi = (0.002 deg/rt h)^2, q_eps = (1e-4 deg/h)^2/s."""
    q = np.zeros(NX)
    q[0:2] = (10e-6 * G0) ** 2
    q[4:7] = (0.002 * np.pi / 180 / 60) ** 2
    q[11:14] = (1e-4) ** 2
    return q


@dataclass(frozen=True)
class Windows:
    """Filter windows of one record: start, end (s) and whether the centrifuge spins."""

    ts: np.ndarray
    te: np.ndarray
    spinning: np.ndarray


def segments_of(schedule: np.ndarray, field: str = "schedule"):
    """Sample-index bounds (ia, ib) of each spin: ia = last static sample before, ib = first static after."""
    moving = schedule != STATIC
    if not moving.any():
        raise InputError(field, "the record never spins (no non-static sample)")
    d = np.diff(moving.astype(np.int8))
    starts = np.flatnonzero(d == 1)           # ia: static at ia, moving at ia + 1
    stops = np.flatnonzero(d == -1) + 1       # ib: first static sample
    if moving[0]:
        raise InputError(field, "the record starts while spinning; it must start at rest")
    if moving[-1]:
        raise InputError(field, "the record ends while spinning; it must end at rest")
    return list(zip(starts.tolist(), stops.tolist()))


def _static_windows(a: float, b: float) -> np.ndarray:
    """The edges (s) of the static windows from ``a`` to ``b`` (§7): every STATIC_WINDOW_S from
    ``a``, then ``b``, a last window shorter than MIN_STATIC_TAIL_S merged into the one before;
    no edges if the stretch is empty."""
    if b - a <= 1e-9:
        return np.empty(0)
    edges = np.append(np.arange(a, b - 1e-9, STATIC_WINDOW_S), b)
    if edges.size > 2 and edges[-1] - edges[-2] < MIN_STATIC_TAIL_S:
        edges = np.delete(edges, -2)
    return edges


def revolution_crossings(t: np.ndarray, psi_u: np.ndarray, ia: int, ib: int) -> np.ndarray:
    """Times where the running max of the unwrapped heading crosses gamma_0 + 2 pi k (§7, paper §3.4.3)."""
    rm = np.maximum.accumulate(psi_u[ia:ib + 1])
    g0 = psi_u[ia]
    k = int(np.floor((rm[-1] - g0) / (2 * np.pi)))
    if k < 1:
        raise InputError("heading_deg", f"the heading never completes a revolution during the spin "
                                        f"from t = {t[ia]:.2f} s to {t[ib]:.2f} s (it turns "
                                        f"{np.degrees(rm[-1] - g0):.1f} deg)")
    targets = g0 + 2 * np.pi * np.arange(1, k + 1)
    j = np.searchsorted(rm, targets, side="left")
    tt = t[ia:ib + 1]
    frac = (targets - rm[j - 1]) / (rm[j] - rm[j - 1])
    return tt[j - 1] + frac * (tt[j] - tt[j - 1])


@dataclass(frozen=True)
class WindowPlan:
    """What a record's windows take from its times and schedule alone (§7), shared by the
    replicates of a batch: per spin its sample-index bounds (ia, ib) (:func:`segments_of`) and half
    the median sample step within it (s; a last crossing nearer the spin's stop than that moves
    onto it), and the static windows' edges (s) before each spin and after the last
    (:func:`_static_windows`)."""

    spins: tuple          # ((ia, ib, half_step_s), ...)
    static_edges: tuple   # len(spins) + 1 arrays of edges (s)


def window_plan(t: np.ndarray, schedule: np.ndarray) -> WindowPlan:
    """The :class:`WindowPlan` of a record's times t (N,) s and schedule (§7)."""
    spins, static, last = [], [], 0
    for ia, ib in segments_of(schedule):
        static.append(_static_windows(t[last], t[ia]))
        spins.append((ia, ib, 0.5 * float(np.median(np.diff(t[ia:ib + 1])))))   # half a sample (jitter-proof)
        last = ib
    static.append(_static_windows(t[last], t[-1]))
    return WindowPlan(tuple(spins), tuple(static))


def find_windows(t: np.ndarray, psi_u: np.ndarray, schedule: np.ndarray, plan: WindowPlan | None = None) -> Windows:
    """The variable-period windows of one record (§7); ``plan``: its :func:`window_plan` when
    already made (a batch of records sharing t and the schedule)."""
    # each stretch's window edges as one array (thousands of windows per record: a Python
    # loop per window was a tenth of a low-precision cell's CPU time, issue 22 item 4)
    plan = window_plan(t, schedule) if plan is None else plan
    parts = []
    for (ia, ib, half_step), static in zip(plan.spins, plan.static_edges):
        parts.append((static, False))
        edges = np.append(t[ia], revolution_crossings(t, psi_u, ia, ib))
        if t[ib] - edges[-1] < half_step:
            edges[-1] = t[ib]
        else:
            edges = np.append(edges, t[ib])
        parts.append((edges, True))
    parts.append((plan.static_edges[-1], False))
    parts = [(e, s) for e, s in parts if e.size > 1]
    return Windows(np.concatenate([e[:-1] for e, _ in parts]), np.concatenate([e[1:] for e, _ in parts]),
                   np.concatenate([np.full(e.size - 1, s) for e, s in parts]))


def cumtrap(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid integral of y (N, m) from t[0] (:func:`_cumtrap`; the window
    integrals of docs/lowprec-centrifuge.md §7)."""
    c = np.empty((y.shape[0], y.shape[1]))
    _cumtrap(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(y, dtype=float), c)
    return c


@njit(cache=True, nogil=True, error_model="numpy")
def _cumtrap(t, y, c):
    """c (N, m) = the cumulative trapezoid of y (N, m) over t (N,) s from 0, in one pass: the
    operations of numpy's ``cumsum(0.5 * diff(t)[:, None] * (y[1:] + y[:-1]))`` (the first
    term alone, then each added to the sum before it), so the same numbers bit for bit
    (docs/lowprec-centrifuge.md §7)."""
    for j in range(y.shape[1]):
        c[0, j] = 0.0
    for k in range(1, t.size):
        h = 0.5 * (t[k] - t[k - 1])
        for j in range(y.shape[1]):
            term = h * (y[k, j] + y[k - 1, j])
            c[k, j] = term if k == 1 else c[k - 1, j] + term


@njit(cache=True, nogil=True, error_model="numpy")
def _boundary_samples(t, v, p_rel, cos_psi, sin_psi, u0, arm_m, f, kb, yk, yk1, ck, fk, fk1, cfk):
    """One pass over a record of N samples keeping only what :func:`boundary_value` reads at the
    sample indices ``kb`` (M,) (non-decreasing, each in [0, N - 2]): row j of yk, yk1, ck (M, 4)
    gets y at kb[j], at kb[j] + 1 and its cumulative trapezoid at kb[j], where y = (VE, VN,
    :func:`arm_offset`) (m/s, m) from v, p_rel (N, 2), cos_psi, sin_psi (N,) of the unwrapped
    heading (numpy's, as :func:`arm_offset`), u0 (2,) and arm_m (m); unless f (N, 2) m/s^2 has no
    rows, fk, fk1, cfk the same of yf = :func:`force_integrand` (g and g^2). Each y value and each
    running sum by the operations and in the order of :func:`_cumtrap` over the whole arrays (bit
    for bit), without writing the (N, 4) arrays (docs/lowprec-centrifuge.md §7)."""
    force = f.shape[0] > 0
    o0, o1 = arm_m * u0[0], arm_m * u0[1]
    m = kb.size
    ja = 0          # the next boundary whose sample kb[ja] is still ahead
    jb = 0          # the next boundary whose sample kb[jb] + 1 is still ahead
    p0 = p1 = p2 = p3 = 0.0          # y at the sample before
    q0 = q1 = q2 = q3 = 0.0          # yf at the sample before
    c0 = c1 = c2 = c3 = 0.0          # running cumulative trapezoids of y (c[0] = 0)
    d0 = d1 = d2 = d3 = 0.0          # and of yf
    g0 = g1 = g2 = g3 = 0.0
    for k in range(t.size):
        y0 = v[k, 0]
        y1 = v[k, 1]
        y2 = p_rel[k, 0] + o0 - arm_m * cos_psi[k]
        y3 = p_rel[k, 1] + o1 - arm_m * sin_psi[k]
        if force:
            ae, an = f[k, 0] / G0, f[k, 1] / G0
            g0, g1, g2, g3 = abs(ae), abs(an), ae * ae, an * an
        if k >= 1:
            h = 0.5 * (t[k] - t[k - 1])
            if k == 1:
                c0, c1, c2, c3 = h * (y0 + p0), h * (y1 + p1), h * (y2 + p2), h * (y3 + p3)
                if force:
                    d0, d1, d2, d3 = h * (g0 + q0), h * (g1 + q1), h * (g2 + q2), h * (g3 + q3)
            else:
                c0, c1, c2, c3 = c0 + h * (y0 + p0), c1 + h * (y1 + p1), c2 + h * (y2 + p2), c3 + h * (y3 + p3)
                if force:
                    d0, d1, d2, d3 = d0 + h * (g0 + q0), d1 + h * (g1 + q1), d2 + h * (g2 + q2), d3 + h * (g3 + q3)
        while jb < m and kb[jb] + 1 == k:
            yk1[jb, 0], yk1[jb, 1], yk1[jb, 2], yk1[jb, 3] = y0, y1, y2, y3
            if force:
                fk1[jb, 0], fk1[jb, 1], fk1[jb, 2], fk1[jb, 3] = g0, g1, g2, g3
            jb += 1
        while ja < m and kb[ja] == k:
            yk[ja, 0], yk[ja, 1], yk[ja, 2], yk[ja, 3] = y0, y1, y2, y3
            ck[ja, 0], ck[ja, 1], ck[ja, 2], ck[ja, 3] = c0, c1, c2, c3
            if force:
                fk[ja, 0], fk[ja, 1], fk[ja, 2], fk[ja, 3] = g0, g1, g2, g3
                cfk[ja, 0], cfk[ja, 1], cfk[ja, 2], cfk[ja, 3] = d0, d1, d2, d3
            ja += 1
        p0, p1, p2, p3 = y0, y1, y2, y3
        q0, q1, q2, q3 = g0, g1, g2, g3


def boundary_index(t: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """The sample index k before each instant ``tb`` (s): t[k] <= tb < t[k + 1], clipped to
    [0, N - 2] (docs/lowprec-centrifuge.md §7)."""
    return np.clip(np.searchsorted(t, tb, side="right") - 1, 0, t.size - 2)


def boundary_value(tb: np.ndarray, t0: np.ndarray, t1: np.ndarray, y0: np.ndarray, y1: np.ndarray,
                   c0: np.ndarray) -> np.ndarray:
    """(B, m) the integral to each instant ``tb`` (s) from the samples around it: times t0 <= tb <
    t1 (s), values y0, y1 (B, m) there and the cumulative trapezoid c0 (B, m) at t0, plus the
    trapezoid to ``tb`` with y linearly interpolated (docs/lowprec-centrifuge.md §7)."""
    h = (tb - t0)[:, None]
    yb = y0 + h / (t1 - t0)[:, None] * (y1 - y0)
    return c0 + 0.5 * h * (y0 + yb)


def boundary_integrals(t: np.ndarray, y: np.ndarray, c: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """(B, m) the integral of y (N, m) from t[0] to each instant ``tb`` (s, within [t[0], t[-1]]):
    its cumulative trapezoid c at the sample before, plus the trapezoid to ``tb`` with y linearly
    interpolated (:func:`boundary_value`, docs/lowprec-centrifuge.md §7). Only the samples around
    each instant are read, so a streamed record (:mod:`.stream`) evaluates it on a block holding
    them and gets the whole record's numbers."""
    k = boundary_index(t, tb)
    return boundary_value(tb, t[k], t[k + 1], y[k], y[k + 1], c[k])


def interval_means(t: np.ndarray, y: np.ndarray, c: np.ndarray, ts: np.ndarray, te: np.ndarray) -> np.ndarray:
    """(W, m) means of y (N, m) over [ts, te] from its cumulative trapezoid c, boundary values interpolated."""
    return (boundary_integrals(t, y, c, te) - boundary_integrals(t, y, c, ts)) / (te - ts)[:, None]


def window_means(ts, te, iy_s, iy_e, if_s, if_e, psi_s, psi_e, arm_m: float):
    """Per window [ts, te] (s): T (s), z (zVE, zVN m/s, zPE, zPN m) and m (m1E, m1N, m2E, m2N, g and
    g^2) of docs/lowprec-centrifuge.md §7
    from the integrals at its ends (:func:`boundary_integrals`) of y = (VE, VN, pcE, pcN) (``iy``)
    and of the force terms (``if_``), and the unwrapped heading there (rad)."""
    tt = te - ts
    mean = (iy_e - iy_s) / tt[:, None]
    m = (if_e - if_s) / tt[:, None]
    du = np.stack([np.cos(psi_e) - np.cos(psi_s), np.sin(psi_e) - np.sin(psi_s)], axis=-1)
    z = np.concatenate([mean[:, 0:2] - arm_m * du / tt[:, None], mean[:, 2:4]], axis=1)
    return tt, z, m


def arm_offset(p_rel: np.ndarray, psi_u: np.ndarray, u0: np.ndarray, arm_m: float) -> np.ndarray:
    """(N, 2) m: the position relative to the centrifuge's centre minus the arm vector
    (docs/lowprec-centrifuge.md §7) from positions ``p_rel`` (m) and the unwrapped heading (rad), the
    centre at -arm u0 from the start (u0 = (cos, sin) of the first sample's heading)."""
    u = np.stack([np.cos(psi_u), np.sin(psi_u)], axis=-1)
    return p_rel + arm_m * u0 - arm_m * u


def force_integrand(f: np.ndarray) -> np.ndarray:
    """(|f|/g0, (f/g0)^2) per axis of f (N, 2) m/s^2: (N, 4) = (|aE|, |aN|, aE^2, aN^2), g and g^2
    (docs/lowprec-centrifuge.md §7)."""
    a = f / G0
    return np.concatenate([np.abs(a), a * a], axis=1)


def force_terms(t: np.ndarray, f: np.ndarray):
    """:func:`force_integrand` of f and its cumulative integral."""
    y = force_integrand(f)
    return y, cumtrap(t, y)


def window_data(t, v, p_rel, psi_u, f, schedule, arm_m, force=None, plan: WindowPlan | None = None):
    """Windows and, per window, T, the observation z (zVE, zVN, zPE, zPN) and m = (m1E, m1N, m2E, m2N) (§7).

    ``force``: :func:`force_terms` of f when already computed (f common to a batch of seeds);
    ``plan``: :func:`window_plan` of t and the schedule when already made (:func:`find_windows`).
    """
    win = find_windows(t, psi_u, schedule, plan)
    # the integrals at the windows' ends (both ends at once: every operation of
    # :func:`boundary_value` is row by row) from one compiled pass that keeps only the samples
    # around them (:func:`_boundary_samples`: no (N, 4) arrays), the heading's cos and sin by
    # numpy as :func:`arm_offset` takes them
    tb = np.concatenate([win.ts, win.te])
    k = boundary_index(t, tb)
    order = np.argsort(k, kind="stable")
    ks = k[order]
    nb = tb.size
    yk, yk1, ck = np.empty((nb, 4)), np.empty((nb, 4)), np.empty((nb, 4))
    fk, fk1, cfk = np.empty((nb, 4)), np.empty((nb, 4)), np.empty((nb, 4))
    _boundary_samples(np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(v, dtype=float),
                      np.ascontiguousarray(p_rel, dtype=float), np.cos(psi_u), np.sin(psi_u),
                      np.array([np.cos(psi_u[0]), np.sin(psi_u[0])]), float(arm_m),
                      np.ascontiguousarray(f, dtype=float) if force is None else np.empty((0, 2)),
                      ks, yk, yk1, ck, fk, fk1, cfk)
    inv = np.empty_like(order)
    inv[order] = np.arange(nb)
    iy = boundary_value(tb, t[k], t[k + 1], yk[inv], yk1[inv], ck[inv])
    if_ = (boundary_value(tb, t[k], t[k + 1], fk[inv], fk1[inv], cfk[inv]) if force is None
           else boundary_integrals(t, force[0], force[1], tb))
    w = win.ts.size
    tt, z, m = window_means(win.ts, win.te, iy[:w], iy[w:], if_[:w], if_[w:],
                            np.interp(win.ts, t, psi_u), np.interp(win.te, t, psi_u), arm_m)
    return win, tt, z, m


def f_base(lat_rad: float) -> np.ndarray:
    """The window-averaged F of §7 without the accelerometer entries (phi_z f dropped)."""
    sl, cl, tl = np.sin(lat_rad), np.cos(lat_rad), np.tan(lat_rad)
    ws, wc = OMEGA_IE * sl, OMEGA_IE * cl
    F = np.zeros((NX, NX))
    F[0, 5] = -G0
    F[0, 1] = 2 * ws
    F[1, 4] = G0
    F[1, 0] = -2 * ws
    F[2, 0] = 1.0
    F[3, 1] = 1.0
    F[4, 1] = -1 / R_EARTH
    F[4, 5] = ws
    F[4, 6] = -wc
    F[4, 11] = DEG_H
    F[5, 0] = 1 / R_EARTH
    F[5, 3] = -ws / R_EARTH
    F[5, 4] = -ws
    F[5, 12] = DEG_H
    F[6, 0] = tl / R_EARTH
    F[6, 3] = wc / R_EARTH
    F[6, 4] = wc
    F[6, 13] = DEG_H
    return F


def f_matrix(lat_rad: float, m: np.ndarray) -> np.ndarray:
    """F (..., 14, 14) for window means m (..., 4) = (m1E, m1N, m2E, m2N) (§7)."""
    F = np.broadcast_to(f_base(lat_rad), m.shape[:-1] + (NX, NX)).copy()
    s = G0 * 1e-6
    F[..., 0, 7] = s * m[..., 0]
    F[..., 0, 8] = s * m[..., 2]
    F[..., 1, 9] = s * m[..., 1]
    F[..., 1, 10] = s * m[..., 3]
    return F


def transition_and_h(F: np.ndarray, T: np.ndarray):
    """Phi = I + FT + (FT)^2/2 + (FT)^3/6 and H = C (I - FT/2 + (FT)^2/6) (§7), batched."""
    ft = F * T[..., None, None]
    ft2 = ft @ ft
    eye = np.eye(NX)
    phi = eye + ft + ft2 / 2 + ft2 @ ft / 6
    h = (eye - ft / 2 + ft2 / 6)[..., :4, :]
    return phi, h


@dataclass
class FilterResult:
    x: np.ndarray        # (S, 14) final estimate
    P: np.ndarray        # (S, 14, 14) final covariance
    n_windows: np.ndarray  # (S,)
    mean_nis: np.ndarray   # (S,) mean normalised innovation squared over the updates (dof 4)
    failed_updates: np.ndarray  # (S,) updates skipped: innovation covariance not positive definite
    innovations: np.ndarray | None = None  # (S, W, 8) innovations and diag(S), when kept

    @property
    def coeffs(self) -> np.ndarray:
        return self.x[:, K_SLICE]

    @property
    def sigmas(self) -> np.ndarray:
        return np.sqrt(np.diagonal(self.P, axis1=1, axis2=2)[:, K_SLICE])


def predict(F: np.ndarray, T: np.ndarray, x: np.ndarray, P: np.ndarray, q: np.ndarray):
    """One window's prediction, batched over seeds (§7): F (S, 14, 14), window lengths T (S,) s
    (0 for a padded window: no change), x (S, 14), P (S, 14, 14), q the noise density (14,).
    Returns Phi, H (S, 4, 14) and the predicted x, P."""
    phi, H = transition_and_h(F, T)
    xp = np.einsum("bij,bj->bi", phi, x)
    Pp = phi @ P @ np.swapaxes(phi, 1, 2) + q * T[:, None, None] * np.eye(NX)
    return phi, H, xp, Pp


@njit(cache=True, nogil=True, error_model="numpy")
def filter_windows(T, z, m, valid, fb, q, r_var, x, P, nis, skipped, innovations):
    """The Kalman filter of docs/lowprec-centrifuge.md §7 over windows, compiled; the state is carried in place, so windows
    can come in blocks. Per seed s (leading axis, independent: batched over replicates) and
    window w with ``valid[s, w]``: F of the window's force means m (:func:`f_matrix`, base ``fb``
    = :func:`f_base`), Phi and H of its length T (s) (:func:`transition_and_h`, the same
    operations in the same order), the prediction x = Phi x, P = Phi P Phi^T + q T (q the noise
    density, :func:`q_density`), then the shared Joseph-form update of the window means z (zVE,
    zVN m/s, zPE, zPN m; noise variances ``r_var``, :func:`platcal.estimation.kalman.joseph_update_sparse`,
    H dense: every column listed). ``nis[s]`` gains each update's NIS, ``skipped[s]`` counts
    updates whose innovation covariance was not positive definite (the prediction kept). With
    ``innovations`` of shape (S, W, 8), each window's innovation and its predicted variance
    diag(H P H^T) + r go there (invalid windows untouched); shape (0, W, 8): not kept."""
    nb, nw = T.shape
    keep = innovations.shape[0] == nb
    s_acc = G0 * 1e-6
    hcols = np.empty((4, NX), np.int64)
    for r in range(4):
        for j in range(NX):
            hcols[r, j] = j
    hnnz = np.full(4, NX, np.int64)
    U, K, D = np.empty((4, NX)), np.empty((4, NX)), np.empty((4, NX))
    S, Sinv = np.empty((4, 4)), np.empty((4, 4))
    nu, innov = np.empty(4), np.empty(4)
    ft, ft2, ft3 = np.empty((NX, NX)), np.empty((NX, NX)), np.empty((NX, NX))
    phi, tmp, Pp = np.empty((NX, NX)), np.empty((NX, NX)), np.empty((NX, NX))
    H = np.empty((4, NX))
    xp = np.empty(NX)
    for s in range(nb):
        for w in range(nw):
            if not valid[s, w]:
                continue
            tw = T[s, w]
            for i in range(NX):
                for j in range(NX):
                    ft[i, j] = fb[i, j] * tw
            ft[0, 7] = (s_acc * m[s, w, 0]) * tw
            ft[0, 8] = (s_acc * m[s, w, 2]) * tw
            ft[1, 9] = (s_acc * m[s, w, 1]) * tw
            ft[1, 10] = (s_acc * m[s, w, 3]) * tw
            _matmul(ft, ft, ft2)
            _matmul(ft2, ft, ft3)
            for i in range(NX):
                for j in range(NX):
                    e = 1.0 if i == j else 0.0
                    phi[i, j] = e + ft[i, j] + ft2[i, j] / 2 + ft3[i, j] / 6
                    if i < 4:
                        H[i, j] = e - ft[i, j] / 2 + ft2[i, j] / 6
            for i in range(NX):
                v = 0.0
                for j in range(NX):
                    v += phi[i, j] * x[s, j]
                xp[i] = v
            _matmul(phi, P[s], tmp)
            for j in range(NX):   # Pp = tmp Phi^T, Phi's zeros skipped (each sum in index order)
                for i in range(NX):
                    Pp[i, j] = 0.0
                for k in range(NX):
                    c = phi[j, k]
                    if c != 0.0:
                        for i in range(NX):
                            Pp[i, j] += tmp[i, k] * c
            for i in range(NX):
                Pp[i, i] += q[i] * tw
            for r in range(4):
                v = 0.0
                for j in range(NX):
                    v += H[r, j] * xp[j]
                innov[r] = z[s, w, r] - v
            if keep:
                for r in range(4):
                    v = 0.0
                    for j in range(NX):
                        u = 0.0
                        for k in range(NX):
                            u += Pp[j, k] * H[r, k]
                        v += H[r, j] * u
                    innovations[s, w, r] = innov[r]
                    innovations[s, w, 4 + r] = v + r_var[r]
            if joseph_update_sparse(xp, Pp, hcols, hnnz, H, innov, r_var, U, K, D, S, Sinv, nu, True):
                nis[s] += nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2] + nu[3] * nu[3]
            else:
                skipped[s] += 1
            for i in range(NX):
                x[s, i] = xp[i]
                for j in range(NX):
                    P[s, i, j] = Pp[i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def _matmul(a, b, out):
    """out = a b for square matrices, each sum in index order with a's zeros skipped (F T and its
    powers are sparse: 22 of 196 entries of F; adding an exact 0 changes no sum, so the result is
    the dense loop's bit for bit). Indexed in 2-D: a row view would take two atomic reference counts
    (half the product's time at 14 x 14, issue 22)."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.0
        for k in range(n):
            c = a[i, k]
            if c != 0.0:
                for j in range(n):
                    out[i, j] += c * b[k, j]


def _filter_range(lo: int, hi: int, kernel, T, z, m, valid, fb, q, r_var, x, P, nis, skipped, innovations) -> None:
    """``kernel`` (:func:`filter_windows`, §7) on seeds ``lo .. hi - 1``: leading-axis slices of
    the padded window arrays (T s, z m/s and m, m g and g^2) and of the state carried in place
    (views: contiguous, written through); ``innovations`` sliced when kept (else its empty array)."""
    keep = innovations.shape[0] == x.shape[0]
    kernel(T[lo:hi], z[lo:hi], m[lo:hi], valid[lo:hi], fb, q, r_var, x[lo:hi], P[lo:hi], nis[lo:hi],
           skipped[lo:hi], innovations[lo:hi] if keep else innovations)


def run_filter(T: np.ndarray, z: np.ndarray, m: np.ndarray, valid: np.ndarray, lat_rad: float,
               keep_innovations: bool = False) -> FilterResult:
    """The Kalman filter over padded window arrays (S, W), batched over seeds: the compiled
    :func:`filter_windows` from x = 0, P = diag(P0_STD^2). Window means of velocity (m/s) and
    position (m) (§7).

    ``keep_innovations``: the result's ``innovations`` (S, W, 8) holds each window's innovation
    (zVE, zVN m/s, zPE, zPN m) and its predicted variance diag(S) (NaN for padding), for the fit check.
    """
    nb, nw = T.shape
    x = np.zeros((nb, NX))
    P = np.broadcast_to(np.diag(P0_STD**2), (nb, NX, NX)).copy()   # writable: the kernel updates it
    nis = np.zeros(nb)
    skipped = np.zeros(nb, dtype=np.int64)
    innovations = np.full((nb if keep_innovations else 0, nw, 8), np.nan)
    # one kernel for every batch (its loop over seeds is serial): at a batch of one the kernel
    # compiled ahead of time when an identify enabled it and it is built (numba then not loaded);
    # a larger batch runs its seeds in contiguous ranges, one per thread of the job (the kernel is
    # nogil, each seed's loop the same code: the numbers do not depend on the thread count)
    kernel = aot_pick(KERNELS, "filter_windows", filter_windows, filter_windows, nb)
    run_threaded(_filter_range, nb, None, kernel, np.ascontiguousarray(T, dtype=float),
                 np.ascontiguousarray(z, dtype=float), np.ascontiguousarray(m, dtype=float),
                 np.ascontiguousarray(valid, dtype=np.bool_), f_base(lat_rad), q_density(), R_DIAG.copy(), x, P, nis,
                 skipped, innovations)
    n_upd = valid.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_nis = nis / (n_upd - skipped)
    return FilterResult(x=x, P=P, n_windows=n_upd, mean_nis=mean_nis, failed_updates=skipped,
                        innovations=innovations if keep_innovations else None)


def unwrap_heading(psi: np.ndarray) -> np.ndarray:
    """``numpy.unwrap`` of each record's heading psi (S, N) rad along its samples, bit for bit:
    a record whose steps are all below pi (every simulated one: the arm turns far less than pi in
    a sample) in one compiled pass (:func:`_unwrap_small_steps`), any other by numpy (the
    windows' heading, docs/lowprec-centrifuge.md §7)."""
    psi = np.ascontiguousarray(psi, dtype=float)
    out = np.empty_like(psi)
    for s in range(psi.shape[0]):
        if not _unwrap_small_steps(psi[s], out[s]):
            out[s] = np.unwrap(psi[s])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _unwrap_small_steps(p, out):
    """numpy.unwrap of p (N,) into out when every step |p[k] - p[k-1]| < pi (True), else False
    (out partly written): numpy then adds a correction of +0.0 to every sample after the first
    (its cumulative sum of zeros), which is done here too (it turns -0.0 into 0.0)."""
    if p.size:
        out[0] = p[0]
    for k in range(1, p.size):
        if not abs(p[k] - p[k - 1]) < np.pi:
            return False
        out[k] = p[k] + 0.0
    return True


def _window_data_range(lo: int, hi: int, t, v, p_rel, psi_u, f, schedule, arm_m: float, common, plan,
                       per: list) -> None:
    """``per[s]`` = (T s, z, m) of :func:`window_data` (§7) for replicates ``lo .. hi - 1`` of the
    batch (v m/s, p_rel m (S, N, 2); psi_u (S, N) rad unwrapped; f (N, 2) or (S, N, 2) m/s^2, its
    :func:`force_terms` ``common`` when shared; ``plan`` the batch's :func:`window_plan`)."""
    for s in range(lo, hi):
        per[s] = window_data(t, v[s], p_rel[s], psi_u[s], f if f.ndim == 2 else f[s], schedule, arm_m, common,
                             plan)[1:]


def identify_proposed(t, v, p_rel, psi, f, schedule, arm_m: float, lat_deg: float,
                      keep_innovations: bool = False) -> FilterResult:
    """Proposed method on S records: t (N,), v, p_rel (S, N, 2), psi (S, N) rad, f (N, 2) or (S, N, 2);
    ``keep_innovations`` as :func:`run_filter`."""
    nb = v.shape[0]
    common = force_terms(t, f) if f.ndim == 2 else None
    psi_u = unwrap_heading(psi)
    plan = window_plan(t, schedule)      # t and the schedule are the batch's: once, not per replicate
    per = [None] * nb
    # the replicates' window means over the job's threads (each replicate's the same code: the
    # compiled pass is nogil, numpy's large ufuncs release the GIL)
    run_threaded(_window_data_range, nb, None, t, v, p_rel, psi_u, f, schedule, arm_m, common, plan,
                 per)
    nw = max(len(a[0]) for a in per)
    T = np.zeros((nb, nw))
    z = np.zeros((nb, nw, 4))
    m = np.zeros((nb, nw, 4))
    valid = np.zeros((nb, nw), dtype=bool)
    for s, (tt, zz, mm) in enumerate(per):
        k = len(tt)
        T[s, :k], z[s, :k], m[s, :k], valid[s, :k] = tt, zz, mm, True
    return run_filter(T, z, m, valid, np.radians(lat_deg), keep_innovations)
