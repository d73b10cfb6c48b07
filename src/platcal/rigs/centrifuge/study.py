"""The centrifuge's Monte Carlo study: its schemes, its ``study:`` section and its hooks for the
generic runner :mod:`platcal.study.montecarlo` (docs/centrifuge-model.md §10-11; issue 3).

Schemes of a study
------------------
``study.schemes`` lists names: a scheme of the config's ``schemes:`` section; ``classical``
(the orthogonal 6-position scheme, each platform axis in turn up and down); ``random`` (expands
to ``random_1 .. random_N``, drawn from ``study.random_schemes.seed``) or one ``random_<i>``;
and ``ga_*`` / any name listed in ``study.generated_schemes``, which resolve to a scheme file
``results/centrifuge/design/<name>.yaml`` written by a workflow rule (the GA design).

The swept noise is the accelerometer's ``sigma_a_ug`` (ug per 5 ms sample); replicate r of
scheme S at level sigma_a draws from ``SeedSequence(seed, spawn_key=(stable_key(S),
round(1000 sigma_a), r))`` (:func:`platcal.study.sweep.replicate_seed`).
"""

from __future__ import annotations

import json
import os
import re
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...estimation.consistency import nees
from ...io import atomic_path, atomic_to_parquet, atomic_write_csv, atomic_write_text, normalise_numbers
from ...lighttable import Table
from ...logs.calibration import write_covariance
from ...log import job_logger
from ...model.instruments import group_of, unit_of
from ...parallel import set_threads
from ...rig import NoiseAxis, ReplicateBatch, resolve
from ...seeding import stable_key
from ...study.sweep import StudySectionHooks, noise_key, noise_label, replicate_seed
from .config import check_filter, study_from_config, validate_config
from .estimators import check_kind
from .identify import SharedRecords, identify_shared, pass_prefixes, simulate_identify, simulate_shared
from ...scheme import check_scheme, load_scheme_file, whole_periods
from .tables import estimates_columns

CLASSICAL_POSITIONS = ((0, 0, 0), (180, 0, 0), (90, 0, 90), (90, 0, 270), (90, 0, 0), (90, 0, 180))
"""Orthogonal 6-position scheme, deg: z_p up, z_p down, x_p up, x_p down, y_p up, y_p down
(beta = 0; the up axis in p is column 3 of C_r^p = Mz(gamma) Mx(alpha))."""

GENERATED_PREFIX = "ga_"
GENERATED_RE = r"ga_(?:doo|(?:J|A|D|maxrel)(?:_n\d+)?)"
"""The generated schemes the design rule can make (design.preset's names)."""
"""Scheme names with this prefix resolve to ``<results>/design/<name>.yaml`` (the GA design)."""

# ---------------------------------------------------------------------------------------------
# schemes of the study


def classical_scheme(dwell_s: float):
    """The orthogonal 6-position scheme (each platform axis in turn up and down)."""
    return check_scheme("classical", {"dwell_s": dwell_s, "positions": [list(p) for p in CLASSICAL_POSITIONS]})


def random_schemes(seed: int, count: int, n_positions: int, dwell_s: float) -> list:
    """``count`` random schemes: alpha, gamma whole degrees in [0, 359], beta = 0 (docs/centrifuge-model.md §10).

    Scheme i (1-based) is drawn from ``SeedSequence(seed, spawn_key=(stable_key('random'), i))``,
    so scheme ``random_2`` is the same whatever ``count`` is.
    """
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
        if name.startswith(GENERATED_PREFIX) and not re.fullmatch(GENERATED_RE, name):
            raise InputError(field, f"unknown generated scheme {name!r}: the design rule makes "
                             "ga_<criterion> and ga_<criterion>_n<N> (criterion J, A, D or maxrel) and ga_doo")
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise InputError(field, f"scheme name {name!r} must be letters, digits, '_', '-' or '.' (it names files)")
        for n in new:
            if n in out:
                raise InputError(field, f"scheme {n!r} is listed twice")
            out.append(n)
    return out


def builtin_scheme(cfg: dict, name: str):
    """A scheme that the config defines (config ``schemes:``, ``classical``, ``random_<i>``)."""
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


