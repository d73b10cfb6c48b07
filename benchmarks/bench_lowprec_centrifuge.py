"""Speed of the low-precision centrifuge rig (docs/lowprec-centrifuge.md §11 item 7).

One scenario = 2 platforms x 3 runs (2 proposed + traditional) x 20 seeds: every truth
simulation (with the 4 lock-step variants), every proposed filter pass and every traditional
solve, plus the cross-validation table. Target: under 30 s on 2 cores.

    python benchmarks/bench_lowprec_centrifuge.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.study import run_scenario
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    a = ap.parse_args()
    study = load_config({"rig": "lowprec_centrifuge"})
    t0 = time.perf_counter()
    simulate_batch(load_config({"rig": "lowprec_centrifuge", "runs": {"P1": {"r": [1, 1]}, "P2": {"r": [1, 1]}},
                                "profile": {"rest_first_s": 1, "rest_between_s": 1}}), "P1", "r", [0])
    warm = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = run_scenario(study, np.arange(a.seeds))
    dt = time.perf_counter() - t0
    n = res["cross"].groupby(["platform", "method", "cal_run", "eval_run"]).ngroups
    print(f"numba load/compile warm-up: {warm:.1f} s")
    print(f"one scenario (2 platforms x 3 runs x {a.seeds} seeds, {n} cross-validation cells): {dt:.1f} s "
          f"({'under' if dt < 30 else 'OVER'} the 30 s target)")


if __name__ == "__main__":
    main()
