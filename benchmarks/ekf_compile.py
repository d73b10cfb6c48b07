"""Issue 22 item 1: the cold numba compile of the centrifuge EKF's state-major kernel
(``run_ekf(..., lanes=True)``, :mod:`platcal.rigs.centrifuge.ekf_lanes`) against the default
kernel's, each on an otherwise warm cache.

For each kernel K, a fresh process on an empty ``NUMBA_CACHE_DIR`` first runs the *other* kernel
(compiling everything the two share: the model, the simulator, the filter's set-up), then a second
fresh process on that cache runs K: its CPU time is K's own cold compile (plus a run of a few
samples). Both kernels run at B = 1 and B = 8 on 2 numba threads, so that the serial and the
threaded entry points are compiled, as in a Monte Carlo cell of the study. A third process runs K
again on the full cache: the load from disk. Prints CPU s and the load average.

    python benchmarks/ekf_compile.py
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

KERNELS = {"default": False, "lanes": True}


def child(kernel: str) -> dict:
    """Runs ``kernel`` on a 6 x 0.2 s Table 1 case at B = 1 and 8; CPU s of the runs alone."""
    from bench_filter import table1_case
    from platcal.parallel import set_threads
    from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf

    set_threads(2)
    scheme, params, settings, z, t = table1_case(8, 0.2)
    c0 = time.process_time()
    for B in (1, 8):
        run_ekf(EstimatorInput([zk[:B] for zk in z], t, scheme.angles_deg, params), settings,
                lanes=KERNELS[kernel])
    return {"cpu": time.process_time() - c0}


def run_child(kernel: str, cache: str) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, __file__, "--child", kernel], env=env, check=True, capture_output=True,
                         text=True, cwd=os.path.dirname(os.path.abspath(__file__))).stdout
    return json.loads(out.strip().splitlines()[-1])["cpu"]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--child", choices=list(KERNELS), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(child(a.child)))
        return
    load0 = os.getloadavg()[0]
    rows = []
    for kernel in KERNELS:
        other = next(k for k in KERNELS if k != kernel)
        with tempfile.TemporaryDirectory() as cache:
            shared = run_child(other, cache)
            cold = run_child(kernel, cache)
            warm = run_child(kernel, cache)
        rows.append((kernel, other, shared, cold, warm))
    print(f"centrifuge EKF kernels: own cold compile on a cache holding everything else; fresh processes; "
          f"load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end")
    print("| kernel | cold CPU s (own compile + run) | warm CPU s (load + run) | the other kernel's cold run first, CPU s |")
    print("|---|---:|---:|---:|")
    for kernel, other, shared, cold, warm in rows:
        print(f"| {kernel} | {cold:.1f} | {warm:.2f} | {other}: {shared:.1f} |")


if __name__ == "__main__":
    main()
