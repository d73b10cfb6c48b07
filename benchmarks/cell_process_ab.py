"""A whole Monte Carlo cell job's process CPU, source trees side by side (issue 22 item 4).

What a workflow job costs the machine from the interpreter's start to its exit: the imports,
numba's start and cache loads, the config check, the cell's compute and writing, and the
interpreter's own exit (which :mod:`platcal` shortens since stop 42 by freezing the garbage
collector at exit). For each cell (``--cell rig:case``: the cell of ``case`` at the rig's first
noise level with every estimator of the default config, :func:`platcal.study.montecarlo.cell_job`)
and each tree (``--tree NAME=ROOT``, ``PYTHONPATH`` = its ``src``, its own numba cache under a
temporary folder, warmed by one untimed run first), one fresh interpreter per run, the trees
alternating round by round; it prints every run's process CPU (user + system of the child,
``RUSAGE_CHILDREN``) and the median per cell and tree, with the load average at the start and
the end. One numba and one BLAS thread, as the study's cells run.

    cd benchmarks && python cell_process_ab.py --tree before=/path/to/worktree --tree after=.. --rounds 4
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from job_ab import CHILD

DEFAULT_CELLS = ("centrifuge:table1", "multiposition:S8", "lowprec_centrifuge:default", "sled:default")


def run_child(root: Path, cell: str, cache: Path) -> float:
    """Process CPU seconds (user + system) of one cell job in a fresh interpreter."""
    env = dict(os.environ, PYTHONPATH=str(root / "src"), NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    # job_ab's child with no timed repeat: the cell job once, in a process of its own
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([sys.executable, "-c", CHILD, f"cell:{cell}", str(root), out, "0"], env=env, cwd=root,
                       check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", default=[], help="NAME=ROOT (a checkout), two or more")
    ap.add_argument("--cell", action="append", default=[], help="rig:case (default: one cell of every rig)")
    ap.add_argument("--rounds", type=int, default=4)
    a = ap.parse_args(argv)
    trees = {name: Path(root).resolve() for name, root in (t.split("=", 1) for t in a.tree)}
    if len(trees) < 2:
        ap.error("give two or more --tree NAME=ROOT")
    cells = a.cell or list(DEFAULT_CELLS)
    work = Path(tempfile.mkdtemp(prefix="cell_process_ab_"))
    print(f"cells {', '.join(cells)}; {a.rounds} rounds, trees alternating; load {os.getloadavg()[0]:.2f} "
          "at the start", flush=True)
    for name, root in trees.items():   # compile or load every kernel once, untimed
        for cell in cells:
            run_child(root, cell, work / name)
    cpu: dict[tuple[str, str], list[float]] = {}
    for r in range(a.rounds):
        order = list(trees) if r % 2 == 0 else list(trees)[::-1]
        for cell in cells:
            for name in order:
                cpu.setdefault((cell, name), []).append(run_child(trees[name], cell, work / name))
        print(f"round {r + 1} done, load {os.getloadavg()[0]:.2f}", flush=True)
    print(f"load {os.getloadavg()[0]:.2f} at the end\n")
    print("| cell | tree | process CPU s per run, in order | median |")
    print("|---|---|---|---:|")
    for cell in cells:
        for name in trees:
            v = cpu[(cell, name)]
            print(f"| {cell} | {name} | {', '.join(f'{x:.2f}' for x in v)} | {statistics.median(v):.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
