"""Test records: one table format for simulated and recorded centrifuge runs (docs/centrifuge-model.md §13).

Columns: ``position`` (1-based), ``t`` (s since the position's start), ``alpha_cmd,
beta_cmd, gamma_cmd`` (deg), ``Ax, Ay, Az`` (g) and, for simulated runs only, the true
``alpha, beta, gamma`` (deg). CSV keeps full float precision; ``.parquet`` is read and
written as well. Identification reads only the columns a real log has.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...lighttable import Table
from ...records import (LOG_COLUMNS, TRUTH_COLUMNS, UNIT_FACTOR, ColumnSpill, NearestSamples, check_gap,  # noqa: F401
                        check_increasing, check_time_unit, gap_verdict, grid_origin, iter_table, nearest_samples,
                        pass_median, refuse_back, spilled_grid_origin, spilled_steps, unit_verdict, whole_group,
                        write_record)  # (UNIT_FACTOR, write_record re-exported)
from ...records import num as _num
from ...logs.calibration import Calibration
from ...logs.dwells import DwellRule, find_dwells, labelled_frame
from ...model.frames import DEG
from ...model.instruments import FULL_NAMES, INDEX, N_FULL, compensate_accelerometers, gyro_drifts
from ...scheme import Scheme

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd
    from ...mapping import RecordMapping  # annotations only: a Monte Carlo cell loads no pint (issue 22 item 4)

GYRO_COLUMNS = ("wx", "wy", "wz")
"""The platform gyros' outputs, deg/h (the rate each measures about its input axis), optional in a
log: identify does not read them (the model sees the gyros through the platform's attitude,
docs/centrifuge-model.md §4, §6); compensate takes their modelled drift out when they are there."""
UNITS = {"position": "dimensionless", "t": "s", "alpha_cmd": "deg", "beta_cmd": "deg", "gamma_cmd": "deg",
         "Ax": "g", "Ay": "g", "Az": "g", "alpha": "deg", "beta": "deg", "gamma": "deg",
         "wx": "deg/h", "wy": "deg/h", "wz": "deg/h"}
OPTIONAL_COLUMNS = TRUTH_COLUMNS + GYRO_COLUMNS
"""Columns a log may hold besides :data:`platcal.records.LOG_COLUMNS`: the true angles
(simulation) and the gyro outputs; each group all or none."""
"""The record's columns and their units (docs/centrifuge-model.md §13), for a config's ``record:`` mapping."""
UNIT_FACTOR_G = 3.0
"""A record whose median specific-force magnitude is this many times larger or smaller than the
centrifuge's is refused: its accelerations are in another unit (m/s^2 gives 9.8, mg 1000)."""


@dataclass
class FilterInput:
    """What the EKF reads from a record: per position, the filter instants and outputs."""

    positions: list[int]
    t: list[np.ndarray]
    z: list[np.ndarray]
    cmd_deg: np.ndarray


def sim_to_frame(sim, scheme: Scheme, replicate: int = 0) -> pd.DataFrame:
    """One replicate of a :class:`~platcal.simulate.SimResult` as a test-record table (a pandas
    DataFrame for the record writer, :meth:`platcal.lighttable.Table.to_pandas`)."""
    K = scheme.n_positions
    n = sim.t.size
    cmd = scheme.angles_deg
    return Table({
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
    }).to_pandas()


def chunk_to_frame(chunk, scheme: Scheme, replicate: int = 0) -> pd.DataFrame:
    """One replicate of a :class:`~platcal.rigs.centrifuge.simulate.SimChunk` as rows of a test
    record: the rows :func:`sim_to_frame` gives for those samples."""
    m = chunk.t.size
    cmd = scheme.angles_deg[chunk.position]
    return Table({
        "position": np.full(m, chunk.position + 1),
        "t": chunk.t,
        "alpha_cmd": np.full(m, cmd[0]),
        "beta_cmd": np.full(m, cmd[1]),
        "gamma_cmd": np.full(m, cmd[2]),
        "Ax": chunk.A[replicate, :, 0],
        "Ay": chunk.A[replicate, :, 1],
        "Az": chunk.A[replicate, :, 2],
        "alpha": chunk.angles[replicate, :, 0] / DEG,
        "beta": chunk.angles[replicate, :, 1] / DEG,
        "gamma": chunk.angles[replicate, :, 2] / DEG,
    }).to_pandas()


