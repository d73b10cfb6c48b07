"""``platcal simulate | identify | observability`` for ``rig: multiposition``.

``platcal simulate --seed N`` writes replicate N (default 0) of the study's Monte Carlo cell of
that scheme at the config's ``noise.sigma_a_ug``: the same ``SeedSequence(seed, spawn_key=
(stable_key(scheme), round(1000 sigma_a), N))`` as the generic runner's (docs/multiposition-1g.md
§16), so a record can be identified alone and compared with the study's replicate.

Every option and input is checked (InputError naming the field, exit status 2) before any
work starts or any file is written; outputs are written atomically.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ...estimation.consistency import estimate_problems
from ...errors import InputError
from ...rig import option
from ...io import atomic_files, check_writable, json_text
from .estimators import estimate, variant_choice
from .filter import nees, replicate_seeds, simulate
from .model import coef_names, group_of, unit_of
from .observability import evaluate
from .record import read_record, to_frame, write_record



def cmd_simulate(cfg, args) -> int:
    scheme = cfg.scheme(args.scheme)
    if args.seed is not None and args.seed < 0:
        raise InputError("--seed", "must be a whole number >= 0")
    replicate = 0 if args.seed is None else int(args.seed)
    check_writable(args.out, "--out")
    t0 = time.perf_counter()
    # --seed N is replicate N of the study's cell (this scheme, noise.sigma_a_ug): the same SeedSequence
    t, phi, z = simulate(cfg, scheme, replicate_seeds(cfg, scheme.name, [replicate]), noise_free=bool(args.noise_free))
    write_record(to_frame(scheme, t, phi[0], z[0]), args.out)
    what = "noise-free" if args.noise_free else (f"replicate {replicate} of the Monte Carlo cell {scheme.name}, "
                                                 f"sigma_a {cfg.sigma_a_ug:g} ug (root seed {cfg.seed})")
    print(f"platcal simulate: multiposition scheme {scheme.name!r}, {scheme.n_positions} positions x "
          f"{scheme.dwell_s:g} s, {what} -> {args.out} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def identify(cfg, rec, choice=None):
    """``(estimate (nc,), covariance (nc, nc), mean NIS, skipped updates)`` of one record with the
    estimator of ``choice`` (:class:`.estimators.FilterChoice`; default the config's ``filter``)."""
    tk, Z, nk = rec.packed()
    r = estimate(cfg, choice or cfg.filter_choice(), rec.cmd_deg, tk, Z, nk=nk)
    return r.coef[0], r.cov[0], float(r.mean_nis[0]), int(r.failed_updates[0])


def run_problems(est: np.ndarray, P: np.ndarray, nis: float, failed_updates: int = 0) -> list[str]:
    """Why an EKF run cannot be trusted (empty if it can): updates skipped because S was not
    positive definite, non-finite estimates, a covariance that is not finite or not positive
    definite, a non-finite NIS (an update that went wrong). Messages in plain numbers and
    coefficient names."""
    out = []
    if failed_updates:
        out.append(f"{failed_updates} measurement update(s) failed (innovation covariance S not positive definite)")
    out += estimate_problems(est, P, coef_names())
    if not np.isfinite(nis):
        out.append("the normalised innovations are not finite")
    return out


def cmd_identify(cfg, args) -> int:
    choice = cfg.filter_choice() if args.estimator is None else variant_choice(cfg, args.estimator)
    scheme = cfg.scheme(args.scheme) if args.scheme else None
    check_writable(args.out, "--out", folder=True)
    rec, scheme = read_record(args.data, scheme, ts=cfg.ts, max_gap_s=float(cfg.raw["record"]["max_gap_s"]))
    t0 = time.perf_counter()
    est, P, nis, failed = identify(cfg, rec, choice)
    seconds = time.perf_counter() - t0
    problems = run_problems(est, P, nis, failed)
    if problems:
        print(f"platcal identify: error: the multiposition EKF run over {args.data} failed: {'; '.join(problems)}. "
              f"Nothing was written to {args.out}. Check the record's units (Ax, Ay, Az in g, angles in deg) "
              "and the config's noise and filter settings.", file=sys.stderr)
        return 1
    used = rec.samples_used()
    names = coef_names()
    sig = np.sqrt(np.diag(P))
    df = pd.DataFrame({"name": names, "unit": [unit_of(n) for n in names], "group": [group_of(n) for n in names],
                       "estimate": est, "sigma": sig})
    summary = {"rig": "multiposition", "scheme": scheme.name, "n_states": len(names) + 3,
               "estimator": choice.estimator, "passes": choice.passes, "estimator_options": choice.options,
               "positions": int(len(rec.t)), "samples": int(sum(used.values())),
               "samples_used_per_position": {str(k): v for k, v in used.items()}, "mean_nis": nis,
               "seconds": seconds}
    use_truth = rec.has_truth and not args.no_truth
    if use_truth:
        tr = cfg.truth()
        df["truth"] = tr
        df["error"] = est - tr
        df["rel_err_pct"] = (est - tr) / np.abs(tr) * 100.0
        g = df["group"] == "gyro"
        summary.update({"nees": float(nees(est[None], P[None], tr)[0]), "nees_dof": len(names),
                        "max_abs_rel_err_pct_gyro": float(df.loc[g, "rel_err_pct"].abs().max()),
                        "max_abs_rel_err_pct_accel": float(df.loc[~g, "rel_err_pct"].abs().max())})
    out = Path(args.out)
    with atomic_files(out) as tmp:  # both files land together, summary.json last
        df.to_csv(tmp("estimates.csv"), index=False)
        tmp("summary.json").write_text(json_text(summary))
    msg = (f"platcal identify: multiposition 27-state {choice.label}, {min(used.values())}-"
           f"{max(used.values())} samples per position, {seconds:.2f} s -> {out}")
    if use_truth:
        msg += (f"; max |rel err| gyro {summary['max_abs_rel_err_pct_gyro']:.3f} %, accel "
                f"{summary['max_abs_rel_err_pct_accel']:.4f} %, NEES {summary['nees']:.1f} (dof 24)")
    print(msg, file=sys.stderr)
    return 0


def cmd_observability(cfg, args) -> int:
    scheme = cfg.scheme(args.scheme)
    check_writable(args.out, "--out", folder=True)
    t0 = time.perf_counter()
    res = evaluate(cfg, scheme)
    res["seconds"] = time.perf_counter() - t0
    out = Path(args.out)
    with atomic_files(out) as tmp:
        pd.DataFrame(res["coefficients"]).to_csv(tmp("coefficients.csv"), index=False)
        tmp("observability.json").write_text(json_text(res))
    v = res["verdict"]
    print(f"platcal observability: multiposition scheme {scheme.name!r}: static rank {res['static_rank']}, "
          f"exact Lie rank {res['exact_rank_nominal']}/{res['exact_rank_truth']} of {res['n_states']}, max "
          f"sigma/|truth| {res['max_rel_sigma_pct']:.3g} % -> {v['decision'].upper()}: {'; '.join(v['reasons'])}"
          f" -> {out} ({res['seconds']:.1f} s)", file=sys.stderr)
    return 0


COMMANDS = {"simulate": cmd_simulate, "identify": cmd_identify, "observability": cmd_observability}

SCHEME = option("--scheme", default=None, help="scheme name of the config or built in (S8, SIX, T1, TET4, ...); "
                                              "default: the config's default_scheme")
OPTIONS = {"simulate": (SCHEME,), "observability": (SCHEME,),
           "identify": (SCHEME, option("--estimator", default=None,
                                       help="ekf or iekf, or a study.estimators name (ekf1, ekf2, iekf)"))}
"""The rig's own options (``--seed`` of simulate: replicate N of the study's Monte Carlo cell)."""
