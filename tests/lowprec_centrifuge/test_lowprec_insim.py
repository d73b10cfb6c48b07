"""The independent truth: the platform INS navigated through the table's motion (insim.py,
docs/lowprec-centrifuge.md §12 "Truth simulation"), against analytic cases and the §5 model."""

import numpy as np
import pytest

from platcal.rigs.lowprec_centrifuge.config import G0, OMEGA_IE, R_EARTH, load_config
from platcal.rigs.lowprec_centrifuge.insim import W, LaneOutputs
from platcal.rigs.lowprec_centrifuge.errormodel import integrate_error_model
from platcal.rigs.lowprec_centrifuge.profile import build_profile, kinematics
from platcal.rigs.lowprec_centrifuge.truth import (DEG_H, coeff_vector, draw_params, fine_truth, gyro_vector,
                                                    run_streams)
from platcal.study.montecarlo import replicate_seed

NONE8, NONE48, NONE3 = np.zeros(8), np.zeros(48), np.zeros(3)


@pytest.fixture(scope="module")
def study():
    return load_config({"rig": "lowprec_centrifuge"})


@pytest.fixture(scope="module")
def p2run2(study):
    return fine_truth(study, "P2", "run2")     # 40 g: the fastest motion


def test_true_motion_obeys_the_navigation_equation(study):
    """V' = f + (2 w_ie sin L + V_E tan L / R)(V_N, -V_E) along the run: the truth's specific force
    integrates to its velocity. The trapezoid is first order here (w' jumps at the spin start, the
    alpha/jerk switch and the level), so the error falls with the step: the bound at 3200 Hz is
    the jumps' h |d(r w')| / 2 summed over a run's spins (about 1e-3 m/s at 800 Hz)."""
    errs = []
    for sub in (8, 32):
        p = build_profile(study, "P1", "run1", sub)
        k = kinematics(p, study.centrifuge, study.latitude_deg)
        kt = 2 * OMEGA_IE * np.sin(k.lat) + k.v[:, 0] * np.tan(k.lat) / R_EARTH
        vd = np.stack([k.f[:, 0] + kt * k.v[:, 1], k.f[:, 1] - kt * k.v[:, 0]], axis=-1)
        v = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * p.dt * (vd[1:] + vd[:-1]), axis=0)])
        errs.append(np.abs(v - k.v).max())
    assert errs[1] < 5e-4                       # m/s, against 33 m/s of speed
    assert errs[1] < 0.3 * errs[0]              # first order: a quarter for a 4x finer step


def test_no_error_ins_reproduces_the_motion(study, p2run2):
    """Without sensor errors the INS (platform torqued at its computed rate, its own Coriolis and
    transport terms) follows the true motion: errors at round-off, the measured specific force the true one."""
    prof, kin, ft = p2run2
    err, phi, fm = ft.navigate(prof.t.size, NONE8, NONE48, NONE3, NONE3, keep_phi=True)
    assert np.abs(err[:, :2]).max() < 1e-12 and np.abs(err[:, 2:]).max() < 1e-9
    assert np.abs(phi).max() < 1e-15
    assert np.abs(fm - kin.f).max() < 1e-12
    assert np.abs(kin.f).max() > 300                  # the 40 g run


def test_pure_bias_gives_the_schuler_velocity_error(study, p2run2):
    """A bias b on the east accelerometer alone, the platform spinning: dV = (b/w_s) sin(w_s t)
    turned by the Foucault rate w_ie sin L (dV_E + i dV_N = (b/w_s) sin(w_s t) exp(-i w_ie sin L t)),
    w_s = sqrt(g0/R). Bound 0.5 % of the amplitude: the terms that formula drops are of order
    w_ie / w_s = 6 % squared (0.3 %)."""
    prof, kin, ft = p2run2
    b = 100e-6
    err, _, _ = ft.navigate(prof.t.size, np.r_[b, 0, 0, 0, 0, 0, 0, 0], NONE48, NONE3, NONE3)
    ws = np.sqrt(G0 / R_EARTH)
    lat = np.radians(study.latitude_deg)
    ref = b * G0 / ws * np.sin(ws * prof.t) * np.exp(-1j * OMEGA_IE * np.sin(lat) * prof.t)
    amp = np.abs(ref).max()
    assert np.abs(err[:, 0] - ref.real).max() < 5e-3 * amp
    assert np.abs(err[:, 1] - ref.imag).max() < 5e-3 * amp
    # the first rest (t <= 100 s, w_s t <= 0.12): b t (1 - (w_s t)^2/6) to 1e-4
    rest = (prof.t > 1) & (prof.t <= study.profile["rest_first_s"])
    assert np.abs(err[rest, 0] / ref.real[rest] - 1).max() < 1e-4