def read_record(path: str | os.PathLike, mapping: RecordMapping | None = None) -> Table:
    """Read a test record (CSV or Parquet) and check its columns and values; a log in other
    columns or units is read through the config's ``record:`` ``mapping`` (:data:`UNITS`). The
    whole file as one :class:`platcal.lighttable.Table` (:func:`platcal.records.iter_table`'s one
    chunk, the checks of ``read_table`` without its DataFrame: identify loads no pandas).

    Raises InputError naming the column (and row) on missing or extra columns, non-numeric,
    NaN or infinite values.
    """
    df = next(iter_table(path, LOG_COLUMNS, OPTIONAL_COLUMNS, mapping=mapping, units=UNITS))
    has_truth_columns(df.columns)
    return df


def has_truth_columns(columns) -> bool:
    """Whether a record's ``columns`` hold the true angles; refused when only some of the three do."""
    return whole_group(columns, TRUTH_COLUMNS, "the true angles")


def check_position_numbers(pos: np.ndarray, scheme: Scheme) -> None:
    """Refuse a ``position`` value that is not one of the scheme's 1..K."""
    K = scheme.n_positions
    off = (pos != np.round(pos)) | (pos < 1) | (pos > K)
    if off.any():
        raise InputError("--data column position", f"index {_num(pos[off][0])} is not a position of scheme "
                         f"{scheme.name!r}, which has positions 1..{K}; pick the right --scheme")


def check_commanded(pos: np.ndarray, rec_cmd: np.ndarray, scheme: Scheme) -> None:
    """Refuse rows whose commanded angles ``rec_cmd`` (N, 3) deg differ from the scheme's at their
    position ``pos`` (N,) (by more than 1e-6 deg)."""
    cmd = scheme.angles_deg
    bad = np.max(np.abs(rec_cmd - cmd[pos.astype(int) - 1]), axis=1) > 1e-6
    if bad.any():
        i = int(np.argmax(bad))
        k = int(pos[i])
        raise InputError(f"--data position {k}", f"commanded angles {rec_cmd[i].tolist()} differ from "
                         f"scheme {scheme.name!r} position {k} {cmd[k - 1].tolist()}; pick the right --scheme")


def check_every_position(found: list[int], scheme: Scheme) -> None:
    """Refuse a record whose positions ``found`` are not all of the scheme's 1..K."""
    K = scheme.n_positions
    missing = [k for k in range(1, K + 1) if k not in found]
    if missing:
        raise InputError("--data column position", f"the record has positions {_ranges(found)} but scheme "
                         f"{scheme.name!r} has {K} (1..{K}): missing {_ranges(missing)}; pick the right --scheme "
                         "or record every position")


def check_record(df: pd.DataFrame, scheme: Scheme, sample_s: float, max_gap_s: float,
                 expected_g: np.ndarray | None = None) -> None:
    """Refuse a record that does not fit the scheme or the sampling, before any filtering.

    Checks, per position, with messages that say what was found and what was expected: the set
    of positions is the scheme's 1..K; ``t`` increases; its median step is within a factor
    :data:`UNIT_FACTOR` of ``sample_s`` (so ``t`` is in seconds); no gap between samples, and
    none between the position's start (t = 0) or end (t = dwell) and its first or last sample,
    exceeds ``max_gap_s`` (config ``record.max_gap_s``); the samples therefore span the scheme's
    dwell. A position's t may count from any origin (:func:`position_origin`). With
    ``expected_g`` (K,), the magnitude of the specific force each position should measure (g),
    the median of ``|(Ax, Ay, Az)|`` must be within a factor :data:`UNIT_FACTOR_G`
    of it (so the accelerations are in g, not mg or m/s^2). Raises InputError naming the column
    and position.
    """
    pos = df["position"].to_numpy(float)
    check_position_numbers(pos, scheme)
    found = sorted({int(p) for p in pos})
    check_every_position(found, scheme)
    a = df[["Ax", "Ay", "Az"]].to_numpy(float) if expected_g is not None else None
    for k in found:
        check_position(k, df["t"].to_numpy(float)[pos == k], None if a is None else a[pos == k], scheme, sample_s,
                       max_gap_s, None if expected_g is None else float(expected_g[k - 1]))


def check_position(k: int, t: np.ndarray, a: np.ndarray | None, scheme: Scheme, sample_s: float, max_gap_s: float,
                   want_g: float | None = None) -> None:
    """:func:`check_record`'s checks of position ``k`` from its times ``t`` (s) and, with
    ``want_g`` (the magnitude of the specific force it should measure, g), its outputs ``a``
    (n, 3) g."""
    field = f"--data column t, position {k}"
    refuse_few_samples(k, t.size, scheme, sample_s)
    check_increasing(t, field, " of the position")
    med = check_time_unit(t, sample_s, field, *_unit_words(sample_s))
    t = t - position_origin(t, med, max_gap_s)
    check_gap(t, max_gap_s, field)
    size = None
    if want_g is not None:
        with np.errstate(over="ignore"):  # 1e300 g is refused below, without a numpy warning
            size = float(np.median(np.linalg.norm(a, axis=1)))
    position_verdicts(k, float(t[0]), float(t[-1]), med, scheme, max_gap_s, want_g, size)


