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
from typing import TYPE_CHECKING
from pathlib import Path

import numpy as np

from ...errors import InputError
from ...lighttable import Table
from ...logs.dwells import DwellRule, find_dwells, labelled_frame, lacks_position
from ...mapping import RecordMapping
from ...model.frames import DEG
from ...plausibility import ClockRate, segment_rate, spilled_segment_rate
from ...records import (LOG_COLUMNS, TRUTH_COLUMNS, ColumnSpill, NearestSamples, check_times, grid_origin,  # noqa: F401
                        iter_table, nearest_samples, num, position_blocks, read_table, spilled_grid_origin,
                        spilled_median_step, spilled_positions, spilled_times, whole_group)
from ...scheme import Scheme
from .model import drift, measure

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd

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

FILTER_BLOCK = 8192
"""Filter instants a streamed identify takes at a time (docs/multiposition-1g.md §9, §16): a block
of the filter's pass, of the fit and plausibility sums and of the nominal output's simulation.
Their temporaries (about 300 bytes an instant, 2.5 MB) are then the same whatever the record's
length; smaller blocks only add calls (the numbers do not depend on the block)."""


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


def position_table(scheme: Scheme, k: int, t: np.ndarray, phi: np.ndarray, z: np.ndarray) -> Table:
    """Position ``k`` (0-based) of one replicate (``t`` (n,) s, phi (n, 3) rad, z (n, 6) ug / arcsec)
    as the rows of a record table (§12), numpy columns."""
    n = t.size
    cmd = scheme.angles_deg[k]
    true = cmd[None, :] + phi / DEG
    meas = z[:, 3:] / 3600.0
    df = {"position": np.full(n, k + 1), "t": t}
    for i, c in enumerate(("alpha_cmd", "beta_cmd", "gamma_cmd")):
        df[c] = np.full(n, cmd[i])
    for i, c in enumerate(("Ax", "Ay", "Az")):
        df[c] = z[:, i] * UG
    for i, c in enumerate(ANGLE_COLUMNS):
        df[c] = meas[:, i]
    for i, c in enumerate(TRUTH_COLUMNS):
        df[c] = true[:, i]
    return Table(df)


def position_frame(scheme: Scheme, k: int, t: np.ndarray, phi: np.ndarray, z: np.ndarray) -> pd.DataFrame:
    """:func:`position_table` as the pandas DataFrame the record writer takes
    (:meth:`platcal.lighttable.Table.to_pandas`: pandas loads for ``simulate``, not ``identify``)."""
    return position_table(scheme, k, t, phi, z).to_pandas()


def to_frame(scheme: Scheme, t: np.ndarray, phi: np.ndarray, z: np.ndarray) -> pd.DataFrame:
    """One replicate (phi (K, n, 3) rad, z (K, n, 6) ug / arcsec) as a record table (a pandas
    DataFrame): every position's :func:`position_table`, one after another."""
    return Table.concat([position_table(scheme, k, t, phi[k], z[k]) for k in range(phi.shape[0])]).to_pandas()


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
        df = next(read_chunks(path, mapping))
    except InputError as exc:  # no position column: a continuous log, cut into the scheme's dwells here
        if scheme is None or not lacks_position(exc, mapping):
            raise
        df, segmentation = continuous_record(read_table(path, CONTINUOUS_COLUMNS, GYRO_COLUMNS, mapping=mapping,
                                                        what="a continuous multiposition log", units=UNITS), scheme)
    cols = list(df.columns)
    has_truth = whole_group(cols, TRUTH_COLUMNS, "the true angles")
    pos = df["position"].to_numpy()
    check_position_numbers(pos, scheme)
    present = sorted({int(k) for k in pos})
    # the commanded angles first: a wrong scheme shows there before anywhere else
    commanded = df[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float)
    cmds = [check_commanded(k, commanded[pos == k], scheme) for k in present]
    if scheme is not None:
        check_every_position(present, scheme)
    ts_used, zs, rates = [], [], []
    for k in present:
        rows = df[pos == k]
        keep, t, rate = instants(k, rows["t"].to_numpy(float), scheme, ts, max_gap_s)
        rates.append(rate)
        ts_used.append(t[keep])
        zs.append(outputs(rows, keep))
    cmd = np.array(cmds)
    if scheme is None:
        scheme = record_scheme(path, cmd, ts_used)
    return Record(cmd_deg=cmd, t=ts_used, z=zs, has_truth=has_truth, positions=present,
                  segmentation=segmentation, clock=ClockRate.combine(rates)), scheme


