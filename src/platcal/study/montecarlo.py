"""The generic Monte Carlo runner: cases x noise levels x estimators x replicates of any rig.

A rig plugs in through its :class:`~platcal.rig.MonteCarloHooks` (``Rig.montecarlo``); this
module only derives the seeds, batches the replicates, runs them (numba threads or joblib
workers) and turns the rig's :class:`~platcal.rig.ReplicateBatch` into the tidy tables.

Seeding
-------
Replicate r of case C at noise level v draws from ``SeedSequence(seed, spawn_key=(stable_key(C),
noise_key(v), r))`` (:func:`replicate_seed`): ``stable_key`` is the first 4 bytes of the name's
SHA-256, never Python's salted ``hash``; ``noise_key`` is the level in thousandths of its unit
(``round(1000 v)``), so the key belongs to the level itself, not to its position in the list.
The estimators are not part of the key: every estimator of a cell sees the same data (common
random numbers); a case may key its seeds by another name (its ``seed_key``), shared by cases
that must see the same data too. A replicate's numbers do not depend on the batch it runs in,
the number of threads or joblib workers, or the job order.

Tidy tables
-----------
``coef``: one row per run x identified quantity, columns :data:`COEF_COLUMNS`; ``runs``: one
row per run, :data:`RUN_COLUMNS` and then the rig's own per-run columns
(``ReplicateBatch.extra``), if any. The case column is called ``scheme`` and the noise column
``noise`` (in the rig's ``NoiseAxis.unit``) whatever the rig.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import re
import time
from collections.abc import Sequence
from functools import lru_cache, partial
from typing import TYPE_CHECKING
from importlib import resources
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from ..estimation.passes import run_with_takers, takers
from ..estimation.relative import rel_err_pct
from ..io import atomic_files, atomic_folder, json_safe
from ..lighttable import Table
from ..log import eta_line, job_logger
from ..parallel import set_threads
from ..rig import Rig, get_rig, resolve
from .sweep import replicate_seed

if TYPE_CHECKING:  # annotations only: a cell job builds and writes its tables without pandas (issue 22 item 4)
    import pandas as pd

CELL = ["scheme", "noise", "estimator"]
"""Columns that name a cell of the sweep."""
COEF_COLUMNS = CELL + ["replicate", "name", "group", "unit", "truth", "estimate", "sigma", "error",
                       "rel_err_pct"]
RUN_COLUMNS = CELL + ["replicate", "passes", "nees", "nees_dof", "mean_nis", "failed_updates", "failed"]
BACKENDS = {"joblib": "platcal.study.workers:map_chunks"}
"""The backends that run a cell's chunks outside the job's process, by ``study.backend`` name:
each a ``map_chunks(fn, calls, workers, consume)`` named by path, so that a cell on the default
``numba`` backend (its chunks in the job's process) does not import joblib."""


def chunks(n: int, size: int) -> list[list[int]]:
    """Replicate indices 0..n-1 in chunks of at most ``size``."""
    return [list(range(a, min(a + size, n))) for a in range(0, n, size)]


def chunk_sizes(n: int, size: int) -> set[int]:
    """The distinct lengths of :func:`chunks` ``(n, size)``: the batch sizes a cell of ``n``
    replicates runs, so a warm-up compiles the one-replicate kernels only when a cell needs them."""
    return {len(c) for c in chunks(n, size)}


def tidy_tables(batch, case: str, level: float, estimator: str, replicates) -> tuple[Table, Table]:
    """The tidy ``coef`` and ``runs`` rows of a :class:`~platcal.rig.ReplicateBatch` as numpy
    columns (:class:`platcal.lighttable.Table`): a cell job never imports pandas."""
    q = batch.quantities
    n = len(q)
    B = len(replicates)
    reps = np.asarray(replicates, dtype=np.int64)
    truth = batch_truth(batch).ravel()
    estimate = np.asarray(batch.estimate).ravel()
    text = lambda v, size: np.full(size, v, dtype=object)  # noqa: E731  (one text value repeated)
    coef = Table({
        "scheme": text(case, B * n), "noise": np.full(B * n, float(level)), "estimator": text(estimator, B * n),
        "replicate": np.repeat(reps, n), "name": np.array(list(q["name"]) * B, dtype=object),
        "group": np.array(list(q["group"]) * B, dtype=object), "unit": np.array(list(q["unit"]) * B, dtype=object),
        "truth": truth, "estimate": estimate, "sigma": np.asarray(batch.sigma).ravel(),
        "error": estimate - truth, "rel_err_pct": rel_err_pct(estimate, truth),
    })
    runs = Table({
        "scheme": text(case, B), "noise": np.full(B, float(level)), "estimator": text(estimator, B),
        "replicate": reps, "passes": np.full(B, int(batch.passes), dtype=np.int64), "nees": np.asarray(batch.nees),
        "nees_dof": np.full(B, int(batch.nees_dof), dtype=np.int64), "mean_nis": np.asarray(batch.mean_nis),
        "failed_updates": np.asarray(batch.failed_updates).astype(np.int64), "failed": failed_runs(batch),
    })
    for k, v in batch.extra.items():  # the rig's own per-run columns, after the standard ones
        runs[k] = np.asarray(v)
    return coef, runs


def tidy_frames(batch, case: str, level: float, estimator: str, replicates) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The tidy ``coef`` and ``runs`` rows of a :class:`~platcal.rig.ReplicateBatch` as pandas
    DataFrames (:func:`tidy_tables`)."""
    coef, runs = tidy_tables(batch, case, level, estimator, replicates)
    return coef.to_pandas(), runs.to_pandas()


def batch_truth(batch) -> np.ndarray:
    """(B, n) truth of every replicate: the batch's own per-replicate truth, else the
    quantities' truth repeated."""
    B = len(np.asarray(batch.nees))
    if batch.truth is not None:
        return np.asarray(batch.truth, float).reshape(B, len(batch.quantities))
    return np.tile(batch.quantities["truth"].to_numpy(float), (B, 1))


def failed_runs(batch) -> np.ndarray:
    """(B,) bool: a run that cannot be trusted, with failed updates or a non-finite estimate, sigma,
    NEES or mean NIS (the estimate alone for an estimator without ``uncertainty``). Such runs stay
    in the tidy tables, flagged, and the summary counts them."""
    est = np.asarray(batch.estimate, float).reshape(len(batch.nees), -1)
    sig = np.asarray(batch.sigma, float).reshape(len(batch.nees), -1)
    finite = np.isfinite(est).all(axis=1)
    if batch.uncertainty:
        finite &= (np.isfinite(sig).all(axis=1) & np.isfinite(np.asarray(batch.nees, float))
                   & np.isfinite(np.asarray(batch.mean_nis, float)))
    return (np.asarray(batch.failed_updates) > 0) | ~finite


def replicate_seeds(hooks, cfg: dict, case, level: float, replicates) -> list[np.random.SeedSequence]:
    """The SeedSequences of ``replicates`` (indices) of ``case`` at ``level`` (module doc,
    "Seeding"): those :func:`cell_tables` hands the rig's ``run_batch``, for a job that simulates
    a chunk once for several estimators."""
    key = getattr(case, "seed_key", case.name)
    seed = hooks.settings(cfg).seed
    return [replicate_seed(seed, key, level, r) for r in replicates]


def _run_chunk(rig_name: str, cells: dict, level: float, replicates, numba_threads: int,
               given: dict | None = None) -> dict:
    """One chunk of replicates of every estimator of ``cells`` (name -> (its checked config, its
    case)): simulated once for all when the rig has ``simulate_cell`` and there are several
    (the first estimator's case simulates; :mod:`platcal.rig`, "Monte Carlo hooks"), else each
    estimator's ``run_batch``. ``given`` (with a shared simulation only: the rig's
    ``pass_prefixes`` of the cells inverted, :func:`platcal.estimation.passes.takers`): an
    estimator that differs from another only by fewer passes is tabled from that one's run after
    its own passes (:func:`platcal.estimation.passes.run_with_takers`) instead of identifying the
    data again.
    Returns name -> (coef, runs, seconds): its identification's seconds (for one taken on the
    way, the run's at the end of its passes) plus an equal share of the shared simulation's. The
    rig is looked up by name so that a joblib worker can rebuild it."""
    set_threads(numba_threads)
    hooks = get_rig(rig_name).montecarlo
    cfg, case = next(iter(cells.values()))
    seeds = replicate_seeds(hooks, cfg, case, level, replicates)
    parts, simulation = {}, 0.0   # name -> (its batch, its identification's seconds)
    if len(cells) > 1 and hasattr(hooks, "simulate_cell"):
        t0 = time.perf_counter()
        data = hooks.simulate_cell({e: c for e, (c, _) in cells.items()}, case, level, seeds)
        simulation = (time.perf_counter() - t0) / len(cells)
        given = given or {}
        taken_on_the_way = {e for names in given.values() for e in names}
        for estimator, (cfg, case) in cells.items():
            if estimator in taken_on_the_way:
                continue
            batch, seconds, taken = run_with_takers(partial(hooks.identify_cell, cfg, case, level, estimator, data),
                                                    given.get(estimator, {}))
            parts.update(taken)
            parts[estimator] = (batch, seconds)
    else:
        for estimator, (cfg, case) in cells.items():
            t0 = time.perf_counter()
            parts[estimator] = (hooks.run_batch(cfg, case, level, estimator, seeds), time.perf_counter() - t0)
    out = {}
    for estimator, (cfg, case) in cells.items():  # in the cells' order
        t0 = time.perf_counter()
        batch, seconds = parts[estimator]
        coef, runs = tidy_tables(batch, case.name, level, estimator, replicates)
        out[estimator] = (coef, runs, seconds + time.perf_counter() - t0 + simulation)
    return out


def cells_tables(rig: Rig, cells: dict, level: float, *, replicates: int | None = None, threads: int = 1,
                 backend: str | None = None, batch: int | None = None, progress=None) -> dict:
    """Run every replicate of one (case, noise level) cell of ``rig`` for every estimator of
    ``cells`` (name -> (its checked config, ``rig.montecarlo.check``; its case object, whose
    ``name`` keys the seeds)), chunk by chunk, each chunk of every estimator before the next
    (:func:`_run_chunk`: one simulation per chunk for a rig with ``simulate_cell``). The run
    settings (replicates, batch, backend) are the first estimator's: the estimators of one call
    share them. ``threads``: numba threads for ``backend='numba'``, joblib workers (each with one
    numba and one BLAS thread) for ``'joblib'``. ``replicates``, ``backend``, ``batch`` default to
    the rig's settings; ``progress(done, total, seconds)`` is called after each chunk.

    Returns name -> ``(coef, runs, timing)``: the tidy tables (:class:`platcal.lighttable.Table`,
    numpy columns: a cell job loads no pandas) and wall-time information (s), which is the only
    output that depends on the machine (an estimator's ``compute_s`` its own seconds plus an equal
    share of the shared simulation's; ``wall_s`` the cell's wall time in the same proportion).
    """
    cfg, case = next(iter(cells.values()))
    st = rig.montecarlo.settings(cfg)
    R = int(st.replicates if replicates is None else replicates)
    backend = backend or st.backend
    batch = int(batch or st.batch)
    threads = max(1, int(threads))
    parts = chunks(R, batch)
    t0 = time.perf_counter()
    # the estimator that runs -> {estimator: passes} of those its run gives on the way
    given = (takers(rig.montecarlo.pass_prefixes({e: c for e, (c, _) in cells.items()}, case, level))
             if len(cells) > 1 and hasattr(rig.montecarlo, "pass_prefixes") else {})
    if backend in BACKENDS and threads > 1 and len(parts) > 1:
        # one numba thread and one BLAS thread per worker: threads workers use threads cores
        results = resolve(BACKENDS[backend])(_run_chunk, [(rig.name, cells, level, p, 1, given) for p in parts],
                                             threads, lambda gen: _collect_progress(gen, R, t0, progress))
    else:
        results = _collect_progress((_run_chunk(rig.name, cells, level, p, threads, given) for p in parts),
                                    R, t0, progress)
    wall = time.perf_counter() - t0
    spent = {e: float(sum(r[e][2] for r in results)) for e in cells}
    out = {}
    for estimator in cells:
        coef = Table.concat([r[estimator][0] for r in results])
        coef = coef[np.argsort(coef["replicate"], kind="stable")]
        runs = Table.concat([r[estimator][1] for r in results])
        runs = runs[np.argsort(runs["replicate"], kind="stable")]
        share = wall * spent[estimator] / max(sum(spent.values()), 1e-300)
        timing = {"scheme": case.name, "noise": float(level), "estimator": estimator,
                  "replicates": R, "threads": threads, "backend": backend, "batch": batch,
                  "wall_s": share, "wall_s_per_run": share / max(R, 1), "compute_s": spent[estimator]}
        out[estimator] = (coef[COEF_COLUMNS], runs[RUN_COLUMNS + [c for c in runs.columns if c not in RUN_COLUMNS]],
                          timing)
    return out


def cell_tables(rig: Rig, cfg: dict, case, level: float, estimator: str, **kw) -> tuple[Table, Table, dict]:
    """Run every replicate of one (case, noise level, estimator) cell of ``rig``: :func:`cells_tables`
    of that estimator alone (``cfg`` its checked config, ``case`` its case object; same keywords).
    Returns ``(coef, runs, timing)``."""
    return cells_tables(rig, {estimator: (cfg, case)}, level, **kw)[estimator]


def run_cell(rig: Rig, cfg: dict, case, level: float, estimator: str, **kw) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """:func:`cell_tables` with the tidy tables as pandas DataFrames (the comparison's cells and
    the tests work on them); same keywords."""
    coef, runs, timing = cell_tables(rig, cfg, case, level, estimator, **kw)
    return coef.to_pandas(), runs.to_pandas(), timing


def _collect_progress(gen, total: int, t0: float, progress) -> list:
    results, done = [], 0
    for res in gen:
        results.append(res)
        done += len(next(iter(res.values()))[1])
        if progress:
            progress(done, total, time.perf_counter() - t0)
    return results


def write_cell(out_dir: str | os.PathLike, coef: Table | pd.DataFrame, runs: Table | pd.DataFrame,
               timing: dict | list[dict]) -> None:
    """``coef.parquet``, ``runs.parquet`` and ``timing.json`` of a cell (``timing``: its record, or a
    list of records for a job of several estimators), each written atomically;
    the tables :class:`platcal.lighttable.Table` (written through pyarrow, no pandas) or pandas
    DataFrames (written as pandas writes them). Either reads back as the same DataFrame.

    ``timing.json`` is written last: the Snakemake rule lists all three, and a job killed before
    the end leaves no complete set.
    """
    with atomic_files(out_dir) as tmp:  # the three land together or not at all
        for name, table in (("coef.parquet", coef), ("runs.parquet", runs)):
            if isinstance(table, Table):
                pq.write_table(table.to_arrow(), tmp(name))
            else:
                table.to_parquet(tmp(name), index=False)
        tmp("timing.json").write_text(json.dumps(json_safe(timing), indent=2, sort_keys=True, allow_nan=False) + "\n")


def estimator_groups(hooks, checked: dict) -> list[list[str]]:
    """The estimators of a cell (``checked``: name -> its checked config) in the groups that run
    together, in order: with the rig's ``simulate_cell``, those of equal run settings (seed,
    replicates, batch, backend: the same chunks of the same seeds) share each chunk's simulation;
    otherwise each runs alone."""
    if not hasattr(hooks, "simulate_cell"):
        return [[e] for e in checked]
    groups: dict = {}
    for e, c in checked.items():
        st = hooks.settings(c)
        groups.setdefault((st.seed, st.replicates, st.batch, st.backend), []).append(e)
    return list(groups.values())


def estimator_runs(rig_name: str, cfg: dict, case_name: str, level: float, estimators: Sequence[str],
                   threads: int = 1, log_path=None, case_file=None):
    """Check every estimator's part of the config for a (case, noise level) cell, then return an
    iterator that runs them (:func:`estimator_groups`: together when they can share the
    simulation, else one after the other), yielding ``(estimator, coef, runs, timing)`` of
    :func:`cells_tables` group by group and logging what runs and how far it is.
    The checks run before this returns: a bad estimator refuses the cell before any of them runs."""
    lg = job_logger(log_path)
    rig = get_rig(rig_name)
    hooks = rig.montecarlo
    # the workflow's master checked the whole config before any job: a cell checks what it uses
    check_cell = getattr(hooks, "check_cell", None)
    checked = {e: check_cell(cfg, case_name, level, e) if check_cell else hooks.check(cfg) for e in estimators}
    cases = {e: hooks.case(c, case_name, case_file) for e, c in checked.items()}

    def progress(done, total, seconds):
        lg.info("  replicates %s", eta_line(done, total, seconds))

    def run():
        for group in estimator_groups(hooks, checked):
            st = hooks.settings(checked[group[0]])
            lg.info("%s cell %s, %s = %g %s, estimator(s) %s: %d replicates, %d thread(s), backend %s, batch %d%s",
                    rig.name, case_name, hooks.noise.name, level, hooks.noise.unit, ", ".join(group),
                    st.replicates, threads, st.backend, st.batch,
                    ", one simulation per chunk for all" if len(group) > 1 else "")
            done = cells_tables(rig, {e: (checked[e], cases[e]) for e in group}, level, threads=threads,
                                progress=progress)
            for estimator, (coef, runs, timing) in done.items():
                lg.info("  %s done: mean NEES %.1f (dof %d), %.2f s per run", estimator, runs["nees"].mean(),
                        int(runs["nees_dof"].iloc[0]), timing["wall_s_per_run"])
                yield estimator, coef, runs, timing

    return run()


def cell_files(cells, estimators, name: str) -> list[str]:
    """The file ``name`` of every estimator of every cell folder of ``cells``, as :func:`cell_job`
    writes them (``<cell>/<estimator>/<name>``), cell by cell."""
    return [str(Path(c) / e / name) for c in cells for e in estimators]


def cell_job(rig_name: str, cfg: dict, case_name: str, level: float, estimators: Sequence[str], out_dir,
             threads: int = 1, log_path=None, case_file=None) -> None:
    """Rule body: a (case, noise level) cell run with every estimator of ``estimators``
    (:func:`estimator_runs`) into the folder ``out_dir``, one sub-folder per estimator
    (:func:`write_cell`), the folder renamed into place once all are written.

    One process for all of a cell's estimators: they run on the same data (common random numbers:
    the seeds do not name the estimator), and a process costs 1-1.5 s to start (imports, numba's
    target and its cached kernels) before it runs anything (issue 22 item 4).
    """
    runs = estimator_runs(rig_name, cfg, case_name, level, estimators, threads, log_path, case_file)
    with atomic_folder(out_dir) as tmp:
        for estimator, coef, table, timing in runs:
            write_cell(tmp / estimator, coef, table, timing)  # the layout cell_files reads
    job_logger(log_path).info("done: %d estimator(s) -> %s", len(estimators), out_dir)


# ---------------------------------------------------------------------------------------------
# code version: a rule param, so that an edit under src/ reruns what it can change


def _package_root() -> Path:
    return Path(str(resources.files("platcal")))


def _module_file(module: str) -> Path | None:
    """The source file of a dotted module name: a ``platcal`` module, or the module of a rig
    installed by another package (None when it is not a module)."""
    if module.split(".")[0] != "platcal":
        spec = importlib.util.find_spec(module) if module else None
        return Path(spec.origin) if spec is not None and spec.origin and spec.origin.endswith(".py") else None
    path = _package_root().parent.joinpath(*module.split("."))
    for f in (path.with_suffix(".py"), path / "__init__.py"):
        if f.is_file():
            return f
    return None


@lru_cache(maxsize=None)
def _platcal_imports(path: Path, pkg: str, stamp: tuple[int, int]) -> tuple[str, ...]:
    """The dotted platcal names that the file ``path`` (a module of package ``pkg``) imports,
    relative ones resolved. Cached per (file, mtime, size) ``stamp``: the workflow's master hashes
    every rig's import closure (one parse of each file instead of one per closure, about 0.5 s of
    its start-up), and an edited file is read again."""
    out: list[str] = []
    text = path.read_text()
    tree = ast.parse(text)
    # imports are statements: walking the statements alone (a tenth of the nodes) halves the
    # master's start-up parse; a path is named in an f-string only where __package__ is read
    nodes = ast.walk(tree) if "__package__" in text else _statements(tree.body)
    for node in nodes:
        if isinstance(node, ast.ImportFrom):
            if node.level:
                parts = pkg.split(".")
                target = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] == "platcal":
                out.append(target)
                out.extend(f"{target}.{a.name}" for a in node.names)  # submodules imported by name
        elif isinstance(node, ast.Import):
            out.extend(a.name for a in node.names if a.name.split(".")[0] == "platcal")
        else:
            out.extend(_named_by_path(node, pkg))
    return tuple(out)


