"""CLI round trip (platcal.cli.main) and bad input refused with exit 2, field named, nothing written."""

import json

import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.identify import identify, metrics
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.simulate import simulate

SHORT = "rig: sled\ntrajectory: {static_after_s: 4}\n"


@pytest.fixture()
def cfgfile(tmp_path):
    p = tmp_path / "sled.yaml"
    p.write_text(SHORT)
    return p


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_simulate_identify_round_trip(tmp_path, cfgfile, suffix):
    rec = tmp_path / f"rec{suffix}"
    assert main(["simulate", "--config", str(cfgfile), "--seed", "5", "--out", str(rec)]) == 0
    assert (tmp_path / f"rec{suffix}.truth.json").is_file()
    out = tmp_path / "id"
    assert main(["identify", "--config", str(cfgfile), "--data", str(rec), "--out", str(out)]) == 0
    met = json.loads((out / "metrics.json").read_text())
    est = pd.read_csv(out / "estimates.csv")
    # --seed 5 is replicate 5 of the default case's Monte Carlo cell: the same numbers in memory
    cfg = load_config({"rig": "sled", "trajectory": {"static_after_s": 4}})
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", [5]))
    ref = metrics(identify(cfg, sb.traj, sb.f, sb.w), sb.truth).iloc[0]
    for key in ("yz_before_max_run_cm", "y_after_b_max_run_cm", "x_naive_stop_cm", "x_constrained_end_cm",
                "phi_y_eff_err_arcsec", "phi_z_eff_err_arcsec"):
        assert met[key] == pytest.approx(ref[key], rel=1e-6, abs=1e-9), key
    assert met["phi_x_eff_err_arcsec"] is None            # 6 states: phi_x is not estimated
    assert set(est["name"]) >= {"phi_x", "phi_y", "phi_z", "nabla_x"}
    row = est[(est.name == "phi_y") & (est["filter"] == "run")].iloc[0]
    assert abs(row.estimate - row.effective) < 4 * row.sigma


def test_identify_without_truth(tmp_path, cfgfile):
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfgfile), "--out", str(rec)]) == 0
    df = pd.read_csv(rec)[["t", "fx", "fy", "fz", "wx", "wy", "wz"]]
    bare = tmp_path / "bare.csv"
    df.to_csv(bare, index=False)
    out = tmp_path / "id"
    assert main(["identify", "--config", str(cfgfile), "--data", str(bare), "--out", str(out)]) == 0
    met = json.loads((out / "metrics.json").read_text())
    assert met["truth_known"] is False and "x_naive_stop_cm" not in met
    assert np.isfinite(met["y_after_b_max_run_cm"])


def test_observability_command(tmp_path, cfgfile):
    assert main(["observability", "--config", str(cfgfile), "--out", str(tmp_path / "obs")]) == 0
    tab = pd.read_csv(tmp_path / "obs" / "rank_table.csv")
    assert tab.iloc[0]["static"] == "5/7"


BAD_CONFIGS = [
    ("trajectory: {brake_g: 0}", "trajectory.brake_g"),
    ("trajectory: {brake_g: -2}", "trajectory.brake_g"),
    ("trajectory: {phases: [{accel_g: 5, duration_s: 0}]}", "trajectory.phases[0].duration_s"),
    ("trajectory: {phases: [{accel_g: -1, duration_s: 3}]}", "trajectory.phases[0].accel_g"),
    ("trajectory: {phases: [{accel_g: 5, duration_s: 2}, {accel_g: -6, duration_s: 2}]}", "trajectory.phases[1].accel_g"),
    ("trajectory: {phases: [{accel_g: 5, duration_s: 0.0031}]}", "trajectory.phases[0].duration_s"),
    ("trajectory: {static_after_s: 0}", "trajectory.static_after_s"),
    ("imu: {accel: {noise_ug_rthz: -1}}", "imu.accel.noise_ug_rthz"),
    ("imu: {gyro: {arw_deg_rth: -0.1}}", "imu.gyro.arw_deg_rth"),
    ("alignment: {sigma_arcsec: [30, -1, 180]}", "alignment.sigma_arcsec[1]"),
    ("filter: {states: 5}", "filter.states"),
    ("filter: {period_ms: 7}", "filter.period_ms"),
    ("filter: {compensation: later}", "filter.compensation"),
    ("filter: {r_sigma: {position_m: 0}}", "filter.r_sigma.position_m"),
    ("imu: {rate_hz: .nan}", "imu.rate_hz"),
    ("colour: red", "(top level)"),
]


@pytest.mark.parametrize("extra, field", BAD_CONFIGS)
def test_bad_config_exits_2_naming_the_field(tmp_path, capsys, extra, field):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("rig: sled\n" + extra + "\n")
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--out", str(out)]) == 2
    assert f"error: {field}" in capsys.readouterr().err
    assert not any(p.name != "bad.yaml" for p in tmp_path.iterdir())


def _record(tmp_path, cfgfile):
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfgfile), "--out", str(rec)]) == 0
    return pd.read_csv(rec)


def _gap(df):
    """10 samples missing: a 0.055 s gap, above record.max_gap_s = 0.02 s (a shorter one is accepted)."""
    return df.drop(index=range(100, 110)).reset_index(drop=True)


def _nan(df):
    df.loc[7, "wy"] = np.nan
    return df


BAD_RECORDS = [
    ("gap", _gap, "--data column t"),
    ("missing fy", lambda df: df.drop(columns=["fy"]), "--data column fy"),
    ("missing t", lambda df: df.drop(columns=["t"]), "--data column t"),
    ("nan", _nan, "--data column wy, row 9"),
    ("short", lambda df: df.iloc[:-40], "--data column t"),
    ("wrong rate", lambda df: df.assign(t=df.t * 2), "--data column t"),
]


@pytest.mark.parametrize("name, damage, field", BAD_RECORDS, ids=[b[0] for b in BAD_RECORDS])
def test_bad_record_exits_2_naming_the_field(tmp_path, capsys, cfgfile, name, damage, field):
    df = damage(_record(tmp_path, cfgfile))
    bad = tmp_path / "bad.csv"
    df.to_csv(bad, index=False)
    out = tmp_path / "id"
    capsys.readouterr()
    assert main(["identify", "--config", str(cfgfile), "--data", str(bad), "--out", str(out)]) == 2
    assert f"error: {field}:" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("argv, field", [
    (["simulate", "--scheme", "table1"], "--scheme"),
    (["simulate", "--platform", "p"], "--platform"),
    (["simulate", "--seed", "-1"], "--seed"),
    (["identify", "--data", "nosuch.csv"], "--data"),
    (["identify", "--data", "x.csv", "--estimator", "ekf"], "--estimator"),
    (["observability", "--rate", "10"], "--rate"),
    (["simulate", "--out", "rec.txt"], "--out"),
])
def test_bad_options(tmp_path, capsys, cfgfile, argv, field, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.csv").write_text("t\n0\n")
    argv = list(argv)
    if "--out" not in argv:
        argv += ["--out", "out.csv" if argv[0] == "simulate" else "outdir"]
    before = set(tmp_path.iterdir())
    assert main([argv[0], "--config", str(cfgfile)] + argv[1:]) == 2
    assert f"error: {field}:" in capsys.readouterr().err
    assert set(tmp_path.iterdir()) == before
