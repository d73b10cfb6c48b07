"""docs/rocket-sled.md §11 "What an implementation must show", items 1-7, on seeds 0-19."""

import numpy as np
import pandas as pd
import pytest

from platcal.rigs.sled.config import ARCSEC, load_config
from platcal.rigs.sled.errmodel import propagate_full
from platcal.rigs.sled.ins import mechanise
from platcal.rigs.sled.observability import rank_table
from platcal.rigs.sled.sensors import accel_error, gyro_error
from platcal.rigs.sled.simulate import record_rotation
from platcal.rigs.sled.trajectory import true_imu


def rms(x):
    return float(np.sqrt(np.mean(np.asarray(x) ** 2)))


def test_item1_scenario(batch, run6):
    _, m = run6
    tr = batch.traj
    assert tr.n_stop == 5180 and tr.stop_time_s == pytest.approx(25.90, abs=1e-9)
    assert tr.run_length_m == pytest.approx(4075.8, abs=0.5)
    assert tr.v_max_m_s == pytest.approx(294.2, abs=0.05)
    assert tr.n == 17180
    yz = m["yz_before_max_run_cm"] / 100
    assert yz.max() > 3.0


@pytest.mark.xfail(strict=True, reason="docs/rocket-sled.md §12: with the runner's streams (issue 19) the "
                   "run-phase Y/Z RMS of replicates 0-19 is 4.08 m; its expectation is 3.67 m (200 replicates), "
                   "outside the spec's 1.5-3.0 m window, which the old seeds met with phi_z draws of RMS 131 arcsec")
def test_item1_yz_rms_window(run6):
    yz = run6[1]["yz_before_max_run_cm"] / 100
    assert 1.5 <= rms(yz) <= 3.0


@pytest.fixture(scope="module")
def linear_vs_ins(batch):
    """§5's full error model driven by the true errors vs the INS, whole test: (max |difference|
    in m, the INS's position errors, the gyro drive's deviation from its deterministic part)."""
    cfg = load_config({"rig": "sled"})
    p = batch.truth.params
    f, w = true_imu(batch.traj, cfg.omega_ie)
    # the spec's form of §4: body-frame samples f̃, ω̃ and Ĉ_0 = exp(−[φ0×])
    Rt = record_rotation(p.phi0).transpose(0, 2, 1)
    fm = np.einsum("sij,snj->sni", Rt, batch.f)
    wm = np.einsum("sij,snj->sni", Rt, batch.w)
    v, r, fl = mechanise(fm, wm, p.phi0, cfg.omega_ie, cfg.dt)
    vt, rt, _ = mechanise(f[None], w[None], np.zeros((1, 3)), cfg.omega_ie, cfg.dt)
    nabla = fm - f                    # all accelerometer errors incl. noise, in l (C = I)
    eps = wm - w
    assert np.abs(nabla.mean(axis=1) - accel_error(p, f).mean(axis=1)).max() < 1.5e-4   # noise averages out (sigma 2e-5)
    _, dr, _ = propagate_full(fl, cfg.omega_ie, p.phi0, nabla, eps, cfg.dt)
    err = np.abs((r - rt) - dr).max()
    print(f'linear model vs INS: max |difference| {100 * err:.3f} cm over the whole test')
    return err, r - rt, eps - gyro_error(p, f)


