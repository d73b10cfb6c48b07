"""Calibration out (issue 21, item 2): calibration.yaml on every rig, compensate on the multiposition rig."""

import hashlib

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.logs.calibration import read_calibration
from platcal.model.frames import DEG, c_rp
from platcal.rigs.multiposition.config import load_config as mp_config
from platcal.rigs.multiposition.model import coef_names, drift, measure

from .test_record_mapping import CENTRIFUGE, LOWPREC, MULTIPOSITION, SLED, write_cfg

CASES = {"centrifuge": (CENTRIFUGE, ["--scheme", "short"]), "multiposition": (MULTIPOSITION, ["--scheme", "short"]),
         "sled": (SLED, []), "lowprec_centrifuge": (LOWPREC, ["--platform", "P1", "--run", "run1"])}


@pytest.mark.slow
@pytest.mark.parametrize("rig", list(CASES))
def test_identify_writes_calibration(tmp_path, rig):
    raw, opts = CASES[rig]
    cfg = write_cfg(tmp_path / "c.yaml", raw)
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", cfg, *opts, "--out", str(rec)]) == 0
    id_opts = opts if rig in ("centrifuge", "multiposition") else []
    out = tmp_path / "id"
    assert main(["identify", "--config", cfg, "--data", str(rec), "--out", str(out), *id_opts]) == 0
    cal = read_calibration(out / "calibration.yaml")
    assert cal.rig == rig and cal.config["rig"] == rig
    assert cal.log_sha256 == hashlib.sha256(rec.read_bytes()).hexdigest()
    est = pd.read_csv(out / "estimates.csv")
    if rig == "sled":
        est = est[est["filter"].isin(["run", "stop"]) & est["name"].isin(cal.names)].drop_duplicates("name")
    est = est.set_index("name")
    for n, v, s in zip(cal.names, cal.values, cal.sigma):
        assert v == pytest.approx(est.loc[n, "estimate"], rel=1e-5, abs=1e-9), n
        if np.isfinite(s) and rig != "sled":
            assert s == pytest.approx(est.loc[n, "sigma"], rel=1e-6), n
    assert np.allclose(cal.covariance, cal.covariance.T, equal_nan=True)
    assert (out / "covariance.csv").exists()


@pytest.mark.slow
def test_multiposition_compensate(tmp_path, capsys):
    cfg = write_cfg(tmp_path / "c.yaml", MULTIPOSITION)
    clean, noisy = tmp_path / "clean.csv", tmp_path / "noisy.csv"
    assert main(["simulate", "--config", cfg, "--scheme", "short", "--noise-free", "--out", str(clean)]) == 0
    assert main(["simulate", "--config", cfg, "--scheme", "short", "--seed", "4", "--out", str(noisy)]) == 0
    assert main(["identify", "--config", cfg, "--data", str(noisy), "--scheme", "short", "--out",
                 str(tmp_path / "id")]) == 0
    calfile = tmp_path / "id" / "calibration.yaml"
    cal = read_calibration(calfile)
    df = pd.read_csv(clean)
    ang = df[["alpha", "beta", "gamma"]].to_numpy() * DEG
    free = np.array([measure(a, np.zeros(27))[0][:3] for a in ang]) * 1e-6      # error-free outputs, g
    # true coefficients: the error-free signal to 1e-9 of its scale (1 g)
    true = yaml.safe_load(calfile.read_text())
    true["values"] = [float(v) for v in mp_config(yaml.safe_load(open(cfg))).truth()]
    (tmp_path / "true.yaml").write_text(yaml.safe_dump(true))
    assert main(["compensate", "--calibration", str(tmp_path / "true.yaml"), "--data", str(clean),
                 "--out", str(tmp_path / "comp_true.csv")]) == 0
    assert "the log has no gyro outputs (wx, wy, wz, deg/h)" in capsys.readouterr().err   # said, not skipped
    got = pd.read_csv(tmp_path / "comp_true.csv")[["Ax", "Ay", "Az"]].to_numpy()
    raw_err = np.abs(df[["Ax", "Ay", "Az"]].to_numpy() - free).max()
    assert raw_err > 1e-5                                   # the record does carry the errors
    assert np.abs(got - free).max() <= 1e-9
    # identified coefficients: the residual within the identification's sigma (5 sigma, every sample)
    assert main(["compensate", "--calibration", str(calfile), "--data", str(clean),
                 "--out", str(tmp_path / "comp_id.csv")]) == 0
    res = (pd.read_csv(tmp_path / "comp_id.csv")[["Ax", "Ay", "Az"]].to_numpy() - free) * 1e6   # ug
    x = np.r_[np.zeros(3), cal.values]
    sig = np.array([np.sqrt(np.einsum("ij,jk,ik->i", H, cal.covariance, H))
                    for H in (measure(a, x)[1][:3, 3:] for a in ang)])
    assert np.all(np.abs(res) <= 5 * sig + 1e-6)
    assert np.abs(res).max() < raw_err * 1e6
    # gyro outputs in the log (wx, wy, wz, deg/h): an error-free rate (Earth's at the true angles)
    # plus the model's drift (§5) at the true angles
    truth = mp_config(yaml.safe_load(open(cfg))).truth()
    lat = np.radians(45.0)
    w_ie = 15.041 * np.array([0.0, np.cos(lat), np.sin(lat)])
    free_w = np.array([c_rp(*a) @ w_ie for a in ang])
    drift_true = np.array([drift(np.r_[np.zeros(3), truth], a) for a in ang])
    assert np.abs(drift_true).max() > 1e-3                      # the gyro outputs carry the drift
    gy = df.assign(**{c: free_w[:, i] + drift_true[:, i] for i, c in enumerate(("wx", "wy", "wz"))})
    gy.to_csv(tmp_path / "gyros.csv", index=False)
    assert main(["compensate", "--calibration", str(tmp_path / "true.yaml"), "--data", str(tmp_path / "gyros.csv"),
                 "--out", str(tmp_path / "comp_gyro.csv")]) == 0
    assert "accelerometers and gyros (wx, wy, wz) compensated" in capsys.readouterr().err
    got = pd.read_csv(tmp_path / "comp_gyro.csv")
    assert np.abs(got[["Ax", "Ay", "Az"]].to_numpy() - free).max() <= 1e-9
    assert np.abs(got[["wx", "wy", "wz"]].to_numpy() - free_w).max() <= 1e-9 * np.abs(free_w).max()


def test_compensate_refuses_bad_calibration(tmp_path, capsys):
    bad = tmp_path / "cal.yaml"
    bad.write_text("rig: multiposition\nnames: [a]\n")
    out = tmp_path / "out.csv"
    assert main(["compensate", "--calibration", str(bad), "--data", "x.csv", "--out", str(out)]) == 2
    assert "--calibration key" in capsys.readouterr().err
    assert not out.exists()
