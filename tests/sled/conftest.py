"""Shared 20-seed batches of the default scenario (docs/rocket-sled.md §11: seeds 0-19)."""

import pytest

from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.identify import identify, metrics
from platcal.rigs.sled.simulate import simulate

SEEDS = range(20)


def run_case(sb, **filter_over):
    cfg = load_config({"rig": "sled", "filter": filter_over})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    return idn, metrics(idn, sb.truth)


@pytest.fixture(scope="session")
def case_runner():
    """``run_case(batch, **filter_overrides) -> (identification, metrics)``."""
    return run_case


@pytest.fixture(scope="session")
def batch():
    """20 seeds of the default config, simulated once."""
    return simulate(load_config({"rig": "sled"}), SEEDS)


@pytest.fixture(scope="session")
def batch_m0():
    """20 seeds with zero accelerometer misalignment."""
    return simulate(load_config({"rig": "sled", "imu": {"accel": {"misalign_arcsec": 0}}}), SEEDS)


@pytest.fixture(scope="session")
def run6(batch):
    return run_case(batch)


@pytest.fixture(scope="session")
def run7(batch):
    return run_case(batch, states=7)
