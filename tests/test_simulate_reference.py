"""The simulator against a plain-numpy implementation of the spec written separately here.

The reference below is written from ``spec/centrifuge-model.md`` sections 1-8 without using
any platcal function, so that a convention slip in one is caught by the other.
"""

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from platcal.rigs.centrifuge.base import Centrifuge
from platcal.model.instruments import FULL_NAMES
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.scheme import check_scheme
from platcal.rigs.centrifuge.simulate import Noise, simulate

G = 9.80665
OMEGA = 7.2921151467e-5
UG = 1e-6
AS = np.pi / 180 / 3600


def mx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, s], [0, -s, c]])


def my(b):
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]])


def mz(g):
    c, s = np.cos(g), np.sin(g)
    return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])


def reference(truth: dict, positions_deg, dwell, lat_deg=28.2, rate_deg_s=180.0, g_level=10.0, dt=0.005):
    wc = np.deg2rad(rate_deg_s)
    ro = g_level * G / wc**2
    lat = np.deg2rad(lat_deg)
    wn, wu = OMEGA * np.cos(lat), OMEGA * np.sin(lat)
    w_ie = np.array([0, wn, wu])
    cg = [np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]),
          np.array([[0, 1, 0], [0, 0, -1], [-1, 0, 0]]),
          np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]])]
    q = lambda n: truth[n]

    def fr(t):
        a = wc**2 * ro + 2 * wc * ro * wu
        return np.array([-a * np.cos(wc * t), -a * np.sin(wc * t), 2 * wc * ro * wn * np.sin(wc * t) + G])

    def cmat(x):
        return mz(x[2]) @ my(x[1]) @ mx(x[0])

    def rhs(x, t):
        C = cmat(x)
        f = C @ fr(t) / G
        eps = np.zeros(3)
        for j, ax in enumerate("xyz"):
            aI, aO, aS = cg[j] @ f
            eps[j] = (q(f"DF_{ax}") + q(f"DI_{ax}") * aI + q(f"DO_{ax}") * aO + q(f"DS_{ax}") * aS
                      + q(f"DII_{ax}") * aI**2 + q(f"DOO_{ax}") * aO**2 + q(f"DSS_{ax}") * aS**2
                      + q(f"DIO_{ax}") * aI * aO + q(f"DIS_{ax}") * aI * aS + q(f"DOS_{ax}") * aO * aS)
        eps_rad = eps * np.pi / 180 / 3600
        b, g = x[1], x[2]
        E = np.array([[np.cos(b) * np.cos(g), np.sin(g), 0], [-np.cos(b) * np.sin(g), np.cos(g), 0],
                      [np.sin(b), 0, 1]])
        return -np.linalg.solve(E, eps_rad + C @ w_ie)

    def out(x, t):
        f = cmat(x) @ fr(t) / G
        tpy, tpz, toz = q("theta_py") * AS, q("theta_pz") * AS, q("theta_oz") * AS
        ca = [np.eye(3), np.array([[tpy, 1, 0], [0, 0, -1], [-1, tpy, 0]]),
              np.array([[tpz, toz, 1], [0, 1, -toz], [-1, 0, tpz]])]
        A = np.zeros(3)
        for j, ax in enumerate("xyz"):
            aI, aP, _ = ca[j] @ f
            A[j] = (q(f"k0_{ax}") * UG + (1 + q(f"k1_{ax}") * UG) * aI + q(f"k2_{ax}") * UG * aI**2
                    + q(f"k3_{ax}") * UG * aI**3 + q(f"kIP_{ax}") * UG * aI * aP)
        return A

    n = int(round(dwell / dt))
    rows = []
    for pos in positions_deg:
        x = np.deg2rad(np.array(pos, float))
        for i in range(n):
            t = i * dt
            rows.append(np.concatenate([out(x, t), np.rad2deg(x)]))
            k1 = rhs(x, t)
            k2 = rhs(x + dt / 2 * k1, t + dt / 2)
            k3 = rhs(x + dt / 2 * k2, t + dt / 2)
            k4 = rhs(x + dt * k3, t + dt)
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(rows)


@pytest.mark.parametrize("case", [0, 1, 2])
def test_noise_free_simulation_matches_reference(case):
    r = np.random.default_rng(100 + case)
    positions = [[float(r.integers(0, 360)), float(r.uniform(-60, 60)), float(r.integers(0, 360))] for _ in range(3)]
    truth = full_truth() * r.uniform(0.2, 3.0, 48)
    truth[45:] = r.uniform(-0.1, 0.1, 3)
    lat, rate, level = r.uniform(-60, 60), r.uniform(60, 240), r.uniform(2, 20)
    dwell = 1.5
    ref = reference(dict(zip(FULL_NAMES, truth)), positions, dwell, lat, rate, level)
    scheme = check_scheme("s", {"dwell_s": dwell, "positions": positions})
    cen = Centrifuge(rate_deg_s=rate, g_level=level, latitude_deg=lat)
    sim = simulate(truth, scheme, cen.scheme_params(scheme), Noise(), None)
    A = sim.A[0].reshape(-1, 3)
    ang = np.rad2deg(sim.angles[0].reshape(-1, 3))
    assert A.shape == ref[:, :3].shape
    np.testing.assert_allclose(A, ref[:, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ang, ref[:, 3:], rtol=0, atol=1e-10)
    # the attitude actually drifts, so the comparison exercises the dynamics
    assert np.abs(ang[-1] - positions[-1]).max() > 1e-6


def test_cli_noise_free_record_matches_reference(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(
        "site: {latitude_deg: 40}\ncentrifuge: {rate_deg_s: 120, g_level: 8}\n"
        "truth: {DF_x: 20.0, DOO_y: 0.07, DIS_z: 0.3}\n"
        "schemes:\n  s: {dwell_s: 0.5, positions: [[10, 25, 300], [200, -40, 15]]}\n")
    out = tmp_path / "r.csv"
    subprocess.run([sys.executable, "-m", "platcal.cli", "simulate", "--config", str(cfg), "--scheme", "s",
                    "--noise-free", "--out", str(out)], check=True)
    df = pd.read_csv(out)
    assert list(df.columns) == ["position", "t", "alpha_cmd", "beta_cmd", "gamma_cmd", "Ax", "Ay", "Az",
                                "alpha", "beta", "gamma"]
    truth = full_truth({"DF_x": 20.0, "DOO_y": 0.07, "DIS_z": 0.3})
    ref = reference(dict(zip(FULL_NAMES, truth)), [[10, 25, 300], [200, -40, 15]], 0.5, 40, 120, 8)
    np.testing.assert_allclose(df[["Ax", "Ay", "Az"]].to_numpy(), ref[:, :3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(df["t"].to_numpy()[:3], [0, 0.005, 0.01])
    assert df["position"].tolist() == [1] * 100 + [2] * 100
