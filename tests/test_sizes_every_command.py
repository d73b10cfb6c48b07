"""Issue 25 item 3, what was left: every command of every rig estimates the memory AND the time its
inputs imply and refuses past ``--max-memory-gb`` / ``--max-hours`` before any work, naming the
field and the option to raise (:mod:`platcal.sizes`); the default study stays far below both.

Each refusal runs in-process in an empty folder and must be fast (the check comes before any
allocation or record read: a record of 1e12 bytes is a sparse file, never read).
"""

import time

import pytest

from platcal.cli import build_parser, main
from platcal.io import read_config
from platcal.rig import get_rig, rig_names, rig_of
from platcal.sizes import DEFAULT_MAX_HOURS, DEFAULT_MAX_MEMORY_GB, check_sizes
from platcal.errors import InputError
from file_snapshot import snapshot

SIX = "[[0, 0, 0], [90, 0, 0], [180, 0, 0], [270, 0, 0], [0, 0, 90], [0, 0, 180]]"
# an hour of dwell at six positions: inside the schema, fits in memory one replicate at a time
HOUR = f"schemes: {{s: {{dwell_s: 3600, positions: {SIX}}}}}\n"
CENTRIFUGE_MC = ("rig: centrifuge\n" + HOUR +
                 "study: {schemes: [s], sigma_a_ug: [10], estimators: {ekf1: {passes: 1}}, replicates: 100000, "
                 "batch: 1, threads: 1, paper: {scheme: s, estimator: ekf1}, compare: {scheme: s, "
                 "estimators: [ekf1], sigma_a_ug: [10], replicates: 2}}\n")
HUGE = "../huge.csv"   # a sparse record file of 1e12 bytes, outside the folder compared before/after

