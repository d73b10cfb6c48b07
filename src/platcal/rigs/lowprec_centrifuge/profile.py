"""Run profiles and centrifuge kinematics (docs/lowprec-centrifuge.md §2, §3).

Conventions ([D] where the spec is silent):
* sample k is at t_k = k/rate_hz from 0; the run lasts the sum of its segments;
* a sample is ``static`` (schedule 0) when the commanded rate is 0, ``hold`` (2) inside a
  traditional-run plateau (first sample >= plateau start, last sample < plateau end) and
  ``spinning`` (1) otherwise;
* the arm angle starts at theta_0 = 0 (East); theta = cumulative trapezoid of the true rate
  (on the truth simulation's fine grid, :mod:`.insim`);
* the true motion is on the spherical Earth of §1 (``kinematics``): the arm's centre at latitude L,
  the platform at east/north offsets r (cos theta, sin theta) from it, the specific force with the
  Earth-rate and transport-rate terms of the navigation equation (the INS's own mechanization,
  inverted), so that an error-free INS reproduces the motion exactly (§2 neglects these terms in
  the error model only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import G0, OMEGA_IE, R_EARTH, Centrifuge, Study

STATIC, SPINNING, HOLD = 0, 1, 2
SCHEDULE_NAMES = ("static", "spinning", "hold")


@dataclass(frozen=True)
class Profile:
    """Commanded (nominal) rate of one run on the sample grid."""

    t: np.ndarray            # (N,) s
    omega_nom: np.ndarray    # (N,) rad/s
    omegadot_nom: np.ndarray  # (N,) rad/s^2
    schedule: np.ndarray     # (N,) int8: STATIC, SPINNING, HOLD
    levels: tuple            # the spin-up levels (proposed) or plateau levels (traditional), g

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])


@dataclass(frozen=True)
class Kinematics:
    """True centrifuge motion (§2) on the spherical Earth of §1: angle, rate, arm, specific force,
    velocity, position and latitude."""

    theta: np.ndarray   # (N,) rad, from East toward North
    omega: np.ndarray   # (N,) rad/s
    r: np.ndarray       # (N,) m
    f: np.ndarray       # (N, 2) horizontal specific force (E, N) in the navigation frame, m/s^2
    f_up: np.ndarray    # (N,) vertical specific force, m/s^2 (g0 and the Coriolis/centripetal terms)
    v: np.ndarray       # (N, 2) velocity over the ground (E, N), m/s
    p: np.ndarray       # (N, 2) position relative to the centre, m (p_E = R cos L0 dlambda, p_N = R dL)
    lat: np.ndarray     # (N,) true latitude, rad

    def subsample(self, step: int) -> "Kinematics":
        """Every ``step``-th sample (the record's grid from the truth's fine grid), as copies (not
        views: the fine grid's arrays can then be freed)."""
        return Kinematics(**{k: np.ascontiguousarray(getattr(self, k)[::step]) for k in self.__dataclass_fields__})


def level_rate(level_g: float, arm_m: float) -> float:
    """Commanded rate of a level, rad/s: A = w^2 r_nom / g0."""
    return float(np.sqrt(level_g * G0 / arm_m))


def spinup_time(level_g: float, cen: Centrifuge) -> float:
    """Duration of the spin-up to ``level_g`` (§2): w(tau) = min(a tau, sqrt(J g0 tau / r), w_L)."""
    wl = level_rate(level_g, cen.arm_m)
    return max(wl / cen.alpha_max_rad_s2, level_g / cen.jerk_g_s)


def _spinup(tau: np.ndarray, level_g: float, cen: Centrifuge):
    """Rate and its derivative of the spin-up law at time tau after the start (§2)."""
    c = cen.jerk_g_s * G0 / cen.arm_m
    wl = level_rate(level_g, cen.arm_m)
    w_a = cen.alpha_max_rad_s2 * tau
    w_j = np.sqrt(c * np.maximum(tau, 0.0))
    w = np.minimum(np.minimum(w_a, w_j), wl)
    wd = np.where(w >= wl, 0.0, np.where(w_a <= w_j, cen.alpha_max_rad_s2, c / (2 * np.maximum(w_j, 1e-300))))
    return w, wd


def segments(study: Study, platform: str, run: str) -> list[tuple]:
    """The run's segments (§3): ("rest", s) | ("up", A) | ("down", A) | ("hold", A, s) | ("ramp", A1, A2)."""
    pr = study.profile
    if run == "traditional":
        a1, a2 = study.traditional["levels_g"]
        h = study.traditional["hold_s"]
        return [("rest", pr["rest_first_s"]), ("up", a1), ("hold", a1, h), ("ramp", a1, a2), ("hold", a2, h),
                ("down", a2), ("rest", study.traditional["rest_last_s"])]
    a1, a2 = study.runs[platform][run]
    return [("rest", pr["rest_first_s"]), ("up", a1), ("down", a1), ("rest", pr["rest_between_s"]),
            ("up", a2), ("down", a2), ("rest", pr["rest_between_s"])]


def _duration(seg, cen: Centrifuge) -> float:
    kind = seg[0]
    if kind == "rest":
        return float(seg[1])
    if kind in ("up", "down"):
        return spinup_time(seg[1], cen)
    if kind == "hold":
        return float(seg[2])
    return (seg[2] - seg[1]) / cen.jerk_g_s


def run_duration(study: Study, platform: str, run: str) -> tuple[float, tuple]:
    """``(seconds, longest segment)`` of a run (§3), from its segments alone: no array is built
    (the size check of :mod:`platcal.sizes` runs before any allocation)."""
    segs = segments(study, platform, run)
    durations = [_duration(seg, study.centrifuge) for seg in segs]
    return float(sum(durations)), segs[max(range(len(segs)), key=durations.__getitem__)]


def profile_grid(study: Study, platform: str, run: str, substeps: int = 1) -> tuple[int, float]:
    """``(samples, step s)`` of :func:`build_profile`'s grid, without building it."""
    durs = [_duration(s, study.centrifuge) for s in segments(study, platform, run)]
    dt = 1.0 / study.rate_hz
    edges = np.concatenate([[0.0], np.cumsum(durs)])
    n = int(np.floor(edges[-1] / dt + 1e-9)) + 1
    return substeps * (n - 1) + 1, dt / substeps


def build_profile(study: Study, platform: str, run: str, substeps: int = 1, rows: tuple | None = None) -> Profile:
    """The commanded rate of a run on the data grid (``profile.rate_hz``, §3), or on a grid
    ``substeps`` times finer with the same span (the truth simulation's, :mod:`.insim`): its
    sample ``substeps * k`` is the data grid's sample k. ``rows`` (a, b): only the grid's samples
    a .. b - 1, each with the whole grid's values (a long run built block by block)."""
    cen = study.centrifuge
    segs = segments(study, platform, run)
    durs = [_duration(s, cen) for s in segs]
    edges = np.concatenate([[0.0], np.cumsum(durs)])
    dt = 1.0 / study.rate_hz
    n = int(np.floor(edges[-1] / dt + 1e-9)) + 1
    n = substeps * (n - 1) + 1
    dt = dt / substeps
    a, b = (0, n) if rows is None else rows
    t = np.arange(a, b) * dt
    n = t.size
    w = np.zeros(n)
    wd = np.zeros(n)
    sched = np.zeros(n, dtype=np.int8)
    idx = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(segs) - 1)
    for i, seg in enumerate(segs):
        m = idx == i
        if not m.any():
            continue
        tau = t[m] - edges[i]
        kind = seg[0]
        if kind == "up":
            w[m], wd[m] = _spinup(tau, seg[1], cen)
        elif kind == "down":
            a, b = _spinup(durs[i] - tau, seg[1], cen)
            w[m], wd[m] = a, -b
        elif kind == "hold":
            w[m] = level_rate(seg[1], cen.arm_m)
            sched[m] = HOLD
        elif kind == "ramp":
            a = seg[1] + cen.jerk_g_s * tau
            w[m] = np.sqrt(a * G0 / cen.arm_m)
            wd[m] = cen.jerk_g_s * G0 / (2 * cen.arm_m * w[m])
    sched[(w > 0) & (sched != HOLD)] = SPINNING
    levels = tuple(study.traditional["levels_g"]) if run == "traditional" else tuple(study.runs[platform][run])
    return Profile(t=t, omega_nom=w, omegadot_nom=wd, schedule=sched, levels=levels)


