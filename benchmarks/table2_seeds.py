"""The README's Table 2 regression figures: Table 1 scheme, default config, seeds 0-4.

For each seed (``SeedSequence(seed)``): the largest gyro and accelerometer relative error of the
paper's one-pass EKF, and the NEES of the 45 coefficients after one pass, after a 1 s warm-up pass
(``filter.warmup_s: 1``) and after two passes (docs/centrifuge-model.md §9, §14). The same runs as
``tests/test_ekf.py::test_regression_of_table2_over_seeds``.

    python benchmarks/table2_seeds.py [--config config/centrifuge.yaml]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from platcal.estimation.consistency import nees
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.identify import simulate_identify


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config/centrifuge.yaml")
    args = ap.parse_args()
    study = load_config(args.config)
    scheme = study.schemes["table1"]
    seeds = [np.random.SeedSequence(s) for s in range(5)]
    truth = study.truth[:45]
    base = replace(study.filter, history_every_s=None, estimator="ekf", estimator_options=())
    two = simulate_identify(study, scheme, seeds, replace(base, passes=2))
    warm = simulate_identify(study, scheme, seeds, replace(base, passes=1, estimator_options=(("warmup_s", 1.0),)))
    rel1 = (two.pass_x[0] - truth) / truth * 100
    print("seed | largest gyro rel err 1 pass % | largest accel rel err % | NEES 1 pass | NEES warm-up 1 s | NEES 2 passes")
    n1 = nees(two.pass_x[0], two.pass_P[0], truth[None])
    nw = nees(warm.coef, warm.P[:, :45, :45], truth[None])
    n2 = nees(two.pass_x[1], two.pass_P[1], truth[None])
    for s in range(5):
        print(f"{s} | {np.abs(rel1[s, :27]).max():.2f} | {np.abs(rel1[s, 27:]).max():.3f} | {n1[s]:.1f} | {nw[s]:.1f} | {n2[s]:.1f}")
    print(f"median largest gyro rel err (1 pass): {np.median(np.abs(rel1[:, :27]).max(axis=1)):.2f} %")


if __name__ == "__main__":
    main()
