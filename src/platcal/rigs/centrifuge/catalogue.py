"""The centrifuge's coefficient catalogue: Table 2 of Xu & Zhang (2017) (docs/centrifuge-model.md §7).

The names, units and groups of the 48 coefficients are those of the instrument error model
(:mod:`platcal.model.instruments`); this module adds the paper's truth and results, shipped in
``platcal/rigs/centrifuge/data/table2.csv``.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources

import numpy as np
import pandas as pd

from ...model.instruments import INDEX, NAMES, N_FULL, N_IDENTIFIED, group_of


@dataclass(frozen=True)
class Catalogue:
    """The 45 coefficients with names, units, groups, truth defaults and the paper's results.

    ``truth``, ``paper_estimate``, ``paper_error`` and ``paper_rel_err_pct`` are arrays of 45 in
    Table 2's order and units.
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    groups: tuple[str, ...]
    truth: np.ndarray
    paper_estimate: np.ndarray
    paper_error: np.ndarray
    paper_rel_err_pct: np.ndarray

    def frame(self) -> pd.DataFrame:
        """The catalogue as a table, one row per coefficient."""
        return pd.DataFrame(
            {
                "name": self.names,
                "unit": self.units,
                "group": self.groups,
                "truth": self.truth,
                "paper_estimate": self.paper_estimate,
                "paper_error": self.paper_error,
                "paper_rel_err_pct": self.paper_rel_err_pct,
            }
        )


def load_catalogue() -> Catalogue:
    """Read Table 2 of the paper (shipped in ``platcal/rigs/centrifuge/data/table2.csv``) into a Catalogue."""
    with resources.files(__package__).joinpath("data/table2.csv").open() as fh:
        df = pd.read_csv(fh)
    if tuple(df["name"]) != NAMES:
        raise RuntimeError("platcal/rigs/centrifuge/data/table2.csv is not in Table 2's order")
    return Catalogue(
        names=NAMES,
        units=tuple(df["unit"]),
        groups=tuple(group_of(n) for n in NAMES),
        truth=df["truth"].to_numpy(float),
        paper_estimate=df["paper_estimate"].to_numpy(float),
        paper_error=df["paper_error"].to_numpy(float),
        paper_rel_err_pct=df["paper_rel_err_pct"].to_numpy(float),
    )


def full_truth(overrides: dict[str, float] | None = None) -> np.ndarray:
    """The 48-vector of true coefficients: Table 2's truth, DOO = 0, then ``overrides``.

    Raises ``KeyError`` naming an unknown coefficient.
    """
    c = np.zeros(N_FULL)
    c[:N_IDENTIFIED] = load_catalogue().truth
    for name, value in (overrides or {}).items():
        if name not in INDEX:
            raise KeyError(name)
        c[INDEX[name]] = float(value)
    return c
