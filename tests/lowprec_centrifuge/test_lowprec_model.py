"""Model pieces of the low-precision centrifuge rig (docs/lowprec-centrifuge.md §2-§8)."""

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import expm
from scipy.optimize import brentq

from platcal.errors import InputError
from platcal.rigs.lowprec_centrifuge.config import G0, load_config
from platcal.rigs.lowprec_centrifuge.metrics import compensate, effect, nonlinear_effect
from platcal.rigs.lowprec_centrifuge.profile import HOLD, STATIC, build_profile, kinematics, spinup_time
from platcal.rigs.lowprec_centrifuge.proposed import (DEG_H, f_matrix, find_windows, transition_and_h,
                                                       window_data)
from platcal.rigs.lowprec_centrifuge.traditional import design_matrix, identify_traditional
from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY
from platcal.rigs.lowprec_centrifuge.errormodel import integrate_error_model
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed


def S(replicates):
    """The study's SeedSequences of these replicates (root seed 0, accelerometer noise 10 ug/rtHz)."""
    return [replicate_seed(0, SEED_KEY, 10.0, r) for r in replicates]


@pytest.fixture(scope="module")
def study():
    return load_config({"rig": "lowprec_centrifuge"})


def small(**over):
    raw = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 5, "rest_between_s": 10},
           "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
           "runs": {"P1": {"run1": [3, 5]}}, "traditional": {"levels_g": [3, 5], "hold_s": 20, "rest_last_s": 5}}
    raw.update(over)
    return load_config(raw)


def test_defaults_complete_and_profile_lengths(study):
    assert study.centrifuge.arm_m == 3.0 and study.traditional["levels_g"] == [20, 30]
    # run lengths of §3: (13, 30) g -> 100 + 2*52 + 300 + 2*120 + 300 s
    p = build_profile(study, "P1", "run1")
    assert p.t[-1] == pytest.approx(1044.0, abs=0.011)
    assert build_profile(study, "P1", "run2").t[-1] == pytest.approx(1124.0, abs=0.011)
    tr = build_profile(study, "P1", "traditional")
    assert (tr.schedule == HOLD).sum() == pytest.approx(2 * 300 * 100, abs=2)


def test_spinup_respects_jerk_and_alpha_limits(study):
    cen = study.centrifuge
    p = build_profile(study, "P2", "run2")
    a = p.omega_nom**2 * cen.arm_m / G0            # commanded level, g
    dadt = np.diff(a) / p.dt
    # the spec's law min(a tau, sqrt(J g0 tau / r), w_L): dA/dt = J on the jerk branch; on the alpha
    # branch below the crossover w* = J g0 / (r a), dA/dt = 2 a^2 tau r / g0 reaches 2 J (spec as written)
    w_star = cen.jerk_g_s * G0 / (cen.arm_m * cen.alpha_max_rad_s2)
    jerk_branch = p.omega_nom[:-1] > w_star * 1.01
    assert np.abs(dadt[jerk_branch]).max() <= cen.jerk_g_s * 1.001
    assert np.abs(dadt).max() <= 2 * cen.jerk_g_s * 1.001
    assert np.abs(np.diff(p.omega_nom)).max() / p.dt <= cen.alpha_max_rad_s2 * 1.001
    assert a.max() == pytest.approx(40.0, rel=1e-9)
    # spin-down is the time reverse of spin-up: the rate profile of each spin is symmetric
    t_start = p.t[np.flatnonzero(p.schedule != STATIC)[0] - 1]       # first spin
    t_peak = t_start + spinup_time(13, cen)
    s = np.linspace(0, spinup_time(13, cen), 500)
    assert np.allclose(np.interp(t_peak + s, p.t, p.omega_nom), np.interp(t_peak - s, p.t, p.omega_nom), atol=2e-3)
    assert spinup_time(40, cen) == pytest.approx(160.0)
    assert spinup_time(0.01, cen) == pytest.approx(np.sqrt(0.01 * G0 / 3) / 0.3)   # alpha-limited


