"""Genetic-algorithm design of a test scheme (paper section 2.3; docs/centrifuge-model.md §10).

Decision variables: ``alpha_k, gamma_k`` in whole degrees [0, 359] (``beta_k`` fixed, 0 by
default), k = 1..N, and with ``g_levels`` one integer per position choosing its g-level. The
search is pymoo's single-objective GA (integer random sampling, tournament selection, SBX
crossover and polynomial mutation, both rounded to integers; duplicates eliminated).

Fitness is a covariance-only run of the scheme (docs/centrifuge-model.md §10) evaluated for the whole
population at once through the exact position decomposition of
:mod:`platcal.observability`: the information of every position not seen before is computed
in one batched covariance-only EKF run, and each scheme's covariance is then
``(P0^-1 + sum_k I_k)^-1``. The criterion is J (eq. 27) or one of A, D, maxrel.

Reproducibility: pymoo's seed is drawn from ``SeedSequence(design.seed or config seed)``.
"""

from __future__ import annotations

import copy
import json
import os
import re
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.callback import Callback
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair
from pymoo.operators.sampling.rnd import IntegerRandomSampling
from pymoo.optimize import minimize

from ...errors import InputError
from ...io import atomic_to_csv, atomic_write_text
from ...log import job_logger
from ...model.instruments import INDEX
from ...schema import load_schema, validate
from .config import check_filter, schema, study_from_config
from .ekf import default_p0_sigma
from .observability import CRITERIA, InfoCache, criteria, relative_scale, setup_from_study
from ...scheme import Scheme, check_scheme, dump_schemes, whole_periods

DESIGN_SCHEMA_RESOURCE = "data/design.schema.yaml"


def design_schema() -> dict:
    """The JSON Schema (with defaults) of a config's ``design:`` section."""
    return load_schema(__package__, DESIGN_SCHEMA_RESOURCE)


def design_config(cfg: dict, **overrides) -> dict:
    """The validated ``design`` section of a config (defaults filled, ``overrides`` applied)."""
    d = copy.deepcopy(cfg.get("design") or {})
    d.update({k: v for k, v in overrides.items() if v is not None})
    d = validate(d, design_schema(), prefix="design")
    if d["name"] is None:
        d["name"] = f"ga_{d['criterion']}" + ("" if d["positions"] == 6 else f"_n{d['positions']}")
    props = schema()["properties"]
    period = (cfg.get("filter") or {}).get("period_ms", props["filter"]["properties"]["period_ms"]["default"])
    # the filter period is a whole number of samples (validate_config), so this covers both
    whole_periods(d["dwell_s"], period / 1000.0, "design.dwell_s", "filter periods")
    return d


PRESET_HELP = ("ga_<criterion> (the design section with that criterion), ga_<criterion>_n<N> "
               "(N positions), ga_doo (two g-levels, 51-state filter, truth D_OO = design.study.doo_truth)")


def preset(study, name: str):
    """``(study, design section)`` of a named design of the workflow; see :data:`PRESET_HELP`."""
    base = design_config(study.config)
    st = base["study"]
    if name == "ga_doo":
        truth = study.truth.copy()
        for a in "xyz":
            truth[INDEX[f"DOO_{a}"]] = float(st["doo_truth"])
        dcfg = design_config(study.config, criterion=st["doo_criterion"], g_levels=list(st["doo_g_levels"]),
                             estimate_doo=True, name=name)
        return replace(study, truth=truth), dcfg
    m = re.fullmatch(r"ga_(J|A|D|maxrel)(?:_n(\d+))?", name)
    if not m:
        raise InputError("--preset", f"unknown design {name!r}; use {PRESET_HELP}")
    over = {"criterion": m.group(1), "name": name}
    if m.group(2):
        over["positions"] = int(m.group(2))
    return study, design_config(study.config, **over)


@dataclass
class DesignResult:
    scheme: Scheme
    value: float                    # best criterion value
    criteria: dict                  # every criterion of the best scheme
    history: pd.DataFrame           # per generation
    population: pd.DataFrame        # final population, best first
    seconds: float
    position_runs: int              # distinct positions evaluated (covariance-only runs)
    settings: dict


