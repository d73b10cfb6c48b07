"""One study job's compute, source trees side by side (issue 22 item 4).

Each round runs every tree (``--tree NAME=ROOT``: a checkout whose ``src`` is put first on
``PYTHONPATH`` and whose ``config/`` the job reads) in a fresh process, the order alternating
from round to round (:func:`study_ab.run_order`). A process first runs the job once untimed (its
kernels compiled into the tree's own numba cache, or loaded from it), then ``--repeat`` times on
one numba and one BLAS thread, and reports the least process CPU of those runs. The jobs:

- ``cell:<rig>:<case>``: the Monte Carlo cell of ``case`` at the rig's first noise level with
  every estimator of the default study (:func:`platcal.study.montecarlo.cell_job`);
- ``compare:<level>``: the centrifuge's estimator comparison at ``level`` ug
  (:func:`platcal.rigs.centrifuge.compare_cells.compare_level_job`).

At the end it compares every tree's outputs of its first timed run with the first tree's: the
Parquet tables column by column but for the cost columns (``wall_s``, ``cpu_s``), other files
byte for byte but for ``timing.json`` (seconds). Exit status 1 if any differ.

    python benchmarks/job_ab.py --tree before=/path/to/worktree --tree after=. --job cell:multiposition:S8
    python benchmarks/job_ab.py --tree before=/path/to/worktree --tree after=. --job compare:5 --repeat 1
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd

from study_ab import run_order

CHILD = """
import json, os, pathlib, sys, time
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"
from platcal.rig import get_rig, rig_config
job, root, out, repeat = sys.argv[1], sys.argv[2], pathlib.Path(sys.argv[3]), int(sys.argv[4])
kind, _, arg = job.partition(":")
if kind == "cell":
    from platcal.study.montecarlo import cell_job
    rig, case = arg.split(":")
    hooks = get_rig(rig).montecarlo
    raw = hooks.check(rig_config({"rigs": {rig: f"{root}/config/{rig}.yaml"}}, rig))
    run = lambda dest: cell_job(rig, raw, case, hooks.noise_levels(raw)[0], hooks.estimators(raw), dest)
else:
    from platcal.rigs.centrifuge.compare_cells import compare_level_job
    cfg = rig_config({"rigs": {"centrifuge": f"{root}/config/centrifuge.yaml"}}, "centrifuge")
    run = lambda dest: compare_level_job(cfg, float(arg), dest)
run(out / "warm")
spent = []
for r in range(repeat):
    t0 = time.process_time()
    run(out / f"run{r}")
    spent.append(time.process_time() - t0)
print(json.dumps(spent))
"""

COST_COLUMNS = ("wall_s", "cpu_s")


def differences(a: Path, b: Path) -> list[str]:
    """Files of the output folder ``a`` that differ in ``b`` (cost columns and timing.json aside)."""
    bad = []
    for f in sorted(p for p in a.rglob("*") if p.is_file()):
        g = b / f.relative_to(a)
        if f.name == "timing.json":
            continue
        if not g.exists():
            bad.append(f"{f.relative_to(a)} (missing)")
        elif f.suffix == ".parquet":
            ta, tb = pd.read_parquet(f), pd.read_parquet(g)
            cols = [c for c in ta.columns if c not in COST_COLUMNS]
            if list(ta.columns) != list(tb.columns) or not ta[cols].equals(tb[cols]):
                bad.append(str(f.relative_to(a)))
        elif f.read_bytes() != g.read_bytes():
            bad.append(str(f.relative_to(a)))
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=ROOT (a checkout), two or more")
    ap.add_argument("--job", required=True, help="cell:<rig>:<case> or compare:<level>")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per process (least CPU kept)")
    a = ap.parse_args(argv)
    trees = dict(t.split("=", 1) for t in a.tree)
    if len(trees) < 2 or not a.job.startswith(("cell:", "compare:")):
        ap.error("give two or more --tree NAME=ROOT and --job cell:<rig>:<case> or compare:<level>")
    work = Path(tempfile.mkdtemp(prefix="job_ab_"))
    least = {n: [] for n in trees}
    print(f"{a.job}: {a.rounds} rounds, trees alternating, least CPU of {a.repeat} runs per process, one thread; "
          f"load {os.getloadavg()[0]:.2f} at the start", flush=True)
    for k, name in enumerate(run_order(list(trees), a.rounds)):
        root = Path(trees[name]).resolve()
        out = work / name / f"p{k}"
        env = dict(os.environ, PYTHONPATH=str(root / "src"), NUMBA_CACHE_DIR=str(work / name / "numba"),
                   NUMBA_NUM_THREADS="1")
        done = subprocess.run([sys.executable, "-c", CHILD, a.job, str(root), str(out), str(a.repeat)], env=env,
                              cwd=root, capture_output=True, text=True)
        if done.returncode:
            print(done.stderr[-4000:], file=sys.stderr)
            return 2
        spent = json.loads(done.stdout.strip().splitlines()[-1])
        least[name].append(min(spent))
        print(f"run {k + 1}: {name} least {min(spent):.3f} s CPU of {', '.join(f'{s:.3f}' for s in spent)}",
              flush=True)
    print(f"load {os.getloadavg()[0]:.2f} at the end")
    print("| tree | least CPU s per process, in order | median |")
    print("|---|---|---:|")
    for name, xs in least.items():
        print(f"| {name} | {', '.join(f'{x:.3f}' for x in xs)} | {statistics.median(xs):.3f} |")
    first = next(iter(trees))
    status = 0
    for name in list(trees)[1:]:
        a_out = next((work / first).glob("p*")) / "run0"
        b_out = next((work / name).glob("p*")) / "run0"
        bad = differences(a_out, b_out)
        n = sum(1 for p in a_out.rglob("*") if p.is_file())
        print(f"outputs of {name} against {first}: {n} files, {len(bad)} differ" + (f": {bad}" if bad else ""))
        status |= bool(bad)
    return status


if __name__ == "__main__":
    sys.exit(main())
