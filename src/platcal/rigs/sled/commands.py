"""``platcal simulate | identify | observability`` for ``rig: sled`` (docs/rocket-sled.md §10)."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from ... import aot
from ...errors import InputError
from ...estimation.consistency import EXIT_RUN_FAILED, failed_run_status
from ...estimation.fit import fit_exit_status
from ...io import atomic_files, check_writable, json_text, write_csv
from ...logs.calibration import read_calibration, write_calibration_files
from ...logs.compensate import compensate_log
from ...logs.increments import increment_units
from ...logs.summary import inspect_log
from ...mapping import RecordMapping
from ...records import CHUNK_OPTION, chunk_rows_of, chunks_beyond_one, iter_table
from ...sizes import Costs, Size, samples_in
from .config import G, SledConfig
from .identify import (calibration, compensated_track, estimate_columns, gyro_rate_block, gyro_rate_error, identify,
                       metric_columns, phi_from_calibration, record_fit, run_problems)
from .montecarlo import replicate_seeds
from .record import (IMU_COLUMNS, TRUTH_COLUMNS, UNITS, check_out_path, check_plausible, read_record, record_arrays,
                     record_truth, samples_per_phase, static_rate_tolerance, table_options, write_record)
from .simulate import simulate
from .stream import identify_streamed, simulate_streamed
from .trajectory import Timeline


def cmd_simulate(cfg: SledConfig, args) -> int:
    """One simulated record (+ ``.truth.json``): replicate ``--seed`` (default 0) of the study's
    ``default`` case, the same SeedSequence as its Monte Carlo cell (:mod:`.montecarlo`)."""
    replicate = 0 if args.seed is None else args.seed
    out = check_out_path(args.out)
    check_writable(out, "--out")
    chunk_rows = chunk_rows_of(args)
    t0 = time.perf_counter()
    seeds = replicate_seeds(cfg.raw, "default", [replicate])
    if chunk_rows and Timeline.of(cfg).n > chunk_rows:   # written a block at a time (.stream)
        traj = simulate_streamed(cfg, seeds[0], out, chunk_rows, noise_free=bool(args.noise_free))
    else:
        sb = simulate(cfg, seeds, noise_free=bool(args.noise_free))
        write_record(sb, out)
        traj = sb.traj
    what = "noise-free" if args.noise_free else f"replicate {replicate} of case default (root seed {cfg.seed})"
    print(f"platcal simulate: sled, stop at {traj.stop_time_s:.2f} s, {traj.run_length_m:.1f} m, {what} "
          f"-> {out} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def cmd_identify(cfg: SledConfig, args) -> int:
    """INS, run and stop filters and X compensation of a record -> estimates.csv, metrics.json, on
    the kernels compiled ahead of time where they are built (``platcal kernels``, :mod:`.aot_kernels`:
    numba is then not loaded), else the JIT's."""
    aot.enable()
    check_writable(args.out, "--out", folder=True)
    chunk_rows = chunk_rows_of(args)
    t0 = [time.perf_counter()]
    if chunk_rows and chunks_beyond_one(iter_table(args.data, **table_options(cfg), chunk_rows=chunk_rows)):
        # longer than one chunk: read three times, held in bounded memory (.stream)
        res = identify_streamed(args.data, cfg, chunk_rows, with_truth=not args.no_truth,
                                checked=lambda _: t0.__setitem__(0, time.perf_counter()))
        idn, truth, tm = res.idn, res.truth, res.times
        samples, per_phase, tolerance = tm.rows, tm.per_phase, tm.tolerance
        one, tail = res.first()
        gyro = lambda est: gyro_rate_block(cfg, est, tolerance, idn if res.gyro_lanes else None, first=1)  # noqa: E731
    else:
        traj, df, t = read_record(args.data, cfg)
        truth = None if args.no_truth else record_truth(args.data, df)
        t0[0] = time.perf_counter()
        f, w = record_arrays(df)
        check_plausible(cfg, traj, f[0], w[0], t)
        idn = identify(cfg, traj, f, w, t=t)
        one, tail = idn, None
        samples, per_phase, tolerance = int(len(t)), samples_per_phase(traj, t, cfg.dt), None
        gyro = lambda est: gyro_rate_error(cfg, traj, f[0], w[0], t, est,  # noqa: E731
                                           static_rate_tolerance(cfg, traj, t))
    if failed_run_status(run_problems(idn), "the sled filters", args.data, args.out,
                         "the record's units (f in m/s^2, w in rad/s) and the config's filter settings"):
        return EXIT_RUN_FAILED
    met = {k: v[0] for k, v in metric_columns(one, truth, tail).items()}  # the first seed slot: the record
    est = estimate_columns(idn, truth)
    seconds = time.perf_counter() - t0[0]
    out = Path(args.out)
    summary = {k: (None if not np.isfinite(v) else float(v)) for k, v in met.items()}
    summary.update({"states": cfg.states, "compensation": cfg.compensation, "tuning": cfg.tuning,
                    "truth_known": truth is not None, "seconds": round(seconds, 3),
                    "samples": samples, "samples_used_per_phase": per_phase,
                    "filter_epochs": {"run": int(idn.j_stop), "stop": int(idn.j_end - idn.j_stop)}})
    fit = record_fit(idn)
    summary["fit"] = fit.as_dict()
    # the filters' sigmas leave out the gyros' constant error, which the record cannot see below
    # the check at rest: what it does to the estimates, and the sigma with it
    summary["gyro_rate_error"] = gyro(est)
    with atomic_files(out) as tmp:  # the files land together, metrics.json last
        write_csv(tmp("estimates.csv"), est, float_format="%.6g")
        write_calibration_files(tmp, calibration(idn, args.data, cfg.raw))
        tmp("metrics.json").write_text(json_text(summary))
    msg = (f"platcal identify: sled {cfg.states}-state run filter, {cfg.compensation} X compensation, "
           f"{seconds:.2f} s -> {out}; Y/Z run max {met['yz_before_max_run_cm']:.1f} cm before, "
           f"{max(met['y_after_a_max_run_cm'], met['z_after_a_max_run_cm']):.3f} cm after (A)")
    if truth is not None:
        msg += f"; X at stop naive {met['x_naive_stop_cm']:.1f} cm, constrained {met['x_constrained_stop_cm']:.1f} cm"
    worst = max(summary["gyro_rate_error"]["estimates"].items(), default=None,
                key=lambda kv: max(kv[1]["shift_at_tolerance_sigmas"]))
    if worst is not None:
        st = summary["gyro_rate_error"]["scale_tolerance"]
        name, w_est = worst
        msg += (f"; gyro rate errors (or scale errors up to {min(st):.2g}-{max(st):.2g}) too small to see at "
                f"rest move {name} by up to {max(w_est['shift_at_tolerance_sigmas']):.1f} sigma: its sigma with "
                f"the gyros' own errors is {w_est['sigma_with_gyro_arcsec']:.3g} arcsec (metrics.json "
                "gyro_rate_error)")
    msg += aot.kernels_note()
    print(msg, file=sys.stderr)
    return fit_exit_status(fit, args.data, out, "metrics.json")


