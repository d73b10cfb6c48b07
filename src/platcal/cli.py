"""The ``platcal`` command line: simulate, identify (and the study tools built on them).

Every sub-command reads ``--config``, looks up the config's ``rig:`` (:mod:`platcal.rig`) and
runs ``RIG.command(<sub-command>)(RIG.load_config(raw), args)``. The parser holds the common
options (:data:`COMMON`) and the options the config's rig declares (``Rig.options``): any other
option is refused, and ``--help`` with ``--config`` lists the rig's. Bad input exits with status
2 and a message naming the field, before any output is written. No rig is named here.

A command's module is imported when the command is chosen (the rigs' command tables and
:data:`GENERIC_RUN` hold module paths, :func:`platcal.rig.resolve`): ``identify`` of one rig
loads neither matplotlib nor the planner, the report or the design search (issue 22 item 3).
"""

from __future__ import annotations

import argparse
import re
import sys


from .errors import EXIT_REFUSED, InputError, error_line
from .io import read_config
from .logs.calibration import read_calibration
from .rig import COUNT, SEED, option, resolve, rig_of, whole
from .sizes import MAX_HOURS, MAX_MEMORY, check_sizes, command_sizes

CONFIG_HELP = "study configuration (YAML); its 'rig:' selects the rig"
COMMANDS = {
    "simulate": "simulate a test of the config's rig and write its test record",
    "identify": "identify the rig's coefficients from a test record",
    "observability": "covariance-only analysis of a test: rank, correlations, CRB",
    "design": "genetic-algorithm search for a test scheme (pymoo)",
    "montecarlo": "run one (case, noise level, estimator) cell of the rig's Monte Carlo study",
    "report": "write the rig's report.md from the study's tables and figures",
    "inspect": "what a log holds as the rig reads it: columns, units, rate, dwells, gaps",
    "compensate": "apply an identification (calibration.yaml) to a log",
    "kernels": "compile the rig's identify kernels ahead of time (numba.pycc, a C compiler) into the per-user "
               "cache: identify then loads neither numba nor llvmlite",
}
COMMON = {
    "simulate": (option("--seed", type=SEED, default=None, help="which run: replicate N of the study's Monte Carlo for the rigs with one, else seed N of its study (default: the config's)"),
                 option("--noise-free", action="store_true", help="no sensor noise and no setting error"),
                 option("--out", required=True, help="test record to write (.csv or .parquet)")),
    "identify": (option("--data", required=True, help="test record (.csv or .parquet)"),
                 option("--out", required=True, help="output folder"),
                 option("--no-truth", action="store_true", help="do not compare with the config's truth")),
    "observability": (option("--out", required=True, help="output folder (observability.json, ...)"),),
    "design": (option("--out", required=True, help="scheme file to write (SCHEME.yaml; history, population beside)"),),
    "montecarlo": (option("--threads", type=whole(1, 1024), default=1, help="threads (numba) or joblib workers"),
                   option("--out", required=True, help="output folder (coef.parquet, runs.parquet, timing.json)")),
    "report": (option("--results", default=None, help="the rig's results folder (default: results/<rig>)"),),
    "inspect": (option("--data", required=True, help="the log (.csv or .parquet), read through the config's "
                                                    "'record:' mapping"),),
    "compensate": (option("--calibration", required=True, help="calibration.yaml written by platcal identify"),
                   option("--data", required=True, help="the log (.csv or .parquet), read through the "
                                                        "calibration's config 'record:' mapping"),
                   option("--out", required=True, help="compensated log to write (.csv or .parquet)")),
    "kernels": (),
}
"""Options every rig's sub-command takes; a rig adds its own (``Rig.options``)."""
GENERIC = {
    "plan": ("plan a calibration campaign across rigs: the cheapest tests meeting every target",
             (option("--campaign", required=True, help="campaign file (YAML; schema: platcal/study/data/"
                                                       "campaign.schema.yaml)"),
              option("--out", required=True, help="output folder (plan.csv, coefficients.csv, alternatives.csv, ...)"),
              option("--replicates", type=COUNT, default=None,
                     help="Monte Carlo replicates of the plan's check (default: the campaign's; 0: none)"))),
}
"""Sub-commands of no one rig (no ``--config``): each asks the rigs its input names through
their hooks (``plan``: :mod:`platcal.study.campaign`)."""
GENERIC_RUN = {"plan": "platcal.study.campaign:plan_command"}
"""The function of each generic sub-command, by module path (imported when it is chosen)."""


