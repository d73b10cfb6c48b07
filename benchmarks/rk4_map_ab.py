"""Issue 22 item 1: the centrifuge's RK4 map with its exact Jacobian for a block of lanes
(:func:`platcal.rigs.centrifuge.ekf_lanes.rk4_jac_lanes`) of several commits, alone, in one
process, alternating.

For each commit (``.`` = the working tree) the kernel module of that commit is loaded as a module of
its own (:func:`ekf_lanes_ablation.variant`); its map is called ``--calls`` times in a compiled loop
(the block kernel's compile: ``noalias`` arrays, numpy's error model, inside the working tree's
``slp_vectorize``, with LLVM's loop vectoriser on or, with ``--no-loop-vectorize``, off, as the
block kernel is compiled since stop 50) on 4 lanes of random angles, coefficients and forces.
Prints whether each commit's ``out``, ``phi_a`` and ``phi_g`` equal the first's bit for bit, then
the least and the median ns per 4-lane call over ``--rounds`` rounds.

    python benchmarks/rk4_map_ab.py HEAD . [--calls 50000] [--rounds 9] [--no-loop-vectorize]
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np
from numba import njit

from ekf_lanes_ablation import variant
from lanes_commits_ab import KERNEL, source
from platcal.estimation.lanes import LANES, NoAliasCompiler, slp_vectorize
from platcal.rigs.centrifuge.attitude import N_GYRO
from platcal.rigs.centrifuge.catalogue import full_truth

LOOP = '''
@njit(pipeline_class=NoAliasCompiler, error_model="numpy")
def loop(N, ang, coef, fr3, g, wn, wu, out, pa, pg, k, ka, kg, v, sc0, sc, fr, w):
    for i in range(N):
        ang[0] += 1e-9  # a new state each call, as the filter's
        fn(ang, coef, fr3, 0.005, g, wn, wu, out, pa, pg, k, ka, kg, v, sc0, sc, fr, w)
    return out[0]
'''
# the map's scratch sizes in lanes (out, phi_a, phi_g, k, ka, kg as large as any commit's, v, sc0, sc, fr, w)
SIZES = (3, 9, 3 * N_GYRO, 12, 36, 12 * N_GYRO, 42, 6, 6, 3, 40)


def loops(commits: list[str], folder: str) -> dict:
    """A compiled loop over each commit's ``rk4_jac_lanes`` (inlined, as in the block kernel)."""
    out = {}
    for i, commit in enumerate(commits):
        scope = {"njit": njit, "NoAliasCompiler": NoAliasCompiler,
                 "fn": variant(source(commit, KERNEL), f"map_ab_{i}", folder).rk4_jac_lanes}
        exec(LOOP, scope)
        out[commit] = scope["loop"]
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("commits", nargs="+")
    ap.add_argument("--calls", type=int, default=50000)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--no-loop-vectorize", action="store_true")
    a = ap.parse_args(argv)
    L = LANES
    rng = np.random.default_rng(0)
    ang0 = rng.uniform(-0.5, 2.0, 3 * L)
    coef = rng.normal(0.0, 1e-3, full_truth().size * L)  # every coefficient the map reads, as the kernel's
    fr3 = np.tile([98.0, 1.0, 9.8], 3 * L) + rng.normal(0.0, 1.0, 9 * L)
    g, wn, wu = np.full(L, 9.8), np.full(L, 5e-5), np.full(L, 5e-5)
    with tempfile.TemporaryDirectory() as folder:
        runs = loops(a.commits, folder)
        first = {}
        with slp_vectorize(loop_vectorize=not a.no_loop_vectorize):
            for commit, loop in runs.items():
                scratch = [np.full(m * L, np.nan) for m in SIZES]
                loop(5, ang0.copy(), coef, fr3, g, wn, wu, *scratch)
                first[commit] = scratch[:3]
        for commit in a.commits:
            same = all(np.array_equal(x, y) for x, y in zip(first[commit], first[a.commits[0]]))
            print(f"{commit}: out, phi_a and phi_g {'equal' if same else 'DIFFER from'} {a.commits[0]}'s bit for bit")
        ns = {c: [] for c in a.commits}
        for _ in range(a.rounds):
            for commit, loop in runs.items():
                scratch = [np.zeros(m * L) for m in SIZES]
                t0 = time.process_time()
                loop(a.calls, ang0.copy(), coef, fr3, g, wn, wu, *scratch)
                ns[commit].append((time.process_time() - t0) / a.calls * 1e9)
    print(f"rk4_jac_lanes, {L} lanes, {a.calls} calls x {a.rounds} alternating rounds, loop vectoriser "
          f"{'off' if a.no_loop_vectorize else 'on'}")
    print("| commit | least ns / call | median |")
    print("|---|---:|---:|")
    for commit, v in ns.items():
        print(f"| {commit} | {min(v):.0f} | {np.median(v):.0f} |")


if __name__ == "__main__":
    main()