def test_item2_linear_model_matches_nonlinear_ins(linear_vs_ins):
    err, dr_ins, gyro_noise = linear_vs_ins
    assert err <= 0.02, err                      # the spec's 1 cm: see the next test
    assert np.abs(dr_ins).max() > 1.0            # the errors themselves are metres
    # gyro noise is in the drive too, at the config's ARW per sample: arw (rad/sqrt(s)) / sqrt(dt)
    cfg = load_config({"rig": "sled"})
    per_sample = cfg.raw["imu"]["gyro"]["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(cfg.dt)
    assert gyro_noise.std() == pytest.approx(per_sample, rel=0.05), (gyro_noise.std(), per_sample)


@pytest.mark.xfail(strict=True, reason="docs/rocket-sled.md §12: 1.14 cm on replicates 0-19 of the runner's "
                   "streams (issue 19) against the spec's 1 cm; the second-order term grows with the phi_z draws")
def test_item2_within_the_specs_1_cm(linear_vs_ins):
    assert linear_vs_ins[0] <= 0.01


def test_item3_metric_a(run6, batch, case_runner):
    _, m = run6
    assert m["y_after_a_max_run_cm"].max() <= 1.0
    assert m["z_after_a_max_run_cm"].max() <= 1.0
    assert m["y_after_a_max_static_cm"].max() <= 1.0
    _, mp = case_runner(batch, tuning="paper")
    worst = mp[["y_after_a_max_run_cm", "z_after_a_max_run_cm", "y_after_a_max_static_cm"]].to_numpy().max()
    assert worst <= 30.0
    assert worst > 1.0          # the literal tuning is visibly worse


def test_item4_metric_b(run6, run7):
    _, m6 = run6
    _, m7 = run7
    assert rms(m7["y_after_b_max_run_cm"]) <= 3.0
    assert m7["y_after_b_max_run_cm"].max() <= 6.0
    assert rms(m7["z_after_b_max_run_cm"]) <= 30.0
    assert rms(m6["y_after_b_max_run_cm"]) >= 25.0


def test_item5_attitude(run6, run7):
    _, m6 = run6
    _, m7 = run7
    assert rms(m6["phi_y_eff_err_arcsec"]) <= 2.5
    assert rms(m6["phi_z_eff_err_arcsec"]) <= 3.0
    assert rms(m7["phi_x_eff_err_arcsec"]) <= 6.0
    # the estimate follows the effective, not the true angle (misalignment is not separable)
    assert rms(m6["phi_y_true_err_arcsec"]) > rms(m6["phi_y_eff_err_arcsec"])


def test_item6_x(run6, batch, batch_m0, case_runner):
    _, m = run6
    assert 40 <= rms(m["x_naive_stop_cm"]) <= 60
    _, mp = case_runner(batch, compensation="post")
    assert rms(mp["x_constrained_stop_cm"]) <= 12
    assert rms(mp["x_constrained_end_cm"]) <= 120
    for mm in (m, mp):
        assert rms(mm["x_naive_end_cm"]) >= 3 * rms(mm["x_constrained_end_cm"])
    _, m0 = case_runner(batch_m0, compensation="post")
    assert rms(m0["x_constrained_stop_cm"]) <= 3


SPEC_TABLE = """\
run 7-state|0|5/7|6/7|6/7|6/7|7/7
run 7-state|Earth rate|6/7|7/7|7/7|7/7|7/7
run 7-state|Earth rate + 0.01 rad/s about z|7/7|7/7|7/7|7/7|7/7
run 6-state|0|4/6|6/6|6/6|6/6|6/6
run 6-state|Earth rate|4/6|6/6|6/6|6/6|6/6
run 6-state|Earth rate + 0.01 rad/s about z|4/6|6/6|6/6|6/6|6/6
stop 6-state|Earth rate|6/6||||"""


def test_item7_observability_table_exact():
    tab = rank_table(load_config({"rig": "sled"})).set_index(["model", "omega"])
    cols = ["static", "boost 5 g", "coast -0.3 g", "brake -4 g", "whole run stacked"]
    for line in SPEC_TABLE.splitlines():
        model, omega, *ranks = line.split("|")
        got = tab.loc[(model, omega), cols].tolist()
        assert got == ranks, (model, omega, got)
    # the 0.1 rad/s azimuth rate of §8 too
    assert tab.loc[("run 7-state", "Earth rate + 0.1 rad/s about z"), "static"] == "7/7"


def test_metrics_table_keys(run7):
    _, m = run7
    keys = ["stop_time_s", "run_length_m", "v_max_m_s", "yz_before_max_run_cm", "y_after_a_max_run_cm",
            "z_after_a_max_run_cm", "y_after_b_max_run_cm", "z_after_b_max_run_cm", "x_naive_stop_cm",
            "x_constrained_stop_cm", "x_naive_end_cm", "x_constrained_end_cm", "phi_y_eff_err_arcsec",
            "phi_z_eff_err_arcsec", "phi_x_eff_err_arcsec"]
    assert set(keys) <= set(m.columns)
    assert isinstance(m, pd.DataFrame) and (m[keys].to_numpy() >= 0).all()


def test_sigma_is_consistent(run6, run7):
    """The filter's 1 sigma covers the effective-attitude error and is not grossly pessimistic
    either (loosely, 20 seeds: RMS error within sigma/4 .. 2 sigma); both in arcsec."""
    for _, m in (run6, run7):
        for ax in "yz":
            err, sig = rms(m[f"phi_{ax}_eff_err_arcsec"]), m[f"phi_{ax}_sigma_arcsec"].mean()
            assert sig / 4 < err < 2 * sig, (ax, err, sig)
    assert ARCSEC == pytest.approx(np.pi / (180 * 3600), rel=1e-15)  # the unit every column above uses
