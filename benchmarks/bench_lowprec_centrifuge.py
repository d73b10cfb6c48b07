"""Speed of the low-precision centrifuge rig (docs/lowprec-centrifuge.md §11 item 7).

One scenario = its two cells on the generic Monte Carlo runner (proposed, traditional), 2
platforms x 20 seeds: every truth simulation (with the 4 lock-step variants; the proposed cell
simulates the proposed runs once for both methods, the traditional cell the traditional run),
every proposed filter pass and every traditional solve, plus the cross-validation metrics
(:func:`~platcal.rigs.lowprec_centrifuge.montecarlo.study_frames`, where the traditional
calibrations are evaluated on the proposed cell's records). Target: under 30 s on 2 cores.
Each cell's CPU seconds are printed too (the default study runs 11 scenarios' cells as jobs,
issue 22 item 4), best of ``--repeat`` runs after the first.

    python benchmarks/bench_lowprec_centrifuge.py [--seeds 20] [--repeat 1]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import pandas as pd

from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.montecarlo import study_frames
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import run_cell


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=1, help="extra runs of each cell for its best CPU time")
    a = ap.parse_args()
    rig = get_rig("lowprec_centrifuge")
    h = rig.montecarlo
    cfg = h.check({"rig": "lowprec_centrifuge"})
    t0 = time.perf_counter()
    simulate_batch(load_config({"rig": "lowprec_centrifuge", "runs": {"P1": {"r": [1, 1]}, "P2": {"r": [1, 1]}},
                                "profile": {"rest_first_s": 1, "rest_between_s": 1}}), "P1", "r",
                   [np.random.SeedSequence(0)])
    warm = time.perf_counter() - t0
    load0 = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    cells, cell_cpu = [], {}
    for e in h.estimators(cfg):
        c1 = time.process_time()
        cells.append(run_cell(rig, cfg, h.case(cfg, "default"), h.noise_levels(cfg)[0], e, replicates=a.seeds))
        cell_cpu[e] = [time.process_time() - c1]
    cross, _ = study_frames(load_config(cfg), ["default"], pd.concat([c[0] for c in cells]),
                            pd.concat([c[1] for c in cells]))
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    n = len(cross.groupby(["platform", "cal_run", "eval_run"]))
    for e in h.estimators(cfg):
        for _ in range(a.repeat):
            c1 = time.process_time()
            run_cell(rig, cfg, h.case(cfg, "default"), h.noise_levels(cfg)[0], e, replicates=a.seeds)
            cell_cpu[e].append(time.process_time() - c1)
    print(f"numba load/compile warm-up: {warm:.1f} s")
    print("cell CPU s (first run, then repeats; best): " + "; ".join(
        f"{e} {' '.join(f'{c:.2f}' for c in v)} (best {min(v):.2f})" for e, v in cell_cpu.items()))
    # CPU seconds and the load beside the wall time: on a shared machine the wall time alone says little
    print(f"one scenario (2 platforms x 3 runs x {a.seeds} seeds, {n} cross-validation cells): {dt:.1f} s wall "
          f"({'under' if dt < 30 else 'OVER'} the 30 s target), {cpu:.1f} s CPU; load average {load0:.2f} at start, "
          f"{os.getloadavg()[0]:.2f} at end, {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