def check_study(raw: dict, cells=None) -> dict:
    """Validate a configuration including its ``study:`` section; return it with defaults.

    Raises InputError naming the field (e.g. ``study.sigma_a_ug[0]``, ``study.schemes[2]``)
    before any job runs. ``cells``: the (sigma_a in ug, estimator name) cells whose filter
    settings are checked (:func:`study_for_cell`; docs/centrifuge-model.md §10-11): every cell of
    the sweep and of the comparison when None (the workflow's master, before any job), one
    cell's own in its job (24 filter checks fewer per job in the default study; issue 22 item 4).
    """
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
    # the paper's cell must be a cell of the sweep, or its tables fail only after every job ran
    paper = st["paper"]
    names = scheme_names(cfg)
    if paper["scheme"] not in names:
        raise InputError("study.paper.scheme", f"scheme {paper['scheme']!r} is not in the sweep; use one of {names}")
    if paper["estimator"] not in st["estimators"]:
        raise InputError("study.paper.estimator", f"unknown estimator {paper['estimator']!r}; the study "
                         f"defines {sorted(st['estimators'])}")
    level = cfg["noise"]["sigma_a_ug"] if paper["sigma_a_ug"] is None else paper["sigma_a_ug"]
    if noise_key(level) not in {noise_key(v) for v in st["sigma_a_ug"]}:
        raise InputError("study.paper.sigma_a_ug", f"sigma_a = {level:g} ug is not a noise level of the sweep "
                         f"(study.sigma_a_ug = {st['sigma_a_ug']}); null means noise.sigma_a_ug")
    labels = [noise_label(v) for v in st["sigma_a_ug"]]
    if len(set(labels)) != len(labels) or len({noise_key(v) for v in st["sigma_a_ug"]}) != len(labels):
        raise InputError("study.sigma_a_ug", f"noise levels must be distinct (to 0.001 ug), got {st['sigma_a_ug']}")
    for name, entry in st["estimators"].items():
        if not re.fullmatch(r"[A-Za-z0-9_-]+", name):
            raise InputError(f"study.estimators.{name}", "an estimator name is letters, digits, '_' or '-'")
        if "estimator" in entry:
            check_kind(entry["estimator"], f"study.estimators.{name}.estimator")
    whole_periods(st["dwell_s"], cfg["sampling"]["sample_ms"] / 1000.0, "study.dwell_s")
    comp = st["compare"]
    if comp["scheme"] is None:  # the paper's cell's scheme, already checked above
        comp["scheme"] = paper["scheme"]
    if comp["scheme"] not in cfg["schemes"] and comp["scheme"] != "classical" \
            and not re.fullmatch(r"random_\d+", comp["scheme"]):
        raise InputError("study.compare.scheme", f"unknown scheme {comp['scheme']!r}; use a scheme of the config's "
                         f"'schemes' ({sorted(cfg['schemes'])}), 'classical' or 'random_<i>'")
    if isinstance(comp["estimators"], dict):  # the comparison's own estimators
        for name, entry in comp["estimators"].items():
            if not re.fullmatch(r"[A-Za-z0-9_-]+", name):
                raise InputError(f"study.compare.estimators.{name}", "an estimator name is letters, digits, '_' or '-'")
            if name in st["estimators"] and entry != st["estimators"][name]:
                raise InputError(f"study.compare.estimators.{name}", f"{name!r} is defined differently in "
                                 "study.estimators; use another name or the same definition")
            if "estimator" in entry:
                check_kind(entry["estimator"], f"study.compare.estimators.{name}.estimator")
    else:
        for i, name in enumerate(comp["estimators"]):
            if name not in st["estimators"]:
                raise InputError(f"study.compare.estimators[{i}]", f"unknown estimator {name!r}; the study "
                                 f"defines {sorted(st['estimators'])} (or give study.compare.estimators as a "
                                 "mapping of the comparison's own estimators)")
        if len(set(comp["estimators"])) != len(comp["estimators"]):
            raise InputError("study.compare.estimators", "an estimator is listed twice")
    if len({noise_key(v) for v in comp["sigma_a_ug"]}) != len(comp["sigma_a_ug"]):
        raise InputError("study.compare.sigma_a_ug", f"noise levels must be distinct (to 0.001 ug), got "
                         f"{comp['sigma_a_ug']}")
    # every cell runs a filter: its settings are checked before any job starts
    both = {**cfg, "study": {**st, "estimators": {**st["estimators"], **(comp["estimators"]
                                                                         if isinstance(comp["estimators"], dict) else {})}}}
    if cells is None:
        cells = ([(level, name) for level in st["sigma_a_ug"] for name in st["estimators"]]
                 + [(level, name) for level in comp["sigma_a_ug"] for name in (comp["estimators"] or st["estimators"])])
    for level, name in cells:
        if name not in both["study"]["estimators"]:
            raise InputError("study.estimators", f"unknown estimator {name!r}; the study defines "
                             f"{sorted(both['study']['estimators'])}")
        study_for_cell(both, level, name)
    return cfg


# ---------------------------------------------------------------------------------------------
# the hooks of the generic runner