STATEMENT_BODIES = ("body", "orelse", "finalbody", "handlers", "cases")
"""The fields of a statement (and of an except handler or a match case) that hold statements."""


def _statements(body):
    """Every statement of ``body`` (a list of statements), nested ones included (function and
    class bodies, branches, loops, with, try and its handlers, match cases), in source order."""
    for node in body:
        yield node
        for field in STATEMENT_BODIES:
            inner = getattr(node, field, None)
            if isinstance(inner, list):
                yield from _statements(inner)


NAMED_BY_PATH = re.compile(r"\.[A-Za-z_][\w.]*:[A-Za-z_]\w*")
"""The tail of a ``f"{__package__}.module:attribute"`` path (:func:`platcal.rig.resolve`)."""


def _named_by_path(node, pkg: str) -> list[str]:
    """The module of the file's own package that ``f"{__package__}.module:attribute"`` names by
    path: the form a rig's kernels use when they are imported only as they run (the multi-position
    and sled lanes kernels, the Lie Jacobian's builder), as much a dependency of the code that
    resolves them as an import statement. Literal ``"platcal.x:attr"`` paths are not followed:
    those in the package draw a figure (``logs.dwells.DWELL_FIGURE``), pick a back-end
    (``study.montecarlo.BACKENDS``) or warm a cache (the rigs' ``warm_kernels``), none of them a
    number of the code that names them, and following them would rerun the cells on a figure's
    edit."""
    if (isinstance(node, ast.JoinedStr) and len(node.values) == 2
            and isinstance(node.values[0], ast.FormattedValue) and isinstance(node.values[0].value, ast.Name)
            and node.values[0].value.id == "__package__" and isinstance(node.values[1], ast.Constant)
            and NAMED_BY_PATH.fullmatch(str(node.values[1].value))):
        return [pkg + str(node.values[1].value).partition(":")[0]]
    return []


