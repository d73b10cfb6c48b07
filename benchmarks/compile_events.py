"""What numba compiles in the centrifuge's default-study jobs, per dispatcher and signature
(issue 22 item 4).

Runs a default-study-like sequence of the centrifuge's jobs, each in a fresh process, one after
the other on one empty ``NUMBA_CACHE_DIR`` (as Snakemake's jobs share a clone's cache): the
sweep's ``ekf1`` and ``ekfw`` cells (batch 8, chunks 8, 8, 4), the comparison's ``ekf2``,
``iekf``, ``ukf`` and ``ml`` cells (each with its 2-period warm-up run), the single run and the
GA design's covariance-only runs. The jobs are the study's own job functions on
``config/centrifuge.yaml`` with short dwells (``bench_compile.study_config``: every ``dwell_s``
``--dwell`` s, the GA at 2 generations of 6): numba's types do not depend on the record's length
or the batch size, so the same specialisations compile. Every compile is recorded with numba's
event API (``numba.core.event``, event ``numba:compile``, fired on cache misses only); a
compile's own seconds are its wall time less the compiles nested in it (callees typed while the
caller compiles).

Prints per job its wall / CPU s and compile CPU s, then per dispatcher its specialisations (argument
types) with their own compile s, and the total. ``--json`` writes the raw records.

    NUMBA_NUM_THREADS=1 python benchmarks/compile_events.py [--dwell 1] [--json out.json]

``--rig multiposition``: the multi-position rig's study jobs in the study's order instead
(:data:`MP_JOBS`): the centrifuge's and the rig's ``kernels`` jobs (the rig's hook
``warm_kernels``), a Monte Carlo cell (S8 at 5 ug, every estimator, the config's 20 seeds) and
``multiposition_centrifuge_table1`` (``platcal observability`` of the centrifuge's config, scheme
table1, which waits for the centrifuge's kernels job); what a job after a kernels job compiles is
what that kernels job did not warm. ``--rig sled`` and ``--rig lowprec_centrifuge`` (:data:`RIG_JOBS`):
the rig's ``kernels`` job, then a Monte Carlo cell of its ``default`` case (the study's first noise
level, every estimator) and, for the sled, the case's one-replicate series (rule ``sled_series``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import yaml
from bench_compile import ROOT, study_config

# platcal before numba, as in the study's jobs: platcal sets numba's cache locators in the
# environment, and numba re-reads a changed environment at its first compile, which resets LLVM's
# SLP vectoriser if that compile runs inside platcal.estimation.lanes.slp_vectorize
from platcal.io import atomic_write_text

from numba.core import event

# (job name, estimator or None): the sweep's estimators first (they start the study), then the
# comparison's other kinds, then the single run and the GA design
JOBS = ("sweep:ekf1", "sweep:ekfw", "compare:10", "single", "design:ga_J")
# the multi-position rig's study jobs, each after the jobs it waits for (--rig multiposition)
MP_JOBS = ("kernels:centrifuge", "kernels:multiposition", "mpcell:S8", "table1")
# the other rigs' kernels job, then a Monte Carlo cell of their first case (and the sled's series)
RIG_JOBS = {"centrifuge": JOBS, "multiposition": MP_JOBS,
            "sled": ("kernels:sled", "cell:sled:default", "series:default"),
            "lowprec_centrifuge": ("kernels:lowprec_centrifuge", "cell:lowprec_centrifuge:default")}


def rig_raw(rig: str) -> dict:
    """The rig's default-study config (``config/<rig>.yaml``), checked by its Monte Carlo hooks."""
    from platcal.rig import get_rig, rig_config
    return get_rig(rig).montecarlo.check(rig_config({"rigs": {rig: str(ROOT / "config" / f"{rig}.yaml")}}, rig))


class Recorder(event.Listener):
    """(wall s, CPU s, event) of every start and end: CPU s is the compile's own work when
    numba runs one thread (NUMBA_NUM_THREADS=1), wall s includes the machine's load."""

    def __init__(self):
        self.buffer = []

    def on_start(self, ev):
        self.buffer.append((time.perf_counter(), time.process_time(), ev))

    def on_end(self, ev):
        self.buffer.append((time.perf_counter(), time.process_time(), ev))


