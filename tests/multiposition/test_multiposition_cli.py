"""CLI of the multiposition rig: simulate, identify, bad input (exit 2, nothing written)."""

import json

import numpy as np
import pandas as pd
import pytest
import sympy as sp

from platcal.cli import main
from platcal.rigs.multiposition.lie_symbolic import symbolic_model
from platcal.rigs.multiposition.model import Site

CUSTOM = """rig: multiposition
truth: {DF_x: -3.1, DI_y: 0.4, DS_z: -2.2, DO_x: 1.7, k0_y: -850, k1_z: 420, theta_px: -75, theta_oz: 33}
schemes:
  odd: {dwell_s: 2, positions: [[17, 12.5, 203], [250, -29, 41], [333, 0, 290]]}
"""


def _write(tmp_path, text, name="c.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_noise_free_t0_equals_h_at_phi0(tmp_path, cfg):
    """With --noise-free the t = 0 sample of each position is h(x) at phi = 0 (to 1e-3 ug),
    h evaluated by the symbolic model (an independent writing of §6-7)."""
    from platcal.rigs.multiposition.config import load_config
    from platcal.io import read_yaml

    c = _write(tmp_path, CUSTOM)
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", c, "--scheme", "odd", "--noise-free", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    cc = load_config(read_yaml(CUSTOM))
    x, p, f, h = symbolic_model(0)
    hf = sp.lambdify([x, p], h, modules="numpy")
    xv = np.concatenate([np.zeros(3), cc.truth()])
    assert xv[3] == -3.1 and xv[3 + 21 + 2] == 33
    for k, pos in enumerate(cc.scheme("odd").positions, start=1):
        row = df[(df.position == k) & (df.t == 0)].iloc[0]
        want = np.array(hf(xv, [*np.radians(pos), *Site().params()]), float)
        got = row[["Ax", "Ay", "Az"]].to_numpy(float) * 1e6
        np.testing.assert_allclose(got, want[:3], atol=1e-3, rtol=0)
        np.testing.assert_allclose(row[["alpha_m", "beta_m", "gamma_m"]].to_numpy(float), pos, atol=1e-9)
    assert len(df) == 3 * 101


def test_simulate_identify_round_trip(tmp_path):
    c = _write(tmp_path, "rig: multiposition\n")
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", c, "--scheme", "TET4", "--seed", "4", "--out", str(rec)]) == 0
    df = pd.read_csv(rec)
    assert {"alpha_m", "beta_m", "gamma_m", "alpha", "Ax"} <= set(df.columns)
    assert main(["identify", "--config", c, "--data", str(rec), "--out", str(tmp_path / "id")]) == 0
    s = json.loads((tmp_path / "id" / "summary.json").read_text())
    assert s["nees_dof"] == 24 and 0 < s["nees"] < 100 and s["max_abs_rel_err_pct_gyro"] < 5
    est = pd.read_csv(tmp_path / "id" / "estimates.csv")
    assert len(est) == 24 and est["name"].iloc[0] == "DF_x"
    # a recorded log (no truth columns) is identified the same way, with the scheme named
    df.drop(columns=["alpha", "beta", "gamma"]).to_csv(tmp_path / "log.csv", index=False)
    assert main(["identify", "--config", c, "--scheme", "TET4", "--data", str(tmp_path / "log.csv"),
                 "--out", str(tmp_path / "id2")]) == 0
    e2 = pd.read_csv(tmp_path / "id2" / "estimates.csv")
    np.testing.assert_allclose(e2["estimate"], est["estimate"], rtol=1e-9)
    assert "nees" not in json.loads((tmp_path / "id2" / "summary.json").read_text())


BAD_CONFIGS = [
    ("rig: multiposition\nschemes: {B: {positions: [[0, 31, 0]]}}\n", "schemes.B.positions[1]"),
    ("rig: multiposition\ngimbal: {beta_max_deg: 10}\nschemes: {B: {positions: [[0, 0, 0], [90, -12, 0]]}}\n",
     "schemes.B.positions[2]"),
    ("rig: multiposition\nschemes: {E: {positions: []}}\n", "schemes.E.positions"),
    ("rig: multiposition\nnoise: {sigma_an_arcsec: 0}\n", "noise.sigma_an_arcsec"),
    ("rig: multiposition\nnoise: {sigma_an_arcsec: -1}\n", "noise.sigma_an_arcsec"),
    ("rig: multiposition\ntruth: {DF_q: 1}\n", "truth.DF_q"),
]


@pytest.mark.parametrize("text, field", BAD_CONFIGS)
def test_bad_config_exits_2_naming_field(tmp_path, capsys, text, field):
    c = _write(tmp_path, text)
    out = tmp_path / "out"
    for argv in (["simulate", "--config", c, "--scheme", "S8", "--out", str(out / "r.csv")],
                 ["observability", "--config", c, "--scheme", "S8", "--out", str(out)]):
        assert main(argv) == 2
        assert field in capsys.readouterr().err
    assert not out.exists()


def test_bad_record_and_options(tmp_path, capsys):
    c = _write(tmp_path, "rig: multiposition\nschemes: {tiny: {dwell_s: 1, positions: [[0, 0, 0], [90, 0, 0]]}}\n")
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", c, "--scheme", "tiny", "--out", str(rec)]) == 0
    pd.read_csv(rec).drop(columns=["beta_m"]).to_csv(tmp_path / "bad.csv", index=False)
    out = tmp_path / "id"
    assert main(["identify", "--config", c, "--data", str(tmp_path / "bad.csv"), "--out", str(out)]) == 2
    assert "beta_m" in capsys.readouterr().err
    assert main(["identify", "--config", c, "--scheme", "S8", "--data", str(rec), "--out", str(out)]) == 2
    assert "--data position 2" in capsys.readouterr().err
    assert main(["simulate", "--config", c, "--scheme", "tiny", "--platform", "p", "--out", str(out / "r.csv")]) == 2
    assert "--platform" in capsys.readouterr().err
    assert main(["simulate", "--config", c, "--scheme", "nope", "--out", str(out / "r.csv")]) == 2
    assert "--scheme" in capsys.readouterr().err
    assert main(["observability", "--config", c, "--scheme", "tiny", "--doo", "--out", str(out)]) == 2
    assert "--doo" in capsys.readouterr().err
    assert not out.exists()
