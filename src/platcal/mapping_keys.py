"""The ``record:`` mapping's config keys and constants (:mod:`platcal.mapping`), apart from the
pint and pymap3d that reading a mapped log needs: every rig's config schema holds these keys, and a
job that only checks a config (a Monte Carlo cell) does not load pint (issue 22 item 4)."""

from __future__ import annotations

STANDARD_GRAVITY = 9.80665
"""m/s^2: the value of the unit ``g`` unless a rig passes its own."""
ISO_TIME = "iso"
"""Unit of a time column written as ISO 8601 date-times."""

SCHEMA_PROPERTIES = {
    "columns": {"type": "object", "default": {}, "additionalProperties": {"type": "string"},
                "description": "which column of the log fills each of the rig's record columns: "
                               "{<rig column>: <file column>}; unmapped columns keep their names"},
    "units": {"type": "object", "default": {}, "additionalProperties": {"type": "string"},
              "description": "unit of each rig column in the log, parsed by pint ({<rig column>: <unit>}, e.g. "
                             "ms, us, iso, m/s^2, g, mg, ug, rad, arcsec, deg/h, rad/s); g is the rig's gravity"},
    "ignore_extra": {"type": "boolean", "default": False,
                     "description": "drop columns of the log that the rig does not read (else they are refused)"},
    "kind": {"type": "string", "enum": ["samples", "increments"], "default": "samples",
             "description": "increments: the rate and specific-force columns hold delta-theta and delta-v per "
                            "sample (platcal.logs.increments); only for a rig whose record has such columns"},
    "geodetic": {"type": "object", "additionalProperties": False, "required": ["lat", "lon"],
                 "properties": {"lat": {"type": "string"}, "lon": {"type": "string"}, "height": {"type": "string"},
                                "angles": {"type": "string", "enum": ["deg", "rad"], "default": "deg"}},
                 "description": "the log's latitude, longitude (and height, m) columns, converted to the rig's "
                                "local east/north positions from the first sample (WGS84, pymap3d); only for "
                                "a rig whose record holds positions"},
    "header_lines": {"type": "integer", "minimum": 0, "maximum": 10000, "default": 0,
                     "description": "lines of a logger's metadata above the column header of a CSV log, "
                                    "skipped (line numbers in messages still count them)"},
}
"""The ``record:`` keys every rig's config schema holds (:func:`with_mapping_schema`)."""


def with_mapping_schema(schema: dict) -> dict:
    """``schema`` (a rig's config schema, modified in place and returned) with the shared
    mapping keys :data:`SCHEMA_PROPERTIES` in its ``record`` section."""
    record = schema["properties"].setdefault("record", {"type": "object", "additionalProperties": False,
                                                        "default": {}, "properties": {}})
    record.setdefault("properties", {}).update(SCHEMA_PROPERTIES)
    return schema
