"""The sled's Monte Carlo replicates and its lanes filter, source trees side by side (issue 22 item 4).

Each round runs every tree (``--tree NAME=SRC``, a ``src`` folder put first on ``PYTHONPATH``) in a
fresh process, the order alternating from round to round; a process loads (or compiles) the
kernels, then times ``run_replicates`` of the default case's first ``--seeds`` seeds ``--repeat``
times on one numba thread and keeps the least CPU, of the whole replicates and of the lanes filter
(:func:`platcal.rigs.sled.filter_lanes.kalman_lanes`) inside them. Each tree keeps its own numba
cache (``--cache-dir/NAME``), so the first round also pays the tree's cold compile outside the
timed calls.

    python benchmarks/sled_filter_ab.py --tree before=/path/to/old/src --tree after=src --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from study_ab import run_order

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, time
from platcal.parallel import set_threads
from platcal.rig import get_rig, rig_config
import platcal.rigs.sled.filter_lanes as lanes
from platcal.rigs.sled.montecarlo import case_config, replicate_seeds, run_replicates
seeds_n, repeat = int(sys.argv[1]), int(sys.argv[2])
raw = get_rig("sled").montecarlo.check(rig_config({"rigs": {"sled": sys.argv[3]}}, "sled"))
set_threads(1)
cfg = case_config(raw, "default")
seeds = replicate_seeds(raw, "default", list(range(seeds_n)))
spent = [0.0]
inner = lanes.kalman_lanes
def timed(*args, **kwargs):
    t = time.process_time()
    try:
        return inner(*args, **kwargs)
    finally:
        spent[0] += time.process_time() - t
lanes.kalman_lanes = timed  # the filters resolve it by path at each call
run_replicates(cfg, seeds[:8])  # kernels loaded (or compiled) outside the timed calls
best = [float("inf"), float("inf")]
for _ in range(repeat):
    spent[0] = 0.0
    t = time.process_time()
    run_replicates(cfg, seeds)
    best = [min(best[0], time.process_time() - t), min(best[1], spent[0])]
print(json.dumps({"replicates_cpu_s": best[0], "filter_cpu_s": best[1]}))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=SRC (a platcal src folder), two or more")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per process (the least CPU is kept)")
    ap.add_argument("--cache-dir", type=Path, help="numba caches, one folder per tree (default: a temporary folder)")
    args = ap.parse_args(argv)
    trees = dict(t.split("=", 1) for t in args.tree)
    if len(trees) < 2 or any(not Path(src, "platcal").is_dir() for src in trees.values()):
        raise SystemExit("give two or more --tree NAME=SRC, each SRC a folder holding platcal/")
    config = str(ROOT / "config" / "sled.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        caches = args.cache_dir or Path(tmp)
        rows = {name: [] for name in trees}
        print(f"load average {os.getloadavg()[0]:.2f} at start; CPU s, least of {args.repeat} per process, "
              f"{args.seeds} seeds, one numba thread")
        for i, name in enumerate(run_order(list(trees), args.rounds)):
            env = dict(os.environ, PYTHONPATH=str(Path(trees[name]).resolve()),
                       NUMBA_CACHE_DIR=str(caches / name), NUMBA_NUM_THREADS="1")
            out = subprocess.run([sys.executable, "-c", CHILD, str(args.seeds), str(args.repeat), config],
                                 env=env, check=True, capture_output=True, text=True).stdout
            fig = json.loads(out.strip().splitlines()[-1])
            rows[name].append(fig)
            print(f"round {i // len(trees) + 1} {name}: replicates {fig['replicates_cpu_s']:.3f} s, "
                  f"filter {fig['filter_cpu_s']:.3f} s", flush=True)
        print(f"load average {os.getloadavg()[0]:.2f} at end")
        for name, figs in rows.items():
            rep = sorted(f["replicates_cpu_s"] for f in figs)
            fil = sorted(f["filter_cpu_s"] for f in figs)
            print(f"{name}: replicates median {rep[len(rep) // 2]:.3f} s, filter median {fil[len(fil) // 2]:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