class _ParseError(Exception):
    """A command line the parser refuses (unknown option, missing value): exit status 2.
    ``unknown``: the option is not one of the rig's (the message then points at ``--help``)."""

    def __init__(self, message: str, unknown: bool = False):
        super().__init__(message)
        self.unknown = unknown


_BAD_VALUE = re.compile(r"^argument ([^\s:/]+)(?:/\S+)?: (.*)$", re.S)
"""argparse's "argument --noise/--sigma-a: got nan; give ..." (a ``type=`` refusal)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        extra = message.split(":", 1)[1].split() if message.startswith("unrecognized arguments:") else []
        flag = next((a.split("=")[0] for a in extra if a.startswith("-")), None)
        # name the option first, as every other refusal does ("error: FIELD: what")
        if flag:
            raise _ParseError(f"{flag}: not an option here ({message})", unknown=True)
        bad = _BAD_VALUE.match(message)
        raise _ParseError(f"{bad.group(1)}: {bad.group(2)}" if bad else message)


def build_parser(rig=None) -> argparse.ArgumentParser:
    """The parser of every sub-command: the common options, and ``rig``'s own when given (else a
    note that ``--config`` shows them)."""
    p = _Parser(prog="platcal", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for command, help_ in COMMANDS.items():
        own = rig.options.get(command, ()) if rig is not None else ()
        epilog = (f"options of rig {rig.name!r} ({rig.title})" if rig is not None
                  else "give --config FILE with --help to see the options of its rig")
        c = sub.add_parser(command, help=help_, description=help_, epilog=epilog)
        if command != "compensate":  # compensate applies the config the calibration was identified with
            c.add_argument("--config", required=True, help=CONFIG_HELP)
        for opt in COMMON[command] + (MAX_MEMORY, MAX_HOURS) + tuple(own):
            c.add_argument(*opt.flags, **opt.kwargs)
    for command, (help_, options) in GENERIC.items():
        c = sub.add_parser(command, help=help_, description=help_)
        for opt in options + (MAX_MEMORY, MAX_HOURS):
            c.add_argument(*opt.flags, **opt.kwargs)
    return p


def _config_of(argv) -> tuple[str | None, str | None]:
    """The ``--config`` and ``--calibration`` of a command line, before the full parse (None when absent)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--config", default=None)
    pre.add_argument("--calibration", default=None)
    known = pre.parse_known_args(argv)[0]
    return known.config, known.calibration


def _raw_config(command: str, path, calibration) -> dict | None:
    """The raw config a command runs with: ``compensate``'s is the one stored in its calibration."""
    if command == "compensate":
        if not calibration:
            return None
        cal = read_calibration(calibration)
        return {**cal.config, "rig": cal.rig}
    return read_config(path) if path else None


def run(args: argparse.Namespace, raw: dict, rig) -> int:
    """Run a parsed command through the config's rig."""
    if args.command not in rig.commands:
        raise InputError("rig", f"rig {rig.name!r} has no '{args.command}' command; it has {sorted(rig.commands)}")
    if getattr(args, "results", "") is None:
        args.results = f"results/{rig.name}"
    cfg = rig.load_config(raw)
    # the memory and time the inputs imply, refused before any allocation
    check_sizes(command_sizes(rig, args.command, cfg, args), args.max_memory_gb, args.max_hours)
    return rig.command(args.command)(cfg, args)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), "platcal")
    path = rig = None
    try:
        path, calibration = _config_of(argv)
        raw = _raw_config(command, path, calibration)
        rig = rig_of(raw) if raw is not None else None
        args = build_parser(rig).parse_args(argv)
        if args.command in GENERIC_RUN:
            return resolve(GENERIC_RUN[args.command])(args)
        return run(args, raw, rig)
    except _ParseError as exc:
        where = (f"; 'platcal {command} --config {path} --help' lists the options of rig {rig.name!r}"
                 if rig and exc.unknown else "")
        print(f"platcal {command}: error: {exc}{where}", file=sys.stderr)
        return 2
    except (InputError, OSError) as exc:  # bad input; a full disk, no permission: one line, not a traceback
        print(f"platcal {command}: error: {error_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED


if __name__ == "__main__":
    sys.exit(main())
