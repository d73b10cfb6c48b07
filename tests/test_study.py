"""The rig-agnostic layer: the study index, the index report, the tidy frames of a batch."""

import numpy as np
import pandas as pd
import pytest

from platcal.errors import InputError
from platcal.rig import ReplicateBatch, get_rig, rig_config
from platcal.study.montecarlo import COEF_COLUMNS, RUN_COLUMNS, tidy_frames
from platcal.study.report import write_index


def test_rig_config_reads_a_path_or_an_inline_mapping(tmp_path):
    f = tmp_path / "c.yaml"
    f.write_text("seed: 3\nfilter: {p0: {k0: 1.0e4}}\n")
    assert rig_config({"rigs": {"centrifuge": str(f)}}, "centrifuge") == {
        "seed": 3, "filter": {"p0": {"k0": 1e4}}, "rig": "centrifuge"}
    # Snakemake's YAML 1.1 reader leaves 1.0e4 as text in an inline mapping; it is read as a number
    inline = {"rigs": {"centrifuge": {"filter": {"p0": {"k0": "1.0e4"}}}}}
    assert rig_config(inline, "centrifuge")["filter"]["p0"]["k0"] == 1e4
    assert inline["rigs"]["centrifuge"]["filter"]["p0"]["k0"] == "1.0e4"  # the index is not modified


@pytest.mark.parametrize("index, field", [
    ({"rigs": {}}, "rigs.centrifuge"),
    ({"rigs": {"centrifuge": 3}}, "rigs.centrifuge"),
    ({"rigs": {"centrifuge": "no/such/file.yaml"}}, "rigs.centrifuge"),
    ({"rigs": {"centrifuge": {"rig": "sled"}}}, "rigs.centrifuge.rig"),
])
def test_rig_config_names_the_bad_entry(index, field):
    with pytest.raises(InputError) as e:
        rig_config(index, "centrifuge")
    assert e.value.field == field


def test_tidy_frames_of_a_batch():
    q = pd.DataFrame({"name": ["a", "b"], "group": ["g1", "g2"], "unit": ["m", "s"], "truth": [1.0, 0.0]})
    batch = ReplicateBatch(quantities=q, estimate=np.array([[1.1, 0.5], [0.9, -0.5]]), sigma=np.ones((2, 2)),
                           nees=np.array([1.0, 2.0]), nees_dof=2, mean_nis=np.array([1.0, 1.0]),
                           failed_updates=np.array([0, 1]), passes=1)
    coef, runs = tidy_frames(batch, "case", 2.5, "kf", [3, 4])
    assert list(coef.columns) == COEF_COLUMNS and list(runs.columns) == RUN_COLUMNS
    assert coef["replicate"].tolist() == [3, 3, 4, 4] and (coef["noise"] == 2.5).all()
    np.testing.assert_allclose(coef["rel_err_pct"].to_numpy()[[0, 2]], [10.0, -10.0])
    assert np.isnan(coef["rel_err_pct"].iloc[1])  # zero truth: no relative error
    assert runs["failed_updates"].tolist() == [0, 1]


def test_index_links_every_section_of_each_rig_report(tmp_path):
    rep = tmp_path / "centrifuge" / "report.md"
    rep.parent.mkdir()
    rep.write_text("# Centrifuge study\n\n## Study\n\ntext\n\n## Table 2, one run\n")
    write_index(["centrifuge"], [rep], tmp_path / "report.md")
    text = (tmp_path / "report.md").read_text()
    assert f"## centrifuge: {get_rig('centrifuge').title}" in text
    assert "[Centrifuge study](centrifuge/report.md)" in text
    assert "(centrifuge/report.md#table-2-one-run)" in text


def test_index_links_the_campaign_report_when_one_is_planned(tmp_path):
    rep = tmp_path / "centrifuge" / "report.md"
    camp = tmp_path / "campaign" / "report.md"
    for p, text in ((rep, "# Centrifuge study\n\n## Study\n"), (camp, "# Campaign plan\n\n## Plan\n\n## Monte Carlo check\n")):
        p.parent.mkdir()
        p.write_text(text)
    write_index(["centrifuge"], [rep], tmp_path / "report.md")
    assert "campaign" not in (tmp_path / "report.md").read_text()
    write_index(["centrifuge"], [rep], tmp_path / "report.md", campaign=camp)
    text = (tmp_path / "report.md").read_text()
    assert "## The calibration campaign" in text and "[Campaign plan](campaign/report.md)" in text
    assert "(campaign/report.md#monte-carlo-check)" in text
