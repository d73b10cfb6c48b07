"""The rig's Snakemake study end to end on a tiny config (workflow/rules/lowprec_centrifuge.smk)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(subprocess.run(SNAKEMAKE + ["--version"], capture_output=True).returncode != 0,
                                 reason="snakemake is not installed")]

TINY = {"rig": "lowprec_centrifuge", "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6], "run2": [4, 7]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20},
        "traditional": {"levels_g": [4, 6], "hold_s": 30, "rest_last_s": 10},
        "study": {"seeds": 2, "rate_errors": [], "arm_errors_mm": [], "gross": {}}}


def setup(tmp_path: Path, rigs: bool = True) -> Path:
    d = tmp_path / "wf"
    (d / "workflow" / "rules").mkdir(parents=True)
    (d / "workflow" / "scripts").mkdir()
    (d / "config").mkdir()
    for f in ("common.smk", "lowprec_centrifuge.smk", "report.smk"):  # the one config path; the ledger
        shutil.copy(ROOT / "workflow" / "rules" / f, d / "workflow" / "rules")
    shutil.copytree(ROOT / "workflow" / "schemas", d / "workflow" / "schemas")
    shutil.copytree(ROOT / "workflow" / "report", d / "workflow" / "report")
    for s in [*(ROOT / "workflow" / "scripts").glob("lowprec_*.py"),
              *(ROOT / "workflow" / "scripts" / f for f in ("claims.py", "ledger.py", "report_index.py"))]:
        shutil.copy(s, d / "workflow" / "scripts")
    shutil.copytree(ROOT / "workflow" / "envs", d / "workflow" / "envs")
    (d / "config" / "lp.yaml").write_text(yaml.safe_dump(TINY))
    (d / "config" / "config.yaml").write_text("rigs: {lowprec_centrifuge: %s}\n" % ("config/lp.yaml" if rigs else "null"))
    (d / "Snakefile").write_text('configfile: "config/config.yaml"\n'
                                 'include: "workflow/rules/common.smk"\n'
                                 'include: "workflow/rules/lowprec_centrifuge.smk"\n'
                                 'include: "workflow/rules/report.smk"\n'
                                 'RIG_TARGETS = {"lowprec_centrifuge": LOWPREC_CENTRIFUGE_TARGETS}\n'
                                 "rule all:\n    input: LOWPREC_CENTRIFUGE_TARGETS, LEDGER if RIGS else []\n")
    return d


def smk(d: Path, *args):
    env = dict(os.environ, PYTHONHASHSEED="0")
    return subprocess.run(SNAKEMAKE + list(args), cwd=d, capture_output=True, text=True, env=env, timeout=400)


def test_tiny_study_runs_and_reports(tmp_path):
    d = setup(tmp_path)
    r = smk(d, "--cores", "2")
    assert r.returncode == 0, r.stderr[-3000:]
    res = d / "results" / "lowprec_centrifuge"
    rep = (res / "report.md").read_text()
    for s in ("The paper's claims", "| proposed_effect_velocity |", "figures/velocity_trace.png", "Table-1 analogue"):
        assert s in rep
    ledger = pd.read_csv(res / "claims.csv")
    assert set(ledger["verdict"]) <= {"reproduced", "not reproduced", "inconclusive"}
    row = ledger.set_index("claim").loc["proposed_effect_velocity"]
    # the verdict follows the numbers: the interval against the criterion (>= 75 %)
    assert (row["verdict"] == "reproduced") == (row["ci_low"] >= 75)
    for f in ("effect_vs_imprecision", "velocity_trace", "windows_heading"):
        assert (res / "figures" / f"{f}.png").stat().st_size > 10_000
    cross = pd.read_csv(res / "tables" / "cross_validation.csv")
    assert set(cross["scenario"]) == {"default", "perfect", "worst"}
    assert set(cross["method"]) == {"proposed", "traditional", "truth"}
    assert set(cross["seed"]) == {0, 1}
    assert (res / "logs" / "scenario_default.log").exists()
    # nothing to do the second time
    again = smk(d, "--cores", "1", "-n")
    assert "Nothing to be done" in again.stdout + again.stderr


def test_without_rig_key_no_targets(tmp_path):
    d = setup(tmp_path, rigs=False)
    r = smk(d, "--cores", "1", "-n")
    assert r.returncode == 0, r.stderr[-2000:]


def test_bad_rig_config_stops_before_jobs(tmp_path):
    d = setup(tmp_path)
    (d / "config" / "lp.yaml").write_text(yaml.safe_dump({**TINY, "centrifuge": {"arm_m": -1}}))
    r = smk(d, "--cores", "1")
    assert r.returncode != 0
    assert "centrifuge.arm_m" in r.stderr + r.stdout
    assert not (d / "results").exists()
