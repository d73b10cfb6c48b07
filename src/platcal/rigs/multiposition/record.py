"""Test records of the multi-position rig (docs/multiposition-1g.md §12).

The positioned-platform log of :data:`platcal.records.LOG_COLUMNS` (docs/centrifuge-model.md §13: ``position, t, alpha_cmd, beta_cmd,
gamma_cmd, Ax, Ay, Az`` in s, deg and g) plus the measured gimbal angles ``alpha_m, beta_m,
gamma_m`` (deg, present in a real log) and, for simulated runs only, the true ``alpha, beta,
gamma`` (deg). A recorded log in these columns is identified exactly as a simulated one; its
timestamps are used as recorded (:func:`read_record`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...logs.dwells import DwellRule, find_dwells, labelled_frame, lacks_position
from ...mapping import RecordMapping
from ...model.frames import DEG
from ...plausibility import ClockRate, segment_rate
from ...records import (LOG_COLUMNS, TRUTH_COLUMNS, check_times, grid_origin, nearest_samples, num,  # noqa: F401
                         read_table, whole_group, write_record)  # write_record: re-exported for the rig's commands
from ...scheme import Scheme
from .model import drift, measure

ANGLE_COLUMNS = ("alpha_m", "beta_m", "gamma_m")
GYRO_COLUMNS = ("wx", "wy", "wz")
"""The platform gyros' outputs, deg/h (the rate each measures about its input axis), optional in a
log: identify does not read them (the gyros are seen through the gimbal angles, §6); compensate
takes their modelled drift out when they are there (docs/multiposition-1g.md §5)."""
COLUMNS = LOG_COLUMNS + ANGLE_COLUMNS
UG = 1e-6
UNITS = {"position": "dimensionless", "t": "s", "alpha_cmd": "deg", "beta_cmd": "deg", "gamma_cmd": "deg",
         "Ax": "g", "Ay": "g", "Az": "g", "alpha_m": "deg", "beta_m": "deg", "gamma_m": "deg",
         "alpha": "deg", "beta": "deg", "gamma": "deg", "wx": "deg/h", "wy": "deg/h", "wz": "deg/h"}
"""The record's columns and their units (§12), for a config's ``record:`` mapping; g is standard
gravity, 9.80665 m/s^2 (:data:`platcal.mapping.STANDARD_GRAVITY`)."""


@dataclass
class Record:
    """What the EKF reads: commanded angles (K, 3) deg, per position times (s) and outputs
    (n_k, 6) in ug and arcsec; ``has_truth`` when the true angles were recorded."""

    cmd_deg: np.ndarray
    t: list
    z: list
    has_truth: bool
    positions: list = None
    """Position numbers (1-based) of ``t`` and ``z``; None: 1..K."""
    segmentation: tuple | None = None
    """For a continuous log cut here: ``(t (N,) s, angle sensors (N, 3) deg, dwells)``."""
    clock: ClockRate = ClockRate.none()
    """Every sample's stamps against ``sampling.ts_ms`` (or a whole divisor of it): the clock-rate
    error the identification checks (:func:`platcal.plausibility.clock_rate`)."""

    def samples_used(self) -> dict[int, int]:
        """Samples the EKF uses, per position number."""
        ks = self.positions or list(range(1, len(self.t) + 1))
        return {int(k): int(len(t)) for k, t in zip(ks, self.t)}

    def packed(self):
        """``(tk (K, m), Z (1, K, m, 6), nk (K,))`` padded to the longest position."""
        K = len(self.t)
        m = max(len(t) for t in self.t)
        tk = np.zeros((K, m))
        Z = np.zeros((1, K, m, 6))
        nk = np.array([len(t) for t in self.t], dtype=np.int64)
        for k in range(K):
            tk[k, : nk[k]] = self.t[k]
            Z[0, k, : nk[k]] = self.z[k]
        return tk, Z, nk


def to_frame(scheme: Scheme, t: np.ndarray, phi: np.ndarray, z: np.ndarray) -> pd.DataFrame:
    """One replicate (phi (K, n, 3) rad, z (K, n, 6) ug / arcsec) as a record table."""
    K, n = phi.shape[:2]
    cmd = scheme.angles_deg
    true = cmd[:, None, :] + phi / DEG
    meas = z[..., 3:] / 3600.0
    df = {"position": np.repeat(np.arange(1, K + 1), n), "t": np.tile(t, K)}
    for i, c in enumerate(("alpha_cmd", "beta_cmd", "gamma_cmd")):
        df[c] = np.repeat(cmd[:, i], n)
    for i, c in enumerate(("Ax", "Ay", "Az")):
        df[c] = z[..., i].ravel() * UG
    for i, c in enumerate(ANGLE_COLUMNS):
        df[c] = meas[..., i].ravel()
    for i, c in enumerate(TRUTH_COLUMNS):
        df[c] = true[..., i].ravel()
    return pd.DataFrame(df)


def read_record(path: str | os.PathLike, scheme: Scheme | None = None, ts: float = 0.02,
                max_gap_s: float = 0.1, mapping: RecordMapping | None = None) -> tuple[Record, Scheme]:
    """Read and check a record (UTF-8 CSV or Parquet, :func:`platcal.records.read_table`) and
    select the samples the EKF uses; InputError naming the column (and position) otherwise.

    Times as recorded (docs/multiposition-1g.md §16): per position, ``t`` must increase, its
    median step must be within a factor 10 of the sample period ``ts`` (``sampling.ts_ms``, so
    t is in seconds), and no gap may exceed ``max_gap_s`` (``record.max_gap_s``). A position's
    clock may restart at 0 (a first sample within ``max_gap_s`` of 0) or run on from any origin
    (a constant offset, removed by :func:`platcal.records.grid_origin`). The EKF instants are
    the multiples of ``ts`` from the position's start; each takes the nearest sample within half
    the median step (decimation by time), used at its recorded time: the filter propagates over
    the actual interval, so jitter enters the dynamics and a small gap drops only the instants it
    covers. With ``scheme`` the record must hold exactly its positions 1..K, with its commanded
    angles, each spanning the scheme's dwell (within ``max_gap_s``); without, the positions and
    dwell are taken from the record (a recorded log needs no scheme file). A log in other columns
    or units is read through the config's ``record:`` ``mapping`` (:data:`UNITS`).
    """
    segmentation = None
    try:
        df = read_table(path, COLUMNS, TRUTH_COLUMNS + GYRO_COLUMNS, what="a multiposition record", mapping=mapping,
                        units=UNITS)
    except InputError as exc:  # no position column: a continuous log, cut into the scheme's dwells here
        if scheme is None or not lacks_position(exc, mapping):
            raise
        df, segmentation = continuous_record(read_table(path, CONTINUOUS_COLUMNS, GYRO_COLUMNS, mapping=mapping,
                                                        what="a continuous multiposition log", units=UNITS), scheme)
    cols = list(df.columns)
    has_truth = whole_group(cols, TRUTH_COLUMNS, "the true angles")
    pos = df["position"].to_numpy()
    off = (pos != np.round(pos)) | (pos < 1)
    if scheme is not None:
        off |= pos > scheme.n_positions
    if off.any():
        where = f"scheme {scheme.name!r} has positions 1..{scheme.n_positions}" if scheme else \
            "positions are whole numbers from 1"
        raise InputError("--data column position", f"index {num(pos[off][0])} is not a position: {where}")
    present = sorted({int(k) for k in pos})
    cmds = []
    for k in present:  # the commanded angles first: a wrong scheme shows there before anywhere else
        c = df.loc[pos == k, ["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float)
        if np.ptp(c, axis=0).max() > 1e-9:
            raise InputError(f"--data position {k}", "commanded angles change within the position")
        if scheme is not None and np.max(np.abs(c[0] - scheme.angles_deg[k - 1])) > 1e-6:
            raise InputError(f"--data position {k}", f"commanded angles {c[0].tolist()} are not those of "
                             f"scheme {scheme.name!r} ({scheme.angles_deg[k - 1].tolist()}); pick the right "
                             "--scheme or leave it out")
        cmds.append(c[0])
    if scheme is not None:
        missing = [k for k in range(1, scheme.n_positions + 1) if k not in present]
        if missing:
            raise InputError("--data column position", f"the record has positions {present} but scheme "
                             f"{scheme.name!r} has {scheme.n_positions}: missing {missing}; pick the right "
                             "--scheme or record every position")
    ts_used, zs, rates = [], [], []
    for k in present:
        rows = df[pos == k]
        field = f"--data column t, position {k}"
        t = rows["t"].to_numpy(float)
        med = check_times(t, ts, max_gap_s, field, f"sampling.ts_ms = {ts * 1e3:g} ms", where=" of the position")
        t = t - (0.0 if abs(t[0]) <= max_gap_s else grid_origin(t, med))
        rates.append(segment_rate(t, ts, divisor=True))
        if scheme is not None:
            span = float(t[-1])
            if abs(span - scheme.dwell_s) > max_gap_s:
                raise InputError(field, f"position {k} spans {num(span)} s (t = {num(t[0])} .. {num(t[-1])} s "
                                 f"from its start), but scheme {scheme.name!r} dwells {scheme.dwell_s:g} s per "
                                 f"position (record.max_gap_s = {max_gap_s:g} s); pick the right --scheme")
        keep = nearest_samples(t, ts, 0.5 * med)
        if keep.size < 2:
            raise InputError(field, f"only {keep.size} sample(s) fall on the {ts * 1e3:g} ms filter instants")
        z = np.empty((keep.size, 6))
        z[:, :3] = rows[["Ax", "Ay", "Az"]].to_numpy(float)[keep] / UG
        z[:, 3:] = rows[list(ANGLE_COLUMNS)].to_numpy(float)[keep] * 3600.0
        ts_used.append(t[keep])
        zs.append(z)
    cmd = np.array(cmds)
    if scheme is None:
        dwell = max(float(t[-1]) for t in ts_used) or 1.0
        scheme = Scheme(name=f"record:{Path(path).name}", positions=tuple(map(tuple, cmd)), dwell_s=dwell)
    return Record(cmd_deg=cmd, t=ts_used, z=zs, has_truth=has_truth, positions=present,
                  segmentation=segmentation, clock=ClockRate.combine(rates)), scheme


CONTINUOUS_COLUMNS = ("t", "Ax", "Ay", "Az") + ANGLE_COLUMNS
"""A continuous log (no ``position`` and commanded angles): its dwells are found (:mod:`platcal.logs.dwells`)."""


def continuous_record(df: pd.DataFrame, scheme: Scheme, rule: DwellRule = DwellRule()) -> tuple[pd.DataFrame, tuple]:
    """A continuous log as a record: its static dwells found and matched to ``scheme``'s
    positions by the angle sensors (:func:`platcal.logs.dwells.find_dwells`) and labelled
    (:func:`platcal.logs.dwells.labelled_frame`: each dwell's clock counted from its first
    sample, the commanded angles filled in, slews dropped). Returns the record and ``(t, angles,
    dwells)`` for the figure. InputError when a position is found twice or not at all."""
    t = df["t"].to_numpy(float)
    ang = df[list(ANGLE_COLUMNS)].to_numpy(float)
    dwells = find_dwells(t, ang, df[["Ax", "Ay", "Az"]].to_numpy(float), scheme.angles_deg, rule)
    return labelled_frame(df, dwells, scheme.angles_deg, scheme.name), (t, ang, dwells)


COMPENSATE_COLUMNS = ("t", "Ax", "Ay", "Az") + ANGLE_COLUMNS
"""What ``platcal compensate`` needs of a log: accelerometer outputs and the gimbal angle sensors."""


def compensate_frame(df: pd.DataFrame, coef: np.ndarray) -> pd.DataFrame:
    """``df`` with ``Ax, Ay, Az`` (g) compensated: the modelled error of §6 at the measured gimbal
    angles (``alpha_m, beta_m, gamma_m``, deg) with coefficients ``coef`` (24, state order of
    :func:`.model.coef_names`) is taken out, leaving the error-free output of each accelerometer
    (the specific force along its nominal input axis, g). The angle sensors' own noise enters
    through the modelled misalignment terms only (second order). When the log has the gyro
    outputs ``wx, wy, wz`` (deg/h, :data:`GYRO_COLUMNS`) they come out less the modelled drift of
    §5 at the measured angles."""
    ang = df[list(ANGLE_COLUMNS)].to_numpy(float) * DEG
    x_cal = np.r_[np.zeros(3), coef]
    x_free = np.zeros_like(x_cal)
    err = np.array([measure(a, x_cal)[0][:3] - measure(a, x_free)[0][:3] for a in ang])  # ug
    out = df.copy()
    out[["Ax", "Ay", "Az"]] = df[["Ax", "Ay", "Az"]].to_numpy(float) - err * UG
    if whole_group(df.columns, GYRO_COLUMNS, "the gyro outputs"):
        out[list(GYRO_COLUMNS)] = df[list(GYRO_COLUMNS)].to_numpy(float) - np.array([drift(x_cal, a) for a in ang])
    return out
