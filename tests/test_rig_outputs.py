"""Every rig probes its output path before any work (issue 13, item 5): exit 2, --out named."""

from pathlib import Path

import pytest

from platcal.cli import main

CONFIG = Path(__file__).resolve().parents[1] / "config"

SIMULATE = {
    "multiposition": ["--scheme", "S8"],
    "sled": [],
    "lowprec_centrifuge": ["--platform", "P1", "--run", "run1"],
}


@pytest.fixture
def blocker(tmp_path):
    """A regular file standing where an output folder's parent should be."""
    f = tmp_path / "not_a_folder"
    f.write_text("x")
    return f


@pytest.mark.parametrize("rig", sorted(SIMULATE))
def test_simulate_refuses_unwritable_out(rig, blocker, capsys):
    cfg = CONFIG / f"{rig}.yaml"
    rc = main(["simulate", "--config", str(cfg), *SIMULATE[rig], "--seed", "0",
               "--out", str(blocker / "rec.csv")])
    assert rc == 2
    assert "--out" in capsys.readouterr().err
    assert blocker.read_text() == "x"


@pytest.mark.parametrize("rig", sorted(SIMULATE))
def test_identify_refuses_unwritable_out_before_reading(rig, blocker, tmp_path, capsys):
    cfg = CONFIG / f"{rig}.yaml"
    rc = main(["identify", "--config", str(cfg), "--data", str(tmp_path / "missing.csv"),
               "--out", str(blocker / "id")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "--out" in err and "missing.csv" not in err
