"""Simulated sled tests (docs/rocket-sled.md §2-4), batched over seeds.

Record convention (a choice, stated in docs/rocket-sled.md §10 notes): the record's body axes
are the axes the navigation is initialised with (Ĉ_0 = I), so a record needs no alignment
data. The simulator therefore stores ``R f̃`` and ``R ω̃`` with ``R = exp(−[φ0×])``; since
``exp([Rω×]) = R exp([ω×]) Rᵀ`` the navigation of this record from I equals §4's navigation
of f̃, ω̃ from ``Ĉ_0 = exp(−[φ0×])`` exactly (to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .config import SledConfig
from .ins import mechanise
from .sensors import ErrorParams, accel_error, draw_errors, draw_noise, measure
from .trajectory import Trajectory, build_trajectory, true_imu


@dataclass(frozen=True)
class Truth:
    """Simulation-only truth per seed: drawn errors and the 1-D truths of §4 (S,N) at t_k."""

    params: ErrorParams
    x_true: np.ndarray      # r_x of the error-free run, m
    vx_true: np.ndarray     # v_x of the error-free run, m/s
    x_inst: np.ndarray      # r_x of the instrument-only run, m
    nabla_static: np.ndarray  # (S,3) accelerometer error at rest (f = [0,0,g]), m/s^2


@dataclass(frozen=True)
class SimBatch:
    seeds: tuple[np.random.SeedSequence, ...]
    traj: Trajectory
    f: np.ndarray           # (S,N,3) recorded specific force, body axes, m/s^2
    w: np.ndarray           # (S,N,3) recorded rate, rad/s
    truth: Truth


def record_rotation(phi0: np.ndarray) -> np.ndarray:
    """R = exp(−[φ0×]) per seed (S,3,3)."""
    return Rotation.from_rotvec(-np.atleast_2d(phi0)).as_matrix()


def simulate(cfg: SledConfig, seeds, noise_free: bool = False) -> SimBatch:
    """Draw errors and noise, one replicate per ``numpy.random.SeedSequence`` of ``seeds`` (the
    Monte Carlo runner's, :func:`platcal.study.sweep.replicate_seed`), make the IMU samples
    and the truths of §4.

    ``noise_free``: no sensor errors, no noise and no initial attitude error.
    """
    seeds = tuple(seeds)
    traj = build_trajectory(cfg)
    f, w = true_imu(traj, cfg.omega_ie)
    rngs = [np.random.default_rng(ss) for ss in seeds]
    p = draw_errors(cfg, rngs)
    wa, wg = draw_noise(cfg, rngs, traj.n)
    if noise_free:
        p = ErrorParams(*(np.zeros_like(a) for a in (p.bias_a, p.scale, p.k2, p.M, p.bias_g, p.g_sens, p.phi0)))
        wa, wg = np.zeros_like(wa), np.zeros_like(wg)
    fm, wm = measure(p, f, w, wa, wg)
    R = record_rotation(p.phi0)
    f_rec = np.einsum("sij,snj->sni", R, fm)
    w_rec = np.einsum("sij,snj->sni", R, wm)
    # truths of §4: error-free run, and instrument-only run (accelerometer errors + noise, φ0 = 0)
    vt, rt, _ = mechanise(f[None], w[None], np.zeros((1, 3)), cfg.omega_ie, cfg.dt)
    f_inst = f + accel_error(p, f) + wa
    _, ri, _ = mechanise(f_inst, np.broadcast_to(w, f_inst.shape), np.zeros((len(seeds), 3)), cfg.omega_ie, cfg.dt)
    S = len(seeds)
    fs = np.array([[0.0, 0.0, 9.80665]])
    truth = Truth(params=p, x_true=np.broadcast_to(rt[0, :-1, 0], (S, traj.n)).copy(),
                  vx_true=np.broadcast_to(vt[0, :-1, 0], (S, traj.n)).copy(), x_inst=ri[:, :-1, 0].copy(),
                  nabla_static=accel_error(p, fs)[:, 0])
    return SimBatch(seeds=seeds, traj=traj, f=f_rec, w=w_rec, truth=truth)


