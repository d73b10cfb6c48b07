"""``platcal simulate`` and ``platcal identify`` for ``rig: lowprec_centrifuge`` (docs/lowprec-centrifuge.md §10).

simulate: ``--platform P --run run1|run2|traditional [--seed N] [--noise-free] [--chunk-rows N] --out rec.csv``
(written N rows at a time, the same text as the whole run);
``--seed N`` writes replicate N (default 0) of the study's Monte Carlo cells (root seed: the
config's ``seed``; the same record in every centrifuge scenario's cells, §9, §12)
identify: ``--data rec.csv --out DIR [--method proposed|traditional] [--no-truth]``
Every option is checked before any work; options of other rigs are refused by name.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ... import aot
from ...estimation.consistency import EXIT_RUN_FAILED, estimate_problems, failed_run_status
from ...errors import InputError
from ...estimation.fit import FitCheck, fit_check, fit_exit_status
from ...rig import option, whole
from ...records import CHUNK_OPTION, chunk_rows_of, record_writer
from ...io import atomic_files, check_writable, json_text, write_csv
from ...study.sweep import replicate_seed
from ...logs.calibration import calibration_of, calibration_values, read_calibration, write_calibration_files
from ...logs.compensate import compensate_log
from ...logs.summary import inspect_log
from ...mapping import RecordMapping
from ...sizes import Costs, Size, record_size, samples_in
from .config import COEFFS, G0, Study
from .montecarlo import SEED_KEY
from .profile import profile_grid, run_duration
from .proposed import K_SLICE, run_filter
from .record import (NUMERIC, POSITIONS, REQUIRED, TRUTH_COLUMNS, UNITS, block_frame, check_against_config, check_out_path,
                     check_plausible, compensated_frame, estimate_columns, read_record, truth_side)
from .stream import WORK_ROWS, scan_record
from .traditional import plateau_estimates
from .truth import RecordRun

METHODS = ("proposed", "traditional")
COEFF_UNITS = ("ug/g", "ug/g^2", "ug/g", "ug/g^2")
"""Units of :data:`.config.COEFFS` (docs/lowprec-centrifuge.md §10): asymmetry ug/g, second order ug/g^2."""


def simulate(study: Study, args) -> int:
    if args.platform is None:
        raise InputError("--platform", f"required: one of {study.platform_names()}")
    if args.platform not in study.platforms:
        raise InputError("--platform", f"unknown platform {args.platform!r}; use one of {study.platform_names()}")
    runs = study.run_names(args.platform)
    if args.run is None or args.run not in runs:
        raise InputError("--run", f"{'required' if args.run is None else 'unknown run ' + repr(args.run)}: "
                                  f"one of {runs}")
    check_out_path(args.out)
    check_writable(args.out, "--out")
    seed = 0 if args.seed is None else int(args.seed)
    chunk = chunk_rows_of(args)
    t0 = time.perf_counter()
    # --seed N is replicate N of the study's cells (any scenario: they share the seeds), root seed `seed`
    ss = replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], seed)
    # the record needs the INS alone (each lane is navigated as if alone, so its numbers are the
    # Monte Carlo's), simulated and written chunk rows at a time: the same numbers and CSV text as
    # the whole run, in one block's memory (issue 22 item 3); the truth side file, which holds the
    # final errors, is written once the last block is
    run = RecordRun(study, args.platform, args.run, ss, noise_free=bool(args.noise_free), keep_phi=True,
                    rows=chunk or run_samples(study, args.platform, args.run))
    with record_writer(check_out_path(args.out),
                       truth=lambda: truth_side(study, args.platform, args.run, seed, run.levels, run.coeffs,
                                                run.draws, 0, run.final)) as write:
        for b in run.blocks():
            write(block_frame(b.t, b.schedule, b.theta, b.err, b.phi, b.v_ind, b.f_meas, b.p_ind, b.psi))
    print(f"platcal simulate: lowprec_centrifuge {args.platform} {args.run} ({', '.join(f'{a:g}' for a in run.levels)}"
          f" g), {'noise-free' if args.noise_free else f'seed {seed}'}, {(run.n - 1) * run.dt:.0f} s -> {args.out} "
          f"({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def run_samples(study: Study, platform: str, run: str) -> int:
    """Data samples of a run (``--chunk-rows 0``: the whole run as one block)."""
    return profile_grid(study, platform, run)[0]


def identify(study: Study, args) -> int:
    """``platcal identify``: the proposed filter (§7) or eq. (2) (§6) over a record read once,
    ``--chunk-rows`` rows at a time (:mod:`.stream`). The filter's kernel is the one compiled ahead
    of time when it is built and current (``platcal kernels``, :mod:`platcal.aot`: numba is then
    not loaded), else the JIT's."""
    aot.enable()
    method = args.method or "proposed"
    if method not in METHODS:
        raise InputError("--method", f"unknown method {method!r}; use one of {list(METHODS)}")
    check_writable(args.out, "--out", folder=True)
    max_gap = float(study.raw["record"]["max_gap_s"])
    arm = study.centrifuge.arm_m
    # one pass over the record, chunk_rows rows at a time (by default WORK_ROWS: its working set,
    # not the reader's larger default, sets the peak): what the identification needs is kept as
    # sums and per-window integrals, not the record (issue 22 item 3, :mod:`.stream`)
    chunk = WORK_ROWS if getattr(args, "chunk_rows", None) is None else chunk_rows_of(args)
    scan = scan_record(args.data, arm, study.rate_hz, max_gap, RecordMapping.from_config(study.raw["record"], g=G0),
                       chunk or None, windows=method == "proposed", use_truth=not args.no_truth)
    found = check_against_config(scan, study, method, max_gap)
    check_plausible(scan, arm)
    t0 = time.perf_counter()
    fit = None
    if method == "proposed":
        if scan.window_error is not None:
            raise scan.window_error
        T, z, m, _ = scan.windows
        res = run_filter(T[None], z[None], m[None], np.ones((1, T.size), bool), np.radians(study.latitude_deg),
                         keep_innovations=True)
        fit = record_fit(res)
        est, sig = res.coeffs[0], res.sigmas[0]
        extra = f"{int(res.n_windows[0])} windows"
        problems = run_problems(res.x[0], res.P[0])
        found["windows"] = int(res.n_windows[0])
    else:
        if any(h[3] < 2 for h in scan.holds):
            raise InputError("schedule", f"the traditional method needs {len(scan.holds)} 'hold' plateaus of at "
                                         f"least two samples; the record has {len(scan.holds)}")
        est = plateau_estimates(np.array([[e[0][0], e[1][0]] for e in scan.plateau_ends]),
                                np.array([[[e[0][1], e[1][1]] for e in scan.plateau_ends]]),
                                np.array([[[e[0][2], e[1][2]] for e in scan.plateau_ends]]),
                                study.traditional["levels_g"], arm)[0]
        sig = np.full(4, np.nan)   # eq. (2) gives no uncertainty
        extra = "eq. (2)"
        problems = run_problems(est, None)
    if failed_run_status(problems, f"the lowprec_centrifuge {method} identification", args.data, args.out,
                         "the record's units (VE, VN in m/s, heading_deg in deg) and its schedule"):
        return EXIT_RUN_FAILED
    seconds = time.perf_counter() - t0
    truth = scan.truth["coefficients"] if scan.truth and "coefficients" in scan.truth else None
    cols = estimate_columns(COEFFS, est, sig, truth)
    summary = {"rig": "lowprec_centrifuge", "method": method, "samples": int(scan.samples), **found,
               "coefficients": dict(zip(COEFFS, map(float, est))), "truth_known": truth is not None,
               "seconds": round(seconds, 3),
               "fit": fit.as_dict() if fit is not None else {
                   "verdict": "not available", "reason": "the traditional method (eq. (2)) has no innovations"}}
    cov = res.P[0][K_SLICE, K_SLICE] if method == "proposed" else np.diag(sig ** 2)
    cal = calibration_of("lowprec_centrifuge", "lowprec-centrifuge.md", COEFFS, COEFF_UNITS, est, cov, args.data, study.raw)
    with atomic_files(args.out) as tmp:   # the files land together, summary.json last
        write_csv(tmp("estimates.csv"), cols)   # pandas' to_csv text, without pandas (issue 22 item 3)
        write_calibration_files(tmp, cal)
        tmp("summary.json").write_text(json_text(summary))
    print(f"platcal identify: lowprec_centrifuge {method} ({extra}), {seconds:.2f} s -> {args.out}; "
          + ", ".join(f"{n} {e:.3f}" for n, e in zip(COEFFS, est))
          + aot.kernels_note(), file=sys.stderr)
    return fit_exit_status(fit, args.data, args.out)