def test_pure_gyro_drift_tilts_the_platform(study, p2run2):
    """A drift eps_y alone: phi_y = eps_y t at first, so dV_E = -g0 eps_y t^2 / 2 (t << 84 min):
    at the end of the first rest (100 s) to 1 % (Schuler, (w_s t)^2/12 = 0.13 %)."""
    prof, kin, ft = p2run2
    eps = 0.01 * DEG_H
    err, phi, _ = ft.navigate(prof.t.size, NONE8, NONE48, np.array([0.0, eps, 0.0]), NONE3, keep_phi=True)
    k = np.searchsorted(prof.t, study.profile["rest_first_s"])
    t = prof.t[k]
    assert phi[k, 1] == pytest.approx(eps * t, rel=1e-2)
    assert err[k, 0] == pytest.approx(-G0 * eps * t**2 / 2, rel=1e-2)


def test_ins_agrees_with_the_section5_error_model(study):
    """Noise-free, no g-sensitive drift: the nonlinear INS's final errors against the §5 linear
    model (Euler at the data rate along the true f) with the same drawn residuals. Bound 2 %: §5
    drops the transport-rate terms, V^2 tan L / (2 R) = 9 ug mean at 36 m/s against the rectified
    bias of the coefficients, >= 500 ug at 13-40 g."""
    st = load_config({"rig": "lowprec_centrifuge", "residuals": {"gyro_g_deg_h_g": 0, "gyro_gg_deg_h_g2": 0}})
    lat = np.radians(st.latitude_deg)
    for platform, run in (("P1", "run1"), ("P2", "run2"), ("P1", "traditional")):
        prof, kin, ft = fine_truth(st, platform, run)
        n = prof.t.size
        par, _ = run_streams(replicate_seed(0, "insim", 10, 0), 1, 1)
        k0, sk, eps, phi0, gg = draw_params(st, np.random.default_rng(par))
        coef = np.concatenate([k0, sk, coeff_vector(st, platform)]) * 1e-6
        err, _, _ = ft.navigate(n, coef, gyro_vector(gg), eps * DEG_H, phi0)
        lin = np.empty((n, 4))
        integrate_error_model(prof.dt, np.ascontiguousarray(kin.f), coef, eps * DEG_H, np.r_[np.zeros(4), phi0],
                              np.zeros((0, 2)), np.zeros((0, 3)), np.sin(lat), np.cos(lat), np.tan(lat), lin,
                              np.zeros((0, 3)))
        assert np.all(np.abs(err[-1] - lin[-1]) <= 0.02 * np.abs(err[-1])), (platform, run, err[-1], lin[-1])


def test_integration_converged(study):
    """The truth at the default 2 RK4 steps per sample (200 Hz) against 8 (800 Hz): final errors
    within 1e-5 relative (the tables print effects to 0.01 % of the error before compensation)."""
    out = []
    for steps in (2, 8):
        st = load_config({"rig": "lowprec_centrifuge", "profile": {"truth_steps": steps}})
        prof, kin, ft = fine_truth(st, "P2", "run2")
        par, _ = run_streams(replicate_seed(0, "insim", 10, 1), 2, 2)
        k0, sk, eps, phi0, gg = draw_params(st, np.random.default_rng(par))
        coef = np.concatenate([k0, sk, coeff_vector(st, "P2")]) * 1e-6
        out.append(ft.navigate(prof.t.size, coef, gyro_vector(gg), eps * DEG_H, phi0)[0][-1])
    assert st.profile["truth_steps"] == 8 and load_config({"rig": "lowprec_centrifuge"}).profile["truth_steps"] == 2
    assert np.all(np.abs(out[0] - out[1]) <= 1e-5 * np.abs(out[1]))


def test_g_sensitive_drift_acts(study):
    """The gyros' g-sensitive terms (drawn per replicate) change the INS's errors: the same
    replicate with and without them differs (they are in the truth, not only in the config)."""
    par, _ = run_streams(replicate_seed(0, "insim", 10, 2), 1, 1)
    k0, sk, eps, phi0, gg = draw_params(study, np.random.default_rng(par))
    assert np.all(gg != 0) and gg.size == 18
    prof, kin, ft = fine_truth(study, "P1", "run1")
    coef = np.concatenate([k0, sk, coeff_vector(study, "P1")]) * 1e-6
    a = ft.navigate(prof.t.size, coef, gyro_vector(gg), eps * DEG_H, phi0)[0][-1]
    b = ft.navigate(prof.t.size, coef, np.zeros(48), eps * DEG_H, phi0)[0][-1]
    assert np.all(np.abs(a - b) > 1e-4 * np.abs(b))