def outputs(rows: pd.DataFrame, keep: np.ndarray) -> np.ndarray:
    """(m, 6) ug and arcsec: the EKF's measurements (Ax, Ay, Az, alpha_m, beta_m, gamma_m) of the
    rows ``keep`` (positions in ``rows``) of a record table in g and deg (docs/multiposition-1g.md §7)."""
    z = np.empty((keep.size, 6))
    z[:, :3] = rows[["Ax", "Ay", "Az"]].to_numpy(float)[keep] / UG
    z[:, 3:] = rows[list(ANGLE_COLUMNS)].to_numpy(float)[keep] * 3600.0
    return z


def read_chunks(path: str | os.PathLike, mapping: RecordMapping | None = None, chunk_rows: int | None = None):
    """The record's checked tables of at most ``chunk_rows`` rows, in file order
    (:func:`platcal.records.iter_table`; None: one table), in :func:`read_record`'s columns."""
    return iter_table(path, COLUMNS, TRUTH_COLUMNS + GYRO_COLUMNS, what="a multiposition record", mapping=mapping,
                      units=UNITS, chunk_rows=chunk_rows)


@dataclass
class StreamScan:
    """What the first read of a streamed record gives (:func:`scan_record`): per position (in
    order) its number, commanded angles (deg), its filter instants and outputs on disk
    (``instants``: one :class:`platcal.records.ColumnSpill` of 7 columns per position, the
    instant's time t (s from the position's start) and z (6,) in ug and arcsec, :func:`outputs`'s
    numbers), their count and the last instant's time (s); whether the true angles are there; the
    scheme (given, or taken from the record as :func:`read_record` does). A context manager: the
    files go at its end (:meth:`close`)."""

    positions: list[int]
    cmd_deg: np.ndarray
    instants: list[ColumnSpill]
    counts: list[int]
    last_t: list[float]
    has_truth: bool
    scheme: Scheme
    clock: ClockRate
    """Every sample's stamps against ``sampling.ts_ms``, as :attr:`Record.clock`."""

    def __enter__(self) -> StreamScan:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        for spill in self.instants:
            spill.close()

    def samples_used(self) -> dict[int, int]:
        """Samples the EKF uses, per position number."""
        return {int(k): int(n) for k, n in zip(self.positions, self.counts)}

    def blocks(self, k: int):
        """Position ``k``'s (0-based) filter instants and outputs from disk, a block at a time
        (:data:`FILTER_BLOCK` instants): ``(t (m,) s, z (m, 6) ug, arcsec)``."""
        for _, v in self.instants[k].blocks():
            for i in range(0, len(v), FILTER_BLOCK):
                w = v[i:i + FILTER_BLOCK]
                yield w[:, 0], w[:, 1:]