class SchemeEvaluator:
    """Criteria of candidate schemes at one study's settings (cached per-position information)."""

    def __init__(self, study, dwell_s: float, estimate_doo: bool | None = None, **filter_overrides):
        over = dict(filter_overrides)
        if estimate_doo is not None and estimate_doo != study.filter.estimate_doo:
            over["estimate_doo"] = bool(estimate_doo)
            over["p0_sigma"] = default_p0_sigma(bool(estimate_doo), study.config["filter"]["p0"])
        self.setup = setup_from_study(study, dwell_s, **over)
        self.cache = InfoCache(self.setup)
        idx = self.setup.filter.coef_index
        self.scale = relative_scale(self.setup.truth[idx], self.setup.p0)

    def covariance(self, angles_deg, g_levels=None) -> np.ndarray:
        return self.cache.covariance(angles_deg, g_levels)

    def evaluate(self, angles_deg, g_levels=None) -> dict[str, np.ndarray]:
        """Every criterion (arrays over the batch) of schemes (B, K, 3) [g_levels (B, K)].

        Criteria are over every estimated coefficient (45; 48 with DOO states).
        """
        return criteria(self.covariance(angles_deg, g_levels), self.scale)


def decode(X: np.ndarray, n_positions: int, beta_deg: float, g_levels=None):
    """Decision vectors (P, 2N [+N]) -> angles (P, N, 3) deg and g-levels (P, N) or None."""
    X = np.asarray(np.round(X), dtype=np.int64)
    P = X.shape[0]
    ang = np.empty((P, n_positions, 3))
    ang[:, :, 0] = X[:, 0:2 * n_positions:2] % 360
    ang[:, :, 1] = beta_deg
    ang[:, :, 2] = X[:, 1:2 * n_positions:2] % 360
    gl = None
    if g_levels is not None:
        gl = np.asarray(g_levels, float)[X[:, 2 * n_positions:3 * n_positions]]
    return ang, gl


def _pymoo_seed(entropy: int) -> int:
    return int(np.random.SeedSequence(int(entropy)).generate_state(1, dtype=np.uint32)[0])


def run_design(study, dcfg: dict, log=None) -> DesignResult:
    """Run the genetic algorithm of a validated ``design`` section; see the module docstring."""

    N = int(dcfg["positions"])
    levels = dcfg["g_levels"]
    crit = dcfg["criterion"]
    beta = float(dcfg["beta_deg"])
    ev = SchemeEvaluator(study, dcfg["dwell_s"], dcfg["estimate_doo"])
    n_var = 2 * N + (N if levels else 0)
    xu = np.full(n_var, 359)
    if levels:
        xu[2 * N:] = len(levels) - 1
    t0 = time.perf_counter()

    class SchemeProblem(Problem):
        def __init__(self):
            super().__init__(n_var=n_var, n_obj=1, xl=np.zeros(n_var), xu=xu, vtype=int)

        def _evaluate(self, X, out, *args, **kwargs):
            ang, gl = decode(X, N, beta, levels)
            out["F"] = ev.evaluate(ang, gl)[crit][:, None]

    rows = []

    class Record(Callback):
        def notify(self, algorithm):
            F = algorithm.pop.get("F")[:, 0]
            opt = algorithm.opt[0]
            ang, gl = decode(opt.X[None], N, beta, levels)
            allc = ev.evaluate(ang, gl)
            row = {"generation": algorithm.n_gen, "n_evals": algorithm.evaluator.n_eval,
                   "best": float(opt.F[0]), "pop_mean": float(np.mean(F[np.isfinite(F)])),
                   "pop_median": float(np.median(F)),
                   **{f"best_{k}": float(v[0]) for k, v in allc.items()},
                   "position_runs": ev.cache.runs, "seconds": time.perf_counter() - t0}
            rows.append(row)
            if log:
                log(f"gen {row['generation']:3d}  evals {row['n_evals']:5d}  best {crit} {row['best']:.4g}  "
                    f"mean {row['pop_mean']:.4g}  runs {row['position_runs']}  {row['seconds']:.0f} s")

    seed = study.seed if dcfg["seed"] is None else int(dcfg["seed"])
    algorithm = GA(
        pop_size=int(dcfg["population"]),
        sampling=IntegerRandomSampling(),
        crossover=SBX(prob=float(dcfg["crossover_prob"]), eta=float(dcfg["crossover_eta"]), vtype=float,
                      repair=RoundingRepair()),
        mutation=PM(eta=float(dcfg["mutation_eta"]), vtype=float, repair=RoundingRepair()),
        eliminate_duplicates=True,
    )
    res = minimize(SchemeProblem(), algorithm, ("n_gen", int(dcfg["generations"])),
                   seed=_pymoo_seed(seed), callback=Record(), verbose=False, save_history=False)
    seconds = time.perf_counter() - t0
    pop = res.pop
    X = np.asarray(np.round(pop.get("X")), dtype=np.int64)
    ang, gl = decode(X, N, beta, levels)
    allc = ev.evaluate(ang, gl)
    order = np.argsort(allc[crit], kind="stable")
    popdf = pd.DataFrame({"rank": np.arange(1, len(order) + 1)})
    for k in range(N):
        popdf[f"alpha_{k + 1}"] = ang[order, k, 0].astype(int)
        popdf[f"gamma_{k + 1}"] = ang[order, k, 2].astype(int)
        if gl is not None:
            popdf[f"g_{k + 1}"] = gl[order, k]
    for c, v in allc.items():
        popdf[c] = v[order]
    best_ang, best_gl = ang[order[0]], None if gl is None else gl[order[0]]
    spec = {"dwell_s": dcfg["dwell_s"], "positions": [[int(a), int(b) if float(b).is_integer() else float(b), int(g)]
                                                     for a, b, g in best_ang]}
    if best_gl is not None:
        spec["g_levels"] = [float(g) for g in best_gl]
    scheme = check_scheme(dcfg["name"], spec, where="design")
    fs = ev.setup.filter
    settings = {
        "criterion": crit, "positions": N, "dwell_s": dcfg["dwell_s"], "beta_deg": beta,
        "population": dcfg["population"], "generations": dcfg["generations"], "seed": seed,
        "g_levels": levels, "estimate_doo": fs.estimate_doo, "n_states": fs.coef_index.size + 3,
        "sigma_a_ug": fs.sigma_a_ug, "arw_deg_rth": fs.arw_deg_rth, "sigma_set_arcsec": fs.sigma_set_arcsec,
        "filter_period_s": fs.period_s, "centrifuge_rate_deg_s": ev.setup.centrifuge.rate_deg_s,
        "g_level": ev.setup.centrifuge.g_level, "pymoo_seed": _pymoo_seed(seed),
    }
    return DesignResult(scheme=scheme, value=float(allc[crit][order[0]]),
                        criteria={c: float(v[order[0]]) for c, v in allc.items()},
                        history=pd.DataFrame(rows), population=popdf, seconds=seconds,
                        position_runs=ev.cache.runs, settings=settings)