def test_lanes_give_each_ins_the_numbers_of_navigating_it_alone(study):
    """The kernel navigates many INSs side by side (vectorised over lanes, in blocks of W): each
    lane's errors, attitude and measured force equal, bit for bit, those of that INS navigated
    alone, across a block boundary, with shared and absent noises."""
    prof, _, ft = fine_truth(study, "P1", "run1")
    n = 600                                    # the first 6 s: the rest and the spin-up's start
    K = W + 3
    rng = np.random.default_rng(5)
    coef = rng.normal(0.0, 30e-6, (K, 8))
    gcoef = np.stack([gyro_vector(rng.normal(0.0, 0.01, 18)) for _ in range(K)])
    eps = rng.normal(0.0, 0.01, (K, 3)) * DEG_H
    phi0 = rng.normal(0.0, 1e-4, (K, 3))
    acc_w = rng.standard_normal((2, n, 2)) * 1e-4
    gyro_w = rng.standard_normal((2, n, 3)) * 1e-7
    noise_of = np.array([k % 3 - 1 for k in range(K)])    # none, stream 0, stream 1, ...
    err, phi, fm = ft.navigate_lanes(n, coef, gcoef, eps, phi0, acc_w, gyro_w, noise_of, keep_phi=True)
    for k in range(K):
        w = noise_of[k]
        alone = ft.navigate(n, coef[k], gcoef[k], eps[k], phi0[k], acc_w[w] if w >= 0 else None,
                            gyro_w[w] if w >= 0 else None, keep_phi=True)
        assert np.array_equal(alone[0], err[k]) and np.array_equal(alone[1], phi[k])
        assert np.array_equal(alone[2], fm[k])
    assert not np.array_equal(err[1], err[4])       # the lanes differ


def test_lanes_write_into_the_rows_they_are_given(study):
    """Each lane's errors, force and attitude go straight into the rows of the caller's arrays
    that :class:`LaneOutputs` names (scattered, shared with other lanes' rows, -1: not stored,
    nothing else touched), bit for bit those of the lane in its own row; every lane's last errors
    are kept, stored or not (a floor's, :func:`simulate_batch`)."""
    prof, _, ft = fine_truth(study, "P2", "run1")
    n, K = 400, W + 2
    rng = np.random.default_rng(11)
    coef = rng.normal(0.0, 30e-6, (K, 8))
    gcoef = np.stack([gyro_vector(rng.normal(0.0, 0.01, 18)) for _ in range(K)])
    eps = rng.normal(0.0, 0.01, (K, 3)) * DEG_H
    phi0 = rng.normal(0.0, 1e-4, (K, 3))
    acc_w = rng.standard_normal((K, n, 2)) * 1e-4
    gyro_w = rng.standard_normal((K, n, 3)) * 1e-7
    noise_of = np.arange(K)
    own = ft.navigate_lanes(n, coef, gcoef, eps, phi0, acc_w, gyro_w, noise_of, keep_phi=True)
    err_row = rng.permutation(K + 3)[:K]
    err_row[[2, 9]] = -1
    f_row = rng.permutation(K)
    f_row[[0, 9, W + 1]] = -1
    out = LaneOutputs(err=np.full((K + 3, n, 4), np.nan), err_row=err_row, f=np.full((K, n, 2), np.nan),
                      phi=np.full((K, n, 3), np.nan), f_row=f_row, last=np.full((K, 4), np.nan))
    ft.navigate_lanes(n, coef, gcoef, eps, phi0, acc_w, gyro_w, noise_of, out=out)
    for k in range(K):
        assert np.array_equal(out.last[k], own[0][k, -1])
        if err_row[k] >= 0:
            assert np.array_equal(out.err[err_row[k]], own[0][k])
        if f_row[k] >= 0:
            assert np.array_equal(out.f[f_row[k]], own[2][k]) and np.array_equal(out.phi[f_row[k]], own[1][k])
    # the rows no lane was given are untouched
    assert np.isnan(np.delete(out.err, err_row[err_row >= 0], axis=0)).all()
    assert np.isnan(np.delete(out.f, f_row[f_row >= 0], axis=0)).all()
    assert np.isnan(np.delete(out.phi, f_row[f_row >= 0], axis=0)).all()
