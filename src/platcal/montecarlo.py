"""Monte Carlo sweep: schemes x noise levels x estimators x replicates (issue 3).

Seeding
-------
Every replicate's randomness comes from one ``SeedSequence(entropy=study.seed,
spawn_key=(scheme_key, noise_key, replicate))``:

* ``scheme_key`` is a stable 32-bit key of the scheme's *name* (first 4 bytes of its SHA-256),
  never Python's salted ``hash``;
* ``noise_key`` is the accelerometer noise level in ng (``round(sigma_a_ug * 1000)``), so the
  key belongs to the level itself, not to its position in the config's list: adding or
  removing a level leaves the other levels' numbers unchanged;
* ``replicate`` counts from 0.

The estimators are not part of the key: every estimator of a cell sees the same data (common
random numbers), so their differences are the filters', not the draws'. A replicate's numbers do
not depend on the batch it runs in, the number of threads or joblib workers, or the job order.

Schemes of a study
------------------
``study.schemes`` lists names: a scheme of the config's ``schemes:`` section; ``classical``
(the orthogonal 6-position scheme, each platform axis in turn up and down); ``random`` (expands
to ``random_1 .. random_N``, drawn from ``study.random_schemes.seed``) or one ``random_<i>``;
and ``ga_*`` / any name listed in ``study.generated_schemes``, which resolve to a scheme file
``results/design/<name>.yaml`` written by a workflow rule (the design issue).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import sys
import time
from dataclasses import replace
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError

log = logging.getLogger("platcal.montecarlo")

CLASSICAL_POSITIONS = ((0, 0, 0), (180, 0, 0), (90, 0, 90), (90, 0, 270), (90, 0, 0), (90, 0, 180))
"""Orthogonal 6-position scheme, deg: z_p up, z_p down, x_p up, x_p down, y_p up, y_p down
(beta = 0; the up axis in p is column 3 of C_r^p = Mz(gamma) Mx(alpha))."""

GENERATED_PREFIX = "ga_"
"""Scheme names with this prefix resolve to ``<results>/design/<name>.yaml`` (the GA design)."""

COEF_COLUMNS = ["scheme", "sigma_a_ug", "estimator", "replicate", "name", "group", "unit", "truth",
                "estimate", "sigma", "error", "rel_err_pct"]
RUN_COLUMNS = ["scheme", "sigma_a_ug", "estimator", "replicate", "passes", "nees", "nees_dof", "mean_nis",
               "failed_updates"]


# ---------------------------------------------------------------------------------------------
# seeding


def stable_key(name: str) -> int:
    """A stable 32-bit integer key of a name (SHA-256; independent of PYTHONHASHSEED)."""
    return int.from_bytes(hashlib.sha256(name.encode("utf-8")).digest()[:4], "big")


def noise_key(sigma_a_ug: float) -> int:
    """Key of an accelerometer noise level: the level in ng, rounded (5 ug -> 5000)."""
    return int(round(float(sigma_a_ug) * 1000.0))


def replicate_seed(seed: int, scheme: str, sigma_a_ug: float, replicate: int) -> np.random.SeedSequence:
    """The SeedSequence of one replicate of one (scheme, noise level) cell."""
    return np.random.SeedSequence(entropy=int(seed),
                                  spawn_key=(stable_key(scheme), noise_key(sigma_a_ug), int(replicate)))


def noise_label(sigma_a_ug: float) -> str:
    """File-name label of a noise level (``10`` -> ``'10'``, ``2.5`` -> ``'2.5'``)."""
    return f"{float(sigma_a_ug):g}"


# ---------------------------------------------------------------------------------------------
# schemes of the study


def classical_scheme(dwell_s: float):
    """The orthogonal 6-position scheme (each platform axis in turn up and down)."""
    from .scheme import check_scheme

    return check_scheme("classical", {"dwell_s": dwell_s, "positions": [list(p) for p in CLASSICAL_POSITIONS]})


def random_schemes(seed: int, count: int, n_positions: int, dwell_s: float) -> list:
    """``count`` random schemes: alpha, gamma whole degrees in [0, 359], beta = 0 (spec 10).

    Scheme i (1-based) is drawn from ``SeedSequence(seed, spawn_key=(stable_key('random'), i))``,
    so scheme ``random_2`` is the same whatever ``count`` is.
    """
    from .scheme import check_scheme

    out = []
    for i in range(1, count + 1):
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(stable_key("random"), i)))
        ag = rng.integers(0, 360, size=(n_positions, 2))
        pos = [[int(a), 0, int(g)] for a, g in ag]
        out.append(check_scheme(f"random_{i}", {"dwell_s": dwell_s, "positions": pos}))
    return out


def is_generated(name: str, study_cfg: dict) -> bool:
    """True when the scheme is produced by a workflow rule (a scheme file), not by the config."""
    return name.startswith(GENERATED_PREFIX) or name in study_cfg.get("generated_schemes", [])


def scheme_names(cfg: dict) -> list[str]:
    """The sweep's scheme names in order, ``random`` expanded; raises InputError naming the field.

    ``cfg`` is a validated configuration (defaults filled in).
    """
    st = cfg["study"]
    n_random = st["random_schemes"]["count"]
    out: list[str] = []
    for i, name in enumerate(st["schemes"]):
        field = f"study.schemes[{i}]"
        if name == "random":
            new = [f"random_{j}" for j in range(1, n_random + 1)]
        elif (name in cfg["schemes"] or name == "classical" or is_generated(name, st)):
            new = [name]
        elif (m := re.fullmatch(r"random_(\d+)", name)) and 1 <= int(m.group(1)) <= n_random:
            new = [name]
        else:
            raise InputError(field, f"unknown scheme {name!r}; use a scheme of the config's 'schemes' "
                             f"({sorted(cfg['schemes'])}), 'classical', 'random', 'random_1'..'random_{n_random}' "
                             f"or a generated '{GENERATED_PREFIX}*' scheme")
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise InputError(field, f"scheme name {name!r} must be letters, digits, '_', '-' or '.' (it names files)")
        for n in new:
            if n in out:
                raise InputError(field, f"scheme {n!r} is listed twice")
            out.append(n)
    return out


def builtin_scheme(cfg: dict, name: str):
    """A scheme that the config defines (config ``schemes:``, ``classical``, ``random_<i>``)."""
    from .scheme import check_scheme

    st = cfg["study"]
    if name in cfg["schemes"]:
        return check_scheme(name, cfg["schemes"][name])
    if name == "classical":
        return classical_scheme(st["dwell_s"])
    m = re.fullmatch(r"random_(\d+)", name)
    if m:
        rs = st["random_schemes"]
        i = int(m.group(1))
        return random_schemes(rs["seed"], i, rs["n_positions"], st["dwell_s"])[i - 1]
    raise InputError("study.schemes", f"scheme {name!r} is not defined by the config (a generated scheme "
                     "is read from its scheme file)")


_FLOAT_RE = re.compile(r"^[-+]?(?:(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?|(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+))$")


def normalise_numbers(obj):
    """Read YAML 1.1 leftovers such as ``'1.0e4'`` (a string to PyYAML's and Snakemake's
    loaders) as floats, in place, as :func:`platcal.io.read_yaml` does; returns ``obj``."""
    items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else ()
    for k, v in list(items):
        if isinstance(v, str) and _FLOAT_RE.match(v):
            obj[k] = float(v.replace("_", ""))
        elif isinstance(v, (dict, list)):
            normalise_numbers(v)
    return obj


def check_study(raw: dict) -> dict:
    """Validate a configuration including its ``study:`` section; return it with defaults.

    Raises InputError naming the field (e.g. ``study.sigma_a_ug[0]``, ``study.schemes[2]``)
    before any job runs.
    """
    from .config import validate_config

    if isinstance(raw, dict):
        raw = normalise_numbers(json.loads(json.dumps(raw)))
    cfg = validate_config(raw)
    st = cfg["study"]
    scheme_names(cfg)
    single = st["single"]
    if single["scheme"] not in cfg["schemes"] and single["scheme"] != "classical" \
            and not re.fullmatch(r"random_\d+", single["scheme"]):
        raise InputError("study.single.scheme", f"unknown scheme {single['scheme']!r}; use a scheme of the "
                         f"config's 'schemes' ({sorted(cfg['schemes'])}) or 'classical'")
    if single["estimator"] not in st["estimators"]:
        raise InputError("study.single.estimator", f"unknown estimator {single['estimator']!r}; the study "
                         f"defines {sorted(st['estimators'])}")
    if single["replicate"] >= st["replicates"]:
        raise InputError("study.single.replicate", f"must be < study.replicates = {st['replicates']}")
    labels = [noise_label(v) for v in st["sigma_a_ug"]]
    if len(set(labels)) != len(labels) or len({noise_key(v) for v in st["sigma_a_ug"]}) != len(labels):
        raise InputError("study.sigma_a_ug", f"noise levels must be distinct (to 0.001 ug), got {st['sigma_a_ug']}")
    for name in st["estimators"]:
        if not re.fullmatch(r"[A-Za-z0-9_-]+", name):
            raise InputError(f"study.estimators.{name}", "an estimator name is letters, digits, '_' or '-'")
    sample = cfg["sampling"]["sample_ms"]
    n = st["dwell_s"] * 1000.0 / sample
    if abs(n - round(n)) > 1e-6:
        raise InputError("study.dwell_s", f"must be a whole number of {sample} ms samples")
    return cfg


# ---------------------------------------------------------------------------------------------
# code version


def code_hash(exclude: tuple[str, ...] = ()) -> str:
    """SHA-256 (16 hex digits) of the package's source and data files, minus ``exclude`` stems.

    A rule param, so that Snakemake reruns the jobs when the package's code changes (an edit
    under ``src/`` is otherwise invisible to it). ``exclude`` drops modules that do not affect
    a rule's output (e.g. the plotting code for the simulation jobs).
    """
    root = resources.files("platcal")
    h = hashlib.sha256()
    files = []
    for sub in ("", "data"):
        d = Path(str(root.joinpath(sub))) if sub else Path(str(root))
        files += [p for p in d.glob("*") if p.suffix in (".py", ".csv", ".yaml") and p.is_file()]
    for p in sorted(files, key=lambda p: p.relative_to(Path(str(root))).as_posix()):
        if p.stem in exclude:
            continue
        h.update(p.relative_to(Path(str(root))).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


COMPUTE_ROOTS = ("montecarlo",)
"""Modules whose import closure (within platcal) a Monte Carlo cell's numbers depend on."""

