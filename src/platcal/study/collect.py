"""The collect step of the Monte Carlo sweep: a rig's cells into its study-wide tidy tables.

Apart from :mod:`platcal.study.montecarlo` because it works on pandas DataFrames, and a cell job,
which imports the runner, loads no pandas (issue 22 item 4: some 0.3 s of every cell's start).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from ..io import atomic_files
from ..log import job_logger
from .montecarlo import CELL


def timing_records(path) -> list[dict]:
    """The timing records of a job's ``timing.json``: one record (a cell), or a list of them (a
    job that runs several cells, e.g. every estimator of a noise level)."""
    t = json.loads(Path(path).read_text())
    return t if isinstance(t, list) else [t]


def collect(coef_files, runs_files, timing_files) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """Concatenate the cells' files into sorted study-wide tables (order-independent)."""
    keys = CELL + ["replicate"]
    coef = pd.concat([pd.read_parquet(f) for f in coef_files], ignore_index=True)
    coef["_i"] = coef.groupby(keys, sort=False).cumcount()  # keeps the rig's quantity order
    coef = coef.sort_values(keys + ["_i"], kind="stable").drop(columns="_i").reset_index(drop=True)
    runs = pd.concat([pd.read_parquet(f) for f in runs_files], ignore_index=True)
    runs = runs.sort_values(keys, kind="stable").reset_index(drop=True)
    timing = pd.DataFrame([t for f in timing_files for t in timing_records(f)])
    timing = timing.sort_values(CELL, kind="stable").reset_index(drop=True)
    return coef, runs, timing


def collect_job(coef_files, runs_files, timing_files, out: dict, log_path=None) -> None:
    """Rule body: cells' files into ``out["coef"]``, ``out["runs"]`` (Parquet) and ``out["timing"]``
    (CSV), written together (a rig's Monte Carlo collect and the centrifuge's comparison collect)."""
    lg = job_logger(log_path)
    lg.info("collecting %d cells", len(coef_files))
    coef, runs, timing = collect(coef_files, runs_files, timing_files)
    with atomic_files(Path(out["coef"]).parent) as tmp:  # the three land together or not at all
        coef.to_parquet(tmp(Path(out["coef"]).name), index=False)
        runs.to_parquet(tmp(Path(out["runs"]).name), index=False)
        timing.to_csv(tmp(Path(out["timing"]).name), index=False)
    lg.info("done: %d rows, %d runs -> %s", len(coef), len(runs), Path(out["coef"]).parent)
