"""The rig's Snakemake study on a tiny config, in a temporary copy of the workflow (results/ never
touched): the generic Monte Carlo cells, the rig's trace and report rules, staleness (an edited
value reruns exactly its dependent jobs, a comment nothing) and the inline config form."""

import re
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml
from workflow_copy import copy_workflow, needs_snakemake, snakemake

OTHERS = ("centrifuge", "multiposition", "sled")

pytestmark = [pytest.mark.slow,
              needs_snakemake]

TINY = {"rig": "lowprec_centrifuge", "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6], "run2": [4, 7]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20},
        "traditional": {"levels_g": [4, 6], "hold_s": 30, "rest_last_s": 10},
        "study": {"seeds": 2, "rate_errors": [], "arm_errors_mm": [], "gross": {}}}
TINY_TEXT = "# the tiny study\n" + yaml.safe_dump(TINY)


def setup(tmp_path: Path, rigs: bool = True, inline: bool = False) -> Path:
    """A copy of the whole workflow whose index names this rig alone (path or inline) or no rig."""
    d = copy_workflow(tmp_path / "wf")
    (d / "config" / "lp.yaml").write_text(TINY_TEXT)
    entry = (TINY if inline else "config/lp.yaml") if rigs else None
    (d / "config" / "config.yaml").write_text(yaml.safe_dump({"rigs": {**{r: None for r in OTHERS},
                                                                        "lowprec_centrifuge": entry}}))
    return d


def smk(d: Path, *args):
    return snakemake(d, *args, timeout=600)


def dry(d: Path) -> str:
    r = smk(d, "-n", "--cores", "1")
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stdout + r.stderr


def jobs(out: str) -> dict:
    """Job counts by rule from the ``snakemake -n`` job table; {} when nothing is to be done."""
    if "Nothing to be done" in out:
        return {}
    table = out.split("Job stats:")[-1].split("Reasons:")[0] if "Job stats:" in out else ""
    counts = {}
    for line in table.splitlines():
        parts = line.split()
        if (len(parts) == 2 and parts[1].isdigit() and parts[0] not in ("job", "total")
                and not parts[0].endswith(":")):
            counts[parts[0]] = int(parts[1])
    return counts


def edit(d: Path, **changes) -> None:
    cfg = yaml.safe_load((d / "config" / "lp.yaml").read_text())
    for path, value in changes.items():
        node = cfg
        keys = path.split("__")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    (d / "config" / "lp.yaml").write_text(yaml.safe_dump(cfg))


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """A finished tiny study (path form)."""
    d = setup(tmp_path_factory.mktemp("lp"))
    r = smk(d, "--cores", "2")
    assert r.returncode == 0, r.stderr[-3000:]
    return d


AFTER = {"claims": 1, "ledger": 1, "report_index": 1, "all": 1}
"""The jobs after the rig's report: its ledger rows, the ledger, the index report."""


def test_tiny_study_runs_and_reports(done):
    res = done / "results" / "lowprec_centrifuge"
    rep = (res / "report.md").read_text()
    for s in ("The paper's claims", "| proposed_effect_velocity |", "Spec §11 checks", "figures/velocity_trace.png",
              "Table-1 analogue"):
        assert s in rep
    ledger = pd.read_csv(res / "claims.csv")
    assert set(ledger["verdict"]) <= {"reproduced", "not reproduced", "inconclusive"}
    row = ledger.set_index("claim").loc["proposed_effect_velocity"]
    # the verdict follows the numbers: the interval against the criterion (>= 75 %)
    assert (row["verdict"] == "reproduced") == (row["ci_low"] >= 75)
    assert (done / "results" / "claims.csv").exists()
    for f in ("effect_vs_imprecision", "velocity_trace", "windows_heading"):
        assert (res / "figures" / f"{f}.png").stat().st_size > 10_000
    cross = pd.read_csv(res / "tables" / "cross_validation.csv")
    assert set(cross["scenario"]) == {"default", "perfect", "worst"}
    assert set(cross["method"]) == {"proposed", "traditional", "truth"}
    assert set(cross["seed"]) == {0, 1}
    runs = pd.read_parquet(res / "montecarlo" / "runs.parquet")
    assert set(runs["scheme"]) == {"default", "perfect", "worst"}
    assert set(runs["estimator"]) == {"proposed", "traditional"}
    assert (res / "logs" / "montecarlo" / "default_noise10.log").exists()
    assert not (res / "scenarios").exists()    # the rig's former own loop is gone
    assert "Nothing to be done" in dry(done)


def test_editing_a_value_reruns_its_jobs_and_a_comment_nothing(done, tmp_path):
    d = tmp_path / "wf"
    shutil.copytree(done, d, symlinks=True)
    # a comment: nothing
    (d / "config" / "lp.yaml").write_text("# another comment\n" + (d / "config" / "lp.yaml").read_text())
    assert jobs(dry(d)) == {}
    text = (d / "config" / "lp.yaml").read_text()
    edit(d, residuals__k0_ug=25)      # every cell (every scenario, both methods), the trace, the report
    assert jobs(dry(d)) == {"montecarlo_cell": 3, "collect": 1, "lowprec_trace": 1, "lowprec_report": 1, **AFTER}
    (d / "config" / "lp.yaml").write_text(text)
    edit(d, platforms__P1__kA_x=-41)
    assert jobs(dry(d)) == {"montecarlo_cell": 3, "collect": 1, "lowprec_trace": 1, "lowprec_report": 1, **AFTER}
    (d / "config" / "lp.yaml").write_text(text)
    # the default scenario's rate: default and the scenarios that keep the default rate (not perfect, worst)
    edit(d, centrifuge__rate_error=4e-4)
    assert jobs(dry(d)) == {"montecarlo_cell": 1, "collect": 1, "lowprec_trace": 1, "lowprec_report": 1, **AFTER}
    (d / "config" / "lp.yaml").write_text(text)
    # the traditional method's profile: every scenario's cell (a cell runs both methods on its
    # data: the proposed one reruns with it, its numbers unchanged), the trace, the report
    edit(d, traditional__hold_s=31)
    out = dry(d)
    assert jobs(out) == {"montecarlo_cell": 3, "collect": 1, "lowprec_trace": 1, "lowprec_report": 1, **AFTER}
    cells = [o for o in re.findall(r"output: (\S+)", out) if "/runs/" in o]   # the cells' folders
    assert sorted(cells) == [f"results/lowprec_centrifuge/runs/{s}/noise10" for s in ("default", "perfect", "worst")]


def test_inline_config_gives_the_same_jobs_as_the_path(tmp_path):
    a = setup(tmp_path / "a")
    b = setup(tmp_path / "b", inline=True)
    ja, jb = dry(a), dry(b)
    assert jobs(ja) == jobs(jb) and jobs(ja)["montecarlo_cell"] == 3
    outs = [sorted(re.findall(r"output: (\S+)", j)) for j in (ja, jb)]
    assert outs[0] == outs[1]


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
