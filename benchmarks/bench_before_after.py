"""The centrifuge's estimators before and after a change, side by side in one run (issue 22 item 1).

The source tree of a git revision (``--before``, default ``main``) is exported to a temporary
directory; this tree (``src/`` beside this script) is "after". Rounds alternate before and after
(each a fresh process that times every estimator kind of the registry on the same simulated
Table 1 data, after a warm-up), so both see the same machine load; each figure is the minimum
over the rounds. The machine's matrix-multiply peak is measured between rounds (its maximum is
kept) and every figure is also given machine-normalised: wall s per replicate x peak GFLOP/s.
The estimates of both trees are compared (``np.array_equal`` on x and P of every kind).

    python benchmarks/bench_before_after.py [--before main] [--rounds 3] [--dwell 60] [--batch 64]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def child(dwell: float, B: int, kinds: list[str], out: str) -> None:
    """One round in this process (the tree on PYTHONPATH): per kind, the best of two calls,
    wall and CPU s per replicate, as JSON on stdout; the estimates into ``out`` (npz)."""
    from bench_filter import table1_case
    from platcal.rigs.centrifuge import ekf
    from platcal.rigs.centrifuge.estimators import KINDS

    def run(kind, z, t):
        # a tree from before issue 19 takes the four arrays of ekf.EstimatorInput one by one
        if hasattr(ekf, "EstimatorInput"):
            return KINDS[kind].run(ekf.EstimatorInput(z, t, scheme.angles_deg, params), settings)
        return KINDS[kind].run(z, t, scheme.angles_deg, params, settings)

    scheme, params, settings, z, t = table1_case(B, dwell)
    res, arrays = {}, {}
    for kind in kinds:
        run(kind, [zk[:1, :20] for zk in z], [tk[:20] for tk in t])
        wall = cpu = np.inf
        for _ in range(2):
            t0, c0 = time.perf_counter(), time.process_time()
            est = run(kind, z, t)
            wall = min(wall, time.perf_counter() - t0)
            cpu = min(cpu, time.process_time() - c0)
        res[kind] = (wall / B, cpu / B)
        arrays[f"{kind}_x"], arrays[f"{kind}_P"] = est.x, est.P
    np.savez(out, **arrays)
    print(json.dumps(res))


def export_tree(ref: str, dest: str) -> str:
    """``src/`` of git revision ``ref`` under ``dest``; returns the path to put on PYTHONPATH."""
    tar = Path(dest) / "src.tar"
    subprocess.run(["git", "-C", str(HERE.parent), "archive", "-o", str(tar), ref, "src"], check=True)
    with tarfile.open(tar) as tf:
        tf.extractall(dest, filter="data")
    return str(Path(dest) / "src")


def matmul_peak(n: int = 1500) -> float:
    """float64 matrix-multiply rate of numpy's BLAS, GFLOP/s (best of three)."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    a @ b
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        a @ b
        best = min(best, time.perf_counter() - t0)
    return 2.0 * n**3 / best / 1e9


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", default="main", help="git revision of the 'before' tree (main)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--dwell", type=float, default=60.0)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--kinds", nargs="+", default=["ekf", "iekf", "ukf", "ml"])
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a.dwell, a.batch, a.kinds, a.child)
        return
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"before": export_tree(a.before, tmp), "after": str(HERE.parent / "src")}
        best = {(tree, k): (np.inf, np.inf) for tree in trees for k in a.kinds}
        peak = 0.0
        for r in range(a.rounds):
            for tree, src in trees.items():
                out = os.path.join(tmp, f"{tree}.npz")
                env = dict(os.environ, PYTHONPATH=src)
                line = subprocess.run([sys.executable, __file__, "--child", out, "--dwell", str(a.dwell), "--batch",
                                       str(a.batch), "--kinds", *a.kinds], env=env, check=True,
                                      capture_output=True, text=True).stdout.strip().splitlines()[-1]
                for k, (w, c) in json.loads(line).items():
                    best[tree, k] = (min(best[tree, k][0], w), min(best[tree, k][1], c))
            peak = max(peak, matmul_peak())
        before, after = np.load(os.path.join(tmp, "before.npz")), np.load(os.path.join(tmp, "after.npz"))
        same = {k: all(np.array_equal(before[f"{k}_{v}"], after[f"{k}_{v}"]) for v in "xP") for k in a.kinds}
        rel = {k: float(np.max(np.abs(after[f"{k}_x"] - before[f"{k}_x"])
                               / np.maximum(np.abs(before[f"{k}_x"]), 1e-300))) for k in a.kinds}
    load1 = os.getloadavg()[0]
    print(f"centrifuge estimators, Table 1 scheme 6 x {a.dwell:g} s, B = {a.batch}, before = {a.before}, after = this "
          f"tree; min over {a.rounds} alternating rounds; matmul peak {peak:.1f} GFLOP/s; load average "
          f"{load0:.2f} at start, {load1:.2f} at end; {os.cpu_count()} cores")
    print()
    print("| kind | before wall s/rep | after wall s/rep | before CPU s/rep | after CPU s/rep | before normalised "
          "| after normalised | after/before (CPU) | estimates |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for k in a.kinds:
        (wb, cb), (wa, ca) = best["before", k], best["after", k]
        agree = "bit-identical" if same[k] else f"max rel. diff. of x {rel[k]:.1e}"
        print(f"| {k} | {wb:.4f} | {wa:.4f} | {cb:.4f} | {ca:.4f} | {wb * peak:.2f} | {wa * peak:.2f} | "
              f"{ca / cb:.2f} | {agree} |")


if __name__ == "__main__":
    main()
