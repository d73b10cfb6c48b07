"""The centrifuge's ``platcal`` sub-commands: ``fn(study, args) -> int`` for ``RIG.commands``.

``study`` is the validated :class:`~platcal.rigs.centrifuge.config.Study` of ``--config``;
``args`` the namespace of :func:`platcal.cli.build_parser`. Every command checks the options it
needs and refuses, naming the option, those the centrifuge has no use for.
"""

from __future__ import annotations

import argparse
import copy
from dataclasses import replace
import sys
import time

from ... import aot
from ...errors import InputError
from ...estimation.consistency import EXIT_RUN_FAILED, failed_run_status
from ...estimation.fit import fit_exit_status
from ...rig import COUNT, SEED, option, real, resolve, whole
from ...io import check_writable
from ...logs.calibration import read_calibration
from ...logs.compensate import compensate_log, gyro_note, read_mapped
from ...logs.dwells import lacks_position
from ...logs.summary import inspect_log
from ...mapping import RecordMapping
from ...scheme import resolve_scheme
from ...sizes import Costs, Size, one_at_a_time, samples_in
from ...study.sweep import replicate_seed
from .catalogue import load_catalogue
from .config import Study, check_filter, study_from_config
from .estimators import KINDS
from .identify import (calibration, check_clock_rate, clock_finding, consistency_warning, continuous_input,
                       identify_input, identify_streamed, record_clock, record_fit, record_input, run_problems,
                       streamable, timed, truth_known, write_identification)
from .record import (COMPENSATE_COLUMNS, CONTINUOUS_COLUMNS, GYRO_COLUMNS, LOG_COLUMNS, OPTIONAL_COLUMNS, UNITS,
                     chunk_to_frame, compensate_frame, full_coefficients, read_record)
from ...records import CHUNK_OPTION, chunk_rows_of, iter_table, record_writer
from .simulate import simulate_chunks
from .study import CentrifugeMonteCarlo

def scheme_option(study: Study, args: argparse.Namespace):
    """The scheme ``--scheme`` names (a config scheme or a scheme file); InputError when absent."""
    if not args.scheme:
        raise InputError("--scheme", "required for rig centrifuge: a scheme name of the config or a scheme YAML file")
    return resolve_scheme(args.scheme, study.schemes)


