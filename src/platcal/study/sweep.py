"""The Monte Carlo sweep's keys and a rig's hook defaults, without the runner's tables (issue 22
item 3): a rig's ``identify`` draws its replicate's SeedSequence and registers its hooks through
this module, so it does not import the runner (:mod:`platcal.study.montecarlo`) and pandas with it.
The seeding is the runner's (its module docstring, "Seeding"): replicate r of case C at noise
level v draws from ``SeedSequence(seed, spawn_key=(stable_key(C), noise_key(v), r))``.
"""

from __future__ import annotations

import numpy as np

from ..rig import RunSettings
from ..seeding import seed_sequence


def noise_key(level: float) -> int:
    """Key of a noise level: the level in thousandths of its unit, rounded (5 -> 5000)."""
    return int(round(float(level) * 1000.0))


def noise_label(level: float) -> str:
    """File-name label of a noise level (``10`` -> ``'10'``, ``2.5`` -> ``'2.5'``)."""
    return f"{float(level):g}"


def replicate_seed(seed: int, case: str, level: float, replicate: int) -> np.random.SeedSequence:
    """The SeedSequence of one replicate of one (case, noise level) cell."""
    return seed_sequence(seed, case, noise_key(level), int(replicate))


class StudySectionHooks:
    """Defaults of :class:`~platcal.rig.MonteCarloHooks` for a rig whose config's ``study``
    section holds the sweep: the noise levels in ``study.<noise.name>`` (the rig's
    :class:`~platcal.rig.NoiseAxis`), the estimators in ``study.estimators``, the replicates per
    cell in ``study.<replicates_key>`` and the speed knobs ``study.batch``, ``backend``,
    ``threads``; the root seed is the config's ``seed``. A rig subclasses it and adds the rest."""

    replicates_key = "replicates"

    def noise_levels(self, cfg: dict) -> list[float]:
        return [float(v) for v in cfg["study"][self.noise.name]]

    def estimators(self, cfg: dict) -> list[str]:
        return list(cfg["study"]["estimators"])

    def settings(self, cfg: dict) -> RunSettings:
        st = cfg["study"]
        return RunSettings(seed=int(cfg["seed"]), replicates=int(st[self.replicates_key]), batch=int(st["batch"]),
                           backend=st["backend"], threads=int(st["threads"]))
