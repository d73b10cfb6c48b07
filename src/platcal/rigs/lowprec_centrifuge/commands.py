"""``platcal simulate`` and ``platcal identify`` for ``rig: lowprec_centrifuge`` (docs/lowprec-centrifuge.md §10).

simulate: ``--platform P --run run1|run2|traditional [--seed N] [--noise-free] --out rec.csv``;
``--seed N`` writes replicate N (default 0) of the study's Monte Carlo cells (root seed: the
config's ``seed``; the same record in every centrifuge scenario's cells, §9, §12)
identify: ``--data rec.csv --out DIR [--method proposed|traditional] [--no-truth]``
Every option is checked before any work; options of other rigs are refused by name.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ...estimation.consistency import estimate_problems
from ...errors import InputError
from ...rig import option
from ...io import atomic_files, check_writable, json_text
from ...study.montecarlo import replicate_seed
from .config import COEFFS, Study
from .montecarlo import SEED_KEY
from .proposed import identify_proposed
from .record import (check_against_config, check_out_path, estimates_frame, read_record, record_frame, truth_json,
                     write_record)
from .traditional import identify_traditional
from .truth import simulate_batch

METHODS = ("proposed", "traditional")


def simulate(study: Study, args) -> int:
    if args.platform is None:
        raise InputError("--platform", f"required: one of {study.platform_names()}")
    if args.platform not in study.platforms:
        raise InputError("--platform", f"unknown platform {args.platform!r}; use one of {study.platform_names()}")
    runs = study.run_names(args.platform)
    if args.run is None or args.run not in runs:
        raise InputError("--run", f"{'required' if args.run is None else 'unknown run ' + repr(args.run)}: "
                                  f"one of {runs}")
    if args.seed is not None and args.seed < 0:
        raise InputError("--seed", "must be a whole number >= 0")
    check_out_path(args.out)
    check_writable(args.out, "--out")
    seed = 0 if args.seed is None else int(args.seed)
    t0 = time.perf_counter()
    # --seed N is replicate N of the study's cells (any scenario: they share the seeds), root seed `seed`
    ss = replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], seed)
    rb = simulate_batch(study, args.platform, args.run, [ss], [seed], keep_phi=True,
                        noise_free=bool(args.noise_free))
    write_record(record_frame(rb), truth_json(rb, study), args.out)
    print(f"platcal simulate: lowprec_centrifuge {args.platform} {args.run} ({', '.join(f'{a:g}' for a in rb.prof.levels)}"
          f" g), {'noise-free' if args.noise_free else f'seed {seed}'}, {rb.prof.t[-1]:.0f} s -> {args.out} "
          f"({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def identify(study: Study, args) -> int:
    method = args.method or "proposed"
    if method not in METHODS:
        raise InputError("--method", f"unknown method {method!r}; use one of {list(METHODS)}")
    check_writable(args.out, "--out", folder=True)
    max_gap = float(study.raw["record"]["max_gap_s"])
    rec = read_record(args.data, use_truth=not args.no_truth, rate_hz=study.rate_hz, max_gap_s=max_gap)
    found = check_against_config(rec, study, method, max_gap)
    t0 = time.perf_counter()
    arm = study.centrifuge.arm_m
    if method == "proposed":
        res = identify_proposed(rec.t, rec.v[None], rec.p[None], rec.psi[None], rec.f, rec.schedule, arm,
                                study.latitude_deg)
        est, sig = res.coeffs[0], res.sigmas[0]
        extra = f"{int(res.n_windows[0])} windows"
        problems = run_problems(res.x[0], res.P[0])
        found["windows"] = int(res.n_windows[0])
    else:
        est = identify_traditional(rec.t, rec.v[None], rec.psi[None], rec.schedule,
                                   study.traditional["levels_g"], arm)[0]
        sig = np.full(4, np.nan)   # eq. (2) gives no uncertainty
        extra = "eq. (2)"
        problems = run_problems(est, None)
    if problems:
        print(f"platcal identify: error: the lowprec_centrifuge {method} identification over {args.data} failed: "
              f"{'; '.join(problems)}. Nothing was written to {args.out}. Check the record's units (VE, VN in "
              "m/s, heading_deg in deg) and its schedule.", file=sys.stderr)
        return 1
    seconds = time.perf_counter() - t0
    truth = rec.truth["coefficients"] if rec.truth and "coefficients" in rec.truth else None
    df = estimates_frame(COEFFS, est, sig, truth)
    summary = {"rig": "lowprec_centrifuge", "method": method, "samples": int(rec.t.size), **found,
               "coefficients": dict(zip(COEFFS, map(float, est))), "truth_known": truth is not None,
               "seconds": round(seconds, 3)}
    with atomic_files(args.out) as tmp:   # both files land together, summary.json last
        df.to_csv(tmp("estimates.csv"), index=False)
        tmp("summary.json").write_text(json_text(summary))
    print(f"platcal identify: lowprec_centrifuge {method} ({extra}), {seconds:.2f} s -> {args.out}; "
          + ", ".join(f"{n} {e:.3f}" for n, e in zip(COEFFS, est)), file=sys.stderr)
    return 0


def run_problems(x: np.ndarray, P: np.ndarray | None) -> list[str]:
    """Why an identification cannot be trusted (empty if it can): non-finite estimates, a
    covariance (proposed filter) that is not finite or not positive definite."""
    return estimate_problems(x, P)

OPTIONS = {
    "simulate": (option("--platform", default=None, help="platform name of the config (required)"),
                 option("--run", default=None, help="run name of the platform, or traditional (required)")),
    "identify": (option("--method", default=None, help="proposed (default) or traditional"),),
}
"""The rig's own options (``--seed`` of simulate: seed N of the study)."""
