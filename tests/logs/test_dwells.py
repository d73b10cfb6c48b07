"""Dwells found, not cut (issue 21, item 3): a continuous multiposition log with slews."""

import json
import runpy
from pathlib import Path

import numpy as np
import pandas as pd

from platcal.cli import main

from .test_record_mapping import MULTIPOSITION, simulated

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "multiposition" / "make_log.py"
continuous = runpy.run_path(str(EXAMPLE))["continuous"]


def test_continuous_log_identifies_as_the_labelled_one(tmp_path):
    cfg, rec = simulated(tmp_path, MULTIPOSITION, "--scheme", "short", "--seed", "6")
    assert main(["identify", "--config", cfg, "--data", str(rec), "--scheme", "short", "--out",
                 str(tmp_path / "a")]) == 0
    log = continuous(pd.read_csv(rec), clock=1234.5, missing=(3,))  # the slew after position 3 not logged
    log.to_csv(tmp_path / "log.csv", index=False)
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "log.csv"), "--scheme", "short", "--out",
                 str(tmp_path / "b")]) == 0
    a = pd.read_csv(tmp_path / "a" / "estimates.csv")
    b = pd.read_csv(tmp_path / "b" / "estimates.csv")
    assert np.all(np.abs(a["estimate"] - b["estimate"]) <= 0.1 * a["sigma"])
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert [d["position"] for d in summary["dwells_found"]] == list(range(1, 9))
    assert all(d["samples"] == 201 for d in summary["dwells_found"])
    assert (tmp_path / "b" / "dwells.png").stat().st_size > 0