def test_kinematics_imprecise(study):
    cen = study.centrifuge
    p = build_profile(study, "P1", "run1")
    k = kinematics(p, cen, study.latitude_deg)
    # the true level is the nominal one times (1 + e_w)^2 (r_nom + dr + s A) / r_nom; the specific
    # force adds the Coriolis 2 w_ie sin L V (3.4e-3 m/s^2 at 36 m/s: 1.2e-5 of 30 g) and w_en x V
    i = np.argmax(p.omega_nom)
    a_true = np.hypot(*k.f[i]) / G0
    r = cen.arm_m + 2e-3 + 0.02e-3 * a_true
    assert a_true == pytest.approx(30 * (1 + 3e-4) ** 2 * r / cen.arm_m, rel=2e-5)
    # centripetal alone: the stretch load is A of the unstretched arm, A0 = w^2 (r_nom + dr) / g0
    r_exact = cen.arm_m + 2e-3 + 0.02e-3 * 30 * (1 + 3e-4) ** 2 * (cen.arm_m + 2e-3) / cen.arm_m
    assert k.omega[i] ** 2 * k.r[i] / G0 == pytest.approx(30 * (1 + 3e-4) ** 2 * r_exact / cen.arm_m, rel=1e-12)


def test_error_model_derivative_matches_F(study):
    """One Euler step of the §5 error model (the compensation's responses) = the §5 equations; they
    match F of §7 (phi_z f dropped)."""
    rng = np.random.default_rng(1)
    lat = np.radians(study.latitude_deg)
    x = np.concatenate([rng.normal(0, 0.1, 2), rng.normal(0, 10, 2), rng.normal(0, 1e-4, 3)])
    eps = rng.normal(0, 0.01, 3)                         # deg/h
    coef = np.array([0, 0, 0, 0, -40, -8, 25, -5]) * 1e-6
    a = np.array([0.7, -0.4])                            # g; constant specific force
    f = np.tile(a * G0, (2, 1))
    out, phi = np.empty((2, 4)), np.empty((2, 3))
    dt = 1e-3
    integrate_error_model(dt, f, coef, eps * DEG_H, x, np.zeros((0, 2)), np.zeros((0, 3)), np.sin(lat), np.cos(lat),
               np.tan(lat), out, phi)
    xdot_v = (out[1, :2] - out[0, :2]) / dt
    xdot_phi = (phi[1] - phi[0]) / dt
    m = np.array([abs(a[0]), abs(a[1]), a[0] ** 2, a[1] ** 2])
    F = f_matrix(lat, m)
    full = np.concatenate([x, [-40, -8, 25, -5], eps])
    ref = F @ full
    # the error model also has the phi_z f terms that F drops (zero mean over a revolution)
    ref[0] += x[6] * f[0, 1]
    ref[1] -= x[6] * f[0, 0]
    assert np.allclose(xdot_v, ref[:2], rtol=1e-9, atol=1e-12)
    assert np.allclose(xdot_phi, ref[4:7], rtol=1e-9, atol=1e-16)
    # position: p' = dV (+ dt dV'/2 in the Euler step)
    assert np.allclose((out[1, 2:] - out[0, 2:]) / dt, x[:2] + dt * ref[:2] / 2, rtol=1e-12)


def test_transition_series_and_window_mean_H(study):
    lat = np.radians(study.latitude_deg)
    F = f_matrix(lat, np.array([0.6, 0.6, 0.5, 0.5]) * 30)
    T = 0.6
    phi, H = transition_and_h(F, np.array(T))
    ft = F * T
    assert np.array_equal(phi, np.eye(14) + ft + ft @ ft / 2 + ft @ ft @ ft / 6)
    assert np.allclose(phi, expm(ft), rtol=1e-6, atol=1e-9)    # 4th-order terms are small
    # H = C mean_{t in [0,T]} Phi(t, T) = C mean expm(-F s), s in [0, T]
    s = np.linspace(0, T, 201)
    mean_phi = simpson(np.array([expm(-F * si) for si in s]), x=s, axis=0) / T
    # H is that mean to second order; what is left is the next term of the series, -(FT)^3/24
    assert np.allclose(H, mean_phi[:4], rtol=1e-5, atol=2e-5)
    assert np.allclose(H - (ft @ ft @ ft)[:4] / 24, mean_phi[:4], rtol=1e-7, atol=1e-9)


