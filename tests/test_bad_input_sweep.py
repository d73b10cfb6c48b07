"""Issue 25, second paragraph, row by row on every rig it applies to: values out of range, sizes
past the limit, non-finite options, a missing results folder, faults while writing.

Each case runs ``platcal`` in-process in an empty folder and must exit 2 (refused) with the field
named in stderr, no traceback, and the folder unchanged (nothing written in ``--out``). The size
cases are inside the schema's bounds and refused by the size check before any allocation.
"""

import csv
import errno
import json
import os

import pandas as pd
import pytest

from platcal.cli import main
from platcal.records import truth_path
from file_snapshot import snapshot

CENTRIFUGE = ("rig: centrifuge\nschemes: {s: {dwell_s: 3, positions: [[45, 0, 167], [350, 0, 325], [209, 0, 182]]}}\n"
              "study: {schemes: [s], sigma_a_ug: [10], estimators: {ekf1: {passes: 1}}, replicates: 2, batch: 2, "
              "threads: 1, paper: {scheme: s, estimator: ekf1}, compare: {scheme: s, estimators: [ekf1], "
              "sigma_a_ug: [10], replicates: 2}}\n")
SIX = "[[0, 0, 0], [90, 0, 0], [180, 0, 0], [270, 0, 0], [0, 0, 90], [0, 0, 180]]"

