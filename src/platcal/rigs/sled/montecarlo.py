"""The sled's hooks for the generic Monte Carlo runner (docs/rocket-sled.md §8, §11, §12).

The study is ``study.cases`` x one noise level x one estimator x ``study.seeds`` replicates, run
by :mod:`platcal.study.montecarlo` (one Snakemake job per case, rule ``montecarlo_cell``) and
collected into the tidy tables ``results/sled/montecarlo/{coef,runs}.parquet``.

- Cases: :data:`CASES`, each a set of overrides of the study's base config (6 or 7 states,
  realtime or post X compensation, zero misalignment, the paper's tuning).
- Noise axis: the accelerometer white noise ``imu.accel.noise_ug_rthz`` (µg/√Hz); the study runs
  the config's level only (it keys the seeds and names the cell folder ``noise20``).
- Estimator: one, ``kf``, the run and stop filters of §6 as the case configures them.
- Seeds: replicate r of case C draws its errors and noise from ``replicate_seed(seed, C,
  noise_ug_rthz, r)`` (``seed`` is the config's root seed; :mod:`.sensors` for the draw order),
  so its numbers are the same whatever the batch; ``platcal simulate --seed r`` writes replicate
  r of the ``default`` case.
- Per run: the run filter's final attitude (φ_y, φ_z; φ_x too with 7 states, arcsec) with its
  1 sigma against the replicate's own *effective* attitude (§5, §8: the truth is drawn per seed,
  ``ReplicateBatch.truth``), NEES of those, the run filter's mean NIS (4 dof per update), skipped
  updates, and §8's metrics (:func:`.identify.metrics`, cm, arcsec, µg) as extra columns of the
  runs table, from which the study's tables and report are made (:mod:`.study`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...io import sorted_mapping
from ...lighttable import Table
from ...rig import NoiseAxis, ReplicateBatch, RunSettings
from ...study.sweep import replicate_seed
from .config import ARCSEC, SledConfig, load_config
from .identify import Identification, effective_phi, identify, metric_columns, phi_columns, run_problems
from .simulate import SimBatch, simulate

CASES = {
    "default": ({}, "6-state run filter, realtime X compensation (the paper's set-up)"),
    "post": ({"filter": {"compensation": "post"}}, "6 states, post X compensation"),
    "run7": ({"filter": {"states": 7}}, "7-state run filter (phi_x kept), realtime"),
    "run7_post": ({"filter": {"states": 7, "compensation": "post"}}, "7 states, post"),
    "misalign0_post": ({"imu": {"accel": {"misalign_arcsec": 0}}, "filter": {"compensation": "post"}},
                       "zero accelerometer misalignment, 6 states, post"),
    "paper_tuning": ({"filter": {"tuning": "paper"}}, "the paper's literal P0 = I, Q = 1e-9 I, R = 1e6 I"),
    "paper7": ({"filter": {"states": 7, "tuning": "paper"}},
               "the paper's own set-up: 7-state run filter, P0 = I, Q = 1e-9 I, R = 1e6 I (realtime)"),
}
"""Study cases: (overrides of the base config, description)."""

ESTIMATOR = "kf"
"""The one estimator of the sweep: the run and stop filters as the case configures them."""

BATCH = 20
"""Replicates per batched call (memory; the numbers do not depend on it)."""

NOISE = NoiseAxis(name="noise_ug_rthz", unit="ug/rtHz", label="accelerometer white noise, ug/sqrt(Hz)")


def merge(base: dict, over: dict) -> dict:
    """Deep merge of mappings (``over`` wins)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


def with_noise(raw: dict, noise: float) -> dict:
    """``raw`` at accelerometer white noise ``noise``, µg/√Hz (the noise axis)."""
    return merge(raw, {"imu": {"accel": {"noise_ug_rthz": float(noise)}}})


def case_raw(raw: dict, case: str, noise: float | None = None) -> dict:
    """The raw config of a study case (base + its overrides), at accelerometer noise ``noise``
    (µg/√Hz; default the config's)."""
    out = merge(raw, CASES[case][0])
    return out if noise is None else with_noise(out, noise)


def case_config(raw: dict, case: str, noise: float | None = None) -> SledConfig:
    return load_config(case_raw(raw, case, noise))


def case_params(raw: dict, case: str, noise: float | None = None) -> dict:
    """What a replicate of ``case`` depends on: the case's config at noise level ``noise``, root
    seed included, without the study section (the sweep's list of cases is no replicate's number).
    A Snakemake param of the rules that run replicates. Keys sorted: a case's overrides are merged
    in, so the same content would otherwise give another order when the base gains the section
    (the sled's mappings carry no order of their own)."""
    return sorted_mapping({k: v for k, v in case_raw(raw, case, noise).items() if k != "study"})


def noise_level(raw: dict) -> float:
    """The study's one noise level: the config's ``imu.accel.noise_ug_rthz``, µg/√Hz."""
    return float(raw["imu"]["accel"]["noise_ug_rthz"])


def replicate_seeds(raw: dict, case: str, replicates) -> list[np.random.SeedSequence]:
    """The runner's SeedSequences of ``replicates`` of ``case`` at the config's noise level."""
    return [replicate_seed(int(raw["seed"]), case, noise_level(raw), r) for r in replicates]


