"""The cells of the centrifuge's estimator comparison (issue 9 item 4): which cells there are,
what each depends on, and the job that runs one (docs/centrifuge-model.md §10-11).

Apart from :mod:`platcal.rigs.centrifuge.compare` (the comparison's tables, figures and report
section) because a cell job and the workflow's master process need none of what those need
(matplotlib, scipy.stats: about 1.5 s of CPU to import, in each of the comparison's cell jobs
and its collect job). A cell's tables are numpy columns (:class:`platcal.lighttable.Table`,
written to Parquet through pyarrow), so a cell job loads no pandas either (issue 22 item 4); the
comparison's collect is the generic :func:`platcal.study.collect.collect_job`.
The cells, their seeds and their outputs are described in :mod:`platcal.rigs.centrifuge.compare`.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...lighttable import Table
from ...log import job_logger
from ...rig import get_rig
from ...study.montecarlo import cell_tables, write_cell
from ...study.sweep import noise_label
from .study import builtin_scheme, check_study, study_for_cell


def compare_settings(cfg: dict) -> dict:
    """``study.compare`` of a checked config with its estimator list filled in (names, in order)."""
    c = dict(cfg["study"]["compare"])
    c["estimators"] = list(c["estimators"]) or list(cfg["study"]["estimators"])
    return c


def with_compare_estimators(cfg: dict) -> dict:
    """The config whose ``study.estimators`` also holds the comparison's own definitions
    (``study.compare.estimators`` given as a mapping), so the generic cell runs them."""
    own = cfg["study"]["compare"]["estimators"]
    if not isinstance(own, dict) or not own:
        return cfg
    out = {**cfg, "study": {**cfg["study"], "estimators": {**cfg["study"]["estimators"], **own}}}
    return out


def compare_levels(cfg: dict) -> dict[str, float]:
    """File label -> noise level of the comparison's cells."""
    return {noise_label(v): float(v) for v in compare_settings(cfg)["sigma_a_ug"]}


def compare_cells(cfg: dict) -> list[tuple[str, str]]:
    """(noise label, estimator) of every comparison cell, in order: every estimator at every level
    of ``study.compare.sigma_a_ug``, except those that ``study.compare.levels_of`` limits to some
    levels (a costly estimator run only at the paper's setting). InputError naming the field for a
    name that is not a comparison estimator or a level that is not compared."""
    c = compare_settings(cfg)
    only = c.get("levels_of") or {}
    levels = [float(v) for v in c["sigma_a_ug"]]
    for name, lv in only.items():
        if name not in c["estimators"]:
            raise InputError(f"study.compare.levels_of.{name}", f"{name!r} is not an estimator of the comparison "
                             f"({c['estimators']})")
        for i, v in enumerate(lv):
            if float(v) not in levels:
                raise InputError(f"study.compare.levels_of.{name}[{i}]", f"{v:g} ug is not a level of "
                                 f"study.compare.sigma_a_ug ({levels})")
    return [(noise_label(v), e) for v in c["sigma_a_ug"] for e in c["estimators"]
            if e not in only or float(v) in [float(u) for u in only[e]]]


def cell_params(cfg: dict, level: float, estimator: str) -> dict:
    """What a comparison cell's numbers depend on (a Snakemake param)."""
    hooks = get_rig("centrifuge").montecarlo
    cfg = with_compare_estimators(cfg)
    c = compare_settings(cfg)
    p = hooks.cell_params(cfg, c["scheme"], level, estimator)
    p["replicates"] = int(c["replicates"])
    return p


def kind_of(cfg: dict, name: str) -> str:
    """The estimator kind of a comparison estimator's name."""
    entry = with_compare_estimators(cfg)["study"]["estimators"][name]
    return str(entry.get("estimator", cfg["filter"]["estimator"]))


def passes_of(cfg: dict, name: str) -> int:
    entry = with_compare_estimators(cfg)["study"]["estimators"][name]
    return int(entry.get("passes", cfg["filter"]["passes"]))


def warm_estimator(cfg: dict, scheme, level: float, estimator: str) -> None:
    """Run ``estimator`` (a name of ``study.estimators`` of the checked ``cfg``) once on a 2-period
    version of ``scheme`` at ``level`` (ug), one replicate: its numba kernels compiled, or loaded
    from numba's cache, and nothing written (docs/centrifuge-model.md §10-11)."""
    short = replace(scheme, dwell_s=2 * float(cfg["filter"]["period_ms"]) / 1000.0)
    get_rig("centrifuge").montecarlo.run_batch(cfg, short, level, estimator, [np.random.SeedSequence(0)])


