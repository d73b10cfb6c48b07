"""The low-precision centrifuge's hooks for the generic Monte Carlo runner (docs/lowprec-centrifuge.md
§2, §8, §9, §12).

The study is scenarios x estimators x ``study.seeds`` replicates, run by
:mod:`platcal.study.montecarlo` (one Snakemake job per scenario, both methods in it, rule
``montecarlo_cell``) and collected into the tidy tables ``results/lowprec_centrifuge/montecarlo/``.

- Cases: the centrifuge scenarios of §2 (:func:`.scenario.scenarios`: default, the rate and arm
  sweeps, perfect, worst, gross, gross-neg), each a :class:`Scenario`.
- Noise axis: the accelerometer white noise ``residuals.accel_noise_ug_rthz`` (ug/rtHz), one
  level, the config's (the study sweeps the centrifuge, not the noise).
- Estimators: ``proposed`` (the §7 filter on every proposed run) and ``traditional`` (eq. 2 on
  the traditional run); both evaluate on the proposed runs. The proposed cell simulates them once
  for both: it keeps each run's end-of-run errors, floor and sensitivities (``ReplicateBatch.extra``,
  :func:`record_column`), and the traditional cell simulates the traditional run only; its
  cross-validations on the proposed runs are computed from those records by
  :func:`study_frames` (the same seeds, the same arithmetic, so the same numbers as simulating
  the proposed runs again in the traditional cell; 176 of a default scenario's 400 navigations fewer).
- Seeds: replicate r is ``SeedSequence(seed, spawn_key=(stable_key("lowprec_centrifuge"),
  round(1000 noise), r))`` for every scenario (:data:`SEED_KEY`: common random numbers across
  the scenarios, §9) and estimator; each (platform, run) draws from its own children
  (:func:`.truth.run_streams`). ``platcal simulate --seed r`` writes replicate r.
- Quantities: ``<platform>.<run>.<coefficient>`` (ug/g, ug/g^2), the platform's true
  coefficients as truth. Per run (``ReplicateBatch.extra``): the cross-validation metrics of §8,
  ``<platform>|<calibration run>|<evaluated run>|<error>|<metric>`` for the proposed
  calibrations and the exact coefficients (``truth``; proposed cell), the proposed runs' records
  ``<platform>|<run>|<final|floor|sens:<coefficient>>|<error>`` (proposed cell, m/s and m; a
  sensitivity per 1 ug/g or ug/g^2), and ``<platform>|<run>|failed`` (a non-finite estimate, a
  covariance not positive definite or a skipped update).
"""

from __future__ import annotations

import copy
import dataclasses
import re
from dataclasses import dataclass

from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...lighttable import Table
from ...rig import NoiseAxis, ReplicateBatch, RunSettings
from ...study.sweep import replicate_seed
from .config import COEFFS, Centrifuge, load_config
from .metrics import CHANNEL, ERRORS, compensate, effect, nonlinear_effect
from .proposed import K_SLICE, identify_proposed
from .scenario import failed_fits, scenarios, trace_of
from .traditional import identify_traditional
from .truth import TruthCache, coeff_vector, simulate_batch

if TYPE_CHECKING:  # annotations only: the rig's identify imports this module and loads no pandas
    import pandas as pd

SEED_KEY = "lowprec_centrifuge"
"""The name every scenario keys its seeds by: common random numbers across scenarios (§9)."""
ESTIMATORS = ("proposed", "traditional")
METRICS = ("before", "after", "effect_pct", "nonlinear_effect_pct")
"""Per-run cross-validation metrics (§8): final error before and after compensation (m/s, m) and
the effect and nonlinear-part effect (%)."""
MODEL_KEYS = ("site", "platforms", "runs", "profile", "residuals", "seed")
"""Config sections every cell's numbers depend on (with its scenario's centrifuge)."""
UNITS = {"kA": "ug/g", "k2": "ug/g^2"}


@dataclass(frozen=True)
class Scenario:
    """One centrifuge of the §2 sweep: its name, imprecision and sweep axis (rate, arm, extreme, default)."""

    name: str
    centrifuge: Centrifuge
    axis: str
    seed_key: str = SEED_KEY


def metric_column(platform: str, cal: str, ev: str, error: str, metric: str) -> str:
    return f"{platform}|{cal}|{ev}|{error}|{metric}"


def failed_column(platform: str, run: str) -> str:
    return f"{platform}|{run}|failed"


