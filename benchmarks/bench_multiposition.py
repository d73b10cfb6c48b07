"""Speed of the multiposition rig (docs/multiposition-1g.md §15 item 7).

The 20-seed Monte Carlo of S8 (8 positions x 60 s, one pass, 27 states) at sigma_a = 5 ug,
after a warm-up call (numba compile excluded). Target: under 10 s on 2 cores. Two figures: the
kernels alone (simulation and the batched EKF, replicates 0..N-1 of the study's cell) and the
study's own path, the generic runner's cell (:func:`platcal.study.montecarlo.run_cell`: seeds,
simulation, EKF, tidy tables) for the same replicates.

    python benchmarks/bench_multiposition.py [--threads 2] [--seeds 20]
"""

import argparse
import time

from platcal.rig import get_rig
from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.filter import nees, run_ekf, simulate
from platcal.study.montecarlo import run_cell


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seeds", type=int, default=20)
    a = ap.parse_args()
    cfg = load_config({"rig": "multiposition"})
    s8 = cfg.scheme("S8")
    warm = cfg.scheme("TET4")
    t, _, z = simulate(cfg, warm, [0])
    run_ekf(cfg, warm.angles_deg, t[:5], z[:, :, :5], threads=a.threads)
    t0 = time.perf_counter()
    t, _, z = simulate(cfg, s8, list(range(a.seeds)), threads=a.threads)
    t1 = time.perf_counter()
    c, P, _ = run_ekf(cfg, s8.angles_deg, t, z, passes=1, threads=a.threads)
    t2 = time.perf_counter()
    steps = a.seeds * s8.n_positions * (t.size - 1)
    print(f"multiposition S8 Monte Carlo, {a.seeds} seeds x 8 positions x 60 s, one pass, {a.threads} thread(s): "
          f"simulate {t1 - t0:.2f} s + EKF {t2 - t1:.2f} s = {t2 - t0:.2f} s "
          f"({(t2 - t1) / steps * 1e6 * a.threads:.1f} us per filter step per core); "
          f"mean NEES {nees(c, P, cfg.truth()).mean():.1f}")
    rig = get_rig("multiposition")
    mc = rig.montecarlo.check({"rig": "multiposition"})
    t0 = time.perf_counter()
    _, runs, timing = run_cell(rig, mc, rig.montecarlo.case(mc, "S8"), 5.0, "ekf1", replicates=a.seeds,
                               threads=a.threads, batch=a.seeds)
    t1 = time.perf_counter()
    print(f"generic runner cell S8 / 5 ug / ekf1, {a.seeds} replicates, {a.threads} thread(s): {t1 - t0:.2f} s "
          f"(target < 10 s); mean NEES {runs['nees'].mean():.1f}")


if __name__ == "__main__":
    main()
