"""The calibration an identification writes and ``platcal compensate`` applies (issue 21, item 2).

``calibration.yaml`` holds everything needed to apply an identification to another log and to
trace it back: the rig, the model version (the rig's spec file and platcal's version), the
coefficient names, units, values and full covariance (rows and columns in the order of the
names), the SHA-256 of the log it was identified from and the config used (validated, every
default filled). It is plain YAML (numbers as floats, no tags), read back by
:func:`read_calibration`; a bad file is refused naming ``--calibration`` and the key.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .. import __version__
from ..errors import InputError
from ..io import json_safe, read_config, write_csv

KEYS = ("rig", "model_version", "names", "units", "values", "covariance", "log_sha256", "config")


@dataclass(frozen=True)
class Calibration:
    """An identification as applied: ``values`` (n,) in ``units``, ``covariance`` (n, n) in
    those units squared, in the order of ``names``."""

    rig: str
    model_version: str
    names: list
    units: list
    values: np.ndarray
    covariance: np.ndarray
    log_sha256: str
    config: dict

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    def value(self, name: str) -> float:
        return float(self.values[self.names.index(name)])

    def as_dict(self) -> dict:
        return {"rig": self.rig, "model_version": self.model_version, "names": list(self.names),
                "units": list(self.units), "values": [float(v) for v in self.values],
                "covariance": [[float(v) for v in row] for row in np.asarray(self.covariance)],
                "log_sha256": self.log_sha256, "config": json_safe(self.config)}

    def text(self) -> str:
        """The YAML text of ``calibration.yaml`` (floats written exactly: repr round-trips)."""
        return yaml.safe_dump(self.as_dict(), sort_keys=False, width=1000)


def model_version(spec: str) -> str:
    """The model a calibration belongs to: the rig's spec file and platcal's version."""
    return f"docs/{spec} (platcal {__version__})"


def sha256_file(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_covariance(path, names, P) -> None:
    """``covariance.csv`` at ``path``: the covariance (units squared) with the names as row
    (``state``) and column labels, the text pandas' ``to_csv`` wrote (written without it by
    :func:`platcal.io.write_csv`: an identify loads no pandas)."""
    P = np.asarray(P)
    write_csv(path, {n: P[:, i] for i, n in enumerate(names)}, index=("state", list(names)))


def read_calibration(path: str | os.PathLike, field: str = "--calibration") -> Calibration:
    """A ``calibration.yaml`` read back; InputError naming ``field`` (and the key) otherwise."""
    path = Path(path)
    raw = read_config(path, field)
    if not isinstance(raw, dict):
        raise InputError(field, f"{path} is not a calibration file (a YAML mapping written by platcal identify)")
    missing = [k for k in KEYS if k not in raw]
    if missing:
        raise InputError(f"{field} key {missing[0]}", f"missing; a calibration file has {list(KEYS)}")
    names, units = list(raw["names"] or []), list(raw["units"] or [])
    try:
        values = np.asarray(raw["values"], dtype=float)
        cov = np.asarray(raw["covariance"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{field} key values", "values and covariance must be numbers") from None
    n = len(names)
    if len(units) != n or values.shape != (n,):
        raise InputError(f"{field} key values", f"{n} names but {len(units)} units and {values.size} values")
    if cov.shape != (n, n):
        raise InputError(f"{field} key covariance", f"must be {n} x {n} (one row per name), got {cov.shape}")
    if not np.all(np.isfinite(values)):
        raise InputError(f"{field} key values", "must be finite numbers")
    if not isinstance(raw["config"], dict):
        raise InputError(f"{field} key config", "must be the config mapping the identification used")
    return Calibration(rig=str(raw["rig"]), model_version=str(raw["model_version"]), names=names, units=units,
                       values=values, covariance=cov, log_sha256=str(raw["log_sha256"]), config=raw["config"])


def calibration_of(rig: str, spec: str, names, units, values, covariance, log_path, config: dict) -> Calibration:
    """The :class:`Calibration` of an identification of the log at ``log_path`` (hashed here)."""
    return Calibration(rig=rig, model_version=model_version(spec), names=list(names), units=list(units),
                       values=np.asarray(values, float), covariance=np.asarray(covariance, float),
                       log_sha256=sha256_file(log_path), config=config)


def write_calibration_files(tmp, cal: Calibration, covariance: bool = True) -> None:
    """``calibration.yaml`` (and ``covariance.csv`` with the names) into an
    :func:`platcal.io.atomic_files` block (``tmp(name) -> Path``)."""
    tmp("calibration.yaml").write_text(cal.text())
    if covariance:
        write_covariance(tmp("covariance.csv"), cal.names, cal.covariance)


def calibration_values(cal: Calibration, names, rig: str) -> np.ndarray:
    """The calibration's values in the order of ``names`` (the rig's model); InputError naming
    ``--calibration`` when it is another rig's or lacks a name."""
    if cal.rig != rig:
        raise InputError("--calibration", f"is a calibration of rig {cal.rig!r}, not {rig!r}")
    missing = [n for n in names if n not in cal.names]
    if missing:
        raise InputError("--calibration key names", f"lacks {missing[0]!r}; the {rig} model needs {list(names)}")
    return np.array([cal.value(n) for n in names])
