"""The cells of the centrifuge's estimator comparison (issue 9 item 4): which cells there are,
what each depends on, and the job that runs one (docs/centrifuge-model.md §10-11).

Apart from :mod:`platcal.rigs.centrifuge.compare` (the comparison's tables, figures and report
section) because a cell job and the workflow's master process need none of what those need
(matplotlib, scipy.stats: about 1.5 s of CPU to import, in each of the comparison's cell jobs
and its collect job). A cell's tables are numpy columns (:class:`platcal.lighttable.Table`,
written to Parquet through pyarrow), so a cell job loads no pandas either (issue 22 item 4); the
comparison's collect is the generic :func:`platcal.study.collect.collect_job`.
The cells, their seeds and their outputs are described in :mod:`platcal.rigs.centrifuge.compare`.

One job per noise level (:func:`compare_level_job`) runs every estimator of the level: its
estimators see the same replicates (the seeds do not depend on the estimator), so each chunk of
replicates is simulated once and identified by each estimator in turn (:func:`level_tables`),
with the numbers of each estimator's cell run alone, bit for bit, one process start-up and one
simulation per level instead of one per estimator (issue 22 item 4).
"""

from __future__ import annotations

import time
from dataclasses import replace
from functools import partial

import numpy as np

from ...errors import InputError
from ...estimation.passes import run_with_takers, takers
from ...lighttable import Table
from ...log import eta_line, job_logger
from ...parallel import set_threads
from ...rig import get_rig
from ...study.montecarlo import chunks, replicate_seeds, tidy_tables, write_cell
from ...study.sweep import noise_label
from .identify import identify_shared, pass_prefixes, simulate_shared
from .study import builtin_scheme, check_study, replicate_batch, study_for_cell


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


def clocks() -> np.ndarray:
    """(wall, process CPU) seconds now."""
    return np.array([time.perf_counter(), time.process_time()])


def level_tables(cfg: dict, scheme, level: float, studies: dict, threads: int = 1,
                 progress=None) -> tuple[list[tuple[Table, Table, dict]], np.ndarray]:
    """Every estimator of ``studies`` (name -> its cell's Study, :func:`study_for_cell`, which
    checks its filter) on the comparison's replicates at ``level`` (ug), a chunk of
    ``study.batch`` replicates at a time: each chunk simulated once, from the seeds of
    :func:`~platcal.study.montecarlo.cell_tables` (every estimator of a level sees the same
    records), and identified by every estimator in turn, so the job holds one chunk's records
    (docs/centrifuge-model.md §8-11; :func:`~.identify.simulate_shared`, kept at the greatest
    common divisor of the estimators' filter periods): each estimator's numbers are those of its
    cell run alone (``cell_tables``), bit for bit. ``cfg``: checked, with the
    comparison's estimators; ``threads``: numba threads (the chunks run in the job's process
    whatever ``study.backend``: the comparison's rule runs one thread); ``progress(done, total,
    seconds)`` after each chunk.

    An estimator whose run another's gives on the way (the EKF of 1 pass and of 2 passes, the
    same settings otherwise: :func:`~.identify.pass_prefixes`) takes its estimates from that run
    after its own passes, with the same numbers bit for bit, instead of filtering the records again.

    Returns, per estimator in order, ``(coef, runs, timing)`` as ``cell_tables`` gives them, the
    runs table with the cost per run (``wall_s``, ``cpu_s``: the estimator's mean over its runs,
    measured around its own calls after its warm-up, not the simulation; for an estimator taken
    on the way, the run's clocks at the end of its passes), and the level's simulation time
    (wall, CPU s), shared by its estimators."""
    hooks = get_rig("centrifuge").montecarlo
    R = int(compare_settings(cfg)["replicates"])
    batch = int(hooks.settings(cfg).batch)
    names, studies = list(studies), list(studies.values())
    set_threads(threads)
    for name in names:
        # load the compiled kernels before the clocks start, so the cost per run is the runs', not
        # the process's start-up
        warm_estimator(cfg, scheme, level, name)
    parts = [[] for _ in names]
    spent = np.zeros((len(names), 2))
    simulation = np.zeros(2)
    t0 = time.perf_counter()
    on_the_way = pass_prefixes({name: st.filter for name, st in zip(names, studies)})
    given = takers(on_the_way)   # name -> {name: passes} of the estimators its run gives on the way
    for reps in chunks(R, batch):
        c = clocks()
        records = simulate_shared(studies, scheme, replicate_seeds(hooks, cfg, scheme, level, reps))
        simulation += clocks() - c
        for i, (name, st) in enumerate(zip(names, studies)):
            if name in on_the_way:
                continue   # tabled from on_the_way[name]'s run below
            est, ran, taken = run_with_takers(partial(identify_shared, st, scheme, records), given.get(name, {}),
                                              clocks)
            for other, (est_j, upto) in taken.items():
                j = names.index(other)
                c = clocks()
                parts[j].append(tidy_tables(replicate_batch(studies[j], est_j), scheme.name, level, names[j], reps))
                spent[j] += upto + clocks() - c
            c = clocks()
            parts[i].append(tidy_tables(replicate_batch(st, est), scheme.name, level, name, reps))
            spent[i] += ran + clocks() - c
        if progress:
            progress(reps[-1] + 1, R, time.perf_counter() - t0)
    out = []
    for name, part, (wall, cpu) in zip(names, parts, spent):
        coef, runs = Table.concat([p[0] for p in part]), Table.concat([p[1] for p in part])
        # the comparison's runs table is machine-dependent in these two columns only
        runs["wall_s"] = np.full(len(runs), wall / R)
        runs["cpu_s"] = np.full(len(runs), cpu / R)
        timing = {"scheme": scheme.name, "noise": float(level), "estimator": name, "replicates": R,
                  "threads": threads, "backend": "numba", "batch": batch, "wall_s": wall, "wall_s_per_run": wall / R,
                  "compute_s": wall, "cpu_s": cpu, "level_simulation_wall_s": simulation[0],
                  "level_simulation_cpu_s": simulation[1]}
        out.append((coef, runs, timing))
    return out, simulation


