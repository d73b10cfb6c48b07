"""Benchmark (docs/rocket-sled.md §11 item 8): 20 seeds of the default sled scenario
(85.9 s at 200 Hz) simulated and identified; target < 10 s on 2 cores.

    python benchmarks/bench_sled.py [--seeds 20] [--repeat 3]

Prints the best of ``--repeat`` timings after one warm-up call (numba kernels compiled and
cached on first use; the warm-up time is printed too).
"""

from __future__ import annotations

import argparse
import os
import time

from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.identify import identify, metrics
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.simulate import simulate


def once(cfg, seeds: int) -> tuple[float, float]:
    t0 = time.perf_counter()
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", range(seeds)))
    t1 = time.perf_counter()
    metrics(identify(cfg, sb.traj, sb.f, sb.w), sb.truth)
    return t1 - t0, time.perf_counter() - t1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    cfg = load_config({"rig": "sled"})
    t0 = time.perf_counter()
    once(cfg, 1)
    warm = time.perf_counter() - t0
    runs = [once(cfg, a.seeds) for _ in range(a.repeat)]
    sim, idn = min(runs, key=sum)
    print(f"sled benchmark: {a.seeds} seeds x 85.9 s at 200 Hz (17180 samples), {os.cpu_count()} CPUs visible")
    print(f"  warm-up (1 seed, incl. numba load/compile): {warm:.2f} s")
    print(f"  simulate {sim:.2f} s + identify {idn:.2f} s = {sim + idn:.2f} s "
          f"(best of {a.repeat}; target < 10 s) -> {'OK' if sim + idn < 10 else 'SLOW'}")


if __name__ == "__main__":
    main()
