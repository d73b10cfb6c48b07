"""A workflow job's fixed cost, source trees side by side (issue 22 item 4).

The fixed cost of a job is what it pays beyond its work: the interpreter, Snakemake's preamble,
imports, numba's start and cache loads, config checks. Measured on a job script that Snakemake
generated (keep them with ``--skip-script-cleanup``; the preamble holds the pickled ``snakemake``
object), run in a fresh interpreter per run: the script's body runs twice in that process, and
the fixed cost is the process CPU (user + system) at the end of the first body minus the second
body's CPU (what a warm process pays again for the same work). Each run prints one JSON line
(``job_cpu``: the job's CPU to the end of its first body; ``fixed_cpu``; ``head``: preamble and
the wrapper's imports; ``body1``, ``body2``; the load average at its start). The trees
alternate, round by round; each runs with its own ``src`` (``PYTHONPATH``) and numba cache
(``<root>/.numba_cache``, warm it first: the rig's ``warm_kernels``), one numba and BLAS thread.
The jobs rewrite their outputs in the working directory (``--workdir``, a study's folder).

    snakemake --cores 1 --skip-script-cleanup -f results/centrifuge/runs/classical/noise10/ekf1/coef.parquet
    python benchmarks/job_fixed_cost.py --workdir . --tree main=/path/to/main --tree branch=. \\
        --rounds 3 .snakemake/scripts/tmp*.montecarlo_cell.py
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time


def cpu() -> float:
    """The process's CPU seconds so far (user + system)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run_twice(script: str) -> dict:
    """Run the job script's body twice in this process (see the module docstring)."""
    src = open(script, encoding="utf-8").read()
    head, sep, body = src.partition("\nsm = snakemake")
    if not sep:
        raise SystemExit(f"{script}: not a platcal wrapper script (no 'sm = snakemake' line)")
    g = {"__name__": "__main__", "__file__": script}
    c0 = cpu()
    exec(compile(head, script, "exec"), g)
    c1 = cpu()
    exec(compile("sm = snakemake" + body, script, "exec"), g)
    c2 = cpu()
    exec(compile("sm = snakemake" + body, script, "exec"), g)
    c3 = cpu()
    return {"start": round(c0, 3), "head": round(c1 - c0, 3), "body1": round(c2 - c1, 3), "body2": round(c3 - c2, 3),
            "job_cpu": round(c2, 3), "fixed_cpu": round(c2 - (c3 - c2), 3)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scripts", nargs="+", help="job scripts kept by snakemake --skip-script-cleanup")
    ap.add_argument("--tree", action="append", metavar="NAME=ROOT",
                    help="a source tree (its root: ROOT/src, ROOT/.numba_cache); give two or more")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--workdir", default=".", help="the study's folder the jobs run in")
    ap.add_argument("--once", action="store_true", help=argparse.SUPPRESS)  # one run in this process
    args = ap.parse_args(argv)
    if args.once:
        print(json.dumps(run_twice(args.scripts[0])))
        return 0
    trees = dict(t.split("=", 1) for t in args.tree or [])
    for r in range(args.rounds):
        for script in args.scripts:
            for name in (list(trees) if r % 2 == 0 else list(reversed(trees))):  # alternate: load drifts hit both
                root = os.path.abspath(trees[name])
                env = dict(os.environ, PYTHONPATH=os.path.join(root, "src"), NUMBA_CACHE_DIR=os.path.join(root, ".numba_cache"),
                           NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
                load = os.getloadavg()[0]
                t = time.perf_counter()
                p = subprocess.run([sys.executable, os.path.abspath(__file__), "--once", os.path.abspath(script)],
                                   env=env, cwd=args.workdir, capture_output=True, text=True)
                out = json.loads(p.stdout.strip().splitlines()[-1]) if p.returncode == 0 else {"error": p.stderr[-300:]}
                out.update(tree=name, job=os.path.basename(script), round=r, load=round(load, 2),
                           wall=round(time.perf_counter() - t, 2))
                print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
