"""Strapdown mechanisation in the Earth-fixed track frame (docs/rocket-sled.md §4), batched.

Per IMU step k (first order, identical in the truth and the erroneous runs)::

    f_l     = Ĉ_k f̃_k
    v_{k+1} = v_k + (f_l − 2 ω_ie × v_k + g^l) dt_k
    r_{k+1} = r_k + (v_k + v_{k+1})/2 dt_k
    Ĉ_{k+1} = exp(−[ω_ie dt_k ×]) Ĉ_k exp([ω̃_k dt_k ×])     (Rodrigues)
    Ĉ_0     = exp(−[φ0 ×]),  v_0 = r_0 = 0

dt_k is the interval sample k covers, t_{k+1} − t_k of the record's own times (docs/rocket-sled.md
§12, "Recorded times"): a jittered or gapped record is integrated over its actual intervals, the
sample before a small gap held over it (zero-order hold, as the IMU's sample-and-hold would).

One numba kernel loops over seeds (leading axis) and samples, the seeds split over the numba
threads set (:func:`platcal.parallel.set_threads`; the numbers do not depend on them).
"""

from __future__ import annotations

import numpy as np

from ...jit import kernel_input, njit
from .aot_kernels import run_seeds, seed_kernel
from .config import G


@njit(cache=True)
def _rodrigues(ax, ay, az, out):
    """exp([a×]) into ``out`` (3×3); series for tiny angles."""
    th2 = ax * ax + ay * ay + az * az
    if th2 < 1e-16:
        s = 1.0 - th2 / 6.0
        c = 0.5 - th2 / 24.0
    else:
        th = np.sqrt(th2)
        s = np.sin(th) / th
        c = (1.0 - np.cos(th)) / th2
    # I + s K + c K², K = [a×]
    out[0, 0] = 1.0 + c * (-(ay * ay + az * az))
    out[1, 1] = 1.0 + c * (-(ax * ax + az * az))
    out[2, 2] = 1.0 + c * (-(ax * ax + ay * ay))
    out[0, 1] = -s * az + c * ax * ay
    out[1, 0] = s * az + c * ax * ay
    out[0, 2] = s * ay + c * ax * az
    out[2, 0] = -s * ay + c * ax * az
    out[1, 2] = -s * ax + c * ay * az
    out[2, 1] = s * ax + c * ay * az


@njit(cache=True)
def _initial_attitude(phi0, C):
    """Ĉ_0 = exp(−[φ0×]) per seed into ``C`` (S,3,3)."""
    for s in range(phi0.shape[0]):
        _rodrigues(-phi0[s, 0], -phi0[s, 1], -phi0[s, 2], C[s])


@njit(cache=True, nogil=True)
def _mechanise(lo, hi, f, w, C, vr, wie, g, dts, v_out, r_out, fl_out):
    """Navigate the samples f, w (S,N,3) of seeds ``lo .. hi - 1`` from the state ``C`` (S,3,3)
    attitude and ``vr`` (S,6) [v, r], both updated in place to the state after the last sample
    (a record's next block continues from it: the same operations as one call over the whole
    record). Seeds are independent: threads take contiguous ranges of them."""
    N = f.shape[1]
    E = np.empty((3, 3))
    D = np.empty((3, 3))
    T = np.empty((3, 3))
    for s in range(lo, hi):
        Cs = C[s]
        v0, v1, v2, r0, r1, r2 = vr[s, 0], vr[s, 1], vr[s, 2], vr[s, 3], vr[s, 4], vr[s, 5]
        v_out[s, 0, 0], v_out[s, 0, 1], v_out[s, 0, 2] = v0, v1, v2
        r_out[s, 0, 0], r_out[s, 0, 1], r_out[s, 0, 2] = r0, r1, r2
        for k in range(N):
            dt = dts[k]
            if k == 0 or dt != dts[k - 1]:
                _rodrigues(-wie[0] * dt, -wie[1] * dt, -wie[2] * dt, E)
            fx = Cs[0, 0] * f[s, k, 0] + Cs[0, 1] * f[s, k, 1] + Cs[0, 2] * f[s, k, 2]
            fy = Cs[1, 0] * f[s, k, 0] + Cs[1, 1] * f[s, k, 1] + Cs[1, 2] * f[s, k, 2]
            fz = Cs[2, 0] * f[s, k, 0] + Cs[2, 1] * f[s, k, 1] + Cs[2, 2] * f[s, k, 2]
            fl_out[s, k, 0] = fx
            fl_out[s, k, 1] = fy
            fl_out[s, k, 2] = fz
            # Coriolis −2 ω × v
            cx = -2.0 * (wie[1] * v2 - wie[2] * v1)
            cy = -2.0 * (wie[2] * v0 - wie[0] * v2)
            cz = -2.0 * (wie[0] * v1 - wie[1] * v0)
            n0 = v0 + (fx + cx) * dt
            n1 = v1 + (fy + cy) * dt
            n2 = v2 + (fz + cz - g) * dt
            r0 += (v0 + n0) * 0.5 * dt
            r1 += (v1 + n1) * 0.5 * dt
            r2 += (v2 + n2) * 0.5 * dt
            v0, v1, v2 = n0, n1, n2
            v_out[s, k + 1, 0] = v0
            v_out[s, k + 1, 1] = v1
            v_out[s, k + 1, 2] = v2
            r_out[s, k + 1, 0] = r0
            r_out[s, k + 1, 1] = r1
            r_out[s, k + 1, 2] = r2
            # attitude: C ← E C exp([ω̃ dt×])
            _rodrigues(w[s, k, 0] * dt, w[s, k, 1] * dt, w[s, k, 2] * dt, D)
            for i in range(3):
                for j in range(3):
                    T[i, j] = Cs[i, 0] * D[0, j] + Cs[i, 1] * D[1, j] + Cs[i, 2] * D[2, j]
            for i in range(3):
                for j in range(3):
                    Cs[i, j] = E[i, 0] * T[0, j] + E[i, 1] * T[1, j] + E[i, 2] * T[2, j]
        vr[s, 0], vr[s, 1], vr[s, 2], vr[s, 3], vr[s, 4], vr[s, 5] = v0, v1, v2, r0, r1, r2