def cmd_inspect(cfg: SledConfig, args) -> int:
    """``platcal inspect``: what ``--data`` holds, read through the config's ``record:`` mapping."""
    mapping = RecordMapping.from_config(cfg.raw["record"], g=G)
    units = increment_units(UNITS, IMU_COLUMNS[1:]) if mapping.kind == "increments" else UNITS
    print(inspect_log(args.data, mapping, units, IMU_COLUMNS, TRUTH_COLUMNS, increments=IMU_COLUMNS[1:]).text())
    return 0


def cmd_compensate(cfg: SledConfig, args) -> int:
    """``platcal compensate``: the record's along-track X(t), V(t) navigated and compensated with
    the calibration's attitude errors (docs/rocket-sled.md §7), written atomically to ``--out``.
    The calibration holds no gyro terms (the run filter estimates attitude errors), so the log's
    rates are navigated as recorded, and the output says so."""
    phi = phi_from_calibration(read_calibration(args.calibration))

    def apply(rec):
        _, df, t = rec
        f, w = record_arrays(df)
        return compensated_track(cfg, f[0], w[0], t, phi)

    return compensate_log(args, "sled", lambda path: read_record(path, cfg), apply,
                          "along-track X(t), V(t) navigated and compensated; the calibration holds attitude errors, "
                          "no gyro terms, so the log's rates wx, wy, wz are navigated as recorded")