def simulate_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal simulate``: one test record (docs/centrifuge-model.md §13)."""
    scheme = scheme_option(study, args)
    check_writable(args.out, "--out")
    replicate = 0 if args.seed is None else int(args.seed)
    # replicate N of the Monte Carlo cell (this scheme, the config's sigma_a): a run of the study
    # can be written out and identified on its own
    seeds = None if args.noise_free else [replicate_seed(study.seed, scheme.name, study.noise.sigma_a_ug, replicate)]
    t0 = time.perf_counter()
    chunk_rows = chunk_rows_of(args)
    # written chunk by chunk (same numbers, same CSV text as the whole record), so a long test
    # does not need its record in memory
    with record_writer(args.out) as write:
        for chunk in simulate_chunks(study.truth, scheme, study.centrifuge.scheme_params(scheme), study.noise, seeds,
                                     sample_s=study.sample_s, chunk_samples=chunk_rows or None):
            write(chunk_to_frame(chunk, scheme))
    print(f"platcal simulate: scheme {scheme.name!r}, {scheme.n_positions} positions x {scheme.dwell_s:g} s, "
          f"{'noise-free' if seeds is None else f'replicate {replicate} of the cell (seed {study.seed})'}"
          f" -> {args.out} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def with_estimator(study: Study, name: str | None) -> Study:
    """The study whose filter is the estimator ``name``: an entry of ``study.estimators`` (its
    ``filter:`` overrides, as in the Monte Carlo) or a kind (:data:`.estimators.KINDS`, the
    config's filter with ``filter.estimator`` set); None keeps the config's. InputError naming
    ``--estimator`` and both lists otherwise."""
    if name is None:
        return study
    named = study.config["study"]["estimators"]
    raw = copy.deepcopy(study.config)
    if name in named:
        raw["filter"].update(named[name])
    elif name in KINDS:
        raw["filter"]["estimator"] = name
    else:
        raise InputError("--estimator", f"unknown estimator {name!r}; use a kind ({', '.join(KINDS)}) or a name "
                         f"of the config's study.estimators ({', '.join(named)})")
    return study_from_config(raw)


def identify_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal identify``: the study's estimator (``--estimator`` or ``filter.estimator``) over a
    test record. Its kernels are the ahead-of-time ones when they are built and current
    (``platcal kernels``, :mod:`platcal.aot`: numba is then not loaded), else the JIT's."""
    aot.enable()
    study = with_estimator(study, args.estimator)
    check_filter(study.filter)
    scheme = scheme_option(study, args)
    check_writable(args.out, "--out", folder=True)
    mapping = RecordMapping.from_config(study.config["record"], g=study.centrifuge.g)
    chunk_rows = chunk_rows_of(args)

    def read_chunks():
        return iter_table(args.data, LOG_COLUMNS, OPTIONAL_COLUMNS, mapping=mapping, units=UNITS,
                          chunk_rows=chunk_rows)

    # a record longer than one chunk is streamed (memory does not grow with it); a shorter one,
    # or an estimator that needs it whole, is read whole as before
    chunks = read_chunks() if chunk_rows and streamable(study.filter) else None
    segmentation = None
    try:
        streamed = chunks is not None and next(chunks, None) is not None and next(chunks, None) is not None
        df = None if streamed else read_record(args.data, mapping)
    except InputError as exc:  # no position column: a continuous log, read whole and cut into dwells
        if not lacks_position(exc, mapping):
            raise
        streamed = False
        df, segmentation = continuous_input(study, scheme, args.data, mapping)
    history = fin = None  # a streamed identify's history, spilled to a temporary file as it was filtered
    if streamed:
        chunks.close()
        t0 = time.perf_counter()
        est, scan, fit, history = identify_streamed(study, scheme, read_chunks)
        seconds = time.perf_counter() - t0
        used = {k: int(n) for k, n in zip(scan.positions, scan.counts)}
        known = scan.truth
    else:
        fin = record_input(study, scheme, df)
        est, seconds = timed(identify_input, study, scheme, fin)
        used = {k: int(t.size) for k, t in zip(fin.positions, fin.t)}
        fit = None
        known = truth_known(df)
    try:
        return identified(study, args, scheme, est, fit, used, known, seconds, segmentation, history,
                          scan.clock if streamed else None, df, fin)
    finally:
        if history is not None:
            history.close()


def identified(study: Study, args: argparse.Namespace, scheme, est, fit, used: dict, known: bool, seconds: float,
               segmentation, history, clock_rate, df, fin) -> int:
    """The end of :func:`identify_command` once the filter has run: the run's and the clock's
    checks, the fit check of a record read whole (``fit`` None; ``df`` the record, ``fin`` its
    filter input; ``clock_rate`` a streamed record's clock, else taken from ``df``), the outputs
    (``history`` a streamed run's spilled history) and the message; the exit status."""
    if failed_run_status(run_problems(est), "the filter run", args.data, args.out,
                         "the record's units (Ax, Ay, Az in g) and the config's noise and filter settings"):
        return EXIT_RUN_FAILED
    clock = check_clock_rate(study, scheme, est, clock_rate if clock_rate is not None else record_clock(study, df))
    if fit is None:
        fit = record_fit(est, fin, study, scheme, clock_finding(study, scheme, df))
    summary = write_identification(args.out, est, study, known and not args.no_truth, seconds,
                                   samples_used=used, calibration=calibration(est, study, args.data), fit=fit,
                                   segmentation=segmentation, clock=clock, history=history)
    msg = (f"platcal identify: {len(est.names)}-state {study.filter.estimator.upper()}, {study.filter.passes} pass(es), "
           f"{min(used.values())}-{max(used.values())} samples per position, {seconds:.2f} s -> {args.out}")
    if segmentation is not None:
        msg += " (dwells found in the continuous log: dwells.png)"
    if "nees" in summary:
        msg += (f"; max |rel err| gyro {summary['max_abs_rel_err_pct_gyro']:.2f} %, accel "
                f"{summary['max_abs_rel_err_pct_accel']:.3f} %, NEES {summary['nees']:.1f} (dof {summary['nees_dof']})")
    msg += aot.kernels_note()
    print(msg, file=sys.stderr)
    warning = consistency_warning(summary)
    if warning:
        print(f"platcal identify: warning: {warning}", file=sys.stderr)
    return fit_exit_status(fit, args.data, args.out)


def inspect_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal inspect``: what ``--data`` holds, read through the config's ``record:`` mapping."""
    mapping = RecordMapping.from_config(study.config["record"], g=study.centrifuge.g)
    # a continuous log (no position column) is read too: identify finds its dwells
    optional = tuple(c for c in LOG_COLUMNS + OPTIONAL_COLUMNS if c not in CONTINUOUS_COLUMNS)
    print(inspect_log(args.data, mapping, UNITS, CONTINUOUS_COLUMNS, optional).text())
    return 0


def compensate_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal compensate``: the log's accelerometer outputs with the calibration's modelled
    errors taken out (docs/centrifuge-model.md §5: the specific force whose modelled outputs are
    the recorded ones), written atomically to ``--out`` in the record's columns and units. The
    record has no gyro channel (the gyros are seen through the platform's attitude, §6): a log
    that holds the gyro outputs ``wx, wy, wz`` (deg/h) gets them less the modelled drift (§4);
    otherwise the output says the gyro terms were not applied."""
    coef = full_coefficients(read_calibration(args.calibration), "centrifuge")
    mapping = RecordMapping.from_config(study.config["record"], g=study.centrifuge.g)
    optional = tuple(c for c in LOG_COLUMNS + OPTIONAL_COLUMNS if c not in COMPENSATE_COLUMNS)
    return compensate_log(args, "centrifuge", read_mapped("centrifuge", mapping, UNITS, COMPENSATE_COLUMNS, optional),
                          lambda df: compensate_frame(df, coef),
                          lambda out: gyro_note(out.columns, GYRO_COLUMNS, "DF, DI, ... DOS"))


COSTS = Costs(values={"simulate": 24, "identify": 96}, seconds={"simulate": 2e-5, "identify": 2e-5},
              per_byte={"inspect": (0.5, 3e-8), "compensate": (0.5, 1.5e-7)},
              measured="per sample 176 and 664 B, 9.6e-6 and 5.4e-6 CPU s (simulate, identify; identify rounded "
                       "up to simulate's: a Monte Carlo replicate does both); per byte inspect 2.8 B and 1.2e-8 s, "
                       "compensate 3.1 B and 6.1e-8 s")
"""The centrifuge's costs (:class:`platcal.sizes.Costs`)."""


def _dwell_field(study: Study, scheme) -> str:
    """The config key (or option) whose dwell sets a scheme's length, for a size message."""
    return f"schemes.{scheme.name}.dwell_s" if scheme.name in study.schemes else "--scheme (its dwell_s)"


def _scheme_size(study: Study, scheme, command: str, replicates: float = 1, runs: float | None = None) -> Size:
    return Size(_dwell_field(study, scheme), scheme.n_positions * samples_in(scheme.dwell_s, study.sample_s),
                COSTS.values[command], replicates,
                f"scheme {scheme.name!r}, {scheme.n_positions} positions x {scheme.dwell_s:g} s at "
                f"{study.sample_s * 1000:g} ms", COSTS.seconds[command], runs)


def sizes(command: str, study: Study, args: argparse.Namespace) -> list[Size]:
    """The work each command's inputs imply (:mod:`platcal.sizes`): the scheme's samples (every
    position) x :data:`COSTS` for simulate and identify (observability simulates its replicates one
    batch at a time and identifies each; a Monte Carlo cell simulates and identifies
    ``study.batch`` replicates at once, ``study.replicates`` in all), the estimates of every
    replicate (replicates x 45); the design's candidates (population x generations x positions x
    dwell, :func:`.study_commands.design_sizes`); inspect and compensate the record file's bytes x
    :data:`COSTS`. report reads the study's own result tables: nothing to size."""
    if command in COSTS.per_byte:
        return COSTS.record(command, args.data)
    if command in ("simulate", "identify") and args.scheme:
        scheme = resolve_scheme(args.scheme, study.schemes)
        size = _scheme_size(study, scheme, command)
        # an identify past --chunk-rows streams the record one position at a time (identify_command)
        streams = command == "identify" and chunk_rows_of(args) and streamable(study.filter)
        return [one_at_a_time(size, scheme.n_positions) if streams else size]
    if command == "observability" and args.scheme:
        scheme = resolve_scheme(args.scheme, study.schemes)
        out = [_scheme_size(study, scheme, "simulate")]
        if args.replicates:
            out += [Size("--replicates", args.replicates, len(load_catalogue().frame()), 1,
                         "the Monte Carlo's estimation errors"),
                    replace(_scheme_size(study, scheme, "identify", 1, args.replicates), field="--replicates")]
        return out
    if command == "montecarlo":
        # the config as validated (the study section's cross-checks are the cell's, after --out's)
        st = study.config["study"]
        case = CentrifugeMonteCarlo().case(study.config, args.scheme, args.scheme_file)
        return [_scheme_size(study, case, "identify", min(st["batch"], st["replicates"]), 0),
                Size("study.replicates", st["replicates"], len(load_catalogue().frame()), 1, "the cell's estimates"),
                replace(_scheme_size(study, case, "identify", 1, st["replicates"]), field="study.replicates")]
    if command == "design":   # the design search's module (pymoo) is imported only when it is chosen
        return resolve(f"{_STUDY}:design_sizes")(study, args)
    return []


_HERE, _STUDY = __name__, f"{__package__}.study_commands"
COMMANDS = {"inspect": f"{_HERE}:inspect_command", "simulate": f"{_HERE}:simulate_command",
            "identify": f"{_HERE}:identify_command", "observability": f"{_STUDY}:observability_command",
            "design": f"{_STUDY}:design_command", "montecarlo": f"{_STUDY}:montecarlo_command",
            "report": f"{_STUDY}:report_command", "compensate": f"{_HERE}:compensate_command",
            "kernels": f"{__package__}.aot_kernels:kernels_command"}
"""Each sub-command by module path (:func:`platcal.rig.resolve`): the commands on a log live
here, those of the study (observability, design, Monte Carlo cell, report: pymoo, matplotlib)
in :mod:`.study_commands`, imported only when one of them is chosen."""

SCHEME = option("--scheme", default=None, help="scheme name of the config (e.g. table1, classical) or a scheme YAML file")
CHUNK = CHUNK_OPTION
OPTIONS = {
    "simulate": (SCHEME, CHUNK),
    "identify": (SCHEME, CHUNK, option("--estimator", default=None,
                                       help="estimator kind or study.estimators name (default: filter.estimator)")),
    "observability": (SCHEME,
                      option("--arw", type=real(0, unit="deg/sqrt(h)"), default=None, help="override the filter's ARW, deg/sqrt(h)"),
                      option("--rate", type=real(0, unit="deg/s"), default=None, help="override the centrifuge rate, deg/s (0: static 1 g)"),
                      option("--doo", action="store_true", help="51-state filter with DOO_x/y/z as states"),
                      option("--replicates", type=COUNT, default=0,
                             help="also run this many Monte Carlo replicates to compare with the CRB")),
    "design": (option("--criterion", choices=("J", "A", "D", "maxrel"), default=None, help="override design.criterion"),
               option("--positions", type=whole(1), default=None, help="override design.positions"),
               option("--population", type=whole(1), default=None, help="override design.population"),
               option("--generations", type=whole(1), default=None, help="override design.generations"),
               option("--seed", type=SEED, default=None, help="override design.seed"),
               option("--name", default=None, help="override design.name"),
               option("--preset", default=None, help="a named design of the workflow (e.g. ga_A, ga_J_n8, ga_doo)"),
               option("-v", "--verbose", action="store_true", help="log every generation")),
    "montecarlo": (option("--scheme", required=True, help="scheme name (config, classical, random_<i>, or generated)"),
                   option("--scheme-file", default=None, help="scheme file of a generated scheme"),
                   option("--noise", "--sigma-a", dest="noise", type=real(0, unit="ug per sample"), default=None,
                          help="sigma_a, ug per sample (default: the config's noise.sigma_a_ug)"),
                   option("--estimator", required=True, help="a key of study.estimators")),
}
"""The centrifuge's own options (``--seed`` of simulate: replicate N of the study's Monte Carlo cell
for the scheme and the config's noise, default 0)."""
