"""Static dwells found in a continuous log (issue 21, item 3): a documented threshold rule.

A log recorded on one clock through a whole test holds dwells (the platform held at a position)
and slews between them (the gimbals turning, recorded or missing from the log). A sample is
*moving* when, from the previous sample, any angle sensor changed by more than
``max_angle_step_arcsec`` or any accelerometer by more than ``max_accel_step_g``, or when more
than ``max_gap_s`` passed (a slew missing from the log); a dwell is a run of samples without
movement lasting at least ``min_dwell_s``. The thresholds sit far above the sensors' noise
(arcsec and ug per sample) and the slow drift of a held platform (Earth rate: a fraction of an
arcsec per sample) and far below a slew (degrees per second). Each dwell is matched to the
scheme's position whose commanded angles are nearest its mean measured angles (wrapped), within
``max_mismatch_deg``. Pure functions on numpy arrays; nothing here names a rig.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class DwellRule:
    """The thresholds of the rule (module docstring): angle step arcsec, accelerometer step g,
    longest sample interval inside a dwell s, shortest dwell s, largest angle mismatch deg."""

    max_angle_step_arcsec: float = 60.0
    max_accel_step_g: float = 0.01
    max_gap_s: float = 0.1
    min_dwell_s: float = 1.0
    max_mismatch_deg: float = 1.0


@dataclass(frozen=True)
class Dwell:
    """Samples ``start .. stop - 1`` of the log, held at scheme position ``position`` (1-based)."""

    start: int
    stop: int
    position: int


def wrapped_deg(d: np.ndarray) -> np.ndarray:
    """Angle differences (deg) wrapped to [-180, 180)."""
    return (np.asarray(d) + 180.0) % 360.0 - 180.0


def static_runs(t: np.ndarray, angles_deg: np.ndarray, accel_g: np.ndarray, rule: DwellRule) -> list[tuple[int, int]]:
    """``[(start, stop)]`` sample ranges of the dwells (runs without movement, at least
    ``rule.min_dwell_s`` long) of a continuous log: ``t`` (N,) s, angles (N, 3) deg, accelerations (N, 3) g."""
    moving = np.zeros(t.size, dtype=bool)
    moving[1:] = ((np.abs(wrapped_deg(np.diff(angles_deg, axis=0))) * 3600.0 > rule.max_angle_step_arcsec).any(axis=1)
                  | (np.abs(np.diff(accel_g, axis=0)) > rule.max_accel_step_g).any(axis=1)
                  | (np.diff(t) > rule.max_gap_s))
    # a run starts at a sample that moved (the slew's last sample is the first at the new position)
    starts = np.flatnonzero(moving)
    bounds = np.r_[0, starts, t.size]
    runs = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        # the sample that ended the movement belongs to the dwell only if the next step is still
        a = a if a == 0 or (a + 1 < t.size and not moving[a + 1]) else a + 1
        if b - a >= 2 and t[b - 1] - t[a] >= rule.min_dwell_s:
            runs.append((int(a), int(b)))
    return runs


def match_positions(angles_deg: np.ndarray, runs: list[tuple[int, int]], commanded_deg: np.ndarray,
                    rule: DwellRule) -> list[Dwell]:
    """Each run matched to the nearest commanded position (K, 3) deg by its mean measured angles;
    InputError when a run is further than ``rule.max_mismatch_deg`` from every position."""
    out = []
    for a, b in runs:
        mean = angles_deg[a] + np.mean(wrapped_deg(angles_deg[a:b] - angles_deg[a]), axis=0)
        miss = np.abs(wrapped_deg(commanded_deg - mean)).max(axis=1)
        k = int(np.argmin(miss))
        if miss[k] > rule.max_mismatch_deg:
            raise InputError("--data", f"the dwell from sample {a + 1} to {b} holds the angles "
                             f"{np.round(mean, 3).tolist()} deg, {miss[k]:.3g} deg from the nearest position of the "
                             f"scheme ({k + 1}: {commanded_deg[k].tolist()}); pick the right --scheme")
        out.append(Dwell(start=a, stop=b, position=k + 1))
    return out


def find_dwells(t, angles_deg, accel_g, commanded_deg, rule: DwellRule = DwellRule()) -> list[Dwell]:
    """The dwells of a continuous log matched to the scheme's positions (module docstring)."""
    return match_positions(np.asarray(angles_deg, float),
                           static_runs(np.asarray(t, float), np.asarray(angles_deg, float),
                                       np.asarray(accel_g, float), rule),
                           np.asarray(commanded_deg, float), rule)