def _unit_words(sample_s: float) -> tuple[str, str]:
    """The ``expected`` and ``origin_note`` of a position's time-unit check."""
    return f"sampling.sample_ms = {sample_s * 1e3:g} ms = {sample_s:g} s", " since the position's start"


def refuse_few_samples(k: int, size: int, scheme: Scheme, sample_s: float) -> None:
    """Refuse a position ``k`` of fewer than 2 samples (:func:`check_position`)."""
    if size < 2:
        raise InputError(f"--data column t, position {k}", f"has {size} sample; a position of scheme "
                         f"{scheme.name!r} lasts {scheme.dwell_s:g} s, about {round(scheme.dwell_s / sample_s)} "
                         "samples")


def position_verdicts(k: int, first: float, last: float, med: float, scheme: Scheme, max_gap_s: float,
                      want_g: float | None, size: float | None) -> None:
    """:func:`check_position`'s checks of position ``k`` after its time checks: the median
    ``|A|`` ``size`` (g) against ``want_g``, the first and last sample ``first``, ``last`` (s from
    the position's start) and the span with the median step ``med`` (s) against the scheme's dwell."""
    field = f"--data column t, position {k}"
    if want_g is not None and not (want_g / UNIT_FACTOR_G <= size <= want_g * UNIT_FACTOR_G):
        raise InputError(f"--data columns Ax, Ay, Az, position {k}",
                         f"median |A| = {size:.4g}, expected about {want_g:.4g} g at this position "
                         "(centrifuge g_level and gravity); the accelerations must be in g")
    if first > max_gap_s:
        raise InputError(field, f"first sample {_num(first)} s after the position's start, more than "
                         f"record.max_gap_s = {max_gap_s:g} s")
    span = float(last + med)
    if abs(span - scheme.dwell_s) > max_gap_s:
        raise InputError(field, f"position {k} spans {span:g} s (t = {_num(first)} .. {_num(last)} s "
                         "from its start), "
                         f"but scheme {scheme.name!r} dwells {scheme.dwell_s:g} s per position "
                         f"(record.max_gap_s = {max_gap_s:g} s); pick the right --scheme")


def check_position_spilled(k: int, t: ColumnSpill, a: ColumnSpill, scheme: Scheme, sample_s: float,
                           max_gap_s: float, want_g: float) -> tuple[float, float]:
    """:func:`check_position` of position ``k`` from its times ``t`` (s) and outputs ``a`` (3
    columns, g) spilled to files (:class:`platcal.records.ColumnSpill`): the same checks in the
    same order with the same messages, the medians by passes over the files
    (:class:`platcal.records.PassMedian`); memory does not grow with the position. Returns
    ``(median step, origin)``, s."""
    field = f"--data column t, position {k}"
    refuse_few_samples(k, t.rows, scheme, sample_s)
    back, big, med = spilled_steps(t)
    refuse_back(back, field, " of the position")
    unit_verdict(med, sample_s, field, *_unit_words(sample_s))
    origin = 0.0 if abs(t.first) <= max_gap_s else spilled_grid_origin(t, med)
    if origin != 0.0:       # the gap of t - origin (its steps round otherwise)
        _, big, _ = spilled_steps(t, origin, median=False)
    gap_verdict(np.array(big[2:]), 0, big[0], max_gap_s, field)

    def norms():
        with np.errstate(over="ignore"):  # 1e300 g is refused below, without a numpy warning
            for _, v in a.blocks():
                yield np.linalg.norm(v, axis=1)

    position_verdicts(k, t.first - origin, t.last - origin, med, scheme, max_gap_s, want_g, pass_median(norms))
    return med, origin


def position_origin(t: np.ndarray, step: float, max_gap_s: float | None) -> float:
    """The time (record's clock) at which a position starts; the filter uses ``t - origin``.

    Convention (docs/centrifuge-model.md §13 says t counts from the position's start): a first
    sample within ``max_gap_s`` of 0 means the clock restarted at the position's start, origin 0
    (exactly, so clean records are used as they are). Otherwise the clock runs on (a constant
    offset per position, e.g. a logger's time of day) and the position starts at its first
    sample; that instant is taken from the whole sample grid (``step`` s apart) rather than from
    the first sample alone, so timestamp jitter does not shift the origin. ``max_gap_s=None``:
    origin 0.
    """
    if max_gap_s is None or abs(t[0]) <= max_gap_s:
        return 0.0
    return grid_origin(t, step)


