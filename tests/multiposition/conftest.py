"""Shared fixtures of the multiposition tests (docs/multiposition-1g.md)."""

import pytest

from platcal.rigs.multiposition.config import load_config


@pytest.fixture(scope="session")
def cfg():
    """The default config: `rig: multiposition` and nothing else (every default of §10)."""
    return load_config({"rig": "multiposition"})
