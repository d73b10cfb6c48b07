"""The sled study's rules in a minimal Snakefile, on a tiny config (slow: ~30 s)."""

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(subprocess.run(SNAKEMAKE + ["--version"], capture_output=True).returncode != 0,
                                 reason="snakemake is not installed")]

SNAKEFILE = """\
configfile: "config/config.yaml"

include: "workflow/rules/common.smk"
include: "workflow/rules/sled.smk"

rule all:
    input: SLED_TARGETS
"""


def run(d: Path, *args, timeout=240):
    env = dict(os.environ, PYTHONHASHSEED="0")
    p = subprocess.Popen(SNAKEMAKE + list(args), cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=env, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        raise
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def make(tmp_path: Path, sled_yaml: str) -> Path:
    d = tmp_path / "wf"
    (d / "workflow" / "rules").mkdir(parents=True)
    (d / "config").mkdir()
    for f in ("common.smk", "sled.smk"):  # common.smk: the one config path (RAW, checked)
        shutil.copy(ROOT / "workflow" / "rules" / f, d / "workflow" / "rules")
    shutil.copytree(ROOT / "workflow" / "schemas", d / "workflow" / "schemas")
    shutil.copytree(ROOT / "workflow" / "scripts", d / "workflow" / "scripts",
                    ignore=lambda _, names: [n for n in names if not n.startswith("sled_")])
    shutil.copytree(ROOT / "workflow" / "envs", d / "workflow" / "envs")
    (d / "Snakefile").write_text(SNAKEFILE)
    (d / "config" / "config.yaml").write_text("rigs: {sled: config/sled.yaml}\n")
    (d / "config" / "sled.yaml").write_text(sled_yaml)
    return d


def test_sled_study_end_to_end(tmp_path):
    d = make(tmp_path, "rig: sled\ntrajectory: {static_after_s: 10}\n"
                       "study: {seeds: 2, cases: [default, run7]}\n")
    r = run(d, "--cores", "2")
    assert r.returncode == 0, r.stderr[-3000:]
    res = d / "results" / "sled"
    report = (res / "report.md").read_text()
    assert "Table-1 analogue" in report and "figures/x_error.png" in report
    for name in ("yz_before_after.png", "x_error.png", "attitude.png"):
        assert (res / "figures" / name).stat().st_size > 10_000
    m = pd.read_csv(res / "cases" / "run7" / "metrics.csv")
    assert list(m.seed) == [0, 1] and m.y_after_b_max_run_cm.max() < 6
    ranks = pd.read_csv(res / "rank_table.csv", dtype=str, keep_default_na=False)
    assert ranks.iloc[0]["static"] == "5/7"
    assert (d / "results" / "logs" / "sled" / "case_default.log").read_text().strip()
    # nothing left to do: a second run is a no-op
    r2 = run(d, "--cores", "1", "-n")
    assert "Nothing to be done" in r2.stdout + r2.stderr


def test_sled_study_bad_config_stops_before_any_job(tmp_path):
    d = make(tmp_path, "rig: sled\ntrajectory: {brake_g: 0}\n")
    r = run(d, "--cores", "1", timeout=120)
    assert r.returncode != 0
    assert "trajectory.brake_g" in r.stdout + r.stderr
    assert not (d / "results").exists()


def test_no_sled_key_no_targets(tmp_path):
    d = make(tmp_path, "rig: sled\n")
    (d / "config" / "config.yaml").write_text("rigs: {sled: null}\n")
    r = run(d, "--cores", "1", "-n", timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
