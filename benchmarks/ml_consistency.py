"""Batch maximum likelihood (MAP) against the one- and two-pass EKF on the same records (issue 9 item 3).

On the config's Table 1 scheme (``config/centrifuge.yaml``), for each accelerometer noise level,
simulates R replicates (truth and filter noise equal, the config's ARW and sigma_set), keeps the
filter instants ``t = period, 2 period, ... < dwell`` (the spec's timing: no sample at the reset
instant) and runs, on the same records:

* ``ekf1``, ``ekf2``: :func:`platcal.rigs.centrifuge.ekf.run_ekf` with 1 and 2 passes;
* ``ml``: :func:`platcal.rigs.centrifuge.ml.solve_ml` from a cold start (every coefficient 0),
  and again from the one-pass EKF's estimate (steps counted; the estimates agree).

Prints per estimator: mean NEES of the 45 coefficients, share beyond the 99.9 % chi2(45) bound
(80.1), share inside the two-sided 95 % band, the largest gyro and accelerometer RMS relative
error over replicates (%), and the CPU / wall s per run; for the ML the Gauss-Newton steps.
Then the ML covariance against observability's Cramer-Rao bound (the covariance-only EKF by the
position decomposition, :func:`platcal.rigs.centrifuge.observability.scheme_covariance`), on the
same times (``t = 0, period, ...``, the observability module's) at the truth, and the ML's
covariance at its estimates against the same bound.

Seeds: ``SeedSequence(config seed, spawn_key=('ml_consistency', sigma_a in nano-g))`` spawned into
R replicates. Usage::

    python benchmarks/ml_consistency.py --replicates 100 --sigma 10 5 [--threads 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
from scipy.stats import chi2

from platcal.estimation.consistency import nees, nees_band
from platcal.model.instruments import FULL_NAMES
from platcal.rigs.centrifuge import observability as ob
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf
from platcal.rigs.centrifuge.ml import _Problem, solve_ml
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.seeding import seed_sequence

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, *a, **kw):
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn(*a, **kw)
    return out, time.process_time() - c0, time.perf_counter() - w0


def summarise(coef, P, truth, cpu, wall):
    """NEES and error statistics of (R, 45) estimates with (R, 45, 45) covariances."""
    e = nees(coef, P, truth[None])
    lo, hi = nees_band(45)
    rel = (coef - truth[None]) / truth[None] * 100.0
    rms = np.sqrt(np.mean(rel**2, axis=0))
    gyro = np.array([n.startswith("D") for n in FULL_NAMES[:45]])
    return {"mean_nees": float(e.mean()), "median_nees": float(np.median(e)),
            "share_beyond_80.1": float(np.mean(e > chi2.ppf(0.999, 45))),
            "share_in_95_band": float(np.mean((e >= lo) & (e <= hi))),
            "max_gyro_rms_rel_pct": float(rms[gyro].max()),
            "max_accel_rms_rel_pct": float(rms[~gyro].max()),
            "cpu_s_per_run": cpu, "wall_s_per_run": wall}


def crb_comparison(study, scheme, fs, params):
    """ML information at the truth vs the covariance-only EKF's bound, same times (t from 0)."""
    setup = ob.setup_from_study(study, scheme.dwell_s, sigma_a_ug=fs.sigma_a_ug)
    crb = ob.scheme_covariance(setup, scheme.angles_deg)[0]
    K = scheme.n_positions
    t = [setup.times] * K
    z = [np.zeros((1, len(setup.times), 3))] * K
    prob = _Problem(z, t, scheme.angles_deg, params, setup.filter)
    theta = prob.start(study.truth[None, :45])
    N, _, _ = prob.evaluate(theta, np.array([0]))
    s = prob.prior_sigma
    A = N[0] * np.outer(s, s) + np.eye(prob.n)
    cov = np.linalg.inv(A) * np.outer(s, s)
    return crb, cov[:45, :45]


