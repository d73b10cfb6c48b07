"""The centrifuge's coefficient catalogue: Table 2 of Xu & Zhang (2017) (docs/centrifuge-model.md §7).

The names, units, groups and truths of the 45 coefficients are the shared platform model's
(:mod:`platcal.model.platform`); this module adds the paper's results, shipped in
``platcal/rigs/centrifuge/data/table2.csv``.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources

import numpy as np

from ...lighttable import Table
from ...model.platform import default_platform
from ...records import read_frame


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

    def frame(self):
        """The catalogue as a pandas DataFrame, one row per coefficient (for the tables and
        reports; through :meth:`platcal.lighttable.Table.to_pandas`, so an identify that loads the
        catalogue loads no pandas)."""
        return Table(
            {
                "name": list(self.names),
                "unit": list(self.units),
                "group": list(self.groups),
                "truth": self.truth,
                "paper_estimate": self.paper_estimate,
                "paper_error": self.paper_error,
                "paper_rel_err_pct": self.paper_rel_err_pct,
            }
        ).to_pandas()


def load_catalogue() -> Catalogue:
    """The platform model (:func:`platcal.model.platform.default_platform`: names, units, groups,
    truth) with the paper's Table 2 results (``platcal/rigs/centrifuge/data/table2.csv``)."""
    platform = default_platform()
    with resources.as_file(resources.files(__package__).joinpath("data/table2.csv")) as path:
        df = read_frame(path, "platcal/rigs/centrifuge/data/table2.csv", "Table 2 of the paper")
    if tuple(df["name"]) != platform.names:
        raise RuntimeError("platcal/rigs/centrifuge/data/table2.csv is not in Table 2's order")
    return Catalogue(
        names=platform.names,
        units=platform.units,
        groups=platform.groups,
        truth=platform.truth,
        paper_estimate=df["paper_estimate"].to_numpy(float),
        paper_error=df["paper_error"].to_numpy(float),
        paper_rel_err_pct=df["paper_rel_err_pct"].to_numpy(float),
    )


def full_truth(overrides: dict[str, float] | None = None) -> np.ndarray:
    """The 48-vector of true coefficients: Table 2's truth, DOO = 0, then ``overrides``.

    Raises ``KeyError`` naming an unknown coefficient.
    """
    return default_platform().full_truth(overrides)
