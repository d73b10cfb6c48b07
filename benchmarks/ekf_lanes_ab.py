"""Issue 22 item 1: the centrifuge EKF's state-major kernel against the reference kernel, in one
process, alternating (so that the shared machine's load falls on both alike).

``run_ekf(..., lanes=True)`` and ``run_ekf`` (the default kernel, the reference) on the Table 1 case
(:func:`bench_filter.table1_case`, 6 x 60 s), one numba thread, ``--rounds`` alternating rounds,
best process CPU time per replicate of each at B = 1, 8, 64; the load average is printed.

    python benchmarks/ekf_lanes_ab.py [--rounds 3] [--batches 1 8 64]
"""

from __future__ import annotations

import argparse
import os
import time

from bench_filter import table1_case
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 8, 64])
    args = ap.parse_args(argv)
    set_threads(1)
    scheme, params, settings, z, t = table1_case(max(args.batches))
    print(f"one numba thread, Table 1 scheme 6 x 60 s, load average {os.getloadavg()[0]:.2f}")
    print("| B | lanes CPU s / replicate | reference CPU s / replicate | lanes / reference |")
    print("|---:|---:|---:|---:|")
    for B in args.batches:
        zb = [zk[:B] for zk in z]
        best = {False: float("inf"), True: float("inf")}
        for ref in (False, True):  # compile / load
            run_ekf(EstimatorInput([zk[:1] for zk in zb], t, scheme.angles_deg, params), settings, lanes=not ref)
        for _ in range(args.rounds):
            for ref in (False, True):
                c0 = time.process_time()
                run_ekf(EstimatorInput(zb, t, scheme.angles_deg, params), settings, lanes=not ref)
                best[ref] = min(best[ref], (time.process_time() - c0) / B)
        print(f"| {B} | {best[False]:.4f} | {best[True]:.4f} | {best[False] / best[True]:.2f} |")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
