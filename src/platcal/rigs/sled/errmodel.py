"""Linear error models of the filters (docs/rocket-sled.md §5-6) and their propagation.

State orders (§6):

* run, 7 states ``[δv_y, δr_y, δv_z, δr_z, φ_x, φ_y, φ_z]``; 6 states drop φ_x;
* stop, 6 states ``[δv_y, δr_y, δv_x, δr_x, φ_x, φ_y]``.

Units: m/s, m, rad. ``f`` is the computed specific force in l (m/s^2), ``w`` the rate in the
attitude block ``−[ω×]φ`` (rad/s), ``wc`` the Earth rate of the Coriolis couplings (rad/s);
both are ω_ie^l in the filters and differ only in the rank study of §8 (the azimuth rate is
modelled as a rotation of the error frame, [D1]). All builders are batched: ``f`` (…,3).
"""

from __future__ import annotations

import numpy as np

from ...jit import njit
from .aot_kernels import seed_kernel

RUN7 = ("dv_y", "dr_y", "dv_z", "dr_z", "phi_x", "phi_y", "phi_z")
RUN6 = ("dv_y", "dr_y", "dv_z", "dr_z", "phi_y", "phi_z")
STOP = ("dv_y", "dr_y", "dv_x", "dr_x", "phi_x", "phi_y")


def skew(a: np.ndarray) -> np.ndarray:
    """[a×] for a (…,3)."""
    a = np.asarray(a, dtype=float)
    z = np.zeros(a.shape[:-1])
    return np.stack([np.stack([z, -a[..., 2], a[..., 1]], -1),
                     np.stack([a[..., 2], z, -a[..., 0]], -1),
                     np.stack([-a[..., 1], a[..., 0], z], -1)], -2)


RUN7_KIND, RUN6_KIND, STOP_KIND = 0, 1, 2
"""The system matrices of :func:`fill_F`: the 7- and 6-state run filters (§6.1), the stop filter (§6.2)."""


@njit(cache=True, nogil=True, inline="always")
def fill_F(kind, f0, f1, f2, w, wc, F, i):
    """The nonzero entries of one system matrix into ``F[i]`` (its other entries must be 0): run
    (§5, §6.1; ``kind`` RUN7_KIND or RUN6_KIND) or stop (§6.2, STOP_KIND) at the computed specific
    force (f0, f1, f2) (m/s^2), attitude-block rate ``w`` and Coriolis rate ``wc`` (3,) rad/s
    (:func:`run_F`, :func:`stop_F`). One definition for the numpy builders and the filter
    kernel, which forms each epoch's F here rather than reading a stored (S, J, n, n) array."""
    if kind == STOP_KIND:
        F[i, 1, 0] = 1.0
        F[i, 0, 4] = f2
        F[i, 0, 2] = -2.0 * wc[2]
        F[i, 3, 2] = 1.0
        F[i, 2, 5] = -f2
        F[i, 2, 0] = 2.0 * wc[2]
        F[i, 4, 5] = w[2]
        F[i, 5, 4] = -w[2]
    elif kind == RUN7_KIND:
        F[i, 0, 2] = 2.0 * wc[0]
        F[i, 0, 4] = f2
        F[i, 0, 6] = -f0
        F[i, 1, 0] = 1.0
        F[i, 2, 0] = -2.0 * wc[0]
        F[i, 2, 5] = f0
        F[i, 2, 4] = -f1
        F[i, 3, 2] = 1.0
        # -[w x] on [phi_x, phi_y, phi_z]
        F[i, 4, 5] = w[2]
        F[i, 4, 6] = -w[1]
        F[i, 5, 4] = -w[2]
        F[i, 5, 6] = w[0]
        F[i, 6, 4] = w[1]
        F[i, 6, 5] = -w[0]
    else:  # the 7-state matrix without phi_x's row and column
        F[i, 0, 2] = 2.0 * wc[0]
        F[i, 0, 5] = -f0
        F[i, 1, 0] = 1.0
        F[i, 2, 0] = -2.0 * wc[0]
        F[i, 2, 4] = f0
        F[i, 3, 2] = 1.0
        F[i, 4, 5] = w[0]
        F[i, 5, 4] = -w[0]


@njit(cache=True)
def _fill_all(kind, f, w, wc, F):
    for i in range(F.shape[0]):
        fill_F(kind, f[i, 0], f[i, 1], f[i, 2], w[i], wc[i], F, i)


def kind_states(kind: int) -> int:
    """The state count of a :func:`fill_F` kind."""
    return 7 if kind == RUN7_KIND else 6


def system_matrices(kind: int, f: np.ndarray, w: np.ndarray, wc: np.ndarray | None = None) -> np.ndarray:
    """:func:`fill_F` batched: F (…, n, n) of the forces ``f`` (…,3), rates ``w``, ``wc`` (…,3)
    broadcast against them (``wc`` default ``w``)."""
    f = np.asarray(f, dtype=float)
    w = np.broadcast_to(np.asarray(w, dtype=float), f.shape)
    wc = w if wc is None else np.broadcast_to(np.asarray(wc, dtype=float), f.shape)
    n = kind_states(kind)
    F = np.zeros((int(np.prod(f.shape[:-1], dtype=np.int64)), n, n))
    # one row of F per force: rows, not seeds, so one call (ahead of time when the identify's
    # kernels are, .aot_kernels)
    (seed_kernel("fill_all", _fill_all) or _fill_all)(kind, np.ascontiguousarray(f.reshape(-1, 3)), np.ascontiguousarray(w.reshape(-1, 3)),
              np.ascontiguousarray(wc.reshape(-1, 3)), F)
    return F.reshape(f.shape[:-1] + (n, n))


