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
from platcal.rig import rig_of
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