FIT_CHANNELS = ("zVE", "zVN", "zPE", "zPN")
"""The proposed filter's window observations (docs/lowprec-centrifuge.md §7): mean velocity
error (m/s) and mean position error about the arm (m), east and north."""


def record_fit(res) -> FitCheck:
    """The fit check (:func:`platcal.estimation.fit.fit_check`) of one record's proposed filter
    from its window innovations and their predicted variances (:func:`.proposed.run_filter`). No
    diagnosis: the windows observe the INS's errors, not the instrument's output, so a unit, sign
    or swap is recognised before the filter (:func:`.record.check_plausible`)."""
    buf = res.innovations[0]
    return fit_check(buf[:, :4], buf[:, 4:], FIT_CHANNELS)


def run_problems(x: np.ndarray, P: np.ndarray | None) -> list[str]:
    """Why an identification cannot be trusted (empty if it can): non-finite estimates, a
    covariance (proposed filter) that is not finite or not positive definite."""
    return estimate_problems(x, P)


def inspect(study: Study, args) -> int:
    """``platcal inspect``: what ``--data`` holds, read through the config's ``record:`` mapping."""
    mapping = RecordMapping.from_config(study.raw["record"], g=G0)
    optional = tuple(c for c in NUMERIC if c not in REQUIRED) + TRUTH_COLUMNS
    print(inspect_log(args.data, mapping, UNITS, REQUIRED, optional, text=("schedule",), positions=POSITIONS).text())
    return 0


