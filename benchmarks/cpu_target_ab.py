"""numba's code-generation target against the centrifuge EKF's speed, side by side (issue 22 item 1).

numba compiles for the host CPU that LLVM names (``llvmlite.binding.get_host_cpu_name()``, e.g.
``znver4``) with the host's features; ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES`` replace them for
a whole process (every kernel and its cache key). This script asks whether another target makes
the EKF faster on this machine: each ``--variant NAME=CPU:EDITS`` runs in fresh processes with its
own empty numba cache (compiled once, untimed), ``CPU`` the LLVM CPU name (empty: the host's) and
``EDITS`` comma-separated changes to the host's feature string (``-avx512*``: every host feature
matching the pattern turned off; ``+prefer-no-gather``: a feature added). Then ``--rounds``
rounds, the variants' order alternating from round to round (:func:`study_ab.run_order`), each
process timing ``run_ekf`` with the state-major kernel (``lanes=True``, the study's) and with the
default kernel (the registry's ``ekf``, ``identify``'s) on the Table 1 case
(:func:`bench_filter.table1_case`, 6 x ``--dwell`` s, B = ``--batch``, one numba thread), best
process CPU of 3 runs each. The same variant twice (``--variant a= --variant b=``) measures the
machine's own spread between processes.

Every variant's x and P (both kernels) are compared with the first variant's (``np.array_equal``):
a target may change speed, never a number (no fast-math, so no contraction into fused
multiply-adds). Exit status 1 if any differ.

    python benchmarks/cpu_target_ab.py --variant host= --variant znver3=znver3:-avx512* \\
        --variant nogather=:+prefer-no-gather,+prefer-no-scatter --rounds 6
    python benchmarks/cpu_target_ab.py --variant host= --per-cpu --rounds 4
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from study_ab import run_order

CHILD = """
import json, os, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
from bench_filter import table1_case
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf
set_threads(1)
B, dwell, out = int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
scheme, params, settings, z, t = table1_case(B, dwell)
data = EstimatorInput(z, t, scheme.angles_deg, params)
best, res = {}, {}
for lanes in (True, False):  # compile, or load from this variant's cache
    run_ekf(EstimatorInput([a[:1] for a in z], t, scheme.angles_deg, params), settings, lanes=lanes)
for _ in range(3):
    for lanes in (True, False):
        c0 = time.process_time()
        res[lanes] = run_ekf(data, settings, lanes=lanes)
        best[lanes] = min(best.get(lanes, 1e9), (time.process_time() - c0) / B)
if out:
    np.savez(out, xl=res[True].x, Pl=res[True].P, xd=res[False].x, Pd=res[False].P)
import llvmlite.binding as ll
from numba.core import config
print(json.dumps({"lanes": best[True], "default": best[False], "load": os.getloadavg()[0],
                  "cpu": config.CPU_NAME or ll.get_host_cpu_name()}))
"""


def features(edits: str, host: str) -> str:
    """The host's feature string ``host`` (``+a,-b,...``) with ``edits`` applied (``-pattern``:
    matching host features turned off; ``+name``: added)."""
    feats = host.split(",")
    for e in filter(None, edits.split(",")):
        sign, pat = e[0], e[1:]
        if sign not in "+-" or not pat:
            raise SystemExit(f"--variant: feature edit {e!r} must be +name or -pattern")
        if sign == "-":
            feats = [f"-{f[1:]}" if fnmatch.fnmatch(f[1:], pat) else f for f in feats]
        else:
            feats.append(e)
    return ",".join(feats)


def start_child(env_extra: dict, cache: Path, batch: int, dwell: float, out: str, cpu: int | None = None):
    """One timed process of a variant (its environment ``env_extra``, its numba cache ``cache``),
    pinned to ``cpu`` if given; :func:`child_result` waits for it."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", **env_extra)
    here = str(Path(__file__).resolve().parent)
    pin = None if cpu is None else (lambda: os.sched_setaffinity(0, {cpu}))
    return subprocess.Popen([sys.executable, "-c", CHILD, here, str(batch), str(dwell), out], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=pin)


def child_result(proc) -> dict:
    out, err = proc.communicate()
    if proc.returncode:
        raise SystemExit(f"child failed:\n{err[-2000:]}")
    return json.loads(out.strip().splitlines()[-1])


def run_child(env_extra: dict, cache: Path, batch: int, dwell: float, out: str) -> dict:
    return child_result(start_child(env_extra, cache, batch, dwell, out))