def run_F(f: np.ndarray, w: np.ndarray, wc: np.ndarray | None = None, states: int = 7) -> np.ndarray:
    """Run-filter system matrix (§5, §6.1), shape (…, n, n), n = ``states``.

    δv̇_y = f_z φ_x − f_x φ_z + 2 ω_x δv_z;  δv̇_z = f_x φ_y − f_y φ_x − 2 ω_x δv_y;
    δṙ = δv;  φ̇ = −[ω×] φ.
    """
    return system_matrices(RUN7_KIND if states == 7 else RUN6_KIND, f, w, wc)


def stop_F(f: np.ndarray, w: np.ndarray, wc: np.ndarray | None = None) -> np.ndarray:
    """Stop (ZUPT) filter system matrix (§6.2), shape (…, 6, 6).

    δṙ_y = δv_y; δv̇_y = f_z φ_x − 2 ω_z δv_x; δṙ_x = δv_x; δv̇_x = −f_z φ_y + 2 ω_z δv_y;
    φ̇_x = ω_z φ_y; φ̇_y = −ω_z φ_x.
    """
    return system_matrices(STOP_KIND, f, w, wc)


def propagate_full(fl: np.ndarray, omega_ie: np.ndarray, phi0: np.ndarray, nabla: np.ndarray,
                   eps: np.ndarray, dt: float):
    """The full 3-D error model of §5 driven by the true error parameters, at the IMU rate.

    ``δv̇ = f^l × φ − 2 ω_ie × δv + ∇^l``, ``φ̇ = −ω_ie × φ − ε^l`` with the INS's first-order
    scheme (δv Euler, δr trapezoid, φ Euler), δv_0 = δr_0 = 0, φ_0 = φ0. ``fl`` computed
    specific force (S,N,3), ``nabla``/``eps`` accelerometer/gyro errors in l (S,N,3).
    Returns δv, δr (S,N+1,3) and φ (S,N+1,3).
    """
    S, N = fl.shape[:2]
    dv = np.zeros((S, N + 1, 3))
    dr = np.zeros((S, N + 1, 3))
    phi = np.zeros((S, N + 1, 3))
    phi[:, 0] = phi0
    W = skew(omega_ie)
    for k in range(N):
        a = np.cross(fl[:, k], phi[:, k]) - 2 * dv[:, k] @ W.T + nabla[:, k]
        dv[:, k + 1] = dv[:, k] + a * dt
        dr[:, k + 1] = dr[:, k] + (dv[:, k] + dv[:, k + 1]) * 0.5 * dt
        phi[:, k + 1] = phi[:, k] - (phi[:, k] @ W.T + eps[:, k]) * dt
    return dv, dr, phi


@njit(cache=True)
def _run_model(fl, w, x0, has_phix, dts, out):
    S, N = fl.shape[0], fl.shape[1]
    for s in range(S):
        vy, ry, vz, rz = 0.0, 0.0, 0.0, 0.0
        px, py, pz = x0[s, 0], x0[s, 1], x0[s, 2]
        if not has_phix:
            px = 0.0
        out[s, 0, 0] = 0.0
        out[s, 0, 1] = 0.0
        for k in range(N):
            dt = dts[k]
            fx, fy, fz = fl[s, k, 0], fl[s, k, 1], fl[s, k, 2]
            ay = fz * px - fx * pz + 2 * w[0] * vz
            az = fx * py - fy * px - 2 * w[0] * vy
            # φ̇ = −ω × φ (φ_x held at 0 in the 6-state model: its row is dropped)
            dpx = -(w[1] * pz - w[2] * py)
            dpy = -(w[2] * px - w[0] * pz)
            dpz = -(w[0] * py - w[1] * px)
            nvy = vy + ay * dt
            nvz = vz + az * dt
            ry += (vy + nvy) * 0.5 * dt
            rz += (vz + nvz) * 0.5 * dt
            vy, vz = nvy, nvz
            if has_phix:
                px += dpx * dt
            py += dpy * dt
            pz += dpz * dt
            out[s, k + 1, 0] = ry
            out[s, k + 1, 1] = rz


def propagate_run_model(fl: np.ndarray, omega_ie: np.ndarray, phi: np.ndarray, states: int, dt) -> np.ndarray:
    """Metric B's model (§8): the run model driven by recorded f^l and a fixed attitude estimate.

    x_0 = [0, 0, 0, 0, φ̂] (``phi`` (S,3) rad, [φ_x, φ_y, φ_z]; φ_x ≡ 0 for 6 states),
    noise-free, integrated at the IMU rate with the INS's scheme (velocity and attitude Euler,
    position trapezoid); the equations are those of :func:`run_F`. Returns the model's
    [δr_y, δr_z] (S,N+1,2), m. ``dt``: the IMU period or (N,) the record's sample intervals, s.
    """
    fl = np.ascontiguousarray(fl, dtype=np.float64)
    dts = np.ascontiguousarray(np.broadcast_to(np.asarray(dt, dtype=np.float64), (fl.shape[1],)))
    out = np.empty((fl.shape[0], fl.shape[1] + 1, 2))
    w, phi = np.ascontiguousarray(omega_ie, dtype=np.float64), np.ascontiguousarray(phi, dtype=np.float64)
    one = seed_kernel("run_model", _run_model)
    if one is None:
        _run_model(fl, w, phi, states == 7, dts, out)
    else:  # ahead of time, a seed at a time (.aot_kernels)
        for s in range(fl.shape[0]):
            one(fl[s:s + 1], w, phi[s:s + 1], states == 7, dts, out[s:s + 1])
    return out
