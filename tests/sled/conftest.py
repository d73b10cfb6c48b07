"""Shared 20-replicate batches of the study's cases (docs/rocket-sled.md §11: 20 seeds), drawn
from the same SeedSequences as the Monte Carlo cells (replicates 0-19)."""

import pytest

from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.identify import identify, metrics
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.simulate import simulate

SEEDS = range(20)


def identify_case(sb, **filter_over):
    cfg = load_config({"rig": "sled", "filter": filter_over})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    return idn, metrics(idn, sb.truth)


@pytest.fixture(scope="session")
def case_runner():
    """``identify_case(batch, **filter_overrides) -> (identification, metrics)``."""
    return identify_case


@pytest.fixture(scope="session")
def batch():
    """20 replicates of the default config (the default case's cell), simulated once."""
    cfg = load_config({"rig": "sled"})
    return simulate(cfg, replicate_seeds(cfg.raw, "default", SEEDS))


@pytest.fixture(scope="session")
def batch_m0():
    """20 replicates with zero accelerometer misalignment (the misalign0_post case's cell)."""
    cfg = load_config({"rig": "sled", "imu": {"accel": {"misalign_arcsec": 0}}})
    return simulate(cfg, replicate_seeds(cfg.raw, "misalign0_post", SEEDS))


@pytest.fixture(scope="session")
def run6(batch):
    return identify_case(batch)


@pytest.fixture(scope="session")
def run7(batch):
    return identify_case(batch, states=7)
