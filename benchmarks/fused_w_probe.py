"""Would forming W = Phi P inside the Joseph pass pay? A probe for issue 22 item 1.

The centrifuge's state-major EKF (:mod:`platcal.rigs.centrifuge.ekf_lanes`) reads the block's
packed P (1176 x 4 doubles) in the Joseph update and again, at the next step, in W = Phi P
(:func:`platcal.estimation.lanes.propagate_rows_lanes`: the 30 columns of Phi's attitude rows). A
kernel that accumulated the next step's W while the Joseph pass writes each entry would read P
once, and each entry of W would still sum its terms in column order (``pcols`` ascending, the
rows of P visited in order), so the numbers would be the same bit for bit; but the part of
W[r, i] that runs along row i of P becomes a chain of dependent additions, row by row.

This probe times, on the kernel's own shapes (``pcols`` from ``ekf._structure`` of the 45
identified coefficients, 4 lanes, random K, U, D and Phi, a positive definite P), one numba
thread, compiled as the block kernel is (``noalias`` arrays, LLVM's SLP vectoriser on), ``--steps``
calls per variant, alternating over ``--rounds`` rounds in one process:

- ``joseph``: :func:`~platcal.estimation.lanes.joseph_correct_lanes` alone;
- ``joseph + W``: it, then :func:`~platcal.estimation.lanes.propagate_rows_lanes` (W, the 3 x 3
  block and W written into P's attitude rows: the kernel today);
- ``fused``: one pass that writes each entry of P and adds it to W where Phi has a column;

and checks that the fused W equals the separate one (``np.array_equal``). It prints ns per call.
Its kernels are compiled afresh in each run, not cached: numba's cache key does not hold the SLP
setting, and this probe once timed scalar code compiled before ``slp_vectorize`` was mended (stop 46).

    python benchmarks/fused_w_probe.py [--steps 20000] [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit

from platcal.estimation.lanes import (LANES, NoAliasCompiler, joseph_correct_lanes, packed_index,
                                     propagate_rows_lanes, slp_vectorize)
from platcal.model.instruments import N_IDENTIFIED
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import _structure


@njit(pipeline_class=NoAliasCompiler)
def joseph(xl, Pl, U, K, D, S, Sinv, innov, steps):
    for _ in range(steps):
        joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, False)


@njit(pipeline_class=NoAliasCompiler)
def joseph_then_w(xl, Pl, U, K, D, S, Sinv, innov, pidx, pcols, phi, W, acc, steps):
    for _ in range(steps):
        joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, False)
        propagate_rows_lanes(Pl, pidx, pcols, phi, W, acc, W.shape[0] - 3)


@njit(pipeline_class=NoAliasCompiler)
def fused(Pl, U, K, D, pos, phi, W, steps):
    """K and D are taken as given (the Joseph update's own K = S^-1 U, D = U - S K come first);
    each packed entry of P is corrected as ``joseph_correct_lanes`` does and added to W: to
    W's column j when row i is a column of Phi (term kk = i), to its column i when j < i is (term kk = j)."""
    n = W.shape[0]
    L = LANES
    for _ in range(steps):
        W[:] = 0.0
        e = 0
        for i in range(n):
            pi = pos[i]
            for j in range(i + 1):
                for l in range(LANES):
                    Pl[e + j, l] -= ((K[i, l] * U[j, l] + K[i, L + l] * U[j, L + l] + K[i, 2 * L + l] * U[j, 2 * L + l])
                                     + (D[i, l] * K[j, l] + D[i, L + l] * K[j, L + l]
                                        + D[i, 2 * L + l] * K[j, 2 * L + l]))
                pj = pos[j]
                if pj >= 0 and j < i:
                    for r in range(3):
                        for l in range(LANES):
                            W[i, r * L + l] += phi[r, pj, l] * Pl[e + j, l]
                if pi >= 0:
                    for r in range(3):
                        for l in range(LANES):
                            W[j, r * L + l] += phi[r, pi, l] * Pl[e + j, l]
            e += i + 1


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args(argv)
    set_threads(1)
    with slp_vectorize():  # compiled as the kernel is: noalias arrays, LLVM's SLP vectoriser on
        probe(a)


def probe(a) -> None:
    pcols = _structure(np.arange(N_IDENTIFIED))[0]
    if np.any(np.diff(pcols) <= 0):
        raise SystemExit(f"pcols not ascending ({pcols}): the fused pass would sum W in another order")
    n, L = N_IDENTIFIED + 3, LANES
    pidx = packed_index(n)
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    P0 = A @ A.T / n + np.eye(n)
    Pl0 = np.empty((n * (n + 1) // 2, L))
    for i in range(n):
        for j in range(i + 1):
            Pl0[pidx[i, j]] = P0[i, j]
    U, K, D = (1e-4 * rng.standard_normal((n, 3 * L)) for _ in range(3))
    # Phi's attitude rows as in the filter: 1 on their own angle, small elsewhere (P stays bounded)
    phi = 1e-3 * rng.standard_normal((3, pcols.size, L))
    for r in range(3):
        phi[r, pcols.size - 3 + r] = 1.0
    pos = np.full(n, -1, dtype=np.int64)
    pos[pcols] = np.arange(pcols.size)
    S, Sinv = np.zeros((3, 3, L)), np.zeros((3, 3, L))
    for l in range(L):
        S[:, :, l] = np.eye(3)
        Sinv[:, :, l] = np.eye(3)
    xl, innov, W, acc = np.zeros((n, L)), np.zeros((3, L)), np.zeros((n, 3 * L)), np.zeros((6, L))
    # the Joseph update forms K and D from U, S, Sinv: the fused pass takes that K and D
    joseph(xl, Pl0.copy(), U, K, D, S, Sinv, innov, 1)
    Ks, Ds = K.copy(), D.copy()
    # the same P+ and W both ways (W before the kernel writes it into P's attitude rows)
    Pa, Wa = Pl0.copy(), np.zeros_like(W)
    joseph(xl, Pa, U, K, D, S, Sinv, innov, 1)
    joseph_then_w(xl, Pl0.copy(), U, K, D, S, Sinv, innov, pidx, pcols, phi, Wa, acc, 1)
    Pb, Wb = Pl0.copy(), np.zeros_like(W)
    fused(Pb, U, Ks, Ds, pos, phi, Wb, 1)
    same = np.array_equal(Pa, Pb) and np.array_equal(Wa, Wb)
    runs = {
        "joseph": lambda P: joseph(xl, P, U, K, D, S, Sinv, innov, a.steps),
        "joseph + W": lambda P: joseph_then_w(xl, P, U, K, D, S, Sinv, innov, pidx, pcols, phi, W, acc, a.steps),
        "fused": lambda P: fused(P, U, Ks, Ds, pos, phi, W, a.steps),
    }
    best = dict.fromkeys(runs, np.inf)
    for _ in range(a.rounds):
        for name, run in runs.items():
            P = Pl0.copy()
            c0 = time.process_time()
            run(P)
            best[name] = min(best[name], (time.process_time() - c0) / a.steps * 1e9)
    print(f"4 lanes, n = {n}, {pcols.size} columns of Phi, one numba thread, {a.steps} calls, best of {a.rounds} "
          f"alternating rounds; load average {os.getloadavg()[0]:.2f}")
    print("| variant | ns per call |")
    print("|---|---:|")
    for name, v in best.items():
        print(f"| {name} | {v:.0f} |")
    print(f"fused P and W equal to the Joseph update then W (np.array_equal): {'yes' if same else 'NO'}")
    print("(the fused variant does not form K and D, which the Joseph update does: compare it with "
          "'joseph + W' less about the K, D and x share of 'joseph')")


if __name__ == "__main__":
    main()