# name: (config text, argv after the command's --config, field that must be named)
CASES = {
    # a dwell or static period of 1e12 s: the schema's bound (a day)
    "centrifuge dwell 1e12": ("rig: centrifuge\nschemes: {s: {dwell_s: 1.0e12, positions: [[0, 0, 0]]}}\n",
                              # identify streams one position at a time: a day's dwell is 3.3 GB held, past a
                           # 1 GB limit (simulate holds a block of a position: test_sizes_every_command.py)
                           ["identify", "--scheme", "s", "--data", "none.csv", "--out", "out", "--max-memory-gb", "1"],
                           "schemes.s.dwell_s"),
    "multiposition dwell 1e12": ("rig: multiposition\nschemes: {s: {dwell_s: 1.0e12, positions: [[0, 0, 0]]}}\n",
                                 # identify streams one position at a time: a day's dwell is 3.3 GB held, past a
                           # 1 GB limit (simulate holds a block of a position: test_sizes_every_command.py)
                           ["identify", "--scheme", "s", "--data", "none.csv", "--out", "out", "--max-memory-gb", "1"],
                           "schemes.s.dwell_s"),
    "sled static_after_s 1e12": ("rig: sled\ntrajectory: {static_after_s: 1.0e12}\n",
                                 ["simulate", "--out", "out/r.csv"], "trajectory.static_after_s"),
    "lowprec rest_between_s 1e12": ("rig: lowprec_centrifuge\nprofile: {rest_between_s: 1.0e12}\n",
                                    ["simulate", "--platform", "P1", "--run", "run1", "--out", "out/r.csv"],
                                    "profile.rest_between_s"),
    # n_sub of 1e9 (hung): the schema's bound
    "multiposition n_sub 1e9": ("rig: multiposition\nsampling: {n_sub: 1.0e9}\n",
                                ["simulate", "--out", "out/r.csv"], "sampling.n_sub"),
    # 1e12 study seeds (replicates per cell)
    "centrifuge replicates 1e12": (CENTRIFUGE.replace("replicates: 2, batch", "replicates: 1.0e12, batch"),
                                   ["montecarlo", "--scheme", "s", "--estimator", "ekf1", "--out", "out"],
                                   "study.replicates"),
    "multiposition seeds 1e12": ("rig: multiposition\nstudy: {seeds: 1.0e12}\n", ["simulate", "--out", "out/r.csv"],
                                 "study.seeds"),
    "sled seeds 1e12": ("rig: sled\nstudy: {seeds: 1.0e12}\n", ["simulate", "--out", "out/r.csv"], "study.seeds"),
    "lowprec seeds 1e12": ("rig: lowprec_centrifuge\nstudy: {seeds: 1.0e12}\n",
                           ["simulate", "--platform", "P1", "--run", "run1", "--out", "out/r.csv"], "study.seeds"),
    # study.rate_errors unbounded: [5] ran, [-1] failed inside a job
    "lowprec rate_errors [5]": ("rig: lowprec_centrifuge\nstudy: {rate_errors: [5]}\n",
                                ["simulate", "--platform", "P1", "--run", "run1", "--out", "out/r.csv"],
                                "study.rate_errors[0]"),
    "lowprec rate_errors [-1]": ("rig: lowprec_centrifuge\nstudy: {rate_errors: [0, -1]}\n",
                                 ["simulate", "--platform", "P1", "--run", "run1", "--out", "out/r.csv"],
                                 "study.rate_errors[1]"),
    # montecarlo --noise -5 | nan | inf (tracebacks)
    **{f"centrifuge montecarlo --noise {v}": (CENTRIFUGE, ["montecarlo", "--scheme", "s", "--estimator", "ekf1",
                                                          f"--noise={v}", "--out", "out"], "--noise")
       for v in ("-5", "nan", "inf", "ten")},
    # observability --arw nan (exit 0 with J = 0), --rate nan (LinAlgError)
    **{f"centrifuge observability --{o} {v}": (CENTRIFUGE, ["observability", "--scheme", "s", f"--{o}", v,
                                                           "--out", "out"], f"--{o}")
       for o in ("arw", "rate") for v in ("nan", "inf", "-1")},
    "centrifuge observability --replicates -1": (CENTRIFUGE, ["observability", "--scheme", "s", "--replicates", "-1",
                                                              "--out", "out"], "--replicates"),
    "centrifuge montecarlo --threads 0": (CENTRIFUGE, ["montecarlo", "--scheme", "s", "--estimator", "ekf1",
                                                       "--threads", "0", "--out", "out"], "--threads"),
    # report --results /nonexistent (traceback); the rigs without a report say so
    "centrifuge report --results /nonexistent": (CENTRIFUGE, ["report", "--results", "/nonexistent/results"],
                                                 "--results"),
    **{f"{rig} report --results /nonexistent": (f"rig: {rig}\n", ["report", "--results", "/nonexistent/results"],
                                                "rig")
       for rig in ("multiposition", "sled", "lowprec_centrifuge")},
    # sizes inside the schema's bounds, past --max-memory-gb: refused before any allocation
    "centrifuge size": (f"rig: centrifuge\nschemes: {{s: {{dwell_s: 86400, positions: {SIX}}}}}\n",
                        ["simulate", "--scheme", "s", "--out", "out/r.csv"], "schemes.s.dwell_s"),
    "centrifuge identify size": (f"rig: centrifuge\nschemes: {{s: {{dwell_s: 86400, positions: {SIX}}}}}\n",
                                 ["identify", "--scheme", "s", "--data", "none.csv", "--out", "out"],
                                 "schemes.s.dwell_s"),
    "multiposition size": (f"rig: multiposition\nschemes: {{s: {{dwell_s: 86400, positions: {SIX}}}}}\n",
                           # identify streams one position at a time: a day's dwell is 3.3 GB held, past a
                           # 1 GB limit (simulate holds a block of a position: test_sizes_every_command.py)
                           ["identify", "--scheme", "s", "--data", "none.csv", "--out", "out", "--max-memory-gb", "1"],
                           "schemes.s.dwell_s"),
    "sled size": ("rig: sled\ntrajectory: {static_after_s: 86400}\n", ["simulate", "--out", "out/r.csv"],
                  "trajectory.static_after_s"),
    "sled identify size": ("rig: sled\ntrajectory: {static_after_s: 86400}\n",
                           ["identify", "--data", "none.csv", "--out", "out"], "trajectory.static_after_s"),
    "lowprec size": ("rig: lowprec_centrifuge\nprofile: {rest_between_s: 86400}\n",
                     ["simulate", "--platform", "P1", "--run", "run1", "--out", "out/r.csv"], "profile.rest_between_s"),
    "size limit raised is still checked": ("rig: sled\n", ["simulate", "--out", "out/r.csv", "--max-memory-gb",
                                                           "0.001"], "trajectory."),
    **{f"--max-memory-gb {v}": ("rig: sled\n", ["simulate", "--out", "out/r.csv", "--max-memory-gb", v],
                                "--max-memory-gb") for v in ("0", "nan", "-1")},
    **{f"{rig} --seed -1": (f"rig: {rig}\n" + ("schemes: {s: {dwell_s: 3, positions: [[0, 0, 0]]}}\n"
                                               if rig == "centrifuge" else ""),
                            ["simulate", "--seed", "-1", "--out", "out/r.csv"], "--seed")
       for rig in ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")},
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_refused_with_the_field_named(case, tmp_path, capsys, monkeypatch):
    text, argv, field = CASES[case]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text(text)
    before = snapshot(tmp_path)
    code = main([argv[0], "--config", "c.yaml", *argv[1:]])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"error: {field}" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert snapshot(tmp_path) == before   # nothing written, no folder made


def test_size_message_names_the_limit_and_the_fix(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.yaml").write_text("rig: sled\ntrajectory: {static_after_s: 86400}\n")
    assert main(["simulate", "--config", "c.yaml", "--out", "r.csv"]) == 2
    err = capsys.readouterr().err
    assert "GB, more than --max-memory-gb 4" in err and "raise --max-memory-gb" in err


# ------------------------------------------------------------------------------------------
# faults: a full disk, no permission (issue 25 item 4)

TINY = {"sled": ("rig: sled\ntrajectory: {static_before_s: 1, phases: [{accel_g: 2, duration_s: 1}], brake_g: 4, "
                 "static_after_s: 1}\n", []),
        "lowprec_centrifuge": ("rig: lowprec_centrifuge\nprofile: {rest_first_s: 2, rest_between_s: 2, rate_hz: 20}\n"
                               "runs: {P1: {run1: [2, 3]}, P2: {run1: [2, 4]}}\n",
                               ["--platform", "P1", "--run", "run1"]),
        "multiposition": ("rig: multiposition\nschemes: {tiny: {dwell_s: 1, positions: [[0, 0, 0], [90, 0, 0]]}}\n",
                          ["--scheme", "tiny"]),
        "centrifuge": ("rig: centrifuge\nschemes: {s: {dwell_s: 0.5, positions: [[45, 0, 167], [350, 0, 325]]}}\n",
                       ["--scheme", "s"])}


def _fail_with(monkeypatch, code: int, method: str = "to_csv"):
    def fail(*a, **k):
        raise OSError(code, os.strerror(code))
    monkeypatch.setattr(pd.DataFrame, method, fail)


def _fail_tables_with(monkeypatch, code: int):
    """The tables an identify writes without pandas (``platcal.io.write_csv``, through the csv
    module's writer) fail with ``code``."""
    def fail(*a, **k):
        raise OSError(code, os.strerror(code))
    monkeypatch.setattr(csv, "writer", fail)


@pytest.mark.parametrize("rig", sorted(TINY))
@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EACCES])
def test_simulate_fault_names_the_path_and_leaves_nothing(rig, code, tmp_path, capsys, monkeypatch):
    """The record's write fails (a full disk, no permission): one line naming the record, exit 2,
    neither the record nor its truth side file nor a temporary left."""
    text, opts = TINY[rig]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    before = snapshot(tmp_path)
    _fail_with(monkeypatch, code)
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfg), *opts, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"error: {out}: {os.strerror(code)}" in err and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1
    assert snapshot(tmp_path) == before


