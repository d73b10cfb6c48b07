"""Replicate 0 of a sled case as time series, the figures' representative run (one small
workflow job per case; docs/rocket-sled.md §8, §11).

Apart from :mod:`platcal.rigs.sled.study` (the tables, figures and report) so that the series
jobs import neither matplotlib nor the plotting helpers (about 0.4 s of CPU in each); the series
is numpy columns written by :func:`platcal.io.atomic_write_csv` (the text ``DataFrame.to_csv``
writes), so they load no pandas either (about 0.5 s more; issue 22 item 4).
"""

from __future__ import annotations

import numpy as np

from ...io import atomic_write_csv
from ...log import job_logger
from .config import ARCSEC
from .identify import after_a, after_b, effective_phi, phi_columns
from .montecarlo import case_config, replicate_seeds, run_replicates


def series(idn, truth, s: int = 0) -> dict[str, np.ndarray]:
    """Time series of seed slot ``s`` at the filter epochs (m, arcsec) for the figures: column
    name -> values, in the CSV's order (docs/rocket-sled.md §11)."""
    cfg = idn.cfg
    J = idn.j_end
    k = idn.epochs.k
    t = idn.t[k]
    a = after_a(idn)
    b = after_b(idn)
    n = len(k)
    df = {"t": t, "r_y": idn.r[s, k, 1], "r_z": idn.r[s, k, 2]}
    js = idn.j_stop
    ay = np.r_[a["y_run"][s], a["y_static"][s, 1:]]
    az = np.r_[a["z_run"][s], np.full(J - js, np.nan)]
    df["a_y"], df["a_z"] = ay, az
    kb = k[k <= idn.n_stop]
    df["b_y"] = np.r_[b[s, kb, 0], np.full(J + 1 - len(kb), np.nan)]
    df["b_z"] = np.r_[b[s, kb, 1], np.full(J + 1 - len(kb), np.nan)]
    df["e_naive"] = idn.r[s, k, 0] - truth.x_true[s, k]
    df["e_con"] = idn.x_con[s, k] - truth.x_true[s, k]
    df["e_inst"] = truth.x_inst[s, k] - truth.x_true[s, k]
    eff = effective_phi(truth)[s] / ARCSEC
    for name, i in phi_columns(cfg.states).items():
        ax = name[-1]
        df[f"{name}_hat"] = np.r_[idn.run.x[s, :, i], np.full(J - js, np.nan)] / ARCSEC
        df[f"{name}_sigma"] = np.r_[idn.run.sigma[s, :, i], np.full(J - js, np.nan)] / ARCSEC
        # constants of the run, repeated on every row (as a DataFrame broadcasts a scalar)
        df[f"{name}_eff"] = np.full(n, eff["xyz".index(ax)])
        df[f"{name}_true"] = np.full(n, truth.params.phi0[s, "xyz".index(ax)] / ARCSEC)
    return df


def write_series(raw: dict, case: str, out, log_path=None) -> None:
    """series.csv of a case's replicate 0 (the figures' representative run): the same
    SeedSequence, config and code as replicate 0 of its Monte Carlo cell."""
    log = job_logger(log_path, "platcal.sled")
    sb, idn = run_replicates(case_config(raw, case), replicate_seeds(raw, case, [0]))
    atomic_write_csv(out, series(idn, sb.truth), float_format="%.10g")
    log.info(f"sled case {case}: series of replicate 0 -> {out}")
