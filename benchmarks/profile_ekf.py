"""Where the centrifuge EKF's cycles go (issue 22 item 1): each part of one filter step timed
alone, in a compiled loop on one thread, on a realistic covariance (the end of a short run).

Parts: the model (base specific force twice, the RK4 map with its exact Jacobian, the
accelerometer outputs and Jacobian), the sparse propagation of P (3 attitude rows), the
Joseph update (rank-6 correction of the lower triangle, mirrored) and the whole step
(:func:`platcal.rigs.centrifuge.ekf._run_pass_serial` over one replicate). Prints ns per call
and the share of the whole step.

    python benchmarks/profile_ekf.py [--steps 20000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit

from platcal.estimation.kalman import joseph_update_sparse, propagate_sparse, update_scratch
from platcal.rigs.centrifuge.attitude import MEAS_COLS, N_GYRO, P_G, make_sc_rk4_scratch, measure_jac_sc, rk4_jac_sc
from platcal.rigs.centrifuge.base import specific_force_into
from platcal.rigs.centrifuge.ekf import EstimatorInput, _structure, run_ekf

from bench_filter import table1_case


@njit(cache=True)
def _loop_model(steps, ang, coef, pb, h):
    scratch = make_sc_rk4_scratch()
    fr3 = np.empty((3, 3))
    fr = np.empty(3)
    out = np.empty(3)
    pa = np.empty((3, 3))
    pg = np.empty((3, N_GYRO))
    hm = np.zeros((3, MEAS_COLS.shape[1]))
    ha = np.empty((3, 3))
    acc = 0.0
    for s in range(steps):
        t = s * h
        specific_force_into(t + 0.5 * h, pb, fr3[1])
        specific_force_into(t + h, pb, fr)
        for r in range(3):
            fr3[0, r] = fr[r]
            fr3[2, r] = fr[r]
        rk4_jac_sc(ang, coef, fr3, h, pb, out, pa, pg, scratch)
        measure_jac_sc(ang, coef, fr[0], fr[1], fr[2], pb[P_G], out, hm, ha)
        acc += out[0] + pa[0, 0] + pg[0, 0] + hm[0, 1] + ha[0, 0]
    return acc


@njit(cache=True)
def _loop_propagate(steps, P, dyn, pcols, phi, q):
    n = P.shape[0]
    W = np.empty((3, n))
    blk = np.empty((3, 3))
    Q = P.copy()
    for _ in range(steps):
        P[:, :] = Q  # the same numbers every time: no drift, no denormals
        propagate_sparse(P, dyn, pcols, phi, q, W, blk)
    return P[0, 0]


@njit(cache=True)
def _loop_copy(steps, P):
    Q = P.copy()
    for _ in range(steps):
        P[:, :] = Q
    return P[0, 0]


@njit(cache=True)
def _loop_update(steps, x, P, hcols, hnnz, hval, innov, r_var):
    n = P.shape[0]
    U, K, D, S, Sinv, nu = update_scratch(3, n)
    Q = P.copy()
    x0 = x.copy()
    for _ in range(steps):
        P[:, :] = Q
        x[:] = x0
        joseph_update_sparse(x, P, hcols, hnnz, hval, innov, r_var, U, K, D, S, Sinv, nu, True)
    return P[0, 0]


def per_call(fn, steps: int, repeat: int = 5) -> float:
    """Smallest CPU time of this thread per call over ``repeat`` runs of ``steps`` calls, ns
    (CPU time, not wall: on a shared machine other processes' share of the core does not count)."""
    fn(10)
    best = np.inf
    for _ in range(repeat):
        t0 = time.thread_time()
        fn(steps)
        best = min(best, time.thread_time() - t0)
    return best / steps * 1e9


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    args = ap.parse_args(argv)
    scheme, params, settings, z, tt = table1_case(1, 10.0)
    run_ekf(EstimatorInput(z, tt, scheme.angles_deg, params), settings)
    t0 = time.thread_time()
    est = run_ekf(EstimatorInput(z, tt, scheme.angles_deg, params), settings)
    whole = (time.thread_time() - t0) / sum(len(x) for x in tt) * 1e9
    for _ in range(4):
        t0 = time.thread_time()
        run_ekf(EstimatorInput(z, tt, scheme.angles_deg, params), settings)
        whole = min(whole, (time.thread_time() - t0) / sum(len(x) for x in tt) * 1e9)

    P = np.ascontiguousarray(est.P[0])
    x = est.x[0].copy()
    n = x.size
    nc = n - 3
    pcols, pg, hcols, hsrc, hnnz = _structure(settings.coef_index)
    rng = np.random.default_rng(0)
    phi = rng.standard_normal((3, pcols.size)) * 1e-6
    phi[:, -3:] += np.eye(3)
    q = np.eye(3) * 1e-12
    hval = rng.standard_normal((3, hcols.shape[1])) * 1e-6
    innov = rng.standard_normal(3) * 1e-5
    r_var = np.full(3, 1e-10)
    coef = np.zeros(48)
    coef[:nc] = x[:nc]
    pb = np.ascontiguousarray(params[0])
    s = args.steps
    parts = {
        "model (2 specific forces, RK4 + Jacobian, outputs + Jacobian)":
            per_call(lambda m: _loop_model(m, x[nc:].copy(), coef, pb, 0.02), s),
        "propagate_sparse (3 attitude rows, incl. restoring P)":
            per_call(lambda m: _loop_propagate(m, P.copy(), np.arange(nc, n), pcols, phi, q), s),
        "joseph_update_sparse (incl. restoring P)":
            per_call(lambda m: _loop_update(m, x.copy(), P.copy(), hcols, hnnz, hval, innov, r_var), s),
        "restoring P alone (subtract from the two above)":
            per_call(lambda m: _loop_copy(m, P.copy()), s),
    }
    print(f"one filter step, n = {n}, one thread, CPU time of the thread, load average {os.getloadavg()[0]:.2f}")
    print("| part | ns per step | % of the whole step |")
    print("|---|---:|---:|")
    copy = parts["restoring P alone (subtract from the two above)"]
    for name, ns in parts.items():
        net = ns - copy if "incl." in name else ns
        print(f"| {name} | {ns:.0f} (net {net:.0f}) | {100 * net / whole:.0f} |")
    print(f"| whole step (run_ekf, B = 1, serial kernel) | {whole:.0f} | 100 |")


if __name__ == "__main__":
    main()
