"""The sled test record (docs/rocket-sled.md §10): one row per IMU sample.

Columns ``t`` (s), ``fx, fy, fz`` (m/s^2), ``wx, wy, wz`` (rad/s) in the record's body axes
(the navigation's initial axes, see :mod:`.simulate`); a simulated record adds the
simulation-only truth columns ``x_true``, ``vx_true`` (error-free run) and ``x_inst``
(instrument-only run), m and m/s at the row's time. The drawn error parameters go to a side
file ``<record>.truth.json`` (JSON: seed, phi0, accelerometer and gyro errors in engineering
units). CSV (``.csv``) or Parquet (``.parquet``) by suffix; both files written atomically, the
side file first, so a record never appears without its truth.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...io import atomic_to_csv, atomic_to_parquet, atomic_write_text
from .config import G, SledConfig
from .sensors import ErrorParams
from .simulate import SimBatch, Truth
from .trajectory import Trajectory, build_trajectory

IMU_COLUMNS = ("t", "fx", "fy", "fz", "wx", "wy", "wz")
TRUTH_COLUMNS = ("x_true", "vx_true", "x_inst")


def truth_path(record: str | Path) -> Path:
    """``<record>.truth.json`` beside the record."""
    return Path(str(record) + ".truth.json")


def check_out_path(path: str | Path, option: str = "--out") -> Path:
    path = Path(path)
    if path.suffix not in (".csv", ".parquet"):
        raise InputError(option, f"a sled record is written as .csv or .parquet, got {path.name!r}")
    return path


def sim_frame(sb: SimBatch, s: int = 0) -> pd.DataFrame:
    """Seed slot ``s`` of a simulated batch as a record frame."""
    df = pd.DataFrame({"t": sb.traj.t})
    for i, ax in enumerate("xyz"):
        df[f"f{ax}"] = sb.f[s, :, i]
    for i, ax in enumerate("xyz"):
        df[f"w{ax}"] = sb.w[s, :, i]
    df["x_true"] = sb.truth.x_true[s]
    df["vx_true"] = sb.truth.vx_true[s]
    df["x_inst"] = sb.truth.x_inst[s]
    return df


def write_record(sb: SimBatch, path: str | Path, s: int = 0) -> None:
    """Write seed slot ``s`` as a record plus its ``.truth.json`` (atomic)."""
    path = check_out_path(path)
    side = {"seed": sb.seeds[s], "nabla_static_ug": (sb.truth.nabla_static[s] / G * 1e6).tolist(),
            **sb.truth.params.to_json(s)}
    atomic_write_text(truth_path(path), json.dumps(side, indent=1) + "\n")
    df = sim_frame(sb, s)
    if path.suffix == ".parquet":
        atomic_to_parquet(df, path)
    else:
        atomic_to_csv(df, path, float_format="%.17g")


def read_record(path: str | Path, cfg: SledConfig) -> tuple[Trajectory, pd.DataFrame]:
    """Read and check a record against the config's trajectory; InputError naming the field.

    Refused: a missing file or column, non-numeric or non-finite values, a time step that is
    not the config's IMU period (a gap), a length that is not the config's trajectory.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("--data", f"no such file: {path}")
    try:
        df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001 (any parse failure is bad input)
        raise InputError("--data", f"cannot read {path.name} as {path.suffix or 'CSV'} ({exc.__class__.__name__})") from None
    for c in IMU_COLUMNS:
        if c not in df.columns:
            raise InputError(f"--data column {c}", f"missing; a sled record has columns {list(IMU_COLUMNS)}")
    for c in list(IMU_COLUMNS) + [c for c in TRUTH_COLUMNS if c in df.columns]:
        vals = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(vals))
        if bad.size:
            raise InputError(f"--data column {c}", f"row {bad[0]}: not a finite number")
    traj = build_trajectory(cfg)
    t = df["t"].to_numpy(dtype=float)
    dt = np.diff(t)
    bad = np.flatnonzero(np.abs(dt - cfg.dt) > 1e-6 * cfg.dt + 1e-9)
    if bad.size:
        k = bad[0]
        raise InputError("--data column t", f"time step {dt[k]:.6g} s between rows {k} and {k + 1} "
                         f"(t = {t[k]:.6g} -> {t[k + 1]:.6g}); the record must be gap-free at "
                         f"imu.rate_hz = {cfg.rate_hz:g} Hz")
    if len(df) != traj.n:
        raise InputError("--data", f"{len(df)} rows; the config's trajectory has {traj.n} IMU samples "
                         f"({traj.n * cfg.dt:g} s): check the trajectory section or the record")
    return traj, df


def record_arrays(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(1,N,3) specific force and rate of a record frame."""
    f = df[["fx", "fy", "fz"]].to_numpy(dtype=float)[None]
    w = df[["wx", "wy", "wz"]].to_numpy(dtype=float)[None]
    return f, w


def record_truth(path: str | Path, df: pd.DataFrame) -> Truth | None:
    """The truth of a simulated record (columns + side file), or None when either is absent."""
    side = truth_path(path)
    if not all(c in df.columns for c in TRUTH_COLUMNS) or not side.is_file():
        return None
    try:
        d = json.loads(side.read_text())
        p = ErrorParams.from_json([d])
        nab = np.asarray(d["nabla_static_ug"], dtype=float)[None] * G * 1e-6
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(str(side), f"not a sled truth file ({exc.__class__.__name__}: {exc})") from None
    return Truth(params=p, x_true=df["x_true"].to_numpy(float)[None], vx_true=df["vx_true"].to_numpy(float)[None],
                 x_inst=df["x_inst"].to_numpy(float)[None], nabla_static=nab)