RECORDS = ("final", "floor") + tuple(f"sens:{c}" for c in COEFFS)
"""What the proposed cell keeps of each proposed run for the other methods' cross-validations
(§8): its end-of-run errors before compensation, the floor (coefficients removed) and the
unit-coefficient responses S_k, each over the four errors."""


def record_column(platform: str, run: str, record: str, error: str) -> str:
    return f"{platform}|{run}|{record}|{error}"


def record_columns(platform: str, run: str, final, floor, sens) -> dict:
    """A proposed run's records as per-run columns (B,): ``final``, ``floor`` (B, 4) and ``sens``
    (4 coefficients, 4 errors), the same for every seed, repeated per run."""
    B = final.shape[0]
    blocks = {"final": final, "floor": floor,
              **{f"sens:{c}": np.broadcast_to(sens[k], (B, len(ERRORS))) for k, c in enumerate(COEFFS)}}
    return {record_column(platform, run, rec, e): np.array(v[:, j]) for rec, v in blocks.items()
            for j, e in enumerate(ERRORS)}


def read_records(runs: pd.DataFrame, platform: str, run: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(final (S, 4), floor (S, 4), sens (4, 4)) of a proposed run from the proposed cell's rows
    ``runs`` (:func:`record_columns`); an InputError names the missing column of tables written
    before the records were kept (rerun the study's cells)."""
    missing = [c for c in (record_column(platform, run, r, e) for r in RECORDS for e in ERRORS) if c not in runs]
    if missing:
        raise InputError(f"runs.{missing[0]}", "the proposed cell's records of this run are missing: rerun "
                         "the study's Monte Carlo cells with this version of platcal")
    block = {r: np.stack([runs[record_column(platform, run, r, e)].to_numpy(float) for e in ERRORS], axis=1)
             for r in RECORDS}
    sens = np.stack([block[f"sens:{c}"][0] for c in COEFFS]) if len(runs) else np.zeros((len(COEFFS), len(ERRORS)))
    return block["final"], block["floor"], sens


def calibration_runs(study, platform: str, estimator: str) -> list[str]:
    """The runs an estimator identifies on: the proposed runs, or the traditional run."""
    return list(study.runs[platform]) if estimator == "proposed" else ["traditional"]


def quantities(study, estimator: str) -> Table:
    """The identified coefficients of a cell, ``<platform>.<run>.<coefficient>``, with their truths."""
    rows = [(f"{p}.{r}.{c}", "accel", UNITS[c[:2]], float(study.platforms[p][c]))
            for p in study.platform_names() for r in calibration_runs(study, p, estimator) for c in COEFFS]
    # numpy columns: the runner builds the cell's tables without pandas (issue 22 item 4)
    return Table({k: [r[j] for r in rows] for j, k in enumerate(("name", "group", "unit", "truth"))})


def cross_metrics(platform: str, cal: str, ev: str, before, after, after_truth) -> dict:
    """The §8 metrics of one calibration -> evaluation cell, as per-run columns (B,)."""
    cols = {}
    eff, nl = effect(before, after), nonlinear_effect(before, after, after_truth)
    for j, e in enumerate(ERRORS):
        for metric, val in zip(METRICS, (before, after, eff, nl)):
            cols[metric_column(platform, cal, ev, e, metric)] = val[:, j]
    return cols


def evaluate(platform: str, cal: str, ev: str, final, floor, sens, truth, c=None) -> dict:
    """The §8 metrics of calibration ``c`` (B, 4; None: the exact coefficients ``truth`` (4,))
    on the evaluated run's ``final`` errors, compensated about its exact ``floor`` with its
    sensitivities ``sens`` (second order in c_hat - c), as :func:`cross_metrics` columns."""
    tcoef = np.broadcast_to(truth, final.shape)
    c = tcoef if c is None else c
    return cross_metrics(platform, cal, ev, final, compensate(floor, sens, c - tcoef), floor)


def block_nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(B,) e^T P^-1 e of the coefficient errors (B, 4) with their covariance block (B, 4, 4); NaN
    where the block is singular or not finite (the run is flagged failed)."""
    out = np.full(err.shape[0], np.nan)
    for b in range(err.shape[0]):
        try:
            out[b] = err[b] @ np.linalg.solve(P[b], err[b])
        except np.linalg.LinAlgError:
            pass
    return out


def cell_batch(study, estimator: str, seeds, replicates=None) -> ReplicateBatch:
    """Simulate and identify one replicate per SeedSequence of ``seeds`` for every platform of
    ``study`` (its centrifuge is the scenario's) with ``estimator`` (§6-§8): ``proposed``
    simulates and identifies every proposed run and keeps their cross-validations and records;
    ``traditional`` simulates and identifies the traditional run only (its cross-validations on
    the proposed runs are :func:`study_frames`'s, from the proposed cell's records)."""
    B = len(seeds)
    est, sig, nees_sum, nis, n_blocks, skipped = [], [], np.zeros(B), np.zeros(B), 0, np.zeros(B, np.int64)
    extra = {}
    arm = study.centrifuge.arm_m
    # each distinct run profile's true motion built once in the cell
    truths = TruthCache(study, [(p, r) for p in study.platform_names() for r in study.run_names(p)
                                if (r == "traditional") == (estimator == "traditional")])
    for p in study.platform_names():
        truth = coeff_vector(study, p)
        finals, floors, sens, coef = {}, {}, {}, {}
        for r in study.run_names(p):
            if (r == "traditional") != (estimator == "traditional"):
                continue
            # the traditional run needs no floor and no unit-coefficient responses (not evaluated on)
            rb = simulate_batch(study, p, r, seeds, replicates, floor=r != "traditional", sens=r != "traditional",
                                truths=truths)
            if r == "traditional":
                c = identify_traditional(rb.prof.t, rb.v_ind, rb.psi, rb.prof.schedule, rb.prof.levels, arm)
                est.append(c)
                sig.append(np.full_like(c, np.nan))
                extra[failed_column(p, r)] = failed_fits(c)
                coef[r] = c
                continue
            finals[r], floors[r], sens[r] = rb.final.copy(), rb.final_floor, rb.sens_final.copy()
            fr = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, rb.prof.schedule, arm,
                                   study.latitude_deg)
            est.append(fr.coeffs)
            sig.append(fr.sigmas)
            nees_sum += block_nees(fr.coeffs - truth, fr.P[:, K_SLICE, K_SLICE])
            nis += fr.mean_nis
            n_blocks += 1
            skipped += fr.failed_updates
            extra[failed_column(p, r)] = failed_fits(fr.x, fr.P) | (fr.failed_updates > 0)
            coef[r] = fr.coeffs
            extra.update(record_columns(p, r, finals[r], floors[r], sens[r]))
            del rb
        for j in finals:
            for i, c in list(coef.items()) + [("truth", None)]:
                extra.update(evaluate(p, i, j, finals[j], floors[j], sens[j], truth, c))
    q = quantities(study, estimator)
    proposed = estimator == "proposed"
    return ReplicateBatch(
        quantities=q, estimate=np.concatenate(est, axis=1), sigma=np.concatenate(sig, axis=1),
        nees=nees_sum if proposed else np.full(B, np.nan), nees_dof=len(q),
        mean_nis=nis / max(n_blocks, 1) if proposed else np.full(B, np.nan), failed_updates=skipped,
        passes=1, extra=extra, uncertainty=proposed)


def check_study(raw) -> dict:
    """Validate a raw config and return the mapping with every default filled in; the scenario
    names are file-name safe (InputError naming the field otherwise)."""
    study = load_config(raw)
    for name in scenarios(study):
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise InputError("study.rate_errors", f"scenario name {name!r} is not file-name safe")
    return study.raw


WARM_SETTINGS = {"profile": {"rest_first_s": 1.0, "rest_between_s": 1.0}, "traditional": {"hold_s": 1.0, "rest_last_s": 1.0}}
"""The warm-up's shorter rests and holds (s): every segment of the profiles still runs, and the
compiled kernels do not depend on the record's length."""


def warm_kernels(cfg: dict) -> None:
    """Compile (or load from numba's cache) the kernels of both estimators once, on two short
    replicates of the first scenario (:data:`WARM_SETTINGS`), so that the Monte Carlo cells that
    follow load them from numba's cache instead of compiling them side by side
    (docs/lowprec-centrifuge.md §2; issue 22 item 4). ``cfg``: the checked config; nothing is written."""
    short = copy.deepcopy(cfg)
    for section, values in WARM_SETTINGS.items():
        short[section].update(values)
    hooks = LowprecMonteCarlo()
    case = hooks.case(short, hooks.cases(short)[0])
    for estimator in ESTIMATORS:
        hooks.run_batch(short, case, hooks.noise_levels(short)[0], estimator,
                        [replicate_seed(int(short["seed"]), case.name, hooks.noise_levels(short)[0], r) for r in (0, 1)])


class LowprecMonteCarlo:
    """The low-precision centrifuge's :class:`~platcal.rig.MonteCarloHooks` (module docstring)."""

    noise = NoiseAxis(name="accel_noise_ug_rthz", unit="ug/rtHz",
                      label="accelerometer white noise, ug/rtHz")

    def check(self, raw: dict) -> dict:
        return check_study(raw)

    def cases(self, cfg: dict) -> list[str]:
        return list(scenarios(load_config(cfg)))

    def noise_levels(self, cfg: dict) -> list[float]:
        return [float(cfg["residuals"]["accel_noise_ug_rthz"])]

    def estimators(self, cfg: dict) -> list[str]:
        return list(ESTIMATORS)

    def settings(self, cfg: dict) -> RunSettings:
        n = int(cfg["study"]["seeds"])
        # one batch: the filter and the simulator are vectorised over the replicates
        return RunSettings(seed=int(cfg["seed"]), replicates=n, batch=n, backend="numba", threads=1)

    def case(self, cfg: dict, name: str, case_file: str | None = None) -> Scenario:
        sc = scenarios(load_config(cfg))
        if name not in sc:
            raise InputError("study", f"unknown scenario {name!r}; the config's are {list(sc)}")
        return Scenario(name=name, centrifuge=sc[name]["centrifuge"], axis=sc[name]["axis"])

    def case_file(self, cfg: dict, name: str) -> str | None:
        return None

    def warm_kernels(self, cfg: dict) -> None:
        """The workflow's rule ``kernels``, which the cells wait for (:func:`warm_kernels`)."""
        warm_kernels(cfg)

    def cell_params(self, cfg: dict, case: str, noise: float, estimator: str) -> dict:
        p = {k: cfg[k] for k in MODEL_KEYS}
        p["centrifuge"] = dataclasses.asdict(self.case(cfg, case).centrifuge)
        p["replicates"] = int(cfg["study"]["seeds"])
        # the traditional run's profile enters its own cells only
        p["traditional"] = cfg["traditional"] if estimator == "traditional" else None
        return p

    def run_batch(self, cfg: dict, case, noise: float, estimator: str, seeds) -> ReplicateBatch:
        study = load_config(cfg)
        if float(noise) != float(study.residuals["accel_noise_ug_rthz"]):
            raise InputError("residuals.accel_noise_ug_rthz", f"the study has one noise level, "
                             f"{study.residuals['accel_noise_ug_rthz']:g}, not {noise:g}")
        return cell_batch(study.with_centrifuge(case.centrifuge), estimator, seeds)


CROSS_COLUMNS = ["scenario", "seed", "platform", "method", "cal_run", "eval_run", "channel", "error", "before",
                 "after", "effect_pct", "nonlinear_effect_pct", "failed"]
COEFF_COLUMNS = ["scenario", "seed", "platform", "method", "run", "coefficient", "estimate", "sigma", "truth",
                 "failed"]


def _cell_runs(runs: pd.DataFrame, scenario: str, estimator: str) -> pd.DataFrame:
    return runs[(runs["scheme"] == scenario) & (runs["estimator"] == estimator)].sort_values("replicate")


def traditional_metrics(study, scenario: str, platform: str, ev: str, coef: pd.DataFrame,
                        runs: pd.DataFrame) -> dict:
    """The §8 metrics of the traditional calibrations of ``scenario`` on the proposed run ``ev``
    (:func:`cross_metrics` columns, seeds in replicate order): the traditional cell's estimates
    (``coef``) applied to the proposed cell's records of that run (``runs``, :func:`read_records`)."""
    prop = _cell_runs(runs, scenario, "proposed")
    trad = _cell_runs(runs, scenario, "traditional")
    seeds = trad["replicate"].to_numpy(np.int64)
    if not np.array_equal(prop["replicate"].to_numpy(np.int64), seeds):
        raise InputError("runs.replicate", f"scenario {scenario!r}: the proposed and traditional cells ran "
                         "different replicates; rerun both cells with the same study.seeds")
    final, floor, sens = read_records(prop, platform, ev)
    c = coef[(coef["scheme"] == scenario) & (coef["estimator"] == "traditional")]
    c = c.set_index(["name", "replicate"])["estimate"]
    est = np.stack([c.loc[f"{platform}.traditional.{k}"].reindex(seeds).to_numpy(float) for k in COEFFS], axis=1)
    return evaluate(platform, "traditional", ev, final, floor, sens, coeff_vector(study, platform), est)


def study_frames(study, names, coef: pd.DataFrame, runs: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The cross-validation and coefficient tables (:data:`CROSS_COLUMNS`, :data:`COEFF_COLUMNS`)
    of the scenarios ``names`` from the study's tidy tables ``coef`` and ``runs`` (§8). Rows:
    scenario, platform, evaluated run, method (proposed runs, traditional, exact), seed, error;
    and scenario, platform, run, seed, coefficient."""
    cross, coeffs = [], []
    for sc in names:
        for p in study.platform_names():
            cals = [(r, "proposed") for r in study.runs[p]] + [("traditional", "traditional"), ("truth", "proposed")]
            for j in study.runs[p]:
                for cal, est in cals:
                    r = _cell_runs(runs, sc, est)
                    S = len(r)
                    cols = r if cal != "traditional" else traditional_metrics(study, sc, p, j, coef, runs)
                    vals = {m: np.stack([np.asarray(cols[metric_column(p, cal, j, e, m)], float) for e in ERRORS],
                                        axis=1) for m in METRICS}
                    failed = (r[failed_column(p, cal)].to_numpy(bool) if cal != "truth" else np.zeros(S, bool))
                    n = S * len(ERRORS)
                    cross.append(Table({
                        "scenario": np.full(n, sc), "seed": np.repeat(r["replicate"].to_numpy(np.int64), len(ERRORS)),
                        "platform": np.full(n, p), "method": np.full(n, "truth" if cal == "truth" else est),
                        "cal_run": np.full(n, cal), "eval_run": np.full(n, j),
                        "channel": [CHANNEL[e] for e in ERRORS] * S, "error": list(ERRORS) * S,
                        **{m: v.ravel() for m, v in vals.items()}, "failed": np.repeat(failed, len(ERRORS))}))
            for run in study.run_names(p):
                est = "traditional" if run == "traditional" else "proposed"
                c = coef[(coef["scheme"] == sc) & (coef["estimator"] == est)
                         & coef["name"].str.startswith(f"{p}.{run}.")]
                c = c.sort_values("replicate", kind="stable")
                bad = _cell_runs(runs, sc, est).set_index("replicate")[failed_column(p, run)].astype(bool)
                n = len(c)
                coeffs.append(Table({
                    "scenario": np.full(n, sc), "seed": c["replicate"].to_numpy(np.int64), "platform": np.full(n, p),
                    "method": np.full(n, est), "run": np.full(n, run),
                    "coefficient": np.array([name.split(".")[-1] for name in c["name"]], dtype=str),
                    "estimate": c["estimate"].to_numpy(float), "sigma": c["sigma"].to_numpy(float),
                    "truth": c["truth"].to_numpy(float), "failed": bad.loc[c["replicate"]].to_numpy(bool)}))
    # built as tables and handed over as pandas DataFrames (:meth:`platcal.lighttable.Table.to_pandas`):
    # this module is imported by the rig's identify, which loads no pandas
    return (Table.concat(cross)[CROSS_COLUMNS].to_pandas(), Table.concat(coeffs)[COEFF_COLUMNS].to_pandas())


def study_trace(cfg: dict) -> dict:
    """The figures' traces (:func:`.scenario.trace_of`): replicate 0 of the default scenario, the
    first platform's first proposed run and its traditional run, with the same seeds as the
    study's cells (so the same numbers)."""
    study = load_config(cfg)
    p = study.platform_names()[0]
    run = list(study.runs[p])[0]
    seeds = [replicate_seed(study.seed, SEED_KEY, study.residuals["accel_noise_ug_rthz"], 0)]
    rb = simulate_batch(study, p, run, seeds)
    fr = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, rb.prof.schedule,
                           study.centrifuge.arm_m, study.latitude_deg)
    tb = simulate_batch(study, p, "traditional", seeds)
    trad = identify_traditional(tb.prof.t, tb.v_ind, tb.psi, tb.prof.schedule, tb.prof.levels, study.centrifuge.arm_m)
    return trace_of(rb, fr.coeffs[0], trad[0], coeff_vector(study, p))
