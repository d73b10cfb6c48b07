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

    def phase_rows(self, p: int) -> tuple[int, int] | None:
        """First and one past the last sample of phase ``p`` (None: the phase is empty)."""
        rows = np.flatnonzero(self.phase == p)
        return (int(rows[0]), int(rows[-1]) + 1) if rows.size else None

    def accel_at(self, k) -> np.ndarray:
        return self.accel[k]

    def phase_at(self, k) -> np.ndarray:
        return self.phase[k]

    def true_imu_at(self, k: np.ndarray, omega_ie: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`true_imu` at samples ``k``, (len(k),3) m/s^2 and rad/s."""
        return _imu(self.accel[k], self.v[k], self.v[np.asarray(k) + 1], omega_ie)


def _pieces(cfg: SledConfig) -> tuple[list[tuple[float, int, int]], list[str]]:
    """The profile of §2 as (acceleration m/s^2, IMU samples, phase index) pieces and their labels:
    static before, the config's phases, the braking to rest, static after."""
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
    return pieces, labels


def _assemble(pieces, labels, dt: float) -> Trajectory:
    accel = np.concatenate([np.full(n, a) for a, n, _ in pieces])
    phase = np.concatenate([np.full(n, p, dtype=np.int64) for _, n, p in pieces])
    v = np.concatenate([[0.0], np.cumsum(accel * dt)])
    n_stop = sum(n for _, n, _ in pieces[:-1])
    v[n_stop:] = 0.0                                   # exactly at rest (rounding of the cumsum)
    x = np.concatenate([[0.0], np.cumsum((v[:-1] + v[1:]) / 2 * dt)])
    return Trajectory(dt=dt, accel=accel, phase=phase, v=v, x=x, n_stop=n_stop, phase_names=tuple(labels))


def build_trajectory(cfg: SledConfig) -> Trajectory:
    """The piecewise-constant acceleration profile of §2 (config already validated)."""
    return _assemble(*_pieces(cfg), cfg.dt)


REST_KEPT = 2
"""Samples of each rest a :class:`Timeline` keeps as arrays (the rest's values are constant)."""


@dataclass(frozen=True)
class Timeline:
    """The trajectory of §2 at any IMU sample without arrays of the whole run's length (a long
    record streamed, issue 22 item 3): the rests before launch and after the stop are constant
    (a = 0, v = 0, x = 0 before and x = the run length after: the cumulative sums add exact
    zeros there), so ``core`` is the trajectory with each rest cut to :data:`REST_KEPT` samples
    and a sample of the whole run maps into it (:meth:`index`); every value is the whole
    trajectory's, bit for bit."""

    core: Trajectory
    n: int                   # IMU samples of the whole run
    n_before: int            # samples of the rest before launch (whole run)
    kept_before: int         # of them in ``core``
    n_stop: int              # sample index of the stop (whole run)
    bounds: tuple            # per phase (first sample, one past its last) of the whole run, or None

    @staticmethod
    def of(cfg: SledConfig) -> "Timeline":
        pieces, labels = _pieces(cfg)
        full = [n for _, n, _ in pieces]
        cut = list(pieces)
        for i in (0, len(pieces) - 1):
            a, n, p = pieces[i]
            cut[i] = (a, min(n, REST_KEPT), p)
        starts = np.r_[0, np.cumsum(full)]
        bounds = tuple((int(starts[i]), int(starts[i + 1])) if full[i] else None for i in range(len(full)))
        return Timeline(core=_assemble(cut, labels, cfg.dt), n=sum(full), n_before=full[0],
                        kept_before=cut[0][1], n_stop=sum(full[:-1]), bounds=bounds)

    @property
    def dt(self) -> float:
        return self.core.dt

    @property
    def phase_names(self) -> tuple[str, ...]:
        return self.core.phase_names

    @property
    def stop_time_s(self) -> float:
        return self.n_stop * self.dt

    @property
    def run_length_m(self) -> float:
        return self.core.run_length_m

    @property
    def v_max_m_s(self) -> float:
        return self.core.v_max_m_s

    def index(self, k, states: bool = False) -> np.ndarray:
        """Samples ``k`` of the whole run (0 … n−1; with ``states`` 0 … n, n the state after the
        last sample, for ``v`` and ``x``) as samples of ``core``."""
        k = np.asarray(k, dtype=np.int64)
        shift = self.n_before - self.kept_before
        last = self.core.n if states else self.core.n - 1
        return np.where(k < self.n_before, np.minimum(k, self.kept_before - 1),
                        np.where(k <= self.n_stop, k - shift, np.minimum(k - shift, last)))

    def phase_rows(self, p: int) -> tuple[int, int] | None:
        """First and one past the last sample of phase ``p`` in the whole run (None: empty)."""
        return self.bounds[p]

    def accel_at(self, k) -> np.ndarray:
        return self.core.accel[self.index(k)]

    def phase_at(self, k) -> np.ndarray:
        return self.core.phase[self.index(k)]

    def true_imu_at(self, k: np.ndarray, omega_ie: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`true_imu` at samples ``k`` (0 … n−1) of the whole run, (len(k),3) m/s^2, rad/s."""
        i = self.index(k)
        return _imu(self.core.accel[i], self.core.v[i], self.core.v[i + 1], omega_ie)


def true_imu(traj: Trajectory, omega_ie: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """True specific force and rate in the body (= track) frame per IMU interval (§2).

    ``f = [a_x,0,0] + 2 ω_ie × [v̄_x,0,0] + [0,0,g]`` with v̄_x the interval's mean velocity;
    ``ω_ib^b = ω_ie^l``. Returns (N,3) arrays in m/s^2 and rad/s.
    """
    return _imu(traj.accel, traj.v[:-1], traj.v[1:], omega_ie)


def _imu(accel: np.ndarray, v0: np.ndarray, v1: np.ndarray, omega_ie: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """§2's specific force and rate of samples with along-track acceleration ``accel`` and
    velocities ``v0``, ``v1`` at their start and end (m/s^2, m/s; (N,) each)."""
    vbar = (v0 + v1) / 2
    vel = np.zeros((accel.size, 3))
    vel[:, 0] = vbar
    f = 2 * np.cross(omega_ie, vel)
    f[:, 0] += accel
    f[:, 2] += G
    w = np.broadcast_to(omega_ie, (accel.size, 3)).copy()
    return f, w