def study_for_cell(cfg: dict, sigma_a_ug: float, estimator: str):
    """The Study of one cell: the config with this noise level and this estimator's settings
    (its filter checked: InputError naming the field)."""
    raw = json.loads(json.dumps(cfg))  # deep copy of plain data
    raw["noise"]["sigma_a_ug"] = float(sigma_a_ug)
    raw["filter"].update(cfg["study"]["estimators"][estimator])
    raw["filter"]["history_s"] = raw["filter"].get("history_s", 1.0)
    study = study_from_config(raw)
    check_filter(study.filter)
    return study


def replicate_batch(study, est, passes: int | None = None) -> ReplicateBatch:
    """The coefficient part of an :class:`~platcal.rigs.centrifuge.ekf.Estimate` for the runner;
    ``passes``: the estimate's (default the study filter's; fewer for one taken on the way)."""
    nc = est.n_coef
    names = tuple(est.names[:nc])
    truth = study.truth[study.filter.coef_index]
    # numpy columns, as the runner's tidy tables take them: a cell job loads no pandas (issue 22 item 4)
    quantities = Table({"name": list(names), "group": [group_of(n) for n in names],
                        "unit": [unit_of(n) for n in names], "truth": truth})
    return ReplicateBatch(
        quantities=quantities, estimate=est.coef, sigma=est.coef_sigma,
        nees=nees(est.coef, est.P[:, :nc, :nc], truth[None]), nees_dof=nc, mean_nis=est.mean_nis,
        failed_updates=est.failed_updates, passes=int(study.filter.passes if passes is None else passes))


def resolve_scheme_for_job(cfg: dict, name: str, scheme_file: str | None = None):
    """The Scheme called ``name``: from its scheme file when generated, else from the config."""
    if scheme_file:
        found = load_scheme_file(scheme_file)
        if name in found:
            return found[name]
        if len(found) == 1:
            s = next(iter(found.values()))
            return replace(s, name=name)
        raise InputError(str(scheme_file), f"holds schemes {sorted(found)}, none called {name!r}")
    return builtin_scheme(cfg, name)


MODEL_KEYS = ("site", "centrifuge", "sampling", "truth", "noise", "filter", "seed")
"""Config sections that every run's numbers depend on (not batch, backend, threads)."""


class CentrifugeMonteCarlo(StudySectionHooks):
    """The centrifuge's :class:`~platcal.rig.MonteCarloHooks`: schemes x sigma_a x estimators."""

    noise = NoiseAxis(name="sigma_a_ug", unit="ug", label="accelerometer noise sigma_a, ug per 5 ms sample")

    def check(self, raw: dict) -> dict:
        return check_study(raw)

    def check_cell(self, raw: dict, case: str, noise: float, estimator: str) -> dict:
        return check_study(raw, cells=[(noise, estimator)])

    def cases(self, cfg: dict) -> list[str]:
        return scheme_names(cfg)

    def case(self, cfg: dict, name: str, case_file: str | None = None):
        return resolve_scheme_for_job(cfg, name, case_file)

    def case_file(self, cfg: dict, name: str) -> str | None:
        return f"design/{name}.yaml" if is_generated(name, cfg["study"]) else None

    def warm_kernels(self, cfg: dict) -> None:
        """Compile (or load) every estimator's kernels once, for the workflow's rule ``kernels``
        that the cells, the comparison's cells and the single run wait for
        (:func:`platcal.rigs.centrifuge.compare_cells.warm_kernels`, named by path: it imports
        this module)."""
        resolve("platcal.rigs.centrifuge.compare_cells:warm_kernels")(cfg)

    def cell_params(self, cfg: dict, case: str, noise: float, estimator: str) -> dict:
        p = {k: cfg[k] for k in MODEL_KEYS}
        p["sigma_a_ug"] = float(noise)
        p["estimator"] = cfg["study"]["estimators"][estimator]
        p["replicates"] = cfg["study"]["replicates"]
        if not is_generated(case, cfg["study"]):
            p["scheme"] = builtin_scheme(cfg, case).as_dict()
        return p

    def run_batch(self, cfg: dict, case, noise: float, estimator: str, seeds) -> ReplicateBatch:
        study = study_for_cell(cfg, noise, estimator)
        return replicate_batch(study, simulate_identify(study, case, seeds))

    def simulate_cell(self, cfgs: dict, case, noise: float, seeds) -> SharedRecords:
        return simulate_shared([study_for_cell(c, noise, e) for e, c in cfgs.items()], case, seeds)

    def identify_cell(self, cfg: dict, case, noise: float, estimator: str, data: SharedRecords,
                      on_pass=None) -> ReplicateBatch:
        study = study_for_cell(cfg, noise, estimator)
        per_pass = None if on_pass is None else (lambda p, est: on_pass(p, replicate_batch(study, est, passes=p)))
        return replicate_batch(study, identify_shared(study, case, data, per_pass))

    def pass_prefixes(self, cfgs: dict, case, noise: float) -> dict[str, tuple[str, int]]:
        # a cell's estimators are one config's variants (the same model and records): their
        # filters say whether one run gives another on the way
        return pass_prefixes({e: study_for_cell(c, noise, e).filter for e, c in cfgs.items()})