def test_compensation_about_the_floor_matches_renavigation(study):
    """§8 compensation (truth.py): e_after = e_floor + sum (c - c_hat)_k S_k against navigating the same
    INS (draws, noise) again with c - c_hat; c_hat off by a traditional-sized error (kA ~ 2x). The
    INS is not linear in the coefficients (the velocity errors of 17 m/s enter the transport-rate
    terms), so the former e_before - sum c_hat S is off by up to 4e-3 |before| on VN; about the
    floor the error is second order in c_hat - c. Bound: 1e-4 |before| (0.01 percentage point of
    the effect, the tables' last digit)."""
    seeds = S([0, 1])
    ra = simulate_batch(study, "P2", "run2", seeds, floor=True)
    d = np.array([-37.0, 2.6, -20.0, 1.5])          # c_hat - c
    raw = dict(study.raw)
    raw["platforms"] = {**study.raw["platforms"], "P2": dict(zip(("kA_x", "k2_x", "kA_y", "k2_y"), (-d).tolist()))}
    exact = simulate_batch(load_config(raw), "P2", "run2", seeds).final
    pred = compensate(ra.final_floor, ra.sens_final, np.tile(d, (2, 1)))
    assert np.all(np.abs(pred - exact) <= 1e-4 * np.abs(ra.final))
    assert np.all(np.abs(exact - ra.final_floor) > 1e3 * np.abs(pred - exact))   # the coefficients matter
    assert np.abs(compensate(ra.final, ra.sens_final, np.tile(ra.coeffs + d, (2, 1))) - exact).max() > 1e-3


def test_windows_interpolated_crossings(study):
    """Window ends = times where theta = gamma_0 + 2 pi k (found by root finding on the true angle)."""
    p = build_profile(study, "P1", "run1")
    k = kinematics(p, study.centrifuge, study.latitude_deg)
    rng = np.random.default_rng(0)
    noisy = k.theta + rng.normal(0, 20 / 206265, k.theta.size)
    wrapped = np.radians(np.mod(np.degrees(noisy), 360.0))
    w = find_windows(p.t, np.unwrap(wrapped), p.schedule)
    spin = w.te[w.spinning]
    ia = np.flatnonzero(p.schedule != STATIC)[0] - 1
    th = lambda t: np.interp(t, p.t, k.theta)  # noqa: E731
    exact = [brentq(lambda t: th(t) - th(p.t[ia]) - 2 * np.pi * n, p.t[ia], p.t[-1]) for n in (1, 2, 10, 30)]
    assert np.abs(spin[[0, 1, 9, 29]] - exact).max() < 2e-3
    assert w.ts[w.spinning][0] == pytest.approx(p.t[ia])
    # static windows are 1 s; revolutions tile each spin without gaps
    assert np.allclose((w.te - w.ts)[~w.spinning][:50], 1.0)
    assert np.allclose(w.ts[1:], w.te[:-1])
    # ~ total revolutions of the two spins + 2 partial windows + static seconds
    revs = (k.theta[-1] - k.theta[0]) / (2 * np.pi)
    assert w.spinning.sum() == pytest.approx(revs + 2, abs=2)


def test_window_observation_removes_the_centrifuge(study):
    """For full revolutions the mean of the true velocity is 0 for any rate, arm or stretch (§7)."""
    cen = study.centrifuge.with_imprecision(1e-2, 30.0, 0.05)
    st = study.with_centrifuge(cen)
    p = build_profile(st, "P1", "run1")
    k = kinematics(p, cen, study.latitude_deg)
    win, T, z, m = window_data(p.t, k.v, k.p - k.p[0], k.theta, k.f, p.schedule, study.centrifuge.arm_m)
    full = win.spinning & (T < 3.0) & np.r_[win.spinning[1:], False]
    assert np.abs(z[full, :2]).max() < 2e-3                  # m/s, against 36 m/s of true speed
    # m1, m2 of a steady revolution: (2/pi) A and A^2/2
    i = np.argmax(np.where(full, m[:, 2], 0))
    a = np.sqrt(2 * m[i, 2])
    assert m[i, 0] == pytest.approx(2 / np.pi * a, rel=1e-3)


def test_traditional_eq2_inverts_its_own_model():
    kA, k2 = -40.0, -8.0
    M = design_matrix([20, 30], [300, 300])
    dv = M @ [kA, k2]
    assert np.allclose(np.linalg.solve(M, dv), [kA, k2])
    assert dv[0] == pytest.approx(G0 * 300 * (kA * 2 / np.pi * 20 + k2 * 200) * 1e-6)