def _ranges(ks: list[int]) -> str:
    """``[1, 2, 3, 5]`` as ``1..3, 5``."""
    out, start = [], None
    for i, k in enumerate(ks):
        if start is None:
            start = k
        if i + 1 == len(ks) or ks[i + 1] != k + 1:
            out.append(str(start) if start == k else f"{start}..{k}")
            start = None
    return ", ".join(out)


def filter_input(df: pd.DataFrame, scheme: Scheme, period_s: float,
                 max_gap_s: float | None = None, update_at_reset: bool = False) -> FilterInput:
    """Select, per position, the samples nearest the filter instants (multiples of ``period_s``
    from the position's start, :func:`position_origin`), with their recorded times.

    Decimation is by time: for each filter instant the nearest sample is used if it lies within
    half the position's median sample step of it, so jittered timestamps are used as recorded
    (the EKF propagates over the actual interval between used samples) and a small gap only
    drops the instants it covers. A clean record (samples on the grid) gives exactly the samples
    at the instants. Checks that every position index is in the scheme, that the commanded
    angles match the scheme's, and that time increases within each position.

    The filter instants are ``period, 2 period, ...`` (docs/centrifuge-model.md §9: the sample at
    a position's reset instant t = 0 is not used; :func:`platcal.rigs.centrifuge.ekf.filter_times`);
    ``update_at_reset`` keeps instant 0 too (config ``filter.update_at_reset``).
    """
    pos = df["position"].to_numpy(float)
    check_position_numbers(pos, scheme)
    present = sorted(set(pos.astype(int)))
    cmd = scheme.angles_deg
    ts, zs = [], []
    for k in present:
        rows = df[pos == k]
        t = rows["t"].to_numpy(float)
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0)) + 1
            raise InputError(f"--data column t, position {k}",
                             f"time does not increase at sample {i} (t = {_num(t[i - 1])} then {_num(t[i])})")
        check_commanded(np.full(len(rows), float(k)), rows[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float),
                        scheme)
        keep, t = select_instants(k, t, period_s, max_gap_s, update_at_reset)
        ts.append(t[keep])
        zs.append(rows[["Ax", "Ay", "Az"]].to_numpy(float)[keep][None])
    return FilterInput(positions=present, t=ts, z=zs, cmd_deg=cmd[np.array(present) - 1])