# ---------------------------------------------------------------------------------------------
# what the workflow's centrifuge rules depend on (their params) and build


DESIGN_KEYS = MODEL_KEYS + ("schemes", "design")
"""Config sections every design number depends on (model, filter, truth, schemes, design)."""

NO_DESIGN = {"study": {"criteria": [], "n_criteria": [], "n_positions": []}, "positions": 6}
"""The design section's shape when the centrifuge is not in the study (no design rules run)."""


def single_params(cfg: dict) -> dict:
    """What the single run's numbers depend on: the model, the single-run settings, the
    estimators and its scheme."""
    p = {k: cfg[k] for k in MODEL_KEYS}
    p["single"] = cfg["study"]["single"]
    p["estimators"] = cfg["study"]["estimators"]
    p["scheme"] = builtin_scheme(cfg, cfg["study"]["single"]["scheme"]).as_dict()
    return p


def design_targets(cases: list[str], dcfg: dict) -> list[str]:
    """The design outputs (under ``results/centrifuge/``) the default target builds: the full
    design report, or the criteria comparison alone, when the sweep uses a GA scheme."""
    if not any(is_generated(c, {}) for c in cases):
        return []
    if dcfg["study"]["report"]:
        return ["design/report.md"]
    if dcfg["study"]["compare"]:
        return [f"design/compare/{f}" for f in ("schemes.csv", "spearman.csv", "criteria_vs_accuracy.png")]
    return []


# ---------------------------------------------------------------------------------------------
# the single run behind Table 2 and the convergence figure


def run_single(cfg: dict, scheme, sigma_a_ug: float, estimator: str, replicate: int, threads: int = 1):
    """One replicate with the filter's history, for Table 2 and the convergence figure.

    It is the same run (same SeedSequence) as replicate ``replicate`` of the Monte Carlo cell.
    Returns (study, Estimate, seconds).
    """
    set_threads(threads)
    study = study_for_cell(cfg, sigma_a_ug, estimator)
    seeds = [replicate_seed(study.seed, scheme.name, sigma_a_ug, replicate)]
    t0 = time.perf_counter()
    est = simulate_identify(study, scheme, seeds, study.filter)
    return study, est, time.perf_counter() - t0


def history_frame(est, scheme, b: int = 0):
    """Long table of the filter's history of run ``b`` (a pandas DataFrame for the Parquet file):
    t_s (s), state, estimate, sigma (the state's unit), pass, position."""
    H = est.history_t.size
    n = len(est.names)
    dwell = scheme.dwell_s
    total = dwell * scheme.n_positions
    t_s = np.repeat(est.history_t, n)
    return Table({
        "t_s": t_s, "state": list(est.names) * H,
        "estimate": est.history_x[b].ravel(), "sigma": est.history_sigma[b].ravel(),
        "pass": (np.floor(t_s / total + 1e-9) + 1).astype(int),
        "position": np.minimum((np.floor((t_s % total) / dwell + 1e-9) + 1).astype(int), scheme.n_positions),
    }).to_pandas()


def write_single(out_dir: str | os.PathLike, study, est, scheme, sigma_a_ug, estimator, replicate, seconds):
    """``estimates.csv``, ``covariance.csv``, ``history.parquet``, ``run.json`` of the single run."""
    out = Path(out_dir)
    nc = est.n_coef
    atomic_write_csv(out / "estimates.csv", estimates_columns(est.names[:nc], est.coef[0], est.coef_sigma[0], study.truth))
    with atomic_path(out / "covariance.csv") as tmp:
        write_covariance(tmp, est.names, est.P[0])
    atomic_to_parquet(history_frame(est, scheme), out / "history.parquet")
    info = {"scheme": scheme.name, "sigma_a_ug": float(sigma_a_ug), "estimator": estimator,
            "replicate": int(replicate), "passes": int(study.filter.passes), "dwell_s": scheme.dwell_s,
            "n_positions": scheme.n_positions,
            "nees": float(nees(est.coef, est.P[:, :nc, :nc], study.truth[study.filter.coef_index][None])[0]),
            "mean_nis": float(est.mean_nis[0]), "failed_updates": int(est.failed_updates[0])}
    atomic_write_text(out / "run.json", json.dumps(info, indent=2, sort_keys=True) + "\n")
    atomic_write_text(out / "timing.json", json.dumps({"wall_s": seconds}, indent=2) + "\n")


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
