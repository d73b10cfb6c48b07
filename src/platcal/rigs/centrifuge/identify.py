"""Identification of one test record: record -> EKF estimate -> tables on disk."""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ...estimation.consistency import nees
from ...io import atomic_to_csv, atomic_write_text
from .config import Study
from .ekf import Estimate, FilterSettings, run_ekf
from .record import TRUTH_COLUMNS, filter_input
from .scheme import Scheme
from .simulate import simulate
from .tables import covariance_frame, estimates_frame, table2_markdown


def simulate_identify(study: Study, scheme: Scheme, seeds, settings: FilterSettings | None = None,
                      truth: np.ndarray | None = None) -> Estimate:
    """Simulate a batch (one run per SeedSequence; ``seeds=None``: one noise-free run) and identify
    it with the EKF: the one simulate -> identify path of the centrifuge (Monte Carlo, design
    studies, observability checks). ``settings`` defaults to the study's filter without history;
    ``truth`` (48,) to the study's. Runs are independent: a batch gives the numbers of B runs of one.
    """
    truth = study.truth if truth is None else truth
    fs = replace(study.filter, history_every_s=None) if settings is None else settings
    params = study.centrifuge.scheme_params(scheme)
    sim = simulate(truth, scheme, params, study.noise, seeds, sample_s=study.sample_s, keep_every=study.keep_every)
    K = scheme.n_positions
    return run_ekf([sim.A[:, k] for k in range(K)], [sim.t] * K, scheme.angles_deg, params, fs)


def identify_record(study: Study, scheme: Scheme, df: pd.DataFrame) -> Estimate:
    """Run the study's EKF over a validated test record (one run: a batch of one)."""
    fin = filter_input(df, scheme, study.filter.period_s)
    params = study.centrifuge.scheme_params(scheme)[np.array(fin.positions) - 1]
    return run_ekf(fin.z, fin.t, fin.cmd_deg, params, study.filter)


def write_identification(out_dir: str | os.PathLike, est: Estimate, study: Study, truth_known: bool,
                         seconds: float | None = None) -> dict:
    """Write ``estimates.csv``, ``covariance.csv``, ``history.csv``, ``table2.md`` and ``summary.json``.

    ``history.csv`` is the decimated history of every pass: ``t`` (s from the start of the
    first pass), each state's estimate and its 1-sigma (``<name>_sigma``), angles in rad.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nc = est.n_coef
    truth = study.truth if truth_known else None
    df = estimates_frame(est.names[:nc], est.coef[0], est.coef_sigma[0], truth)
    summary = {"n_states": len(est.names), "passes": study.filter.passes,
               "mean_nis": float(est.mean_nis[0]), "failed_updates": int(est.failed_updates[0])}
    if seconds is not None:
        summary["seconds"] = seconds
    if truth is not None:
        idx = study.filter.coef_index
        summary["nees"] = float(nees(est.coef, est.P[:, :nc, :nc], truth[idx][None])[0])
        summary["nees_dof"] = nc
        rel = df["rel_err_pct"].abs()
        gyro = df["name"].str.startswith("D")
        summary["max_abs_rel_err_pct_gyro"] = float(rel[gyro].max())
        summary["max_abs_rel_err_pct_accel"] = float(rel[~gyro].max())
    atomic_to_csv(df, out / "estimates.csv")
    atomic_to_csv(covariance_frame(est.names, est.P[0]), out / "covariance.csv", index=True)
    atomic_to_csv(history_frame(est), out / "history.csv")
    atomic_write_text(out / "table2.md", table2_markdown(df))
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def history_frame(est: Estimate, replicate: int = 0) -> pd.DataFrame:
    """The decimated estimate and 1-sigma history of one run as a wide table."""
    cols = {"t": est.history_t}
    for i, name in enumerate(est.names):
        cols[name] = est.history_x[replicate, :, i]
    for i, name in enumerate(est.names):
        cols[f"{name}_sigma"] = est.history_sigma[replicate, :, i]
    return pd.DataFrame(cols)


def truth_known(df: pd.DataFrame) -> bool:
    """A record carries its truth when it has the simulated true-angle columns."""
    return all(c in df.columns for c in TRUTH_COLUMNS)


def timed(fn, *args, **kw):
    """``(result, seconds)`` of a call."""
    t0 = time.perf_counter()
    res = fn(*args, **kw)
    return res, time.perf_counter() - t0

