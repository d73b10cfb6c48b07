"""Sizes before allocation: the memory a command's inputs imply, refused past a limit the user sets.

Every rig gives :attr:`platcal.rig.Rig.sizes`, ``sizes(command, cfg, args) -> list[Size]``: for
the data a command would hold whose size follows from its inputs (a dwell, a run length,
replicates): the samples, the float64 values held per sample (the rig's peak resident memory per
sample, measured by ``benchmarks/size_estimate.py``), the replicates held at once, and the config
key or option that drives it. :func:`check_sizes` multiplies them out (8 bytes a value) and
refuses, before any allocation, one above ``--max-memory-gb`` (InputError naming the driving
field: exit 2), so a dwell of a day is a clear message, not a ``MemoryError`` traceback or a
machine swapping for an hour. The fixed cost of Python, numpy and numba (about 0.35 GB) is not
counted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import InputError
from .rig import option, real

DEFAULT_MAX_MEMORY_GB = 4.0
"""Default limit (GB) on the data one command may hold: half the memory of the 8 GB machines the
project runs on, leaving room for the temporaries the estimate does not count."""
MAX_MEMORY_OPTION = "--max-memory-gb"
MAX_MEMORY = option(MAX_MEMORY_OPTION, type=real(above=0, unit="GB"), default=DEFAULT_MAX_MEMORY_GB,
                    help=f"refuse, before any work, a command whose inputs imply more data than this, GB "
                         f"(default {DEFAULT_MAX_MEMORY_GB:g})")
"""The one size-limit option, common to every command of every rig (:mod:`platcal.cli`)."""
BYTES_PER_VALUE = 8
"""float64."""


@dataclass(frozen=True)
class Size:
    """The data one command holds: ``samples`` (float: 1e12 s / 5 ms does not overflow) x
    ``channels`` (values held per sample) x ``replicates`` values, driven by ``field`` (the config key or
    option to change); ``what`` says in words where the samples come from (for the message)."""

    field: str
    samples: float
    channels: int
    replicates: float = 1
    what: str = ""

    @property
    def gigabytes(self) -> float:
        return float(self.samples) * self.channels * float(self.replicates) * BYTES_PER_VALUE / 1e9


def samples_in(seconds: float, period_s: float) -> float:
    """Samples of a span of ``seconds`` at ``period_s`` (the end sample included), as a float."""
    return math.floor(seconds / period_s) + 1.0


def check_sizes(sizes: list[Size], limit_gb: float) -> None:
    """Refuse (InputError naming the driving field) the first size above ``limit_gb``."""
    for s in sizes:
        gb = s.gigabytes
        if gb > limit_gb:
            reps = f" x {s.replicates:.3g} replicates" if s.replicates != 1 else ""
            raise InputError(s.field, f"{s.what + ': ' if s.what else ''}{s.samples:.3g} samples x {s.channels} "
                             f"values held per sample{reps} x {BYTES_PER_VALUE} bytes = {gb:.3g} GB, more than "
                             f"{MAX_MEMORY_OPTION} {limit_gb:g}; make {s.field} smaller or raise "
                             f"{MAX_MEMORY_OPTION}")
