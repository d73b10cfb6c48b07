"""examples/multiposition (issue 21, item 5): the vendor log made and run through the commands
of its README (inspect, identify, compensate)."""

import json
import runpy
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from platcal.cli import main

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "multiposition"


def test_multiposition_example(tmp_path, monkeypatch, capsys):
    for name in ("config.yaml", "make_log.py"):
        shutil.copy(EXAMPLE / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    runpy.run_path("make_log.py", run_name="__main__")
    assert main(["inspect", "--config", "config.yaml", "--data", "vendor_log.csv"]) == 0
    assert "gaps (> 1.5 steps): 0" in capsys.readouterr().out
    assert main(["identify", "--config", "config.yaml", "--data", "vendor_log.csv", "--scheme", "short",
                 "--out", "id"]) == 0
    assert main(["identify", "--config", "simulated.yaml", "--data", "simulated.csv", "--scheme", "short",
                 "--out", "labelled"]) == 0
    assert main(["compensate", "--calibration", "id/calibration.yaml", "--data", "vendor_log.csv",
                 "--out", "compensated.csv"]) == 0
    summary = json.loads(Path("id/summary.json").read_text())
    assert [d["position"] for d in summary["dwells_found"]] == list(range(1, 9))
    a, b = pd.read_csv("labelled/estimates.csv"), pd.read_csv("id/estimates.csv")
    assert ((a["estimate"] - b["estimate"]).abs() <= 0.1 * a["sigma"]).all()
    assert Path("id/dwells.png").stat().st_size > 0
    skip = yaml.safe_load(open("config.yaml"))["record"].get("header_lines", 0)
    assert len(pd.read_csv("compensated.csv")) == len(pd.read_csv("vendor_log.csv", skiprows=skip))


VENDOR_EXAMPLES = {"centrifuge": ["--scheme", "short"], "sled": [], "lowprec_centrifuge": []}
"""The other rigs' examples (issue 21, item 5): the rig's identify options of their READMEs."""


@pytest.mark.slow
@pytest.mark.parametrize("rig", sorted(VENDOR_EXAMPLES))
def test_vendor_example(tmp_path, monkeypatch, capsys, rig):
    """The README's commands run as written; the vendor log identifies as platcal's own record."""
    example = EXAMPLE.parent / rig
    for name in ("config.yaml", "make_log.py"):
        shutil.copy(example / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    runpy.run_path("make_log.py", run_name="__main__")
    opts = VENDOR_EXAMPLES[rig]
    assert main(["inspect", "--config", "config.yaml", "--data", "vendor_log.csv"]) == 0
    assert "gaps (> 1.5 steps): 0" in capsys.readouterr().out
    assert main(["identify", "--config", "config.yaml", "--data", "vendor_log.csv", *opts, "--out", "id"]) == 0
    assert main(["identify", "--config", "simulated.yaml", "--data", "simulated.csv", *opts,
                 "--out", "labelled"]) == 0
    assert main(["compensate", "--calibration", "id/calibration.yaml", "--data", "vendor_log.csv",
                 "--out", "compensated.csv"]) == 0
    a, b = pd.read_csv("labelled/estimates.csv"), pd.read_csv("id/estimates.csv")
    ok = a["sigma"].notna()
    assert ((a["estimate"] - b["estimate"])[ok].abs() <= 1e-6 * a["sigma"][ok]).all()
    skip = yaml.safe_load(open("config.yaml"))["record"].get("header_lines", 0)
    assert len(pd.read_csv("compensated.csv")) == len(pd.read_csv("vendor_log.csv", skiprows=skip))
