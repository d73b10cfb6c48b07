"""Estimators of the multiposition rig compared (issue 9 item 5; docs/multiposition-1g.md §16).

For each scheme (default S8, T1, TET4) at sigma_a = 5 ug and replicates 0..N-1 (default 20; the
SeedSequences of the study's cells, so the statistics equal the study's table): the EKF
of §9 with one and two passes and the Gauss-Newton iterated EKF (config defaults of
``filter.iekf``), on the same simulated records. Prints, per scheme and estimator: mean NEES of
the 24 coefficients (24 expected) and the share above the chi-square(24) 99.9 % bound (51.2),
median and worst largest gyro / accelerometer relative error per seed, measurement
linearisations per update and the wall time per run (one thread, numba compile excluded).

    python benchmarks/bench_multiposition_estimators.py [--seeds 20] [--schemes S8,T1,TET4]
"""

import argparse
import time

import numpy as np

from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.estimators import FilterChoice, estimate
from platcal.rigs.multiposition.filter import nees, simulate
from platcal.rigs.multiposition.model import coef_names


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--schemes", default="S8,T1,TET4")
    ap.add_argument("--iterations", type=int, default=None)
    ap.add_argument("--tolerance", type=float, default=None)
    a = ap.parse_args()
    cfg = load_config({"rig": "multiposition"})
    io = dict(cfg.filter_choice().options if cfg.estimator == "iekf" else {"iterations": 3, "tolerance": 0.01})
    io.update({k: v for k, v in (("iterations", a.iterations), ("tolerance", a.tolerance)) if v is not None})
    choices = {"ekf1": FilterChoice("ekf", 1, {}), "ekf2": FilterChoice("ekf", 2, {}),
               "iekf": FilterChoice("iekf", 1, io)}
    gyro = np.array([n.startswith("D") for n in coef_names()])
    tr = cfg.truth()
    warm = cfg.scheme("TET4")
    t, _, z = simulate(cfg, warm, [0])
    for ch in choices.values():  # compile outside the timing
        estimate(cfg, ch, warm.angles_deg, t[:5], z[:, :, :5], threads=1)
    print(f"sigma_a {cfg.sigma_a_ug:g} ug, {a.seeds} seeds, iekf options {io}")
    print("scheme estimator  meanNEES  >51.2  gyro_med  gyro_worst  acc_med  acc_worst  lin/upd  s/run")
    for name in a.schemes.split(","):
        s = cfg.scheme(name)
        t, _, z = simulate(cfg, s, list(range(a.seeds)), threads=1)
        for label, ch in choices.items():
            t0 = time.perf_counter()
            r = estimate(cfg, ch, s.angles_deg, t, z, threads=1)
            sec = (time.perf_counter() - t0) / a.seeds
            ne = nees(r.coef, r.cov, tr)
            rel = np.abs(r.coef - tr) / np.abs(tr) * 100
            g, ac = rel[:, gyro].max(1), rel[:, ~gyro].max(1)
            print(f"{name:6s} {label:9s} {ne.mean():8.1f} {np.mean(ne > 51.18) * 100:5.0f}% {np.median(g):8.2f}% "
                  f"{g.max():9.2f}% {np.median(ac):7.3f}% {ac.max():8.3f}% {r.linearisations.mean():8.2f} {sec:6.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