def nav_outputs(S: int, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uninitialised outputs of the mechanisation (§4) of S seeds' N samples: ``v`` (m/s), ``r`` (m)
    (S,N+1,3) and ``f_l`` (m/s^2) (S,N,3), each C-contiguous, as views of one allocation (72 bytes
    a sample). One block rather than three: glibc's malloc raises its mmap
    and trim thresholds to the largest block freed (up to 32 MB on 64 bits), so a loop of
    identifies (a Monte Carlo cell, a benchmark) gets the freed block back without faulting and
    zeroing its pages again, where three blocks of a third each were returned to the system on
    every free (issue 22 item 2; ``benchmarks/profile_sled.py``)."""
    nv = S * (N + 1) * 3
    buf = np.empty(2 * nv + S * N * 3)
    return buf[:nv].reshape(S, N + 1, 3), buf[nv:2 * nv].reshape(S, N + 1, 3), buf[2 * nv:].reshape(S, N, 3)


class Navigator:
    """The mechanisation of a record read in blocks (issue 22 item 3): :meth:`step` navigates the
    next block's samples from where the previous one stopped (attitude, velocity, position
    carried), so the blocks together give :func:`mechanise` of the whole record, bit for bit."""

    def __init__(self, phi0: np.ndarray, omega_ie: np.ndarray):
        phi0 = np.ascontiguousarray(np.atleast_2d(phi0), dtype=np.float64)
        self.C = np.empty((phi0.shape[0], 3, 3))
        one = seed_kernel("initial_attitude", _initial_attitude)
        if one is None:
            _initial_attitude(phi0, self.C)
        else:  # ahead of time, a seed at a time (.aot_kernels)
            for s in range(phi0.shape[0]):
                one(phi0[s:s + 1], self.C[s:s + 1])
        self.vr = np.zeros((phi0.shape[0], 6))
        self.wie = np.asarray(omega_ie, dtype=np.float64)

    def step(self, f: np.ndarray, w: np.ndarray, dt):
        """``v, r`` (S,N+1,3) at the block's t_0 … t_N (t_N: the next block's first sample) and
        ``f_l`` (S,N,3) of samples f̃, ω̃ (S,N,3) over ``dt`` (s, scalar or (N,)); see :func:`mechanise`."""
        f = np.ascontiguousarray(f, dtype=np.float64)
        w = kernel_input(np.broadcast_to(w, f.shape))
        S, N = f.shape[:2]
        v, r, fl = nav_outputs(S, N)
        dts = kernel_input(np.broadcast_to(np.asarray(dt, dtype=np.float64), (N,)))
        run_seeds("mechanise", _mechanise, S, f, w, self.C, self.vr, self.wie, G, dts, v, r, fl)
        return v, r, fl


def mechanise(f: np.ndarray, w: np.ndarray, phi0: np.ndarray, omega_ie: np.ndarray, dt):
    """Navigate IMU samples f̃, ω̃ (S,N,3; m/s^2, rad/s) from attitude error φ0 (S,3; rad).

    ``dt``: the IMU period (s), or (N,) the interval each sample covers (recorded times).

    Returns ``v, r`` (S,N+1,3; m/s, m, at t_0 … t_N) and the computed specific force
    ``f_l = Ĉ_k f̃_k`` (S,N,3; m/s^2) per interval: one :class:`Navigator` step.
    """
    f = np.asarray(f)
    return Navigator(np.broadcast_to(phi0, (f.shape[0], 3)), omega_ie).step(f, w, dt)
