"""The sled study through the whole Snakefile (generic Monte Carlo cells + the sled's own rules),
on the tiny sled part of config/test.yaml (slow: about a minute)."""

import re
from pathlib import Path

import pandas as pd
import pytest
import yaml
from workflow_copy import ROOT, copy_workflow, needs_snakemake
from workflow_copy import snakemake as run

OTHERS = ("centrifuge", "multiposition", "lowprec_centrifuge")

pytestmark = [pytest.mark.slow, needs_snakemake]


def tiny_sled() -> dict:
    """The sled part of config/test.yaml (an inline mapping)."""
    return yaml.safe_load((ROOT / "config" / "test.yaml").read_text())["rigs"]["sled"]


def index(d: Path, sled) -> None:
    """The study index with the sled alone: ``sled`` is a path or an inline mapping."""
    (d / "config" / "config.yaml").write_text(yaml.safe_dump({"rigs": {**{r: None for r in OTHERS}, "sled": sled}}))


def make(tmp_path: Path, sled_yaml: str) -> Path:
    """A copy of the workflow whose index names config/sled.yaml, holding ``sled_yaml``."""
    d = copy_workflow(tmp_path / "wf")
    (d / "config" / "sled.yaml").write_text(sled_yaml)
    index(d, "config/sled.yaml")
    return d


def jobs(d: Path, *extra) -> dict[str, int]:
    """Jobs ``snakemake -n`` would run, by rule."""
    r = run(d, "--cores", "1", "-n", "--quiet", "rules", *extra)
    assert r.returncode == 0, r.stderr[-3000:]
    text = r.stdout + r.stderr
    return {m[1]: int(m[2]) for m in re.finditer(r"^(\w+)\s+(\d+)$", text, re.M) if m[1] != "total"}


def job_outputs(d: Path) -> list[str]:
    """Every output file of the jobs ``snakemake -n`` lists (the job list, wildcards resolved)."""
    r = run(d, "--cores", "1", "-n")
    assert r.returncode == 0, r.stderr[-3000:]
    return sorted(re.findall(r"^\s+output: (.+)$", r.stdout + r.stderr, re.M))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """The tiny sled study, run once (path form of the index)."""
    d = make(tmp_path_factory.mktemp("sled"), yaml.safe_dump(tiny_sled()))
    r = run(d, "--cores", "2")
    assert r.returncode == 0, r.stderr[-3000:]
    return d


def test_sled_study_end_to_end(study):
    res = study / "results" / "sled"
    report = (res / "report.md").read_text()
    assert "Table-1 analogue" in report and "figures/x_error.png" in report
    # the report opens on the rig's ledger rows, as the claims rule wrote them to claims.csv
    claims = pd.read_csv(res / "claims.csv").set_index("claim")
    assert report.index("## Claims") < report.index("## Cases")
    assert "| lateral_metric_b_7 |" in report and claims.loc["lateral_metric_b_7", "settings"] == "case run7, 2 replicates"
    for name in ("yz_before_after.png", "x_error.png", "attitude.png"):
        assert (res / "figures" / name).stat().st_size > 10_000
    runs = pd.read_parquet(res / "montecarlo" / "runs.parquet")
    cases = tiny_sled()["study"]["cases"]
    assert sorted(runs.scheme.unique()) == sorted(cases)
    assert runs.groupby("scheme").replicate.apply(list).to_dict() == {c: [0, 1] for c in cases}
    m7 = runs[runs.scheme == "run7"]
    assert m7.y_after_b_max_run_cm.max() < 6 and not runs.failed.any()
    coef = pd.read_parquet(res / "montecarlo" / "coef.parquet")
    assert set(coef[coef.scheme == "run7"].name) == {"phi_x", "phi_y", "phi_z"}
    assert coef.truth.notna().all() and coef.groupby("name").truth.nunique().min() == 2   # drawn per replicate
    # the figures' series is replicate 0 of its cell
    ser = pd.read_csv(res / "series" / "default.csv")
    c0 = coef[(coef.scheme == "default") & (coef.replicate == 0)].set_index("name")
    assert ser.phi_y_eff.iloc[0] == pytest.approx(c0.truth["phi_y"], rel=1e-8)
    assert ser.phi_z_hat.dropna().iloc[-1] == pytest.approx(c0.estimate["phi_z"], rel=1e-8)
    ranks = pd.read_csv(res / "rank_table.csv", dtype=str, keep_default_na=False)
    assert ranks.iloc[0]["static"] == "5/7"
    assert (res / "logs" / "series_default.log").read_text().strip()
    assert "Nothing to be done" in "".join(run(study, "--cores", "1", "-n").stdout)


def test_inline_config_gives_the_same_jobs(study, tmp_path):
    """The index's sled entry inline: the same content, so nothing to do on the finished study;
    and on a fresh copy the same job list as the path form."""
    index(study, tiny_sled())
    try:
        assert jobs(study) == {}
    finally:
        index(study, "config/sled.yaml")
    fresh = make(tmp_path, yaml.safe_dump(tiny_sled()))
    by_path = job_outputs(fresh)
    index(fresh, tiny_sled())
    assert job_outputs(fresh) == by_path and any("montecarlo_cell" in o or "/runs/" in o for o in by_path)


@pytest.mark.parametrize("edit, expected", [
    # the attitude draws: every case's cell, series, collect and summary; not the rank table
    (lambda c: c.update(alignment={"sigma_arcsec": [30, 31, 180]}),
     {"montecarlo_cell": 2, "sled_series": 2, "collect": 1, "sled_summary": 1, "claims": 1, "ledger": 1,
      "report_index": 1, "all": 1}),
    # the filter's states: the default case only (run7 sets them), and the rank table's filter section
    (lambda c: c.update(filter={"states": 7}),
     {"montecarlo_cell": 1, "sled_series": 1, "collect": 1, "sled_summary": 1, "sled_observability": 1,
      "claims": 1, "ledger": 1, "report_index": 1, "all": 1}),
    # one more case: its cell and series only, then the aggregates (the study index's report too)
    (lambda c: c["study"].update(cases=c["study"]["cases"] + ["post"]),
     {"montecarlo_cell": 1, "sled_series": 1, "collect": 1, "sled_summary": 1, "claims": 1, "ledger": 1,
      "report_index": 1, "all": 1}),
])
def test_a_changed_value_reruns_exactly_what_depends_on_it(study, edit, expected):
    cfg = tiny_sled()
    edit(cfg)
    path = study / "config" / "sled.yaml"
    before = path.read_text()
    try:
        path.write_text(yaml.safe_dump(cfg))
        assert jobs(study) == expected
        path.write_text(before + "# a comment\n")
        assert jobs(study) == {}
    finally:
        path.write_text(before)


def test_sled_study_bad_config_stops_before_any_job(tmp_path):
    d = make(tmp_path, "rig: sled\ntrajectory: {brake_g: 0}\n")
    r = run(d, "--cores", "1", timeout=120)
    assert r.returncode != 0
    assert "trajectory.brake_g" in r.stdout + r.stderr
    assert not (d / "results").exists()


def test_no_sled_entry_no_sled_jobs(tmp_path):
    d = make(tmp_path, "rig: sled\n")
    index(d, None)
    r = run(d, "--cores", "1", "-n", timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "rule sled" not in r.stdout and "results/sled" not in r.stdout  # (the tmp path names the test)
