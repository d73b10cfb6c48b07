"""Issue 22 item 1: the centrifuge's state-major EKF kernel of several commits in one process,
alternating (so that the shared machine's load falls on all alike).

For each commit (or ``.`` for the working tree), the kernel module
``src/platcal/rigs/centrifuge/ekf_lanes.py`` and the shared lane pieces
``src/platcal/estimation/lanes.py`` of that commit (``git show``) are loaded as modules of their
own beside the installed platcal (its other modules are the working tree's); ``run_ekf(...,
lanes=True)`` then runs the Table 1 case (:func:`bench_filter.table1_case`, 6 x 60 s) at
``--batch`` replicates on one numba thread with each commit's kernel in turn, ``--rounds`` rounds.
Prints whether every commit's x and P equal the first's bit for bit, then per commit the least and
the median CPU s per replicate (and ns per replicate-step) and the load average. Finer than
``ekf_lanes_ab.py`` run in two trees one after the other: a change of 1 % shows over 30 rounds.

    python benchmarks/lanes_commits_ab.py 7e1fb50 . [--batch 16] [--rounds 30]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import platcal.rigs.centrifuge.ekf_lanes as ekf_lanes
from bench_filter import table1_case
from ekf_lanes_ablation import variant
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf

KERNEL = "src/platcal/rigs/centrifuge/ekf_lanes.py"
PIECES = "src/platcal/estimation/lanes.py"
REPO = Path(__file__).resolve().parent.parent


def source(commit: str, path: str) -> str:
    """The text of ``path`` at ``commit`` (``.``: the working tree)."""
    if commit == ".":
        return (REPO / path).read_text()
    return subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:{path}"], check=True, capture_output=True,
                          text=True).stdout


def kernels(commits: list[str], folder: str) -> dict:
    """``run_pass_lanes`` of each commit, its kernel and lane pieces as modules ``ab_lanes_<i>`` and
    ``ab_ekf_lanes_<i>`` in ``folder`` (:func:`ekf_lanes_ablation.variant`: relative imports made
    absolute to the installed platcal)."""
    sys.path.insert(0, folder)
    runs = {}
    for i, commit in enumerate(commits):
        variant(source(commit, PIECES), f"ab_lanes_{i}", folder)
        text = source(commit, KERNEL).replace("from ...estimation.lanes import", f"from ab_lanes_{i} import")
        runs[commit] = variant(text, f"ab_ekf_lanes_{i}", folder).run_pass_lanes
    return runs


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("commits", nargs="+", help="commits to compare (. = the working tree)")
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=30)
    a = ap.parse_args(argv)
    set_threads(1)
    scheme, params, settings, z, t = table1_case(a.batch)
    data = EstimatorInput(z, t, scheme.angles_deg, params)
    small = EstimatorInput([zk[:1] for zk in z], t, scheme.angles_deg, params)
    steps = sum(len(tk) for tk in t)
    load0 = os.getloadavg()[0]
    own = ekf_lanes.run_pass_lanes
    cpu = {c: [] for c in a.commits}
    # run_ekf imports run_pass_lanes from ekf_lanes at each call: the module's name is swapped
    try:
        with tempfile.TemporaryDirectory() as folder:
            runs = kernels(a.commits, folder)
            results = {}
            for commit, kernel in runs.items():  # compile, and each commit's numbers
                ekf_lanes.run_pass_lanes = kernel
                run_ekf(small, settings, lanes=True)
                results[commit] = run_ekf(data, settings, lanes=True)
            first = results[a.commits[0]]
            for commit, est in results.items():
                same = np.array_equal(first.x, est.x) and np.array_equal(first.P, est.P)
                print(f"{commit}: x and P {'equal' if same else 'DIFFER from'} {a.commits[0]}'s bit for bit")
            for _ in range(a.rounds):
                for commit, kernel in runs.items():
                    ekf_lanes.run_pass_lanes = kernel
                    c0 = time.process_time()
                    run_ekf(data, settings, lanes=True)
                    cpu[commit].append((time.process_time() - c0) / a.batch)
    finally:
        ekf_lanes.run_pass_lanes = own
    print(f"state-major EKF kernel, Table 1 case 6 x 60 s ({steps} steps), B = {a.batch}, one numba thread, "
          f"{a.rounds} alternating rounds; load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end")
    print("| commit | least CPU s / replicate | median | ns / replicate-step (least) |")
    print("|---|---:|---:|---:|")
    for commit, v in cpu.items():
        print(f"| {commit} | {min(v):.5f} | {np.median(v):.5f} | {min(v) / steps * 1e9:.0f} |")


if __name__ == "__main__":
    main()
