"""Calibration applied (issue 21, item 4) on the centrifuge, the sled and the low-precision
centrifuge: ``platcal compensate`` with the true coefficients returns the error-free signal, with
the identified ones it removes most of the error."""

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.io import read_config
from platcal.logs.calibration import read_calibration
from platcal.model.frames import c_rp
from platcal.model.instruments import I_K0, I_THETA, INDEX, N_FULL, gyro_drift, gyro_drifts
from platcal.rig import get_rig
from platcal.rigs.centrifuge.simulate import simulate as centrifuge_simulate
from platcal.rigs.sled.config import ARCSEC
from platcal.rigs.sled.identify import compensated_track
from platcal.rigs.sled.simulate import record_rotation, simulate as sled_simulate

from .test_record_mapping import CENTRIFUGE, LOWPREC, SLED, write_cfg


def identified(tmp_path, cfg, sim_opts, id_opts, seed=2):
    """A calibration.yaml identified from replicate ``seed`` (any exit status: the fit check may
    flag a short test; the calibration is written either way)."""
    rec = tmp_path / "noisy.csv"
    assert main(["simulate", "--config", cfg, *sim_opts, "--seed", str(seed), "--out", str(rec)]) == 0
    assert main(["identify", "--config", cfg, "--data", str(rec), *id_opts, "--out", str(tmp_path / "id")]) in (0, 3)
    return tmp_path / "id" / "calibration.yaml"


def with_values(calfile, values, path):
    cal = yaml.safe_load(calfile.read_text())
    cal["values"] = [float(v) for v in values]
    path.write_text(yaml.safe_dump(cal))
    return path


def compensate(tmp_path, calfile, data, name):
    out = tmp_path / name
    assert main(["compensate", "--calibration", str(calfile), "--data", str(data), "--out", str(out)]) == 0
    return pd.read_csv(out)


@pytest.mark.slow
def test_centrifuge_compensate(tmp_path):
    cfg = write_cfg(tmp_path / "c.yaml", CENTRIFUGE)
    study = get_rig("centrifuge").load_config(read_config(cfg))
    scheme = study.schemes["short"]
    params = study.centrifuge.scheme_params(scheme)
    clean = tmp_path / "clean.csv"
    assert main(["simulate", "--config", cfg, "--scheme", "short", "--noise-free", "--out", str(clean)]) == 0
    # the error-free outputs: the same run with the accelerometer terms zero (they do not move the platform)
    free_truth = study.truth.copy()
    free_truth[I_K0:I_THETA + 3] = 0.0
    free = centrifuge_simulate(free_truth, scheme, params, study.noise, None, sample_s=study.sample_s)
    free_a = np.concatenate([free.A[0, k] for k in range(scheme.n_positions)])
    df = pd.read_csv(clean)
    rec_a = df[["Ax", "Ay", "Az"]].to_numpy()
    assert np.abs(rec_a - free_a).max() > 1e-5                 # the record carries the errors
    calfile = identified(tmp_path, cfg, ["--scheme", "short"], ["--scheme", "short"])
    cal = read_calibration(calfile)
    true = with_values(calfile, [study.truth[INDEX[n]] for n in cal.names], tmp_path / "true.yaml")
    got = compensate(tmp_path, true, clean, "comp_true.csv")[["Ax", "Ay", "Az"]].to_numpy()
    scale = np.abs(free_a).max()
    assert np.abs(got - free_a).max() <= 1e-9 * scale
    res = compensate(tmp_path, calfile, clean, "comp_id.csv")[["Ax", "Ay", "Az"]].to_numpy() - free_a
    assert np.abs(res).max() < 0.2 * np.abs(rec_a - free_a).max()
    # gyro outputs in the log (wx, wy, wz, deg/h): an error-free rate (Earth's, seen at the true
    # angles) plus the model's drift (eqs. 11-12) at the error-free specific force
    ang = np.radians(df[["alpha", "beta", "gamma"]].to_numpy())
    lat = np.radians(study.centrifuge.latitude_deg)
    w_ie = 15.041 * np.array([0.0, np.cos(lat), np.sin(lat)])
    free_w = np.array([c_rp(*a) @ w_ie for a in ang])
    drift_true = np.array([gyro_drift(study.truth, f) for f in free_a])
    assert np.abs(drift_true).max() > 1e-3                     # the gyro outputs carry the drift
    with_gyros = df.assign(wx=free_w[:, 0] + drift_true[:, 0], wy=free_w[:, 1] + drift_true[:, 1],
                           wz=free_w[:, 2] + drift_true[:, 2])
    with_gyros.to_csv(tmp_path / "gyros.csv", index=False)
    out = tmp_path / "comp_gyro.csv"
    assert main(["compensate", "--calibration", str(true), "--data", str(tmp_path / "gyros.csv"),
                 "--out", str(out)]) == 0
    got = pd.read_csv(out)
    assert np.abs(got[["Ax", "Ay", "Az"]].to_numpy() - free_a).max() <= 1e-9 * scale
    assert np.abs(got[["wx", "wy", "wz"]].to_numpy() - free_w).max() <= 1e-9 * np.abs(free_w).max()
    # identified coefficients: the gyro residual within the identification's sigma (5 sigma, every
    # sample); the drift is linear in the coefficients, so its Jacobian is the drift of unit vectors
    out = tmp_path / "comp_gyro_id.csv"
    assert main(["compensate", "--calibration", str(calfile), "--data", str(tmp_path / "gyros.csv"),
                 "--out", str(out)]) == 0
    res_w = pd.read_csv(out)[["wx", "wy", "wz"]].to_numpy() - free_w
    J = np.stack([gyro_drifts(np.eye(N_FULL)[INDEX[n]], free_a) for n in cal.names], axis=-1)   # (N, 3, n)
    sig_w = np.sqrt(np.einsum("tij,jk,tik->ti", J, cal.covariance, J))
    assert np.all(np.abs(res_w) <= 5 * sig_w + 1e-9)
    assert np.abs(res_w).max() < np.abs(drift_true).max()


