"""The multiposition rig's hooks for the generic Monte Carlo runner (docs/multiposition-1g.md §14-16).

The study is ``study.schemes`` x ``study.sigma_a_ug`` x ``study.estimators`` x ``study.seeds``
replicates, run by :mod:`platcal.study.montecarlo` (one Snakemake job per (scheme, sigma_a) cell
with every estimator, rule ``montecarlo_cell``) and collected into the tidy tables ``results/multiposition/montecarlo/``.

- Cases: a scheme of the config (the §11 schemes are built in) or a GA design (``GA``, or
  ``GA<K>`` with K in ``design.positions``), read from the file the rule ``multiposition_design``
  writes, ``results/multiposition/design/<name>.yaml``.
- Noise axis: the accelerometer white noise ``sigma_a_ug``, ug per sample (``sampling.ts_ms``,
  20 ms by default), used by the simulator and by the filter's R alike.
- Estimators: the keys of ``study.estimators`` (overrides of ``filter``: ``ekf1``, ``ekf2``,
  ``iekf`` by default); every estimator of a cell sees the same simulated records.
- Seeds: replicate r of scheme S at sigma_a draws from ``SeedSequence(seed, spawn_key=
  (stable_key(S), round(1000 sigma_a), r))`` (:func:`platcal.study.sweep.replicate_seed`;
  ``seed`` is the config's root ``seed``) in §14's order of use (:func:`.filter.draw_noise`), so
  its numbers are the same whatever the batch, thread count or job order, and
  ``platcal simulate --seed r`` writes the same record.
- Per run: the 24 coefficients' estimate and sigma, NEES (dof 24), mean NIS, updates skipped
  because S was not positive definite, and the measurement linearisations per update (an extra
  column of the runs table).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...estimation.passes import pass_prefixes
from ...io import read_yaml
from ...lighttable import Table
from ...parallel import get_threads
from ...rig import NoiseAxis, ReplicateBatch, resolve
from ...scheme import Scheme
from ...study.sweep import StudySectionHooks, noise_key, noise_label
from .config import load_config, make_scheme, scheme_table
from .estimators import estimate, raw_variant_choice, variant_choice
from .filter import nees, simulate
from .model import coef_names, coef_terms, group_of, unit_of

NAME_RE = r"[A-Za-z0-9_.-]+"
"""Scheme and estimator names of the sweep name files and folders."""

MODEL_KEYS = ("site", "gimbal", "sampling", "truth", "seed")
"""Config sections every run's numbers depend on (with the noise, the filter and the scheme)."""


def ga_names(raw: dict) -> set[str]:
    """The GA designs the design rule writes: ``GA`` and ``GA<K>`` for K in ``design.positions``."""
    return {"GA"} | {f"GA{k}" for k in raw["design"]["positions"]}


def check_scheme_names(cfg) -> None:
    """Every scheme named in ``study.schemes`` and ``study.rank_schemes`` is one of the config's
    schemes or a GA design (InputError naming the field, before any job runs); the sweep's names
    are file-name safe and listed once."""
    ga = ga_names(cfg.raw)
    for key in ("schemes", "rank_schemes"):
        seen = set()
        for i, name in enumerate(cfg.raw["study"].get(key, [])):
            if name not in cfg.schemes and name not in ga:
                raise InputError(f"study.{key}[{i}]", f"unknown scheme {name!r}; use one of the config's "
                                 f"schemes {sorted(cfg.schemes)} or a GA design {sorted(ga)}")
            if not re.fullmatch(NAME_RE, name):
                raise InputError(f"study.{key}[{i}]", f"scheme name {name!r} must be letters, digits, '_', '-' "
                                 "or '.' (it names files)")
            if name in seen:
                raise InputError(f"study.{key}[{i}]", f"scheme {name!r} is listed twice")
            seen.add(name)


