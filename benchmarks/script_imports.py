"""What each workflow script pays to import, source trees side by side (issue 22 item 4).

Every Snakemake job is a fresh interpreter running one of ``workflow/scripts/*.py``, so what its
top imports it pays per job. For each script this runs the script's head (its statements before
the first that reads ``snakemake``: the docstring, the BLAS-thread settings, the imports) in a
fresh interpreter per run, each tree its own script with its own ``src`` on ``PYTHONPATH``,
alternating the trees run by run, and prints per script and tree the best process CPU seconds (user + system, the
interpreter's own start included) and wall seconds of ``--runs`` runs, and the heavy libraries the
head left loaded. With ``--rules`` it also multiplies by the default study's jobs per rule (the
counts of ``snakemake -n --quiet rules``, given as a file, one ``rule count`` per line).

    NUMBA_NUM_THREADS=1 nice -n 5 python benchmarks/script_imports.py \\
        --tree main=/path/to/main --tree branch=. --runs 3
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


def head_of(script: Path) -> str | None:
    """The script's statements before the first that reads the name ``snakemake``; None for a
    script that never does (not a job's script: run by hand) or is missing."""
    if not script.exists():
        return None
    text = script.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    for node in ast.parse(text).body:
        if any(isinstance(n, ast.Name) and n.id == "snakemake" for n in ast.walk(node)):
            return "".join(lines[:node.lineno - 1])
    return None


def children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_head(code: str, root: Path) -> tuple[float, float, list[str]]:
    """CPU and wall seconds of a fresh interpreter running ``code`` in the tree ``root`` with its
    ``src`` first on the path, and the heavy modules it left loaded."""
    c, t = children_cpu(), time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, cwd=root,
                         env=dict(os.environ, PYTHONPATH=str(root / "src")))
    return children_cpu() - c, time.perf_counter() - t, json.loads(out.stdout.splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, metavar="NAME=ROOT",
                    help="a source tree: a name and its root (holding src/ and workflow/scripts/; one or more)")
    ap.add_argument("--runs", type=int, default=3, help="fresh interpreters per script and tree (best reported)")
    ap.add_argument("--scripts", nargs="*", help="script names (default: every workflow/scripts/*.py)")
    ap.add_argument("--rules", help="a file of 'rule count' lines: the study's jobs per rule")
    args = ap.parse_args(argv)
    trees = {name: Path(root).resolve() for name, root in (t.split("=", 1) for t in args.tree)}
    names = sorted({p.stem for root in trees.values() for p in (root / "workflow" / "scripts").glob("*.py")})
    if args.scripts:
        names = [n for n in names if n in args.scripts]
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
    for name in names:
        code = {t: head_of(root / "workflow" / "scripts" / f"{name}.py") for t, root in trees.items()}
        if any(c is None for c in code.values()):
            continue  # not a job's script (or not in every tree)
        best = {t: (float("inf"), float("inf"), []) for t in trees}
        for i in range(args.runs):
            for t in (list(trees) if i % 2 == 0 else list(reversed(trees))):  # alternate: load drifts hit both
                cpu, wall, loaded = run_head(code[t] + FOOTER.format(heavy=HEAVY), trees[t])
                best[t] = (min(best[t][0], cpu), min(best[t][1], wall), loaded)
        n = jobs.get(name, "")
        for t in trees:
            total[t] += best[t][0] * (n or 0)
        print(f"| {name} | {n} | " + " | ".join(f"{best[t][0]:.2f} ({best[t][1]:.2f})" for t in trees)
              + " | " + " / ".join(", ".join(m for m in best[t][2] if m != "matplotlib" or "matplotlib.pyplot"
                                             not in best[t][2]) or "-" for t in trees) + " |")
    if jobs:
        print("# CPU s x jobs over the study: " + ", ".join(f"{t} {v:.1f}" for t, v in total.items()))
    print(f"# load {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