def run_job(job: str, dwell: float, out: Path) -> None:
    """One job of :data:`JOBS` as the study's rule runs it, files under ``out``."""
    kind, _, arg = job.partition(":")
    if kind == "kernels":
        from platcal.rig import get_rig
        get_rig(arg).montecarlo.warm_kernels(rig_raw(arg))
        return
    if kind == "mpcell":
        from platcal.study.montecarlo import cell_job
        raw = rig_raw("multiposition")
        cell_job("multiposition", raw, arg, 5.0, list(raw["study"]["estimators"]), out / "cell")
        return
    if kind == "cell":  # cell:<rig>:<case>, the study's first noise level, every estimator
        from platcal.rig import get_rig
        from platcal.study.montecarlo import cell_job
        rig, case = arg.split(":")
        hooks, raw = get_rig(rig).montecarlo, rig_raw(rig)
        cell_job(rig, raw, case, hooks.noise_levels(raw)[0], hooks.estimators(raw), out / "cell")
        return
    if kind == "series":  # the sled's one-replicate series of a case (rule sled_series)
        from platcal.rigs.sled.series import write_series
        write_series(rig_raw("sled"), arg, out / "series.csv")
        return
    if kind == "table1":
        from platcal.cli import main as cli
        raw = yaml.safe_load((ROOT / "config" / "centrifuge.yaml").read_text(encoding="utf-8"))
        raw.pop("study", None)  # as the rule's params
        (out / "config.yaml").write_text(yaml.safe_dump(raw), encoding="utf-8")
        cli(["observability", "--config", str(out / "config.yaml"), "--scheme", "table1", "--out", str(out / "o")])
        return
    cfg = study_config(dwell)
    if kind == "sweep":
        from platcal.study.montecarlo import cell_job
        cell_job("centrifuge", cfg, "table1", 10.0, [arg], out)
    elif kind == "compare":
        from platcal.rigs.centrifuge.compare_cells import compare_level_job
        compare_level_job(cfg, float(arg), out)  # every estimator of the level, as the rule runs them
    elif kind == "single":
        from platcal.rigs.centrifuge.study import single_job
        single_job(cfg, out)
    elif kind == "design":
        from platcal.rigs.centrifuge.design import design_scheme_job
        design_scheme_job(cfg, arg, out / f"{arg}.yaml")
    else:
        raise ValueError(job)


def child(job: str, dwell: float) -> None:
    """Run ``job`` recording numba's compile events; print one JSON line of records."""
    rec = Recorder()
    event.register("numba:compile", rec)
    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory() as out:
        run_job(job, dwell, Path(out))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    # pair start/end events; a compile's own time excludes the compiles nested in it
    stack, rows = [], []
    for ts, cs, ev in rec.buffer:
        if ev.is_start:
            stack.append([ts, cs, 0.0, 0.0])
        else:
            start, cstart, nested, cnested = stack.pop()
            dur, cdur = ts - start, cs - cstart
            if stack:
                stack[-1][2] += dur
                stack[-1][3] += cdur
            d = ev.data["dispatcher"]
            rows.append({"fn": f"{d.py_func.__module__}.{d.py_func.__qualname__}",
                         "sig": ", ".join(str(a) for a in ev.data["args"]), "incl": dur, "own": dur - nested,
                         "cpu_incl": cdur, "cpu_own": cdur - cnested, "depth": len(stack)})
    print(json.dumps({"job": job, "wall": wall, "cpu": cpu, "compiles": rows}))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dwell", type=float, default=1.0, help="s per position of every scheme (default 1)")
    ap.add_argument("--rig", choices=tuple(RIG_JOBS), default="centrifuge",
                    help="whose study jobs (default centrifuge: JOBS; multiposition: MP_JOBS; sled and "
                         "lowprec_centrifuge: RIG_JOBS)")
    ap.add_argument("--jobs", nargs="+", choices=sorted({j for jobs in RIG_JOBS.values() for j in jobs}),
                    help="these jobs, in this order")
    ap.add_argument("--json", help="write the raw records here")
    ap.add_argument("--width", type=int, default=120, help="characters of argument types shown (default 120)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a.child, a.dwell)
        return
    load0 = os.getloadavg()[0]
    results = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for job in a.jobs or RIG_JOBS[a.rig]:
            out = subprocess.run([sys.executable, __file__, "--child", job, "--dwell", str(a.dwell)], env=env,
                                 check=True, capture_output=True, text=True).stdout.strip().splitlines()[-1]
            r = json.loads(out)
            results.append(r)
            top = sum(c["cpu_incl"] for c in r["compiles"] if c["depth"] == 0)
            print(f"{job}: {r['wall']:.1f} s wall, {r['cpu']:.1f} s CPU, {top:.1f} s CPU compiling, "
                  f"{len(r['compiles'])} specialisations", flush=True)
    per = defaultdict(list)
    for r in results:
        for c in r["compiles"]:
            per[c["fn"]].append((r["job"], c))
    print()
    print(f"numba compiles per dispatcher (own CPU s and wall s: less nested compiles), cold cache shared by the jobs in "
          f"order; load {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end; "
          f"NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'default')}")
    print("| dispatcher | job | own CPU s | own wall s | argument types |")
    print("|---|---|---:|---:|---|")
    for fn, cs in sorted(per.items(), key=lambda kv: -sum(c["cpu_own"] for _, c in kv[1])):
        for job, c in cs:
            print(f"| {fn} | {job} | {c['cpu_own']:.2f} | {c['own']:.2f} | {c['sig'][:a.width]} |")
    total = sum(c["cpu_own"] for cs in per.values() for _, c in cs)
    print(f"\ntotal: {total:.1f} s CPU compiling, {sum(len(cs) for cs in per.values())} specialisations of "
          f"{len(per)} dispatchers; jobs {sum(r['cpu'] for r in results):.1f} s CPU, "
          f"{sum(r['wall'] for r in results):.1f} s wall")
    if a.json:
        atomic_write_text(a.json, json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