def module_closure(roots) -> list[str]:
    """Dotted platcal modules imported (anywhere in the file) by ``roots``, recursively: a static
    reading of the import statements, relative ones resolved."""
    seen: set[str] = set()
    todo = list(roots)
    while todo:
        mod = todo.pop()
        path = _module_file(mod) if mod not in seen else None
        if path is None:
            continue
        seen.add(mod)
        pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        st = path.stat()
        todo.extend(_platcal_imports(path, pkg, (st.st_mtime_ns, st.st_size)))
    return sorted(seen)


def code_hash(modules=None, data=()) -> str:
    """SHA-256 (16 hex digits) of source and data files of the package: of every ``.py``,
    ``.csv`` and ``.yaml`` file by default, else of the dotted ``modules`` and the package-relative
    ``data`` files."""
    root = _package_root()
    if modules is None:
        files = [p for p in root.rglob("*") if p.suffix in (".py", ".csv", ".yaml") and p.is_file()]
    else:
        files = [_module_file(m) for m in modules] + [root / d for d in data]
    def key(p: Path) -> str:  # package-relative, or the file's own path for a rig of another package
        return p.relative_to(root).as_posix() if p.is_relative_to(root) else p.as_posix()

    h = hashlib.sha256()
    for p in sorted({f for f in files if f is not None}, key=key):
        h.update(key(p).encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


# A rig's claims are read by the claims rule alone (its hash is the whole package's), so editing a
# claim must not rerun the rig's simulations.
LEDGER_DATA = ("claims.yaml",)


def _package_data(package: str) -> list[str]:
    """Package-relative paths of a subpackage's ``data/*.csv|yaml`` (config schema, tables), the
    claims ledger's file excepted."""
    f = _module_file(package)
    if f is None or not f.is_relative_to(_package_root()):
        return []
    return [p.relative_to(_package_root()).as_posix() for p in sorted((f.parent / "data").glob("*"))
            if p.suffix in (".csv", ".yaml") and p.name not in LEDGER_DATA]


def compute_code_hash(rig: Rig) -> str:
    """Code hash of what a rig's Monte Carlo cells compute: the import closure of its hooks'
    module and of this runner, and the rig's package data (config schema, tables). Edits to its
    figures, reports or design code leave the cells alone."""
    hooks_module = type(rig.montecarlo).__module__
    return code_hash(module_closure([hooks_module, __name__]),
                     _package_data(hooks_module.rpartition(".")[0] or hooks_module))


def package_code_hash(package: str) -> str:
    """Code hash of a whole subpackage (e.g. a rig's study): the import closure of all its
    modules, shared core included, and its package data; the rule param of a rig's own rules."""
    pkg = _module_file(package).parent
    mods = module_closure([package] + [f"{package}.{p.stem}" for p in sorted(pkg.glob("*.py"))])
    return code_hash(mods, _package_data(package))