@pytest.mark.slow
def test_sled_compensate(tmp_path):
    cfg = write_cfg(tmp_path / "c.yaml", SLED)
    sled = get_rig("sled").load_config(read_config(cfg))
    sb = sled_simulate(sled, [np.random.SeedSequence(0)], noise_free=True)
    phi0 = np.array([10.0, -30.0, 20.0]) * ARCSEC
    R = record_rotation(phi0)[0]
    t = np.arange(sb.f.shape[1]) * sled.dt
    rec = pd.DataFrame({"t": t, **{c: v for c, v in zip(("fx", "fy", "fz"), (sb.f[0] @ R.T).T)},
                        **{c: v for c, v in zip(("wx", "wy", "wz"), (sb.w[0] @ R.T).T)}})
    data = tmp_path / "tilted.csv"
    rec.to_csv(data, index=False)
    calfile = identified(tmp_path, cfg, [], [])
    cal = read_calibration(calfile)
    true = with_values(calfile, [{"phi_x": 10.0, "phi_y": -30.0, "phi_z": 20.0}.get(n, 0.0) for n in cal.names],
                       tmp_path / "true.yaml")
    got = compensate(tmp_path, true, data, "comp.csv")
    free = compensated_track(sled, sb.f[0], sb.w[0], t, np.zeros(3))
    n = sb.traj.n_stop
    before, after = abs(got.x_nav_m[n] - free.x_nav_m[n]), abs(got.x_m[n] - free.x_nav_m[n])
    assert before > 0.1                                       # 30 arcsec of pitch: tens of cm at the stop
    assert after < 1e-3 * before                              # first-order model: second-order residual
    assert abs(got.v_m_s[n] - free.v_nav_m_s[n]) < 1e-3 * abs(got.v_nav_m_s[n] - free.v_nav_m_s[n])


