"""How closely a clean low-precision-centrifuge record's fE, fN agree with the derivative of its own
VE, VN (the plausibility check's F_SCALE_TOL, docs/lowprec-centrifuge.md §10): the largest
|ratio - 1| of ``specific_force_scale`` over seeds 0..N-1 of every platform's runs (the records
``platcal simulate --platform P --run R --seed N`` writes, in memory).

    python benchmarks/lowprec_force_agreement.py [--seeds 100]
"""

from __future__ import annotations

import argparse

import numpy as np

from platcal.io import read_config
from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY
from platcal.rigs.lowprec_centrifuge.record import F_SCALE_TOL, Record, specific_force_scale
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config/lowprec_centrifuge.yaml")
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    study = get_rig("lowprec_centrifuge").load_config(read_config(args.config))
    noise = study.residuals["accel_noise_ug_rthz"]
    for platform in study.platform_names():
        for run in study.run_names(platform):
            worst = 0.0
            for a in range(0, args.seeds, 10):
                ns = list(range(a, min(a + 10, args.seeds)))
                seeds = [replicate_seed(study.seed, SEED_KEY, noise, n) for n in ns]
                rb = simulate_batch(study, platform, run, seeds, ns)
                for s in range(len(ns)):
                    rec = Record(t=rb.prof.t, v=rb.v_ind[s], p=rb.p_ind[s], psi=rb.psi[s], f=rb.f_meas[s],
                                 schedule=rb.prof.schedule, truth=None)
                    worst = max(worst, float(np.max(np.abs(specific_force_scale(rec) - 1.0))))
            print(f"{platform} {run}: largest |fE, fN / d(VE, VN)/dt - 1| over {args.seeds} seeds {worst:.3g} "
                  f"(tolerance {F_SCALE_TOL:g})", flush=True)


if __name__ == "__main__":
    main()
