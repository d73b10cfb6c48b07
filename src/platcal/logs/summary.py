"""``platcal inspect``: what a log holds, as the rig would read it (issue 21, item 1).

Generic over the rigs: a rig passes its record's columns and units (and its config's ``record:``
mapping); the log is read and converted exactly as ``identify`` reads it, and summarised: the
columns and their units after the mapping, the sample rate, the duration, the gaps and the dwells
(stretches of one ``position``, when the log has that column).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..records import read_table

if TYPE_CHECKING:  # annotations only: a command that imports this module does not load pandas
    import pandas as pd

GAP_FACTOR = 1.5
"""A step longer than this many median steps is reported as a gap."""


@dataclass(frozen=True)
class LogSummary:
    """What a log holds: ``columns`` (rig column -> unit, after the mapping), ``samples``, the
    median ``rate_hz``, ``duration_s``, ``gaps`` ((start s, length s) of steps longer than
    :data:`GAP_FACTOR` median steps) and ``dwells`` ((position, start s, end s, samples))."""

    columns: dict
    samples: int
    rate_hz: float
    duration_s: float
    gaps: list
    dwells: list

    def text(self) -> str:
        """The summary as lines for people."""
        lines = [f"columns: {', '.join(f'{c} [{u}]' for c, u in self.columns.items())}",
                 f"samples: {self.samples}, rate {self.rate_hz:.6g} Hz, duration {self.duration_s:.6g} s",
                 f"gaps (> {GAP_FACTOR:g} steps): {len(self.gaps)}"
                 + "".join(f"\n  at t = {a:.6g} s, {d:.6g} s" for a, d in self.gaps[:20])]
        if self.dwells:
            lines.append(f"dwells: {len(self.dwells)}")
            lines += [f"  position {p}: t = {a:.6g} .. {b:.6g} s, {n} samples" for p, a, b, n in self.dwells]
        else:
            lines.append("dwells: none marked (no position column; a rig that can finds them in identify)")
        return "\n".join(lines)


def time_steps(t: np.ndarray) -> tuple[float, list]:
    """Median step of ``t`` (s) and its gaps ``[(start s, length s)]``."""
    step = np.diff(t)
    if step.size == 0:
        return float("nan"), []
    med = float(np.median(step))
    big = np.flatnonzero(step > GAP_FACTOR * med)
    return med, [(float(t[i]), float(step[i])) for i in big]


def marked_dwells(pos: np.ndarray, t: np.ndarray) -> list:
    """Stretches of one position value in log order: ``[(position, start s, end s, samples)]``."""
    change = np.flatnonzero(np.diff(pos) != 0) + 1
    starts, ends = np.r_[0, change], np.r_[change, pos.size]
    return [(int(pos[a]), float(t[a]), float(t[b - 1]), int(b - a)) for a, b in zip(starts, ends)]


def summarise(df: pd.DataFrame, units: dict) -> LogSummary:
    """The :class:`LogSummary` of a log read in the rig's columns (``units``: column -> unit).
    Per-position clocks that restart are summarised per dwell; the rate is the median step's."""
    t = df["t"].to_numpy(float)
    pos = df["position"].to_numpy(float) if "position" in df.columns else None
    dwells = marked_dwells(pos, t) if pos is not None else []
    if dwells:
        bounds = np.cumsum([0] + [d[3] for d in dwells])
        pieces = [time_steps(t[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
        med = float(np.median([p[0] for p in pieces if np.isfinite(p[0])]))
        gaps = [g for p in pieces for g in p[1]]
        duration = float(sum(d[2] - d[1] + med for d in dwells))
    else:
        med, gaps = time_steps(t)
        duration = float(t[-1] - t[0] + med) if t.size else 0.0
    return LogSummary(columns={c: units.get(c) or "text" for c in df.columns}, samples=int(len(df)),
                      rate_hz=1.0 / med if med > 0 else float("nan"), duration_s=duration, gaps=gaps, dwells=dwells)


def inspect_log(path, mapping, units: dict, required: tuple[str, ...], optional: tuple[str, ...] = (),
                text: tuple[str, ...] = (), increments: tuple[str, ...] = (),
                positions: tuple[str, ...] = ()) -> LogSummary:
    """Read ``path`` as the rig's record (:func:`platcal.records.read_table` with the config's
    ``mapping``; InputError naming the field) and summarise it; ``increments``: the columns a
    ``kind: increments`` mapping reads as increments (shown as such, in ``units``); ``positions``:
    the east and north columns a ``geodetic`` mapping fills."""
    df = read_table(path, required, optional, text=text, mapping=mapping, units=units, increments=increments,
                    positions=positions)
    return summarise(df, units)
