"""Test records of the multi-position rig (docs/multiposition-1g.md §12).

The centrifuge's record (docs/centrifuge-model.md §13: ``position, t, alpha_cmd, beta_cmd,
gamma_cmd, Ax, Ay, Az`` in s, deg and g) plus the measured gimbal angles ``alpha_m, beta_m,
gamma_m`` (deg, present in a real log) and, for simulated runs only, the true ``alpha, beta,
gamma`` (deg). A recorded log in these columns is identified exactly as a simulated one.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ...model.frames import DEG
from ..centrifuge.record import LOG_COLUMNS, TRUTH_COLUMNS, write_record  # noqa: F401  (re-exported)
from ..centrifuge.scheme import Scheme

ANGLE_COLUMNS = ("alpha_m", "beta_m", "gamma_m")
COLUMNS = LOG_COLUMNS + ANGLE_COLUMNS
UG = 1e-6


@dataclass
class Record:
    """What the EKF reads: commanded angles (K, 3) deg, per position times (s) and outputs
    (n_k, 6) in ug and arcsec; ``has_truth`` when the true angles were recorded."""

    cmd_deg: np.ndarray
    t: list
    z: list
    has_truth: bool

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


def read_record(path: str | os.PathLike, scheme: Scheme | None = None) -> tuple[Record, Scheme]:
    """Read and check a record (CSV or Parquet); InputError naming the column otherwise.

    With ``scheme`` the commanded angles must match it; without, the positions are taken from
    the record (a recorded log needs no scheme file).
    """
    path = Path(path)
    try:
        df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    except FileNotFoundError:
        raise InputError("--data", f"no such file: {path}") from None
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise InputError("--data", f"cannot read {path} as a test record: {exc}") from None
    cols = list(df.columns)
    missing = [c for c in COLUMNS if c not in cols]
    if missing:
        raise InputError(f"--data column {missing[0]}", f"missing; a multiposition record has columns "
                         f"{list(COLUMNS)} (the gimbal angle sensors alpha_m, beta_m, gamma_m in deg, §12) "
                         f"and optionally the true {list(TRUTH_COLUMNS)}")
    extra = [c for c in cols if c not in COLUMNS + TRUTH_COLUMNS]
    if extra:
        raise InputError(f"--data column {extra[0]}", f"unexpected column; allowed: {list(COLUMNS + TRUTH_COLUMNS)}")
    if len(df) == 0:
        raise InputError("--data", "the record has no rows")
    for c in cols:
        v = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = ~np.isfinite(v)
        if bad.any():
            row = int(np.argmax(bad))
            raise InputError(f"--data column {c}, row {row + 2}", f"value {df[c].iloc[row]!r} is not a finite number")
        df[c] = v
    pos = df["position"].to_numpy()
    if np.any(pos != np.round(pos)) or pos.min() < 1:
        raise InputError("--data column position", "positions are whole numbers from 1")
    present = sorted(set(pos.astype(int)))
    cmds, ts, zs = [], [], []
    for k in present:
        rows = df[pos == k]
        c = rows[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float)
        if np.ptp(c, axis=0).max() > 1e-9:
            raise InputError(f"--data position {k}", "commanded angles change within the position")
        if scheme is not None:
            if k > scheme.n_positions or np.max(np.abs(c[0] - scheme.angles_deg[k - 1])) > 1e-6:
                raise InputError(f"--data position {k}", f"commanded angles {c[0].tolist()} are not those of "
                                 f"scheme {scheme.name!r}; pick the right --scheme or leave it out")
        t = rows["t"].to_numpy(float)
        if np.any(np.diff(t) <= 0):
            raise InputError(f"--data column t, position {k}", "time must increase within a position")
        z = np.empty((len(rows), 6))
        z[:, :3] = rows[["Ax", "Ay", "Az"]].to_numpy(float) / UG
        z[:, 3:] = rows[list(ANGLE_COLUMNS)].to_numpy(float) * 3600.0
        cmds.append(c[0])
        ts.append(t - t[0])
        zs.append(z)
    cmd = np.array(cmds)
    if scheme is None:
        dwell = max(float(t[-1]) for t in ts) or 1.0
        scheme = Scheme(name=f"record:{path.name}", positions=tuple(map(tuple, cmd)), dwell_s=dwell)
    return Record(cmd_deg=cmd, t=ts, z=zs, has_truth=all(c in cols for c in TRUTH_COLUMNS)), scheme