COMPUTE_DATA = ("config.schema.yaml", "table2.csv")
"""Package data a cell depends on (defaults of the config; the truth of Table 2)."""


def module_closure(roots=COMPUTE_ROOTS) -> list[str]:
    """platcal modules imported (anywhere in the file, also inside functions) by ``roots``,
    recursively: a static reading of ``from .x import`` / ``from . import x`` statements."""
    import ast

    base = Path(str(resources.files("platcal")))
    seen: set[str] = set()
    todo = list(roots)
    while todo:
        mod = todo.pop()
        if mod in seen or not (base / f"{mod}.py").is_file():
            continue
        seen.add(mod)
        for node in ast.walk(ast.parse((base / f"{mod}.py").read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                if node.module:
                    todo.append(node.module.split(".")[0])
                else:
                    todo.extend(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("platcal."):
                todo.append(node.module.split(".")[1])
    return sorted(seen)


def compute_code_hash() -> str:
    """Code hash of what a Monte Carlo cell's numbers depend on: the import closure of
    :mod:`platcal.montecarlo` and the config schema and Table 2 data. Edits elsewhere in the
    package (design, plots, reports) leave the cells alone."""
    keep = set(module_closure()) | {Path(f).stem for f in COMPUTE_DATA}
    base = Path(str(resources.files("platcal")))
    stems = {p.stem for p in base.glob("*.py")} | {p.stem for p in (base / "data").glob("*")}
    return code_hash(tuple(sorted(stems - keep)))


# ---------------------------------------------------------------------------------------------
# running a cell


def set_threads(n: int) -> None:
    """Threads of the numba kernels (prange over the batch); a replicate's result does not depend on it."""
    try:
        from . import parallel  # the colleague's module, once it lands
        parallel.set_threads(n)  # type: ignore[attr-defined]
        return
    except (ImportError, AttributeError):
        pass
    import numba

    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))


def _study_for_cell(cfg: dict, sigma_a_ug: float, estimator: str):
    """The Study of one cell: the config with this noise level and this estimator's settings."""
    from .config import study_from_config

    raw = json.loads(json.dumps(cfg))  # deep copy of plain data
    raw["noise"]["sigma_a_ug"] = float(sigma_a_ug)
    raw["filter"].update(cfg["study"]["estimators"][estimator])
    raw["filter"]["history_s"] = raw["filter"].get("history_s", 1.0)
    return study_from_config(raw)


def run_batch(study, scheme, seeds: list[np.random.SeedSequence], history: bool = False):
    """Simulate and identify a batch of replicates of one scheme; returns (Estimate, seconds).

    Every replicate is independent of the others in the batch (its own SeedSequence, the
    filters never mix rows), so batching only changes speed.
    """
    from .ekf import run_ekf
    from .simulate import simulate

    t0 = time.perf_counter()
    params = study.centrifuge.scheme_params(scheme)
    sim = simulate(study.truth, scheme, params, study.noise, seeds, sample_s=study.sample_s,
                   keep_every=study.keep_every)
    K = scheme.n_positions
    fs = study.filter if history else replace(study.filter, history_every_s=None)
    est = run_ekf([sim.A[:, k] for k in range(K)], [sim.t] * K, scheme.angles_deg, params, fs)
    return est, time.perf_counter() - t0


def _batch_frames(study, est, scheme_name, sigma_a_ug, estimator, replicates):
    from .ekf import nees
    from .instruments import group_of, unit_of
    from .tables import rel_err_pct

    nc = est.n_coef
    names = list(est.names[:nc])
    idx = study.filter.coef_index
    truth = study.truth[idx]
    B = len(replicates)
    est_c = est.coef
    sig = est.coef_sigma
    coef = pd.DataFrame({
        "scheme": scheme_name, "sigma_a_ug": float(sigma_a_ug), "estimator": estimator,
        "replicate": np.repeat(np.asarray(replicates, dtype=np.int64), nc),
        "name": names * B, "group": [group_of(n) for n in names] * B, "unit": [unit_of(n) for n in names] * B,
        "truth": np.tile(truth, B), "estimate": est_c.ravel(), "sigma": sig.ravel(),
    })
    coef["error"] = coef["estimate"] - coef["truth"]
    coef["rel_err_pct"] = rel_err_pct(coef["estimate"], coef["truth"])
    runs = pd.DataFrame({
        "scheme": scheme_name, "sigma_a_ug": float(sigma_a_ug), "estimator": estimator,
        "replicate": np.asarray(replicates, dtype=np.int64), "passes": int(study.filter.passes),
        "nees": nees(est_c, est.P[:, :nc, :nc], truth[None]), "nees_dof": nc,
        "mean_nis": est.mean_nis, "failed_updates": est.failed_updates.astype(np.int64),
    })
    return coef, runs


def _run_chunk(cfg, scheme, scheme_name, sigma_a_ug, estimator, replicates, numba_threads):
    """One chunk of replicates (a joblib task or an in-process batch)."""
    set_threads(numba_threads)
    study = _study_for_cell(cfg, sigma_a_ug, estimator)
    seeds = [replicate_seed(study.seed, scheme_name, sigma_a_ug, r) for r in replicates]
    est, seconds = run_batch(study, scheme, seeds)
    coef, runs = _batch_frames(study, est, scheme_name, sigma_a_ug, estimator, replicates)
    return coef, runs, seconds


def chunks(n: int, size: int) -> list[list[int]]:
    """Replicate indices 0..n-1 in chunks of at most ``size``."""
    return [list(range(a, min(a + size, n))) for a in range(0, n, size)]


def run_cell(cfg: dict, scheme, sigma_a_ug: float, estimator: str, *, replicates: int | None = None,
             threads: int = 1, backend: str | None = None, batch: int | None = None,
             progress=None) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Run every replicate of one (scheme, noise level, estimator) cell.

    Parameters
    ----------
    cfg : validated configuration (``check_study``).
    scheme : the Scheme (its ``name`` keys the seeds).
    sigma_a_ug : accelerometer noise of this cell, ug per sample.
    estimator : a key of ``study.estimators``.
    replicates : number of replicates (default ``study.replicates``).
    threads : the job's threads: numba threads for ``backend='numba'``, joblib workers
        (``n_jobs``, each with one numba thread and one BLAS thread) for ``'joblib'``.
    backend, batch : default ``study.backend`` and ``study.batch``.
    progress : callable(done, total, seconds) called after each chunk.

    Returns
    -------
    (coef, runs, timing): one row per replicate x coefficient; one row per replicate (NEES
    of the 45 coefficient errors against their covariance, mean NIS, failed updates); and
    wall-time information (s), which is the only output that depends on the machine.
    """
    st = cfg["study"]
    R = int(st["replicates"] if replicates is None else replicates)
    backend = backend or st["backend"]
    batch = int(batch or st["batch"])
    threads = max(1, int(threads))
    parts = chunks(R, batch)
    t0 = time.perf_counter()
    results = []
    if backend == "joblib" and threads > 1 and len(parts) > 1:
        from joblib import Parallel, delayed, parallel_config

        # one numba thread and one BLAS thread per worker: threads workers use threads cores
        with parallel_config(backend="loky", inner_max_num_threads=1):
            gen = Parallel(n_jobs=threads, return_as="generator")(
                delayed(_run_chunk)(cfg, scheme, scheme.name, sigma_a_ug, estimator, p, 1) for p in parts)
            done = 0
            for res in gen:
                results.append(res)
                done += len(res[1])
                if progress:
                    progress(done, R, time.perf_counter() - t0)
    else:
        done = 0
        for p in parts:
            results.append(_run_chunk(cfg, scheme, scheme.name, sigma_a_ug, estimator, p, threads))
            done += len(p)
            if progress:
                progress(done, R, time.perf_counter() - t0)
    wall = time.perf_counter() - t0
    coef = pd.concat([r[0] for r in results], ignore_index=True).sort_values(
        ["replicate"], kind="stable").reset_index(drop=True)
    runs = pd.concat([r[1] for r in results], ignore_index=True).sort_values("replicate").reset_index(drop=True)
    timing = {"scheme": scheme.name, "sigma_a_ug": float(sigma_a_ug), "estimator": estimator,
              "replicates": R, "threads": threads, "backend": backend, "batch": batch,
              "wall_s": wall, "wall_s_per_run": wall / max(R, 1),
              "compute_s": float(sum(r[2] for r in results))}
    return coef[COEF_COLUMNS], runs[RUN_COLUMNS], timing


def run_single(cfg: dict, scheme, sigma_a_ug: float, estimator: str, replicate: int, threads: int = 1):
    """One replicate with the filter's history, for Table 2 and the convergence figure.

    It is the same run (same SeedSequence) as replicate ``replicate`` of the Monte Carlo cell.
    Returns (study, Estimate, seconds).
    """
    set_threads(threads)
    study = _study_for_cell(cfg, sigma_a_ug, estimator)
    seeds = [replicate_seed(study.seed, scheme.name, sigma_a_ug, replicate)]
    est, seconds = run_batch(study, scheme, seeds, history=True)
    return study, est, seconds


def history_frame(est, scheme, b: int = 0) -> pd.DataFrame:
    """Long table of the filter's history of run ``b``: t (s), state, estimate, sigma, pass, position."""
    H = est.history_t.size
    n = len(est.names)
    dwell = scheme.dwell_s
    total = dwell * scheme.n_positions
    t = est.history_t
    df = pd.DataFrame({
        "t_s": np.repeat(t, n), "state": list(est.names) * H,
        "estimate": est.history_x[b].ravel(), "sigma": est.history_sigma[b].ravel(),
    })
    df["pass"] = (np.floor(df["t_s"] / total + 1e-9) + 1).astype(int)
    df["position"] = (np.floor((df["t_s"] % total) / dwell + 1e-9) + 1).astype(int).clip(upper=scheme.n_positions)
    return df


# ---------------------------------------------------------------------------------------------
# files


def write_cell(out_dir: str | os.PathLike, coef: pd.DataFrame, runs: pd.DataFrame, timing: dict) -> None:
    """``coef.parquet``, ``runs.parquet`` and ``timing.json`` of a cell, each written atomically.

    ``timing.json`` is written last: the Snakemake rule lists all three, and a job killed before
    the end leaves no complete set.
    """
    from .io import atomic_to_parquet, atomic_write_text

    out = Path(out_dir)
    atomic_to_parquet(coef, out / "coef.parquet")
    atomic_to_parquet(runs, out / "runs.parquet")
    atomic_write_text(out / "timing.json", json.dumps(timing, indent=2, sort_keys=True) + "\n")


def write_single(out_dir: str | os.PathLike, study, est, scheme, sigma_a_ug, estimator, replicate, seconds):
    """``estimates.csv``, ``covariance.csv``, ``history.parquet``, ``run.json`` of the single run."""
    from .ekf import nees
    from .io import atomic_to_csv, atomic_to_parquet, atomic_write_text
    from .tables import covariance_frame, estimates_frame

    out = Path(out_dir)
    nc = est.n_coef
    df = estimates_frame(est.names[:nc], est.coef[0], est.coef_sigma[0], study.truth)
    atomic_to_csv(df, out / "estimates.csv")
    atomic_to_csv(covariance_frame(est.names, est.P[0]), out / "covariance.csv", index=True)
    atomic_to_parquet(history_frame(est, scheme), out / "history.parquet")
    info = {"scheme": scheme.name, "sigma_a_ug": float(sigma_a_ug), "estimator": estimator,
            "replicate": int(replicate), "passes": int(study.filter.passes), "dwell_s": scheme.dwell_s,
            "n_positions": scheme.n_positions,
            "nees": float(nees(est.coef, est.P[:, :nc, :nc], study.truth[study.filter.coef_index][None])[0]),
            "mean_nis": float(est.mean_nis[0]), "failed_updates": int(est.failed_updates[0])}
    atomic_write_text(out / "run.json", json.dumps(info, indent=2, sort_keys=True) + "\n")
    atomic_write_text(out / "timing.json", json.dumps({"wall_s": seconds}, indent=2) + "\n")


def collect(coef_files, runs_files, timing_files):
    """Concatenate the cells' files into sorted study-wide tables (order-independent)."""
    keys = ["scheme", "sigma_a_ug", "estimator", "replicate"]
    coef = pd.concat([pd.read_parquet(f) for f in coef_files], ignore_index=True)
    coef["_i"] = coef.groupby(keys, sort=False).cumcount()  # keeps Table 2's coefficient order
    coef = coef.sort_values(keys + ["_i"], kind="stable").drop(columns="_i").reset_index(drop=True)
    runs = pd.concat([pd.read_parquet(f) for f in runs_files], ignore_index=True)
    runs = runs.sort_values(keys, kind="stable").reset_index(drop=True)
    timing = pd.DataFrame([json.loads(Path(f).read_text()) for f in timing_files])
    timing = timing.sort_values(["scheme", "sigma_a_ug", "estimator"], kind="stable").reset_index(drop=True)
    return coef, runs, timing


def resolve_scheme_for_job(cfg: dict, name: str, scheme_file: str | None = None):
    """The Scheme called ``name``: from its scheme file when generated, else from the config."""
    from .scheme import load_scheme_file

    if scheme_file:
        found = load_scheme_file(scheme_file)
        if name in found:
            return found[name]
        if len(found) == 1:
            s = next(iter(found.values()))
            return replace(s, name=name)
        raise InputError(str(scheme_file), f"holds schemes {sorted(found)}, none called {name!r}")
    return builtin_scheme(cfg, name)


# ---------------------------------------------------------------------------------------------
# logging and the command line


def job_logger(path: str | os.PathLike | None) -> logging.Logger:
    """A logger writing timestamped lines to ``path`` (a job's log) and to stderr."""
    lg = logging.getLogger("platcal.job")
    lg.setLevel(logging.INFO)
    lg.handlers.clear()
    fmt = logging.Formatter("%(asctime)s %(message)s", "%H:%M:%S")
    h = logging.StreamHandler(sys.stderr)
    h.setFormatter(fmt)
    lg.addHandler(h)
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fh = logging.FileHandler(path, mode="w")
        fh.setFormatter(fmt)
        lg.addHandler(fh)
    return lg


def cell_job(cfg: dict, scheme_name: str, sigma_a_ug: float, estimator: str, out_dir, threads: int = 1,
             log_path=None, scheme_file=None) -> None:
    """Run a cell and write its files, logging what runs and how far it is (the rule's body)."""
    lg = job_logger(log_path)
    cfg = check_study(cfg)
    scheme = resolve_scheme_for_job(cfg, scheme_name, scheme_file)
    st = cfg["study"]
    lg.info("cell scheme=%s (%d positions x %g s) sigma_a=%g ug estimator=%s (%s): %d replicates, "
            "%d thread(s), backend %s, batch %d", scheme.name, scheme.n_positions, scheme.dwell_s, sigma_a_ug,
            estimator, st["estimators"][estimator], st["replicates"], threads, st["backend"], st["batch"])

    def progress(done, total, seconds):
        eta = seconds / done * (total - done)
        lg.info("  %d/%d replicates done (%.0f %%), %.1f s elapsed, ~%.0f s left",
                done, total, 100.0 * done / total, seconds, eta)

    coef, runs, timing = run_cell(cfg, scheme, sigma_a_ug, estimator, threads=threads, progress=progress)
    write_cell(out_dir, coef, runs, timing)
    lg.info("done: mean NEES %.1f (dof %d), %.2f s per run -> %s", runs["nees"].mean(),
            int(runs["nees_dof"].iloc[0]), timing["wall_s_per_run"], out_dir)


def single_job(cfg: dict, out_dir, threads: int = 1, log_path=None) -> None:
    """The single run of ``study.single`` with history (Table 2 and the convergence figure)."""
    lg = job_logger(log_path)
    cfg = check_study(cfg)
    s = cfg["study"]["single"]
    scheme = builtin_scheme(cfg, s["scheme"])
    sigma = cfg["noise"]["sigma_a_ug"] if s["sigma_a_ug"] is None else s["sigma_a_ug"]
    lg.info("single run: scheme=%s sigma_a=%g ug estimator=%s replicate=%d", scheme.name, sigma,
            s["estimator"], s["replicate"])
    study, est, seconds = run_single(cfg, scheme, sigma, s["estimator"], s["replicate"], threads)
    write_single(out_dir, study, est, scheme, sigma, s["estimator"], s["replicate"], seconds)
    lg.info("done in %.2f s -> %s", seconds, out_dir)


def _cmd_cell(args) -> int:
    from .config import load_config  # noqa: F401  (validates the file's YAML)
    from .io import read_yaml

    raw = read_yaml(Path(args.config).read_text())
    cell_job(raw, args.scheme, args.sigma_a, args.estimator, args.out, threads=args.threads,
             scheme_file=args.scheme_file)
    return 0


def register_cli(sub) -> None:
    """``platcal montecarlo``: run one cell of the sweep (what the workflow's jobs run)."""
    p = sub.add_parser("montecarlo", help="run one (scheme, noise level, estimator) cell of the Monte Carlo study")
    p.add_argument("--config", required=True, help="study configuration (YAML)")
    p.add_argument("--scheme", required=True, help="scheme name (config, classical, random_<i>, or generated)")
    p.add_argument("--scheme-file", default=None, help="scheme file of a generated scheme")
    p.add_argument("--sigma-a", type=float, required=True, help="accelerometer noise, ug per sample")
    p.add_argument("--estimator", required=True, help="a key of study.estimators")
    p.add_argument("--threads", type=int, default=1, help="threads (numba) or joblib workers")
    p.add_argument("--out", required=True, help="output folder (coef.parquet, runs.parquet, timing.json)")
    p.set_defaults(func=_cmd_cell)

