"""Where the centrifuge UKF's step goes (issue 22 item 4, the comparison's ``ukf``: sigma points in
the measurement update): each part of one update timed alone in a compiled loop on one thread, on
a realistic state (the end of a 6 x 10 s Table 1 run), against the whole step of ``run_ukf``.

Parts: the upper Cholesky factor of the 48 x 48 P; the 96 sigma points' outputs less the mean's
(``_sigma_deviations``); the cross-covariance (``_cross_covariance``); the whole update
(``update_all``: those, the transform's moments and the Joseph update; P restored every call,
the restore's own time subtracted). Prints ns per call (thread CPU time, best of 5) and the flops.

    python benchmarks/profile_ukf.py [--steps 20000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit

from platcal.estimation.kalman import update_scratch
from platcal.estimation.unscented import cholesky_upper_into
from platcal.model.instruments import I_K0, I_THETA
from platcal.parallel import set_threads
from platcal.rigs.centrifuge import ukf
from platcal.rigs.centrifuge.base import specific_force
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings

from bench_filter import table1_case
from profile_ekf import per_call


@njit(cache=True)
def _loop_cholesky(steps, P, R):
    s = 0.0
    for _ in range(steps):
        cholesky_upper_into(P, R)
        s += R[1, 2]
    return s


@njit(cache=True)
def _loop_sigma(steps, x, Sf, coef, fr, g, h, mstates, est_idx, Dp, Dm):
    n = x.shape[0]
    nc = n - 3
    cs = coef.copy()
    y0 = np.zeros(3)
    T = np.empty((21, n))
    s = 0.0
    for _ in range(steps):
        ukf._sigma_deviations(np.sin(x[nc]), np.cos(x[nc]), np.sin(x[nc + 1]), np.cos(x[nc + 1]),
                              np.sin(x[nc + 2]), np.cos(x[nc + 2]), Sf, h, mstates, est_idx, coef, cs, fr,
                              g, y0, T, Dp, Dm)
        s += Dp[3, 1]
    return s


@njit(cache=True)
def _loop_cross(steps, Sf, Dp, Dm, h, U):
    s = 0.0
    for _ in range(steps):
        ukf._cross_covariance(Sf, Dp, Dm, h, True, U)
        s += U[1, 4]
    return s


@njit(cache=True)
def _restore(x, P, x0, Q):
    n = x.shape[0]
    for i in range(n):
        x[i] = x0[i]
        for j in range(n):
            P[i, j] = Q[i, j]


@njit(cache=True)
def _loop_restore(steps, x, P):
    Q, x0 = P.copy(), x.copy()
    for _ in range(steps):
        _restore(x, P, x0, Q)
    return P[1, 1]


@njit(cache=True)
def _loop_update(steps, x, P, coef, fr, g, zrow, r_var, h, w2, mstates, est_idx):
    n = x.shape[0]
    U, K, D, S, F, nu = update_scratch(3, n)
    Q, x0 = P.copy(), x.copy()
    perm = np.arange(n)
    Rp, Sf, Dp, Dm, T = np.zeros((n, n)), np.zeros((n, n)), np.empty((n, 3)), np.empty((n, 3)), np.empty((21, n))
    innov, y0, mz, Pzz = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros((3, 3))
    cs = coef.copy()
    s = 0.0
    for _ in range(steps):
        _restore(x, P, x0, Q)
        s += ukf.update_all(x, P, coef, fr, g, zrow, r_var, h, w2, perm, mstates, est_idx, True, Rp, Sf, Dp, Dm,
                            T, U, S, K, D, F, nu, innov, cs, y0, mz, Pzz)[1]
    return s


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args(argv)
    set_threads(1)
    scheme, params, _, z, tt = table1_case(1, 10.0)
    fs = FilterSettings(history_every_s=None)
    data = EstimatorInput(z, tt, scheme.angles_deg, params)
    est = ukf.run_ukf(data, fs)
    whole = np.inf
    for _ in range(3):
        t0 = time.thread_time()
        ukf.run_ukf(data, fs)
        whole = min(whole, (time.thread_time() - t0) / sum(len(t) for t in tt) * 1e9)
    x, P = est.x[0].copy(), np.ascontiguousarray(est.P[0])
    n, nc = x.size, x.size - 3
    est_idx = fs.coef_index
    coef = np.zeros(48)
    coef[est_idx] = x[:nc]
    h, w2, _ = ukf.check_options(n, "update", 1.0, 2.0, None)
    fr, g = specific_force(3.3, params[0]), float(params[0][2])
    mstates = np.array([k for k, f in enumerate(est_idx) if I_K0 <= f < I_THETA + 3], dtype=np.int64)
    Sf = np.zeros((n, n))
    assert cholesky_upper_into(P, Sf)
    Dp, Dm = np.empty((n, 3)), np.empty((n, 3))
    _loop_sigma(1, x, Sf, coef, fr, g, h, mstates, est_idx, Dp, Dm)
    s = args.steps
    restore = per_call(lambda m: _loop_restore(m, x.copy(), P.copy()), s)
    parts = [
        ("Cholesky factor of P (n^3/3 flops)", per_call(lambda m: _loop_cholesky(m, P, np.zeros((n, n))), s),
         n ** 3 / 3),
        ("sigma-point outputs (2n points)", per_call(lambda m: _loop_sigma(m, x, Sf, coef, fr, g, h, mstates,
                                                                          est_idx, Dp, Dm), s), None),
        ("cross-covariance (3 x n(n+1) flops)", per_call(lambda m: _loop_cross(m, Sf, Dp, Dm, h, np.empty((3, n))), s),
         3.0 * n * (n + 1)),
        ("whole update (net of restoring P)", per_call(lambda m: _loop_update(
            m, x.copy(), P.copy(), coef, fr, g, np.array([0.1, 0.2, 0.97]), np.full(3, 1e-10), h, w2, mstates,
            est_idx), s) - restore, None),
    ]
    print(f"UKF (update variant), n = {n}, one thread, thread CPU time, load average {os.getloadavg()[0]:.2f}")
    print("| part | ns per step | GFLOP/s | % of the whole step |")
    print("|---|---:|---:|---:|")
    for name, ns, flops in parts:
        rate = f"{flops / ns:.1f}" if flops else "-"
        print(f"| {name} | {ns:.0f} | {rate} | {100 * ns / whole:.0f} |")
    print(f"| whole step (run_ukf, B = 1, serial kernel) | {whole:.0f} | - | 100 |")


if __name__ == "__main__":
    main()
