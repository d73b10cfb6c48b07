"""Batched simulator and EKF (issue 5): a batch of B equals B runs of one, the sparse kernels
equal their dense definitions, the thread count changes nothing, memory does not grow with the
dwell time."""

import numpy as np
import pytest

from platcal.estimation import kalman
from platcal.rigs.centrifuge import attitude as platform
from platcal.rigs.centrifuge.base import Centrifuge, specific_force
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.parallel import get_threads, max_threads, set_threads, threads
from platcal.scheme import check_scheme
from platcal.scheme import TABLE1_POSITIONS
from platcal.rigs.centrifuge.simulate import Noise, simulate

CEN = Centrifuge()
RTOL = 1e-10


def _fr3(t, h, params):
    """The base specific force at an RK4 step's start, middle and end (m/s^2)."""
    return np.stack([specific_force(t + c * h, params) for c in (0.0, 0.5, 1.0)])


def _scheme(dwell=2.0, positions=TABLE1_POSITIONS):
    return check_scheme("t", {"dwell_s": dwell, "positions": [list(p) for p in positions]})


def _seeds(idx):
    return [np.random.SeedSequence([7, i]) for i in idx]


def _sim(scheme, idx, truth=None):
    truth = full_truth() if truth is None else truth
    return simulate(truth, scheme, CEN.scheme_params(scheme), Noise(), _seeds(idx), keep_every=4)


def _ekf(scheme, sim, settings, **kw):
    return run_ekf(EstimatorInput([sim.A[:, k] for k in range(scheme.n_positions)], [sim.t] * scheme.n_positions,
                   scheme.angles_deg, CEN.scheme_params(scheme)), settings, **kw)


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=0)


@pytest.fixture(scope="module")
def batch():
    scheme = _scheme(2.0)
    settings = FilterSettings(passes=2, history_every_s=0.5)
    # on every thread of numba's pool (not the one a pytest-xdist worker's kernels are given,
    # tests/conftest.py): test_thread_count_changes_nothing compares one thread against it
    with threads(max_threads()):
        sim = _sim(scheme, range(4))
        return scheme, settings, sim, _ekf(scheme, sim, settings)


def test_simulation_batch_equals_runs_of_one(batch):
    scheme, _, sim, _ = batch
    for i in range(4):
        one = _sim(scheme, [i])
        _close(one.A[0], sim.A[i])
        _close(one.angles[0], sim.angles[i])
        _close(one.set_error[0], sim.set_error[i])


def test_simulated_noise_is_the_replicate_stream_scaled():
    """The accelerometer noise is the replicate's second stream drawn position by position,
    3 per 5 ms sample (kept or not), times sigma_a then 1e-6 (ug -> g), added to the noise-free
    output (the kernel scales each draw as it uses it)."""
    scheme = _scheme(0.5)
    params = CEN.scheme_params(scheme)
    # fresh SeedSequences for every use: spawning advances a SeedSequence's children
    noisy = simulate(full_truth(), scheme, params, Noise(sigma_a_ug=7.0, arw_deg_rth=0.0), _seeds(range(3)),
                     keep_every=4)
    clean = simulate(full_truth(), scheme, params, Noise(sigma_a_ug=0.0, arw_deg_rth=0.0), _seeds(range(3)),
                     keep_every=4)
    n = int(round(0.5 / 0.005))
    for b, ss in enumerate(_seeds(range(3))):
        draws = np.random.default_rng(ss.spawn(3)[1]).standard_normal((scheme.n_positions, n, 3))
        expected = clean.A[b] + draws[:, ::4] * 7.0 * 1e-6
        assert np.array_equal(noisy.A[b], expected)
        assert np.array_equal(noisy.angles[b], clean.angles[b])


def test_ekf_batch_equals_runs_of_one(batch):
    scheme, settings, sim, est = batch
    for i in range(4):
        one_sim = _sim(scheme, [i])
        one = _ekf(scheme, one_sim, settings)
        _close(one.x[0], est.x[i])
        _close(one.P[0], est.P[i])
        _close(one.pass_x[:, 0], est.pass_x[:, i])
        _close(one.pass_P[:, 0], est.pass_P[:, i])
        _close(one.history_x[0], est.history_x[i])
        _close(one.history_sigma[0], est.history_sigma[i])
        _close(one.mean_nis[0], est.mean_nis[i])


def test_covariance_stays_symmetric_positive_definite(batch):
    *_, est = batch
    assert np.array_equal(est.P, np.swapaxes(est.P, 1, 2))
    assert np.linalg.eigvalsh(est.P).min() > 0
    assert (est.failed_updates == 0).all()


