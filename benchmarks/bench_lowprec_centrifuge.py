"""Speed of the low-precision centrifuge rig (docs/lowprec-centrifuge.md §11 item 7).

One scenario = its two cells on the generic Monte Carlo runner (proposed, traditional), 2
platforms x 20 seeds: every truth simulation (with the 4 lock-step variants; the traditional cell
simulates the proposed runs too, to evaluate on them), every proposed filter pass and every
traditional solve, plus the cross-validation metrics. Target: under 30 s on 2 cores.

    python benchmarks/bench_lowprec_centrifuge.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from platcal.rig import get_rig
from platcal.study.montecarlo import run_cell, warm_up


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    a = ap.parse_args()
    rig = get_rig("lowprec_centrifuge")
    h = rig.montecarlo
    cfg = h.check({"rig": "lowprec_centrifuge"})
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:  # the study's warm-up: every kernel the cells run, compiled or loaded
        warm_up(rig.name, cfg, Path(tmp) / "warmup.json")
    warm = time.perf_counter() - t0
    load0 = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    runs = [run_cell(rig, cfg, h.case(cfg, "default"), h.noise_levels(cfg)[0], e, replicates=a.seeds)[1]
            for e in h.estimators(cfg)]
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    n = len({c.rsplit("|", 2)[0] for r in runs for c in r.columns if c.count("|") == 4})
    print(f"numba load/compile warm-up (platcal.study.montecarlo.warm_up): {warm:.1f} s wall")
    print(f"one scenario (2 platforms x 3 runs x {a.seeds} seeds, {n} cross-validation cells): {dt:.1f} s wall "
          f"({'under' if dt < 30 else 'OVER'} the 30 s target), {cpu:.1f} s CPU; load average {load0:.2f} at start, "
          f"{os.getloadavg()[0]:.2f} at end, {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