# name: (config text, argv after the command's --config, field named, limit named)
CASES = {
    "centrifuge montecarlo 1e5 replicates of an hour-long scheme":
        (CENTRIFUGE_MC, ["montecarlo", "--scheme", "s", "--noise", "10", "--estimator", "ekf1", "--out", "out"],
         "study.replicates", "--max-hours"),
    "centrifuge observability 1e5 replicates":
        ("rig: centrifuge\n" + HOUR, ["observability", "--scheme", "s", "--replicates", "100000", "--out", "out"],
         "--replicates", "--max-hours"),
    "centrifuge design 1e6 generations":
        ("rig: centrifuge\n" + HOUR, ["design", "--generations", "1000000", "--out", "out/d.yaml"],
         "--generations", "--max-hours"),
    "multiposition observability past a small limit":
        ("rig: multiposition\n" + HOUR, ["observability", "--scheme", "s", "--out", "out", "--max-hours", "1e-6"],
         "schemes.s.dwell_s", "--max-hours"),
    "sled simulate past a small limit":
        ("rig: sled\n", ["simulate", "--out", "out/r.csv", "--max-hours", "1e-9"], "trajectory.", "--max-hours"),
    **{f"{rig} inspect of a 1e12-byte record": (f"rig: {rig}\n" + (HOUR if rig == "centrifuge" else ""),
                                               ["inspect", "--data", HUGE], "--data", "--max-")
       for rig in ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")},
    "lowprec_centrifuge identify of a 1e12-byte record":
        ("rig: lowprec_centrifuge\n", ["identify", "--data", HUGE, "--out", "out"], "--data", "--max-"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_absurd_input_refused_fast_with_the_field(case, tmp_path, capsys, monkeypatch):
    text, argv, field, limit = CASES[case]
    run = tmp_path / "run"
    run.mkdir()
    monkeypatch.chdir(run)
    (run / "c.yaml").write_text(text)
    with open(run / HUGE, "wb") as f:
        f.truncate(10**12)
    before = snapshot(run)
    t0 = time.process_time()
    code = main([argv[0], "--config", "c.yaml", *argv[1:]])
    cpu = time.process_time() - t0
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"error: {field}" in err and f"raise {limit}" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert cpu < 2.0, f"{cpu:.2f} CPU s: the check did work before refusing"
    assert snapshot(run) == before


def test_compensate_of_a_huge_record_is_refused(tmp_path):
    """compensate's config comes from a calibration file; its hook is the same mechanism."""
    raw = {"rig": "sled"}
    rig = rig_of(raw)
    huge = tmp_path / "huge.csv"
    with open(huge, "wb") as f:
        f.truncate(10**12)
    args = build_parser(rig).parse_args(["compensate", "--calibration", "cal.yaml", "--data", str(huge),
                                         "--out", "o.csv"])
    with pytest.raises(InputError) as e:
        check_sizes(rig.sizes("compensate", rig.load_config(raw), args), DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
    assert e.value.field == "--data"


def _default_commands(rig_name: str, raw: dict):
    """Every sized command line of a rig's default study (config/<rig>.yaml)."""
    if rig_name in ("centrifuge", "multiposition"):
        for s in raw["schemes"]:
            yield ["simulate", "--scheme", s, "--out", "r.csv"]
            yield ["identify", "--scheme", s, "--data", "r.csv", "--out", "o"]
            yield ["observability", "--scheme", s, "--out", "o"]
    if rig_name == "centrifuge":
        for s in raw["study"]["schemes"]:
            if s in raw["schemes"] or s in ("classical",):
                yield ["montecarlo", "--scheme", s, "--noise", "10", "--estimator", "ekf1", "--out", "o"]
        yield ["design", "--out", "d.yaml"]
    if rig_name == "sled":
        yield ["simulate", "--out", "r.csv"]
        yield ["identify", "--data", "r.csv", "--out", "o"]
        yield ["observability", "--out", "o"]
    if rig_name == "lowprec_centrifuge":
        for p, runs in raw["runs"].items():
            for r in runs:
                yield ["simulate", "--platform", p, "--run", r, "--out", "r.csv"]


@pytest.mark.parametrize("rig_name", ["centrifuge", "multiposition", "sled", "lowprec_centrifuge"])
def test_default_study_far_below_the_limits(rig_name):
    raw = read_config(f"config/{rig_name}.yaml")
    rig = rig_of(raw)
    cfg = rig.load_config(raw)
    n = 0
    for argv in _default_commands(rig_name, raw):
        args = build_parser(rig).parse_args([argv[0], "--config", "x.yaml", *argv[1:]])
        sizes = rig.sizes(args.command, cfg, args)
        check_sizes(sizes, DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
        assert all(s.hours < DEFAULT_MAX_HOURS / 10 for s in sizes), (argv, [s.hours for s in sizes])
        n += 1
    assert n > 0


# ---------------------------------------------------------------- the commands sized last (plan, report,
# the sled's observability) and a Parquet record sized from its footer

CAMPAIGN = ("targets: {gyro: 1, accel: 1000, theta: 100}\n"
            "rigs: {multiposition: {config: {}, schemes: [S8], dwell_s: [60], max_repeats: 1}}\n"
            "optimiser: {population: 4, generations: %s}\nmontecarlo: {replicates: 2}\n")


def _refused_fast(argv, field, limit, tmp_path, capsys, monkeypatch, files=None, cpu_limit=2.0):
    """``platcal argv`` in an empty folder (``files``: name -> text written first) exits 2 naming
    ``field`` and the option ``limit`` to raise, in one line, within ``cpu_limit`` CPU s, writing nothing."""
    run = tmp_path / "run"
    run.mkdir()
    monkeypatch.chdir(run)
    for name, text in (files or {}).items():
        (run / name).write_text(text)
    before = snapshot(run)
    t0 = time.process_time()
    code = main(argv)
    cpu = time.process_time() - t0
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"error: {field}" in err and f"raise {limit}" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert cpu < cpu_limit, f"{cpu:.2f} CPU s: the check did work before refusing"
    assert snapshot(run) == before
    return err


def test_plan_of_a_billion_generations_is_refused_before_the_search(tmp_path, capsys, monkeypatch):
    # campaign.py (pymoo, matplotlib) imported first: the CPU measured is the command's, not the import's
    import platcal.study.campaign  # noqa: F401
    err = _refused_fast(["plan", "--campaign", "camp.yaml", "--out", "out"], "optimiser.generations", "--max-",
                        tmp_path, capsys, monkeypatch, {"camp.yaml": CAMPAIGN % "1000000000"})
    assert "population 4 x 1000000000 generations" in err


def test_plan_check_past_the_limit_is_refused_before_the_monte_carlo(tmp_path, capsys, monkeypatch):
    """The check's size is known once the plans are: refused after the (small) search, before the
    Monte Carlo, nothing written; the field is the option that set the replicates. The search
    compiles kernels on a cold cache, so "before the Monte Carlo" is checked by the Monte Carlo
    check failing the test if it starts, not by a CPU bound."""
    import platcal.study.campaign as campaign

    def started(*args, **kwargs):
        raise AssertionError("the Monte Carlo check started before the size was refused")

    monkeypatch.setattr(campaign, "check_plan", started)
    _refused_fast(["plan", "--campaign", "camp.yaml", "--out", "out", "--replicates", "100000", "--max-hours", "1"],
                  "--replicates", "--max-hours", tmp_path, capsys, monkeypatch, {"camp.yaml": CAMPAIGN % "1"},
                  cpu_limit=float("inf"))


def test_plan_options_are_the_common_limits():
    args = build_parser().parse_args(["plan", "--campaign", "c.yaml", "--out", "o"])
    assert args.max_memory_gb == DEFAULT_MAX_MEMORY_GB and args.max_hours == DEFAULT_MAX_HOURS


def test_sled_observability_is_sized_by_its_phases(tmp_path, capsys, monkeypatch):
    phases = ", ".join("{accel_g: 1, duration_s: 1}" for _ in range(50))
    _refused_fast(["observability", "--config", "c.yaml", "--out", "out", "--max-memory-gb", "1e-4"],
                  "trajectory.phases", "--max-memory-gb", tmp_path, capsys, monkeypatch,
                  {"c.yaml": f"rig: sled\ntrajectory: {{phases: [{phases}]}}\n"})


@pytest.mark.parametrize("rig_name", [r for r in rig_names() if "report" in get_rig(r).commands])
def test_report_of_huge_result_tables_is_refused(rig_name, tmp_path, capsys, monkeypatch):
    """Every rig's report (the centrifuge's today) reads its results folder's tables whole: sized by their bytes."""
    res = tmp_path / "res"
    res.mkdir()
    with open(res / "coef.csv", "wb") as f:
        f.truncate(10**12)
    _refused_fast(["report", "--config", "c.yaml", "--results", str(res)], "--results", "--max-", tmp_path, capsys,
                  monkeypatch, {"c.yaml": f"rig: {rig_name}\n" + (HOUR if rig_name == "centrifuge" else "")})


def test_a_parquet_record_is_sized_by_its_footer_not_its_compressed_bytes(tmp_path):
    """A Parquet file compresses (here a constant record, to almost nothing): its size is rows x
    columns x the CSV bytes of a value, from the footer alone."""
    import numpy as np
    import pandas as pd
    from platcal.sizes import CSV_BYTES_PER_VALUE, record_bytes, record_size

    rows, cols = 200_000, 11
    path = tmp_path / "rec.parquet"
    pd.DataFrame(np.zeros((rows, cols)), columns=[f"c{i}" for i in range(cols)]).to_parquet(path)
    n, how = record_bytes(path)
    assert n == rows * cols * CSV_BYTES_PER_VALUE
    assert n > 100 * path.stat().st_size           # the file's own bytes would underestimate it
    assert "footer" in how
    size = record_size(path, 0.5, 1e-8)
    assert size.samples == n and "bytes of the record as CSV" in size.unit
    with pytest.raises(InputError) as e:          # the same record past a small limit, named
        check_sizes([size], limit_gb=size.gigabytes / 2)
    assert e.value.field == "--data"
    # a CSV is its own bytes; a file named .parquet that is not one is sized by its bytes (the reader names it)
    bad = tmp_path / "bad.parquet"
    bad.write_text("not parquet")
    assert record_bytes(bad)[0] == bad.stat().st_size


def test_default_campaign_far_below_the_limits():
    """The default campaign's planning (config/campaign.yaml) is sized far below both limits."""
    from platcal.study.campaign import load_campaign, search_sizes

    sizes = search_sizes(load_campaign("config/campaign.yaml"))
    check_sizes(sizes, DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
    assert all(s.hours < DEFAULT_MAX_HOURS / 10 and s.gigabytes < DEFAULT_MAX_MEMORY_GB / 2 for s in sizes), sizes


@pytest.mark.parametrize("rig_name", ["centrifuge", "multiposition"])
def test_a_streamed_identify_is_sized_by_one_position(rig_name):
    """identify past ``--chunk-rows`` holds one position at a time (issue 22 item 3): hours at each
    of six positions (3 h at the centrifuge's 5 ms, 10 h at the multi-position rig's 20 ms: 8-10 GB
    read whole) pass the default memory limit streamed and are refused read whole
    (``--chunk-rows 0``), naming the dwell."""
    dwell = {"centrifuge": 10800, "multiposition": 36000}[rig_name]
    raw = {"rig": rig_name, "schemes": {"s": {"dwell_s": dwell, "positions": [list(map(float, p)) for p in
                                                                               eval(SIX)]}}}
    rig = rig_of(raw)
    cfg = rig.load_config(raw)
    base = ["identify", "--config", "c.yaml", "--scheme", "s", "--data", "r.csv", "--out", "o"]
    streamed = build_parser(rig).parse_args(base)
    check_sizes(rig.sizes("identify", cfg, streamed), DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
    whole = build_parser(rig).parse_args(base + ["--chunk-rows", "0"])
    with pytest.raises(InputError) as e:
        check_sizes(rig.sizes("identify", cfg, whole), DEFAULT_MAX_MEMORY_GB, DEFAULT_MAX_HOURS)
    assert e.value.field == "schemes.s.dwell_s"


def test_the_multiposition_simulate_is_sized_by_one_block():
    """The multi-position rig's simulate holds a block of a position, not the position
    (issue 22 item 3; ``filter.SIM_BLOCK``): a day at each of six positions (4.3e6 samples a
    position, 1.7 GB held as one) passes a 1 GB limit and is timed by every sample; identify of
    the same scheme, streamed one position at a time, is refused by that limit, naming the dwell."""
    raw = {"rig": "multiposition", "schemes": {"s": {"dwell_s": 86400, "positions": [list(map(float, p)) for p in
                                                                                     eval(SIX)]}}}
    rig = rig_of(raw)
    cfg = rig.load_config(raw)
    sim = rig.sizes("simulate", cfg, build_parser(rig).parse_args(["simulate", "--config", "c.yaml", "--scheme", "s",
                                                                   "--out", "r.csv"]))
    check_sizes(sim, 1.0, DEFAULT_MAX_HOURS)
    (size,) = sim
    assert size.gigabytes < 0.01
    assert size.samples * size.runs == pytest.approx(6 * (86400 / cfg.ts + 1))
    streamed = build_parser(rig).parse_args(["identify", "--config", "c.yaml", "--scheme", "s", "--data", "r.csv",
                                             "--out", "o"])
    with pytest.raises(InputError) as e:
        check_sizes(rig.sizes("identify", cfg, streamed), 1.0, DEFAULT_MAX_HOURS)
    assert e.value.field == "schemes.s.dwell_s"