def warm_kernels(cfg: dict) -> None:
    """Compile (or load) the kernels of every estimator of the sweep and of the comparison once
    (:func:`warm_estimator` on the comparison's scheme), so that the cells, the comparison's cells
    and the single run that follow load them from numba's cache instead of compiling them side by
    side (issue 22 item 4). ``cfg``: the raw or checked centrifuge config."""
    cfg = with_compare_estimators(check_study(cfg))
    scheme = builtin_scheme(cfg, compare_settings(cfg)["scheme"])
    level = float(cfg["study"]["sigma_a_ug"][0])
    for name in cfg["study"]["estimators"]:  # the sweep's and the comparison's own, in order
        warm_estimator(cfg, scheme, level, name)


def level_estimators(cfg: dict, level: float) -> list[str]:
    """The comparison estimators that run at ``level`` (ug), in :func:`compare_cells` order.
    ``cfg``: a checked config."""
    return [e for label, e in compare_cells(cfg) if label == noise_label(level)]


def level_params(cfg: dict, level: float) -> dict:
    """What a comparison level job's numbers depend on (a Snakemake param): :func:`cell_params`
    of every estimator of the level, by name, so an edit of one estimator's settings reruns the
    level's job."""
    return {e: cell_params(cfg, level, e) for e in level_estimators(cfg, level)}


def estimator_tables(cfg: dict, scheme, level: float, estimator: str, threads: int = 1) -> tuple[Table, Table, dict]:
    """One estimator's cell of the comparison at ``level`` (ug): its tidy tables and timing, the
    runs table with the cost per run (``wall_s``, ``cpu_s``: the cell's mean, simulation and
    filter, every thread of the process) measured around its own runs after its warm-up
    (docs/centrifuge-model.md §10-11). ``cfg``: checked, with the comparison's estimators."""
    # load the compiled kernels before the clock starts, so the cost per run is the runs', not the
    # process's start-up
    warm_estimator(cfg, scheme, level, estimator)
    t0, c0 = time.perf_counter(), time.process_time()
    coef, runs, timing = cell_tables(get_rig("centrifuge"), cfg, scheme, level, estimator,
                                     replicates=int(compare_settings(cfg)["replicates"]), threads=threads)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    # the comparison's runs table is machine-dependent in these two columns only
    R = max(len(runs), 1)
    runs["wall_s"] = np.full(len(runs), wall / R)
    runs["cpu_s"] = np.full(len(runs), cpu / R)
    timing["cpu_s"] = cpu
    return coef, runs, timing


def compare_level_job(cfg: dict, level: float, out_dir, threads: int = 1, log_path=None) -> None:
    """Rule body: every estimator of one noise level of the comparison (:func:`level_estimators`),
    one after another in one process (one process start-up per level instead of one per
    estimator; issue 22 item 4), into one ``coef.parquet``, ``runs.parquet`` (the estimators' rows
    in order, an ``estimator`` column) and ``timing.json`` (a list: one timing record per
    estimator) under ``out_dir``. Every estimator's filter settings are checked before any work
    (InputError naming the field)."""
    lg = job_logger(log_path)
    cfg = with_compare_estimators(check_study(cfg, cells=[]))
    names = level_estimators(cfg, level)
    if not names:
        raise InputError("study.compare.sigma_a_ug", f"{level:g} ug is not a level of the comparison "
                         f"({compare_settings(cfg)['sigma_a_ug']})")
    for name in names:  # the filter checks that check_study(cfg, cells=...) runs, the level's only
        study_for_cell(cfg, level, name)
    c = compare_settings(cfg)
    scheme = builtin_scheme(cfg, c["scheme"])
    lg.info("comparison level %s, sigma_a = %g ug, estimators %s: %d replicates each", scheme.name, level,
            ", ".join(names), c["replicates"])
    cells = []
    for name in names:
        cells.append(estimator_tables(cfg, scheme, level, name, threads))
        runs = cells[-1][1]
        lg.info("  %s: mean NEES %.1f, %.3f s CPU per run", name, runs["nees"].mean(), runs["cpu_s"].mean())
    write_cell(out_dir, Table.concat([t[0] for t in cells]), Table.concat([t[1] for t in cells]),
               [t[2] for t in cells])
    lg.info("done -> %s", out_dir)
