"""The sled trajectory and the true IMU inputs (docs/rocket-sled.md §2).

Convention: IMU sample k covers the interval [t_k, t_k + dt), t_k = k·dt, and holds the
interval's constant along-track acceleration; navigation states are at t_0 … t_N. The braking
time is ``ceil(v_end / (brake_g·g) / dt)·dt`` and its acceleration ``−v_end / T`` (§2), so the
sled is exactly at rest at sample ``n_stop``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import G, SledConfig


@dataclass(frozen=True)
class Trajectory:
    """Along-track truth at the IMU rate (m, m/s, m/s^2; arrays over samples)."""

    dt: float
    accel: np.ndarray          # (N,) a_x per IMU interval, m/s^2
    phase: np.ndarray          # (N,) 0 = static before, 1..P phases, P+1 braking, P+2 static after
    v: np.ndarray              # (N+1,) v_x at t_k, m/s
    x: np.ndarray              # (N+1,) r_x at t_k, m
    n_stop: int                # sample index of the stop (v = 0 from here on)
    phase_names: tuple[str, ...]

    @property
    def n(self) -> int:
        return len(self.accel)

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.n) * self.dt

    @property
    def stop_time_s(self) -> float:
        return self.n_stop * self.dt

    @property
    def run_length_m(self) -> float:
        return float(self.x[self.n_stop])

    @property
    def v_max_m_s(self) -> float:
        return float(self.v.max())


def build_trajectory(cfg: SledConfig) -> Trajectory:
    """The piecewise-constant acceleration profile of §2 (config already validated)."""
    dt = cfg.dt
    pieces, labels = [(0.0, int(round(cfg.static_before_s * cfg.rate_hz)), 0)], ["static before"]
    v_end = 0.0
    for i, ph in enumerate(cfg.phases):
        n = int(round(ph.duration_s * cfg.rate_hz))
        pieces.append((ph.accel_g * G, n, i + 1))
        labels.append(f"phase {i + 1} ({ph.accel_g:+g} g)")
        v_end += ph.accel_g * G * n * dt
    n_brake = int(np.ceil(v_end / (cfg.brake_g * G) / dt - 1e-9))
    pieces.append((-v_end / (n_brake * dt), n_brake, len(cfg.phases) + 1))
    labels.append("braking")
    pieces.append((0.0, int(round(cfg.static_after_s * cfg.rate_hz)), len(cfg.phases) + 2))
    labels.append("static after")
    accel = np.concatenate([np.full(n, a) for a, n, _ in pieces])
    phase = np.concatenate([np.full(n, p, dtype=np.int64) for _, n, p in pieces])
    v = np.concatenate([[0.0], np.cumsum(accel * dt)])
    n_stop = sum(n for _, n, _ in pieces[:-1])
    v[n_stop:] = 0.0                                   # exactly at rest (rounding of the cumsum)
    x = np.concatenate([[0.0], np.cumsum((v[:-1] + v[1:]) / 2 * dt)])
    return Trajectory(dt=dt, accel=accel, phase=phase, v=v, x=x, n_stop=n_stop, phase_names=tuple(labels))


def true_imu(traj: Trajectory, omega_ie: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """True specific force and rate in the body (= track) frame per IMU interval (§2).

    ``f = [a_x,0,0] + 2 ω_ie × [v̄_x,0,0] + [0,0,g]`` with v̄_x the interval's mean velocity;
    ``ω_ib^b = ω_ie^l``. Returns (N,3) arrays in m/s^2 and rad/s.
    """
    vbar = (traj.v[:-1] + traj.v[1:]) / 2
    vel = np.zeros((traj.n, 3))
    vel[:, 0] = vbar
    f = 2 * np.cross(omega_ie, vel)
    f[:, 0] += traj.accel
    f[:, 2] += G
    w = np.broadcast_to(omega_ie, (traj.n, 3)).copy()
    return f, w