def compare_level_job(cfg: dict, level: float, out_dir, threads: int = 1, log_path=None) -> None:
    """Rule body: every estimator of one noise level of the comparison (:func:`level_estimators`)
    in one process, on records simulated once (:func:`level_tables`; one process start-up and one
    simulation per level instead of one per estimator; issue 22 item 4), into one
    ``coef.parquet``, ``runs.parquet`` (the estimators' rows in order, an ``estimator`` column)
    and ``timing.json`` (a list: one timing record per estimator) under ``out_dir``. Every
    estimator's filter settings are checked before any work (InputError naming the field)."""
    lg = job_logger(log_path)
    cfg = with_compare_estimators(check_study(cfg, cells=[]))
    names = level_estimators(cfg, level)
    if not names:
        raise InputError("study.compare.sigma_a_ug", f"{level:g} ug is not a level of the comparison "
                         f"({compare_settings(cfg)['sigma_a_ug']})")
    # the filter checks that check_study(cfg, cells=...) runs, the level's only, before any work
    studies = {name: study_for_cell(cfg, level, name) for name in names}
    c = compare_settings(cfg)
    scheme = builtin_scheme(cfg, c["scheme"])
    lg.info("comparison level %s, sigma_a = %g ug, estimators %s: %d replicates each", scheme.name, level,
            ", ".join(names), c["replicates"])

    def progress(done, total, seconds):
        lg.info("  replicates %s", eta_line(done, total, seconds))

    cells, (wall, cpu) = level_tables(cfg, scheme, level, studies, threads, progress)
    lg.info("simulation, once for the level's estimators: %.2f s wall, %.2f s CPU (%.4f s CPU per run)", wall, cpu,
            cpu / max(int(c["replicates"]), 1))
    for name, (_, runs, _) in zip(names, cells):
        lg.info("  %s: mean NEES %.1f, %.3f s CPU per run", name, runs["nees"].mean(), runs["cpu_s"].mean())
    write_cell(out_dir, Table.concat([t[0] for t in cells]), Table.concat([t[1] for t in cells]),
               [t[2] for t in cells])
    lg.info("done -> %s", out_dir)
