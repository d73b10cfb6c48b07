"""A record's chunk as numpy columns: what :func:`platcal.records.iter_table` yields (issue 22 item 3).

The streamed read of a long log holds one chunk at a time, and the floor under its memory is
the libraries it imports: pandas alone is some 80 MB of resident set before one row is read.
A chunk is therefore a :class:`Table`, an ordered mapping of column name -> numpy array with
the few DataFrame methods the rigs' readers use (``df[col].to_numpy(float)``, ``df[[cols]]``,
``len(df)``, ``df.columns``, a boolean row mask, ``drop``, ``rename``); a caller that wants a
pandas DataFrame (a whole-log tool: summaries, reports) asks :meth:`Table.to_pandas`.
Text columns are object arrays whose missing values are NaN, as pandas reads them.
"""

from __future__ import annotations

import math

import numpy as np
import pyarrow as pa


def is_missing(v) -> bool:
    """Whether a value of an object column is missing (None or a float NaN), as ``pandas.isna``."""
    return v is None or (isinstance(v, float) and math.isnan(v))


def _number(v) -> float:
    """One value as a float, NaN when it is not a number (text, missing): ``pandas.to_numeric``'s
    ``errors="coerce"`` for one element."""
    if isinstance(v, (bool, np.bool_)):
        return float(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if isinstance(v, str) and "_" not in v:  # Python's float() takes 1_000; a log's number does not
        try:
            return float(v)
        except ValueError:
            return math.nan
    return math.nan


def numeric(values) -> np.ndarray:
    """``values`` (a column) as float64, anything that is not a number NaN (as
    ``pandas.to_numeric(values, errors="coerce")``): numeric columns are converted as they are,
    object columns (text read from a log) value by value."""
    a = np.asarray(values)
    if a.dtype.kind in "fiub":
        return a.astype(float, copy=False)
    return np.fromiter((_number(v) for v in a.ravel()), float, a.size).reshape(a.shape)


class Column(np.ndarray):
    """One column of a :class:`Table`: a numpy array with the pandas Series methods record
    readers call (``to_numpy``, ``iloc``, ``map``, ``isna``, ``fillna``)."""

    def __new__(cls, values):
        return np.asarray(values).view(cls)

    def to_numpy(self, dtype=None) -> np.ndarray:
        """The values as a plain numpy array (of ``dtype`` when given)."""
        a = np.asarray(self)
        return a if dtype is None else a.astype(dtype, copy=False)

    def astype(self, dtype, *args, **kwargs):
        """As numpy's, except that ``astype(str)`` gives Python strings (an object column, as
        pandas does: a value in a message reads ``'spin'``, not ``np.str_('spin')``)."""
        if dtype is str:
            return Column(np.array([str(v) for v in np.asarray(self).tolist()], dtype=object))
        return super().astype(dtype, *args, **kwargs)

    @property
    def iloc(self) -> np.ndarray:
        """Positional access, as a Series' ``iloc``."""
        return np.asarray(self)

    def isna(self) -> "Column":
        """Missing values (NaN, None), as ``Series.isna``."""
        a = np.asarray(self)
        if a.dtype.kind == "f":
            return Column(np.isnan(a))
        if a.dtype.kind == "O":
            return Column(np.fromiter((is_missing(v) for v in a), bool, a.size))
        return Column(np.zeros(a.shape, bool))

    def fillna(self, value) -> "Column":
        """Missing values replaced by ``value``, as ``Series.fillna``."""
        return Column(np.where(np.asarray(self.isna()), value, np.asarray(self)))

    def map(self, mapping: dict) -> "Column":
        """Each value looked up in ``mapping`` (NaN when absent), as ``Series.map`` with a dict."""
        return Column(np.array([mapping.get(v, math.nan) for v in np.asarray(self).tolist()]))


class Table:
    """Columns of equal length in order: a chunk of a record (see the module's doc)."""

    def __init__(self, data: dict):
        self._data = {str(k): np.asarray(v) for k, v in data.items()}
        sizes = {v.shape[0] for v in self._data.values()}
        if len(sizes) > 1:
            raise ValueError(f"columns of different lengths: {sorted(sizes)}")
        self._rows = sizes.pop() if sizes else 0

    @property
    def columns(self) -> list[str]:
        """The column names, in order."""
        return list(self._data)

    def __len__(self) -> int:
        return self._rows

    def __contains__(self, name) -> bool:
        return name in self._data

    def __getitem__(self, key):
        """A column by name; a :class:`Table` of the columns in a list; the rows of a boolean mask."""
        if isinstance(key, str):
            return Column(self._data[key])
        if isinstance(key, (list, tuple)):
            return Table({k: self._data[k] for k in key})
        mask = np.asarray(key)
        return Table({k: v[mask] for k, v in self._data.items()})

    def __setitem__(self, key: str, values) -> None:
        values = np.asarray(values)
        if self._data and values.shape[0] != self._rows:
            raise ValueError(f"column {key!r} has {values.shape[0]} values, the table {self._rows} rows")
        self._data[str(key)] = values
        self._rows = values.shape[0]

    def drop(self, columns) -> "Table":
        """The table without ``columns``."""
        gone = set(columns)
        return Table({k: v for k, v in self._data.items() if k not in gone})

    def rename(self, columns: dict) -> "Table":
        """The table with columns renamed by ``columns`` (old -> new)."""
        return Table({columns.get(k, k): v for k, v in self._data.items()})

    def to_numpy(self, dtype=None) -> np.ndarray:
        """(rows, columns) array of the columns side by side."""
        if not self._data:
            return np.empty((self._rows, 0), dtype=dtype or float)
        return np.column_stack([v if dtype is None else v.astype(dtype, copy=False) for v in self._data.values()])

    def to_pandas(self):
        """The table as a pandas DataFrame, for whole-log tools that work on one."""
        # pandas only here: a streamed read (the chunks' own methods) never loads its ~80 MB
        import pandas as pd

        return pd.DataFrame(self._data)

    def to_arrow(self) -> pa.Table:
        """The table as a pyarrow Table (numbers, booleans, text as ``large_string`` with missing
        values null, as pandas writes a text column), to write Parquet without pandas."""
        return pa.Table.from_arrays([arrow_column(k, v) for k, v in self._data.items()], names=self.columns)

    @staticmethod
    def concat(tables: list["Table"]) -> "Table":
        """The rows of ``tables`` (same columns) one after another."""
        if len(tables) == 1:
            return tables[0]
        cols = tables[0].columns
        return Table({c: np.concatenate([t._data[c] for t in tables]) for c in cols})


def arrow_column(name: str, values: np.ndarray) -> pa.Array:
    """One numpy column as a pyarrow Array, built from its buffers: ``pa.array`` of any input
    imports pandas (pyarrow asks whether it is a pandas object), some 0.3 s of a cell job's start
    (issue 22 item 4). Numbers keep their dtype, booleans are bit-packed, text (a ``str`` or an
    object column of ``str`` and missing values) becomes ``large_string``; anything else is
    refused with a TypeError naming the column."""
    a = np.ascontiguousarray(values)
    n = len(a)
    if a.dtype.kind in "fiu":
        return pa.Array.from_buffers(pa.from_numpy_dtype(a.dtype), n, [None, pa.py_buffer(a)])
    if a.dtype.kind == "b":
        return pa.Array.from_buffers(pa.bool_(), n, [None, pa.py_buffer(np.packbits(a, bitorder="little"))])
    if a.dtype.kind in "UO":
        items = a.tolist()
        missing = np.fromiter((is_missing(v) for v in items), bool, n)
        if not all(isinstance(v, str) for v, m in zip(items, missing) if not m):
            raise TypeError(f"column {name!r}: only numbers, booleans and text convert to Arrow")
        data = [b"" if m else v.encode() for v, m in zip(items, missing)]
        offsets = np.zeros(n + 1, np.int64)
        np.cumsum([len(d) for d in data], out=offsets[1:])
        valid = None if not missing.any() else pa.py_buffer(np.packbits(~missing, bitorder="little"))
        return pa.Array.from_buffers(pa.large_string(), n, [valid, pa.py_buffer(offsets), pa.py_buffer(b"".join(data))],
                                     null_count=int(missing.sum()))
    raise TypeError(f"column {name!r}: dtype {a.dtype} does not convert to Arrow (numbers, booleans, text)")
