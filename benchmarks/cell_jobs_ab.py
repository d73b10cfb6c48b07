"""A Monte Carlo cell's estimators in one process or one process each (issue 22 item 4).

Since stop 38 the workflow runs a (case, noise level) cell with all its estimators in one job
(``platcal.study.montecarlo.cell_job``); before, each estimator was a job of its own. This script
runs the same cells both ways with the same installed code, alternating, in fresh interpreters:
``per-estimator`` starts one process per estimator (``cell_job`` with that estimator alone),
``per-cell`` one process for the cell (``cell_job`` with every estimator). It prints the wall and
the CPU (user + system of the child processes) per cell, median over the rounds, and the saving
per cell; the job-seconds saved over a study are the saving times the study's cells of that rig.

Run it from a folder whose ``config/config.yaml`` is the study's and after the study's kernels
jobs (numba's cache warm, as the cells find it), e.g. in a clone where ``snakemake`` ran once:

    PYTHONPATH=$PWD/src NUMBA_CACHE_DIR=$PWD/.numba_cache NUMBA_NUM_THREADS=1 \\
        python benchmarks/cell_jobs_ab.py --rounds 3
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

RUN = """
import os, sys
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"
from platcal.io import read_config
from platcal.rig import rig_config
from platcal.study.montecarlo import cell_job
rig, case, level, out, case_file = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4], sys.argv[5] or None
cell_job(rig, rig_config(read_config("config/config.yaml", "config"), rig), case, level, sys.argv[6:], out,
         case_file=case_file)
"""

# (rig, case, level, estimators, the case's file when a rule generates it) of the default study
CELLS = [
    ("centrifuge", "classical", 10.0, ["ekf1", "ekfw"], ""),
    ("multiposition", "S8", 5.0, ["ekf1", "ekf2", "iekf"], ""),
    ("lowprec_centrifuge", "default", 10.0, ["proposed", "traditional"], ""),
]


def run(rig: str, case: str, level: float, estimators: list[str], case_file: str, out: str) -> tuple[float, float]:
    """Wall and child CPU seconds of one process running ``estimators`` of the cell."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", RUN, rig, case, str(level), out, case_file, *estimators], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} at the start; {args.rounds} rounds, alternating")
    print("| rig | cell | estimators | per-estimator wall / CPU s | per-cell wall / CPU s | CPU saved per cell |")
    print("|---|---|---|---:|---:|---:|")
    for rig, case, level, estimators, case_file in CELLS:
        sep, one = [], []
        with tempfile.TemporaryDirectory() as d:
            for r in range(args.rounds):
                walls = [run(rig, case, level, [e], case_file, os.path.join(d, f"s{r}{e}")) for e in estimators]
                sep.append((sum(w for w, _ in walls), sum(c for _, c in walls)))
                one.append(run(rig, case, level, estimators, case_file, os.path.join(d, f"o{r}")))
        med = lambda xs, i: statistics.median(x[i] for x in xs)  # noqa: E731
        print(f"| {rig} | {case} noise {level:g} | {len(estimators)} | {med(sep, 0):.2f} / {med(sep, 1):.2f} "
              f"| {med(one, 0):.2f} / {med(one, 1):.2f} | {med(sep, 1) - med(one, 1):.2f} |")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