OBSERVABILITY_PER_PHASE = (1000, 2.5e-3)
"""(float64 values held, CPU s) per phase of the observability rank table (static, each phase,
braking: 2 models x 4 rates, an SVD each and of the stack): 250-670 values and 1.1e-3 CPU s a
phase measured (benchmarks/size_estimate_more.py, 200 and 2000 phases, load 6-8 on 2 cores),
rounded up."""
COSTS = Costs(values={"simulate": 48, "identify": 96}, seconds={"simulate": 2.5e-5, "identify": 5e-6},
              per_byte={"inspect": (0.5, 1e-8), "compensate": (0.5, 5e-8)},
              measured="per sample 344 and 614 B, 1.1e-5 and 2.1e-6 CPU s (simulate, identify); per byte inspect "
                       "2.1 B and 3.9e-9 s, compensate 1.7 B and 2.1e-8 s")
"""The sled's costs (:class:`platcal.sizes.Costs`)."""


def sizes(command: str, cfg: SledConfig, args) -> list[Size]:
    """The work a command's inputs imply (:mod:`platcal.sizes`): simulate and identify hold and
    run the run's IMU samples (static before, the phases, the braking, static after, at
    ``imu.rate_hz``) x :data:`COSTS`, the longest part naming the field; inspect and compensate
    the record file's bytes x :data:`COSTS`.
    observability's rank table holds and decomposes small matrices per phase (docs/rocket-sled.md
    §8), whatever the durations: the phases x :data:`OBSERVABILITY_PER_PHASE`."""
    if command in COSTS.per_byte:
        return COSTS.record(command, args.data)
    if command == "observability":
        n = len(cfg.phases) + 2.0   # the static period and the braking too
        return [Size("trajectory.phases", n, OBSERVABILITY_PER_PHASE[0], 1, f"{n:g} phases (static, the config's, "
                     "braking), 2 models x 4 rates", OBSERVABILITY_PER_PHASE[1], unit="phases")]
    if command not in ("simulate", "identify"):
        return []
    v_end = sum(ph.accel_g * G * ph.duration_s for ph in cfg.phases)
    parts = {"trajectory.static_before_s": cfg.static_before_s, "trajectory.static_after_s": cfg.static_after_s,
             "trajectory.brake_g": max(v_end, 0.0) / (cfg.brake_g * G)}
    parts.update({f"trajectory.phases[{i}].duration_s": ph.duration_s for i, ph in enumerate(cfg.phases)})
    seconds = sum(parts.values())
    return [Size(max(parts, key=parts.get), samples_in(seconds, cfg.dt), COSTS.values[command], 1,
                 f"a run of {seconds:g} s at {cfg.rate_hz:g} Hz", COSTS.seconds[command])]


OPTIONS = {"simulate": (CHUNK_OPTION,), "identify": (CHUNK_OPTION,)}
"""The sled's own options: ``--chunk-rows`` (a record longer than one chunk is simulated and
identified block by block, :mod:`.stream`)."""

COMMANDS = {"compensate": cmd_compensate, "inspect": cmd_inspect, "simulate": cmd_simulate, "identify": cmd_identify,
            # by module path: the rank table's pandas loads only for this command (issue 22 item 3)
            "observability": "platcal.rigs.sled.observability:cmd_observability",
            "kernels": f"{__package__}.aot_kernels:kernels_command"}
