"""The ``platcal`` command line: simulate, identify (and the study tools built on them).

Bad input exits with status 2 and a message naming the field, before any output is written.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from .errors import InputError


def _study_and_scheme(args):
    from .config import load_config
    from .scheme import resolve_scheme

    if not args.scheme:
        raise InputError("--scheme", "required for rig centrifuge: a scheme name of the config or a scheme YAML file")
    study = load_config(args.config)
    return study, resolve_scheme(args.scheme, study.schemes)


def cmd_simulate(args) -> int:
    from .record import sim_to_frame, write_record
    from .simulate import simulate

    study, scheme = _study_and_scheme(args)
    if args.seed is not None and args.seed < 0:
        raise InputError("--seed", "must be a whole number >= 0")
    seeds = None if args.noise_free else [np.random.SeedSequence(study.seed if args.seed is None else args.seed)]
    t0 = time.perf_counter()
    sim = simulate(study.truth, scheme, study.centrifuge.scheme_params(scheme), study.noise, seeds,
                   sample_s=study.sample_s)
    write_record(sim_to_frame(sim, scheme), args.out)
    print(f"platcal simulate: scheme {scheme.name!r}, {scheme.n_positions} positions x {scheme.dwell_s:g} s, "
          f"{'noise-free' if seeds is None else 'seed ' + str(args.seed if args.seed is not None else study.seed)}"
          f" -> {args.out} ({time.perf_counter() - t0:.2f} s)", file=sys.stderr)
    return 0


def cmd_identify(args) -> int:
    from .identify import identify_record, timed, truth_known, write_identification
    from .record import read_record

    study, scheme = _study_and_scheme(args)
    df = read_record(args.data)
    est, seconds = timed(identify_record, study, scheme, df)
    summary = write_identification(args.out, est, study, truth_known(df) and not args.no_truth, seconds)
    msg = f"platcal identify: {len(est.names)}-state EKF, {study.filter.passes} pass(es), {seconds:.2f} s -> {args.out}"
    if "nees" in summary:
        msg += (f"; max |rel err| gyro {summary['max_abs_rel_err_pct_gyro']:.2f} %, accel "
                f"{summary['max_abs_rel_err_pct_accel']:.3f} %, NEES {summary['nees']:.1f} (dof {summary['nees_dof']})")
    print(msg, file=sys.stderr)
    return 0


RIG_OPTIONS = {
    "simulate": (("--scheme", "scheme name in the config, or a scheme YAML file (rigs with schemes)"),
                 ("--platform", "platform name of the config (rigs with several platforms)"),
                 ("--run", "run name of the platform (rigs with several runs)")),
    "identify": (("--scheme", "scheme name in the config, or a scheme YAML file (rigs with schemes)"),
                 ("--estimator", "estimator name (default: the rig's default)"),
                 ("--method", "identification method (rigs with several methods)")),
}
"""Options that only some rigs use: every rig checks the ones it needs and refuses the others."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="platcal", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="simulate a test of the config's rig and write its test record")
    s.add_argument("--config", required=True, help="study configuration (YAML); its 'rig:' selects the rig")
    s.add_argument("--seed", type=int, default=None, help="seed of this run (default: the config's seed)")
    s.add_argument("--noise-free", action="store_true", help="no sensor noise and no setting error")
    s.add_argument("--out", required=True, help="test record to write (.csv or .parquet)")
    s.set_defaults(func=cmd_simulate)

    i = sub.add_parser("identify", help="identify the rig's coefficients from a test record")
    i.add_argument("--config", required=True, help="study configuration (YAML); its 'rig:' selects the rig")
    i.add_argument("--data", required=True, help="test record (.csv or .parquet)")
    i.add_argument("--out", required=True, help="output folder")
    i.add_argument("--no-truth", action="store_true", help="do not compare with the config's truth")
    i.set_defaults(func=cmd_identify)
    for name, parser in (("simulate", s), ("identify", i)):
        for opt, help_ in RIG_OPTIONS[name]:
            parser.add_argument(opt, default=None, help=help_)

    for register in _extensions():
        register(sub)
    return p


EXTENSION_MODULES = ("observability", "design", "montecarlo", "report")
"""Modules that add sub-commands through a ``register_cli(subparsers)`` function."""


def _extensions():
    """Sub-command registrars of the study tools (observability, design, montecarlo, report)."""
    import importlib

    regs = []
    for name in EXTENSION_MODULES:
        try:
            mod = importlib.import_module(f"platcal.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"platcal.{name}":
                raise
            continue
        if hasattr(mod, "register_cli"):
            regs.append(mod.register_cli)
    return regs


def _rig_command(args):
    """The config's rig's own implementation of this sub-command (None for the centrifuge's).

    The config file is read here only for its ``rig:`` key; the rig validates the rest.
    """
    from pathlib import Path

    from .io import read_yaml
    from .rig import DEFAULT_RIG, rig_of

    path = getattr(args, "config", None)
    if path is None:
        return None
    try:
        raw = read_yaml(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("--config", f"no such file: {path}") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError("--config", f"not a UTF-8 YAML file ({exc.__class__.__name__})") from None
    rig = rig_of(raw)
    if rig.name == DEFAULT_RIG:
        return None
    if args.command not in rig.commands:
        raise InputError("rig", f"rig {rig.name!r} has no '{args.command}' command; it has {sorted(rig.commands)}")
    return lambda: rig.commands[args.command](rig.load_config(raw), args)


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        run = _rig_command(args)
        return run() if run is not None else args.func(args)
    except InputError as exc:
        print(f"platcal {args.command}: error: {exc.field}: {exc.message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
