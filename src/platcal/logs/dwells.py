"""Static dwells found in a continuous log (issue 21, item 3): a documented threshold rule.

A log recorded on one clock through a whole test holds dwells (the platform held at a position)
and slews between them (the gimbals turning, recorded or missing from the log). A sample is
*moving* when, from the previous sample, any angle column changed by more than
``max_angle_step_arcsec`` or any level signal by more than ``max_accel_step_g``, or when more
than ``max_gap_s`` passed (a slew missing from the log); a dwell is a run of samples without
movement lasting at least ``min_dwell_s``. The level signal is the rig's: the accelerometer
outputs of a platform held still (docs/multiposition-1g.md §12), the specific-force magnitude
``|A|`` of a platform on a turning table, whose outputs turn with the table but whose magnitude
holds (docs/centrifuge-model.md §13). A rig may also mark the samples *at a dwell's level* (the
table at its rate): a sample off the level belongs to no dwell. The thresholds sit far above the
sensors' noise (arcsec and ug per sample) and the slow drift of a held platform (Earth rate: a
fraction of an arcsec per sample) and far below a slew (degrees per second). Each dwell is
matched to the scheme's position nearest its mean angles (wrapped, within ``max_mismatch_deg``)
or, with no angle column, nearest its mean accelerometer outputs (within ``max_mismatch_g``),
and a log must hold each of the scheme's positions once (:func:`labelled_frame`). Pure functions
on numpy arrays and tables; nothing here names a rig.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd


@dataclass(frozen=True)
class DwellRule:
    """The thresholds of the rule (module docstring): angle step arcsec, level step g, longest
    sample interval inside a dwell s, shortest dwell s, largest angle mismatch deg, largest
    mismatch of the mean accelerometer outputs g (a log without angle columns)."""

    max_angle_step_arcsec: float = 60.0
    max_accel_step_g: float = 0.01
    max_gap_s: float = 0.1
    min_dwell_s: float = 1.0
    max_mismatch_deg: float = 1.0
    max_mismatch_g: float = 0.05


POSITION_MISSING = ("--data column position", "record.columns.position")
"""The fields of the reader's refusal of a log without a ``position`` column (read directly or
through a ``record:`` mapping): such a log is a continuous one, whose dwells are found here."""


def lacks_position(exc: InputError, mapping=None) -> bool:
    """Whether a read refused a log only for having no ``position`` column: a continuous log. Not
    so when the config's ``record:`` ``mapping`` (:class:`platcal.mapping.RecordMapping`) gave the
    log's own ``position`` column to another of the rig's columns: that log is labelled and the
    mapping wrong, and the refusal stands."""
    taken = mapping is not None and "position" in mapping.columns.values() and "position" not in mapping.columns
    return exc.field in POSITION_MISSING and not taken


@dataclass(frozen=True)
class Dwell:
    """Samples ``start .. stop - 1`` of the log, held at scheme position ``position`` (1-based)."""

    start: int
    stop: int
    position: int


def wrapped_deg(d: np.ndarray) -> np.ndarray:
    """Angle differences (deg) wrapped to [-180, 180)."""
    return (np.asarray(d) + 180.0) % 360.0 - 180.0


def static_runs(t: np.ndarray, angles_deg: np.ndarray, accel_g: np.ndarray, rule: DwellRule,
                at_level: np.ndarray | None = None) -> list[tuple[int, int]]:
    """``[(start, stop)]`` sample ranges of the dwells (runs without movement, at least
    ``rule.min_dwell_s`` long) of a continuous log: ``t`` (N,) s, angles (N, a) deg (a may be 0),
    level signals (N, m) g; ``at_level`` (N,) bool: the samples at a dwell's level (None: all)."""
    step = np.zeros(t.size, dtype=bool)
    step[1:] = ((np.abs(wrapped_deg(np.diff(angles_deg, axis=0))) * 3600.0 > rule.max_angle_step_arcsec).any(axis=1)
                | (np.abs(np.diff(accel_g, axis=0)) > rule.max_accel_step_g).any(axis=1)
                | (np.diff(t) > rule.max_gap_s))
    if at_level is not None:  # a sample off the level is linked to neither neighbour
        off = ~np.asarray(at_level, dtype=bool)
        step[1:] |= off[1:] | off[:-1]
    # a run is the samples linked by still steps: it starts at the sample that ended the
    # movement (the slew's last sample is the first at the new position)
    bounds = np.r_[0, np.flatnonzero(step), t.size]
    runs = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= 2 and t[b - 1] - t[a] >= rule.min_dwell_s:
            runs.append((int(a), int(b)))
    return runs