def scan_record(chunks, path: str | os.PathLike, scheme: Scheme | None = None, ts: float = 0.02,
                max_gap_s: float = 0.1, each=None) -> StreamScan:
    """Check a record read in ``chunks`` (:func:`read_chunks` tables, file order) as
    :func:`read_record` checks a whole one, holding one position at a time, and select its
    filter instants (docs/multiposition-1g.md §12, §16).

    A streamed record holds each position as one block of rows, positions in increasing order (a
    logger's order; any other order is read whole, ``--chunk-rows 0``). Position numbers and
    commanded angles are checked chunk by chunk; a position's time checks, clock rate and instants
    need its times whole (medians, :func:`platcal.records.check_times`,
    :func:`~platcal.records.grid_origin`), so its ``t``, ``Ax, Ay, Az`` and angle sensors are
    spilled to temporary files (56 bytes a sample on disk, :class:`platcal.records.ColumnSpill`)
    and taken by passes over them (:func:`instants_spilled`); its instants' times and outputs go
    to a file of their own (:attr:`StreamScan.instants`, 56 bytes an instant on disk), which the
    filter's passes read block by block. Held: the longest position's instant indices and times
    (16 bytes an instant) and one block (:data:`FILTER_BLOCK` instants). ``each(k, cmd, last, t, a)``, when given, receives each
    position's number, commanded angles (3,) deg and last instant's time (s), then block by block
    its instants (s) and ``Ax, Ay, Az`` there (g), in time order (the plausibility sums). The
    caller closes the scan (its files): ``with scan_record(...) as scan``."""
    positions, cmds, spills, counts, last_t, rates = [], [], [], [], [], []
    has_truth = None
    held: dict = {"cmd": None, "angles": None}

    def finish(k: int, row0: int, t: ColumnSpill, a: ColumnSpill) -> None:
        keep, tk, rate = instants_spilled(k, t, scheme, ts, max_gap_s)
        rates.append(rate)
        out = ColumnSpill(7)
        spills.append(out)
        # the instants' outputs, block by block: the spilled rows of Ax, Ay, Az and the angle
        # sensors side by side, as outputs() takes them from the table (the same numbers)
        for (i0, acc), (_, ang) in zip(a.blocks(), held["angles"].blocks()):
            first, end = np.searchsorted(keep, [i0, i0 + len(acc)])
            for lo in range(first, end, FILTER_BLOCK):
                hi = min(lo + FILTER_BLOCK, end)
                sel = keep[lo:hi] - i0
                block = np.empty((sel.size, 7))
                block[:, 0] = tk[lo:hi]
                block[:, 1:4] = acc[sel] / UG
                block[:, 4:] = ang[sel] * 3600.0
                out.write(block)
                if each is not None:
                    each(k, held["cmd"], float(tk[-1]), tk[lo:hi], acc[sel])
        held["angles"].close()
        positions.append(k)
        cmds.append(held["cmd"])
        counts.append(int(keep.size))
        last_t.append(float(tk[-1]))

    def check(df) -> None:
        nonlocal has_truth
        if has_truth is None:
            has_truth = whole_group(list(df.columns), TRUTH_COLUMNS, "the true angles")
        check_position_numbers(df["position"].to_numpy(), scheme)

    def commanded(df, i0, i1, k, starts) -> None:
        cmd = df[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float)[i0:i1]
        if starts:
            held["cmd"] = check_commanded(k, cmd, scheme)
            held["angles"] = ColumnSpill(3)  # the previous position's went in its finish
        elif np.ptp(np.vstack([held["cmd"][None], cmd]), axis=0).max() > 1e-9:
            raise InputError(f"--data position {k}", "commanded angles change within the position")
        held["angles"].write(df[list(ANGLE_COLUMNS)].to_numpy(float)[i0:i1])

    try:
        for position in spilled_positions(chunks, check, commanded):
            finish(*position)
        if scheme is not None:
            check_every_position(positions, scheme)
        cmd = np.array(cmds)
        if scheme is None:
            scheme = record_scheme(path, cmd, [np.array([t]) for t in last_t])
    except BaseException:  # a refused record leaves no file behind
        for spill in spills + [held["angles"]]:
            if spill is not None:
                spill.close()
        raise
    return StreamScan(positions, cmd, spills, counts, last_t, bool(has_truth), scheme, ClockRate.combine(rates))


def check_position_numbers(pos: np.ndarray, scheme: Scheme | None) -> None:
    """Refuse a ``position`` that is not a whole number from 1 (and, with ``scheme``, up to its K)."""
    off = (pos != np.round(pos)) | (pos < 1)
    if scheme is not None:
        off |= pos > scheme.n_positions
    if off.any():
        where = f"scheme {scheme.name!r} has positions 1..{scheme.n_positions}" if scheme else \
            "positions are whole numbers from 1"
        raise InputError("--data column position", f"index {num(pos[off][0])} is not a position: {where}")


def check_commanded(k: int, c: np.ndarray, scheme: Scheme | None) -> np.ndarray:
    """Position ``k``'s commanded angles (3,) deg from its rows ``c`` (n, 3) deg: refused when they
    change within the position or (with ``scheme``) differ from the scheme's."""
    if np.ptp(c, axis=0).max() > 1e-9:
        raise InputError(f"--data position {k}", "commanded angles change within the position")
    if scheme is not None and np.max(np.abs(c[0] - scheme.angles_deg[k - 1])) > 1e-6:
        raise InputError(f"--data position {k}", f"commanded angles {c[0].tolist()} are not those of "
                         f"scheme {scheme.name!r} ({scheme.angles_deg[k - 1].tolist()}); pick the right "
                         "--scheme or leave it out")
    return c[0]


