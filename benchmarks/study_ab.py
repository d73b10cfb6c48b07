"""The default study from fresh clones, source trees side by side (issue 22 item 4).

What the README's "How long, now" paragraphs report, by one command: for each round and each
tree (``--tree NAME=COMMIT``, a commit of ``--repo``; the order alternates from round to round:
A B, then B A), a fresh ``git clone`` of the commit, then ``snakemake --cores 2`` in it with its
own ``src`` on ``PYTHONPATH``, an empty numba cache and an empty user cache dir
(``XDG_CACHE_HOME``: platcal's generated sources, matplotlib's font list) in the clone (cold
caches, as on a fresh machine; before stop 41 the user cache dir was this machine's, warm; pip
excluded: the clones share this Python environment's installed dependencies).

Per run it records the wall time (clone included and apart), the CPU of Snakemake and its jobs
(user + system of the whole process tree), the peak resident memory of the largest process, the
Snakemake process's own CPU (its scheduler, the benchmark threads, the job bookkeeping; measured
inside it at exit), how many scheduler passes it made, the load average at the start and the end,
and the job-seconds per rule from the study's Snakemake benchmark files
(:func:`platcal.study.timing.read_benchmarks`). Then it compares every run's outputs with the
first run's: the CSV tables column by column but for the timing columns (:data:`TIMING_COLUMNS`),
``results/claims.md`` byte for byte, and the figures (PNG) byte for byte.

    python benchmarks/study_ab.py --tree start=cb1a5d9 --tree final=HEAD --rounds 2 \\
        --workdir /tmp/study_ab --out benchmarks/results_study_ab.md

A tree may carry extra Snakemake arguments after a colon (``--tree ts2=HEAD:--max-jobs-per-timespan=100/2s``);
``--target`` passes targets to every run (any output or rule of the workflow; a quick check of
the script: ``--target results/sled/montecarlo/coef.parquet``). The same commit twice (``--tree a=HEAD --tree b=HEAD``) measures
the machine's own run-to-run spread, which any A/B must exceed to mean something. Runs one after
the other, nothing else should run meanwhile; a log line per run with an ETA.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from platcal.study.tables import frame_markdown
from platcal.study.timing import read_benchmarks

ROOT = Path(__file__).resolve().parents[1]

TIMING_COLUMNS = frozenset({
    "cheap", "compute_s", "cost_vs_ekf1", "cpu_s", "cpu_s_per_run", "jobs", "max_rss_mb", "max_s", "seconds",
    "seconds_per_run", "share_pct", "wall_s", "wall_s_per_run"})
"""Columns of the study's CSV tables that hold measured times or memory, or a verdict on them
(the comparison's ``cheap``: ``cost_vs_ekf1`` <= 1.5, which a measured 1.49 or 1.51 decides);
they differ between any two runs; every other column must be equal."""
TIMING_FILES = ("timing", "benchmarks")
"""Tables left out of the comparison: a path with one of these parts is all timing."""
TIMING_FIGURES = frozenset({"compare_cost.png"})
"""Figures that plot measured times (expected to differ)."""

SNAKEMAKE = """
import atexit, json, resource, sys
passes = [0]
try:  # count the scheduler's passes (Snakemake's own loop; absent in other versions: not counted)
    from snakemake.scheduling import job_scheduler as _js
    _orig = _js.JobScheduler._schedule_reevalutation
    def _counted(self, delay):
        passes[0] += 1
        return _orig(self, delay)
    _js.JobScheduler._schedule_reevalutation = _counted
except (ImportError, AttributeError):
    passes[0] = None
out = sys.argv[1]
def _report():
    ru = resource.getrusage(resource.RUSAGE_SELF)
    with open(out, "w") as fh:
        json.dump({"snakemake_cpu_s": ru.ru_utime + ru.ru_stime, "scheduler_passes": passes[0]}, fh)
atexit.register(_report)
sys.argv = ["snakemake"] + sys.argv[2:]
from snakemake.cli import main
main()
"""
"""Snakemake's command line run in a Python that writes, at exit, the Snakemake process's own CPU
and its scheduler passes into the file named by its first argument."""


def parse_tree(text: str) -> tuple[str, str, list[str]]:
    """``NAME=COMMIT[:ARG ARG...]`` -> (name, commit, extra Snakemake arguments)."""
    if "=" not in text:
        raise SystemExit(f"--tree {text!r}: write NAME=COMMIT, e.g. --tree start=cb1a5d9")
    name, rest = text.split("=", 1)
    commit, _, extra = rest.partition(":")
    return name, commit, extra.split()


def run_order(names: list[str], rounds: int) -> list[str]:
    """Every tree once per round, the order reversed every other round (A B, B A, A B, ...)."""
    return [n for r in range(rounds) for n in (names if r % 2 == 0 else names[::-1])]


def clone(repo: Path, commit: str, dest: Path) -> None:
    if dest.exists():
        shutil.rmtree(dest)
    subprocess.run(["git", "clone", "-q", str(repo), str(dest)], check=True)
    subprocess.run(["git", "-C", str(dest), "checkout", "-q", commit], check=True)


def run_study(dest: Path, cores: int, extra: list[str], targets: list[str]) -> dict:
    """``snakemake --cores N`` in the clone ``dest``: its figures (wall s, CPU s of the process tree,
    peak RSS MB of its largest process, Snakemake's own CPU s, scheduler passes, load averages)."""
    # every cache cold, as on a fresh machine: numba's and the user cache dir's (platcal's generated
    # sources, matplotlib's fonts), which runs of earlier clones would otherwise have filled
    env = dict(os.environ, PYTHONPATH=str(dest / "src"), NUMBA_CACHE_DIR=str(dest / ".numba_cache"),
               XDG_CACHE_HOME=str(dest / ".cache"))
    own = dest / ".snakemake_self.json"
    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    with open(dest / "study.log", "w") as log:
        proc = subprocess.Popen([sys.executable, "-c", SNAKEMAKE, str(own), "--cores", str(cores), *extra, *targets],
                                cwd=dest, env=env, stdout=log, stderr=subprocess.STDOUT)
        # wait4: the rusage of this process tree alone (Snakemake and every job it waited for)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    self_figures = json.loads(own.read_text()) if own.exists() else {}
    return {"exit": proc.returncode, "wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
            "peak_rss_mb": usage.ru_maxrss / 1024,
            "snakemake_cpu_s": self_figures.get("snakemake_cpu_s"),
            "scheduler_passes": self_figures.get("scheduler_passes"),
            "load_start": load0, "load_end": os.getloadavg()[0]}


def job_seconds(dest: Path) -> pd.Series:
    """Job-seconds (wall) per ``rig/rule`` from the run's Snakemake benchmark files."""
    jobs = read_benchmarks(dest / "results" / "benchmarks")
    return jobs.assign(rule=jobs["rig"] + "/" + jobs["rule"]).groupby("rule")["wall_s"].sum()


def differing_tables(a: Path, b: Path) -> tuple[int, list[str]]:
    """(tables compared, what differs) between two runs' CSV tables, timing columns aside."""
    n, bad = 0, []
    for fa in sorted((a / "results").rglob("*.csv")):
        rel = fa.relative_to(a)
        if any(part in TIMING_FILES or part.startswith("timing") for part in rel.parts):
            continue
        fb = b / rel
        if not fb.exists():
            bad.append(f"{rel}: missing")
            continue
        ta, tb = pd.read_csv(fa), pd.read_csv(fb)
        n += 1
        if list(ta.columns) != list(tb.columns) or len(ta) != len(tb):
            bad.append(f"{rel}: shape")
            continue
        cols = [c for c in ta.columns if c not in TIMING_COLUMNS and not ta[c].equals(tb[c])]
        if cols:
            bad.append(f"{rel}: {', '.join(cols)}")
    return n, bad


def differing_files(a: Path, b: Path, pattern: str) -> tuple[int, list[str]]:
    """(files compared, those not byte-identical) of ``pattern`` under the two runs' results."""
    files = sorted((a / "results").rglob(pattern))
    bad = [str(f.relative_to(a)) for f in files
           if not (b / f.relative_to(a)).exists() or f.read_bytes() != (b / f.relative_to(a)).read_bytes()]
    return len(files), bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=COMMIT[:snakemake args], two or more")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--repo", type=Path, default=ROOT, help="the repository to clone (default: this one)")
    ap.add_argument("--workdir", type=Path, required=True, help="where the clones go (NAME_rR each)")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--target", action="append", default=[], help="a Snakemake target (default: the study)")
    ap.add_argument("--out", type=Path, help="also write the report (Markdown) here")
    args = ap.parse_args(argv)
    trees = {}
    for text in args.tree:
        name, commit, extra = parse_tree(text)
        if name in trees:
            raise SystemExit(f"--tree {text!r}: the name {name!r} is given twice")
        trees[name] = (commit, extra)
    if len(trees) < 2 or args.rounds < 1:
        raise SystemExit("give two or more --tree and --rounds >= 1")
    args.workdir.mkdir(parents=True, exist_ok=True)
    order = run_order(list(trees), args.rounds)
    runs, rules, dests = [], {}, []
    t_all = time.perf_counter()
    for i, name in enumerate(order):
        commit, extra = trees[name]
        rnd = i // len(trees) + 1
        dest = args.workdir / f"{name}_r{rnd}"
        t0 = time.perf_counter()
        clone(args.repo, commit, dest)
        clone_s = time.perf_counter() - t0
        fig = run_study(dest, args.cores, extra, args.target)
        key = f"{name} r{rnd}"
        runs.append({"run": key, "tree": name, "commit": commit, "round": rnd, "clone_s": clone_s, **fig,
                     "clone_to_end_s": clone_s + fig["wall_s"]})
        if (dest / "results" / "benchmarks").exists():
            rules[key] = job_seconds(dest)
        dests.append((key, dest))
        done = time.perf_counter() - t_all
        eta = done / (i + 1) * (len(order) - i - 1)
        print(f"{time.strftime('%H:%M:%S')} {key} ({commit}): exit {fig['exit']}, wall {fig['wall_s']:.0f} s, "
              f"CPU {fig['cpu_s']:.0f} s, job-seconds {rules[key].sum() if key in rules else float('nan'):.0f}; "
              f"{i + 1}/{len(order)} runs, ETA {eta / 60:.0f} min", flush=True)
    table = pd.DataFrame(runs).set_index("run")
    table["job_s"] = pd.Series({k: v.sum() for k, v in rules.items()})
    per_rule = pd.DataFrame(rules).fillna(0.0)
    per_rule = per_rule.loc[per_rule.max(axis=1).sort_values(ascending=False).index]
    ref_key, ref = dests[0]
    checks = []
    for key, dest in dests[1:]:
        n_t, bad_t = differing_tables(ref, dest)
        n_c, bad_c = differing_files(ref, dest, "claims.md")
        n_f, bad_f = differing_files(ref, dest, "*.png")
        checks.append(f"- {key} against {ref_key}: {n_t} CSV tables, {len(bad_t)} differ beyond timing columns"
                      f"{': ' + '; '.join(bad_t) if bad_t else ''}; claims ledgers {n_c}, {len(bad_c)} differ; "
                      f"figures {n_f}, {len(bad_f)} differ"
                      f"{' (' + ', '.join(Path(p).name for p in bad_f) + ')' if bad_f else ''}"
                      f"{' (timing figures)' if bad_f and all(Path(p).name in TIMING_FIGURES for p in bad_f) else ''}")
    cols = ["commit", "exit", "clone_s", "wall_s", "clone_to_end_s", "cpu_s", "job_s", "snakemake_cpu_s",
            "scheduler_passes", "peak_rss_mb", "load_start", "load_end"]
    text = "\n\n".join([
        f"# The default study from fresh clones ({time.strftime('%Y-%m-%d %H:%M')}, "
        f"`python benchmarks/study_ab.py {' '.join(sys.argv[1:] if argv is None else argv)}`)",
        "Runs in order (seconds; cpu_s: Snakemake and its jobs, user + system; job_s: the jobs' wall seconds "
        "summed from the benchmark files; snakemake_cpu_s: the Snakemake process's own CPU):",
        frame_markdown(table[cols].reset_index(), {c: ".1f" for c in cols if c not in ("exit", "scheduler_passes")}),
        "Job-seconds per rule:",
        frame_markdown(per_rule.reset_index(), {c: ".1f" for c in per_rule.columns}),
        "Outputs:\n" + "\n".join(checks),
    ]) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0 if all(r["exit"] == 0 for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
