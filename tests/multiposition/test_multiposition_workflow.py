"""The multiposition rules on a tiny config, in a temporary copy (results/ never touched)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
SNAKEFILE = """configfile: "config/config.yaml"
include: "workflow/rules/common.smk"
include: "workflow/rules/montecarlo.smk"
include: "workflow/rules/multiposition.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/report.smk"
RIG_TARGETS = {"multiposition": MULTIPOSITION_TARGETS}
rule all:
    input: MULTIPOSITION_TARGETS
"""
TINY = """rig: multiposition
schemes:
  TET4: {dwell_s: 6, positions: [[0, 0, 0], [109.47, 0, 0], [109.47, 0, 120], [109.47, 0, 240]]}
design: {positions: [4], grid_deg: 90, population: 6, generations: 2, info_step_s: 2, dwell_s: 6}
extension: {random_positions: 10, dwell_s: 6}
study: {seeds: 2, schemes: [TET4, GA], rank_schemes: [TET4, ROLL4], sigma_a_ug: [5], estimators: {ekf1: {estimator: ekf}, iekf: {estimator: iekf}}}
"""


def _tree(tmp_path: Path) -> Path:
    d = tmp_path / "wf"
    (d / "workflow/rules").mkdir(parents=True)
    (d / "workflow/scripts").mkdir(parents=True)
    (d / "config").mkdir()
    # the rig's own rules, the generic Monte Carlo and the ledger's (the report opens on claims.csv);
    # campaign.smk defines no job without a campaign but the index reads its targets
    for rules in ("common", "montecarlo", "multiposition", "campaign", "report"):
        shutil.copy(ROOT / f"workflow/rules/{rules}.smk", d / "workflow/rules")
    shutil.copytree(ROOT / "workflow/envs", d / "workflow/envs")
    shutil.copytree(ROOT / "workflow/report", d / "workflow/report")
    shutil.copytree(ROOT / "workflow/schemas", d / "workflow/schemas")
    for p in [*(ROOT / "workflow/scripts").glob("multiposition_*.py"), ROOT / "workflow/scripts/montecarlo_cell.py",
              ROOT / "workflow/scripts/kernels.py",
              ROOT / "workflow/scripts/collect.py", ROOT / "workflow/scripts/claims.py"]:
        shutil.copy(p, d / "workflow/scripts")
    (d / "Snakefile").write_text(SNAKEFILE)
    (d / "config/config.yaml").write_text("rigs: {multiposition: config/multiposition.yaml}\n")
    (d / "config/multiposition.yaml").write_text(TINY)
    return d


@pytest.mark.slow
def test_tiny_study_end_to_end(tmp_path):
    pytest.importorskip("snakemake")
    d = _tree(tmp_path)
    env = dict(os.environ, PYTHONHASHSEED="0")
    r = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "--quiet"], cwd=d, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    res = d / "results/multiposition"
    report = (res / "report.md").read_text()
    assert "## Scheme check" in report and "figures/ranks.png" in report
    # the report opens on the rig's ledger rows, as the claims rule wrote them
    claims = pd.read_csv(res / "claims.csv").set_index("claim")
    assert report.index("## Claims") < report.index("## Scheme check")
    assert claims.loc["refuse_roll4", "measured"] == 0 and "| refuse_roll4 |" in report
    assert claims.loc["accept_s8", "verdict"] == "inconclusive"  # S8 is not in this study's rank_schemes
    assert (res / "figures/extension_draws.png").stat().st_size > 0
    ranks = pd.read_csv(res / "tables/ranks.csv").set_index("scheme")
    assert ranks.loc["ROLL4", "verdict"] == "refuse" and ranks.loc["ROLL4", "static rank"] == 21
    summ = pd.read_csv(res / "tables/montecarlo_summary.csv")
    assert set(summ["scheme"]) == {"TET4", "GA"} and set(summ["estimator"]) == {"ekf1", "iekf"}
    # a code-free rerun does nothing
    r2 = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "2", "-n"], cwd=d, env=env,
                        capture_output=True, text=True, timeout=300)
    assert "Nothing to be done" in r2.stdout + r2.stderr


def test_no_rig_key_defines_no_targets(tmp_path):
    pytest.importorskip("snakemake")
    d = _tree(tmp_path)
    (d / "config/config.yaml").write_text("rigs: {multiposition: null}\n")
    r = subprocess.run([sys.executable, "-m", "snakemake", "--cores", "1", "-n"], cwd=d,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    lint = subprocess.run([sys.executable, "-m", "snakemake", "--lint"], cwd=d, capture_output=True, text=True,
                          timeout=300)
    assert "Congratulations" in lint.stdout + lint.stderr, (lint.stdout + lint.stderr)[-2000:]
