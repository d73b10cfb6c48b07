"""Is the lanes kernel's W = Phi P pass bound by its stores of W? A probe for issue 22 item 1.

:func:`platcal.estimation.lanes.phi_rows_times_p_lanes` (the first part of
``propagate_rows_lanes``) forms W = Phi[attitude rows] P (3 x 48 x 4
lanes) over the 30 columns of Phi two at a time: each pass over the 48 columns of W loads and
stores W once per two columns of Phi. Taking 3, 5 or 6 columns per pass stores W fewer times with
every entry's terms still added in column order (the same numbers bit for bit; checked here with
``np.array_equal``). This probe times the kernel's loop against those variants on
the kernel's shapes (``pcols`` of the 45 identified coefficients, 4 lanes), one numba thread,
compiled as the block kernel is (``noalias`` arrays, SLP on), ``steps`` calls per variant,
alternating over ``rounds`` rounds in one process. Prints ns per 4-lane call.

    python benchmarks/w_columns_probe.py [steps] [rounds]
"""
import os
import sys
import time

import numpy as np
from numba import njit
from platcal.estimation.lanes import LANES, NoAliasCompiler, packed_index, phi_rows_times_p_lanes, slp_vectorize
from platcal.model.instruments import N_IDENTIFIED
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import _structure


@njit(pipeline_class=NoAliasCompiler)
def kernel_loop(Pl, pidx, pcols, phi, W, steps):
    """The kernel's own loop (two columns of Phi a pass), :func:`phi_rows_times_p_lanes`."""
    for _ in range(steps):
        phi_rows_times_p_lanes(Pl, pidx, pcols, phi, W)


def columns_per_pass(m: int):
    """W's loop taking ``m`` columns of Phi per pass over W (``m`` divides their number): each
    entry's ``m`` terms added in column order into one running value, stored once per pass."""

    @njit(pipeline_class=NoAliasCompiler)
    def w(Pl, pidx, pcols, phi, W, steps):
        n = W.shape[0]
        npc = pcols.shape[0]
        for _ in range(steps):
            W[:] = 0.0
            for kk in range(0, npc - m + 1, m):
                for j in range(n):
                    for r in range(3):
                        for l in range(LANES):
                            v = W[j, r * LANES + l]
                            for q in range(m):  # m is a constant of the compile: unrolled
                                v = v + phi[r, kk + q, l] * Pl[pidx[pcols[kk + q], j], l]
                            W[j, r * LANES + l] = v
    return w


def main():
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    set_threads(1)
    with slp_vectorize():
        pcols = _structure(np.arange(N_IDENTIFIED))[0]
        n, L = N_IDENTIFIED + 3, LANES
        pidx = packed_index(n)
        rng = np.random.default_rng(0)
        Pl0 = rng.standard_normal((n * (n + 1) // 2, L))
        phi = rng.standard_normal((3, pcols.size, L))
        if pcols.size % 30:
            raise SystemExit(f"{pcols.size} columns of Phi: 2, 3, 5 and 6 columns a pass need a multiple of 30")
        variants = {"2 columns a pass (the kernel)": kernel_loop,
                    **{f"{m} columns": columns_per_pass(m) for m in (3, 5, 6)}}
        ref = np.zeros((n, 3 * L))
        kernel_loop(Pl0, pidx, pcols, phi, ref, 1)
        for name, f in variants.items():
            W = np.full((n, 3 * L), np.nan)
            f(Pl0, pidx, pcols, phi, W, 1)
            print(f"{name}: W equal to the kernel's loop (np.array_equal): {np.array_equal(W, ref)}")
        best = {k: np.inf for k in variants}
        for _ in range(rounds):
            for name, f in variants.items():
                W = np.zeros((n, 3 * L))
                c0 = time.process_time()
                f(Pl0, pidx, pcols, phi, W, steps)
                best[name] = min(best[name], (time.process_time() - c0) / steps * 1e9)
        print(f"4 lanes, n = {n}, {pcols.size} columns of Phi, one numba thread, {steps} calls, best of {rounds} "
              f"alternating rounds; load average {os.getloadavg()[0]:.2f}")
        for k, v in best.items():
            print(f"{k}: {v:.0f} ns per 4-lane call ({v/4:.0f} per replicate)")


if __name__ == "__main__":
    main()
