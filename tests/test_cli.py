"""The command line: quick start (simulate then identify) and bad input (exit 2, field named, no output)."""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from centrifuge_short import short_config, with_sections
from platcal.cli import main
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.record import sim_to_frame
from platcal.rigs.centrifuge.simulate import simulate
from platcal.study.montecarlo import replicate_seed

SMALL = short_config(passes=2)


@pytest.fixture()
def small(tmp_path):
    cfg = tmp_path / "config.yaml"
    cfg.write_text(SMALL)
    rec = tmp_path / "run.csv"
    assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "3", "--out", str(rec)]) == 0
    return cfg, rec


@pytest.mark.parametrize("noise_free", [True, False])
def test_zero_noise_config_simulates_but_a_filter_refuses_it(tmp_path, noise_free, capsys):
    """platcal simulate needs no filter settings (issue 9 item 2): a config with zero noise
    simulates, with and without --noise-free; identify (a filter run) refuses it, naming the field."""
    cfg = tmp_path / "zero.yaml"
    cfg.write_text(SMALL.replace("noise: {sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}",
                                 "noise: {sigma_a_ug: 0, arw_deg_rth: 0, sigma_set_arcsec: 0}"))
    rec = tmp_path / "run.csv"
    args = ["simulate", "--config", str(cfg), "--scheme", "short", "--out", str(rec)]
    assert main(args + (["--noise-free"] if noise_free else [])) == 0
    df = pd.read_csv(rec)
    assert len(df) == 3 * 800
    # zero noise: the record is the noise-free one whatever the seed
    np.testing.assert_array_equal(df[["alpha", "beta", "gamma"]].to_numpy()[::800],
                                  df[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy()[::800])
    capsys.readouterr()
    out = tmp_path / "id"
    assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec), "--out", str(out)]) == 2
    assert "filter.sigma_set_arcsec" in capsys.readouterr().err and not out.exists()
    # the filter's own settings make it runnable again
    cfg.write_text(cfg.read_text().replace("filter: {period_ms: 20, passes: 2}",
                                           "filter: {period_ms: 20, passes: 2, sigma_set_arcsec: 10, sigma_a_ug: 10}"))
    assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec), "--out", str(out)]) == 0


def test_identify_estimator_option(small, tmp_path, capsys):
    """--estimator: a kind or a study.estimators name (its filter overrides); unknown -> exit 2
    naming both lists; summary.json says which estimator ran."""
    cfg, rec = small
    cfg.write_text(SMALL + "study:\n  estimators: {ekf1: {passes: 1}, ekf2: {passes: 2}, "
                   "it2: {estimator: iekf, iterations: 2, passes: 1}}\n")
    base = ["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec)]
    out = {}
    for name in ("iekf", "it2", "ekf1"):
        out[name] = tmp_path / name
        assert main(base + ["--out", str(out[name]), "--estimator", name]) == 0
    s = {k: json.loads((v / "summary.json").read_text()) for k, v in out.items()}
    assert s["iekf"]["estimator"] == "iekf" and s["iekf"]["passes"] == 2  # the config's filter, kind iekf
    assert s["iekf"]["estimator_options"]["iterations"] == 2  # the schema default
    assert s["it2"]["estimator"] == "iekf" and s["it2"]["passes"] == 1 and s["it2"]["estimator_options"]["iterations"] == 2
    assert s["ekf1"]["estimator"] == "ekf" and s["ekf1"]["passes"] == 1 and s["ekf1"]["estimator_options"] == {}
    e1 = pd.read_csv(out["ekf1"] / "estimates.csv")["estimate"]
    e2 = pd.read_csv(out["it2"] / "estimates.csv")["estimate"]
    assert not np.allclose(e1, e2, rtol=1e-9, atol=0)
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main(base + ["--out", str(bad), "--estimator", "kalman"]) == 2
    err = capsys.readouterr().err
    assert "--estimator" in err and "ekf, iekf" in err and "ekf1, ekf2, it2" in err and not bad.exists()


def test_quick_start_simulate_then_identify(small, tmp_path):
    cfg, rec = small
    df = pd.read_csv(rec)
    assert len(df) == 3 * 800 and df["t"].iloc[1] == 0.005
    out = tmp_path / "id"
    assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec), "--out", str(out)]) == 0
    est = pd.read_csv(out / "estimates.csv")
    assert list(est.columns) == ["name", "unit", "estimate", "sigma", "truth", "error", "rel_err_pct"]
    assert len(est) == 45 and est["name"].iloc[0] == "DF_x" and np.all(est["sigma"] > 0)
    cov = pd.read_csv(out / "covariance.csv", index_col=0)
    assert cov.shape == (48, 48) and list(cov.index) == list(cov.columns)
    assert cov.columns[-1] == "gamma"
    np.testing.assert_allclose(np.sqrt(np.diag(cov.to_numpy()))[:45], est["sigma"], rtol=1e-12)
    hist = pd.read_csv(out / "history.csv")
    # 2 passes x 3 positions x instants 1, 2, 3 s (the first instant is 20 ms after the reset,
    # docs/centrifuge-model.md §9, so no history entry at t = 0 of a position)
    assert len(hist) == 2 * 3 * 3 and hist["t"].is_monotonic_increasing
    assert hist["DF_x_sigma"].iloc[-1] < hist["DF_x_sigma"].iloc[0]
    md = (out / "table2.md").read_text()
    assert "| DF_x | deg/h | 7.37 | 7.3807 | 0.15 |" in md
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_states"] == 48 and summary["nees"] > 0


