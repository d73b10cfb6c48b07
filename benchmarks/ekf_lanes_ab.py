"""Issue 22 item 1: the centrifuge EKF's state-major kernel against the reference kernel, in one
process, alternating (so that the shared machine's load falls on both alike).

``run_ekf(..., lanes=True)`` and ``run_ekf`` (the default kernel, the reference) on the Table 1 case
(:func:`bench_filter.table1_case`, 6 x 60 s), one numba thread, ``--rounds`` alternating rounds,
best process CPU time per replicate of each at B = 1, 8, 64; the load average is printed.
``--kinds``: also the IEKF (``run_iekf``, its defaults) and the covariance-only run (about the
truth), the study's other uses of the kernel. ``--check``: instead, whether the two kernels give
bit-identical results (``np.array_equal`` of x, P, the history, the per-pass estimates, NIS, failed
updates and innovations) for the EKF (1 and 2 passes, warm-up), the IEKF and the covariance-only
run at B = 1, 3 and 8 on 1 and 2 threads (Table 1, 6 x ``--dwell`` s).

    python benchmarks/ekf_lanes_ab.py [--rounds 3] [--batches 1 8 64] [--kinds ekf iekf cov]
    python benchmarks/ekf_lanes_ab.py --check [--dwell 10]
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

import numpy as np

from bench_filter import table1_case
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf, run_iekf

FIELDS = ("x", "P", "history_t", "history_x", "history_sigma", "pass_x", "pass_P", "mean_nis",
          "failed_updates", "innovations")


def run_kind(kind: str, scheme, params, settings, z, t, lanes: bool):
    """One run of ``kind`` (``ekf``, ``ekf2``: 2 passes, ``ekfw``: a 1 s warm-up, ``iekf``,
    ``cov``: covariance-only about the truth) on the batch of ``z``, with or without the lanes."""
    data = EstimatorInput(z, t, scheme.angles_deg, params)
    if kind == "ekf":
        return run_ekf(data, settings, lanes=lanes)
    if kind == "ekf2":
        return run_ekf(data, replace(settings, passes=2, innovations=True), lanes=lanes)
    if kind == "ekfw":
        return run_ekf(data, settings, warmup_s=1.0, lanes=lanes)
    if kind == "iekf":
        return run_iekf(data, settings, lanes=lanes)
    lin = np.repeat(full_truth()[None], z[0].shape[0], axis=0)
    return run_ekf(EstimatorInput(None, t, scheme.angles_deg, params), settings, linearise_about=lin, lanes=lanes)


def _same(a, b) -> bool:
    """Bit-identical arrays (NaN equal to NaN), or both None (innovations not kept)."""
    if a is None or b is None:
        return a is None and b is None
    return np.array_equal(a, b, equal_nan=np.asarray(a).dtype.kind == "f")


def check(dwell: float) -> None:
    """Print, per kind, batch and thread count, whether the lanes equal the default kernel bit for bit."""
    scheme, params, settings, z, t = table1_case(8, dwell)
    bad = 0
    for threads in (1, 2):
        set_threads(threads)
        for B in (1, 3, 8):
            zb = [zk[:B] for zk in z]
            for kind in ("ekf", "ekf2", "ekfw", "iekf", "cov"):
                ref = run_kind(kind, scheme, params, settings, zb, t, False)
                new = run_kind(kind, scheme, params, settings, zb, t, True)
                diff = [f for f in FIELDS if not _same(getattr(ref, f), getattr(new, f))]
                bad += len(diff)
                print(f"threads {threads} B {B} {kind}: {'bit-identical' if not diff else 'differ: ' + ', '.join(diff)}",
                      flush=True)
    print(f"{bad} arrays differ; load average {os.getloadavg()[0]:.2f}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 8, 64])
    ap.add_argument("--kinds", nargs="+", default=["ekf"], choices=["ekf", "iekf", "cov"])
    ap.add_argument("--check", action="store_true", help="bit-identity of the two kernels instead of timings")
    ap.add_argument("--dwell", type=float, default=10.0, help="--check: dwell per position, s")
    args = ap.parse_args(argv)
    if args.check:
        check(args.dwell)
        return
    set_threads(1)
    scheme, params, settings, z, t = table1_case(max(args.batches))
    print(f"one numba thread, Table 1 scheme 6 x 60 s, load average {os.getloadavg()[0]:.2f}")
    print("| run | B | lanes CPU s / replicate | reference CPU s / replicate | lanes / reference |")
    print("|---|---:|---:|---:|---:|")
    for kind in args.kinds:
        for B in args.batches:
            zb = [zk[:B] for zk in z]
            best = {False: float("inf"), True: float("inf")}
            for ref in (False, True):  # compile / load
                run_kind(kind, scheme, params, settings, [zk[:1] for zk in zb], t, not ref)
            for _ in range(args.rounds):
                for ref in (False, True):
                    c0 = time.process_time()
                    run_kind(kind, scheme, params, settings, zb, t, not ref)
                    best[ref] = min(best[ref], (time.process_time() - c0) / B)
            print(f"| {kind} | {B} | {best[False]:.4f} | {best[True]:.4f} | {best[False] / best[True]:.2f} |")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