def test_covariance_only_batch_over_schemes_equals_one_by_one():
    rng = np.random.default_rng(3)
    B, K = 5, 6
    cmd = np.zeros((B, K, 3))
    cmd[:, :, 0] = rng.integers(0, 360, (B, K))
    cmd[:, :, 2] = rng.integers(0, 360, (B, K))
    t = np.arange(0.0, 2.0, 0.02)
    lin = np.repeat(full_truth()[None], B, axis=0)
    s = FilterSettings(history_every_s=None)
    est = run_ekf(EstimatorInput([None] * K, [t] * K, cmd, CEN.params()), s, linearise_about=lin)
    for b in range(B):
        one = run_ekf(EstimatorInput([None] * K, [t] * K, cmd[b], CEN.params()), s, linearise_about=lin[b:b + 1])
        _close(one.P[0], est.P[b])
        _close(one.x[0], est.x[b])
    # different schemes really give different covariances
    assert not np.allclose(est.P[0], est.P[1])


def test_thread_count_changes_nothing(batch):
    scheme, settings, sim, est = batch
    with threads(1) as n:
        assert n == 1 == get_threads()
        one_thread = _ekf(scheme, sim, settings)
        sim1 = _sim(scheme, range(4))
    assert np.array_equal(one_thread.x, est.x)
    assert np.array_equal(one_thread.P, est.P)
    assert np.array_equal(sim1.A, sim.A)
    assert set_threads(10**6) == max_threads() == get_threads()


def test_filter_memory_independent_of_dwell():
    sizes = []
    for dwell in (1.0, 3.0):
        scheme = _scheme(dwell, TABLE1_POSITIONS[:2])
        sim = _sim(scheme, range(2))
        est = _ekf(scheme, sim, FilterSettings(history_every_s=None))
        n = 48
        assert est.P.shape == (2, n, n) and est.x.shape == (2, n)
        assert est.history_x.shape == (2, 0, n)
        sizes.append(sum(a.nbytes for a in vars(est).values() if isinstance(a, np.ndarray)))
    assert sizes[0] == sizes[1]
    # with history, one row per kept instant: decimated, not per filter step
    scheme = _scheme(3.0, TABLE1_POSITIONS[:2])
    est = _ekf(scheme, _sim(scheme, range(2)), FilterSettings(history_every_s=1.0))
    assert est.history_x.shape == (2, 2 * 3, 48)
    assert np.all(np.diff(est.history_t) > 0)


# the sparse fast kernels against the reference kernels and dense formulas -------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scalar_model_kernels_equal_reference(seed):
    rng = np.random.default_rng(seed)
    params = CEN.params()
    ang = rng.uniform(-3, 3, 3)
    ang[1] = rng.uniform(-1.2, 1.2)
    coef = full_truth() * rng.uniform(0.5, 2, 48)
    coef[45:] = rng.uniform(-0.1, 0.1, 3)
    t, h = rng.uniform(0, 60), 0.02
    out, pa, pc = platform.rk4(ang, coef, _fr3(t, h, params), h, params)
    fr3 = np.stack([specific_force(t + c * h, params) for c in (0.0, 0.5, 1.0)])
    o2, pa2, pg2 = np.empty(3), np.empty((3, 3)), np.empty((3, platform.N_GYRO))
    platform.rk4_jac_sc(ang, coef, fr3, h, params, o2, pa2, pg2, platform.make_sc_rk4_scratch())
    np.testing.assert_allclose(o2, out, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pa2, pa, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pg2, pc[:, platform.GYRO_COLS], rtol=1e-12, atol=1e-22)
    # every other coefficient column of the RK4 map is structurally zero
    assert not np.delete(pc, platform.GYRO_COLS, axis=1).any()
    o3 = np.empty(3)
    platform.rk4_scalar(ang, coef, fr3, h, params, o3)
    np.testing.assert_allclose(o3, out, rtol=0, atol=1e-15)
    A, hc, ha = platform.measure(ang, coef, specific_force(t, params), params)
    for r in range(3):
        cols = platform.MEAS_COLS[r][platform.MEAS_COLS[r] >= 0]
        assert set(np.flatnonzero(hc[r])) == set(cols)
    A3, hm, ha3 = np.empty(3), np.zeros(platform.MEAS_COLS.shape), np.empty((3, 3))
    platform.measure_jac_sc(ang, coef, *fr3[0], params[2], A3, hm, ha3)
    np.testing.assert_allclose(A3, A, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ha3, ha, rtol=1e-12, atol=1e-16)
    for r in range(3):
        cols = platform.MEAS_COLS[r]
        np.testing.assert_allclose(hm[r, cols >= 0], hc[r, cols[cols >= 0]], rtol=1e-13, atol=0)
    m = platform.measure_scalar(*np.ravel([[np.sin(a), np.cos(a)] for a in ang]), coef, *fr3[0], params[2])
    np.testing.assert_allclose(m, A, rtol=0, atol=1e-15)