@pytest.mark.slow
def test_lowprec_compensate(tmp_path):
    cfg = write_cfg(tmp_path / "c.yaml", LOWPREC)
    opts = ["--platform", "P1", "--run", "run1"]
    clean = tmp_path / "clean.csv"
    assert main(["simulate", "--config", cfg, *opts, "--noise-free", "--out", str(clean)]) == 0
    df = pd.read_csv(clean)
    calfile = identified(tmp_path, cfg, opts, [])
    study = get_rig("lowprec_centrifuge").load_config(read_config(cfg))
    cal = read_calibration(calfile)
    true = with_values(calfile, [study.platforms["P1"][n] for n in cal.names], tmp_path / "true.yaml")
    got = compensate(tmp_path, true, clean, "comp_true.csv")
    for col, err in (("VE", "truth_dVE"), ("VN", "truth_dVN"), ("pE", "truth_dpE"), ("pN", "truth_dpN")):
        free = df[col] - df[err]                              # the noise-free record's errors are the coefficients'
        scale = max(np.abs(df[err]).max(), 1e-12)
        assert np.abs(df[err]).max() > 0
        # compensate integrates the §5 error model along the log's f; the record is the navigated INS
        # (lowprec insim.py), which that model follows to 0.5 % of the coefficients' error
        # (tests/lowprec_centrifuge/test_lowprec_insim.py): exact no longer, within that
        assert np.abs(got[col] - free).max() <= 5e-3 * scale, col
    ident = compensate(tmp_path, calfile, clean, "comp_id.csv")
    for col, err in (("pE", "truth_dpE"), ("pN", "truth_dpN")):
        assert np.abs(ident[col] - (df[col] - df[err])).max() < 0.2 * np.abs(df[err]).max()


def _calibration(path, rig, names):
    n = len(names)
    path.write_text(yaml.safe_dump({"rig": rig, "model_version": "x", "names": names, "units": ["u"] * n,
                                    "values": [1.0] * n, "covariance": np.eye(n).tolist(), "log_sha256": "0",
                                    "config": CENTRIFUGE if rig == "centrifuge" else {"rig": rig}}))
    return path


@pytest.mark.parametrize("rig, names, named", [
    ("sled", ["kA_x"], "lacks 'phi_y'"),                       # not a sled calibration's names
    ("centrifuge", ["DF_x", "kA_x"], "'kA_x' is not a coefficient"),
    ("lowprec_centrifuge", ["kA_x"], "lacks 'k2_x'"),
])
def test_compensate_refuses_calibration_names(tmp_path, capsys, rig, names, named):
    out = tmp_path / "out.csv"
    code = main(["compensate", "--calibration", str(_calibration(tmp_path / "cal.yaml", rig, names)),
                 "--data", "x.csv", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "--calibration key names" in err and named in err
    assert not out.exists()


def test_compensate_refuses_out_suffix(tmp_path, capsys):
    cal = _calibration(tmp_path / "cal.yaml", "centrifuge", ["k0_x"])
    code = main(["compensate", "--calibration", str(cal), "--data", "x.csv", "--out", str(tmp_path / "out.txt")])
    err = capsys.readouterr().err
    assert code == 2 and "--out" in err and ".csv or .parquet" in err


def test_compensate_refuses_some_gyro_columns(tmp_path, capsys):
    """Gyro outputs come as all of wx, wy, wz or none: a log with some exits 2 naming the first
    missing column, nothing written."""
    df = pd.DataFrame({"t": [0.0, 0.005], "Ax": [0.1, 0.1], "Ay": [0.2, 0.2], "Az": [1.0, 1.0], "wx": [1.0, 1.0]})
    df.to_csv(tmp_path / "log.csv", index=False)
    out = tmp_path / "out.csv"
    code = main(["compensate", "--calibration", str(_calibration(tmp_path / "cal.yaml", "centrifuge", ["DF_x"])),
                 "--data", str(tmp_path / "log.csv"), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "--data column wy" in err and "gyro outputs" in err
    assert not out.exists()