def compensate(study: Study, args) -> int:
    """``platcal compensate``: the log's velocities and positions with the errors the
    calibration's coefficients cause taken out (docs/lowprec-centrifuge.md §8), written
    atomically to ``--out`` in the record's columns and units. No gyro output is compensated: the
    calibration holds accelerometer terms only and the record no gyro channel (the output says so)."""
    coeffs = calibration_values(read_calibration(args.calibration), COEFFS, "lowprec_centrifuge")
    mapping = RecordMapping.from_config(study.raw["record"], g=G0)
    read = lambda path: read_record(path, use_truth=False, rate_hz=study.rate_hz,  # noqa: E731
                                    max_gap_s=float(study.raw["record"]["max_gap_s"]), mapping=mapping)
    return compensate_log(args, "lowprec_centrifuge", read, lambda rec: compensated_frame(rec, coeffs, study.latitude_deg),
                          "velocity and position compensated; no gyro output is compensated (the calibration holds "
                          "the accelerometer terms kA, k2 only and the log no gyro channel)")


def _segment_field(study: Study, seg: tuple) -> str:
    """The config key that sets a segment's length (for a size message)."""
    if seg[0] == "hold":
        return "traditional.hold_s"
    if seg[0] == "rest":
        keys = (("profile", "rest_first_s"), ("profile", "rest_between_s"), ("traditional", "rest_last_s"))
        return next((f"{a}.{b}" for a, b in keys if study.raw[a][b] == seg[1]), "profile.rest_first_s")
    return "profile.jerk_g_s"


COSTS = Costs(values={"simulate": 160}, seconds={"simulate": 5e-5},
              per_byte={"inspect": (0.5, 1.2e-8), "compensate": (0.5, 6e-8), "identify": (0.5, 3e-8)},
              measured="simulate per sample 1146 B (a 60 s / 1500 s rest; an earlier 60 s / 3000 s gave 465) and "
                       "2.3e-5 CPU s; per byte inspect 1.8 B and 5.6e-9 s, compensate 1.2 B and 3.0e-8 s, identify "
                       "1.5 B and 1.1e-8 s")
"""The low-precision centrifuge's costs (:class:`platcal.sizes.Costs`)."""


STREAMED_IDENTIFY_VALUES = 0.02
"""float64 values a streamed identify (``--chunk-rows`` not 0, :mod:`.stream`) holds per byte of its
record as CSV: its peak RSS grew 342 -> 387 MB from the 1 h to the 6 h record (116 -> 691 MB of
CSV, benchmarks/bench_memory.md), 0.078 bytes a byte, rounded up about 2x as :data:`COSTS`. Kept
as a bound since the windows went into arrays and the default block to :data:`.stream.WORK_ROWS`
rows (150 -> 156 MB on ahead-of-time kernels, 0.01 bytes a byte)."""


def sizes(command: str, study: Study, args) -> list[Size]:
    """The work a command's inputs imply (:mod:`platcal.sizes`): simulate runs the run's record
    (its duration at ``profile.rate_hz``) x :data:`COSTS`, its memory counted as the whole run's
    even when streamed (as the sled's: a bound on the record it writes too, and an absurd run is
    refused before it writes gigabytes); identify, inspect and
    compensate read the record they are given, sized by its file's bytes x :data:`COSTS` (a
    streamed identify by :data:`STREAMED_IDENTIFY_VALUES` per byte, its time as read whole)."""
    if command == "identify" and chunk_rows_of(args) != 0:
        return [record_size(args.data, STREAMED_IDENTIFY_VALUES, COSTS.per_byte["identify"][1])]
    if command in COSTS.per_byte:
        return COSTS.record(command, args.data)
    if command != "simulate" or args.platform not in study.platforms or args.run not in study.run_names(args.platform):
        return []   # the command names a missing platform or run itself
    seconds, longest = run_duration(study, args.platform, args.run)
    return [Size(_segment_field(study, longest), samples_in(seconds, 1.0 / study.rate_hz),
                 COSTS.values["simulate"], 1, f"run {args.platform} {args.run}, {seconds:g} s at {study.rate_hz:g} Hz",
                 COSTS.seconds["simulate"])]


OPTIONS = {
    "simulate": (option("--platform", default=None, help="platform name of the config (required)"),
                 option("--run", default=None, help="run name of the platform, or traditional (required)"),
                 CHUNK_OPTION),
    "identify": (option("--method", default=None, help="proposed (default) or traditional"),
                 option("--chunk-rows", type=whole(0), default=None,
                        help=f"rows read and processed at a time (default {WORK_ROWS}; 0: the whole record at "
                             "once); the identification keeps sums and per-window integrals, not the record")),
}
"""The rig's own options (``--seed`` of simulate: seed N of the study)."""
