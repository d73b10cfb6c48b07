"""The ``platcal`` command line: simulate, identify (and the study tools built on them).

Every sub-command reads ``--config``, looks up the config's ``rig:`` (:mod:`platcal.rig`) and
runs ``RIG.commands[<sub-command>](RIG.load_config(raw), args)``. The parser holds the union of
the rigs' options; each rig checks the ones it needs and refuses the others. Bad input exits
with status 2 and a message naming the field, before any output is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from .errors import InputError
from .io import read_yaml
from .logs.calibration import read_calibration
from .rig import rig_of

RIG_OPTIONS = {
    "simulate": (("--scheme", "scheme name in the config, or a scheme YAML file (rigs with schemes)"),
                 ("--platform", "platform name of the config (rigs with several platforms)"),
                 ("--run", "run name of the platform (rigs with several runs)")),
    "identify": (("--scheme", "scheme name in the config, or a scheme YAML file (rigs with schemes)"),
                 ("--estimator", "estimator name (default: the rig's default)"),
                 ("--method", "identification method (rigs with several methods)")),
}
"""Options that only some rigs use: every rig checks the ones it needs and refuses the others."""

CONFIG_HELP = "study configuration (YAML); its 'rig:' selects the rig"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="platcal", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="simulate a test of the config's rig and write its test record")
    s.add_argument("--config", required=True, help=CONFIG_HELP)
    s.add_argument("--seed", type=int, default=None,
                   help="which run: the centrifuge and multiposition write replicate N of the study's Monte Carlo "
                        "cell for this scheme and the config's noise (default 0); the sled and the low-precision "
                        "centrifuge write seed N of their studies (default: the config's seed)")
    s.add_argument("--noise-free", action="store_true", help="no sensor noise and no setting error")
    s.add_argument("--out", required=True, help="test record to write (.csv or .parquet)")

    i = sub.add_parser("identify", help="identify the rig's coefficients from a test record")
    i.add_argument("--config", required=True, help=CONFIG_HELP)
    i.add_argument("--data", required=True, help="test record (.csv or .parquet)")
    i.add_argument("--out", required=True, help="output folder")
    i.add_argument("--no-truth", action="store_true", help="do not compare with the config's truth")
    for name, parser in (("simulate", s), ("identify", i)):
        for opt, help_ in RIG_OPTIONS[name]:
            parser.add_argument(opt, default=None, help=help_)

    n = sub.add_parser("inspect", help="what a log holds as the rig reads it: columns, units, rate, dwells, gaps")
    n.add_argument("--config", required=True, help=CONFIG_HELP + "; its 'record:' maps the log's columns and units")
    n.add_argument("--data", required=True, help="the log (.csv or .parquet)")

    c = sub.add_parser("compensate", help="apply an identification (calibration.yaml) to a log")
    c.add_argument("--calibration", required=True, help="calibration.yaml written by platcal identify")
    c.add_argument("--data", required=True, help="the log (.csv or .parquet), read through the calibration's "
                                                 "config 'record:' mapping")
    c.add_argument("--out", required=True, help="compensated log to write (.csv or .parquet)")

    o = sub.add_parser("observability", help="covariance-only run of a scheme: J, correlations, rank, CRB")
    o.add_argument("--config", required=True, help=CONFIG_HELP)
    o.add_argument("--scheme", default=None, help="scheme name in the config, or a scheme YAML file (rigs with schemes)")
    o.add_argument("--out", required=True, help="output folder (observability.json, ...)")
    o.add_argument("--arw", type=float, default=None, help="override the filter's ARW, deg/sqrt(h) (centrifuge)")
    o.add_argument("--rate", type=float, default=None,
                   help="override the centrifuge rate, deg/s (0: static 1 g) (centrifuge)")
    o.add_argument("--doo", action="store_true", help="51-state filter with DOO_x/y/z as states (centrifuge)")
    o.add_argument("--replicates", type=int, default=0,
                   help="also run this many Monte Carlo replicates to compare with the CRB")

    d = sub.add_parser("design", help="genetic-algorithm search for a test scheme (pymoo)")
    d.add_argument("--config", required=True, help="study configuration (YAML); its 'design:' section")
    d.add_argument("--out", required=True, help="scheme file to write (SCHEME.yaml; history, population beside)")
    d.add_argument("--criterion", choices=("J", "A", "D", "maxrel"), default=None, help="override design.criterion")
    d.add_argument("--positions", type=int, default=None, help="override design.positions")
    d.add_argument("--population", type=int, default=None, help="override design.population")
    d.add_argument("--generations", type=int, default=None, help="override design.generations")
    d.add_argument("--seed", type=int, default=None, help="override design.seed")
    d.add_argument("--name", default=None, help="override design.name")
    d.add_argument("--preset", default=None, help="a named design of the workflow (e.g. ga_A, ga_J_n8, ga_doo)")
    d.add_argument("-v", "--verbose", action="store_true", help="log every generation")

    m = sub.add_parser("montecarlo", help="run one (scheme, noise level, estimator) cell of the Monte Carlo study")
    m.add_argument("--config", required=True, help=CONFIG_HELP)
    m.add_argument("--scheme", required=True, help="scheme name (config, classical, random_<i>, or generated)")
    m.add_argument("--scheme-file", default=None, help="scheme file of a generated scheme")
    m.add_argument("--noise", "--sigma-a", dest="noise", type=float, default=None,
                   help="the swept noise level in the rig's unit (centrifuge: sigma_a, ug per sample)")
    m.add_argument("--estimator", required=True, help="a key of study.estimators")
    m.add_argument("--threads", type=int, default=1, help="threads (numba) or joblib workers")
    m.add_argument("--out", required=True, help="output folder (coef.parquet, runs.parquet, timing.json)")

    r = sub.add_parser("report", help="write the rig's report.md from the study's tables and figures")
    r.add_argument("--config", required=True, help=CONFIG_HELP)
    r.add_argument("--results", default="results/centrifuge",
                   help="the rig's results folder (default: results/centrifuge)")
    return p


def read_config(path) -> dict:
    """The raw mapping of a config file (InputError naming ``--config`` if it cannot be read)."""
    try:
        return read_yaml(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("--config", f"no such file: {path}") from None
    except IsADirectoryError:
        raise InputError("--config", f"{path} is a folder; give a YAML config file") from None
    except UnicodeDecodeError as exc:
        raise InputError("--config", f"{path} is not UTF-8 text (byte {exc.start} cannot be decoded); "
                         "a config is a UTF-8 YAML file") from None
    except (ValueError, yaml.YAMLError) as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        problem = getattr(exc, "problem", None)
        raise InputError("--config", f"{path} is not valid YAML{at} ({problem or exc.__class__.__name__}); "
                         "a config is a UTF-8 YAML file") from None


def run(args: argparse.Namespace) -> int:
    """Run a parsed command through the config's rig."""
    if args.command == "compensate":  # the config is the one the calibration was identified with
        cal = read_calibration(args.calibration)
        raw = {**cal.config, "rig": cal.rig}
    else:
        raw = read_config(args.config)
    rig = rig_of(raw)
    if args.command not in rig.commands:
        raise InputError("rig", f"rig {rig.name!r} has no '{args.command}' command; it has {sorted(rig.commands)}")
    return rig.commands[args.command](rig.load_config(raw), args)


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run(args)
    except InputError as exc:
        print(f"platcal {args.command}: error: {exc.field}: {exc.message}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