def test_simulate_fault_keeps_the_earlier_pair(tmp_path, capsys, monkeypatch):
    """A rerun that fails on a full disk leaves the earlier record and its own truth untouched."""
    text, opts = TINY["sled"]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--seed", "0", "--out", str(out)]) == 0
    before = snapshot(tmp_path)
    _fail_with(monkeypatch, errno.ENOSPC)
    assert main(["simulate", "--config", str(cfg), "--seed", "1", "--out", str(out)]) == 2
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("rig", sorted(TINY))
def test_identify_fault_writes_nothing(rig, tmp_path, capsys, monkeypatch):
    text, opts = TINY[rig]
    scheme = opts if opts[:1] == ["--scheme"] else []  # identify takes the scheme, not the platform and run
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfg), *opts, "--out", str(rec)]) == 0
    capsys.readouterr()
    _fail_tables_with(monkeypatch, errno.ENOSPC)
    out = tmp_path / "id"
    code = main(["identify", "--config", str(cfg), *scheme, "--data", str(rec), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "No space left on device" in err and "Traceback" not in err, err
    assert str(out) in err
    assert not out.exists() or not any(out.iterdir())


def test_read_only_folder_during_the_write(tmp_path, capsys, monkeypatch):
    """A folder made read-only after the pre-check (or a file system that refuses late): the
    real permission error when not root (root ignores the mode: then a monkeypatched one)."""
    text, opts = TINY["sled"]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    ro = tmp_path / "ro"
    ro.mkdir()
    if os.geteuid() == 0:
        _fail_with(monkeypatch, errno.EACCES)
    else:
        monkeypatch.setattr("platcal.rigs.sled.commands.check_writable", lambda *a, **k: None)
        ro.chmod(0o555)
    try:
        assert main(["simulate", "--config", str(cfg), "--out", str(ro / "rec.csv")]) == 2
    finally:
        ro.chmod(0o755)
    err = capsys.readouterr().err
    assert str(ro) in err and "Permission denied" in err and "Traceback" not in err, err
    assert list(ro.iterdir()) == []


# ------------------------------------------------------------------------------------------
# rec.csv and rec.parquet in one folder: each has its own truth


@pytest.mark.parametrize("rig", ["sled", "lowprec_centrifuge"])
def test_csv_and_parquet_records_keep_their_own_truth(rig, tmp_path, capsys):
    text, _ = TINY[rig]
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    # two different truths: another seed (sled, drawn per seed), another platform (lowprec)
    sims = {"rec.csv": ["--seed", "0"] + (["--platform", "P1", "--run", "run1"] if rig != "sled" else []),
            "rec.parquet": ["--seed", "1"] + (["--platform", "P2", "--run", "run1"] if rig != "sled" else [])}
    truths = {}
    for name, opts in sims.items():
        assert main(["simulate", "--config", str(cfg), *opts, "--out", str(tmp_path / name)]) == 0
        side = truth_path(tmp_path / name)
        assert side.name == f"{name}.truth.json"
        truths[name] = json.loads(side.read_text())
    assert truths["rec.csv"] != truths["rec.parquet"]
    got = {}
    for name in sims:
        out = tmp_path / f"id_{name}"
        assert main(["identify", "--config", str(cfg), "--data", str(tmp_path / name), "--out", str(out)]) in (0, 3)
        got[name] = pd.read_csv(out / "estimates.csv").set_index("name")["truth"]
    if rig == "lowprec_centrifuge":
        for name in sims:   # each identification compares with its own record's coefficients
            assert got[name].to_dict() == pytest.approx(truths[name]["coefficients"])
    else:
        for name in sims:
            assert got[name].loc["nabla_x"] == pytest.approx(truths[name]["nabla_static_ug"][0], rel=1e-5)  # %.6g
    assert not got["rec.csv"].equals(got["rec.parquet"])
