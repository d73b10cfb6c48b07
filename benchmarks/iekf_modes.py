"""Which iterated EKF (issue 9 item 3): NEES, tail, largest-gyro error and cost of EKF variants.

On the Table 1 scheme (60 s dwell, the default config), ``--replicates`` runs per noise level
(replicate r draws from ``SeedSequence(seed, spawn_key=(stable_key('table1'), 1000 sigma_a, r))``,
the Monte Carlo's seeds), batches of ``--batch``, ``--threads`` numba threads, it runs each
variant on the same simulated data and prints, per variant and noise level: mean NEES (45 dof),
share of runs inside the chi2(45) 95 % band and beyond the 99.9 % bound 80.1, the largest-gyro
and largest-accelerometer RMS relative error (%, RMS over runs per coefficient, then the
largest), wall and CPU seconds per run (filter only). ``--diagnose`` adds the numbers behind
"why": the NEES of a noise-free run (the linearisation's own error), the NEES after each
position (prefix runs), and runs with the gyro noise or the setting error switched off.

Usage::

    python benchmarks/iekf_modes.py --replicates 100 --levels 10 5 --out iekf_modes.csv
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import chi2

from platcal.estimation.consistency import nees
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.ekf import EstimatorInput, first_instant, run_ekf, run_iekf
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.study.montecarlo import replicate_seed

CONFIG = Path(__file__).resolve().parents[1] / "config" / "centrifuge.yaml"

VARIANTS = {
    "ekf1": (run_ekf, {}, 1),
    "ekf2": (run_ekf, {}, 2),
    "iekf2": (run_iekf, {"iterations": 2}, 1),
    "iekf3": (run_iekf, {"iterations": 3, "tol": 0.01}, 1),
    "iekf3_first1s": (run_iekf, {"iterations": 3, "tol": 0.01, "until_s": 1.0}, 1),
    "iekf3_first10s": (run_iekf, {"iterations": 3, "tol": 0.01, "until_s": 10.0}, 1),
    "iekf3_ratio1e-4": (run_iekf, {"iterations": 3, "tol": 0.01, "ratio": 1e-4}, 1),
    "iekf5": (run_iekf, {"iterations": 5, "tol": 0.01}, 1),
    "ekf_warm1s": (run_ekf, {"warmup_s": 1.0}, 1),
    "ekf_warm2s": (run_ekf, {"warmup_s": 2.0}, 1),
    "ekf_warm5s": (run_ekf, {"warmup_s": 5.0}, 1),
    "ekf_warm10s": (run_ekf, {"warmup_s": 10.0}, 1),
}


def simulate_cell(study, scheme, level, replicates, noise=None):
    noise = noise or replace(study.noise, sigma_a_ug=float(level))
    seeds = [replicate_seed(study.seed, scheme.name, level, r) for r in range(replicates)]
    params = study.centrifuge.scheme_params(scheme)
    return simulate(study.truth, scheme, params, noise, seeds, sample_s=study.sample_s,
                    keep_every=study.keep_every), params


def run_variant(fn, opts, passes, fs, sim, scheme, params, batch, positions=None):
    K = scheme.n_positions if positions is None else positions
    i0 = first_instant(fs.update_at_reset)
    B = sim.A.shape[0]
    x, P, wall, cpu = [], [], 0.0, 0.0
    for a in range(0, B, batch):
        z = [sim.A[a:a + batch, k, i0:] for k in range(K)]
        t0, c0 = time.perf_counter(), time.process_time()
        est = fn(EstimatorInput(z, [sim.t[i0:]] * K, scheme.angles_deg[:K], params[:K] if params.ndim == 2 else params),
                 replace(fs, passes=passes), **opts)
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        x.append(est.coef)
        P.append(est.P[:, :est.n_coef, :est.n_coef])
    return np.concatenate(x), np.concatenate(P), wall / B, cpu / B


def metrics(x, P, truth):
    n = nees(x, P, truth[None])
    rel = (x - truth) / truth * 100.0
    rms = np.sqrt(np.mean(rel**2, axis=0))
    lo, hi = chi2.ppf([0.025, 0.975], 45)
    return {"mean_nees": float(n.mean()), "median_nees": float(np.median(n)),
            "inside_95_pct": float(np.mean((n >= lo) & (n <= hi)) * 100),
            "beyond_999_pct": float(np.mean(n > chi2.ppf(0.999, 45)) * 100),
            "gyro_rms_rel_pct": float(rms[:27].max()), "accel_rms_rel_pct": float(rms[27:].max())}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--levels", type=float, nargs="+", default=[10.0, 5.0])
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS))
    ap.add_argument("--diagnose", action="store_true")
    ap.add_argument("--out", default=None, help="CSV of the table")
    args = ap.parse_args(argv)
    set_threads(args.threads)
    study = load_config(CONFIG)
    scheme = study.schemes["table1"]
    truth = study.truth[:45]
    fs0 = replace(study.filter, history_every_s=None)
    print(f"table1 6 x {scheme.dwell_s:g} s, {args.replicates} replicates, batch {args.batch}, "
          f"threads {args.threads}, load average {os.getloadavg()[0]:.2f}")
    rows = []
    for level in args.levels:
        sim, params = simulate_cell(study, scheme, level, args.replicates)
        fs = replace(fs0, sigma_a_ug=float(level))
        for name in args.variants:
            fn, opts, passes = VARIANTS[name]
            x, P, wall, cpu = run_variant(fn, opts, passes, fs, sim, scheme, params, args.batch)
            row = {"variant": name, "sigma_a_ug": level, **metrics(x, P, truth), "wall_s_per_run": wall,
                   "cpu_s_per_run": cpu}
            rows.append(row)
            print(" | ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()),
                  flush=True)
        if args.diagnose:
            diagnose(study, scheme, level, fs, sim, params, args, truth)
    df = pd.DataFrame(rows)
    print(df.to_markdown(index=False, floatfmt=".4g"))
    if args.out:
        df.to_csv(args.out, index=False)


def diagnose(study, scheme, level, fs, sim, params, args, truth):
    """The numbers behind the over-confidence of the one-pass EKF at this noise level."""
    print(f"-- diagnosis at {level:g} ug")
    # linearisation error alone: noise-free data, the filter's own noise model
    nf, _ = simulate_cell(study, scheme, level, 1, noise=Noise(0.0, 0.0, 0.0))
    for name in ("ekf1", "ekf2", "iekf3", "ekf_warm5s"):
        fn, opts, passes = VARIANTS[name]
        x, P, _, _ = run_variant(fn, opts, passes, fs, nf, scheme, params, 1)
        print(f"noise-free {name}: NEES {float(nees(x, P, truth[None])[0]):.1f}")
    # after each position: prefix runs
    for K in range(1, scheme.n_positions + 1):
        out = {}
        for name in ("ekf1", "ekf2", "iekf3"):
            fn, opts, passes = VARIANTS[name]
            x, P, _, _ = run_variant(fn, opts, passes, fs, sim, scheme, params, args.batch, positions=K)
            out[name] = metrics(x, P, truth)
        print(f"after position {K}: ekf1 mean NEES {out['ekf1']['mean_nees']:.1f} (beyond 80.1: "
              f"{out['ekf1']['beyond_999_pct']:.0f} %), ekf2 mean NEES {out['ekf2']['mean_nees']:.1f}, "
              f"iekf3 mean NEES {out['iekf3']['mean_nees']:.1f}", flush=True)
    # the noise sources one at a time (filter model unchanged except what is switched off)
    for label, noise, fsx in [
            ("no gyro noise (ARW 0 in truth and filter)", replace(study.noise, sigma_a_ug=level, arw_deg_rth=0.0),
             replace(fs, arw_deg_rth=0.0)),
            ("no setting error (truth 0, filter sigma_set 0.01 arcsec)",
             replace(study.noise, sigma_a_ug=level, sigma_set_arcsec=0.0), replace(fs, sigma_set_arcsec=0.01)),
            ("update at the reset instant too (before issue 9)", None, replace(fs, update_at_reset=True))]:
        s2, _ = simulate_cell(study, scheme, level, args.replicates, noise=noise)
        x, P, _, _ = run_variant(run_ekf, {}, 1, fsx, s2, scheme, params, args.batch)
        m = metrics(x, P, truth)
        print(f"ekf1, {label}: mean NEES {m['mean_nees']:.1f}, beyond 80.1 {m['beyond_999_pct']:.0f} %, "
              f"largest gyro RMS {m['gyro_rms_rel_pct']:.2f} %", flush=True)


if __name__ == "__main__":
    main()