def check_study(raw) -> dict:
    """Validate a raw config, ``study:`` included; return the mapping with every default filled
    in. InputError names the field (``study.schemes[2]``, ``study.sigma_a_ug``,
    ``study.estimators.<name>``...) before any job runs."""
    cfg = load_config(raw)
    check_scheme_names(cfg)
    st = cfg.raw["study"]
    levels = [float(v) for v in st["sigma_a_ug"]]
    if len({noise_key(v) for v in levels}) != len(levels) or len({noise_label(v) for v in levels}) != len(levels):
        raise InputError("study.sigma_a_ug", f"noise levels must be distinct (to 0.001 ug), got {st['sigma_a_ug']}")
    for name in st["estimators"]:
        field = f"study.estimators.{name}"
        if not re.fullmatch(r"[A-Za-z0-9_-]+", name):
            raise InputError(field, "an estimator name is letters, digits, '_' or '-' (it names folders)")
        variant_choice(cfg, name, field=field)
    return cfg.raw


def quantities(cfg):
    """The 24 identified coefficients of a config: name, group (gyro / accel), unit, truth (a
    :class:`platcal.lighttable.Table`, as the runner's tidy tables take it: neither the rig's
    identify nor a Monte Carlo cell job loads pandas, issue 22 item 4)."""
    names = coef_names()
    return Table({"name": names, "group": [group_of(n) for n in names],
                  "unit": [unit_of(n) for n in names], "truth": cfg.truth()})


def run_cell_batch(cfg, scheme: Scheme, sigma_a_ug: float, estimator: str, seeds, threads: int = 1) -> ReplicateBatch:
    """Simulate one replicate per SeedSequence of ``scheme`` at ``sigma_a_ug`` (truth and filter
    R) and identify it with the study's estimator variant ``estimator``; ``threads`` of the
    simulator's and filter's thread pools change the speed only."""
    choice = study_variant(cfg, estimator)  # an unknown estimator is refused before the simulation
    return identify_records(cfg, scheme, sigma_a_ug, choice, simulate_records(cfg, scheme, sigma_a_ug, seeds, threads),
                            threads)


def study_variant(cfg, estimator: str):
    """The estimator variant ``estimator`` of the study (:func:`.estimators.variant_choice`; an
    InputError names ``study.estimators.<estimator>``)."""
    return variant_choice(cfg, estimator, field=f"study.estimators.{estimator}")


def simulate_records(cfg, scheme: Scheme, sigma_a_ug: float, seeds, threads: int = 1) -> tuple:
    """The simulated replicates of :func:`run_cell_batch` (one per SeedSequence): instants and
    measurements as :func:`.filter.simulate` gives them, which every estimator variant reads
    unchanged (docs/multiposition-1g.md §9)."""
    t, _, z = simulate(cfg.with_noise(sigma_a_ug=float(sigma_a_ug)), scheme, list(seeds), threads=threads)
    return t, z


def identify_records(cfg, scheme: Scheme, sigma_a_ug: float, choice, records: tuple, threads: int = 1,
                     on_pass=None) -> ReplicateBatch:
    """The estimator variant ``choice`` (:func:`.estimators.variant_choice`) on simulated
    ``records`` (:func:`simulate_records`): the batch of :func:`run_cell_batch`. ``on_pass(p,
    batch)``, when given, after each pass but the last with the batch of the same variant run with
    p passes (:func:`.estimators.estimate`; bit for bit)."""
    c = cfg.with_noise(sigma_a_ug=float(sigma_a_ug))
    t, z = records
    per_pass = None if on_pass is None else (lambda p, res: on_pass(p, estimate_batch(c, res, p)))
    return estimate_batch(c, estimate(c, choice, scheme.angles_deg, t, z, threads=threads, on_pass=per_pass),
                          int(choice.passes))


def estimate_batch(cfg, res, passes: int) -> ReplicateBatch:
    """The runner's batch of an :class:`.estimators.Estimate` of ``passes`` passes (``cfg`` with
    the cell's noise: its truth and quantities)."""
    truth = cfg.truth()
    return ReplicateBatch(
        quantities=quantities(cfg), estimate=res.coef, sigma=np.sqrt(np.diagonal(res.cov, axis1=1, axis2=2)),
        nees=nees(res.coef, res.cov, truth), nees_dof=truth.size, mean_nis=res.mean_nis,
        failed_updates=res.failed_updates, passes=int(passes),
        extra={"linearisations": np.asarray(res.linearisations, float)})


