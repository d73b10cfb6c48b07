"""The centrifuge's ``simulate`` and UKF, before against after (issue 22 items 1 and 4), in one run.

Times, in fresh processes that alternate between two source trees (``--before``, ``--after``:
the ``src`` directories of two checkouts), one numba thread as in the default study's jobs, on
the Table 1 scheme (6 x 60 s, default noise, seeds ``[2017, i]`` as ``bench_filter.py``):

* ``simulate`` at B = 8 and B = 64 (outputs kept one sample in four, the filter's period);
* the UKF (registry kind ``ukf``, default options) at B = 8, the study's batch;

as process CPU seconds per replicate (best of ``--repeat`` calls after a warm-up that compiles
or loads the kernels), with the load average printed at every process. Each process also
saves its simulated record and UKF estimate; the driver checks that the two trees' are
bit-identical (``np.array_equal``) and prints what the default study's centrifuge cells would
save: every Monte Carlo replicate simulates (sweep 36 cells x 20, comparison 16 cells x 100,
all 6 x 60 s) and the comparison's UKF cell runs 100 replicates.

Usage::

    python benchmarks/bench_sim_ukf.py --before /path/to/main/src --after src --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

SWEEP_REPLICATES = 36 * 20
COMPARE_REPLICATES = 16 * 100
UKF_REPLICATES = 100


def worker(out_npz: str, repeat: int) -> None:
    """Time this process's platcal (the one on PYTHONPATH) and print one JSON line."""
    import platcal
    from platcal.parallel import set_threads
    from platcal.rigs.centrifuge.base import Centrifuge
    from platcal.rigs.centrifuge.catalogue import full_truth
    from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, first_instant
    from platcal.rigs.centrifuge.estimators import KINDS
    from platcal.rigs.centrifuge.simulate import Noise, simulate
    from platcal.scheme import TABLE1_POSITIONS, check_scheme

    set_threads(1)
    settings = FilterSettings()
    scheme = check_scheme("table1", {"dwell_s": 60.0, "positions": [list(p) for p in TABLE1_POSITIONS]})
    params = Centrifuge().scheme_params(scheme)
    truth = full_truth()
    seeds = [np.random.SeedSequence([2017, i]) for i in range(64)]
    keep = int(round(settings.period_s / 0.005))
    K = scheme.n_positions
    i0 = first_instant(settings.update_at_reset)

    def sim(B):
        return simulate(truth, scheme, params, Noise(), seeds[:B], keep_every=keep)

    def ukf(data, B):
        inp = EstimatorInput([data.A[:B, k, i0:] for k in range(K)], [data.t[i0:]] * K, scheme.angles_deg, params)
        return KINDS["ukf"].run(inp, settings)

    def best_cpu(fn, B):
        best, out = np.inf, None
        for _ in range(repeat):
            c0 = time.process_time()
            out = fn()
            best = min(best, time.process_time() - c0)
        return best / B, out

    # warm-up: compile or load every kernel timed below
    warm = sim(2)
    ukf(warm, 1)
    res = {"platcal": os.path.dirname(platcal.__file__), "load": os.getloadavg()[0]}
    res["sim8"], data8 = best_cpu(lambda: sim(8), 8)
    res["sim64"], data64 = best_cpu(lambda: sim(64), 64)
    res["ukf8"], est = best_cpu(lambda: ukf(data8, 8), 8)
    res["load_end"] = os.getloadavg()[0]
    np.savez(out_npz, A8=data8.A, ang8=data8.angles, A64=data64.A, x=est.x, P=est.P, hx=est.history_x,
             hs=est.history_sigma, nis=est.mean_nis)
    print(json.dumps(res))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", required=True, help="src directory of the tree before the change")
    ap.add_argument("--after", required=True, help="src directory of the tree after the change")
    ap.add_argument("--rounds", type=int, default=3, help="processes per tree, alternating (3)")
    ap.add_argument("--repeat", type=int, default=2, help="timed calls per figure and process (best)")
    ap.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(args.worker, args.repeat)
        return
    trees = {"before": os.path.abspath(args.before), "after": os.path.abspath(args.after)}
    for name, path in trees.items():
        if not os.path.isdir(os.path.join(path, "platcal")):
            print(f"--{name}: {path} holds no platcal package; give a checkout's src directory", file=sys.stderr)
            sys.exit(2)
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    runs = {"before": [], "after": []}
    with tempfile.TemporaryDirectory() as tmp:
        outs = {}
        for rnd in range(args.rounds):
            for name, path in trees.items():
                outs[name] = os.path.join(tmp, f"{name}.npz")
                proc = subprocess.run([sys.executable, os.path.abspath(__file__), "--before", ".", "--after", ".",
                                       "--repeat", str(args.repeat), "--worker", outs[name]],
                                      env=dict(env, PYTHONPATH=path), capture_output=True, text=True, check=True)
                r = json.loads(proc.stdout.strip().splitlines()[-1])
                runs[name].append(r)
                print(f"round {rnd + 1} {name:6s} ({r['platcal']}): simulate B=8 {r['sim8']:.4f}, B=64 "
                      f"{r['sim64']:.4f}, ukf B=8 {r['ukf8']:.4f} CPU s/replicate; load {r['load']:.2f} -> "
                      f"{r['load_end']:.2f}", flush=True)
        a, b = np.load(outs["before"]), np.load(outs["after"])
        same = {k: bool(np.array_equal(a[k], b[k])) for k in a.files}
    print(f"bit-identical (np.array_equal, before vs after): {same}")
    print("\n| figure (CPU s per replicate, best of the rounds, 1 thread) | before | after | after / before |")
    print("|---|---:|---:|---:|")
    best = {name: {k: min(r[k] for r in rs) for k in ("sim8", "sim64", "ukf8")} for name, rs in runs.items()}
    for key, label in (("sim8", "simulate, B = 8"), ("sim64", "simulate, B = 64"), ("ukf8", "UKF, B = 8")):
        x, y = best["before"][key], best["after"][key]
        print(f"| {label} | {x:.4f} | {y:.4f} | {y / x:.2f} |")
    d_sim = best["before"]["sim8"] - best["after"]["sim8"]
    d_ukf = best["before"]["ukf8"] - best["after"]["ukf8"]
    n_sim = SWEEP_REPLICATES + COMPARE_REPLICATES
    print(f"\ndefault study, centrifuge cells: {n_sim} replicates simulated x {d_sim:.4f} s = {n_sim * d_sim:.1f} "
          f"CPU s; the UKF cell: {UKF_REPLICATES} x {d_ukf:.4f} s = {UKF_REPLICATES * d_ukf:.1f} CPU s; "
          f"together {n_sim * d_sim + UKF_REPLICATES * d_ukf:.1f} CPU s")
    if not all(same.values()):
        sys.exit(1)


if __name__ == "__main__":
    main()