def kinematics(prof: Profile, cen: Centrifuge, lat_deg: float, theta0: float = 0.0) -> Kinematics:
    """True motion (§2) on the spherical Earth (§1, radius R) at latitude ``lat_deg`` (deg) of the
    arm's centre: w = w_nom (1 + e_w), r = r_nom + dr + s A, A = w^2 (r_nom + dr) / g0, theta the
    cumulative trapezoid of w from ``theta0`` (rad); east/north offsets r (cos theta, sin theta)
    from the centre (p_E = R cos L0 dlambda, p_N = R dL). Velocity over the ground
    V = (R cos L lambda', R L') and the specific force of the navigation equation inverted,
    f = V' - g + (2 w_ie + w_en) x V (g = (0, 0, -g0), w_en = (-VN/R, VE/R, VE tan L / R)): the
    motion an error-free INS mechanizing that equation reproduces. The arm's stretch rate enters
    through r' and r'' (w'' by central differences of the tabulated w')."""
    w = prof.omega_nom * (1.0 + cen.rate_error)
    wd = prof.omegadot_nom * (1.0 + cen.rate_error)
    wdd = np.gradient(wd, prof.t)
    theta = theta0 + np.concatenate([[0.0], np.cumsum(0.5 * prof.dt * (w[1:] + w[:-1]))])
    return motion(w, wd, wdd, theta, cen, lat_deg)


