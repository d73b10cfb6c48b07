"""``platcal simulate | identify | inspect | compensate`` for ``rig: multiposition`` (``observability``: :mod:`.study_commands`).

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

from ... import aot
from ...estimation.consistency import EXIT_RUN_FAILED, estimate_problems, failed_run_status
from ...estimation.fit import FitCheck, FitSums, Moments, fit_check, fit_exit_status, gross_errors_moments
from ...errors import InputError
from ...rig import option, resolve
from ...io import atomic_files, check_writable, json_text, write_csv
from ...logs.calibration import calibration_of, calibration_values, read_calibration, write_calibration_files
from ...logs.compensate import compensate_log, gyro_note, read_mapped
from ...logs.dwells import DWELL_FIGURE, dwells_found, lacks_position
from ...logs.summary import inspect_log
from ...mapping import RecordMapping
from ...plausibility import clock_rate_tolerance, refuse_clock_rate, refuse_recognised, refuse_recognised_moments
from ...records import CHUNK_OPTION, chunk_rows_of, chunks_beyond_one, record_writer
from ...sizes import Costs, Size, in_blocks, one_at_a_time, samples_in
from .estimators import estimate, estimate_positions, variant_choice
from .filter import SIM_BLOCK, nees, replicate_seeds, simulate_blocks, simulate_positions
from .model import coef_names, group_of, unit_of
from .record import (COLUMNS, COMPENSATE_COLUMNS, CONTINUOUS_COLUMNS, FILTER_BLOCK, GYRO_COLUMNS, TRUTH_COLUMNS,
                     UG, UNITS, compensate_frame, position_frame, read_chunks, read_record, scan_record)



def cmd_simulate(cfg, args) -> int:
    scheme = cfg.scheme(args.scheme)
    replicate = 0 if args.seed is None else int(args.seed)
    check_writable(args.out, "--out")
    t0 = time.perf_counter()
    # --seed N is replicate N of the study's cell (this scheme, noise.sigma_a_ug): the same SeedSequence
    # block by block of each position (the numbers and CSV text of the whole record), so a long test
    # does not need its record, nor a whole position, in memory
    with record_writer(args.out) as write:
        for k, t, phi, z in simulate_positions(cfg, scheme, replicate_seeds(cfg, scheme.name, [replicate])[0],
                                               noise_free=bool(args.noise_free)):
            write(position_frame(scheme, k, t, phi, z))
    what = "noise-free" if args.noise_free else (f"replicate {replicate} of the Monte Carlo cell {scheme.name}, "
                                                 f"sigma_a {cfg.sigma_a_ug:g} ug (root seed {cfg.seed})")
    print(f"platcal simulate: multiposition scheme {scheme.name!r}, {scheme.n_positions} positions x "
          f"{scheme.dwell_s:g} s, {what} -> {args.out} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def identify(cfg, rec, choice=None, innovations=None):
    """``(estimate (nc,), covariance (nc, nc), mean NIS, skipped updates)`` of one record with the
    estimator of ``choice`` (:class:`.estimators.FilterChoice`; default the config's ``filter``);
    ``innovations`` (1, K, n, 12) receives the last pass's innovations (:func:`.filter.run_filter`)."""
    tk, Z, nk = rec.packed()
    r = estimate(cfg, choice or cfg.filter_choice(), rec.cmd_deg, tk, Z, nk=nk, innovations=innovations)
    return r.coef[0], r.cov[0], float(r.mean_nis[0]), int(r.failed_updates[0])


FIT_CHANNELS = ("Ax", "Ay", "Az", "alpha_m", "beta_m", "gamma_m")


def innovation_buffer(rec) -> np.ndarray:
    """The (1, K, n, 12) array :func:`identify` fills with innovations for :func:`record_fit`."""
    tk, _, _ = rec.packed()
    return np.zeros((1,) + tk.shape + (12,))


def nominal_output(cfg, scheme, rec) -> np.ndarray:
    """(M, 6) ug, arcsec: the noise-free output of the nominal instrument (every coefficient 0)
    at the commanded angles and the record's filter instants (docs/multiposition-1g.md §7)."""
    return np.concatenate([nominal_position(cfg, scheme.angles_deg[k], scheme.dwell_s, tk)
                           for k, tk in enumerate(rec.t)])


def nominal_position(cfg, cmd_deg: np.ndarray, dwell_s: float, tk: np.ndarray) -> np.ndarray:
    """(m, 6) ug, arcsec: :func:`nominal_output` of one position (commanded angles ``cmd_deg`` (3,)
    deg, the scheme's dwell ``dwell_s`` s) at its instants ``tk`` (s) (docs/multiposition-1g.md §7,
    §12): :class:`NominalPosition` in one call."""
    return NominalPosition(cfg, cmd_deg, dwell_s).at(tk)


class NominalPosition:
    """The noise-free output of the nominal instrument (every coefficient 0) over one position
    (commanded angles ``cmd_deg`` (3,) deg, the scheme's dwell ``dwell_s`` s;
    docs/multiposition-1g.md §7, §12), taken at increasing instants block by block (:meth:`at`):
    a simulation of that position alone in blocks (:func:`.filter.simulate_blocks`: the
    simulator restarts each position, so these are the same numbers while one block of samples
    is held; ``block`` samples at a time)."""

    def __init__(self, cfg, cmd_deg: np.ndarray, dwell_s: float, block: int = FILTER_BLOCK):
        self.ts = cfg.ts
        self.n = int(round(dwell_s / cfg.ts)) + 1
        self._blocks = simulate_blocks(cfg, cmd_deg, dwell_s, truth=np.zeros_like(cfg.truth()), block=block)
        self._j0, self._z = 0, np.empty((0, 6))

    def at(self, tk: np.ndarray) -> np.ndarray:
        """(m, 6) ug, arcsec at the instants ``tk`` (s, increasing, none before the previous
        call's): each instant takes the simulated sample nearest it."""
        idx = np.clip(np.rint(np.asarray(tk, float) / self.ts).astype(int), 0, self.n - 1)
        out = np.empty((idx.size, 6))
        i = 0
        while i < idx.size:
            while idx[i] >= self._j0 + len(self._z):  # the next block of the simulation
                self._j0, _, self._z = next(self._blocks)
            hi = int(np.searchsorted(idx, self._j0 + len(self._z)))
            out[i:hi] = self._z[idx[i:hi] - self._j0]
            i = hi
        return out


def check_plausible(cfg, scheme, rec) -> None:
    """Refuse (InputError naming the column) a record whose accelerometers are a unit, sign or
    swap of what the nominal instrument reads at the commanded angles (a static platform reads
    |f| = 1 g; :func:`platcal.plausibility.refuse_recognised`). The angle sensors are left to the
    fit check: a log may wrap them differently from the commanded angles (+-180 deg)."""
    z = np.concatenate(rec.z)
    nominal = nominal_output(cfg, scheme, rec)
    refuse_recognised(z[:, :3] * UG, nominal[:, :3] * UG, FIT_CHANNELS[:3], "g",
                      "Ax, Ay, Az must be the x, y, z accelerometers in g (a static platform reads |f| = 1 g)")


def check_clock_rate(cfg, rec, est: np.ndarray, sigma: np.ndarray) -> dict:
    """Refuse (exit 2, column t) a record whose clock runs off ``sampling.ts_ms`` by more than the
    rate error that moves the most sensitive coefficient by 0.3 of its sigma
    (docs/multiposition-1g.md §16, :func:`platcal.plausibility.clock_rate_tolerance`): a clock
    1 + e fast stretches the time every drift (deg/h) is read over, moving it by e |D|, and the
    Earth's turn the model integrates over it, an extra drift of up to e x Earth rate on any drift
    coefficient (the platform is static at 1 g: one unit of a drift coefficient makes at most one
    deg/h). Needs the run's sigmas, so it follows the filter (the outputs are not written).
    Returns the summary's ``clock`` block when it passes."""
    names = coef_names()
    per_hour = [unit_of(n).startswith("deg/h") for n in names]
    earth_deg_h = np.degrees(cfg.site.earth_rate) * 3600.0
    tol, most = clock_rate_tolerance(names, est, sigma, per_hour, earth_deg_h, np.asarray(per_hour, float))
    return refuse_clock_rate(rec.clock, tol, most, "sampling.ts_ms (a record sampled at the filter's period)",
                             "docs/multiposition-1g.md §16")


def record_fit(cfg, scheme, rec, innovations: np.ndarray) -> FitCheck:
    """The fit check (:func:`platcal.estimation.fit.fit_check`) of one run from its innovations of
    Ax, Ay, Az (ug) and the angle sensors (arcsec) (docs/multiposition-1g.md §9); the diagnosis
    regresses the record on the noise-free output of the nominal instrument (coefficients 0) at
    the commanded angles."""
    nk = [len(t) for t in rec.t]
    buf = innovations[0]
    rows = np.concatenate([buf[k, :n] for k, n in enumerate(nk)])
    z = np.concatenate(rec.z)
    t = np.concatenate(rec.t)
    segment = np.repeat(np.arange(len(nk)), nk)
    innov = rows[:, :6]
    nominal = nominal_output(cfg, scheme, rec)
    # the angle sensors against the filter's own (wrapped) prediction: a log may wrap +-180 deg
    nominal[:, 3:] = z[:, 3:] - innov[:, 3:]
    return fit_check(innov, rows[:, 6:], FIT_CHANNELS, predicted=z - innov, nominal=nominal, t=t, segment=segment)


def identify_streamed(cfg, choice, path, scheme, mapping, max_gap_s: float, rows_at_once: int):
    """Identify a record read in chunks of ``rows_at_once`` rows (docs/multiposition-1g.md §9, §16):
    a first read checks it, selects its filter instants and spills their times and outputs to
    temporary files (:func:`.record.scan_record`), summing its accelerometers against the nominal
    output (the plausibility check, as :func:`check_plausible`); each filter pass reads those
    files a block at a time (:func:`.estimators.estimate_positions`), the last pass's innovations
    going into the fit check's running sums (:class:`~platcal.estimation.fit.FitSums`) and the
    diagnosis's sums (:class:`~platcal.estimation.fit.Moments`) block by block. Memory holds a
    block and the longest position's instant indices, not the record. Estimate and covariance are
    bit-identical to the whole read's, the mean NIS and the fit's figures equal to rounding; the
    streamed diagnosis names units, signs and swaps, not a clock (which the whole read finds in
    the innovations' time derivative). Returns ``(estimate, covariance, mean NIS, skipped updates,
    scan, fit)``; the scan's files are gone."""
    plaus = Moments.zero(3)
    nominal: dict = {}

    def dwell(last):  # the scheme's, else the position's own (the same nominal numbers: see NominalPosition)
        return scheme.dwell_s if scheme is not None else last

    def nominal_of(k, cmd, last):
        """Position k's NominalPosition, made at its first block (one position held)."""
        if nominal.get("k") != k:
            nominal.update(k=k, at=NominalPosition(cfg, cmd, dwell(last)).at)
        return nominal["at"]

    def each(k, cmd, last, tk, a):
        plaus.add(a, nominal_of(k, cmd, last)(tk)[:, :3] * UG)

    # read FILTER_BLOCK rows at a time (fewer with a smaller --chunk-rows, which decides whether the
    # record streams): the scan spills and sums block by block, and chunks of the default 100 000 rows
    # (11 MB each) made the peak grow with the record's chunks (issue 22 item 3)
    reading = min(rows_at_once, FILTER_BLOCK)
    with scan_record(read_chunks(path, mapping, reading), path, scheme, cfg.ts, max_gap_s, each=each) as scan:
        refuse_recognised_moments(plaus, FIT_CHANNELS[:3], "g", "Ax, Ay, Az must be the x, y, z accelerometers in g "
                                  "(a static platform reads |f| = 1 g)")
        held: dict = {}

        def blocks(k):
            for t, z in scan.blocks(k):
                held["t"], held["z"] = t, z  # the block on_innovations is called for, after the filter's step
                yield t, z

        sums, diag = FitSums(6), Moments.zero(6)
        nominal.clear()

        def on_innovations(k, rec):
            innov, z = rec[:, :6], held["z"]
            ok = sums.add(innov, rec[:, 6:], np.full(len(rec), k))
            nom = nominal_of(k, scan.cmd_deg[k], scan.last_t[k])(held["t"])
            # the angle sensors against the filter's own (wrapped) prediction, as record_fit does
            nom[:, 3:] = z[:, 3:] - innov[:, 3:]
            diag.add(z[ok], nom[ok])

        r = estimate_positions(cfg, choice, scan.cmd_deg, lambda: (blocks(k) for k in range(len(scan.positions))),
                               on_innovations)
    fit = sums.check(FIT_CHANNELS, diagnosis=tuple(text for _, text in gross_errors_moments(diag, FIT_CHANNELS)))
    return r.coef[0], r.cov[0], float(r.mean_nis[0]), int(r.failed_updates[0]), scan, fit


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
    """``platcal identify``: the coefficients of one record (docs/multiposition-1g.md §9, §16). Its
    kernels are the ones compiled ahead of time when they are built and current (``platcal
    kernels``, :mod:`.aot_kernels`: numba is then not loaded), else the JIT's."""
    aot.enable()
    choice = cfg.filter_choice() if args.estimator is None else variant_choice(cfg, args.estimator)
    scheme = cfg.scheme(args.scheme) if args.scheme else None
    check_writable(args.out, "--out", folder=True)
    mapping = RecordMapping.from_config(cfg.raw["record"])
    max_gap_s = float(cfg.raw["record"]["max_gap_s"])
    rows_at_once = chunk_rows_of(args)
    # a record longer than one chunk is streamed (memory does not grow with it); a shorter one, or
    # a continuous log (no position column: its dwells are found in the whole log), is read whole
    try:
        streamed = bool(rows_at_once) and chunks_beyond_one(read_chunks(args.data, mapping, rows_at_once))
    except InputError as exc:
        if scheme is None or not lacks_position(exc, mapping):
            raise
        streamed = False
    if streamed:
        t0 = time.perf_counter()
        est, P, nis, failed, rec, fit = identify_streamed(cfg, choice, args.data, scheme, mapping, max_gap_s,
                                                          rows_at_once)
        scheme = rec.scheme
        seconds = time.perf_counter() - t0
    else:
        rec, scheme = read_record(args.data, scheme, ts=cfg.ts, max_gap_s=max_gap_s, mapping=mapping)
        check_plausible(cfg, scheme, rec)
        t0 = time.perf_counter()
        innovations = innovation_buffer(rec)
        est, P, nis, failed = identify(cfg, rec, choice, innovations)
        seconds = time.perf_counter() - t0
    if failed_run_status(run_problems(est, P, nis, failed), "the multiposition EKF run", args.data, args.out,
                         "the record's units (Ax, Ay, Az in g, angles in deg) and the config's noise and filter "
                         "settings"):
        return EXIT_RUN_FAILED
    clock = check_clock_rate(cfg, rec, est, np.sqrt(np.diag(P)))
    used = rec.samples_used()
    names = coef_names()
    sig = np.sqrt(np.diag(P))
    units = [unit_of(n) for n in names]
    groups = [group_of(n) for n in names]
    # estimates.csv's columns, written by platcal.io.write_csv (pandas' to_csv text, without pandas)
    table = {"name": names, "unit": units, "group": groups, "estimate": est, "sigma": sig}
    summary = {"rig": "multiposition", "scheme": scheme.name, "n_states": len(names) + 3,
               "estimator": choice.estimator, "passes": choice.passes, "estimator_options": choice.options,
               "positions": len(used), "samples": int(sum(used.values())),
               "samples_used_per_position": {str(k): v for k, v in used.items()}, "mean_nis": nis,
               "seconds": seconds, "clock": clock}
    segmentation = None if streamed else rec.segmentation
    if segmentation is not None:
        summary["dwells_found"] = dwells_found(segmentation[0], segmentation[2])
    if not streamed:
        fit = record_fit(cfg, scheme, rec, innovations)
    summary["fit"] = fit.as_dict()
    use_truth = rec.has_truth and not args.no_truth
    if use_truth:
        tr = cfg.truth()
        rel = (est - tr) / np.abs(tr) * 100.0
        table.update({"truth": tr, "error": est - tr, "rel_err_pct": rel})
        g = np.array(groups) == "gyro"  # the largest errors skip a NaN (a zero truth) as pandas' max did
        summary.update({"nees": float(nees(est[None], P[None], tr)[0]), "nees_dof": len(names),
                        "max_abs_rel_err_pct_gyro": float(np.nanmax(np.abs(rel[g]))),
                        "max_abs_rel_err_pct_accel": float(np.nanmax(np.abs(rel[~g])))})
    out = Path(args.out)
    cal = calibration_of("multiposition", "multiposition-1g.md", names, units, est, P, args.data, cfg.raw)
    with atomic_files(out) as tmp:  # the files land together, summary.json last
        write_csv(tmp("estimates.csv"), table)
        write_calibration_files(tmp, cal)
        if segmentation is not None:
            resolve(DWELL_FIGURE)(*segmentation, tmp("dwells.png"))
        tmp("summary.json").write_text(json_text(summary))
    msg = (f"platcal identify: multiposition 27-state {choice.label}, {min(used.values())}-"
           f"{max(used.values())} samples per position, {seconds:.2f} s -> {out}")
    if use_truth:
        msg += (f"; max |rel err| gyro {summary['max_abs_rel_err_pct_gyro']:.3f} %, accel "
                f"{summary['max_abs_rel_err_pct_accel']:.4f} %, NEES {summary['nees']:.1f} (dof 24)")
    msg += aot.kernels_note()
    print(msg, file=sys.stderr)
    return fit_exit_status(fit, args.data, out)


def cmd_inspect(cfg, args) -> int:
    """``platcal inspect``: what ``--data`` holds, read through the config's ``record:`` mapping."""
    # a continuous log (no position column) is read too: identify finds its dwells
    optional = tuple(c for c in COLUMNS + TRUTH_COLUMNS + GYRO_COLUMNS if c not in CONTINUOUS_COLUMNS)
    summary = inspect_log(args.data, RecordMapping.from_config(cfg.raw["record"]), UNITS, CONTINUOUS_COLUMNS, optional)
    print(summary.text())
    return 0


def cmd_compensate(cfg, args) -> int:
    """``platcal compensate``: the log's accelerometer outputs (and gyro outputs, when it has them)
    with the calibration's modelled errors taken out (docs/multiposition-1g.md §5, §6), written
    atomically to ``--out``; the output says when the log has no gyro outputs to compensate."""
    coef = calibration_values(read_calibration(args.calibration), coef_names(), "multiposition")
    optional = tuple(c for c in COLUMNS + TRUTH_COLUMNS + GYRO_COLUMNS if c not in COMPENSATE_COLUMNS)
    read = read_mapped("multiposition", RecordMapping.from_config(cfg.raw["record"]), UNITS, COMPENSATE_COLUMNS,
                       optional)
    return compensate_log(args, "multiposition", read, lambda df: compensate_frame(df, coef),
                          lambda out: gyro_note(out.columns, GYRO_COLUMNS, "DF, DI, ... DOS"))


COMMANDS = {"inspect": f"{__name__}:cmd_inspect", "compensate": f"{__name__}:cmd_compensate",
            "simulate": f"{__name__}:cmd_simulate", "identify": f"{__name__}:cmd_identify",
            "observability": f"{__package__}.study_commands:cmd_observability",
            "kernels": f"{__package__}.aot_kernels:kernels_command"}
"""Each sub-command by module path (:func:`platcal.rig.resolve`): ``observability`` (the exact
Lie-derivative rank, sympy) in :mod:`.study_commands`, imported only when it is chosen."""

COSTS = Costs(values={"simulate": 48, "identify": 96}, seconds={"simulate": 2.5e-5, "identify": 2e-5},
              per_byte={"inspect": (0.5, 1e-8), "compensate": (0.5, 4e-7)},
              measured="per sample 324 and 651 B, 1.2e-5 and 7.8e-6 CPU s (simulate, identify); per byte inspect "
                       "2.2 B and 5.2e-9 s, compensate 2.8 B and 1.9e-7 s")
"""The multi-position rig's costs (:class:`platcal.sizes.Costs`)."""


def sizes(command: str, cfg, args) -> list[Size]:
    """The work a command's inputs imply (:mod:`platcal.sizes`): simulate and identify hold and run
    the scheme's samples (every position, at ``sampling.ts_ms``) x :data:`COSTS`; observability
    propagates a covariance over the same samples (or
    fewer, at a coarser step) holding one matrix per position, so it is timed at identify's cost per
    sample (an upper bound: the covariance step is a part of the filter's) and holds nothing per
    sample; inspect and compensate the record file's bytes x :data:`COSTS`; kernels builds a fixed
    set of kernels (no input to size)."""
    if command in COSTS.per_byte:
        return COSTS.record(command, args.data)
    if command == "kernels":
        return []
    scheme = cfg.scheme(args.scheme)
    kind = "simulate" if command == "simulate" else "identify"
    field = f"schemes.{scheme.name}.dwell_s" if scheme.name in cfg.raw["schemes"] else "--scheme (its dwell_s)"
    held = COSTS.values[kind] if command != "observability" else 0
    size = Size(field, scheme.n_positions * samples_in(scheme.dwell_s, cfg.ts), held, 1,
                f"scheme {scheme.name!r}, {scheme.n_positions} positions x {scheme.dwell_s:g} s at "
                f"{cfg.ts * 1000:g} ms", COSTS.seconds[kind])
    if command == "simulate":  # a block of a position at a time (.filter.simulate_positions)
        return [in_blocks(size, SIM_BLOCK)]
    # identify streams past --chunk-rows one position at a time
    return [one_at_a_time(size, scheme.n_positions) if command == "identify" and chunk_rows_of(args) else size]


SCHEME = option("--scheme", default=None, help="scheme name of the config or built in (S8, SIX, T1, TET4, ...); "
                                              "default: the config's default_scheme")
OPTIONS = {"simulate": (SCHEME,), "observability": (SCHEME,),
           "identify": (SCHEME, CHUNK_OPTION, option("--estimator", default=None,
                                       help="ekf or iekf, or a study.estimators name (ekf1, ekf2, iekf)"))}
"""The rig's own options (``--seed`` of simulate: replicate N of the study's Monte Carlo cell)."""
