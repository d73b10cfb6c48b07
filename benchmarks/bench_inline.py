"""Cold compile of every rig's kernels and numba's share inlining them, two source trees side by side
(issue 22 item 4, ``platcal.numba_inline``).

Per rig and tree, a fresh process (``PYTHONPATH=<tree>``, ``NUMBA_NUM_THREADS=1``, an empty
``NUMBA_CACHE_DIR``) runs the rig's Monte Carlo hook ``warm_kernels`` on the default study's config,
as the study's ``kernels`` job does, and reports its CPU seconds, the CPU seconds inside numba's
inliner at its call sites (``InlineInlinables._do_work``, outermost calls only: nested inlining
counted once) and the load average; the trees alternate rig by rig, so each pair runs in the same minutes.

    python benchmarks/bench_inline.py --before <main checkout>/src --after src [--rigs centrifuge ...] [--rounds 1]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RIGS = ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")

CHILD = """
import json, os, sys, time
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"
import yaml
from numba.core.untyped_passes import InlineInlinables
from platcal.rig import get_rig, rig_config

inlining = [0.0, 0]  # CPU s in outermost inlining calls, current nesting depth
do_work = InlineInlinables._do_work


def timed(self, *args):
    # the pass's call per call site, around inline_function: numba's or platcal.numba_inline's
    t = time.process_time()
    inlining[1] += 1
    try:
        return do_work(self, *args)
    finally:
        inlining[1] -= 1
        if inlining[1] == 0:
            inlining[0] += time.process_time() - t


InlineInlinables._do_work = timed
rig = sys.argv[1]
idx = yaml.safe_load(open(sys.argv[2]))
hooks = get_rig(rig).montecarlo
cfg = hooks.check(rig_config(idx, rig))
t0 = time.process_time()
hooks.warm_kernels(cfg)
print(json.dumps({"cpu_s": time.process_time() - t0, "inline_s": inlining[0], "load": os.getloadavg()[0]}))
"""


def cold(tree: Path, rig: str) -> dict:
    """One fresh process's cold ``warm_kernels`` of ``rig`` on ``tree``'s sources."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_CACHE_DIR=cache, NUMBA_NUM_THREADS="1",
                   PLATCAL_AOT_DIR=str(Path(cache) / "aot"))
        run = subprocess.run([sys.executable, "-c", CHILD, rig, str(ROOT / "config" / "config.yaml")],
                             capture_output=True, text=True, env=env, cwd=ROOT, check=True)
    return json.loads(run.stdout.splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="src directory of the reference tree")
    ap.add_argument("--after", type=Path, required=True, help="src directory of the tree under test")
    ap.add_argument("--rigs", nargs="+", default=list(RIGS), choices=RIGS)
    ap.add_argument("--rounds", type=int, default=1)
    a = ap.parse_args()
    print(f"load at start {os.getloadavg()[0]:.2f}", flush=True)
    for r in range(a.rounds):
        for rig in a.rigs:
            for name, tree in (("before", a.before), ("after", a.after)):
                res = cold(tree.resolve(), rig)
                print(f"round {r + 1} {rig:20s} {name:6s} cold CPU {res['cpu_s']:6.1f} s, inlining "
                      f"{res['inline_s']:5.1f} s ({100 * res['inline_s'] / res['cpu_s']:.0f} %), "
                      f"load {res['load']:.2f}", flush=True)


if __name__ == "__main__":
    main()
