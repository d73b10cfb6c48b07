"""Recorded test logs, for every rig: the one reader (UTF-8 CSV or Parquet) and the time checks.

A real log differs from a simulated one in its clock: timestamps jitter, a logger counts from
its own origin, samples go missing. The rigs therefore use the record's own times (each filter
propagates over the actual interval between the samples it uses) and refuse, before any work,
what would give silent garbage: time that does not increase, ``t`` in another unit (a median
step far from the configured sample period), a gap longer than the rig's ``record.max_gap_s``.
These are pure functions on numpy arrays; messages say what was found and what was expected,
in plain numbers, and the :class:`~platcal.errors.InputError` names the column.
"""

from __future__ import annotations

import codecs
import json
import os
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from .errors import InputError
from .io import atomic_files
from .lighttable import Table, numeric
from .mapping_keys import ISO_TIME
from .rig import option, whole

if TYPE_CHECKING:  # annotations only: the mapping's pint loads in the jobs that read a mapped log
    from .mapping import RecordMapping

PARQUET_MAGIC = b"PAR1"
"""The first (and last) four bytes of every Parquet file."""
UNIT_FACTOR = 10.0
"""A record whose median time step is this many times larger or smaller than the configured
sample period is refused: its ``t`` is in another unit (ms for s gives a factor of 1000)."""
TIME_TOL = 1e-6
"""Tolerance (s) when matching sample times to filter instants."""
LOG_COLUMNS = ("position", "t", "alpha_cmd", "beta_cmd", "gamma_cmd", "Ax", "Ay", "Az")
"""Columns of a positioned-platform test log (docs/centrifuge-model.md §13, docs/multiposition-1g.md
§12): position number, time s, commanded gimbal angles deg, accelerometer outputs g."""
CHUNK_ROWS = 100_000
"""Rows per chunk of a streamed record (``--chunk-rows``): about 9 MB of float64 for the
centrifuge's 11 columns, so reading, checking and filtering hold a few chunks at most."""
TRUTH_COLUMNS = ("alpha", "beta", "gamma")
"""The true gimbal angles (deg) of a simulated positioned-platform log."""


CHUNK_OPTION = option("--chunk-rows", type=whole(0), default=None,
                      help=f"rows of the record held at a time (default {CHUNK_ROWS}; 0: the whole record at once)")
"""``--chunk-rows`` of every rig's ``simulate`` and ``identify`` that stream a record (:func:`chunk_rows_of`)."""


def chunk_rows_of(args) -> int:
    """``--chunk-rows`` of a command's ``args`` (default :data:`CHUNK_ROWS`; 0: the whole record at
    once); InputError when negative."""
    n = CHUNK_ROWS if getattr(args, "chunk_rows", None) is None else int(args.chunk_rows)
    if n < 0:
        raise InputError("--chunk-rows", f"must be a whole number >= 0 (0: the whole record at once), got {n}")
    return n


def chunks_beyond_one(chunks) -> bool:
    """Whether the tables ``chunks`` (an :func:`iter_table` of a record) are more than one: the
    record is then streamed; the generator is closed (the caller reads the record afresh)."""
    try:
        return next(chunks, None) is not None and next(chunks, None) is not None
    finally:
        chunks.close()


def whole_group(columns, group: tuple[str, ...], what: str) -> bool:
    """Whether a log's ``columns`` hold the optional ``group`` (e.g. the three true angles, named
    ``what`` in the message); InputError naming the first missing column when only some do."""
    present = [c for c in group if c in columns]
    if present and len(present) != len(group):
        raise InputError(f"--data column {[c for c in group if c not in columns][0]}",
                         f"{what} come as all {len(group)} of {', '.join(group)} or not at all")
    return bool(present)


def num(v) -> int | float:
    """A plain Python number for messages (no ``np.float64(...)``, no float noise)."""
    v = float(f"{float(v):.10g}")  # no float noise such as 1.6500000000000001
    return int(v) if v.is_integer() else v


def shown(v) -> str:
    """A record value for a message: text quoted, numbers plain."""
    return repr(v) if isinstance(v, str) else str(num(v))


CSV_BLOCK = 1 << 16
"""Bytes read at a time when a CSV record's text is checked (64 KiB). The check holds a block, its
text and the header and last line, so its memory follows this size, not the file's: 1 MiB blocks
held 6.9 MB (tracemalloc's peak) for any file above a few MB, 64 KiB hold 0.3 MB (issue 22 item 3)."""

CSV_LINE_CHARS = 1 << 20
"""The longest header or last line (characters) the CSV check reads whole; a longer one is cut
there (its fields then counted on the first or last 1 Mi characters)."""


def last_line(text: str) -> str:
    """The end of ``text`` from the line break before its last non-empty line (that line and the
    line breaks after it; at most :data:`CSV_LINE_CHARS` characters): what :func:`check_csv_file`
    needs of the text read so far to know the file's last line and its trailing line breaks."""
    cut = text.rstrip("\r\n").rfind("\n")
    return text[max(cut, len(text) - CSV_LINE_CHARS, 0):]


def check_csv_file(path: Path, field: str = "--data", what: str = "a test record", skip: int = 0) -> None:
    """Refuse a CSV record that is not UTF-8 text without NUL bytes, or whose last line is
    incomplete, reading it in blocks of :data:`CSV_BLOCK` bytes (memory does not grow with the
    file). A last line with fewer fields than the header (the line after ``skip`` lines of
    metadata, ``record.header_lines``) is reported as a truncated file (a log cut off while being
    written), not as a bad number."""
    decoder = codecs.getincrementaldecoder("utf-8")()
    offset, breaks, head, tail = 0, 0, "", ""
    with open(path, "rb") as fh:
        while True:
            block = fh.read(CSV_BLOCK)
            try:
                text = decoder.decode(block, final=not block)
            except UnicodeDecodeError as exc:
                raise InputError(field, f"{path} is not a UTF-8 CSV file (byte {offset + exc.start} cannot be "
                                 f"decoded); {what} is CSV text or Parquet (.parquet)") from None
            if "\x00" in text:
                raise InputError(field, f"{path} is not a CSV text file (it holds NUL bytes); {what} is CSV "
                                 "text or Parquet (.parquet)")
            if not block:
                break
            offset += len(block)
            breaks += text.count("\n")
            if len(head) < (skip + 1) * CSV_LINE_CHARS and head.count("\n") <= skip:
                head += text
            tail = last_line(tail + text)
    stripped = tail.rstrip("\r\n")
    n_lines = breaks - tail[len(stripped):].count("\n") + 1
    lines = stripped.splitlines()
    if n_lines <= skip:
        raise InputError("record.header_lines", f"{path} has {n_lines} line(s), not more than the {skip} metadata "
                         "line(s) the config skips; set record.header_lines to the lines above the column header")
    if n_lines >= skip + 2 and lines:
        n_head, n_last = head.splitlines()[skip].count(","), lines[-1].count(",")
        if n_last < n_head:
            raise InputError(f"{field} line {n_lines}", f"the last line is truncated: {n_last + 1} of "
                             f"{n_head + 1} fields (was the file cut off while being written?)")


