"""The ``record:`` mapping of a config: a vendor's log read as the rig's record (issue 21).

A config may say which file column fills each of the rig's record columns and in which unit it
is, the same block on every rig::

    record:
      columns: {t: Time_ms, Ax: acc_x}   # <rig column>: <file column>
      units: {t: ms, Ax: m/s^2}          # <rig column>: <unit of the file column>
      ignore_extra: true                 # drop file columns the rig does not read

Units are parsed by ``pint``. ``g`` (and ``mg``, ``ug``) is the rig's gravity unit, not the gram:
1 g = the rig's ``g`` in m/s^2 (9.80665 m/s^2, standard gravity, unless the rig's config sets
another value; each rig's spec says which). A time column may also be ``iso`` (ISO 8601 date-times,
read as seconds since the log's first sample). Every mapped column is converted to the rig's own
unit before the rig's checks run, so a mapped log is refused or accepted exactly as a log written in
the rig's units. Bad mappings are refused (InputError naming ``record.columns.<col>`` or
``record.units.<col>``) before any work: a rig column the rig does not have, a file column the log
does not have, a unit pint does not know, a unit of the wrong dimension, a required column that
neither the log nor the mapping fills.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import pint
import pymap3d

from .errors import InputError
from .lighttable import numeric
from .mapping_keys import ISO_TIME, SCHEMA_PROPERTIES, STANDARD_GRAVITY, with_mapping_schema  # noqa: F401  (platcal.mapping's names)

@lru_cache(maxsize=8)
def registry(g: float) -> pint.UnitRegistry:
    """A pint registry with ``gee`` = ``g`` m/s^2 (cached: building one takes a fraction of a second)."""
    ureg = pint.UnitRegistry()
    ureg.define(f"gee = {g!r} * meter / second ** 2")
    return ureg


_G_TOKEN = re.compile(r"(?<![A-Za-z_])([mu\u00b5]?)g(?![A-Za-z_0-9])")


def pint_unit(ureg: pint.UnitRegistry, text: str, field_: str):
    """The pint unit of ``text`` with ``g``/``mg``/``ug`` as gravity (InputError naming ``field_``)."""
    spelled = _G_TOKEN.sub(lambda m: ("u" if m.group(1) == "\u00b5" else m.group(1)) + "gee", text.strip())
    try:
        unit = ureg.parse_units(spelled)
    except Exception:  # pint raises several types (undefined unit, syntax, tokenizer) for a bad unit
        raise InputError(field_, f"unknown unit {text!r}; use e.g. s, ms, us, {ISO_TIME}, m/s^2, g, mg, ug, deg, "
                         "rad, arcsec, deg/s, rad/s, deg/h, m") from None
    return unit


def conversion_factor(unit: str, native: str, g: float, field_: str) -> float:
    """Factor turning values in ``unit`` into the rig's ``native`` unit; InputError naming
    ``field_`` for an unknown unit or one of another dimension."""
    ureg = registry(float(g))
    have, want = pint_unit(ureg, unit, field_), pint_unit(ureg, native, field_)
    if have.dimensionality != want.dimensionality:
        raise InputError(field_, f"{unit!r} is a unit of {have.dimensionality}, but the column is in {native} "
                         f"({want.dimensionality}); give a unit of that kind")
    return float(ureg.Quantity(1.0, have).to(want).magnitude)


def iso_seconds(values, field_: str, carry: dict | None = None) -> np.ndarray:
    """ISO 8601 date-times (a column of text) as seconds since the first one (InputError naming ``field_``).

    ``carry`` (a chunk of a streamed log, :func:`platcal.records.iter_table`): ``row0`` the file
    row of the chunk's first value (0-based data row), and the log's first stamp under
    ``iso_origin``, set by the first chunk, so every chunk counts from the log's first sample."""
    # pandas parses ISO 8601 in all its forms (offsets, Z, fractions); only a log mapped with
    # iso times loads it, so the read of a plain log (every streamed identify) does not
    import pandas as pd

    carry = {} if carry is None else carry
    values = pd.Series(np.asarray(values))
    stamps = pd.to_datetime(values, errors="coerce", utc=True, format="ISO8601")
    bad = stamps.isna().to_numpy()
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{field_}, row {carry.get('row0', 0) + i + 2}", f"{values.iloc[i]!r} is not an ISO 8601 "
                         "date-time")
    origin = carry.setdefault(f"iso_origin {field_}", stamps.iloc[0])
    ns = (stamps - origin).to_numpy("timedelta64[ns]").astype(np.int64)  # any resolution pandas chose
    return ns * 1e-9


def geodetic_positions(df, geodetic: dict, positions: tuple[str, ...], source: str, carry: dict | None = None):
    """``df`` with its latitude, longitude (and height, m) columns named in ``geodetic`` replaced
    by the local east and north positions ``positions`` (m) from the first sample, on the WGS84
    ellipsoid (pymap3d.geodetic2enu); InputError naming ``record.geodetic.<key>`` for a column
    the log lacks or a value that is not a finite number. ``carry``: as in :func:`iso_seconds`
    (the first sample's latitude, longitude and height under ``geodetic_origin``)."""
    carry = {} if carry is None else carry
    row0 = carry.get("row0", 0)
    cols = [str(c) for c in df.columns]
    deg = geodetic.get("angles", "deg") == "deg"
    values = {}
    for key in ("lat", "lon", "height"):
        if key not in geodetic:
            continue
        src = geodetic[key]
        if src not in cols:
            raise InputError(f"record.geodetic.{key}", f"{source} has no column {src!r}; its columns: {cols}")
        v = numeric(df[src])
        if not np.all(np.isfinite(v)):
            row = int(np.argmax(~np.isfinite(v)))
            raise InputError(f"record.geodetic.{key}, row {row0 + row + 2}", f"value {df[src].iloc[row]!r} of column "
                             f"{src!r} is not a finite number")
        values[key] = v
    lat, lon = values["lat"], values["lon"]
    limit = 90.0 if deg else np.pi / 2
    if np.abs(lat).max() > limit:
        raise InputError("record.geodetic.lat", f"column {geodetic['lat']!r} reaches {np.abs(lat).max():g}, beyond "
                         f"+-{limit:g}: not a latitude in {'deg' if deg else 'rad'} (record.geodetic.angles)")
    h = values.get("height", np.zeros_like(lat))
    lat0, lon0, h0 = carry.setdefault("geodetic_origin", (lat[0], lon[0], h[0]))
    e, n, _ = pymap3d.geodetic2enu(lat, lon, h, lat0, lon0, h0, deg=deg)
    out = df.drop(columns=[geodetic[k] for k in values])
    out[positions[0]], out[positions[1]] = np.asarray(e, float), np.asarray(n, float)
    return out


