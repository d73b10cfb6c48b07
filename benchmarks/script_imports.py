"""What each workflow script pays to import, source trees side by side (issue 22 item 4).

Every Snakemake job is a fresh interpreter running one of ``workflow/scripts/*.py``, so what its
top imports it pays per job. For each script this runs the script's head (its statements before
the first that reads ``snakemake``: the docstring, the BLAS-thread settings, the imports) in a
fresh interpreter per run, each tree with its own ``src`` on ``PYTHONPATH``, alternating the trees
run by run, and prints per script and tree the best process CPU seconds (user + system, the
interpreter's own start included) and wall seconds of ``--runs`` runs, and the heavy libraries the
head left loaded. With ``--rules`` it also multiplies by the default study's jobs per rule (the
counts of ``snakemake -n --quiet rules``, given as a file, one ``rule count`` per line).

    NUMBA_NUM_THREADS=1 nice -n 5 python benchmarks/script_imports.py \\
        --tree main=/path/to/main/src --tree branch=src --runs 3
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

HEAVY = ("matplotlib.pyplot", "matplotlib", "scipy.stats", "scipy.optimize", "scipy.interpolate", "scipy.linalg",
         "scipy.special", "pandas", "sympy", "numba", "pymoo", "pyarrow", "jsonschema", "joblib", "pint")
FOOTER = "\nimport json as _j, sys as _s\nprint(_j.dumps(sorted(m for m in {heavy!r} if m in _s.modules)))\n"
ROOT = Path(__file__).resolve().parents[1]


def head_of(script: Path) -> str:
    """The script's statements before the first that reads the name ``snakemake``."""
    text = script.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    for node in ast.parse(text).body:
        if any(isinstance(n, ast.Name) and n.id == "snakemake" for n in ast.walk(node)):
            return "".join(lines[:node.lineno - 1])
    return text


def children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_head(code: str, src: str) -> tuple[float, float, list[str]]:
    """CPU and wall seconds of a fresh interpreter running ``code`` with ``src`` first on the path,
    and the heavy modules it left loaded."""
    c, t = children_cpu(), time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, cwd=ROOT,
                         env=dict(os.environ, PYTHONPATH=os.path.abspath(src)))
    return children_cpu() - c, time.perf_counter() - t, json.loads(out.stdout.splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, metavar="NAME=SRC",
                    help="a source tree: a name and its src directory (one or more)")
    ap.add_argument("--runs", type=int, default=3, help="fresh interpreters per script and tree (best reported)")
    ap.add_argument("--scripts", nargs="*", help="script names (default: every workflow/scripts/*.py)")
    ap.add_argument("--rules", help="a file of 'rule count' lines: the study's jobs per rule")
    args = ap.parse_args(argv)
    trees = dict(t.split("=", 1) for t in args.tree)
    scripts = sorted((ROOT / "workflow" / "scripts").glob("*.py"))
    if args.scripts:
        scripts = [s for s in scripts if s.stem in args.scripts]
    jobs = {}
    if args.rules:
        for line in Path(args.rules).read_text().splitlines():
            parts = line.split()
            if len(parts) == 2 and parts[1].isdigit():
                jobs[parts[0]] = int(parts[1])
    print(f"# load {os.getloadavg()[0]:.2f} at the start; best of {args.runs}; CPU s (wall s) per tree")
    print("| script | jobs | " + " | ".join(trees) + " | heavy modules (" + " / ".join(trees) + ") |")
    print("|---|---|" + "---|" * len(trees) + "---|")
    total = {t: 0.0 for t in trees}
    for script in scripts:
        code = head_of(script) + FOOTER.format(heavy=HEAVY)
        best = {t: (float("inf"), float("inf"), []) for t in trees}
        for i in range(args.runs):
            for t in (list(trees) if i % 2 == 0 else list(reversed(trees))):  # alternate: load drifts hit both
                cpu, wall, loaded = run_head(code, trees[t])
                best[t] = (min(best[t][0], cpu), min(best[t][1], wall), loaded)
        n = jobs.get(script.stem, "")
        for t in trees:
            total[t] += best[t][0] * (n or 0)
        print(f"| {script.stem} | {n} | " + " | ".join(f"{best[t][0]:.2f} ({best[t][1]:.2f})" for t in trees)
              + " | " + " / ".join(", ".join(m for m in best[t][2] if m != "matplotlib" or "matplotlib.pyplot"
                                             not in best[t][2]) or "-" for t in trees) + " |")
    if jobs:
        print("# CPU s x jobs over the study: " + ", ".join(f"{t} {v:.1f}" for t, v in total.items()))
    print(f"# load {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
