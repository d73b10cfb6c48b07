"""The centrifuge EKF's measurement update split into its parts (issue 22 item 1), each timed
alone in a compiled loop on one thread, on a realistic covariance (the end of a short run):
U = H P and S (``innovation_covariance``), the 3 x 3 Cholesky and inverse, K and D, the
lower-triangle Joseph correction (rows padded to whole vectors) and its mirror, and the whole
``joseph_update_sparse`` for comparison; with each part's floating-point operation count, its
rate, and the port limit of its arithmetic (2 vector ports x 4 doubles a cycle, no FMA: the
bit-identity rules out contraction) at the clock given by ``--ghz``.

    python benchmarks/profile_ekf_joseph.py [--steps 20000] [--ghz 3.0]
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from numba import njit

from platcal.estimation.kalman import (_LANES, _correct3, cholesky_inverse, gain3, innovation_covariance,
                                       joseph_lower3, mirror_lower, update_scratch)
from platcal.rigs.centrifuge.ekf import EstimatorInput, _structure, run_ekf

from bench_filter import table1_case
from profile_ekf import _loop_copy, _loop_update, per_call


@njit(cache=True)
def _loop_u(steps, P, hcols, hnnz, hval, r_var):
    U, K, D, S, Sinv, nu = update_scratch(3, P.shape[0])
    acc = 0.0
    for _ in range(steps):
        innovation_covariance(P, hcols, hnnz, hval, r_var, U, S)
        acc += S[0, 0]
    return acc


@njit(cache=True)
def _loop_chol(steps, S, innov):
    F = np.empty((3, 3))
    nu = np.empty(3)
    acc = 0.0
    for _ in range(steps):
        cholesky_inverse(S, F, nu, innov)
        acc += F[0, 0]
    return acc


@njit(cache=True)
def _loop_kd(steps, U, S, Sinv, K, D):
    for _ in range(steps):
        gain3(U, S, Sinv, K, D)
    return K[0, 0]


@njit(cache=True)
def _loop_lower(steps, P, U, K, D):
    """P drifts (no restore), which costs the same per operation (no subnormals arise)."""
    for _ in range(steps):
        joseph_lower3(P, U, K, D)
    return P[0, 0]


@njit(cache=True)
def _loop_mirror(steps, P):
    for _ in range(steps):
        mirror_lower(P)
    return P[0, 1]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--ghz", type=float, default=3.0, help="core clock for the port limit, GHz")
    a = ap.parse_args(argv)
    scheme, params, settings, z, tt = table1_case(1, 10.0)
    est = run_ekf(EstimatorInput(z, tt, scheme.angles_deg, params), settings)
    P = np.ascontiguousarray(est.P[0])
    x = est.x[0].copy()
    n = x.size
    pcols, pg, hcols, hsrc, hnnz = _structure(settings.coef_index)
    rng = np.random.default_rng(0)
    hval = rng.standard_normal((3, hcols.shape[1])) * 1e-6
    innov = rng.standard_normal(3) * 1e-5
    r_var = np.full(3, 1e-10)
    U, K, D, S, Sinv, nu = (np.ascontiguousarray(v) for v in update_scratch(3, n))
    # U and S of this P, then K and D, as the update computes them
    Pw = P.copy()
    innovation_covariance(Pw, hcols, hnnz, hval, r_var, U, S)
    cholesky_inverse(S, Sinv, nu, innov)
    _correct3(x.copy(), Pw, innov, U, K, D, S, Sinv, True)
    s = a.steps
    entries = sum(min(n, (i // _LANES + 1) * _LANES) for i in range(n))
    nnz = int(hnnz.sum())
    parts = [
        ("U = H P and S", per_call(lambda m: _loop_u(m, P, hcols, hnnz, hval, r_var), s), 2 * nnz * n),
        ("Cholesky of S, L^-1 innov, S^-1", per_call(lambda m: _loop_chol(m, S, innov), s), 0),
        ("K = U S^-1, D = U - K S", per_call(lambda m: _loop_kd(m, U, S, Sinv, K, D), s), 3 * n * 5 + 3 * n * 6),
        (f"lower-triangle correction ({entries} entries x 12)",
         per_call(lambda m: _loop_lower(m, P.copy(), U, K, D), s), 12 * entries),
        (f"mirror ({n * (n - 1) // 2} entries, mirror_lower)", per_call(lambda m: _loop_mirror(m, P.copy()), s), 0),
    ]
    restore = per_call(lambda m: _loop_copy(m, P.copy()), s)
    whole = per_call(lambda m: _loop_update(m, x.copy(), P.copy(), hcols, hnnz, hval, innov, r_var), s) - restore
    print(f"the measurement update of one filter step, n = {n}, one thread, CPU time of the thread, load average "
          f"{os.getloadavg()[0]:.2f}; port limit = flops / (8 per cycle x {a.ghz:g} GHz)")
    print("| part | ns per step | flops | GFLOP/s | port limit ns |")
    print("|---|---:|---:|---:|---:|")
    for name, ns, fl in parts:
        print(f"| {name} | {ns:.0f} | {fl} | {fl / ns if fl else 0:.1f} | {fl / 8 / a.ghz:.0f} |")
    print(f"| sum of the parts | {sum(p[1] for p in parts):.0f} | | | |")
    print(f"| whole joseph_update_sparse (x updated; less restoring P: {restore:.0f} ns) | {whole:.0f} | | | |")


if __name__ == "__main__":
    main()