PANDAS_NA = ("", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND", "1.#QNAN", "<NA>",
             "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null")
"""The texts read as a missing value (NaN), pandas ``read_csv``'s defaults: a log reads as it did
when pandas read it."""


def _arrow_values(col) -> np.ndarray:
    """One pyarrow column (array or chunked array) as numpy: numbers from the array's buffers
    (float64 with NaN where a value is missing), anything else (text) as an object array with NaN
    where missing, as pandas reads them. pyarrow's own ``to_numpy`` is not used: it imports pandas."""
    if isinstance(col, pa.ChunkedArray):
        parts = [_arrow_values(c) for c in col.chunks]
        return np.concatenate(parts) if parts else np.zeros(0)
    t = col.type
    if pa.types.is_integer(t) or pa.types.is_floating(t):
        kind = "float" if pa.types.is_floating(t) else "uint" if pa.types.is_unsigned_integer(t) else "int"
        dtype = np.dtype(f"{kind}{t.bit_width}")
        values = np.frombuffer(col.buffers()[1], dtype=dtype, count=len(col), offset=col.offset * dtype.itemsize)
        if not col.null_count:
            return values
        bits = np.unpackbits(np.frombuffer(col.buffers()[0], np.uint8), bitorder="little")
        valid = bits[col.offset:col.offset + len(col)].astype(bool)
        return np.where(valid, values.astype(float), np.nan)
    values = np.empty(len(col), dtype=object)
    values[:] = [np.nan if v is None else v for v in col.to_pylist()]
    return values


def _numpy_columns(batch) -> dict:
    """A pyarrow record batch (or table) as numpy columns (:func:`_arrow_values`)."""
    return {name: _arrow_values(col) for name, col in zip(batch.schema.names, batch.columns)}


def _csv_columns(path: Path, skip: int) -> list[str]:
    """The column names of a CSV record (pyarrow reads its header and first block)."""
    reader = pacsv.open_csv(path, read_options=pacsv.ReadOptions(skip_rows=skip, block_size=CSV_READ_BLOCK,
                                                                 use_threads=False),
                            convert_options=pacsv.ConvertOptions(null_values=list(PANDAS_NA)),
                            memory_pool=pa.system_memory_pool())
    try:
        return list(reader.schema.names)
    finally:
        reader.close()


CSV_READ_BLOCK = 1 << 16
"""Bytes of CSV text pyarrow's streaming reader parses at a time (64 KiB). The reader holds
blocks ahead of the one it returns, so its memory follows this size: 2 M rows of the 6-hour
centrifuge record (603 MB of CSV) read with 4 MiB blocks hold 212 MB more than before the
read, with 1 MiB 62-79 MB, 256 KiB 21-31 MB, 64 KiB 10 MB; CPU 1.4, 1.2-1.3, 1.3-1.4, 1.6 s
(pyarrow 26; the filter of those rows takes some 30 s)."""


def _csv_batches(path: Path, skip: int, types: dict) -> Iterator[dict]:
    """The CSV record's blocks (:data:`CSV_READ_BLOCK` bytes of text each) as numpy columns, the
    columns of ``types`` read as those pyarrow types (the others as pyarrow infers them from the
    first block). pyarrow allocates from the system's allocator (malloc), which returns freed
    blocks as pyarrow's own pool (mimalloc) does not (74 against 84 MB in the measurement above, 256 KiB)."""
    reader = pacsv.open_csv(path, read_options=pacsv.ReadOptions(skip_rows=skip, block_size=CSV_READ_BLOCK,
                                                                 use_threads=False),
                            convert_options=pacsv.ConvertOptions(column_types=types, null_values=list(PANDAS_NA),
                                                                 strings_can_be_null=True),
                            memory_pool=pa.system_memory_pool())
    try:
        for batch in reader:
            yield _numpy_columns(batch)
    finally:
        reader.close()


def _rechunked(batches: Iterator[dict], chunk_rows: int | None) -> Iterator[dict]:
    """Columns of ``batches`` regrouped into chunks of exactly ``chunk_rows`` rows (the last one
    shorter; None: one chunk of everything). Each batch is copied into its chunk's arrays as it
    comes, so pyarrow's buffers are let go at once and a chunk is held once, not again while joined."""
    if chunk_rows is None:
        parts = [{c: v.copy() for c, v in cols.items()} for cols in batches]  # a copy: the buffers go
        if parts:
            yield _joined(parts)
        return
    out: dict | None = None
    rows = 0
    for cols in batches:
        n = len(next(iter(cols.values()))) if cols else 0
        at = 0
        while at < n:
            if out is None:
                out = {c: np.empty(chunk_rows, dtype=v.dtype) for c, v in cols.items()}
            take = min(n - at, chunk_rows - rows)
            for c, v in cols.items():
                out[c][rows:rows + take] = v[at:at + take]
            rows, at = rows + take, at + take
            if rows == chunk_rows:
                yield out
                out, rows = None, 0
    if out is not None:
        yield {c: v[:rows] for c, v in out.items()}


def _joined(parts: list[dict]) -> dict:
    """Numpy columns of ``parts`` one after another (a column of text and numbers is object)."""
    return parts[0] if len(parts) == 1 else {c: np.concatenate([p[c] for p in parts]) for c in parts[0]}


def _csv_chunks(path: Path, skip: int, chunk_rows: int | None, numbers) -> Iterator[dict]:
    """The CSV record's chunks of ``chunk_rows`` rows as numpy columns: the columns ``numbers``
    parsed by pyarrow as float64, the others as text (``numbers`` None: as pyarrow infers them).
    A value pyarrow does not take for a number (text, ``1,5``, a space, a float after a first
    block of whole numbers) switches to reading every column as text (the file read again from
    the start, the chunks already yielded skipped): :func:`_checked` then takes each value as
    pandas would and names a bad one by its line, as for any log."""
    names = _csv_columns(path, skip)
    types = {} if numbers is None else {n: pa.float64() if n in numbers else pa.string() for n in names}
    done = 0
    try:
        for cols in _rechunked(_csv_batches(path, skip, types), chunk_rows):
            yield cols
            done += 1
            del cols  # not held while the next chunk is read
    except pa.ArrowInvalid as exc:
        if "conversion error" not in str(exc):
            raise
        text = {n: pa.string() for n in names}
        for i, cols in enumerate(_rechunked(_csv_batches(path, skip, text), chunk_rows)):
            if i >= done:
                yield cols
                done += 1
            del cols
    if not done:  # a header without rows: the columns, for the checks that name a missing one
        yield {n: np.zeros(0) for n in names}


