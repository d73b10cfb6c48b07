"""CLI round trip and bad input for rig lowprec_centrifuge (docs/lowprec-centrifuge.md §10)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main

SMALL = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 10, "rest_between_s": 30},
         "runs": {"P1": {"run1": [5, 8]}, "P2": {"run1": [5, 8]}},
         "traditional": {"levels_g": [5, 8], "hold_s": 60, "rest_last_s": 10}}


def cfg_file(tmp_path, **over):
    raw = json.loads(json.dumps(SMALL))
    for k, v in over.items():
        raw[k] = {**raw.get(k, {}), **v} if isinstance(v, dict) else v
    p = tmp_path / f"cfg{len(list(tmp_path.glob('cfg*')))}.yaml"
    p.write_text(yaml.safe_dump(raw))
    return str(p)


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    cfg = cfg_file(d)
    assert main(["simulate", "--config", cfg, "--platform", "P1", "--run", "run1", "--seed", "7",
                 "--out", str(d / "rec.csv")]) == 0
    assert main(["simulate", "--config", cfg, "--platform", "P1", "--run", "traditional", "--seed", "7",
                 "--out", str(d / "trad.parquet")]) == 0
    return d, cfg


def test_record_columns_and_side_file(records):
    d, _ = records
    df = pd.read_csv(d / "rec.csv")
    for c in ("t", "VE", "VN", "pE", "pN", "heading_deg", "schedule", "fE", "fN", "truth_dVE", "truth_phi_z"):
        assert c in df.columns
    assert set(df["schedule"]) == {"static", "spinning"}
    assert df["heading_deg"].between(0, 360).all()
    assert df["pE"].iloc[0] == pytest.approx(0, abs=0.1)
    meta = json.loads((d / "rec.csv.truth.json").read_text())
    assert meta["coefficients"] == {"kA_x": -40.0, "k2_x": -8.0, "kA_y": 25.0, "k2_y": -5.0}
    assert meta["seed"] == 7 and meta["levels_g"] == [5, 8]
    tr = pd.read_parquet(d / "trad.parquet")
    assert (tr["schedule"] == "hold").sum() == pytest.approx(2 * 60 * 100, abs=2)


def test_round_trip_proposed(records, tmp_path):
    d, cfg = records
    assert main(["identify", "--config", cfg, "--data", str(d / "rec.csv"), "--out", str(tmp_path / "o")]) == 0
    est = pd.read_csv(tmp_path / "o" / "estimates.csv").set_index("name")
    assert list(est.index) == ["kA_x", "k2_x", "kA_y", "k2_y"]
    assert (est["error"].abs() < 4 * est["sigma"]).all(), est
    assert (est["sigma"] < [20, 5, 20, 5]).all()       # well below the prior (100, 20)
    # --no-truth: no truth columns
    assert main(["identify", "--config", cfg, "--data", str(d / "rec.csv"), "--out", str(tmp_path / "n"),
                 "--no-truth"]) == 0
    assert "truth" not in pd.read_csv(tmp_path / "n" / "estimates.csv").columns


def test_round_trip_traditional(records, tmp_path):
    d, cfg = records
    assert main(["identify", "--config", cfg, "--data", str(d / "trad.parquet"), "--out", str(tmp_path),
                 "--method", "traditional"]) == 0
    est = pd.read_csv(tmp_path / "estimates.csv").set_index("name")
    assert est["sigma"].isna().all()
    assert np.isfinite(est["estimate"]).all()


def test_simulate_is_reproducible(records, tmp_path):
    d, cfg = records
    assert main(["simulate", "--config", cfg, "--platform", "P1", "--run", "run1", "--seed", "7",
                 "--out", str(tmp_path / "again.csv")]) == 0
    assert (tmp_path / "again.csv").read_bytes() == (d / "rec.csv").read_bytes()


def _bad_record(src, tmp_path, how):
    df = pd.read_csv(src)
    if how == "nan":
        df.loc[1234, "VE"] = np.nan
    elif how == "no-revolution":
        df["heading_deg"] = 10.0 + 0.1 * np.sin(df["t"])
    elif how == "text":
        df["pN"] = df["pN"].astype(object)
        df.loc[5, "pN"] = "x"
    elif how == "no-column":
        df = df.drop(columns="heading_deg")
    p = tmp_path / f"{how}.csv"
    df.to_csv(p, index=False)
    return str(p)


@pytest.mark.parametrize("how, field", [
    ("nan", "column VE, row 1236"),   # rows counted as the file's lines (header = 1), as every rig
    ("no-revolution", "heading_deg"),
    ("text", "column pN, row 7"),
    ("no-column", "column heading_deg"),
])
def test_bad_record_exits_2_nothing_written(records, tmp_path, capsys, how, field):
    d, cfg = records
    bad = _bad_record(d / "rec.csv", tmp_path, how)
    out = tmp_path / "out"
    assert main(["identify", "--config", cfg, "--data", bad, "--out", str(out)]) == 2
    assert field in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("over, args, field", [
    ({"centrifuge": {"jerk_g_s": 0.002}}, [], "runs.P1.run1[0]"),          # 5 g unreachable in 30 min
    ({"centrifuge": {"arm_m": -3.0}}, [], "centrifuge.arm_m"),
    ({"traditional": {"levels_g": [8, 5]}}, [], "traditional.levels_g[1]"),
    ({}, ["--scheme", "table1"], "--scheme"),
    ({}, ["--platform", "P9"], "--platform"),
    ({}, ["--run", "run7"], "--run"),
    ({}, ["--seed", "-1"], "--seed"),
    ({}, ["--out-txt"], "--out"),
])
def test_bad_simulate_input_exits_2(tmp_path, capsys, over, args, field):
    cfg = cfg_file(tmp_path, **over)
    out = tmp_path / "r.csv"
    argv = {"--platform": "P1", "--run": "run1", "--out": str(out)}
    extra = []
    for a in args:
        if a == "--out-txt":
            argv["--out"] = str(tmp_path / "r.txt")
    it = iter(args)
    for a in it:
        if a == "--out-txt":
            continue
        val = next(it)
        if a in argv:
            argv[a] = val
        else:
            extra += [a, val]
    flat = [x for kv in argv.items() for x in kv] + extra
    assert main(["simulate", "--config", cfg] + flat) == 2
    assert f"error: {field}" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "r.csv.truth.json").exists() and not (tmp_path / "r.txt").exists()


def test_missing_platform_and_bad_method(records, tmp_path, capsys):
    d, cfg = records
    assert main(["simulate", "--config", cfg, "--run", "run1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--platform" in capsys.readouterr().err
    for opt, val in (("--method", "ekf"), ("--estimator", "ekf"), ("--scheme", "s")):
        assert main(["identify", "--config", cfg, "--data", str(d / "rec.csv"), "--out", str(tmp_path / "o"),
                     opt, val]) == 2
        assert f"error: {opt}" in capsys.readouterr().err
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "none.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "--data" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_traditional_method_needs_plateaus(records, tmp_path, capsys):
    d, cfg = records
    assert main(["identify", "--config", cfg, "--data", str(d / "rec.csv"), "--out", str(tmp_path / "o"),
                 "--method", "traditional"]) == 2
    assert "schedule" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