def test_same_seed_same_record_and_seeds_differ(small, tmp_path):
    cfg, rec = small
    again = tmp_path / "again.csv"
    other = tmp_path / "other.csv"
    main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "3", "--out", str(again)])
    main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "4", "--out", str(other)])
    assert rec.read_bytes() == again.read_bytes()
    assert rec.read_bytes() != other.read_bytes()


def test_recorded_log_without_truth_columns(small, tmp_path):
    cfg, rec = small
    log = tmp_path / "log.parquet"
    pd.read_csv(rec).drop(columns=["alpha", "beta", "gamma"]).to_parquet(log)
    out = tmp_path / "id"
    assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(log), "--out", str(out)]) == 0
    est = pd.read_csv(out / "estimates.csv")
    assert list(est.columns) == ["name", "unit", "estimate", "sigma"]


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "platcal.cli", *args], capture_output=True, text=True)


CONFIG_CASES = {
    "unknown coefficient": ("truth: {DF_q: 1.0}", "truth.DF_q"),
    "position not three numbers": ("schemes:\n  short: {dwell_s: 4, positions: [[45, 0, 167], [1, 2]]}",
                                   "schemes.short.positions[2]"),
    "beta near 90": ("schemes:\n  short: {dwell_s: 4, positions: [[45, 89.5, 167]]}", "schemes.short.positions[1]"),
    "dwell zero": ("schemes:\n  short: {dwell_s: 0, positions: [[45, 0, 167]]}", "schemes.short.dwell_s"),
    "negative noise": ("noise: {sigma_a_ug: -1}", "noise.sigma_a_ug"),
    "wrong type": ("filter: {passes: two}", "filter.passes"),
    "unknown key": ("filtre: {passes: 2}", "(top level)"),
}


@pytest.mark.parametrize("case", sorted(CONFIG_CASES))
def test_bad_config_exits_2_naming_the_field(case, tmp_path):
    override, field = CONFIG_CASES[case]
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(with_sections(SMALL, override))  # the override's section replaces SMALL's
    out = tmp_path / "out.csv"
    r = run_cli("simulate", "--config", str(cfg), "--scheme", "short", "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert field in r.stderr
    assert not out.exists()


def test_unknown_scheme(small, tmp_path):
    cfg, _ = small
    r = run_cli("simulate", "--config", str(cfg), "--scheme", "nope", "--out", str(tmp_path / "x.csv"))
    assert r.returncode == 2 and "--scheme" in r.stderr and "nope" in r.stderr
    assert not (tmp_path / "x.csv").exists()


def _mangle(df: pd.DataFrame, how: str) -> pd.DataFrame:
    df = df.copy()
    if how == "missing column":
        return df.drop(columns=["Ay"])
    if how == "extra column":
        df["temperature"] = 20.0
        return df
    if how == "nan":
        df.loc[10, "Ax"] = np.nan
        return df
    if how == "inf":
        df.loc[11, "t"] = np.inf
        return df
    if how == "time not increasing":
        df.loc[5, "t"] = df.loc[3, "t"]
        return df
    if how == "position not in scheme":
        df.loc[df.index[-1], "position"] = 7
        return df
    raise ValueError(how)


DATA_CASES = {
    "missing column": "column Ay",
    "extra column": "column temperature",
    "nan": "column Ax, row 12",
    "inf": "column t, row 13",
    "time not increasing": "column t, position 1",
    "position not in scheme": "column position",
}


@pytest.mark.parametrize("case", sorted(DATA_CASES))
def test_bad_data_exits_2_naming_the_field(case, small, tmp_path):
    cfg, rec = small
    bad = tmp_path / "bad.csv"
    _mangle(pd.read_csv(rec), case).to_csv(bad, index=False)
    out = tmp_path / "id"
    r = run_cli("identify", "--config", str(cfg), "--scheme", "short", "--data", str(bad), "--out", str(out))
    assert r.returncode == 2, r.stderr
    assert DATA_CASES[case] in r.stderr
    assert not out.exists()


def test_simulate_seed_is_replicate_of_the_study_cell(tmp_path, small):
    """``platcal simulate --seed 3`` writes replicate 3 of the Monte Carlo cell of that scheme at
    the config's sigma_a (the runner's SeedSequence), so a run of the study can be written out;
    without --seed, replicate 0."""
    cfg, rec = small
    study = load_config(cfg)
    scheme = study.schemes["short"]
    params = study.centrifuge.scheme_params(scheme)
    for r, path in ((3, rec), (0, tmp_path / "r0.csv")):
        if r == 0:
            assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--out", str(path)]) == 0
        sim = simulate(study.truth, scheme, params, study.noise,
                       [replicate_seed(study.seed, "short", study.noise.sigma_a_ug, r)], sample_s=study.sample_s)
        want = sim_to_frame(sim, scheme)
        got = pd.read_csv(path)
        assert list(got.columns) == list(want.columns)
        np.testing.assert_array_equal(got.to_numpy(float), want.to_numpy(float))
    other = simulate(study.truth, scheme, params, study.noise,
                     [replicate_seed(study.seed, "short", study.noise.sigma_a_ug, 4)], sample_s=study.sample_s)
    assert not np.allclose(pd.read_csv(rec)[["Ax"]].to_numpy().ravel(), sim_to_frame(other, scheme)["Ax"].to_numpy())