def warm_up(study, scheme, params):
    """Load every compiled kernel (serial and threaded) before anything is timed."""
    K = scheme.n_positions
    fs = replace(study.filter, history_every_s=None)
    sim = simulate(study.truth, scheme, params, study.noise, np.random.SeedSequence(0).spawn(2),
                   sample_s=study.sample_s, keep_every=study.keep_every)
    for B in (1, 2):
        z = [np.ascontiguousarray(sim.A[:B, k, 1:20]) for k in range(K)]
        t = [sim.t[1:20]] * K
        run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), fs)
        solve_ml(EstimatorInput(z, t, scheme.angles_deg, params), fs, start="zero", max_iter=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "config" / "centrifuge.yaml"))
    ap.add_argument("--replicates", type=int, default=100)
    ap.add_argument("--sigma", type=float, nargs="+", default=[10.0, 5.0], help="sigma_a, ug")
    ap.add_argument("--batch", type=int, default=10)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--damping", action="store_true", help="Levenberg-Marquardt for the ML")
    ap.add_argument("--tol", type=float, default=1e-2, help="ML Newton-decrement tolerance, posterior sigmas")
    ap.add_argument("--json", default=None, help="write the numbers here too")
    ap.add_argument("--no-arw-variant", action="store_true",
                    help="also run the ML with the filter's ARW set to 0 (process noise ignored)")
    ap.add_argument("--variants", nargs="*", default=["ml_c16:16:converge", "ml_c16_1step:16:one-step"],
                    help="further ML variants name:coarse:final (run from a cold start)")
    args = ap.parse_args(argv)
    numba.set_num_threads(args.threads)
    study = load_config(args.config)
    scheme = study.schemes["table1"]
    params = study.centrifuge.scheme_params(scheme)
    K = scheme.n_positions
    truth = study.truth[:45]
    results = {}
    warm_up(study, scheme, params)
    print(f"load average at start: {os.getloadavg()}")
    for sig in args.sigma:
        noise = replace(study.noise, sigma_a_ug=sig)
        fs = replace(study.filter, sigma_a_ug=sig, history_every_s=None)
        root = seed_sequence(study.seed, "ml_consistency", int(round(sig * 1000)))
        seeds = root.spawn(args.replicates)
        variants = [(v.split(":")[0], int(v.split(":")[1]), v.split(":")[2]) for v in args.variants]
        names = (("ekf1", "ekf2", "ml") + (("ml_no_arw",) if args.no_arw_variant else ())
                 + tuple(v[0] for v in variants))
        vsteps = {v[0]: [] for v in variants}
        acc = {k: {"coef": [], "P": [], "cpu": 0.0, "wall": 0.0} for k in names}
        steps_cold, steps_ekf, conv, ml_ekf_cpu, nis, ml_diff, ml_sig = [], [], [], 0.0, [], [], []
        for a in range(0, args.replicates, args.batch):
            sd = seeds[a:a + args.batch]
            sim = simulate(study.truth, scheme, params, Noise(**vars(noise)), sd, sample_s=study.sample_s,
                           keep_every=study.keep_every)
            z = [np.ascontiguousarray(sim.A[:, k, 1:]) for k in range(K)]
            t = [sim.t[1:]] * K
            e1, c, w = timed(run_ekf, z, t, scheme.angles_deg, params, fs)
            acc["ekf1"]["coef"].append(e1.coef); acc["ekf1"]["P"].append(e1.P[:, :45, :45])
            acc["ekf1"]["cpu"] += c; acc["ekf1"]["wall"] += w
            e2, c, w = timed(run_ekf, z, t, scheme.angles_deg, params, replace(fs, passes=2))
            acc["ekf2"]["coef"].append(e2.coef); acc["ekf2"]["P"].append(e2.P[:, :45, :45])
            acc["ekf2"]["cpu"] += c; acc["ekf2"]["wall"] += w
            (em, info), c, w = timed(solve_ml, z, t, scheme.angles_deg, params, fs, start="zero",
                                     damping=args.damping, tol=args.tol)
            acc["ml"]["coef"].append(em.coef); acc["ml"]["P"].append(em.P[:, :45, :45])
            acc["ml"]["cpu"] += c; acc["ml"]["wall"] += w
            steps_cold.append(info.steps); conv.append(info.converged); nis.append(em.mean_nis)
            (em2, info2), c, _ = timed(solve_ml, z, t, scheme.angles_deg, params, fs, start=e1.coef,
                                       damping=args.damping, tol=args.tol)
            ml_ekf_cpu += c
            steps_ekf.append(info2.steps)
            ml_diff.append(np.max(np.abs(em2.coef - em.coef) / em.coef_sigma, axis=1))
            ml_sig.append(em.coef_sigma)
            if args.no_arw_variant:
                (en, _), c, w = timed(solve_ml, z, t, scheme.angles_deg, params, replace(fs, arw_deg_rth=0.0),
                                      start="zero", damping=args.damping, tol=args.tol)
                acc["ml_no_arw"]["coef"].append(en.coef); acc["ml_no_arw"]["P"].append(en.P[:, :45, :45])
                acc["ml_no_arw"]["cpu"] += c; acc["ml_no_arw"]["wall"] += w
            for name, coarse, final in variants:
                (ev, iv), c, w = timed(solve_ml, z, t, scheme.angles_deg, params, fs, start="zero",
                                       damping=args.damping, tol=args.tol, coarse=coarse, final=final)
                acc[name]["coef"].append(ev.coef); acc[name]["P"].append(ev.P[:, :45, :45])
                acc[name]["cpu"] += c; acc[name]["wall"] += w
                vsteps[name].append(np.stack([iv.coarse_steps, iv.steps, iv.converged], axis=1))
            print(f"sigma_a {sig:g} ug: {a + len(sd)}/{args.replicates} replicates", flush=True)
        R = args.replicates
        res = {}
        for k, v in acc.items():
            res[k] = summarise(np.concatenate(v["coef"]), np.concatenate(v["P"]), truth, v["cpu"] / R, v["wall"] / R)
        sc, se = np.concatenate(steps_cold), np.concatenate(steps_ekf)
        res["ml"].update({
            "steps_cold_mean": float(sc.mean()), "steps_cold_max": int(sc.max()),
            "steps_from_ekf_mean": float(se.mean()), "steps_from_ekf_max": int(se.max()),
            "converged_share": float(np.concatenate(conv).mean()),
            "cpu_s_per_run_from_ekf_incl_ekf_pass": ml_ekf_cpu / R + res["ekf1"]["cpu_s_per_run"],
            "max_diff_cold_vs_ekf_start_sigma": float(np.concatenate(ml_diff).max()),
            "mean_nis": float(np.concatenate(nis).mean()),
            "cost_vs_ekf1_pass": res["ml"]["cpu_s_per_run"] / res["ekf1"]["cpu_s_per_run"],
        })
        for name, _, _ in variants:
            v = np.concatenate(vsteps[name])
            res[name].update({"coarse_steps_mean": float(v[:, 0].mean()), "steps_mean": float(v[:, 1].mean()),
                              "steps_max": int(v[:, 1].max()), "converged_share": float(v[:, 2].mean()),
                              "cost_vs_ekf1_pass": res[name]["cpu_s_per_run"] / res["ekf1"]["cpu_s_per_run"]})
        crb, cov_truth = crb_comparison(study, scheme, fs, params)
        s_crb = np.sqrt(np.diag(crb))
        ratio_truth = np.sqrt(np.diag(cov_truth)) / s_crb
        ratio_est = np.concatenate(ml_sig) / s_crb[None]
        res["crb"] = {"ml_at_truth_over_crb_sigma_min": float(ratio_truth.min()),
                      "ml_at_truth_over_crb_sigma_max": float(ratio_truth.max()),
                      "ml_at_estimates_over_crb_sigma_min": float(ratio_est.min()),
                      "ml_at_estimates_over_crb_sigma_max": float(ratio_est.max())}
        results[f"{sig:g}"] = res
        print(f"\n== sigma_a {sig:g} ug, {R} replicates, table1, threads {args.threads} ==")
        print(f"{'estimator':9s} {'meanNEES':>9s} {'>80.1':>7s} {'in95%':>7s} {'gyroRMS%':>9s} "
              f"{'accRMS%':>8s} {'CPU s':>7s} {'wall s':>7s}")
        for k in names:
            r = res[k]
            print(f"{k:9s} {r['mean_nees']:9.2f} {r['share_beyond_80.1']:7.3f} {r['share_in_95_band']:7.3f} "
                  f"{r['max_gyro_rms_rel_pct']:9.3f} {r['max_accel_rms_rel_pct']:8.4f} "
                  f"{r['cpu_s_per_run']:7.3f} {r['wall_s_per_run']:7.3f}")
        m = res["ml"]
        print(f"ml steps cold mean {m['steps_cold_mean']:.2f} max {m['steps_cold_max']}; from ekf1 mean "
              f"{m['steps_from_ekf_mean']:.2f} max {m['steps_from_ekf_max']}; converged {m['converged_share']:.3f}; "
              f"cold vs ekf start max diff {m['max_diff_cold_vs_ekf_start_sigma']:.2e} sigma; mean NIS "
              f"{m['mean_nis']:.4f}")
        print(f"ml CPU per run = {m['cost_vs_ekf1_pass']:.2f} x one EKF pass (cold start); from the EKF: "
              f"{m['cpu_s_per_run_from_ekf_incl_ekf_pass']:.3f} s incl. the EKF pass")
        for name, _, _ in variants:
            r = res[name]
            print(f"{name}: coarse steps mean {r['coarse_steps_mean']:.2f}, full steps mean {r['steps_mean']:.2f} "
                  f"max {r['steps_max']}, converged {r['converged_share']:.3f}, CPU = {r['cost_vs_ekf1_pass']:.2f} x "
                  "one EKF pass")
        c = res["crb"]
        print(f"ML sigma / CRB sigma: at the truth (t from 0) {c['ml_at_truth_over_crb_sigma_min']:.6f} .. "
              f"{c['ml_at_truth_over_crb_sigma_max']:.6f}; at the estimates (t from period) "
              f"{c['ml_at_estimates_over_crb_sigma_min']:.5f} .. {c['ml_at_estimates_over_crb_sigma_max']:.5f}")
    print(f"load average at end: {os.getloadavg()}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
