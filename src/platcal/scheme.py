"""Test schemes: ordered platform positions and a dwell time per position.

Shared by the rigs that turn a platform to commanded gimbal positions (docs/centrifuge-model.md
§7, docs/multiposition-1g.md §11). A scheme file is YAML in the config's scheme format::

    schemes:
      table1: {dwell_s: 60, positions: [[45, 0, 167], [350, 0, 325], ...]}

Positions are (alpha, beta, gamma) in degrees. beta at or near +-90 deg is rejected because
the Euler kinematics (docs/centrifuge-model.md eq. 15, the T of docs/multiposition-1g.md §2) are
singular there; a rig with a narrower gimbal range checks it itself.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from .errors import InputError
from .io import atomic_write_text, read_yaml

BETA_MARGIN_DEG = 1.0
"""Closest a position's beta may come to +-90 deg."""

TABLE1_POSITIONS = ((45, 0, 167), (350, 0, 325), (209, 0, 182), (134, 0, 141), (106, 0, 338), (142, 0, 269))
"""The optimal 6-position scheme of Xu & Zhang's Table 1 (docs/centrifuge-model.md §7), deg: the
centrifuge's default scheme and a named scheme the 1 g test compares with (docs/multiposition-1g.md §11)."""

@dataclass(frozen=True)
class Scheme:
    """An ordered list of positions (deg) and the dwell time per position (s)."""

    name: str
    positions: tuple[tuple[float, float, float], ...]
    dwell_s: float
    g_levels: tuple[float, ...] | None = None
    """Specific-force level per position (multi-g-level schemes); None: the rig's own."""

    @property
    def angles_deg(self) -> np.ndarray:
        """(K, 3) commanded alpha, beta, gamma, deg."""
        return np.array(self.positions, dtype=float).reshape(-1, 3)

    @property
    def n_positions(self) -> int:
        return len(self.positions)

    def as_dict(self) -> dict:
        """The config's scheme format (numbers as plain ints where whole)."""
        def num(v: float):
            return int(v) if float(v).is_integer() else float(v)

        out = {"dwell_s": num(self.dwell_s), "positions": [[num(a) for a in p] for p in self.positions]}
        if self.g_levels is not None:
            out["g_levels"] = [num(g) for g in self.g_levels]
        return out


def whole_periods(dwell_s: float, period_s: float, field: str, what: str = "samples") -> int:
    """Number of ``period_s`` periods in a dwell of ``dwell_s`` s: the one check that a dwell is a
    whole number of samples or filter periods (InputError naming ``field`` otherwise)."""
    n = int(round(dwell_s / period_s))
    if n < 1 or abs(n * period_s - dwell_s) > 1e-9 * max(1.0, dwell_s):
        raise InputError(field, f"must be a whole number of {period_s * 1000:g} ms {what}, got {dwell_s:g} s")
    return n


def check_scheme(name: str, spec: dict, where: str = "schemes") -> Scheme:
    """Validate one scheme mapping and return it; raise InputError naming the field."""
    field = f"{where}.{name}"
    if not isinstance(spec, dict):
        raise InputError(field, "must be a mapping with 'dwell_s' and 'positions'")
    extra = set(spec) - {"dwell_s", "positions", "g_levels", "description"}
    if extra:
        raise InputError(f"{field}.{sorted(extra)[0]}", "unknown key; a scheme has 'dwell_s', 'positions' "
                         "and optionally 'g_levels' and 'description'")
    dwell = spec.get("dwell_s")
    if isinstance(dwell, bool) or not isinstance(dwell, (int, float)) or not math.isfinite(dwell) or dwell <= 0:
        raise InputError(f"{field}.dwell_s", f"must be a number > 0 (seconds), got {dwell!r}")
    positions = spec.get("positions")
    if not isinstance(positions, (list, tuple)) or len(positions) == 0:
        raise InputError(f"{field}.positions", "must be a non-empty list of [alpha, beta, gamma] in deg")
    out = []
    for k, p in enumerate(positions, start=1):
        pf = f"{field}.positions[{k}]"
        if (not isinstance(p, (list, tuple)) or len(p) != 3
                or any(isinstance(a, bool) or not isinstance(a, (int, float)) for a in p)):
            raise InputError(pf, f"must be three numbers [alpha, beta, gamma] in deg, got {p!r}")
        if not all(math.isfinite(a) for a in p):
            raise InputError(pf, f"angles must be finite, got {p!r}")
        beta = float(p[1])
        if abs(math.cos(math.radians(beta))) < math.sin(math.radians(BETA_MARGIN_DEG)):
            raise InputError(pf, f"beta = {beta} deg is at or near +-90 deg, where the Euler "
                             f"kinematics are singular; keep |beta| <= {90 - BETA_MARGIN_DEG} deg")
        out.append(tuple(float(a) for a in p))
    levels = spec.get("g_levels")
    if levels is not None:
        if (not isinstance(levels, (list, tuple)) or len(levels) != len(out)
                or any(isinstance(g, bool) or not isinstance(g, (int, float)) or not math.isfinite(g) or g < 0
                       for g in levels)):
            raise InputError(f"{field}.g_levels", f"must be a list of {len(out)} numbers >= 0 "
                             f"(one g-level per position), got {levels!r}")
        levels = tuple(float(g) for g in levels)
    return Scheme(name=name, positions=tuple(out), dwell_s=float(dwell), g_levels=levels)


def load_scheme_file(path: str | os.PathLike) -> dict[str, Scheme]:
    """Read a scheme file (``schemes: {name: {...}}``) and validate every scheme."""
    try:
        data = read_yaml(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(str(path), f"cannot read scheme file: {exc}") from exc
    if not isinstance(data, dict) or not isinstance(data.get("schemes"), dict):
        raise InputError(f"{path}: schemes", "a scheme file is a mapping with a 'schemes' mapping")
    return {n: check_scheme(n, s) for n, s in data["schemes"].items()}


def dump_schemes(schemes: list[Scheme], path: str | os.PathLike, header: str = "") -> None:
    """Write schemes in the config's format (atomically)."""
    text = yaml.safe_dump({"schemes": {s.name: s.as_dict() for s in schemes}}, sort_keys=False,
                          default_flow_style=None)
    atomic_write_text(path, (header + text) if header else text)


def resolve_scheme(name: str, schemes: dict[str, Scheme]) -> Scheme:
    """A scheme by name from the config, or from a scheme file if ``name`` is a path."""
    if name in schemes:
        return schemes[name]
    if name.endswith((".yaml", ".yml")) and Path(name).exists():
        found = load_scheme_file(name)
        if len(found) != 1:
            raise InputError("--scheme", f"{name} holds {len(found)} schemes; name one in the config")
        return next(iter(found.values()))
    raise InputError("--scheme", f"unknown scheme {name!r}; the config defines {sorted(schemes)}")
