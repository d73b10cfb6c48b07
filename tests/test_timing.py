"""The "Where the time goes" table (platcal.study.timing): benchmark files summed per rig and rule."""

import pandas as pd
import pytest

from platcal.errors import InputError
from platcal.study.timing import TOTAL, read_benchmarks, where_the_time_goes, write_timing

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def bench(root, rig, rule, job, s, cpu, rss):
    f = root / rig / rule / f"{job}.tsv"
    f.parent.mkdir(parents=True, exist_ok=True)
    f.write_text(HEADER + f"{s}\t0:00:00\t{rss}\t1\t1\t1\t0\t0\t50\t{cpu}\n")


def test_sums_per_rig_and_rule(tmp_path):
    bench(tmp_path, "a", "cell", "x_noise1_e", 10.0, 9.0, 100)
    bench(tmp_path, "a", "cell", "y_noise1_e", 30.0, 28.0, 300)
    bench(tmp_path, "a", "report", "job", 2.0, "NA", 50)   # shorter than Snakemake's first sample
    bench(tmp_path, "b", "cell", "x_noise1_e", 8.0, 7.5, 80)
    t = where_the_time_goes(read_benchmarks(tmp_path))
    row = t.set_index(["rig", "rule"])
    assert row.loc[("a", "cell"), "jobs"] == 2 and row.loc[("a", "cell"), "wall_s"] == 40.0
    assert row.loc[("a", "cell"), "cpu_s"] == 37.0 and row.loc[("a", "cell"), "max_s"] == 30.0
    assert row.loc[("a", TOTAL), "wall_s"] == 42.0 and row.loc[("a", TOTAL), "cpu_s"] == 37.0
    assert row.loc[("all rigs", TOTAL), "jobs"] == 4 and row.loc[("all rigs", TOTAL), "wall_s"] == 50.0
    assert row.loc[("all rigs", TOTAL), "share_pct"] == 100.0
    assert row.loc[("a", TOTAL), "share_pct"] == pytest.approx(84.0)
    assert list(t["rig"])[:3] == ["a", "a", "a"]  # the costliest rig first, its rules largest first
    assert list(t["rule"])[:3] == ["cell", "report", TOTAL]


def test_a_rig_left_out_of_the_study_is_left_out(tmp_path):
    bench(tmp_path, "a", "cell", "job", 1.0, 1.0, 10)
    bench(tmp_path, "b", "cell", "job", 2.0, 2.0, 10)
    bench(tmp_path, "study", "ledger", "job", 0.5, 0.4, 10)
    jobs = read_benchmarks(tmp_path, rigs=["a"])
    assert sorted(jobs["rig"]) == ["a", "study"]
    assert len(read_benchmarks(tmp_path)) == 3


def test_written_by_the_one_table_writer(tmp_path):
    bench(tmp_path / "b", "a", "cell", "job", 1.5, 1.0, 10)
    write_timing(tmp_path / "b", tmp_path / "timing")
    assert pd.read_csv(tmp_path / "timing.csv")["wall_s"].tolist() == [1.5, 1.5, 1.5]
    assert "# Where the time goes" in (tmp_path / "timing.md").read_text()
    assert "<table" in (tmp_path / "timing.html").read_text()


def test_no_benchmarks_gives_an_empty_table(tmp_path):
    assert where_the_time_goes(read_benchmarks(tmp_path)).empty


def test_a_file_that_is_not_a_benchmark_is_named(tmp_path):
    f = tmp_path / "a" / "cell" / "job.tsv"
    f.parent.mkdir(parents=True)
    f.write_text("x\ty\n1\t2\n")
    with pytest.raises(InputError, match="job.tsv.*cpu_time"):
        read_benchmarks(tmp_path)