PARQUET_BUFFER = 1 << 16
"""Bytes a streamed Parquet read fetches at a time (pyarrow's ``buffer_size``)."""


def iter_frames(path: str | os.PathLike, field: str = "--data", what: str = "a test record",
                chunk_rows: int | None = None, skip: int = 0, numbers=None,
                unread: frozenset[str] = frozenset()) -> Iterator[Table]:
    """Read a record file as tables (:class:`platcal.lighttable.Table`, numpy columns) of at
    most ``chunk_rows`` rows (None: one table, the whole file): Parquet when named ``.parquet``
    (its row batches, pyarrow ``iter_batches``), UTF-8 CSV otherwise (pyarrow's streaming CSV
    reader, :data:`CSV_READ_BLOCK` bytes at a time), its first ``skip`` lines (a logger's metadata
    above the column header, ``record.header_lines``) skipped. Whole-file reading is the
    one-chunk case. ``numbers``: the CSV columns parsed as numbers straight away, the others read
    as text (None: as pyarrow infers them). ``unread``: columns a Parquet file's reader leaves in
    the file (the caller does not use them: a row group of unused columns is not decoded); a CSV
    record's are parsed with the rest, its text read in blocks. pandas is not imported.

    Refused before the first table (InputError naming ``field``): a missing file, a folder, a
    file whose content is not what its name says (Parquet named .csv or the reverse), text that
    is not UTF-8 or holds NUL bytes, a truncated last line; then anything pyarrow cannot parse,
    when it is met.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(field, f"no such file: {path}")
    if path.is_dir():
        raise InputError(field, f"{path} is a folder; give {what} file (.csv or .parquet)")
    if chunk_rows is not None and chunk_rows < 1:
        raise InputError("--chunk-rows", f"must be a whole number >= 1, got {chunk_rows}")
    parquet = path.suffix == ".parquet"
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise InputError(field, f"cannot read {path}: {exc.strerror}") from None
    if parquet and head != PARQUET_MAGIC:
        raise InputError(field, f"{path} is named .parquet but is not a Parquet file; a CSV record is named .csv")
    if not parquet and head == PARQUET_MAGIC:
        raise InputError(field, f"{path} is a Parquet file named {path.suffix or 'without .parquet'}; "
                         "rename it to .parquet")
    if parquet and skip:
        raise InputError("record.header_lines", f"{path} is Parquet, which has no lines above its columns; "
                         "header_lines applies to CSV logs (set it to 0)")
    if not parquet:
        check_csv_file(path, field, what, skip)
    try:
        if parquet:
            # streamed: a column chunk read through a 64 kB buffer as it is decoded, not the row
            # group's bytes fetched whole first (about 25 MB less at a 100 000-row group)
            pf = pq.ParquetFile(path) if chunk_rows is None else pq.ParquetFile(path, pre_buffer=False,
                                                                                  buffer_size=PARQUET_BUFFER)
            names = [n for n in pf.schema_arrow.names if n not in unread]
            if chunk_rows is None:
                # ParquetFile.read, not pq.read_table: the latter loads pyarrow.dataset, which loads pandas
                yield Table(_numpy_columns(pf.read(columns=names)))
            else:
                # map, not a loop: no reference to a chunk is kept while the next one is read
                yield from map(lambda batch: Table(_numpy_columns(batch)),
                               pf.iter_batches(batch_size=chunk_rows, columns=names))
        else:
            yield from map(Table, _csv_chunks(path, skip, chunk_rows, None if numbers is None else set(numbers)))
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise InputError(field, f"cannot read {path} as {what}: {exc}") from None


def read_frame(path: str | os.PathLike, field: str = "--data", what: str = "a test record") -> Table:
    """The whole record file as one table (:func:`iter_frames` with one chunk)."""
    return next(iter_frames(path, field, what))


def iter_table(path: str | os.PathLike, required: tuple[str, ...], optional: tuple[str, ...] = (),
               text: tuple[str, ...] = (), field: str = "--data", what: str = "a test record",
               min_rows: int = 1, mapping: RecordMapping | None = None, units: dict | None = None,
               increments: tuple[str, ...] = (), positions: tuple[str, ...] = (),
               chunk_rows: int | None = None, unused: tuple[str, ...] = ()) -> Iterator[Table]:
    """:func:`read_table` in chunks of at most ``chunk_rows`` rows (None: one chunk): every chunk
    is mapped, converted and checked as the whole file is (a row named by its line in the file;
    ISO times and geodetic positions count from the log's first sample, not the chunk's), so
    memory does not grow with the record. ``min_rows`` is checked before a chunk is yielded (a
    record that is too short yields nothing): a chunk is held back only while the rows read are
    fewer, so no chunk is held while the next is read (issue 22 item 3). Checks that span rows
    (time increasing, gaps) are the rig's, on the chunks it is handed (:class:`TimeCheck`).
    The chunks are :class:`platcal.lighttable.Table` (numpy columns; pandas is not imported).
    ``unused``: ``optional`` columns the command does not use (a record's truth columns for an
    identify): allowed in the file but neither checked nor handed on, and not read from a
    Parquet file (issue 22 item 3: half the columns of a low-precision record)."""
    skip = 0 if mapping is None else mapping.header_lines
    unused = tuple(c for c in unused if c in optional)
    unread = frozenset(c if mapping is None else mapping.columns.get(c, c) for c in unused)
    # row0 + row + 2 is a row's line in the file (the header line and 1-based counting), the
    # metadata lines above the header included
    carry: dict = {"row0": skip}
    chunks = iter_frames(path, field, what, chunk_rows, skip, numbers=_file_numbers(required + optional, text, mapping),
                         unread=unread)
    held: list[Table] = []   # the chunks read while they are fewer than min_rows rows
    rows = 0
    for df in chunks:
        if mapping is not None:
            df = mapping.apply(df, units, required, str(path), increments, positions, carry)
        if unused:
            df = df.drop(unused)
        df = _checked(df, required, optional, text, field, what, carry["row0"])
        carry["row0"] += len(df)
        rows += len(df)
        held.append(df)
        del df  # the caller's chunk only: not one more held while the next is read
        if rows >= min_rows:
            while held:
                yield held.pop(0)
    if rows < min_rows:
        raise InputError(field, f"the record has {rows or 'no'} rows; {what} needs at least {min_rows}")


def position_blocks(chunks, check: Callable[[Table], None] | None = None) -> Iterator[tuple]:
    """The blocks of rows of one position in a positioned-platform log (docs/centrifuge-model.md §13,
    docs/multiposition-1g.md §12) read in ``chunks`` (tables
    in file order, :func:`iter_table`): ``(df, row0, i0, i1, k, starts)`` for rows ``i0:i1`` of
    the chunk ``df`` (whose first row is the file's data row ``row0``, 0-based), all at position
    ``k``; ``starts`` at a position's first block. ``check(df)`` runs on each chunk before its
    blocks (the rig's checks of a chunk). A streamed log holds each position as one block of rows,
    positions in increasing order (a logger's order): InputError naming ``--data column
    position`` and ``--chunk-rows 0`` (read whole, any order) otherwise."""
    last, row = None, 0
    for df in chunks:
        if check is not None:
            check(df)
        pos = df["position"].to_numpy(float)
        cuts = np.r_[0, np.flatnonzero(np.diff(pos)) + 1, pos.size]
        for i0, i1 in zip(cuts[:-1], cuts[1:]):
            k = int(pos[i0])
            starts = k != last
            if starts and last is not None and k <= last:
                raise InputError("--data column position", f"position {k} follows position {last} at "
                                 f"row {row + i0 + 2}: a record read in chunks holds each position as one block, "
                                 "in increasing order; sort it so, or read it whole with --chunk-rows 0")
            last = k
            yield df, row, int(i0), int(i1), k, starts
        row += len(df)


def spilled_positions(chunks, check: Callable[[Table], None] | None = None,
                      each_block: Callable | None = None) -> Iterator[tuple[int, int, ColumnSpill, ColumnSpill]]:
    """The positions of a positioned-platform log read in ``chunks`` (:func:`position_blocks`, its
    ``check`` of each chunk), each gathered into temporary files as it is read: yields ``(k, row0,
    t, a)`` when position ``k`` (whose first row is the file's data row ``row0``) ends, its ``t``
    (s) and ``Ax, Ay, Az`` (g, 3 columns) as :class:`ColumnSpill` (the files go when the caller
    asks for the next position). ``each_block(df, i0, i1, k, starts)`` sees every block of rows
    before it is spilled (a rig's checks of a position's rows). Held: one chunk; the position is
    on disk (32 bytes a sample)."""
    cur = None
    try:
        for df, row0, i0, i1, k, starts in position_blocks(chunks, check):
            if starts and cur is not None:
                yield cur
                for spill in cur[2:]:
                    spill.close()
                cur = None
            if each_block is not None:
                each_block(df, i0, i1, k, starts)
            if starts:
                cur = (k, row0 + i0, ColumnSpill(), ColumnSpill(3))
            cur[2].write(df["t"].to_numpy(float)[i0:i1])
            cur[3].write(df[["Ax", "Ay", "Az"]].to_numpy(float)[i0:i1])
        if cur is not None:
            yield cur
    finally:
        for spill in cur[2:] if cur is not None else ():
            spill.close()


def _file_numbers(columns: tuple[str, ...], text: tuple[str, ...], mapping: RecordMapping | None) -> set[str]:
    """The file columns a CSV reader parses as numbers straight away: those that fill the rig's
    numeric ``columns`` (not ``text``, not ISO date-times; by the file's names when ``mapping``
    renames them) and a geodetic mapping's latitude, longitude and height. The others are read
    as text (a vendor's extra columns, the rig's text); a number among them is converted as any."""
    if mapping is None:
        return {c for c in columns if c not in text}
    iso = {c for c, u in mapping.units.items() if u.strip() == ISO_TIME}
    out = {mapping.columns.get(c, c) for c in columns if c not in text and c not in iso}
    return out | {v for k, v in mapping.geodetic.items() if k in ("lat", "lon", "height")}


def _checked(df: Table, required: tuple[str, ...], optional: tuple[str, ...], text: tuple[str, ...],
             field: str, what: str, row0: int) -> Table:
    """One chunk's columns and values checked (see :func:`read_table`); ``row0``: the file's
    data row of its first row (0-based), for the line numbers of messages."""
    cols = [str(c) for c in df.columns]
    missing = [c for c in required if c not in cols]
    if missing:
        hint = ""
        if len(cols) == 1 and any(sep in cols[0] for sep in ";\t|"):
            hint = f"; the header {cols[0][:60]!r} is not comma-separated: a CSV record uses ','"
        raise InputError(f"{field} column {missing[0]}", f"missing; {what} has columns {list(required)}"
                         + (f" (and optionally {list(optional)})" if optional else "") + hint)
    extra = [c for c in cols if c not in required + optional]
    if extra:
        raise InputError(f"{field} column {extra[0]}", f"unexpected column; allowed: {list(required + optional)}")
    for c in cols:
        if c in text:
            continue
        values = numeric(df[c])
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.argmax(bad))
            raise InputError(f"{field} column {c}, row {row0 + row + 2}",
                             f"value {shown(df[c].iloc[row])} is not a finite number (NaN, infinite or text)")
        df[c] = values
    return df


def read_table(path: str | os.PathLike, required: tuple[str, ...], optional: tuple[str, ...] = (),
               text: tuple[str, ...] = (), field: str = "--data", what: str = "a test record",
               min_rows: int = 1, mapping: RecordMapping | None = None, units: dict | None = None,
               increments: tuple[str, ...] = (), positions: tuple[str, ...] = ()):
    """A pandas DataFrame (for the whole-log tools that work on one): :func:`read_frame` plus the columns: every ``required`` one present, nothing outside
    ``required + optional``, at least ``min_rows`` rows, every column except ``text`` a finite
    number (InputError naming the column and the file's line). Numeric columns come back as float.
    With a config's ``mapping`` (:class:`platcal.mapping.RecordMapping`) and the rig's column
    ``units`` (None for a text column) the log is first renamed and converted to the rig's units
    (``increments``: the columns ``record.kind: increments`` applies to; ``positions``: the east
    and north position columns ``record.geodetic`` fills). The one-chunk case of :func:`iter_table`.
    """
    return next(iter_table(path, required, optional, text, field, what, min_rows, mapping, units, increments,
                           positions)).to_pandas()


class TimeCheck:
    """Time increasing across the chunks of a streamed record: each chunk's ``t`` is checked as
    :func:`check_increasing` checks a whole one, with the last time of the previous chunk in
    front, so a step back at a chunk boundary is refused as one inside a chunk is."""

    def __init__(self, field: str, where: str = ""):
        self.field, self.where = field, where
        self.last: float | None = None
        self.count = 0

    def __call__(self, t: np.ndarray) -> None:
        if t.size == 0:
            return
        ahead = t if self.last is None else np.r_[self.last, t]
        try:
            check_increasing(ahead, self.field, self.where)
        except InputError:
            step = np.diff(ahead)
            i = int(np.argmax(step <= 0)) + 1  # in ``ahead``
            n = self.count + i + (0 if self.last is None else -1)
            raise InputError(self.field, f"time does not increase at sample {n + 1}{self.where} "
                             f"(t = {num(ahead[i - 1])} then {num(ahead[i])} s)") from None
        self.last = float(t[-1])
        self.count += t.size


def check_increasing(t: np.ndarray, field: str, where: str = "", step: np.ndarray | None = None) -> None:
    """Refuse time that does not increase strictly (``where``: e.g. " of the position";
    ``step``: ``np.diff(t)`` when the caller has it already)."""
    step = np.diff(t) if step is None else step
    if np.any(step <= 0):
        i = int(np.argmax(step <= 0)) + 1
        raise InputError(field, f"time does not increase at sample {i + 1}{where} "
                         f"(t = {num(t[i - 1])} then {num(t[i])} s)")


def check_time_unit(t: np.ndarray, sample_s: float, field: str, expected: str, origin_note: str = "") -> float:
    """The median time step (s) of increasing ``t``; refused when it is more than
    :data:`UNIT_FACTOR` times off the configured sample period ``sample_s`` (``expected`` names
    the config key and its value, e.g. ``"sampling.ts_ms = 20 ms"``): ``t`` is then not in
    seconds (ms give 1000) or the config's rate is not the log's."""
    return unit_verdict(float(np.median(np.diff(t))), sample_s, field, expected, origin_note)


def unit_verdict(med: float, sample_s: float, field: str, expected: str, origin_note: str = "") -> float:
    """:func:`check_time_unit` on the median step ``med`` (s) already taken."""
    ratio = med / sample_s
    if ratio > UNIT_FACTOR or ratio < 1 / UNIT_FACTOR:
        hint = " (t looks like milliseconds)" if 300 < ratio < 3000 else ""
        raise InputError(field, f"median time step {med:g} s, expected about {expected}{hint}; "
                         f"t must be seconds{origin_note}")
    return med


def largest_gap(t: np.ndarray) -> tuple[int, float]:
    """``(i, step)``: the largest step of ``t``, between samples i and i + 1."""
    step = np.diff(t)
    i = int(np.argmax(step))
    return i, float(step[i])


def check_gap(t: np.ndarray, max_gap_s: float, field: str, key: str = "record.max_gap_s",
              sample_s: float | None = None) -> None:
    """Refuse a gap between consecutive samples longer than ``max_gap_s`` (config ``key``). With
    the configured sample period ``sample_s`` a step of up to 1.5 periods is never a gap (so a
    limit below the period, e.g. 0.05 s at 10 Hz, does not refuse every step)."""
    if t.size < 2:
        return
    gap_verdict(t, *largest_gap(t), max_gap_s, field, key, sample_s)


def gap_verdict(t: np.ndarray, i: int, step: float, max_gap_s: float, field: str, key: str = "record.max_gap_s",
                sample_s: float | None = None) -> None:
    """:func:`check_gap` on the largest step ``step`` (s), between samples ``i`` and ``i + 1``."""
    if step > max_gap_s and (sample_s is None or step > 1.5 * sample_s):
        raise InputError(field, f"gap of {step:g} s between t = {num(t[i])} and {num(t[i + 1])} s, "
                         f"more than {key} = {max_gap_s:g} s (raise it in the config if the gap is harmless)")


def check_times(t: np.ndarray, sample_s: float, max_gap_s: float, field: str, expected: str,
                gap_key: str = "record.max_gap_s", where: str = "") -> float:
    """Increasing, in seconds, without a gap above ``max_gap_s``; returns the median step (s)."""
    if t.size < 2:
        raise InputError(field, f"has {t.size} sample{where}; a record needs samples every {sample_s:g} s")
    # One array of steps serves every check, its median taken in place last: a 6 h record at
    # 200 Hz would otherwise hold three 35 MB copies beside t.
    step = np.diff(t)
    check_increasing(t, field, where, step)
    i = int(np.argmax(step))
    largest = float(step[i])
    med = unit_verdict(float(np.median(step, overwrite_input=True)), sample_s, field, expected)
    gap_verdict(t, i, largest, max_gap_s, field, gap_key, sample_s)
    return med


MEDIAN_DISTINCT = 4096
"""Distinct values :class:`PassMedian` counts in its first pass before it turns to radix passes
(a clean record's steps take a handful of values: its median is then known after one pass)."""
MEDIAN_HOLD = 1 << 18
"""Values :class:`PassMedian` gathers in one pass (2 MiB of keys): once the candidates of a middle
rank are this few, the next pass collects them and ends the selection."""
_SIGN = np.uint64(1 << 63)


def _order_keys(v: np.ndarray) -> np.ndarray:
    """float64 values as uint64 keys in the same order (IEEE 754 bit patterns: a positive value's
    sign bit set, a negative one's bits inverted, so unsigned order is numeric order; -0 < +0)."""
    u = np.ascontiguousarray(v, dtype=np.float64).view(np.uint64)
    return np.where(u & _SIGN, ~u, u | _SIGN)


def _key_value(key: int) -> float:
    """The float64 of one :func:`_order_keys` key."""
    k = np.uint64(key)
    u = k ^ _SIGN if k & _SIGN else ~k
    return float(np.array([u], dtype=np.uint64).view(np.float64)[0])


class PassMedian:
    """The exact median of values that can be read again (``np.median``'s number, bit for bit) in
    memory that does not grow with their count: the caller feeds every value to :meth:`add` in a
    pass, calls :meth:`end_pass`, and feeds the same values again, in any order and cut, while it
    returns False. Pass 1 counts the values, their distinct values (up to :data:`MEDIAN_DISTINCT`:
    a median of few distinct values is then known) and a 65 536-bin histogram of the top 16 bits
    of their order keys (:func:`_order_keys`); each further pass narrows each middle rank's bin
    by the next 16 bits, or gathers its candidates once they are at most :data:`MEDIAN_HOLD`
    (radix selection: at most 4 passes after the first, 1-2 on a jittered clock's steps). Held:
    two 65 536-bin counts (1 MiB) and at most :data:`MEDIAN_HOLD` keys. NaN among the values gives
    NaN, as ``np.median``; no values give NaN (the callers refuse an empty record before)."""

    def __init__(self):
        self.n, self.nan, self.passes = 0, False, 0
        self.value: float | None = None
        self._distinct: tuple[np.ndarray, np.ndarray] | None = (np.zeros(0), np.zeros(0, np.int64))
        self._hist = np.zeros(1 << 16, np.int64)
        self._ranks: list[dict] = []     # per middle rank: its key's known top bits and what the pass gathers

    def add(self, values) -> None:
        """Feed values of this pass (any shape: flattened)."""
        v = np.asarray(values, dtype=np.float64).ravel()
        if self.value is not None or v.size == 0:
            return
        if self.passes == 0:
            self.n += v.size
            if np.isnan(v).any():
                self.nan = True
                return
            if self._distinct is not None:
                new_vals, new_counts = np.unique(v, return_counts=True)
                vals = np.union1d(self._distinct[0], new_vals)
                if vals.size > MEDIAN_DISTINCT:
                    self._distinct = None   # a jittered clock: the radix passes
                else:
                    counts = np.zeros(vals.size, np.int64)
                    counts[np.searchsorted(vals, self._distinct[0])] += self._distinct[1]
                    counts[np.searchsorted(vals, new_vals)] += new_counts
                    self._distinct = (vals, counts)
            self._hist += np.bincount((_order_keys(v) >> np.uint64(48)).astype(np.int64), minlength=1 << 16)
            return
        if self.nan:
            return
        keys = _order_keys(v)
        for r in self._ranks:
            if r["key"] is not None:
                continue
            inside = keys[(keys >> np.uint64(r["shift"])) == np.uint64(r["prefix"])]
            if r["gather"]:
                r["got"].append(inside)
            else:
                digit = ((inside >> np.uint64(r["shift"] - 16)) & np.uint64(0xFFFF)).astype(np.int64)
                r["hist"] += np.bincount(digit, minlength=1 << 16)

    def _narrow(self, r: dict, hist: np.ndarray) -> None:
        """Rank ``r``'s bin in ``hist`` (the counts of its next 16 bits): its top bits, rank inside."""
        cum = np.cumsum(hist)
        b = int(np.searchsorted(cum, r["rank"], side="right"))
        r["rank"] -= int(cum[b - 1]) if b else 0
        r["prefix"], r["shift"] = (r["prefix"] << 16) | b, r["shift"] - 16
        if r["shift"] == 0:
            r["key"] = r["prefix"]
            return
        r["gather"] = int(hist[b]) <= MEDIAN_HOLD
        r["got"], r["hist"] = [], None if r["gather"] else np.zeros(1 << 16, np.int64)

    def end_pass(self) -> bool:
        """End a pass; True once the median is known (:attr:`value`), False when the values must
        be fed again."""
        if self.value is not None:
            return True
        first = self.passes == 0
        self.passes += 1
        if self.nan or self.n == 0:
            self.value = float("nan")
            return True
        mid = sorted({(self.n - 1) // 2, self.n // 2})
        if first and self._distinct is not None:
            vals, counts = self._distinct
            cum = np.cumsum(counts)
            return self._done([float(vals[int(np.searchsorted(cum, i, side="right"))]) for i in mid])
        if first:
            self._ranks = [{"rank": i, "prefix": 0, "shift": 64, "key": None} for i in mid]
            for r in self._ranks:
                self._narrow(r, self._hist)
            self._hist = None
        else:
            for r in self._ranks:
                if r["key"] is not None:
                    continue
                if r["gather"]:
                    got = np.concatenate(r["got"])
                    r["key"], r["got"] = int(np.partition(got, r["rank"])[r["rank"]]), None
                else:
                    self._narrow(r, r["hist"])
        if all(r["key"] is not None for r in self._ranks):
            return self._done([_key_value(r["key"]) for r in self._ranks])
        return False

    def _done(self, middle: list[float]) -> bool:
        # np.median's own arithmetic: the mean of the middle value(s)
        self.value = float(np.mean(np.array(middle)))
        return True


def pass_median(passes: Callable[[], Iterator[np.ndarray]]) -> float:
    """:class:`PassMedian` of the values ``passes()`` yields afresh at each call (its arrays, in
    order): ``np.median`` of them all, in bounded memory."""
    m = PassMedian()
    while True:
        for values in passes():
            m.add(values)
        if m.end_pass():
            return m.value


SPILL_BLOCK = 1 << 16
"""Values a :class:`ColumnSpill` hands back at a time (512 KiB of float64)."""


class ColumnSpill:
    """One float64 column of a streamed record (its ``t``, s; or ``width`` columns side by side,
    e.g. Ax, Ay, Az) spilled to a temporary file as the chunks are read, so that the checks that
    need it whole (medians, nearest samples) pass over it again from disk, :data:`SPILL_BLOCK`
    rows at a time, instead of reading the record again or holding it (8 bytes a value on disk,
    none in memory). A context manager: the file goes at the end. ``first`` and ``last``: the
    first and last values of a single column."""

    def __init__(self, width: int = 1):
        self._fh = tempfile.TemporaryFile(prefix="platcal_spill_")
        self.width, self.rows = width, 0
        self.first = self.last = float("nan")

    def __enter__(self) -> ColumnSpill:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._fh.close()

    def write(self, values: np.ndarray) -> None:
        """Append the next chunk's values ((n,) or (n, width))."""
        v = np.ascontiguousarray(values, dtype=np.float64)
        if v.size == 0:
            return
        if self.width == 1:
            if self.rows == 0:
                self.first = float(v[0])
            self.last = float(v[-1])
        self._fh.seek(0, os.SEEK_END)
        self._fh.write(v.tobytes())
        self.rows += v.size // self.width

    def blocks(self, shift: float = 0.0, rows: int | None = None,
               per_block: int | None = None) -> Iterator[tuple[int, np.ndarray]]:
        """``(i0, values - shift)``: the column from row ``i0``, ``per_block`` rows at a time
        (default :data:`SPILL_BLOCK`; ``shift`` taken off elementwise, as ``t - shift`` of the whole
        column), up to row ``rows`` (default: every row); (n, width) for a spill of several columns."""
        end = self.rows if rows is None else min(rows, self.rows)
        step = SPILL_BLOCK if per_block is None else per_block
        self._fh.seek(0)
        for i0 in range(0, end, step):
            n = min(step, end - i0)
            v = np.fromfile(self._fh, dtype=np.float64, count=n * self.width)
            if self.width > 1:
                v = v.reshape(n, self.width)
            yield i0, (v - shift if shift != 0.0 else v)

    def take(self, idx: np.ndarray) -> np.ndarray:
        """The rows ``idx`` (increasing) of the spill, as ``values[idx]`` of the whole column."""
        out = np.empty((idx.size,) + ((self.width,) if self.width > 1 else ()))
        for i0, v in self.blocks():
            a, b = np.searchsorted(idx, [i0, i0 + len(v)])
            out[a:b] = v[idx[a:b] - i0]
        return out

    def steps(self, shift: float = 0.0) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """``(g, ahead, step)``: each block with the previous block's last value in front
        (``ahead``, whose first value is row ``g``) and ``step = np.diff(ahead)`` (the steps of
        ``values - shift`` from row ``g`` on, those across block boundaries included)."""
        prev = None
        for i0, v in self.blocks(shift):
            ahead = v if prev is None else np.r_[prev, v]
            yield (i0 if prev is None else i0 - 1), ahead, np.diff(ahead)
            prev = v[-1]


def spilled_steps(spill: ColumnSpill, shift: float = 0.0, median: bool = True) -> tuple:
    """``(back, largest, med)`` of the steps of the spilled ``t - shift`` (s): the first step
    that is not positive as ``(i, t[i - 1], t[i])`` or None; the first largest step as
    ``(step, i, t[i], t[i + 1])``; their median (``np.median``'s number by
    :class:`PassMedian`; None when not ``median`` or when a step back is found: the callers
    refuse it first)."""
    med, back, big = PassMedian(), None, (-np.inf, 0, 0.0, 0.0)
    while True:
        for g, ahead, step in spill.steps(shift):
            if median and back is None:
                med.add(step)
            if med.passes:
                continue
            if back is None and np.any(step <= 0):
                j = int(np.argmax(step <= 0))
                back = (g + j + 1, ahead[j], ahead[j + 1])
            j = int(np.argmax(step))
            if step[j] > big[0]:        # strictly: the first largest step, as np.argmax over the record
                big = (float(step[j]), g + j, ahead[j], ahead[j + 1])
        if not median or back is not None or med.end_pass():
            return back, big, (med.value if median and back is None else None)


def refuse_back(back: tuple | None, field: str, where: str = "") -> None:
    """:func:`check_increasing`'s refusal of the step back ``back`` (:func:`spilled_steps`)."""
    if back is not None:
        i, t0, t1 = back
        raise InputError(field, f"time does not increase at sample {i + 1}{where} (t = {num(t0)} then {num(t1)} s)")


def spilled_times(spill: ColumnSpill, sample_s: float, max_gap_s: float, field: str, expected: str,
                  gap_key: str = "record.max_gap_s", where: str = "") -> float:
    """:func:`check_times` of the spilled ``t`` (s): the same checks in the same order, with the
    same messages and the same median step (s, :class:`PassMedian`: ``np.median``'s number), in
    memory that does not grow with the record."""
    n = spill.rows
    if n < 2:
        raise InputError(field, f"has {n} sample{where}; a record needs samples every {sample_s:g} s")
    back, (largest, _, t0, t1), med = spilled_steps(spill)
    refuse_back(back, field, where)
    unit_verdict(med, sample_s, field, expected)
    gap_verdict(np.array([t0, t1]), 0, largest, max_gap_s, field, gap_key, sample_s)
    return med


def spilled_grid_origin(spill: ColumnSpill, step: float) -> float:
    """:func:`grid_origin` of the spilled ``t`` (s), in bounded memory."""
    t0 = spill.first

    def offsets():
        for _, v in spill.blocks():
            d = v - t0
            yield d - step * np.round(d / step)

    return float(t0 + pass_median(offsets))


def spilled_median_step(spill: ColumnSpill, shift: float = 0.0) -> float:
    """``np.median(np.diff(t - shift))`` of the spilled ``t`` (s), in bounded memory."""
    return pass_median(lambda: (step for _, _, step in spill.steps(shift)))


class NearestSamples:
    """:func:`nearest_samples` of a ``t`` seen block by block, in order (:meth:`add` each block
    with the row of its first sample, the previous block's last sample in front or not;
    :meth:`result` at the end): the same indices, with the times at them. ``t_first`` and
    ``t_last``: the record's first and last times (the multiples to look for). Holds the
    result (two values per index found)."""

    def __init__(self, t_first: float, t_last: float, period_s: float, tol_s: float, first: int | None = None):
        self.period, self.tol = period_s, tol_s
        self.m0 = np.ceil((t_first - tol_s) / period_s)
        self.m1 = np.floor((t_last + tol_s) / period_s)
        if first is not None:
            self.m0 = max(self.m0, float(first))
        self.idx: list[np.ndarray] = []
        self.at: list[np.ndarray] = []
        self.tail: tuple | None = None      # the row of the last two samples seen, their times
        self.started = False
        self.last_found = -1                # the last index :meth:`found` handed out

    def _wants(self, lo: float, hi: float) -> np.ndarray:
        """The multiples ``m period`` in (lo, hi] (lo = -inf: every one up to hi), as the whole
        record's ``np.arange`` of m times the period gives them."""
        a = self.m0 if lo == -np.inf else max(self.m0, np.floor(lo / self.period) - 1)
        b = self.m1 if hi == np.inf else min(self.m1, np.floor(hi / self.period) + 1)
        if b < a:
            return np.zeros(0)
        want = np.arange(a, b + 1) * self.period
        return want[(want > lo) & (want <= hi)]

    def _keep(self, j: np.ndarray, tj: np.ndarray, want: np.ndarray) -> None:
        ok = np.abs(tj - want) <= self.tol + TIME_TOL
        self.idx.append(j[ok])
        self.at.append(tj[ok])

    def add(self, g: int, ahead: np.ndarray) -> None:
        """One block: ``ahead`` the samples from row ``g`` (the previous block's last in front)."""
        if not self.started:
            self.started = True
            want = self._wants(-np.inf, float(ahead[0]))        # at or before the first sample: sample 0
            self._keep(np.zeros(want.size, np.int64), np.full(want.size, ahead[0]), want)
        if ahead.size > 1:
            want = self._wants(float(ahead[0]), float(ahead[-1]))
            j = np.searchsorted(ahead, want)                     # 1 .. len - 1: ahead[j - 1] < want <= ahead[j]
            j = np.where(np.abs(ahead[j - 1] - want) <= np.abs(ahead[j] - want), j - 1, j)
            self._keep(g + j, ahead[j], want)
        if ahead.size > 1:
            self.tail = (g + ahead.size - 2, ahead[-2:].copy())

    def _after_last(self) -> None:
        """After the last sample: the nearer of the last two, as the whole record's clip."""
        if self.tail is not None:
            g, two = self.tail
            want = self._wants(float(two[1]), np.inf)
            j = np.where(np.abs(two[0] - want) <= np.abs(two[1] - want), 0, 1)
            self._keep(g + j, two[j], want)

    def found(self, final: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`result` in pieces, so that a long record's indices need not be held: the
        ``(indices, times)`` found since the last call (and after the last sample when
        ``final``), increasing and without repeats of each other or of earlier pieces. The
        blocks' multiples come in order, so the indices found never decrease and dropping an
        index equal to the one before gives ``np.unique``'s (its first time)."""
        if final:
            self._after_last()
        idx = np.concatenate(self.idx).astype(np.int64) if self.idx else np.zeros(0, np.int64)
        at = np.concatenate(self.at) if self.at else np.zeros(0)
        self.idx, self.at = [], []
        new = idx != np.r_[self.last_found, idx[:-1]]
        if idx.size:
            self.last_found = int(idx[-1])
        return idx[new], at[new]

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """``(indices, times)``: the samples nearest each multiple, increasing, without repeats."""
        self._after_last()
        idx = np.concatenate(self.idx) if self.idx else np.zeros(0, np.int64)
        at = np.concatenate(self.at) if self.at else np.zeros(0)
        self.idx, self.at = [], []
        idx, first = np.unique(idx, return_index=True)
        return idx.astype(np.int64), at[first]


class RowsAt:
    """``values[idx]`` of a column that comes in blocks ``(i0, values)`` in order
    (:meth:`ColumnSpill.blocks`, a simulation's chunks), for indices asked in increasing order
    across calls (:meth:`take`): one pass over the blocks, one block held."""

    def __init__(self, blocks):
        self._blocks = iter(blocks)
        self._i0, self._v = 0, None

    def take(self, idx: np.ndarray) -> np.ndarray:
        """The rows ``idx`` (non-decreasing, none below an earlier call's)."""
        parts, a = [], 0
        while a < idx.size:
            while self._v is None or idx[a] >= self._i0 + len(self._v):
                self._i0, self._v = next(self._blocks)
            b = a + int(np.searchsorted(idx[a:], self._i0 + len(self._v)))
            parts.append(self._v[idx[a:b] - self._i0])
            a = b
        if not parts:  # nothing asked: no rows, of the column's width (the first block's)
            if self._v is None:
                self._i0, self._v = next(self._blocks, (0, np.zeros(0)))
            return self._v[:0]
        return np.concatenate(parts) if len(parts) > 1 else parts[0]


def grid_origin(t: np.ndarray, step: float) -> float:
    """The instant of the first sample of a (jittered) grid of period ``step``: ``t[0]`` corrected
    by the median offset of all samples from the grid, so jitter of the first sample alone does not
    shift the origin (a constant clock offset is then removed exactly)."""
    d = t - t[0]
    return float(t[0] + np.median(d - step * np.round(d / step)))


def nearest_samples(t: np.ndarray, period_s: float, tol_s: float, first: int | None = None) -> np.ndarray:
    """Indices of the samples nearest each multiple ``m period_s`` (within ``tol_s``; ``m >= first``
    when ``first`` is given), increasing and without repeats: decimation by time, not by an exact
    grid match. ``t`` increases."""
    m = np.arange(np.ceil((t[0] - tol_s) / period_s), np.floor((t[-1] + tol_s) / period_s) + 1)
    if first is not None:
        m = m[m >= first]
    if m.size == 0:
        return np.zeros(0, dtype=np.int64)
    want = m * period_s
    j = np.clip(np.searchsorted(t, want), 1, t.size - 1) if t.size > 1 else np.zeros(want.size, dtype=int)
    if t.size > 1:
        j = np.where(np.abs(t[j - 1] - want) <= np.abs(t[j] - want), j - 1, j)
    ok = np.abs(t[j] - want) <= tol_s + TIME_TOL
    return np.unique(j[ok])


TRUTH_SUFFIX = ".truth.json"
"""A simulated record's side file (its drawn truth) is named from the record's FULL file name:
``rec.csv.truth.json`` and ``rec.parquet.truth.json``, so two records never share one."""


def truth_path(record: str | os.PathLike) -> Path:
    """The truth side file of ``record`` (:data:`TRUTH_SUFFIX`), for every rig that writes one."""
    return Path(str(record) + TRUTH_SUFFIX)


def write_record(df, path: str | os.PathLike, truth: dict | None = None,
                 float_format: str | None = None) -> None:
    """Write a whole test record atomically (:func:`record_writer` with one chunk): ``.parquet``
    as Parquet, anything else as CSV, with its ``truth`` side file as a pair."""
    with record_writer(path, truth, float_format) as write:
        write(df)


def read_truth(record: str | os.PathLike) -> dict | None:
    """The truth side file of ``record`` as a mapping; None when there is none; InputError naming
    the side file when it is not JSON."""
    side = truth_path(record)
    if not side.is_file():
        return None
    try:
        return json.loads(side.read_text())
    except (ValueError, UnicodeDecodeError):
        raise InputError(str(side), "not a JSON truth file (delete it or simulate the record again)") from None


@contextmanager
def record_writer(path: str | os.PathLike, truth: dict | Callable[[], dict] | None = None,
                  float_format: str | None = None) -> Iterator[Callable]:
    """Write a test record chunk by chunk: yields ``write(df)``, each chunk appended (CSV rows
    after one header, floats at ``float_format``, default full precision; a Parquet row group
    each) to a temporary file, so a long record is written without being held. With ``truth`` (a
    mapping, or a callable giving it once the block's writes are done, e.g. a streamed run's final
    errors), its side
    file (:func:`truth_path`, JSON) is written as a pair with it: both go to temporaries
    and are renamed together when the block ends without error, the side file first (a record
    never appears without its truth; :func:`platcal.io.atomic_files`); a failed write (a full
    disk) removes both temporaries and leaves the files already there untouched, so no orphan
    side file and nothing half-written."""
    path = Path(path)
    parquet = path.suffix == ".parquet"
    with atomic_files(path.parent) as tmp:
        # the side file's temporary asked for first, so it is renamed first; its text written when
        # the record is complete (a callable ``truth`` is then known: a streamed run's final state)
        side = None if truth is None else tmp(truth_path(path).name)
        out = tmp(path.name)
        state: dict = {}

        def write(df) -> None:  # a pandas DataFrame
            if parquet:
                table = pa.Table.from_pandas(df, preserve_index=False)
                if "writer" not in state:
                    state["writer"] = pq.ParquetWriter(out, table.schema)
                state["writer"].write_table(table)
            else:
                df.to_csv(out, index=False, float_format=float_format, mode="a" if state else "w", header=not state)
                state["csv"] = True

        try:
            yield write
        finally:
            if "writer" in state:
                state["writer"].close()
        if side is not None:
            side.write_text(json.dumps(truth() if callable(truth) else truth, indent=1) + "\n")
