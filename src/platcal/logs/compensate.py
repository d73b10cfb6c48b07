"""``platcal compensate``'s common path (issue 21, item 4): read a log through the calibration's
config ``record:`` mapping, apply the rig's compensation, write the result atomically.

The rig supplies its record's columns and units and a pure function from the log (in the rig's
columns and units) to the compensated log; checks of ``--out`` come first, before the log is
read, so a bad option is refused before any work. Nothing here names a rig.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from ..errors import InputError
from ..io import check_writable
from ..records import read_table, write_record
from ..mapping import RecordMapping

if TYPE_CHECKING:  # annotations only: a command that imports this module does not load pandas
    import pandas as pd

OUT_SUFFIXES = (".csv", ".parquet")


def check_compensate_out(path) -> None:
    """InputError naming ``--out`` unless it is a writable .csv or .parquet file path."""
    if Path(path).suffix not in OUT_SUFFIXES:
        raise InputError("--out", f"a compensated log is written as .csv or .parquet, got {Path(path).name!r}")
    check_writable(path, "--out")


def read_mapped(rig: str, mapping: RecordMapping, units: dict, required: tuple, optional: tuple = (),
                text: tuple = ()) -> Callable[[str], pd.DataFrame]:
    """A reader of a log in the rig's ``units`` (columns ``required`` + ``optional``) through
    ``mapping``, for :func:`compensate_log`."""
    return lambda path: read_table(path, required, optional, text=text, mapping=mapping, units=units,
                                   what=f"a {rig} log")


def compensate_log(args, rig: str, read: Callable[[str], object], apply: Callable[[object], pd.DataFrame],
                   what: str | Callable[[pd.DataFrame], str]) -> int:
    """Check ``args.out``, read ``args.data`` with ``read`` (the rig's checks, InputError naming
    the column), write ``apply(log)`` to ``args.out`` in the rig's columns and units, and say so
    on stderr naming ``what`` was compensated (and what was not: ``what(out)`` when it depends on
    the log's columns). Returns the exit status 0."""
    check_compensate_out(args.out)
    out = apply(read(args.data))
    write_record(out, args.out)
    said = what(out) if callable(what) else what
    print(f"platcal compensate: {rig}, {len(out)} samples, {said} -> {args.out}", file=sys.stderr)
    return 0


def gyro_note(columns, gyro: tuple[str, ...], terms: str) -> str:
    """What ``compensate`` did with the gyros of a rig whose log may hold their outputs
    ``gyro``: compensated when the log's ``columns`` hold them; otherwise said plainly that the
    calibration's gyro ``terms`` were not applied, rather than skipped silently."""
    if all(c in columns for c in gyro):
        return f"accelerometers and gyros ({', '.join(gyro)}) compensated"
    return (f"accelerometers compensated; the log has no gyro outputs ({', '.join(gyro)}, deg/h), so the "
            f"calibration's gyro drift terms ({terms}) were not applied")
