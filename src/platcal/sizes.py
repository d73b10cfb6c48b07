"""Sizes before allocation: the memory and time a command's inputs imply, refused past limits the
user sets (issue 25 item 3).

Every rig gives :attr:`platcal.rig.Rig.sizes`, ``sizes(command, cfg, args) -> list[Size]``, for
every command: for the work whose size follows from its inputs (a dwell, a run length,
replicates, a record file, a search's population x generations): the units of work (samples, a
file's bytes, candidates), the float64 values held per unit (the rig's peak resident memory per
unit), the CPU seconds per unit, the replicates held at once and run in all, and the config key or
option that drives it; both costs are measured on this project's machine (2 cores, 8 GB, under a
load of 2-5) by ``benchmarks/size_estimate.py`` (the slope between a short and a long run, so the
fixed start-up cost is left out; per byte on a CSV record), stated next to each rig's constants
and rounded up about 2x for the load's noise. :func:`check_sizes` multiplies them out and
refuses, before any allocation, one above ``--max-memory-gb`` or ``--max-hours`` (InputError naming
the driving field and the option to raise: exit 2), so a dwell of a day is a clear message, not a
``MemoryError`` traceback, a machine swapping for an hour or a job that would run for a month. The
fixed cost of Python, numpy and numba (about 0.35 GB, a few seconds) is not counted.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import pyarrow.parquet as pq

from .errors import InputError
from .rig import option, real

DEFAULT_MAX_MEMORY_GB = 4.0
"""Default limit (GB) on the data one command may hold: half the memory of the 8 GB machines the
project runs on, leaving room for the temporaries the estimate does not count."""
MAX_MEMORY_OPTION = "--max-memory-gb"
MAX_MEMORY = option(MAX_MEMORY_OPTION, type=real(above=0, unit="GB"), default=DEFAULT_MAX_MEMORY_GB,
                    help=f"refuse, before any work, a command whose inputs imply more data than this, GB "
                         f"(default {DEFAULT_MAX_MEMORY_GB:g})")
"""The memory-limit option, common to every command of every rig (:mod:`platcal.cli`)."""
DEFAULT_MAX_HOURS = 24.0
"""Default limit (hours of CPU time on the machine the costs were measured on) on one command's
estimated work: a day, far above any command of the default study (its longest job, a Monte Carlo
cell, takes minutes), low enough that a typo in a duration or a replicate count is caught."""
MAX_HOURS_OPTION = "--max-hours"
MAX_HOURS = option(MAX_HOURS_OPTION, type=real(above=0, unit="h"), default=DEFAULT_MAX_HOURS,
                   help=f"refuse, before any work, a command whose inputs imply more CPU time than this, hours, "
                        f"estimated from per-sample costs measured by benchmarks/size_estimate.py "
                        f"(default {DEFAULT_MAX_HOURS:g})")
"""The time-limit option, common to every command of every rig (:mod:`platcal.cli`)."""
BYTES_PER_VALUE = 8
"""float64."""
CSV_BYTES_PER_VALUE = 14.5
"""Bytes a value takes in a CSV record written by :func:`platcal.records.write_record` (full
precision, the commas and line ends): 12.7 (centrifuge, 72000 rows x 11 columns) and 14.4
(multiposition, 24008 x 14), measured on seed 0 of each default test
(benchmarks/size_estimate_more.py); the larger, rounded up. The
per-byte costs were measured on such CSV files, so a Parquet record is sized by the CSV it would be
(:func:`record_bytes`): its own file is about 2.2x smaller (5.7 and 6.4 bytes a value, compressed)."""


@dataclass(frozen=True)
class Size:
    """The work of one command, driven by ``field`` (the config key or option to change): memory
    ``samples`` (float: 1e12 s / 5 ms does not overflow) x ``channels`` (float64 values held per
    sample; 0: none counted) x ``replicates`` (held at once) values; time ``samples`` x ``runs``
    (replicates run in all; default ``replicates``) x ``seconds_per_sample`` (CPU s, measured; 0:
    none counted). ``unit`` names what a sample is ("samples", "bytes of the record",
    "candidates"); ``what`` says in words where they come from (for the message)."""

    field: str
    samples: float
    channels: float
    replicates: float = 1
    what: str = ""
    seconds_per_sample: float = 0.0
    runs: float | None = None
    unit: str = "samples"

    @property
    def gigabytes(self) -> float:
        return float(self.samples) * self.channels * float(self.replicates) * BYTES_PER_VALUE / 1e9

    @property
    def hours(self) -> float:
        runs = self.replicates if self.runs is None else self.runs
        return float(self.samples) * float(runs) * self.seconds_per_sample / 3600.0


def one_at_a_time(size: Size, parts: int) -> Size:
    """``size`` of a record streamed one of its ``parts`` (positions) at a time: the memory of one
    part (``size.samples / parts``) held, the time of all of them (``parts`` runs of one)."""
    return replace(size, samples=size.samples / parts, replicates=1, runs=parts,
                   what=f"{size.what}, streamed: one of {parts} positions held at a time")


def in_blocks(size: Size, block: float) -> Size:
    """``size`` of work streamed in blocks of at most ``block`` samples: the memory of one block
    held, the time of all of ``size``'s samples (every replicate's)."""
    held = min(float(block), float(size.samples))
    return replace(size, samples=held, replicates=1, runs=float(size.samples) * float(size.replicates) / held,
                   what=f"{size.what}, streamed: {held:g} samples held at a time")


def samples_in(seconds: float, period_s: float) -> float:
    """Samples of a span of ``seconds`` at ``period_s`` (the end sample included), as a float."""
    return math.floor(seconds / period_s) + 1.0


def file_bytes(path) -> float:
    """The size of a record file in bytes (0 when it does not exist: the command names a missing
    file itself, with its own message)."""
    try:
        return float(os.stat(path).st_size)
    except (OSError, TypeError, ValueError):
        return 0.0


@dataclass(frozen=True)
class Costs:
    """A rig's costs, measured on the project's machine by ``benchmarks/size_estimate.py`` and
    rounded up about 2x (``measured`` states the raw figures): per command, ``values`` (float64
    values held per sample at the peak: the slope of peak RSS between a short and a long run) and
    ``seconds`` (CPU s per sample); ``per_byte``: (values held, CPU s) per byte of the record file,
    for the commands sized by the record they read whole (:func:`record_size`)."""

    values: dict
    seconds: dict
    per_byte: dict
    measured: str = ""

    def record(self, command: str, path) -> list[Size]:
        """The size of ``command`` reading the record file ``path`` whole (one of :attr:`per_byte`)."""
        return [record_size(path, *self.per_byte[command])]


def check_sizes(sizes: list[Size], limit_gb: float, limit_hours: float = DEFAULT_MAX_HOURS) -> None:
    """Refuse (InputError naming the driving field) the first size above ``limit_gb`` of memory or
    ``limit_hours`` of CPU time."""
    for s in sizes:
        gb = s.gigabytes
        unit = s.unit[:-1] if s.unit.endswith("s") else s.unit  # "per sample", "per byte of ..."
        what = f"{s.what}: " if s.what else ""
        if gb > limit_gb:
            reps = f" x {s.replicates:.3g} replicates" if s.replicates != 1 else ""
            raise InputError(s.field, f"{what}{s.samples:.3g} {s.unit} x {s.channels:.3g} values held per "
                             f"{unit}{reps} x {BYTES_PER_VALUE} bytes = {gb:.3g} GB, more than "
                             f"{MAX_MEMORY_OPTION} {limit_gb:g}; make {s.field} smaller or raise "
                             f"{MAX_MEMORY_OPTION}")
        hours = s.hours
        if hours > limit_hours:
            runs = s.replicates if s.runs is None else s.runs
            reps = f" x {runs:.3g} runs" if runs != 1 else ""
            raise InputError(s.field, f"{what}{s.samples:.3g} {s.unit}{reps} x {s.seconds_per_sample:.3g} CPU s per "
                             f"{unit} (measured on the project's 2-core machine; platcal.sizes says where) = "
                             f"{hours:.3g} h, more than {MAX_HOURS_OPTION} {limit_hours:g}; make {s.field} smaller "
                             f"or raise {MAX_HOURS_OPTION}")


def record_bytes(path) -> tuple[float, str]:
    """The bytes of ``path`` as the CSV record the per-byte costs were measured on, and how they
    were found: a Parquet file (named ``.parquet`` and with a readable footer) from its footer
    alone, rows x columns x :data:`CSV_BYTES_PER_VALUE` (no data page is read: a compressed file
    is not underestimated by its compression ratio); any other file by its size."""
    n = file_bytes(path)
    if str(path).lower().endswith(".parquet") and n > 0:
        try:
            meta = pq.ParquetFile(path).metadata
        except (OSError, ValueError, TypeError):  # not a Parquet file: the reader names it itself
            return n, f"{n:.3g} bytes"
        values = float(meta.num_rows) * float(meta.num_columns)
        return values * CSV_BYTES_PER_VALUE, (f"{meta.num_rows:.3g} rows x {meta.num_columns} columns (its Parquet "
                                              f"footer) x {CSV_BYTES_PER_VALUE:g} bytes a value in CSV")
    return n, f"{n:.3g} bytes"


def record_size(path, values_per_byte: float, seconds_per_byte: float, field: str = "--data") -> Size:
    """The work of a command that reads a whole record file (inspect, compensate, an identification
    sized by its record): the record's bytes as CSV (:func:`record_bytes`) x the values held and
    CPU seconds per byte (measured by ``benchmarks/size_estimate.py`` on a CSV record)."""
    n, how = record_bytes(path)
    return Size(field, n, values_per_byte, 1, f"the record {path}, {how}", seconds_per_byte,
                unit="bytes of the record as CSV")


REPORT_PER_BYTE = (0.5, 3e-8)
"""(float64 values held, CPU s) per byte of the result tables a ``report`` reads: the largest of
the rigs' ``inspect`` costs (a table read whole, the centrifuge's: 2.8 B and 1.2e-8 s a byte
measured, rounded up), not measured on a report itself (the default study's results are not
kept in the repository); the figures' fixed cost is not counted."""
RESULT_TABLES = (".csv", ".parquet", ".json")
"""The files of a results folder a report reads (its tables and summaries)."""


def results_size(folder, field: str = "--results") -> Size:
    """The work of a ``report`` of ``folder`` (every rig's: it reads the study's result tables
    whole): the bytes of its tables (:data:`RESULT_TABLES`, every subfolder; a Parquet table as
    the CSV it would be, :func:`record_bytes`) x :data:`REPORT_PER_BYTE`. A folder that does not
    exist counts 0 (the report names it itself)."""
    root = os.fspath(folder)
    n, files = 0.0, 0
    for base, _, names in os.walk(root):
        for name in names:
            if name.lower().endswith(RESULT_TABLES):
                n += record_bytes(os.path.join(base, name))[0]
                files += 1
    return Size(field, n, REPORT_PER_BYTE[0], 1, f"{files} result table(s) under {root}, {n:.3g} bytes as CSV",
                REPORT_PER_BYTE[1], unit="bytes of result tables")


def command_sizes(rig, command: str, cfg, args) -> list[Size]:
    """Every size of a rig's command: the rig's own (``Rig.sizes``) and those of the commands
    every rig shares (``report``: :func:`results_size` of ``--results``)."""
    sizes = list(rig.sizes(command, cfg, args)) if rig.sizes is not None else []
    if command == "report":
        sizes.append(results_size(args.results))
    return sizes
