"""Test records: one table format for simulated and recorded centrifuge runs (docs/centrifuge-model.md §13).

Columns: ``position`` (1-based), ``t`` (s since the position's start), ``alpha_cmd,
beta_cmd, gamma_cmd`` (deg), ``Ax, Ay, Az`` (g) and, for simulated runs only, the true
``alpha, beta, gamma`` (deg). CSV keeps full float precision; ``.parquet`` is read and
written as well. Identification reads only the columns a real log has.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...io import atomic_to_csv, atomic_to_parquet
from ...model.frames import DEG
from .scheme import Scheme

LOG_COLUMNS = ("position", "t", "alpha_cmd", "beta_cmd", "gamma_cmd", "Ax", "Ay", "Az")
TRUTH_COLUMNS = ("alpha", "beta", "gamma")
TIME_TOL = 1e-6
"""Tolerance (s) when matching sample times to filter instants."""


@dataclass
class FilterInput:
    """What the EKF reads from a record: per position, the filter instants and outputs."""

    positions: list[int]
    t: list[np.ndarray]
    z: list[np.ndarray]
    cmd_deg: np.ndarray


def sim_to_frame(sim, scheme: Scheme, replicate: int = 0) -> pd.DataFrame:
    """One replicate of a :class:`~platcal.simulate.SimResult` as a test-record table."""
    K = scheme.n_positions
    n = sim.t.size
    cmd = scheme.angles_deg
    return pd.DataFrame({
        "position": np.repeat(np.arange(1, K + 1), n),
        "t": np.tile(sim.t, K),
        "alpha_cmd": np.repeat(cmd[:, 0], n),
        "beta_cmd": np.repeat(cmd[:, 1], n),
        "gamma_cmd": np.repeat(cmd[:, 2], n),
        "Ax": sim.A[replicate, :, :, 0].ravel(),
        "Ay": sim.A[replicate, :, :, 1].ravel(),
        "Az": sim.A[replicate, :, :, 2].ravel(),
        "alpha": sim.angles[replicate, :, :, 0].ravel() / DEG,
        "beta": sim.angles[replicate, :, :, 1].ravel() / DEG,
        "gamma": sim.angles[replicate, :, :, 2].ravel() / DEG,
    })


def write_record(df: pd.DataFrame, path: str | os.PathLike) -> None:
    """Write a test record atomically: ``.parquet`` as Parquet, anything else as CSV."""
    if str(path).endswith(".parquet"):
        atomic_to_parquet(df, path)
    else:
        atomic_to_csv(df, path, float_format=None)


def read_record(path: str | os.PathLike) -> pd.DataFrame:
    """Read a test record (CSV or Parquet) and check its columns and values.

    Raises InputError naming the column (and row) on missing or extra columns, non-numeric,
    NaN or infinite values.
    """
    path = Path(path)
    try:
        df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    except FileNotFoundError as exc:
        raise InputError("--data", f"no such file: {path}") from exc
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise InputError("--data", f"cannot read {path} as a test record: {exc}") from exc
    cols = list(df.columns)
    missing = [c for c in LOG_COLUMNS if c not in cols]
    if missing:
        raise InputError(f"--data column {missing[0]}", f"missing; a test record has columns {list(LOG_COLUMNS)} "
                         f"(and optionally {list(TRUTH_COLUMNS)})")
    extra = [c for c in cols if c not in LOG_COLUMNS + TRUTH_COLUMNS]
    if extra:
        raise InputError(f"--data column {extra[0]}", f"unexpected column; allowed: {list(LOG_COLUMNS + TRUTH_COLUMNS)}")
    present_truth = [c for c in TRUTH_COLUMNS if c in cols]
    if present_truth and len(present_truth) != 3:
        raise InputError(f"--data column {[c for c in TRUTH_COLUMNS if c not in cols][0]}",
                         "the true angles come as all three of alpha, beta, gamma or not at all")
    if len(df) == 0:
        raise InputError("--data", "the record has no rows")
    for c in cols:
        values = pd.to_numeric(df[c], errors="coerce")
        bad = ~np.isfinite(values.to_numpy(float))
        if bad.any():
            row = int(np.argmax(bad))
            raise InputError(f"--data column {c}, row {row + 2}",
                             f"value {df[c].iloc[row]!r} is not a finite number (NaN, infinite or text)")
        df[c] = values
    return df


def filter_input(df: pd.DataFrame, scheme: Scheme, period_s: float) -> FilterInput:
    """Select the samples at the filter instants (multiples of ``period_s``) per position.

    Checks that every position index is in the scheme, that the commanded angles match the
    scheme's, and that time increases within each position.
    """
    K = scheme.n_positions
    pos = df["position"].to_numpy()
    if not np.all(pos == np.round(pos)) or pos.min() < 1 or pos.max() > K:
        bad = pos[(pos != np.round(pos)) | (pos < 1) | (pos > K)][0]
        raise InputError("--data column position", f"index {bad!r} is not a position of scheme "
                         f"{scheme.name!r} (1..{K})")
    present = sorted(set(pos.astype(int)))
    cmd = scheme.angles_deg
    ts, zs = [], []
    for k in present:
        rows = df[pos == k]
        t = rows["t"].to_numpy(float)
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0)) + 1
            raise InputError(f"--data column t, position {k}",
                             f"time does not increase at sample {i} (t = {t[i - 1]!r} then {t[i]!r})")
        rec_cmd = rows[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float)
        if np.max(np.abs(rec_cmd - cmd[k - 1])) > 1e-6:
            raise InputError(f"--data position {k}", f"commanded angles {rec_cmd[0].tolist()} differ from "
                             f"scheme {scheme.name!r} position {k} {cmd[k - 1].tolist()}; pick the right --scheme")
        m = np.round(t / period_s)
        keep = np.abs(t - m * period_s) < TIME_TOL
        if keep.sum() < 1:
            raise InputError(f"--data column t, position {k}", f"no sample falls on a {period_s * 1e3:g} ms filter instant")
        ts.append(t[keep])
        zs.append(rows[["Ax", "Ay", "Az"]].to_numpy(float)[keep][None])
    return FilterInput(positions=present, t=ts, z=zs, cmd_deg=cmd[np.array(present) - 1])