def nearest_positions(runs: list[tuple[int, int]], signatures: np.ndarray, miss: np.ndarray, targets: np.ndarray,
                      tolerance: float, what: str, unit: str, fix: str) -> list[Dwell]:
    """Each run matched to the scheme position (row of ``targets`` (K, m)) with the smallest
    ``miss`` (R, K) from the run's ``signatures`` (R, m) (in ``unit``); InputError naming
    ``--data`` when a run is further than ``tolerance`` from every position (``what`` the run
    holds, ``fix`` what the user should do)."""
    out = []
    for (a, b), sig, row in zip(runs, signatures, miss):
        k = int(np.argmin(row))
        if row[k] > tolerance:
            raise InputError("--data", f"the dwell from sample {a + 1} to {b} holds {what} "
                             f"{np.round(sig, 3).tolist()} {unit}, {row[k]:.3g} {unit} from the nearest position of "
                             f"the scheme ({k + 1}: {np.round(targets[k], 6).tolist()}); {fix}")
        out.append(Dwell(start=a, stop=b, position=k + 1))
    return out


def match_positions(angles_deg: np.ndarray, runs: list[tuple[int, int]], commanded_deg: np.ndarray,
                    rule: DwellRule) -> list[Dwell]:
    """Each run matched to the nearest commanded position (K, 3) deg by its mean measured angles
    (wrapped); InputError when a run is further than ``rule.max_mismatch_deg`` from every position."""
    means = np.array([angles_deg[a] + np.mean(wrapped_deg(angles_deg[a:b] - angles_deg[a]), axis=0)
                      for a, b in runs]).reshape(len(runs), angles_deg.shape[1])
    miss = np.array([np.abs(wrapped_deg(commanded_deg - m)).max(axis=1) for m in means])
    return nearest_positions(runs, means, miss, commanded_deg, rule.max_mismatch_deg, "the angles", "deg",
                             "pick the right --scheme")


def match_levels(accel_g: np.ndarray, runs: list[tuple[int, int]], expected_g: np.ndarray,
                 rule: DwellRule) -> list[Dwell]:
    """Each run matched to the position whose expected mean accelerometer outputs
    ``expected_g`` (K, 3) g (the nominal instrument over the position's dwell) are nearest the
    run's mean outputs, within ``rule.max_mismatch_g``. Positions of the scheme that cannot be
    told apart this way (expected means within twice the tolerance) are refused: the log then
    needs its commanded angles."""
    K = len(expected_g)
    for i in range(K):
        for j in range(i + 1, K):
            if np.abs(expected_g[i] - expected_g[j]).max() <= 2 * rule.max_mismatch_g:
                raise InputError("--data", f"positions {i + 1} and {j + 1} of the scheme give the same mean "
                                 "accelerometer outputs, so a log without commanded angles cannot tell their dwells "
                                 "apart; log the commanded angles (record.columns alpha_cmd, beta_cmd, gamma_cmd)")
    means = np.array([np.mean(accel_g[a:b], axis=0) for a, b in runs]).reshape(len(runs), accel_g.shape[1])
    miss = np.array([np.abs(expected_g - m).max(axis=1) for m in means])
    return nearest_positions(runs, means, miss, expected_g, rule.max_mismatch_g, "the mean accelerometer outputs", "g",
                             "pick the right --scheme, or check that the log's dwells are whole positions")


