"""The centrifuge's study sub-commands (``observability``, ``design``, ``montecarlo``,
``report``): ``fn(study, args) -> int`` for ``RIG.commands``, as in :mod:`.commands`; apart from
it so that the commands on a log (simulate, identify, ...) do not import the design search
(pymoo), the report's figures (matplotlib) or the Monte Carlo runner (issue 22 item 3).
"""

from __future__ import annotations

import argparse
import sys
import time

from ...errors import InputError
from ...io import check_writable
from ...sizes import Size
from ...study.montecarlo import estimator_runs, write_cell
from .commands import scheme_option
from .config import Study, check_filter
from .design import design_config, preset, run_design, write_design
from .observability import write_observability
from .report import report_from_results


def observability_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal observability``: covariance-only analysis of a scheme."""
    check_filter(study.filter)
    scheme = scheme_option(study, args)
    check_writable(args.out, "--out", folder=True)
    t0 = time.perf_counter()
    res = write_observability(args.out, study, scheme, replicates=args.replicates, arw_deg_rth=args.arw,
                              estimate_doo=True if args.doo else None, rate_deg_s=args.rate)
    om = res["observability_matrix"]
    msg = (f"platcal observability: scheme {scheme.name!r}: J = {res['J']:.2f} over {res['n_pairs']} pairs "
           f"(ARW {res['settings']['arw_deg_rth']:g}), A = {res['criteria']['A']:.3g}, "
           f"max rel sigma {res['criteria']['maxrel']:.3g} %, observability rank {om['rank']}/{om['n_cols']}")
    if "monte_carlo" in res:
        msg += f"; MC RMS rel err {res['monte_carlo']['rms_rel_err_pct_45']:.3f} % ({args.replicates} runs)"
    print(msg + f" -> {args.out} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    return 0


def design_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal design``: the genetic-algorithm scheme search."""
    check_filter(study.filter)
    if not str(args.out).endswith((".yaml", ".yml")):
        raise InputError("--out", "must be a scheme file name ending in .yaml")
    check_writable(args.out, "--out")
    over = dict(criterion=args.criterion, positions=args.positions, population=args.population,
                generations=args.generations, seed=args.seed, name=args.name)
    if args.preset:
        study, dcfg = preset(study, args.preset)
        dcfg = design_config({**study.config, "design": dcfg}, **over)
    else:
        dcfg = design_config(study.config, **over)
    log = (lambda m: print(m, file=sys.stderr)) if args.verbose else None
    res = run_design(study, dcfg, log=log)
    write_design(res, args.out)
    print(f"platcal design: {res.scheme.name}: {dcfg['criterion']} = {res.value:.4g} "
          f"(J {res.criteria['J']:.2f}, max rel sigma {res.criteria['maxrel']:.3g} %), "
          f"{dcfg['population']} x {dcfg['generations']} generations, {res.position_runs} position runs, "
          f"{res.seconds:.0f} s -> {args.out}", file=sys.stderr)
    return 0


def montecarlo_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal montecarlo``: one (scheme, sigma_a, estimator) cell of the sweep."""
    check_filter(study.filter)
    if args.noise is None:
        raise InputError("--noise", "required for rig centrifuge: the accelerometer noise sigma_a, ug per sample")
    check_writable(args.out, "--out", folder=True)
    for _, coef, runs, timing in estimator_runs("centrifuge", study.config, args.scheme, args.noise, [args.estimator],
                                                threads=args.threads, case_file=args.scheme_file):
        write_cell(args.out, coef, runs, timing)
    return 0


def report_command(study: Study, args: argparse.Namespace) -> int:
    """``platcal report``: rewrite ``report.md`` from a results folder's tables."""
    out = report_from_results(study.config, args.results)
    print(f"platcal report: -> {out}")
    return 0


SECONDS_PER_DESIGN_SECOND = 2e-4
"""CPU seconds the design search takes per candidate position-second (population x generations x
positions x dwell_s; an upper bound: the search caches repeated position runs), measured by
benchmarks/size_estimate.py (population 8, 1 and 4 generations, 6 x 60 s: 0.85 CPU s over 8640,
9.8e-5; load 4 on 2 cores), rounded up 2x for the load's noise."""


def design_sizes(study: Study, args: argparse.Namespace) -> list[Size]:
    """The design search's work (:mod:`platcal.sizes`): its candidate position-seconds (population
    x generations x positions x dwell_s) x :data:`SECONDS_PER_DESIGN_SECOND`; it holds little."""
    dcfg = design_config(study.config, population=args.population, generations=args.generations,
                         positions=args.positions)
    field = "--generations" if args.generations else "design.generations"
    work = float(dcfg["population"]) * float(dcfg["generations"]) * dcfg["positions"] * dcfg["dwell_s"]
    return [Size(field, work, 0, 1, f"the search's population {dcfg['population']} x {dcfg['generations']} "
                 f"generations x {dcfg['positions']} positions x {dcfg['dwell_s']:g} s dwell",
                 SECONDS_PER_DESIGN_SECOND, unit="candidate position-seconds")]
