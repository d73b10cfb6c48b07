"""Issue 22 item 4: LLVM's optimisation level 1 for numba (``NUMBA_OPT=1``) against numba's
default (3): the cold compile of each rig's kernels job and the CPU of one Monte Carlo cell per
rig, with the cells' tables compared. The study keeps numba's default: level 1 saved 3-15 % of the
compile and cost up to 24 % of a cell (``benchmarks/results_issue22_numba_opt.txt``).

For each rig and level, alternating the levels (``--rounds`` times): a fresh process on an empty
``NUMBA_CACHE_DIR`` runs the rig's ``warm_kernels`` (what the study's rule ``kernels`` runs; CPU s
= the cold compile), then a fresh process on that cache runs one cell of the default study (the
rig's first case, noise level and estimator: CPU s of the cell's replicates, the kernels loaded
before the clock). The cells' coefficient and run tables of the two levels must be equal
(``np.array_equal`` column by column, timing columns aside): the optimisation level changes no
floating-point operation (no fast-math flags), only the time to compile.

    NUMBA_NUM_THREADS=1 python benchmarks/numba_opt_ab.py [--rigs centrifuge ...] [--rounds 2]

Run from the repository root (the config paths are the default study's).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

LEVELS = ("3", "1")
TIMING = {"wall_s", "cpu_s", "wall_s_per_run", "seconds_per_run"}


def child(rig_name: str, what: str, out: str) -> dict:
    """In a fresh process: ``compile`` (warm_kernels) or ``cell`` (one cell; tables to ``out``)."""
    from platcal.io import read_yaml
    from platcal.rig import get_rig, rig_config
    from platcal.study.montecarlo import cell_tables

    hooks = get_rig(rig_name).montecarlo
    cfg = hooks.check(rig_config(read_yaml(Path("config/config.yaml").read_text()), rig_name))
    if what == "compile":
        c0 = time.process_time()
        hooks.warm_kernels(cfg)
        return {"cpu": time.process_time() - c0}
    case = hooks.case(cfg, hooks.cases(cfg)[0], None)
    level, est = hooks.noise_levels(cfg)[0], hooks.estimators(cfg)[0]
    hooks.warm_kernels(cfg)  # loaded from the cache: outside the clock
    c0 = time.process_time()
    coef, runs, _ = cell_tables(get_rig(rig_name), cfg, case, level, est)
    cpu = time.process_time() - c0
    np.savez(out, **{f"coef_{k}": np.asarray(coef[k]) for k in coef.columns},
             **{f"runs_{k}": np.asarray(runs[k]) for k in runs.columns if k not in TIMING})
    return {"cpu": cpu, "cell": f"{case.name} {level:g} {est}"}


def run_child(rig: str, what: str, level: str, cache: str, out: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, NUMBA_OPT=level)
    res = subprocess.run([sys.executable, __file__, "--child", rig, what, out], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(res.strip().splitlines()[-1])


def same_tables(a: str, b: str) -> bool:
    with np.load(a, allow_pickle=True) as x, np.load(b, allow_pickle=True) as y:
        return sorted(x.files) == sorted(y.files) and all(
            np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f") for k in x.files)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    ap.add_argument("--rigs", nargs="+", default=["centrifuge", "multiposition", "sled", "lowprec_centrifuge"])
    ap.add_argument("--rounds", type=int, default=1)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(child(*a.child)))
        return
    print(f"NUMBA_OPT A/B, fresh processes, levels alternating; load average {os.getloadavg()[0]:.2f} at start")
    print("| rig | round | level | cold compile CPU s (warm_kernels) | cell CPU s | cell | tables equal to level 3 |")
    print("|---|---:|---:|---:|---:|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for rig in a.rigs:
            for r in range(a.rounds):
                for level in LEVELS:
                    cache = os.path.join(tmp, f"{rig}_{r}_{level}")
                    comp = run_child(rig, "compile", level, cache, "")
                    out = os.path.join(tmp, f"{rig}_{r}_{level}.npz")
                    cell = run_child(rig, "cell", level, cache, out)
                    same = same_tables(os.path.join(tmp, f"{rig}_{r}_3.npz"), out)
                    print(f"| {rig} | {r + 1} | {level} | {comp['cpu']:.1f} | {cell['cpu']:.2f} | {cell['cell']} | "
                          f"{same} |", flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