def test_traditional_on_synthetic_plateaus():
    """A record whose velocity error grows exactly as eq. (2) says is identified exactly."""
    t = np.arange(0, 100, 0.01)
    sched = np.zeros(t.size, dtype=np.int8)
    sched[1000:4000], sched[5000:8000] = HOLD, HOLD
    sched[4000:5000], sched[8000:9000], sched[100:1000] = 1, 1, 1
    c = np.array([30.0, 5.0, -20.0, 2.0])
    dv = np.zeros((t.size, 2))
    for (a, lvl) in (((1000, 4000), 20.0), ((5000, 8000), 30.0)):
        for ax in (0, 1):
            rate = G0 * 1e-6 * (c[2 * ax] * 2 / np.pi * lvl + c[2 * ax + 1] * lvl**2 / 2)
            dv[a[0]:a[1], ax] += rate * (t[a[0]:a[1]] - t[a[0]])
            dv[a[1]:, ax] += rate * (t[a[1] - 1] - t[a[0]])
    psi = np.linspace(0, 300, t.size)
    w = np.where(t < 45, np.sqrt(20 * G0 / 3), np.sqrt(30 * G0 / 3))
    v = w[:, None] * 3 * np.stack([-np.sin(psi), np.cos(psi)], axis=1) + dv
    est = identify_traditional(t, v[None], psi[None], sched, [20, 30], 3.0)[0]
    assert np.allclose(est, c, rtol=1e-9)


def test_effect_definitions():
    assert effect(np.array([-4.0]), np.array([0.4]))[0] == pytest.approx(90.0)
    assert effect(np.array([1.0]), np.array([-2.0]))[0] == pytest.approx(-100.0)
    assert nonlinear_effect(np.array([10.0]), np.array([1.5]), np.array([1.0]))[0] == pytest.approx(
        100 * (1 - 0.5 / 9))


@pytest.mark.parametrize("raw, field", [
    ({"centrifuge": {"arm_m": -3.0}}, "centrifuge.arm_m"),
    ({"centrifuge": {"jerk_g_s": 0.001}}, "runs.P1.run1[0]"),
    ({"traditional": {"levels_g": [30, 20]}}, "traditional.levels_g[1]"),
    ({"runs": {"P1": {"run1": [13, -30]}, "P2": {"run1": [13, 35]}}}, "runs.P1.run1[1]"),
    ({"platforms": {"P1": {"kA_x": 1, "k2_x": 1, "kA_y": 1}}}, "platforms.P1"),
    ({"centrifuge": {"rate_error": float("nan")}}, "centrifuge.rate_error"),
    ({"nosuch": 1}, "(top level)"),
])
def test_bad_config_names_the_field(raw, field):
    with pytest.raises(InputError) as ei:
        load_config({"rig": "lowprec_centrifuge", **raw})
    assert ei.value.field == field


def test_same_seed_same_numbers_whatever_the_batch():
    st = small()
    one = simulate_batch(st, "P1", "run1", S([3]))
    many = simulate_batch(st, "P1", "run1", S([0, 1, 2, 3]))
    assert np.array_equal(one.v_ind[0], many.v_ind[3]) and np.array_equal(one.psi[0], many.psi[3])
    assert np.array_equal(one.err[0], many.err[3])
    assert not np.array_equal(many.err[0], many.err[3])


def test_proposed_filter_covariance_is_symmetric_positive_definite():
    from platcal.rigs.lowprec_centrifuge.proposed import identify_proposed

    st = small()
    rb = simulate_batch(st, "P1", "run1", S([0, 1]))
    res = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, rb.prof.schedule,
                            st.centrifuge.arm_m, st.latitude_deg)
    for P in res.P:
        assert np.array_equal(P, P.T)
        assert np.linalg.eigvalsh(P / np.outer(np.sqrt(np.diag(P)), np.sqrt(np.diag(P)))).min() > 0


def test_schema_defaults_are_the_spec_section_10_block():
    """Every key of the spec's §10 YAML block is in the schema with that default; config file = defaults."""
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[2]
    text = (root / "docs" / "lowprec-centrifuge.md").read_text()
    block = text.split("## 10.")[1].split("```yaml")[1].split("```")[0]
    spec = yaml.safe_load(block)
    got = load_config({"rig": "lowprec_centrifuge"}).raw

    def walk(a, b, path=""):
        for k, v in a.items():
            assert k in b, f"{path}{k} missing"
            if isinstance(v, dict):
                walk(v, b[k], f"{path}{k}.")
            else:
                assert b[k] == v, f"{path}{k}: {b[k]!r} != {v!r}"

    walk(spec, got)
    from platcal.io import read_yaml

    assert load_config(read_yaml((root / "config" / "lowprec_centrifuge.yaml").read_text())).raw == got