def motion(w, wd, wdd, theta, cen: Centrifuge, lat_deg: float) -> Kinematics:
    """:func:`kinematics` from the true rate w (rad/s), its first and second derivatives wd
    (rad/s^2), wdd (rad/s^3) and the arm angle theta (rad), sample by sample (a block of the grid
    gives the whole grid's values)."""
    r0 = cen.arm_m + cen.arm_error_mm * 1e-3
    ks = cen.stretch_mm_per_g * 1e-3 * r0 / G0          # r = r0 + ks w^2
    r = r0 + ks * w**2
    rd = 2 * ks * w * wd
    rdd = 2 * ks * (wd**2 + w * wdd)
    c, s = np.cos(theta), np.sin(theta)
    lat0 = np.radians(lat_deg)
    lat = lat0 + r * s / R_EARTH
    slat, clat = np.sin(lat), np.cos(lat)                # once each (the same values every use)
    scale = clat / np.cos(lat0)                          # R cos L lambda' over R cos L0 lambda'
    de, dn = rd * c - r * w * s, rd * s + r * w * c      # d/dt of the offsets r (cos, sin)
    dde = rdd * c - 2 * rd * w * s - r * wd * s - r * w**2 * c
    ddn = rdd * s + 2 * rd * w * c + r * wd * c - r * w**2 * s
    ve, vn = scale * de, dn
    lat_dot = vn / R_EARTH
    vde = scale * dde - slat * lat_dot / np.cos(lat0) * de
    vdn = ddn
    wx = -vn / R_EARTH
    wy = 2 * OMEGA_IE * clat + ve / R_EARTH
    wz = 2 * OMEGA_IE * slat + ve * np.tan(lat) / R_EARTH
    f = np.stack([vde - wz * vn, vdn + wz * ve], axis=-1)
    f_up = G0 + wx * vn - wy * ve
    return Kinematics(theta=theta, omega=w, r=r, f=f, f_up=f_up, v=np.stack([ve, vn], axis=-1),
                      p=np.stack([r * c, r * s], axis=-1), lat=lat)


def grid_gradient(f: np.ndarray, t: np.ndarray, dx: float | None) -> np.ndarray:
    """``np.gradient(f, t)`` (first-order edges) with its spacing chosen for the whole grid, not
    for ``t``: ``dx`` the whole grid's constant step (s) when its steps are all equal (numpy then
    uses the uniform formula), None when they are not (the non-uniform formula, numpy's operations
    in numpy's order). A block of the grid with one sample of context each side (none at the
    grid's ends) thus gets the whole grid's values at its own samples."""
    if dx is not None:
        return np.gradient(f, dx)
    d = np.diff(t)
    dx1, dx2 = d[:-1], d[1:]
    out = np.empty_like(f)
    out[1:-1] = (-(dx2) / (dx1 * (dx1 + dx2)) * f[:-2] + (dx2 - dx1) / (dx1 * dx2) * f[1:-1]
                 + dx1 / (dx2 * (dx1 + dx2)) * f[2:])
    out[0] = (f[1] - f[0]) / d[0]
    out[-1] = (f[-1] - f[-2]) / d[-1]
    return out