def output_paths(out: str | os.PathLike) -> dict[str, Path]:
    """The files a design run writes beside ``SCHEME.yaml``."""
    out = Path(out)
    stem = out.with_suffix("")
    return {"scheme": out, "history": Path(f"{stem}.history.csv"),
            "population": Path(f"{stem}.population.csv"), "summary": Path(f"{stem}.json")}


def write_design(res: DesignResult, out: str | os.PathLike) -> dict[str, Path]:
    paths = output_paths(out)
    header = (f"# platcal design: GA ({res.settings['population']} x {res.settings['generations']} gen, "
              f"seed {res.settings['seed']}), criterion {res.settings['criterion']} = {res.value:.6g}\n")
    dump_schemes([res.scheme], paths["scheme"], header=header)
    atomic_to_csv(res.history, paths["history"])
    atomic_to_csv(res.population, paths["population"])
    summary = {"scheme": res.scheme.name, **res.scheme.as_dict(), "criterion": res.settings["criterion"],
               "value": res.value, "criteria": res.criteria, "seconds": res.seconds,
               "position_runs": res.position_runs, "settings": res.settings}
    atomic_write_text(paths["summary"], json.dumps(summary, indent=2) + "\n")
    return paths


def design_study_of(config: dict):
    """The centrifuge study of a rig config for the design jobs (its ``study:`` sweep section
    left out), its filter checked."""
    cfg = {k: v for k, v in config.items() if k not in ("study",)}
    study = study_from_config(cfg)
    check_filter(study.filter)
    return study


def design_scheme_job(config: dict, name: str, out, log_path=None) -> None:
    """One named GA design (``ga_<criterion>[_n<N>]`` or ``ga_doo``) -> ``out`` and its side files.

    Here, not in :mod:`.design_study`, so that the GA job loads neither matplotlib nor
    scipy.stats (about 1 s CPU of imports; issue 22 item 4)."""
    study, dcfg = preset(design_study_of(config), name)
    log = job_logger(log_path).info
    res = run_design(study, dcfg, log=log)
    write_design(res, out)
    log(f"{name}: {dcfg['criterion']} = {res.value:.6g} in {res.seconds:.0f} s, "
        f"{res.position_runs} position runs")
