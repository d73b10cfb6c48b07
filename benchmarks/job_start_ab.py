"""A Monte Carlo cell job's start-up CPU, two source trees side by side (issue 22 item 4).

Runs, in a fresh interpreter per run, what a cell does before its compute: the imports of
``workflow/scripts/montecarlo_cell.py``, ``get_rig``, the config check and the first case of the
default study's config (``config/config.yaml``; a rig's own cell only where its hooks have
``check_cell``, as ``cell_job`` checks), for each rig named, alternating the trees
(``PYTHONPATH`` = each tree's ``src``), and prints the median process CPU seconds (user + system;
CPU, not wall, so that a loaded machine changes the figures little) per tree and rig. Run it from
the project's root; the job-seconds a change saves over the default study are the saving per cell
times the rig's cells.

    NUMBA_NUM_THREADS=1 python benchmarks/job_start_ab.py --tree main=/path/to/main/src --tree branch=src
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys

PROBE = """
import sys
from platcal.rig import rig_config, get_rig
from platcal.study.montecarlo import cell_job
from platcal.io import read_config
name, case, level, estimator = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
hooks = get_rig(name).montecarlo
raw = rig_config(read_config("config/config.yaml", "config"), name)
check_cell = getattr(hooks, "check_cell", None)  # as cell_job checks: its own cell where the rig can
cfg = check_cell(raw, case, level, estimator) if check_cell else hooks.check(raw)
hooks.case(cfg, case, None)
"""
FIRST_CELL = """
import json, sys
from platcal.rig import rig_config, get_rig
from platcal.io import read_config
hooks = get_rig(sys.argv[1]).montecarlo
cfg = hooks.check(rig_config(read_config("config/config.yaml", "config"), sys.argv[1]))
print(json.dumps([hooks.cases(cfg)[0], str(hooks.noise_levels(cfg)[0]), hooks.estimators(cfg)[0]]))
"""
RIGS = ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")


def children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, metavar="NAME=SRC",
                    help="a source tree to time: a name and its src directory (give two or more)")
    ap.add_argument("--runs", type=int, default=7, help="runs per tree and rig (median reported)")
    ap.add_argument("--rigs", nargs="+", default=list(RIGS))
    args = ap.parse_args(argv)
    trees = dict(t.split("=", 1) for t in args.tree)
    for rig in args.rigs:
        first = next(iter(trees.values()))  # the default study's first cell, as the first tree reads it
        cell = json.loads(subprocess.run([sys.executable, "-c", FIRST_CELL, rig], check=True, capture_output=True, text=True,
                                         env=dict(os.environ, PYTHONPATH=os.path.abspath(first))).stdout)
        cpu = {t: [] for t in trees}
        for i in range(args.runs):
            order = list(trees) if i % 2 == 0 else list(reversed(trees))  # alternate: load drifts hit both
            for t in order:
                c = children_cpu()
                subprocess.run([sys.executable, "-c", PROBE, rig, *cell], check=True,
                               env=dict(os.environ, PYTHONPATH=os.path.abspath(trees[t])))
                cpu[t].append(children_cpu() - c)
        print(rig + ": " + ", ".join(f"{t} {statistics.median(v):.3f} s CPU" for t, v in cpu.items())
              + f" (median of {args.runs})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
