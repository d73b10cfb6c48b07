"""Model pieces: trajectory (§2), Jacobians (§5-6), record convention (§4/§10), seeding (§3)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from platcal.rigs.sled.config import G, load_config
from platcal.rigs.sled.errmodel import run_F, skew, stop_F
from platcal.rigs.sled.filters import discretise
from platcal.rigs.sled.identify import _x_compensated, _x_corrections, compensate_modes, x_corrections_held
from platcal.rigs.sled.ins import _mechanise, mechanise
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.observability import rank
from platcal.rigs.sled.simulate import record_rotation, simulate
from platcal.rigs.sled.trajectory import build_trajectory, true_imu


def nonlinear_rates(x3, f, w, wc):
    """Exact 3-D error dynamics: δv̇ = (exp(−[φ×]) − I)·(−1)… written as Ĉ f − C f with the
    computed force f (so the true force is exp([φ×]) f), −2 ω×δv, φ̇ = −ω×φ."""
    dv, phi = x3[:3], x3[3:]
    ftrue = Rotation.from_rotvec(phi).apply(f)
    return np.r_[f - ftrue - 2 * np.cross(wc, dv), -np.cross(w, phi)]


def fd_jacobian(fun, x0, h=1e-7):
    return np.stack([(fun(x0 + h * e) - fun(x0 - h * e)) / (2 * h) for e in np.eye(len(x0))], axis=1)


@pytest.mark.parametrize("states", [6, 7])
def test_run_F_is_the_jacobian_of_the_error_dynamics(states):
    f, w = np.array([30.0, 0.4, 9.7]), np.array([3e-5, 2e-5, 5e-5])
    names = ["dv_y", "dr_y", "dv_z", "dr_z", "phi_x", "phi_y", "phi_z"]
    keep = [n for n in names if states == 7 or n != "phi_x"]

    def rates(x):
        s = dict(zip(keep, x))
        x3 = np.array([0.0, s["dv_y"], s["dv_z"], s.get("phi_x", 0.0), s["phi_y"], s["phi_z"]])
        d = nonlinear_rates(x3, f, w, w)
        # §5: δv_x is not a run state (its coupling dropped, as in eq. 4)
        out = {"dv_y": d[1], "dr_y": s["dv_y"], "dv_z": d[2], "dr_z": s["dv_z"],
               "phi_x": d[3], "phi_y": d[4], "phi_z": d[5]}
        return np.array([out[n] for n in keep])

    J = fd_jacobian(rates, np.zeros(states))
    assert np.allclose(run_F(f, w, states=states), J, atol=1e-9)


def test_stop_F_is_the_jacobian_of_the_zupt_dynamics():
    f, w = np.array([0.0, 0.0, G]), np.array([3e-5, 2e-5, 5e-5])

    def rates(x):
        vy, ry, vx, rx, px, py = x
        d = nonlinear_rates(np.array([vx, vy, 0.0, px, py, 0.0]), f, w, w)
        # §6.2: with δv_z = φ_z = 0 only the ω_z couplings remain
        return np.array([d[1], vy, d[0], vx, d[3], d[4]])

    J = fd_jacobian(rates, np.zeros(6))
    assert np.allclose(stop_F(f, w), J, atol=1e-9)


def test_discretisation_second_order():
    F = run_F(np.array([49.0, 0.0, G]), np.array([4e-5, 2e-5, 5e-5]), states=7)
    from scipy.linalg import expm
    T = 0.02
    err2 = np.abs(discretise(F, T) - expm(F * T)).max()
    err1 = np.abs(np.eye(7) + F * T - expm(F * T)).max()
    assert err2 < 1e-6 and err2 < 1e-2 * err1


def test_rank_helper():
    assert rank(np.diag([1.0, 1e-3, 1e-12])) == 2
    assert rank(np.diag([1.0, 1e-3, 1e-12]), rtol=1e-15) == 3
    assert rank(np.zeros((3, 3))) == 0


def test_three_g_boost_trajectory():
    cfg = load_config({"rig": "sled", "trajectory": {"phases": [{"accel_g": 3.0, "duration_s": 5}],
                                                     "brake_g": 2.0, "static_after_s": 10}})
    tr = build_trajectory(cfg)
    v_end = 3 * G * 5
    n_brake = int(np.ceil(v_end / (2 * G) / cfg.dt - 1e-9))
    assert tr.n_stop == 1000 + 1000 + n_brake
    assert tr.v_max_m_s == pytest.approx(v_end)
    assert tr.v[tr.n_stop] == 0 and abs(tr.v[tr.n_stop - 1]) > 0
    assert tr.accel[tr.n_stop - 1] == pytest.approx(-v_end / (n_brake * cfg.dt))
    assert tr.run_length_m == pytest.approx(0.5 * v_end * 5 + 0.5 * v_end * n_brake * cfg.dt, rel=1e-9)


def test_true_specific_force_and_truth_run_stays_on_track():
    cfg = load_config({"rig": "sled"})
    tr = build_trajectory(cfg)
    f, w = true_imu(tr, cfg.omega_ie)
    assert np.allclose(f[:, 2], G + 2 * (cfg.omega_ie[0] * 0 - cfg.omega_ie[1] * (tr.v[:-1] + tr.v[1:]) / 2))
    v, r, _ = mechanise(f[None], w[None], np.zeros((1, 3)), cfg.omega_ie, cfg.dt)
    assert np.abs(r[0, :, 0] - tr.x).max() < 1e-3
    assert np.abs(r[0, :, 1:]).max() < 5e-3          # first-order scheme: mm, not metres


def test_record_axes_equal_the_spec_initial_attitude():
    """INS of R f̃, R ω̃ from I equals INS of f̃, ω̃ from Ĉ_0 = exp(−[φ0×]) (module simulate)."""
    cfg = load_config({"rig": "sled", "trajectory": {"static_after_s": 5}})
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", [1, 2]))
    R = record_rotation(sb.truth.params.phi0)
    fm = np.einsum("sji,snj->sni", R, sb.f)
    wm = np.einsum("sji,snj->sni", R, sb.w)
    _, r1, _ = mechanise(sb.f, sb.w, np.zeros((2, 3)), cfg.omega_ie, cfg.dt)
    _, r2, _ = mechanise(fm, wm, sb.truth.params.phi0, cfg.omega_ie, cfg.dt)
    assert np.abs(r1 - r2).max() < 1e-8
    assert np.allclose(R, Rotation.from_matrix(np.eye(3) - skew(sb.truth.params.phi0)).as_matrix(), atol=1e-7)


def test_seed_draws_do_not_depend_on_the_batch():
    cfg = load_config({"rig": "sled", "trajectory": {"static_after_s": 2}})
    a = simulate(cfg, replicate_seeds(cfg.raw, "default", [4]))
    b = simulate(cfg, replicate_seeds(cfg.raw, "default", [2, 3, 4]))
    assert np.array_equal(a.f[0], b.f[2]) and np.array_equal(a.truth.x_inst[0], b.truth.x_inst[2])
    assert not np.array_equal(b.f[0], b.f[1])


def test_noise_free_record_has_no_errors():
    cfg = load_config({"rig": "sled", "trajectory": {"static_after_s": 2}})
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", [0]), noise_free=True)
    f, w = true_imu(sb.traj, cfg.omega_ie)
    assert np.array_equal(sb.f[0], f) and np.array_equal(sb.truth.x_inst, sb.truth.x_true)


def test_kernel_types_do_not_depend_on_the_batch():
    """One seed (its rates a broadcast numpy hands over read-only), two seeds, a scalar period
    and a record's own sample intervals all reach the navigation and X-correction kernels as
    writable arrays (``platcal.jit.kernel_input``), as do identify's X compensation's (read-only
    broadcasts here), so numba compiles each once for all of them
    (issue 22 item 4), and the numbers are those of the same inputs passed as fresh copies."""
    rng = np.random.default_rng(3)
    N = 40
    f1 = rng.normal(0.0, 1.0, (1, N, 3)) + [0.0, 0.0, -9.8]
    w1 = rng.normal(0.0, 1e-4, (N, 3))
    dts = np.full(N, 0.01) + rng.uniform(0.0, 1e-5, N)
    omega_ie = np.array([0.0, 5.6e-5, 4.2e-5])
    runs = [(f1, w1[None], np.zeros((1, 3)), dts),                       # one seed, rates broadcast
            (np.repeat(f1, 2, axis=0), w1[None], np.full((2, 3), 1e-4), 0.01)]   # two seeds, scalar dt
    for f, w, phi0, dt in runs:
        got = mechanise(f, w, phi0, omega_ie, dt)
        ref = mechanise(f.copy(), np.array(np.broadcast_to(w, f.shape)), phi0.copy(), omega_ie,
                            np.array(np.broadcast_to(np.asarray(dt, float), (N,))))
        for a, b in zip(got, ref):
            assert np.array_equal(a, b)
        S, fl = f.shape[0], ref[2]
        est, hold = rng.normal(0.0, 1e-4, (S, 3, 3)), np.arange(N) % 3
        got = x_corrections_held(got[2], est, hold, dt, start=(0.1, 0.2))
        ref = x_corrections_held(ref[2], est, hold, np.array(np.broadcast_to(np.asarray(dt, float), (N,))),
                                 start=(np.full(S, 0.1), np.full(S, 0.2)))
        for a, b in zip(got, ref):
            assert np.array_equal(a, b)
        # identify's compensation: a read-only broadcast of one seed's positions and estimates
        r_one = np.broadcast_to(np.zeros((1, N + 1, 3)), (S, N + 1, 3))
        got = compensate_modes(np.broadcast_to(fl[:1], fl.shape), r_one,
                               np.broadcast_to(est[:1], est.shape), np.broadcast_to(hold, (2, N)), dt)
        ref = compensate_modes(np.array(np.broadcast_to(fl[:1], fl.shape)), np.zeros((S, N + 1, 3)),
                               np.array(np.broadcast_to(est[:1], est.shape)), np.array([hold, hold]), dt)
        assert np.array_equal(got, ref)
    readonly = [str(t) for k in (_mechanise, _x_corrections, _x_compensated) for sig in k.signatures for t in sig
                if hasattr(t, "ndim") and not t.mutable]
    assert readonly == []