class MultipositionMonteCarlo(StudySectionHooks):
    """The multiposition rig's :class:`~platcal.rig.MonteCarloHooks` (see the module docstring)."""

    replicates_key = "seeds"

    noise = NoiseAxis(name="sigma_a_ug", unit="ug",
                      label="accelerometer noise sigma_a, ug per sample (20 ms by default)")

    def check(self, raw: dict) -> dict:
        return check_study(raw)

    def cases(self, cfg: dict) -> list[str]:
        return list(cfg["study"]["schemes"])

    # case, case_file and cell_params are called for every job while Snakemake builds its DAG:
    # they read the checked mapping directly (the schema validation is for check and run_batch)

    def case(self, cfg: dict, name: str, case_file: str | None = None) -> Scheme:
        if case_file:  # a GA design: {dwell_s, positions} written by the design rule
            d = read_yaml(Path(case_file).read_text(encoding="utf-8"))
            return make_scheme(name, d["positions"], d["dwell_s"], float(cfg["gimbal"]["beta_max_deg"]),
                               where=str(case_file))
        schemes = scheme_table(cfg)
        if name not in schemes:
            raise InputError("study.schemes", f"scheme {name!r} is a GA design: its cells need the design "
                             f"rule's file results/multiposition/{self.case_file(cfg, name)}")
        return schemes[name]

    def case_file(self, cfg: dict, name: str) -> str | None:
        return None if name in scheme_table(cfg) else f"design/{name}.yaml"

    def warm_kernels(self, cfg: dict) -> None:
        """Compile (or load) the numba kernels once, for the workflow's rule ``kernels`` that every
        cell and covariance job waits for: with a cold cache the first cells would compile them
        side by side (:func:`platcal.rigs.multiposition.study.warm_kernels`, named by path: it
        imports this module)."""
        resolve("platcal.rigs.multiposition.study:warm_kernels")(load_config(cfg))

    def cell_params(self, cfg: dict, case: str, noise: float, estimator: str) -> dict:
        choice = raw_variant_choice(cfg, estimator, field=f"study.estimators.{estimator}")
        p = {k: cfg[k] for k in MODEL_KEYS}
        p["truth"] = {k: v for k, v in cfg["truth"].items() if k in coef_names()}  # §13 terms: not in the 24
        p["noise"] = {**cfg["noise"], "sigma_a_ug": float(noise)}
        p["filter"] = {"estimator": choice.estimator, "passes": choice.passes, "options": choice.options,
                       "p0": {k: v for k, v in cfg["filter"]["p0"].items() if k in coef_terms()}}
        p["replicates"] = int(cfg["study"]["seeds"])
        schemes = scheme_table(cfg)
        if case in schemes:  # a GA design is the rule's input file instead
            p["scheme"] = schemes[case].as_dict()
        return p

    def run_batch(self, cfg: dict, case, noise: float, estimator: str, seeds) -> ReplicateBatch:
        # the runner has set this process's kernel threads (numba's count): the thread pools follow it
        return run_cell_batch(load_config(cfg), case, noise, estimator, seeds, threads=get_threads())

    def simulate_cell(self, cfgs: dict, case, noise: float, seeds) -> tuple:
        return simulate_records(load_config(next(iter(cfgs.values()))), case, noise, seeds, threads=get_threads())

    def identify_cell(self, cfg: dict, case, noise: float, estimator: str, data: tuple,
                      on_pass=None) -> ReplicateBatch:
        c = load_config(cfg)
        return identify_records(c, case, noise, study_variant(c, estimator), data, threads=get_threads(),
                                on_pass=on_pass)

    def pass_prefixes(self, cfgs: dict, case, noise: float) -> dict[str, tuple[str, int]]:
        # every estimator here hands its passes (run_filter's on_pass); two differ in nothing but
        # passes when their cells' params (all their numbers depend on) do not
        params = {e: self.cell_params(c, case.name, noise, e) for e, c in cfgs.items()}

        def same(a: str, b: str) -> bool:
            pa, pb = ({**p, "filter": {k: v for k, v in p["filter"].items() if k != "passes"}}
                      for p in (params[a], params[b]))
            return pa == pb

        return pass_prefixes({e: int(p["filter"]["passes"]) for e, p in params.items()}, same)