@dataclass(frozen=True)
class RecordMapping:
    """A config's ``record:`` mapping (:data:`SCHEMA_PROPERTIES`) and the rig's gravity ``g``
    (m/s^2) that converts ``g``, ``mg``, ``ug``."""

    columns: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)
    ignore_extra: bool = False
    g: float = STANDARD_GRAVITY
    kind: str = "samples"
    geodetic: dict = field(default_factory=dict)
    header_lines: int = 0

    @classmethod
    def from_config(cls, record: dict, g: float = STANDARD_GRAVITY) -> "RecordMapping":
        """The mapping of a validated config's ``record`` section."""
        return cls(columns=dict(record.get("columns") or {}), units=dict(record.get("units") or {}),
                   ignore_extra=bool(record.get("ignore_extra", False)), g=float(g),
                   kind=str(record.get("kind", "samples")), geodetic=dict(record.get("geodetic") or {}),
                   header_lines=int(record.get("header_lines", 0)))

    @property
    def empty(self) -> bool:
        return not (self.columns or self.units or self.ignore_extra or self.kind != "samples" or self.geodetic
                    or self.header_lines)

    def check(self, native: dict) -> None:
        """Refuse, before reading any log, a mapping of a column the rig's record does not have,
        an unknown unit or one of the wrong dimension (``native``: the rig's columns and units,
        None for a text column)."""
        for key, what in (("columns", self.columns), ("units", self.units)):
            for col in what:
                if col not in native:
                    raise InputError(f"record.{key}.{col}", f"{col!r} is not a column of this rig's record; its "
                                     f"columns: {list(native)}")
        for col, unit in self.units.items():
            field_ = f"record.units.{col}"
            if native[col] is None:
                raise InputError(field_, f"column {col} is text; it has no unit")
            if unit.strip() == ISO_TIME:
                if native[col] != "s":
                    raise InputError(field_, f"{ISO_TIME!r} (date-times) is a unit of time only; {col} is in {native[col]}")
                continue
            conversion_factor(unit, native[col], self.g, field_)

    def apply(self, df, native: dict, required: tuple[str, ...], source: str = "the log",
              increments: tuple[str, ...] = (), positions: tuple[str, ...] = (), carry: dict | None = None):
        """The log ``df`` (a :class:`platcal.lighttable.Table`) renamed to the rig's columns and converted to its units (``native``:
        rig column -> unit, None for text). Unmapped columns keep their names; with
        ``ignore_extra`` the columns the rig does not read are dropped. A required column that is
        missing afterwards is refused naming ``record.columns.<col>``. ``increments``: the columns
        that ``kind: increments`` turns into increments (none: the rig refuses that kind).
        ``positions``: the rig's east and north position columns (m) a ``geodetic`` mapping fills
        (:func:`geodetic_positions`; none: the rig refuses it). ``carry``: a streamed log's
        state from chunk to chunk (:func:`iso_seconds`), None for a whole log."""
        if self.kind == "increments" and not increments:
            raise InputError("record.kind", "this rig's record has no rate or specific-force columns, so it cannot "
                             "be read from increments; use kind: samples")
        if self.geodetic and not positions:
            raise InputError("record.geodetic", "this rig's record has no position columns, so it cannot be read "
                             "from latitude and longitude; remove record.geodetic")
        self.check(native)
        if self.geodetic:
            df = geodetic_positions(df, self.geodetic, positions, source, carry)
        cols = [str(c) for c in df.columns]
        for col, src in self.columns.items():
            if src not in cols:
                raise InputError(f"record.columns.{col}", f"{source} has no column {src!r}; its columns: {cols}")
        rename = {src: col for col, src in self.columns.items()}
        taken = [c for c in cols if c in native and c not in rename and c in self.columns]
        out = df.drop(columns=taken).rename(columns=rename) if taken else df.rename(columns=rename)
        if self.ignore_extra:
            out = out[[c for c in out.columns if c in native]]
        if not self.empty:
            for col in required:
                if col not in out.columns:
                    raise InputError(f"record.columns.{col}", f"the rig's record needs column {col!r}, which "
                                     f"{source} does not have; map one of its columns {cols} to it")
        for col, unit in self.units.items():
            if col not in out.columns:
                continue
            if unit.strip() == ISO_TIME:
                out[col] = iso_seconds(out[col], f"record.units.{col}", carry)
                continue
            values = numeric(out[col])
            factor = conversion_factor(unit, native[col], self.g, f"record.units.{col}")
            bad = ~np.isfinite(values)
            if bad.any():  # left for the rig's reader to report with its own message
                out[col] = np.where(bad, np.asarray(out[col], dtype=object), values * factor)
            else:
                out[col] = values * factor
        return out