def columns(x) -> np.ndarray:
    """``x`` as a float array of one column per signal: (N,) becomes (N, 1)."""
    x = np.asarray(x, float)
    return x[:, None] if x.ndim == 1 else x


def find_dwells(t, angles_deg, accel_g, commanded_deg, rule: DwellRule = DwellRule(), at_level=None,
                level_g=None, expected_g=None) -> list[Dwell]:
    """The dwells of a continuous log matched to the scheme's positions (module docstring): ``t``
    (N,) s, angle columns (N, a) deg, accelerometer outputs (N, 3) g, the scheme's commanded
    angles (K, 3) deg; ``level_g`` (N, m): the level signal of the step rule (default the
    accelerometer outputs); ``at_level`` (N,) bool (:func:`static_runs`). With no angle column
    (a = 0) the dwells are matched by their mean outputs to ``expected_g`` (K, 3) g."""
    t = np.asarray(t, float)
    angles, accel = columns(angles_deg), columns(accel_g)
    runs = static_runs(t, angles, accel if level_g is None else columns(level_g), rule, at_level)
    if angles.shape[1]:
        return match_positions(angles, runs, np.asarray(commanded_deg, float), rule)
    return match_levels(accel, runs, np.asarray(expected_g, float), rule)


def labelled_frame(df: pd.DataFrame, dwells: list[Dwell], commanded_deg: np.ndarray, scheme_name: str,
                   commanded_columns: tuple[str, ...] = ("alpha_cmd", "beta_cmd", "gamma_cmd")) -> pd.DataFrame:
    """A continuous log ``df`` (column ``t`` s) as a labelled record: the rows of each dwell, its
    clock counted from its first sample, a ``position`` column first and the commanded angles
    (K, 3) deg of its position filled in where the log has none; slews are dropped. InputError
    naming ``--data`` when a position of the scheme is found twice or not at all."""
    found = [d.position for d in dwells]
    for k in range(1, len(commanded_deg) + 1):
        if found.count(k) != 1:
            raise InputError("--data", f"{found.count(k)} dwells of the log match position {k} of scheme "
                             f"{scheme_name!r} (dwells found at positions {found}); a continuous log holds each "
                             "position once")
    t = df["t"].to_numpy(float)
    # one row selection with the frame's own methods (the same rows and columns as concatenating
    # the dwells' slices): the module needs no pandas of its own, so an identify loads none
    rows = np.concatenate([np.arange(d.start, d.stop) for d in dwells])
    pos = np.concatenate([np.full(d.stop - d.start, d.position) for d in dwells])
    out = df.iloc[rows].reset_index(drop=True)
    out["t"] = np.concatenate([t[d.start:d.stop] - t[d.start] for d in dwells])
    out.insert(0, "position", pos.astype(float))
    for i, c in enumerate(commanded_columns):
        if c not in df.columns:
            out[c] = np.asarray(commanded_deg, float)[pos - 1, i]
    return out


def dwells_found(t: np.ndarray, dwells: list[Dwell]) -> list[dict]:
    """The dwells as ``summary.json`` reports them: position, first and last sample's time (s,
    the log's clock) and samples."""
    return [{"position": d.position, "t_start": float(t[d.start]), "t_end": float(t[d.stop - 1]),
             "samples": d.stop - d.start} for d in dwells]


DWELL_FIGURE = "platcal.logs.dwell_figure:dwell_figure"
"""The path of the segmentation figure (:func:`platcal.logs.dwell_figure.dwell_figure`): a command
draws it through :func:`platcal.rig.resolve`, so matplotlib loads only when a log was segmented,
not for every ``identify`` (issue 22 item 3)."""
