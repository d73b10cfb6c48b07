"""The platform's error model as one object: the coefficients every rig identifies a part of.

The 45 identified coefficients of the gimballed platform (docs/centrifuge-model.md §4-§7: gyro
drift terms DF, DI, DS, DO and the g-squared terms, accelerometer k0, k1, misalignments, k2, k3,
kIP, per axis x, y, z) in their engineering units, grouped ``gyro`` / ``accel``, with the default
truths of the seeds' platform (the truth column of the precision-centrifuge paper's results table,
``model/data/platform_truth.csv``). The
names, order and groups are those of :mod:`platcal.model.instruments`, which the kernels index.

A rig identifies a subset (the centrifuge all 45, the 1 g multi-position test the 24 of its §9
model plus higher-order terms in §13, the low-precision centrifuge the accelerometers' asymmetry
and second order, the sled the attitude and the terms it compensates) and maps its states onto
these names with :meth:`PlatformModel.subset` / :meth:`PlatformModel.index`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from ..lighttable import Table
from ..records import read_frame
from .instruments import INDEX, NAMES, N_FULL, N_IDENTIFIED, group_of


@dataclass(frozen=True)
class PlatformModel:
    """Coefficient ``names``, ``units``, ``groups`` and default ``truth`` (arrays of equal length,
    in the order of :data:`platcal.model.instruments.NAMES`, engineering units)."""

    names: tuple[str, ...]
    units: tuple[str, ...]
    groups: tuple[str, ...]
    truth: np.ndarray

    def index(self, name: str) -> int:
        """Position of coefficient ``name``; KeyError naming it otherwise."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(name) from None

    def subset(self, names) -> "PlatformModel":
        """The coefficients ``names`` (in that order) of this model."""
        idx = [self.index(n) for n in names]
        return PlatformModel(tuple(self.names[i] for i in idx), tuple(self.units[i] for i in idx),
                             tuple(self.groups[i] for i in idx), self.truth[idx].copy())

    def frame(self):
        """One row per coefficient: ``name``, ``unit``, ``group``, ``truth`` (a pandas DataFrame,
        for the tables and reports; through :meth:`platcal.lighttable.Table.to_pandas`, so this
        module loads no pandas for the identify that uses the model)."""
        return Table({"name": list(self.names), "unit": list(self.units), "group": list(self.groups),
                      "truth": self.truth}).to_pandas()

    def full_truth(self, overrides: dict[str, float] | None = None) -> np.ndarray:
        """The instrument model's 48-vector (the 45 and DOO_x/y/z = 0), then ``overrides``
        (KeyError naming an unknown coefficient)."""
        c = np.zeros(N_FULL)
        c[:N_IDENTIFIED] = self.truth
        for name, value in (overrides or {}).items():
            if name not in INDEX:
                raise KeyError(name)
            c[INDEX[name]] = float(value)
        return c


@lru_cache(maxsize=1)
def _truth_table() -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Units and truths of ``data/platform_truth.csv``, read once per process: a config check
    builds the platform for every cell of its study (the centrifuge's: 24 reads, 0.09 s of each
    job's start; issue 22 item 4). Tuples, so no caller can change the cached values."""
    with resources.as_file(resources.files(__package__).joinpath("data/platform_truth.csv")) as path:
        df = read_frame(path, "platcal/model/data/platform_truth.csv", "the platform's truth table")
    if tuple(df["name"]) != NAMES:
        raise RuntimeError("platcal/model/data/platform_truth.csv is not in the instrument model's order")
    return tuple(str(u) for u in df["unit"]), tuple(df["truth"].to_numpy(float).tolist())


def default_platform() -> PlatformModel:
    """The seeds' platform: the 45 coefficients with their default truths (``data/platform_truth.csv``);
    a new model (its own ``truth`` array) at each call."""
    units, truth = _truth_table()
    return PlatformModel(names=NAMES, units=units, groups=tuple(group_of(n) for n in NAMES),
                         truth=np.array(truth, dtype=float))