def per_cpu(env: dict, cache: Path, batch: int, dwell: float, rounds: int) -> None:
    """Every CPU at once, a process pinned to each, ``rounds`` times (``--per-cpu``)."""
    cpus = sorted(os.sched_getaffinity(0))
    run_child(env, cache, batch, dwell, "")  # compile
    scale = 60.0 / dwell
    print(f"Table 1 case, 6 x {dwell:g} s, B = {batch}, one numba thread per process, one process pinned to "
          f"each CPU at once; CPU s per replicate scaled to 6 x 60 s (x {scale:g})\n")
    print("| round | " + " | ".join(f"CPU {c}: lanes / default" for c in cpus) + " | load |")
    print("|---:|" + "---|" * len(cpus) + "---:|")
    for k in range(rounds):
        res = [child_result(p) for p in [start_child(env, cache, batch, dwell, "", c) for c in cpus]]
        cells = " | ".join(f"{scale * r['lanes']:.4f} / {scale * r['default']:.4f}" for r in res)
        print(f"| {k + 1} | {cells} | {res[0]['load']:.2f} |", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", action="append", required=True, help="NAME=CPU:EDITS (see the module's doc)")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--dwell", type=float, default=20.0, help="s per position")
    ap.add_argument("--per-cpu", action="store_true", help="the first variant pinned to every CPU at once")
    args = ap.parse_args(argv)
    import llvmlite.binding as ll

    host = ll.get_host_cpu_features().flatten()
    variants = {}
    for v in args.variant:
        name, _, spec = v.partition("=")
        cpu, _, edits = spec.partition(":")
        # neither given: numba's own choice of the host's (no variable set)
        variants[name] = ({"NUMBA_CPU_NAME": cpu or ll.get_host_cpu_name(), "NUMBA_CPU_FEATURES": features(edits, host)}
                          if cpu or edits else {})
    names = list(variants)
    times = {n: [] for n in names}
    with tempfile.TemporaryDirectory(prefix="cpu_target_ab-") as tmp:
        tmp = Path(tmp)
        if args.per_cpu:
            per_cpu(variants[names[0]], tmp / "cache", args.batch, args.dwell, args.rounds)
            return
        cpus, loads = {}, []
        for n in names:  # compile each variant once; its x and P for the check
            r = run_child(variants[n], tmp / f"cache-{n}", args.batch, args.dwell, str(tmp / f"{n}.npz"))
            cpus[n] = r["cpu"]
            print(f"{n}: compiled (LLVM CPU {r['cpu']})", flush=True)
        for i, n in enumerate(run_order(names, args.rounds)):
            r = run_child(variants[n], tmp / f"cache-{n}", args.batch, args.dwell, "")
            times[n].append((r["lanes"], r["default"]))
            loads.append(r["load"])
            print(f"round {i // len(names) + 1} {n}: lanes {r['lanes']:.4f} default {r['default']:.4f} "
                  f"CPU s per replicate of 6 x {args.dwell:g} s, load {r['load']:.2f}", flush=True)
        ref = np.load(tmp / f"{names[0]}.npz")
        same = {n: all(np.array_equal(ref[f], np.load(tmp / f"{n}.npz")[f]) for f in ref.files) for n in names}
    scale = 60.0 / args.dwell
    print(f"\nTable 1 case, 6 x {args.dwell:g} s, B = {args.batch}, one numba thread; CPU s per replicate scaled "
          f"to 6 x 60 s (x {scale:g}); load average {min(loads):.2f}-{max(loads):.2f}; host LLVM CPU "
          f"{ll.get_host_cpu_name()}\n")
    print("| variant | LLVM CPU | lanes: each round | lanes median | default: each round | default median | "
          f"x, P equal to {names[0]} |")
    print("|---|---|---|---:|---|---:|---|")
    for n in names:
        ln = [scale * a for a, _ in times[n]]
        df = [scale * b for _, b in times[n]]
        print(f"| {n} | {cpus[n]} | {' '.join(f'{v:.4f}' for v in ln)} | {statistics.median(ln):.4f} | "
              f"{' '.join(f'{v:.4f}' for v in df)} | {statistics.median(df):.4f} | {'yes' if same[n] else 'NO'} |")
    if not all(same.values()):
        sys.exit(1)


if __name__ == "__main__":
    main()