def _spd(n, rng):
    a = rng.normal(size=(n, n))
    return a @ a.T + n * np.eye(n)


def test_propagate_sparse_equals_dense():
    rng = np.random.default_rng(5)
    n = 12
    P = _spd(n, rng)
    dyn = np.array([9, 10, 11])
    cols = np.array([0, 2, 3, 7, 9, 10, 11])
    phi = rng.normal(size=(3, cols.size))
    q = np.diag(rng.uniform(0.1, 1, 3))
    Phi = np.eye(n)
    Phi[dyn] = 0.0
    Phi[np.ix_(dyn, cols)] = phi
    Q = np.zeros((n, n))
    Q[np.ix_(dyn, dyn)] = q
    ref = Phi @ P @ Phi.T + Q
    kalman.propagate_sparse(P, dyn, cols, phi, q, np.empty((3, n)), np.empty((3, 3)))
    np.testing.assert_allclose(P, ref, rtol=1e-12, atol=1e-12)
    assert np.array_equal(P, P.T)


def test_joseph_update_sparse_equals_dense_joseph():
    rng = np.random.default_rng(6)
    n = 12
    P = _spd(n, rng)
    x = rng.normal(size=n)
    hcols = np.array([[0, 4, 9, 0], [1, 5, 10, 11], [2, 9, 10, 11]])
    hnnz = np.array([3, 4, 4])
    hval = rng.normal(size=(3, 4))
    H = np.zeros((3, n))
    for r in range(3):
        H[r, hcols[r, :hnnz[r]]] = hval[r, :hnnz[r]]
    R = np.diag([0.3, 0.4, 0.5])
    innov = rng.normal(size=3)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    IKH = np.eye(n) - K @ H
    P_ref = IKH @ P @ IKH.T + K @ R @ K.T
    x_ref = x + K @ innov
    S = H @ P @ H.T + R
    nis_ref = innov @ np.linalg.solve(S, innov)
    nu = np.empty(3)
    ok = kalman.joseph_update_sparse(x, P, hcols, hnnz, hval, innov, np.diag(R).copy(),
                                     np.empty((3, n)), np.empty((3, n)), np.empty((3, n)),
                                     np.empty((3, 3)), np.empty((3, 3)), nu, True)
    assert ok
    np.testing.assert_allclose(P, P_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(x, x_ref, rtol=1e-12, atol=1e-12)
    assert np.array_equal(P, P.T)
    assert nu @ nu == pytest.approx(nis_ref, rel=1e-12)


@pytest.mark.parametrize("m", [1, 2, 4])
def test_joseph_update_sparse_any_measurement_size(m):
    """The update is dimension-agnostic: m = 1, 2, 4 against the dense Joseph form."""
    rng = np.random.default_rng(60 + m)
    n = 10
    P = _spd(n, rng)
    x = rng.normal(size=n)
    w = 3
    hcols = np.stack([rng.choice(n, size=w, replace=False) for _ in range(m)])
    hnnz = rng.integers(1, w + 1, size=m)
    hval = rng.normal(size=(m, w))
    H = np.zeros((m, n))
    for r in range(m):
        H[r, hcols[r, :hnnz[r]]] = hval[r, :hnnz[r]]
    R = np.diag(rng.uniform(0.2, 0.6, m))
    innov = rng.normal(size=m)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(n) - K @ H
    P_ref = IKH @ P @ IKH.T + K @ R @ K.T
    x_ref = x + K @ innov
    nu = np.empty(m)
    ok = kalman.joseph_update_sparse(x, P, hcols, hnnz, hval, innov, np.diag(R).copy(), np.empty((m, n)),
                                     np.empty((m, n)), np.empty((m, n)), np.empty((m, m)), np.empty((m, m)), nu, True)
    assert ok
    np.testing.assert_allclose(P, P_ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(x, x_ref, rtol=1e-12, atol=1e-12)
    assert np.array_equal(P, P.T)
    assert nu @ nu == pytest.approx(innov @ np.linalg.solve(S, innov), rel=1e-12)


def test_written_out_update_equals_the_general_loops_for_m3():
    """The m = 3 fast path gives the general path's numbers bit for bit."""
    rng = np.random.default_rng(9)
    n, m = 12, 3
    U = rng.normal(size=(m, n))
    S = _spd(m, rng)
    Sinv = np.linalg.inv(S)
    innov = rng.normal(size=m)
    P0 = _spd(n, rng)
    x0 = rng.normal(size=n)
    out = []
    for fn in (kalman._correct, kalman._correct3):
        x, P, K, D = x0.copy(), P0.copy(), np.empty((m, n)), np.empty((m, n))
        fn(x, P, innov, U, K, D, S, Sinv, True)
        out.append((x, P, K, D))
    for a, b in zip(*out):
        assert np.array_equal(a, b)


def test_cholesky_inverse_refuses_an_indefinite_s():
    F, nu = np.empty((2, 2)), np.empty(2)
    assert not kalman.cholesky_inverse(np.array([[1.0, 2.0], [2.0, 1.0]]), F, nu, np.zeros(2))
    S = np.array([[4.0, 1.0], [1.0, 3.0]])
    assert kalman.cholesky_inverse(S, F, nu, np.array([1.0, 2.0]))
    np.testing.assert_allclose(F, np.linalg.inv(S), rtol=1e-14)


def _dense_ekf(z, t, cmd_rad, params, settings):
    """Plain dense EKF (numpy, full Phi and H from the reference helpers, Joseph form): what the
    sparse batched kernel must reproduce."""
    idx = settings.coef_index
    nc = idx.size
    n = nc + 3
    x = np.zeros(n)
    P = np.diag(np.r_[np.asarray(settings.p0_sigma) ** 2, np.zeros(3)])
    R = np.eye(3) * (settings.sigma_a_ug * 1e-6) ** 2
    q = (settings.arw_deg_rth * np.pi / 180 / 60.0) ** 2
    reset = (settings.sigma_set_arcsec * np.pi / 180 / 3600) ** 2
    coef = np.zeros(48)
    for k in range(len(t)):
        x[nc:] = cmd_rad[k]
        P[nc:, :] = 0.0
        P[:, nc:] = 0.0
        P[nc:, nc:] = np.eye(3) * reset
        t_prev = 0.0  # the reset instant (docs/centrifuge-model.md §14): propagate from it
        for m in range(len(t[k])):
            if t[k][m] > t_prev:
                h = t[k][m] - t_prev
                coef[idx] = x[:nc]
                ang, pa, pc = platform.rk4(x[nc:], coef, _fr3(t_prev, h, params[k]), h, params[k])
                t_prev = t[k][m]
                F = np.eye(n)
                F[nc:, :nc] = pc[:, idx]
                F[nc:, nc:] = pa
                x[nc:] = ang
                P = F @ P @ F.T
                P[nc:, nc:] += np.eye(3) * q * h
            coef[idx] = x[:nc]
            A, hc, ha = platform.measure(x[nc:], coef, specific_force(t[k][m], params[k]), params[k])
            H = np.hstack([hc[:, idx], ha])
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            x = x + K @ (z[k][m] - A)
            IKH = np.eye(n) - K @ H
            P = IKH @ P @ IKH.T + K @ R @ K.T
    return x, P


@pytest.mark.parametrize("estimate_doo,first", [(False, 1), (True, 1), (False, 0)])
def test_sparse_batched_ekf_equals_dense_ekf(estimate_doo, first):
    """first = 1: the spec's instants (period, 2 period, ...: the kernel propagates from the reset
    at t = 0 to the first one); first = 0: filter.update_at_reset (an update at t = 0)."""
    positions = [(45, 0, 167), (350, 30, 325)]
    scheme = _scheme(0.4, positions)
    truth = full_truth({"DOO_x": 0.05}) if estimate_doo else full_truth()
    sim = _sim(scheme, range(2), truth)
    from platcal.rigs.centrifuge.ekf import default_p0_sigma
    s = FilterSettings(estimate_doo=estimate_doo, p0_sigma=default_p0_sigma(estimate_doo))
    t = sim.t[first:]
    assert t[0] == pytest.approx(0.02 * first)
    est = run_ekf(EstimatorInput([sim.A[:, k, first:] for k in range(2)], [t] * 2, scheme.angles_deg,
                                 CEN.scheme_params(scheme)), s)
    params = CEN.scheme_params(scheme)
    for b in range(2):
        x, P = _dense_ekf([sim.A[b, k, first:] for k in range(2)], [t] * 2, scheme.angles_deg * np.pi / 180,
                          params, s)
        sig = np.sqrt(np.diag(P))
        # same filter; only the order of rounding differs (e.g. the RK4 end time t[m] vs t + h)
        assert np.max(np.abs(est.x[b] - x) / sig) < 1e-6
        assert np.max(np.abs(est.P[b] - P) / np.outer(sig, sig)) < 1e-7
