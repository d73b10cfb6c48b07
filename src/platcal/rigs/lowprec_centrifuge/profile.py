"""Run profiles and centrifuge kinematics (docs/lowprec-centrifuge.md §2, §3).

Conventions ([D] where the spec is silent):
* sample k is at t_k = k/rate_hz from 0; the run lasts the sum of its segments;
* a sample is ``static`` (schedule 0) when the commanded rate is 0, ``hold`` (2) inside a
  traditional-run plateau (first sample >= plateau start, last sample < plateau end) and
  ``spinning`` (1) otherwise;
* the arm angle starts at theta_0 = 0 (East); theta = cumulative trapezoid of the true rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import G0, Centrifuge, Study

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
    """True centrifuge motion (§2): angle, rate, arm, specific force, velocity and position."""

    theta: np.ndarray   # (N,) rad, from East toward North
    omega: np.ndarray   # (N,) rad/s
    r: np.ndarray       # (N,) m
    f: np.ndarray       # (N, 2) horizontal specific force (E, N), m/s^2
    v: np.ndarray       # (N, 2) velocity, m/s
    p: np.ndarray       # (N, 2) position relative to the centre, m


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


def build_profile(study: Study, platform: str, run: str) -> Profile:
    """The commanded rate of a run on the 100 Hz grid (§3)."""
    cen = study.centrifuge
    segs = segments(study, platform, run)
    durs = [_duration(s, cen) for s in segs]
    edges = np.concatenate([[0.0], np.cumsum(durs)])
    dt = 1.0 / study.rate_hz
    n = int(np.floor(edges[-1] / dt + 1e-9)) + 1
    t = np.arange(n) * dt
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


def kinematics(prof: Profile, cen: Centrifuge, theta0: float = 0.0) -> Kinematics:
    """True motion (§2): w = w_nom (1 + e_w), r = r_nom + dr + s A, A = w^2 (r_nom + dr) / g0."""
    w = prof.omega_nom * (1.0 + cen.rate_error)
    wd = prof.omegadot_nom * (1.0 + cen.rate_error)
    r0 = cen.arm_m + cen.arm_error_mm * 1e-3
    r = r0 + cen.stretch_mm_per_g * 1e-3 * (w**2 * r0 / G0)
    dt = prof.dt
    theta = theta0 + np.concatenate([[0.0], np.cumsum(0.5 * dt * (w[1:] + w[:-1]))])
    c, s = np.cos(theta), np.sin(theta)
    f = np.stack([-w**2 * r * c - r * wd * s, -w**2 * r * s + r * wd * c], axis=-1)
    v = np.stack([-r * w * s, r * w * c], axis=-1)
    p = np.stack([r * c, r * s], axis=-1)
    return Kinematics(theta=theta, omega=w, r=r, f=f, v=v, p=p)
