"""The test record of one run (docs/lowprec-centrifuge.md §10): CSV or Parquet, plus a side JSON.

Columns, one row per sample: ``t`` (s), ``VE, VN`` (m/s), ``pE, pN`` (m, relative to the start),
``heading_deg`` (gimbal azimuth angle, wrapped to [0, 360)), ``fE, fN`` (m/s^2, the INS's own
horizontal specific force; optional on input: without them it is differentiated from VE, VN),
``schedule`` (``static`` | ``spinning`` | ``hold``). A simulated record adds simulation-only
truth columns ``truth_dVE, truth_dVN`` (m/s), ``truth_dpE, truth_dpN`` (m), ``truth_phi_x/y/z``
(rad) and ``truth_theta_deg``; the identification never reads them. [D] The drawn parameters
and the true coefficients go to a side file ``<record stem>.truth.json`` next to the record.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...io import atomic_path, atomic_to_csv, atomic_to_parquet, atomic_write_text
from .config import COEFFS
from .profile import SCHEDULE_NAMES
from .truth import RunBatch

REQUIRED = ("t", "VE", "VN", "pE", "pN", "heading_deg", "schedule")
NUMERIC = ("t", "VE", "VN", "pE", "pN", "heading_deg", "fE", "fN")


@dataclass(frozen=True)
class Record:
    """A record read back: arrays for the estimators (psi in rad, not unwrapped)."""

    t: np.ndarray
    v: np.ndarray          # (N, 2)
    p: np.ndarray          # (N, 2)
    psi: np.ndarray        # (N,)
    f: np.ndarray          # (N, 2)
    schedule: np.ndarray   # (N,) int8
    truth: dict | None


def truth_path(record_path) -> Path:
    p = Path(record_path)
    return p.with_name(p.stem + ".truth.json")


def check_out_path(path, field: str = "--out") -> Path:
    p = Path(path)
    if p.suffix not in (".csv", ".parquet"):
        raise InputError(field, f"a record is .csv or .parquet, got {p.name!r}")
    return p


def record_frame(rb: RunBatch, i: int = 0) -> pd.DataFrame:
    """The record of seed ``rb.seeds[i]`` (§10)."""
    df = pd.DataFrame({
        "t": rb.prof.t, "VE": rb.v_ind[i, :, 0], "VN": rb.v_ind[i, :, 1], "pE": rb.p_ind[i, :, 0],
        "pN": rb.p_ind[i, :, 1], "heading_deg": np.mod(np.degrees(rb.psi[i]), 360.0),
        "fE": rb.kin.f[:, 0], "fN": rb.kin.f[:, 1],
        "schedule": np.asarray(SCHEDULE_NAMES)[rb.prof.schedule],
        "truth_dVE": rb.err[i, :, 0], "truth_dVN": rb.err[i, :, 1], "truth_dpE": rb.err[i, :, 2],
        "truth_dpN": rb.err[i, :, 3], "truth_theta_deg": np.degrees(rb.kin.theta)})
    if rb.phi is not None:
        for j, ax in enumerate("xyz"):
            df[f"truth_phi_{ax}"] = rb.phi[i, :, j]
    return df


def truth_json(rb: RunBatch, study, i: int = 0) -> dict:
    cen = study.centrifuge
    return {"rig": "lowprec_centrifuge", "platform": rb.platform, "run": rb.run, "seed": int(rb.seeds[i]),
            "levels_g": list(rb.prof.levels),
            "coefficients": dict(zip(COEFFS, map(float, rb.coeffs))),
            "centrifuge": {"arm_m": cen.arm_m, "rate_error": cen.rate_error, "arm_error_mm": cen.arm_error_mm,
                           "stretch_mm_per_g": cen.stretch_mm_per_g},
            "drawn": {"k0_ug": rb.draws.k0_ug[i].tolist(), "scale_ppm": rb.draws.scale_ppm[i].tolist(),
                      "gyro_drift_deg_h": rb.draws.drift_deg_h[i].tolist(),
                      "phi0_rad": rb.draws.phi0_rad[i].tolist()},
            "final_errors": dict(zip(("dVE", "dVN", "dpE", "dpN"), map(float, rb.err[i, -1])))}


def write_record(df: pd.DataFrame, meta: dict, path) -> None:
    """Record and side JSON, each written atomically (the JSON first: a record never lacks its truth)."""
    path = check_out_path(path)
    atomic_write_text(truth_path(path), json.dumps(meta, indent=1) + "\n")
    if path.suffix == ".parquet":
        atomic_to_parquet(df, path)
    else:
        atomic_to_csv(df, path)


def read_record(path, use_truth: bool = True) -> Record:
    """Read and check a record; InputError naming the column (and row) of the first problem."""
    p = Path(path)
    if not p.is_file():
        raise InputError("--data", f"no such record file: {path}")
    try:
        df = pd.read_parquet(p) if p.suffix == ".parquet" else pd.read_csv(p)
    except Exception as exc:  # noqa: BLE001 - any reader failure is bad input
        raise InputError("--data", f"cannot read {p.name} as a record ({exc.__class__.__name__})") from None
    missing = [c for c in REQUIRED if c not in df.columns]
    if missing:
        raise InputError(f"{p.name}: column {missing[0]}", f"missing; a record has columns {list(REQUIRED)}")
    if len(df) < 3:
        raise InputError(f"{p.name}: rows", "a record needs at least 3 samples")
    for c in NUMERIC:
        if c not in df.columns:
            continue
        col = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(col))
        if bad.size:
            raise InputError(f"{p.name}: column {c}, row {int(bad[0]) + 1}",
                             f"not a finite number ({df[c].iloc[bad[0]]!r}); NaN or text in a record is refused")
        df[c] = col
    t = df["t"].to_numpy()
    if np.any(np.diff(t) <= 0):
        raise InputError(f"{p.name}: column t, row {int(np.flatnonzero(np.diff(t) <= 0)[0]) + 2}",
                         "time must increase strictly")
    sched_s = df["schedule"].astype(str)
    bad = ~sched_s.isin(SCHEDULE_NAMES)
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(f"{p.name}: column schedule, row {i + 1}",
                         f"{sched_s.iloc[i]!r} is not one of {list(SCHEDULE_NAMES)}")
    schedule = np.array([SCHEDULE_NAMES.index(s) for s in sched_s], dtype=np.int8)
    v = df[["VE", "VN"]].to_numpy()
    if "fE" in df.columns and "fN" in df.columns:
        f = df[["fE", "fN"]].to_numpy()
    else:  # [D] no specific-force columns: differentiate the INS velocity (nav frame, Coriolis neglected)
        f = np.gradient(v, t, axis=0)
    truth = None
    tp = truth_path(p)
    if use_truth and tp.is_file():
        try:
            truth = json.loads(tp.read_text())
        except ValueError:
            raise InputError(tp.name, "not a JSON file") from None
    return Record(t=t, v=v, p=df[["pE", "pN"]].to_numpy(), psi=np.radians(df["heading_deg"].to_numpy()), f=f,
                  schedule=schedule, truth=truth)


def write_estimates(out_dir, names, est, sigma, truth: dict | None) -> Path:
    """``estimates.csv`` (name, estimate, sigma, truth, error) in ``out_dir``, atomically."""
    df = pd.DataFrame({"name": list(names), "estimate": est, "sigma": sigma})
    if truth is not None:
        df["truth"] = [truth[n] for n in names]
        df["error"] = df["estimate"] - df["truth"]
    path = Path(out_dir) / "estimates.csv"
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)
    return path