def check_every_position(present: list[int], scheme: Scheme) -> None:
    """Refuse a record without every position 1..K of ``scheme``."""
    missing = [k for k in range(1, scheme.n_positions + 1) if k not in present]
    if missing:
        raise InputError("--data column position", f"the record has positions {present} but scheme "
                         f"{scheme.name!r} has {scheme.n_positions}: missing {missing}; pick the right "
                         "--scheme or record every position")


def instants(k: int, t: np.ndarray, scheme: Scheme | None, ts: float,
             max_gap_s: float) -> tuple[np.ndarray, np.ndarray, ClockRate]:
    """``(keep, t from the position's start, clock rate)``: position ``k``'s time checks
    (increasing, seconds, no gap above ``max_gap_s``, spanning the scheme's dwell), the indices of
    its samples nearest the filter instants (see :func:`read_record`) and its stamps' rate error
    against ``ts`` or a whole divisor of it (:func:`platcal.plausibility.segment_rate`)."""
    field = f"--data column t, position {k}"
    med = check_times(t, ts, max_gap_s, field, f"sampling.ts_ms = {ts * 1e3:g} ms", where=" of the position")
    t = t - (0.0 if abs(t[0]) <= max_gap_s else grid_origin(t, med))
    span_verdict(k, float(t[0]), float(t[-1]), scheme, max_gap_s)
    keep = nearest_samples(t, ts, 0.5 * med)
    refuse_few_instants(k, keep, ts)
    return keep, t, segment_rate(t, ts, divisor=True)


def span_verdict(k: int, first: float, last: float, scheme: Scheme | None, max_gap_s: float) -> None:
    """Refuse position ``k`` whose samples (``first`` .. ``last``, s from its start) do not span
    the scheme's dwell within ``max_gap_s`` (:func:`instants`)."""
    if scheme is not None and abs(last - scheme.dwell_s) > max_gap_s:
        raise InputError(f"--data column t, position {k}", f"position {k} spans {num(last)} s (t = {num(first)} .. "
                         f"{num(last)} s from its start), but scheme {scheme.name!r} dwells {scheme.dwell_s:g} s "
                         f"per position (record.max_gap_s = {max_gap_s:g} s); pick the right --scheme")


def refuse_few_instants(k: int, keep: np.ndarray, ts: float) -> None:
    """Refuse position ``k`` with fewer than 2 samples ``keep`` on the filter instants."""
    if keep.size < 2:
        raise InputError(f"--data column t, position {k}",
                         f"only {keep.size} sample(s) fall on the {ts * 1e3:g} ms filter instants")


def instants_spilled(k: int, t: ColumnSpill, scheme: Scheme | None, ts: float,
                     max_gap_s: float) -> tuple[np.ndarray, np.ndarray, ClockRate]:
    """:func:`instants` of position ``k``'s times spilled to a file
    (:class:`platcal.records.ColumnSpill`): ``(keep, t[keep] from the position's start, clock
    rate)``, the same checks and messages, the medians and instants by passes over the file
    (:func:`platcal.records.spilled_times`, :class:`platcal.records.NearestSamples`), the rate by
    :func:`platcal.plausibility.spilled_segment_rate` (to rounding)."""
    med = spilled_times(t, ts, max_gap_s, f"--data column t, position {k}", f"sampling.ts_ms = {ts * 1e3:g} ms",
                        where=" of the position")
    origin = 0.0 if abs(t.first) <= max_gap_s else spilled_grid_origin(t, med)
    first, last = t.first - origin, t.last - origin
    span_verdict(k, first, last, scheme, max_gap_s)
    near = NearestSamples(first, last, ts, 0.5 * med)
    for g, ahead, _ in t.steps(origin):
        near.add(g, ahead)
    keep, tk = near.result()
    refuse_few_instants(k, keep, ts)
    # the rate's median step is that of t - origin (of t when the origin is 0: the same numbers)
    med_t = med if origin == 0.0 else spilled_median_step(t, origin)
    return keep, tk, spilled_segment_rate(t, ts, med_t, divisor=True, shift=origin)


def record_scheme(path: str | os.PathLike, cmd: np.ndarray, ts_used: list[np.ndarray]) -> Scheme:
    """The scheme a record without ``--scheme`` implies: its positions' commanded angles (K, 3)
    deg, dwelling as long as its longest position's instants ``ts_used`` (s)."""
    dwell = max(float(t[-1]) for t in ts_used) or 1.0
    return Scheme(name=f"record:{Path(path).name}", positions=tuple(map(tuple, cmd)), dwell_s=dwell)


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