def select_instants(k: int, t: np.ndarray, period_s: float, max_gap_s: float | None,
                    update_at_reset: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(keep, t - origin)``: the indices of position ``k``'s samples nearest its filter
    instants and its times from the position's start (see :func:`filter_input`)."""
    step = float(np.median(np.diff(t))) if t.size > 1 else period_s
    origin = position_origin(t, step, max_gap_s)
    if origin != 0.0:
        t = t - origin
    keep = nearest_samples(t, period_s, 0.5 * step, first=0 if update_at_reset else 1)
    refuse_no_instant(k, keep, period_s)
    return keep, t


def refuse_no_instant(k: int, keep: np.ndarray, period_s: float) -> None:
    """Refuse position ``k`` when no sample falls on a filter instant (``keep`` empty)."""
    if keep.size < 1:
        raise InputError(f"--data column t, position {k}", f"no sample falls on a {period_s * 1e3:g} ms filter instant")


def instants_spilled_blocks(k: int, t: ColumnSpill, med: float, origin: float, period_s: float,
                            update_at_reset: bool):
    """:func:`select_instants` of position ``k``'s times spilled to a file (``med``, ``origin``:
    its median step and origin from :func:`check_position_spilled`, s), in pieces: yields
    ``(keep, t[keep] - origin)``, the samples nearest the filter instants, block by block (:meth:`platcal.records.NearestSamples.found`; the same indices and times end to end),
    so that a long position's instants need not be held (issue 22 item 3); refuses a position
    without any instant (:func:`refuse_no_instant`) after its last block."""
    near = NearestSamples(t.first - origin, t.last - origin, period_s, 0.5 * med, first=0 if update_at_reset else 1)
    n = 0
    for g, ahead, _ in t.steps(origin):
        near.add(g, ahead)
        keep, tk = near.found()
        n += keep.size
        yield keep, tk
    keep, tk = near.found(final=True)
    refuse_no_instant(k, np.zeros(n + keep.size), period_s)
    yield keep, tk


COMMANDED_COLUMNS = ("alpha_cmd", "beta_cmd", "gamma_cmd")
CONTINUOUS_COLUMNS = ("t", "Ax", "Ay", "Az")
"""What a continuous log (one clock, no ``position`` column) must hold; the commanded angles
(:data:`COMMANDED_COLUMNS`) and the true angles may come too, all three of each or none."""
LEVEL_SHARE = 0.01
"""A sample of a continuous log is at a dwell's level when its ``|A|`` is within this share of
the specific force of one of the scheme's positions (``hypot(g_level, 1)`` g): the table at its
rate. Within a dwell ``|A|`` holds to the Coriolis term and the instrument's errors as the force
turns (a simulated 10 g test of Table 2's truth: within 3.5e-3 of it, 5e-4 g per 5 ms step); a
table spun down for a slew gives 1 g."""


def continuous_record(df: pd.DataFrame, scheme: Scheme, level_g: np.ndarray, mean_g: np.ndarray, turning: bool,
                      rule: DwellRule = DwellRule()) -> tuple[pd.DataFrame, tuple]:
    """A continuous centrifuge log (docs/centrifuge-model.md §13, "Continuous logs") as a
    labelled record: the dwells found (:func:`platcal.logs.dwells.find_dwells`) among the
    samples at one of the positions' specific-force levels ``level_g`` (K,) g (:data:`LEVEL_SHARE`),
    cut where the commanded angles step, ``|A|`` steps (``turning``: the outputs turn with the
    table, their magnitude holds; otherwise the outputs themselves) or the clock jumps; matched
    to the scheme's positions by the commanded angles when the log has them, else by the mean
    outputs against ``mean_g`` (K, 3) g, the nominal instrument's over each position. Each dwell's
    clock counts from its first sample (the position's start). Returns the record and ``(t,
    |A|, dwells)`` for the figure; InputError naming ``--data`` when the dwells do not match
    the scheme."""
    present = list(COMMANDED_COLUMNS) if whole_group(df.columns, COMMANDED_COLUMNS, "the commanded angles") else []
    t = df["t"].to_numpy(float)
    a = df[["Ax", "Ay", "Az"]].to_numpy(float)
    size = np.linalg.norm(a, axis=1)
    at_level = (np.abs(size[:, None] - level_g[None, :]) <= LEVEL_SHARE * level_g[None, :]).any(axis=1)
    dwells = find_dwells(t, df[present].to_numpy(float), a, scheme.angles_deg, rule, at_level=at_level,
                         level_g=size if turning else a, expected_g=mean_g)
    return labelled_frame(df, dwells, scheme.angles_deg, scheme.name, COMMANDED_COLUMNS), (t, size, dwells)


COMPENSATE_COLUMNS = ("t", "Ax", "Ay", "Az")
"""The columns ``platcal compensate`` needs; the record's others pass through unchanged."""


def full_coefficients(cal: Calibration, rig: str) -> np.ndarray:
    """(48,) the full coefficient vector of :mod:`platcal.model.instruments` (its units) from a
    calibration: the identified coefficients by name, 0 for those it does not hold (DOO, or a
    filter without them). InputError naming ``--calibration key names`` for a name the model
    does not have (``rig`` names the model in the message)."""
    unknown = [n for n in cal.names if n not in INDEX]
    if unknown:
        raise InputError("--calibration key names", f"{unknown[0]!r} is not a coefficient of the {rig} model "
                         f"({', '.join(FULL_NAMES[:3])}, ...)")
    coef = np.zeros(N_FULL)
    coef[[INDEX[n] for n in cal.names]] = cal.values
    return coef


def compensate_frame(df: pd.DataFrame, coef: np.ndarray) -> pd.DataFrame:
    """``df`` with ``Ax, Ay, Az`` (g) compensated with ``coef`` (48,): each sample replaced by
    the error-free output, the specific force in p whose modelled outputs are the recorded ones
    (:func:`platcal.model.instruments.compensate_accelerometers`, docs/centrifuge-model.md §5);
    and, when the log has the gyro outputs ``wx, wy, wz`` (deg/h, :data:`GYRO_COLUMNS`), those
    less the modelled drift at that specific force (§4)."""
    out = df.copy()
    f = compensate_accelerometers(df[["Ax", "Ay", "Az"]].to_numpy(float), coef)
    out[["Ax", "Ay", "Az"]] = f
    if whole_group(df.columns, GYRO_COLUMNS, "the gyro outputs"):
        out[list(GYRO_COLUMNS)] = df[list(GYRO_COLUMNS)].to_numpy(float) - gyro_drifts(coef, f)
    return out
