"""The lanes' Joseph update, one row of P a pass against two (issue 22 item 1, stop 49).

:func:`platcal.estimation.lanes.joseph_correct_lanes` corrects the packed lower triangle of a
block's P two rows a pass since stop 49: column j's K and U are loaded once for rows i and i + 1
(4 vector loads an entry instead of 7), each row a view of P so that its entries' indices are the
loop's own (no negative-index code) and the two rows' loads and stores stay apart for LLVM's SLP
vectoriser. This probe times the shared function (with ``update_x`` off: K, D and the triangle)
against the same function with the triangle one row a pass (stop 48's loop, kept here), on the
centrifuge's n = 48 and the multi-position rig's n = 27 (odd: its last row alone), 4 lanes, one
numba thread, compiled as the block kernels are (``noalias`` arrays, SLP on), ``steps`` calls
each, alternating over ``rounds`` rounds in one process. Checks that both give the same P bit
for bit (``np.array_equal``), then prints the least ns per 4-lane call and the cycles per entry
of the triangle at ``--ghz``.

    python benchmarks/joseph_rows_probe.py [--steps 20000] [--rounds 5] [--ghz 2.596]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from numba import njit

from platcal.estimation.lanes import LANES, NoAliasCompiler, gain_lanes, joseph_correct_lanes, slp_vectorize
from platcal.parallel import set_threads

L = LANES


@njit(pipeline_class=NoAliasCompiler)
def two_rows(xl, Pl, U, K, D, S, Sinv, innov, steps):
    """The shared function as the kernels call it."""
    for _ in range(steps):
        joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, False)


@njit(pipeline_class=NoAliasCompiler)
def one_row(xl, Pl, U, K, D, S, Sinv, innov, steps):
    """The same K and D, then the triangle one row a pass (stop 48's loop)."""
    n = xl.shape[0]
    for _ in range(steps):
        gain_lanes(U, S, Sinv, K, D)
        e = 0
        for i in range(n):
            for j in range(i + 1):
                for l in range(L):
                    Pl[e + j, l] -= ((K[i, l] * U[j, l] + K[i, L + l] * U[j, L + l] + K[i, 2 * L + l] * U[j, 2 * L + l])
                                     + (D[i, l] * K[j, l] + D[i, L + l] * K[j, L + l] + D[i, 2 * L + l] * K[j, 2 * L + l]))
            e += i + 1


def case(n: int, rng):
    """A block's arguments at ``n`` states: a symmetric positive definite S per lane, its inverse,
    U, and P; x and the innovations unused (``update_x`` off)."""
    A = rng.standard_normal((L, 3, 3))
    S = np.einsum("lij,lkj->ikl", A, A) + 3.0 * np.eye(3)[:, :, None]
    Sinv = np.ascontiguousarray(np.stack([np.linalg.inv(S[:, :, l]) for l in range(L)], axis=2))
    U = rng.standard_normal((n, 3 * L))
    P = rng.standard_normal((n * (n + 1) // 2, L))
    return (np.zeros((n, L)), P, U, np.empty((n, 3 * L)), np.empty((n, 3 * L)), S, Sinv, np.zeros((3, L)))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--ghz", type=float, default=2.596, help="clock for the cycles per entry (this VM's nominal)")
    a = ap.parse_args(argv)
    set_threads(1)
    rng = np.random.default_rng(49)
    fs = {"one row a pass (stop 48)": one_row, "two rows a pass (the kernels')": two_rows}
    with slp_vectorize():
        for n in (48, 27):
            args = case(n, rng)
            outs = []
            for f in fs.values():
                P = args[1].copy()
                f(args[0], P, *args[2:], 1)
                outs.append(P)
            same = np.array_equal(outs[0], outs[1])
            best = dict.fromkeys(fs, np.inf)
            for _ in range(a.rounds):
                for name, f in fs.items():
                    P = args[1].copy()
                    c0 = time.process_time()
                    f(args[0], P, *args[2:], a.steps)
                    best[name] = min(best[name], (time.process_time() - c0) / a.steps * 1e9)
            entries = n * (n + 1) // 2
            print(f"n = {n} ({entries} entries), 4 lanes, one numba thread, {a.steps} calls, best of {a.rounds} "
                  f"alternating rounds, load average {os.getloadavg()[0]:.2f}; P equal bit for bit: {same}")
            for name, ns in best.items():
                print(f"  {name}: {ns:.0f} ns per 4-lane call, {ns * a.ghz / entries:.2f} cycles per entry at "
                      f"{a.ghz:g} GHz")


if __name__ == "__main__":
    main()
