"""UKF against the EKF on the same simulated records (issue 9 item 3; Su et al.'s claim).

On the Table 1 scheme of ``config/centrifuge.yaml`` (dwell, noise, filter settings as configured
unless overridden), simulates ``--replicates`` runs (platcal.rigs.centrifuge.simulate.simulate,
as identify.simulate_identify calls it) and runs every estimator of ``--estimators`` on the same
records, at the filter instants ``period, 2 period, ...`` (the sample at each reset instant is
not used). Prints, per estimator: mean NEES of the 45 coefficients (45 expected), the share of
runs beyond the 99.9 % chi-square(45) bound (80.1) and inside the 95 % band, the largest gyro and
accelerometer RMS relative error over the replicates (%), the median of the runs' largest gyro
error, mean NIS, failed updates, and wall / CPU seconds per run (one numba thread, batches of
``--batch``). ``--compare-full N`` also runs the full UKF (``sigma_points="all"``, 2n + 1 sigma
points everywhere) on the first N replicates and prints, for every one-pass UKF estimator given,
its largest difference from the full one in units of the full one's sigma, the sigma ratios, and
the NEES of both.

Estimators: ``ekf1``, ``ekf2`` (EKF, 1 or 2 passes); ``ukf`` (run_ukf's default), ``ukf2`` (2
passes), with ``-upd``, ``-nl``, ``-all`` for the ``sigma_points`` variant ("update",
"nonlinear", "all") and ``:a=<alpha>/b=<beta>/k=<kappa>`` for other transform parameters (k may
be ``none`` = 3 - n), e.g. ``ukf-nl:a=1e-3/b=2/k=0``.

Usage::

    python benchmarks/ukf_study.py --replicates 200 --sigma-a 10
    python benchmarks/ukf_study.py --replicates 100 --sigma-a 5 --estimators ekf1,ekf2,ukf
    python benchmarks/ukf_study.py --replicates 4 --compare-full 4 --estimators ukf
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from platcal.estimation.consistency import nees, nees_band
from platcal.model.instruments import N_IDENTIFIED
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.rigs.centrifuge.ukf import run_ukf

ROOT = Path(__file__).resolve().parents[1]


def parse_estimator(spec: str):
    """(label, function, settings overrides, options) of an estimator name:
    ``ekf1``/``ekf2``, or ``ukf[2][-upd|-nl|-all][:a=<alpha>/b=<beta>/k=<kappa>]``."""
    if spec in ("ekf1", "ekf2"):
        return spec, run_ekf, {"passes": int(spec[-1])}, {}
    if not spec.startswith("ukf"):
        raise SystemExit(f"unknown estimator {spec!r}")
    head, _, params = spec.partition(":")
    name, _, variant = head.partition("-")
    if name not in ("ukf", "ukf2") or variant not in ("", "upd", "nl", "all"):
        raise SystemExit(f"unknown estimator {spec!r}")
    opts = {}
    if variant:
        opts["sigma_points"] = {"upd": "update", "nl": "nonlinear", "all": "all"}[variant]
    for part in params.split("/") if params else []:
        key, val = part.split("=")
        opts[{"a": "alpha", "b": "beta", "k": "kappa"}[key]] = None if val == "none" else float(val)
    return spec, run_ukf, {"passes": 2 if name == "ukf2" else 1}, opts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default=str(ROOT / "config" / "centrifuge.yaml"))
    ap.add_argument("--scheme", default="table1")
    ap.add_argument("--replicates", type=int, default=50)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--sigma-a", type=float, default=None, help="ug per sample (truth and filter)")
    ap.add_argument("--dwell", type=float, default=None, help="s per position (default: the scheme's)")
    ap.add_argument("--seed", type=int, default=None, help="default: the config's seed")
    ap.add_argument("--estimators", default="ekf1,ekf2,ukf")
    ap.add_argument("--compare-full", type=int, default=0)
    ap.add_argument("--json", default=None, help="write the numbers here too")
    args = ap.parse_args()
    set_threads(1)

    study = load_config(args.config)
    scheme = study.schemes[args.scheme]
    if args.dwell is not None:
        scheme = replace(scheme, dwell_s=float(args.dwell))
    noise = study.noise if args.sigma_a is None else replace(study.noise, sigma_a_ug=args.sigma_a)
    fs = replace(study.filter, sigma_a_ug=noise.sigma_a_ug, history_every_s=None)
    params = study.centrifuge.scheme_params(scheme)
    truth = study.truth
    seed = study.seed if args.seed is None else args.seed
    root = np.random.SeedSequence([seed, 9, int(round(noise.sigma_a_ug * 1000))])
    seeds = root.spawn(args.replicates)
    K = scheme.n_positions
    specs = [parse_estimator(s) for s in args.estimators.split(",") if s]
    nc = N_IDENTIFIED
    res = {label: {"coef": [], "P": [], "nis": [], "bad": [], "wall": 0.0, "cpu": 0.0}
           for label, *_ in specs}
    full_diff = []
    sim_s = 0.0
    # compile (or load from numba's cache) every kernel before any timing
    warm = simulate(truth, scheme, params, noise, seeds[:1], sample_s=study.sample_s, keep_every=study.keep_every)
    for label, fn, over, opts in specs:
        fn([warm.A[:, k, 1:3] for k in range(K)], [warm.t[1:3]] * K, scheme.angles_deg, params,
           replace(fs, **over), **opts)
    for b0 in range(0, args.replicates, args.batch):
        bs = seeds[b0:b0 + args.batch]
        t0 = time.perf_counter()
        sim = simulate(truth, scheme, params, noise, bs, sample_s=study.sample_s, keep_every=study.keep_every)
        sim_s += time.perf_counter() - t0
        keep = sim.t > 0  # the filter instants period, 2 period, ...: not the reset instant
        z = [np.ascontiguousarray(sim.A[:, k][:, keep]) for k in range(K)]
        t = [sim.t[keep]] * K
        ests = {}
        for label, fn, over, opts in specs:
            s = replace(fs, **over)
            w0, c0 = time.perf_counter(), time.process_time()
            est = fn(z, t, scheme.angles_deg, params, s, **opts)
            res[label]["wall"] += time.perf_counter() - w0
            res[label]["cpu"] += time.process_time() - c0
            res[label]["coef"].append(est.coef)
            res[label]["P"].append(est.P[:, :nc, :nc])
            res[label]["nis"].append(est.mean_nis)
            res[label]["bad"].append(est.failed_updates)
            ests[label] = est
        n_full = max(0, min(len(bs), args.compare_full - b0))
        if n_full:
            sl = slice(0, n_full)
            c0 = time.process_time()
            full = run_ukf(EstimatorInput([zk[sl] for zk in z], t, scheme.angles_deg, params), replace(fs, passes=1),
                           sigma_points="all")
            full_cpu = (time.process_time() - c0) / n_full
            sig = full.coef_sigma
            for label, _, over, _ in specs:
                if over["passes"] != 1 or not label.startswith("ukf") or label.startswith("ukf2") \
                        or label == "ukf-all":
                    continue
                red = ests[label]
                full_diff.append({
                    "label": label,
                    "max_diff_sigma": float(np.max(np.abs(red.coef[sl] - full.coef) / sig)),
                    "sigma_ratio_min": float(np.min(red.coef_sigma[sl] / sig)),
                    "sigma_ratio_max": float(np.max(red.coef_sigma[sl] / sig)),
                    "nees_full": nees(full.coef, full.P[:, :nc, :nc], truth[None, :nc]).tolist(),
                    "nees_other": nees(red.coef[sl], red.P[sl, :nc, :nc], truth[None, :nc]).tolist(),
                    "cpu_s_per_run_full": full_cpu,
                })
        print(f"# {min(b0 + args.batch, args.replicates)}/{args.replicates} replicates", flush=True)

    lo, hi = nees_band(nc)
    bound = float(chi2.ppf(0.999, nc))
    gyro = np.array([n.startswith("D") for n in study.filter.state_names[:nc]])
    out = {"scheme": scheme.name, "dwell_s": scheme.dwell_s, "sigma_a_ug": noise.sigma_a_ug,
           "replicates": args.replicates, "seed": seed, "simulate_s_per_run": sim_s / args.replicates,
           "estimators": {}}
    print(f"\nTable 1 scheme, dwell {scheme.dwell_s:g} s, sigma_a {noise.sigma_a_ug:g} ug, "
          f"{args.replicates} replicates (seed {seed}); NEES dof {nc}, 95 % band {lo:.1f}-{hi:.1f}, "
          f"99.9 % bound {bound:.1f}")
    print("| estimator | mean NEES | median NEES | > 80.1 | in 95 % band | max gyro RMS rel err % | "
          "max accel RMS rel err % | median run max gyro % | mean NIS | failed | wall s/run | CPU s/run |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    base_cpu = None
    for label, *_ in specs:
        r = res[label]
        coef = np.concatenate(r["coef"])
        P = np.concatenate(r["P"])
        e = nees(coef, P, truth[None, :nc])
        rel = (coef - truth[:nc]) / truth[:nc] * 100.0
        rms = np.sqrt(np.mean(rel**2, axis=0))
        row = {
            "mean_nees": float(e.mean()), "median_nees": float(np.median(e)),
            "share_beyond_999": float(np.mean(e > bound)), "share_in_95": float(np.mean((e >= lo) & (e <= hi))),
            "max_gyro_rms_rel_pct": float(rms[gyro].max()), "max_accel_rms_rel_pct": float(rms[~gyro].max()),
            "worst_gyro": study.filter.state_names[int(np.flatnonzero(gyro)[np.argmax(rms[gyro])])],
            "median_run_max_gyro_pct": float(np.median(np.abs(rel[:, gyro]).max(axis=1))),
            "mean_nis": float(np.concatenate(r["nis"]).mean()), "failed": int(np.concatenate(r["bad"]).sum()),
            "wall_s_per_run": r["wall"] / args.replicates, "cpu_s_per_run": r["cpu"] / args.replicates,
        }
        out["estimators"][label] = row
        print(f"| {label} | {row['mean_nees']:.1f} | {row['median_nees']:.1f} | {row['share_beyond_999']:.1%} | "
              f"{row['share_in_95']:.1%} | {row['max_gyro_rms_rel_pct']:.2f} ({row['worst_gyro']}) | "
              f"{row['max_accel_rms_rel_pct']:.3f} | {row['median_run_max_gyro_pct']:.2f} | {row['mean_nis']:.3f} | "
              f"{row['failed']} | {row['wall_s_per_run']:.3f} | {row['cpu_s_per_run']:.3f} |")
        if label == "ekf1":
            base_cpu = row["cpu_s_per_run"]
    if base_cpu:
        print("CPU per run relative to one EKF pass: "
              + ", ".join(f"{k} {v['cpu_s_per_run'] / base_cpu:.2f}x" for k, v in out["estimators"].items()))
    if full_diff:
        out["full_vs_other"] = full_diff
        cpu_full = np.mean([d["cpu_s_per_run_full"] for d in full_diff])
        print(f"full UKF (2n+1 everywhere) on the first {args.compare_full} replicates, CPU {cpu_full:.2f} s/run")
        for label in dict.fromkeys(d["label"] for d in full_diff):
            ds = [d for d in full_diff if d["label"] == label]
            ef = np.concatenate([d["nees_full"] for d in ds])
            eo = np.concatenate([d["nees_other"] for d in ds])
            print(f"  {label} vs full: largest |difference| {max(d['max_diff_sigma'] for d in ds):.4f} sigma, "
                  f"sigma ratio {min(d['sigma_ratio_min'] for d in ds):.5f}-{max(d['sigma_ratio_max'] for d in ds):.5f}; "
                  f"mean NEES {eo.mean():.2f} vs {ef.mean():.2f}, beyond {bound:.1f}: {np.mean(eo > bound):.1%} vs "
                  f"{np.mean(ef > bound):.1%}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
