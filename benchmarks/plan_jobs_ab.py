"""The campaign job and the GA design job, two source trees side by side (issue 22 item 4).

Runs, in a fresh interpreter per run, the body of ``workflow/scripts/campaign_plan.py``
(``run_campaign`` on ``config/campaign.yaml``) or of ``centrifuge_design_scheme.py`` (the
``ga_J`` design of ``config/centrifuge.yaml``), each tree in turn (``PYTHONPATH`` = the tree's
``src``, ``NUMBA_CACHE_DIR`` = the tree's ``.numba_cache``: run each tree once first so that its
numba cache is warm), for ``--rounds`` rounds, and prints each run's process CPU seconds (user +
system: CPU, not wall, so that a loaded machine changes the figures less), wall seconds, peak RSS
and the load average, then each tree's median CPU. The outputs go to ``--out/<tree>-<job>-<round>``
(compare them with ``cmp``: only the check's ``seconds`` may differ). Run it from the project's
root with one numba thread, as the jobs run:

    NUMBA_NUM_THREADS=1 nice -n 5 python benchmarks/plan_jobs_ab.py --tree main=/path/to/main \\
        --tree branch=. --job campaign --rounds 2 --out /tmp/plan_ab
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from job_start_ab import children_cpu  # benchmarks/ is the script's folder

JOBS = {
    "campaign": ("from platcal.study.campaign import run_campaign\n"
                 "run_campaign('config/campaign.yaml', sys.argv[1])\n"),
    "design": ("from platcal.rig import rig_config\n"
               "from platcal.rigs.centrifuge.design import design_scheme_job\n"
               "design_scheme_job(rig_config({'rigs': {'centrifuge': 'config/centrifuge.yaml'}}, 'centrifuge'), "
               "'ga_J', sys.argv[1] + '/ga_J.yaml', log_path=sys.argv[1] + '/ga_J.log')\n"),
}


# the child's last line: its own peak RSS, kB
PEAK = "import resource\nprint(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, metavar="NAME=ROOT",
                    help="a project tree to time: a name and its root (src/ and .numba_cache/ in it)")
    ap.add_argument("--job", choices=sorted(JOBS), action="append", required=True)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    trees = dict(t.split("=", 1) for t in args.tree)
    cpu: dict[tuple[str, str], list[float]] = {}
    for r in range(args.rounds):
        for job in args.job:
            for name, root in trees.items():
                root = Path(root).resolve()
                out = args.out / f"{name}-{job}-{r}"
                out.mkdir(parents=True, exist_ok=True)
                env = {**os.environ, "PYTHONPATH": str(root / "src"), "NUMBA_CACHE_DIR": str(root / ".numba_cache"),
                       "PLATCAL_AOT_DIR": str(root / ".aot")}
                load = os.getloadavg()[0]
                c0 = children_cpu()
                w0 = time.perf_counter()
                done = subprocess.run([sys.executable, "-c", "import sys\n" + JOBS[job] + PEAK, str(out)], env=env,
                                      check=True, stdout=subprocess.PIPE, text=True)
                c1 = children_cpu()
                cpu.setdefault((name, job), []).append(c1 - c0)
                rss = int(done.stdout.split()[-1]) / 1024
                print(f"round {r} {job:8s} {name:8s} CPU {c1 - c0:7.2f} s  wall {time.perf_counter() - w0:7.2f} s  "
                      f"peak RSS {rss:.0f} MB  load {load:.1f} -> {os.getloadavg()[0]:.1f}", flush=True)
    for (name, job), v in cpu.items():
        print(f"{job:8s} {name:8s} median CPU {statistics.median(v):.2f} s over {len(v)} runs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
