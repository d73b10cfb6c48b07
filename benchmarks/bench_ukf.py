"""Benchmark of the centrifuge UKF against one EKF pass (issue 9 item 3), per replicate.

On the same simulated data (Table 1 scheme, 6 positions x dwell s, default noise and filter
settings, filter instants 20 ms, 40 ms, ... of each position), times ``run_ekf`` (1 pass) and
``run_ukf`` (the default ``"update"`` variant and the ``"nonlinear"`` one; ``--full`` adds the
2n + 1 ``"all"`` variant on one replicate) for batches of B = 1 and 8, best of ``--repeat`` calls, after a warm-up that
compiles or loads the kernels. Wall and process CPU seconds per replicate are printed; CPU time
shows the work done even when other processes hold the cores. The last line is
``ukf_over_ekf_cpu=<ratio>`` (default variant) at B = 1.

Usage::

    python benchmarks/bench_ukf.py                  # about a minute on 2 idle cores
    python benchmarks/bench_ukf.py --dwell 10 --threads 2 --full
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from platcal.parallel import get_threads, set_threads
from platcal.rigs.centrifuge.base import Centrifuge
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf
from platcal.scheme import check_scheme
from platcal.scheme import TABLE1_POSITIONS
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.rigs.centrifuge.ukf import run_ukf


def best_times(fn, repeat: int) -> tuple[float, float]:
    """Smallest wall and process CPU time (s) of ``repeat`` calls."""
    wall, cpu = np.inf, np.inf
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dwell", type=float, default=60.0, help="s per position")
    ap.add_argument("--threads", type=int, default=1, help="numba threads")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--full", action="store_true", help="also time the 2n + 1 UKF (one replicate)")
    args = ap.parse_args()
    set_threads(args.threads)
    cen = Centrifuge()
    scheme = check_scheme("table1", {"dwell_s": args.dwell, "positions": [list(p) for p in TABLE1_POSITIONS]})
    params = cen.scheme_params(scheme)
    K = scheme.n_positions
    sim = simulate(full_truth(), scheme, params, Noise(), [np.random.SeedSequence([1, i]) for i in range(8)],
                   keep_every=4)
    keep = sim.t > 0
    z = [np.ascontiguousarray(sim.A[:, k][:, keep]) for k in range(K)]
    t = [sim.t[keep]] * K
    fs = FilterSettings(history_every_s=None)
    print(f"load average at start: {os.getloadavg()[0]:.2f}; numba threads {get_threads()}; "
          f"Table 1, {K} x {args.dwell:g} s, {int(keep.sum())} filter instants per position")
    runs = [("ekf (1 pass)", lambda zz: run_ekf(EstimatorInput(zz, t, scheme.angles_deg, params), fs)),
            ("ukf (update)", lambda zz: run_ukf(EstimatorInput(zz, t, scheme.angles_deg, params), fs)),
            ("ukf nonlinear", lambda zz: run_ukf(EstimatorInput(zz, t, scheme.angles_deg, params), fs,
                                                 sigma_points="nonlinear"))]
    for _, fn in runs:  # compile / load from cache
        fn([zk[:1] for zk in z])
        fn(z)
    cpu1 = {}
    for B in (1, 8):
        zb = [zk[:B] for zk in z]
        for name, fn in runs:
            wall, cpu = best_times(lambda: fn(zb), args.repeat if B == 1 else max(1, args.repeat - 1))
            if B == 1:
                cpu1[name] = cpu
            print(f"B = {B}: {name:14s} wall {wall / B:.4f} s, CPU {cpu / B:.4f} s per replicate")
    if args.full:
        z1 = [zk[:1] for zk in z]
        run_ukf(EstimatorInput([zk[:, :2] for zk in z1], [tk[:2] for tk in t], scheme.angles_deg, params), fs,
                sigma_points="all")
        wall, cpu = best_times(lambda: run_ukf(EstimatorInput(z1, t, scheme.angles_deg, params), fs, sigma_points="all"),
                               1)
        print(f"B = 1: ukf (2n+1 all)  wall {wall:.4f} s, CPU {cpu:.4f} s per replicate "
              f"({cpu / cpu1['ekf (1 pass)']:.1f}x one EKF pass)")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    print(f"ukf_nonlinear_over_ekf_cpu={cpu1['ukf nonlinear'] / cpu1['ekf (1 pass)']:.2f}")
    print(f"ukf_over_ekf_cpu={cpu1['ukf (update)'] / cpu1['ekf (1 pass)']:.2f}")


if __name__ == "__main__":
    main()