def check(raw) -> dict:
    """Validate a raw sled config and every study case's config; return the mapping with every
    default filled in (InputError naming the field)."""
    full = load_config(raw).raw
    seen = set()
    for i, case in enumerate(full["study"]["cases"]):
        if case in seen:
            raise InputError(f"study.cases[{i}]", f"case {case!r} is listed twice")
        seen.add(case)
        case_config(full, case)
    return full


def run_replicates(cfg: SledConfig, seeds) -> tuple[SimBatch, Identification]:
    """Simulate and identify one replicate per SeedSequence (§2-8)."""
    sb = simulate(cfg, seeds)
    return sb, identify(cfg, sb.traj, sb.f, sb.w)


WARM_TRAJECTORY = {"static_after_s": 10.0}
"""The warm-up's trajectory override: 10 s at rest after the stop instead of the config's (every
phase and both filters still run; the compiled kernels do not depend on the record's length)."""


def warm_kernels(raw: dict) -> None:
    """Compile (or load from numba's cache) the kernels of every study case once, on one short
    replicate each (:data:`WARM_TRAJECTORY`), so that the series and Monte Carlo jobs that follow
    load them from the cache instead of compiling them side by side (docs/rocket-sled.md §11;
    issue 22 item 4). ``raw``: the checked config (:func:`check`); nothing is written."""
    short = merge(raw, {"trajectory": WARM_TRAJECTORY})
    for case in raw["study"]["cases"]:
        # one replicate: the kernels' types do not depend on the batch (platcal.jit.kernel_input)
        sb, idn = run_replicates(case_config(short, case), replicate_seeds(short, case, [0]))
        replicate_batch(idn, sb)  # the cells' tables: their metrics' kernels too


def quantities(states: int):
    """The run filter's attitude estimates (φ_x only with 7 states), arcsec; truth drawn per seed
    (a :class:`platcal.lighttable.Table`, as the runner's tidy tables take it: a cell job loads no
    pandas, issue 22 item 4)."""
    names = ["phi_x", "phi_y", "phi_z"] if states == 7 else ["phi_y", "phi_z"]
    n = len(names)
    return Table({"name": names, "group": ["attitude"] * n, "unit": ["arcsec"] * n,
                  "truth": np.full(n, np.nan)})


def failed_updates(idn: Identification) -> np.ndarray:
    """(S,) updates the run and stop filters skipped; a run with another problem of
    :func:`.identify.run_problems` (non-finite navigation or estimates, final covariance not
    positive definite) counts one, so the runner flags exactly the runs the rig cannot trust."""
    skipped = idn.run.failed_updates + idn.stop.failed_updates
    other = np.array([bool(run_problems(idn, s)) for s in range(len(skipped))])
    return skipped + ((skipped == 0) & other)


def replicate_batch(idn: Identification, sb: SimBatch) -> ReplicateBatch:
    """The :class:`~platcal.rig.ReplicateBatch` of a batch of identified replicates."""
    cols = sorted("xyz".index(name[-1]) for name in phi_columns(idn.cfg.states))
    est = idn.phi_run[:, cols] / ARCSEC
    sig = idn.sig_run[:, cols] / ARCSEC
    truth = effective_phi(sb.truth)[:, cols] / ARCSEC
    met = metric_columns(idn, sb.truth)  # numpy columns: no pandas in a cell job
    return ReplicateBatch(
        quantities=quantities(idn.cfg.states), estimate=est, sigma=sig, truth=truth,
        nees=np.sum(((est - truth) / sig) ** 2, axis=1), nees_dof=len(cols), mean_nis=idn.run.mean_nis,
        failed_updates=failed_updates(idn), passes=1,
        extra={c: np.asarray(v, dtype=float) for c, v in met.items()})


@dataclass(frozen=True)
class SledCase:
    """A study case: its name (keys the seeds) and its raw config (base + overrides)."""

    name: str
    raw: dict


class SledMonteCarlo:
    """The sled's :class:`~platcal.rig.MonteCarloHooks` (see the module docstring)."""

    noise = NOISE

    def check(self, raw: dict) -> dict:
        return check(raw)

    def cases(self, cfg: dict) -> list[str]:
        return list(cfg["study"]["cases"])

    def noise_levels(self, cfg: dict) -> list[float]:
        return [noise_level(cfg)]

    def estimators(self, cfg: dict) -> list[str]:
        return [ESTIMATOR]

    def settings(self, cfg: dict) -> RunSettings:
        return RunSettings(seed=int(cfg["seed"]), replicates=int(cfg["study"]["seeds"]), batch=BATCH,
                           backend="numba", threads=1)

    def case(self, cfg: dict, name: str, case_file: str | None = None) -> SledCase:
        if name not in CASES:
            raise InputError("study.cases", f"unknown case {name!r}; use one of {list(CASES)}")
        return SledCase(name, case_raw(cfg, name))

    def case_file(self, cfg: dict, name: str) -> str | None:
        return None

    def warm_kernels(self, cfg: dict) -> None:
        """The workflow's rule ``kernels``, which the series and the cells wait for (:func:`warm_kernels`)."""
        warm_kernels(cfg)

    def cell_params(self, cfg: dict, case: str, noise: float, estimator: str) -> dict:
        return {**case_params(cfg, case, noise), "replicates": int(cfg["study"]["seeds"])}

    def run_batch(self, cfg: dict, case: SledCase, noise: float, estimator: str, seeds) -> ReplicateBatch:
        sb, idn = run_replicates(load_config(with_noise(case.raw, noise)), seeds)
        return replicate_batch(idn, sb)
