"""The unscented transform and the centrifuge UKF (issue 9 item 3).

Generic pieces (platcal.estimation.unscented): exact on linear functions, mean and cross-covariance
exact on quadratics (covariance too for a scalar input with the Gaussian kurtosis), the central
form equal to the textbook weighted sums, a UKF built from them equal to the Kalman filter on a
linear-Gaussian problem. Centrifuge UKF (platcal.rigs.centrifuge.ukf): the nonlinear-subset update
equals the 2n + 1 update with the permuted square root, the linearised propagation equals the
unscented one to the attitude's tiny nonlinearity, convergence on noise-free data, batch and
thread bit-identity, a symmetric positive definite covariance, the two variants agreeing.
"""

import numpy as np
import pytest

from platcal.errors import InputError
from platcal.estimation.consistency import nees
from platcal.estimation.unscented import (cholesky_upper_into, joseph_update, sigma_points_into,
                                          unscented_transform, ut_cross_into, ut_moments_into,
                                          ut_spread, ut_weights)
from platcal.parallel import max_threads, threads
from platcal.rigs.centrifuge import ukf
from platcal.rigs.centrifuge.base import Centrifuge, specific_force
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.attitude import make_sc_rk4_scratch
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, propagate_attitude
from platcal.scheme import check_scheme
from platcal.scheme import TABLE1_POSITIONS
from platcal.rigs.centrifuge.simulate import Noise, simulate

CEN = Centrifuge()
PARAM_SETS = [(1.0, 2.0, None), (1e-3, 2.0, 0.0), (0.5, 1.0, 1.0)]


def test_cholesky_upper_factor():
    rng = np.random.default_rng(0)
    for n in (1, 2, 5, 18, 48):
        A = rng.standard_normal((n, n))
        P = A @ A.T + 0.1 * np.eye(n)
        R = np.full((n, n), 7.0)
        assert cholesky_upper_into(P, R)
        np.testing.assert_allclose(R, np.linalg.cholesky(P).T, rtol=1e-12, atol=1e-13)
        Q = np.tril(P) + np.triu(np.full((n, n), np.nan), 1)  # only the lower triangle is read
        assert cholesky_upper_into(Q, Q)
        np.testing.assert_array_equal(Q, R)
    assert not cholesky_upper_into(np.diag([1.0, -1.0, 2.0]), np.zeros((3, 3)))


def _cholesky_right_looking(A):
    """The outer-product (right-looking) upper Cholesky factor, written out loop by loop: the
    form the compiled kernel had before issue 22, to compare bits with. None if not PD."""
    n = A.shape[0]
    R = np.triu(A.T).astype(float)  # R[j, i] = A[i, j]: the lower triangle read
    for j in range(n):
        v = R[j, j]
        if not v > 0.0:
            return None
        d = np.sqrt(v)
        R[j, j] = d
        inv = 1.0 / d
        for k in range(j + 1, n):
            R[j, k] *= inv
        for k in range(j + 1, n):
            c = R[j, k]
            for i in range(k, n):
                R[k, i] -= c * R[j, i]
    return R


def test_cholesky_same_bits_as_the_right_looking_form():
    """The up-looking kernel (four rows per pass) applies each entry's operations in the same
    order as the outer-product form: the same factor to the last bit, in place or not, and the
    same refusal of a matrix that is not positive definite."""
    rng = np.random.default_rng(22)
    for n in (1, 3, 4, 5, 9, 48):
        for _ in range(4):
            A = rng.standard_normal((n, n)) * np.exp(rng.uniform(-8.0, 3.0, n))
            P = A @ A.T + np.diag(np.exp(rng.uniform(-20.0, 0.0, n)))
            ref = _cholesky_right_looking(P)
            R = np.full((n, n), 7.0)
            assert cholesky_upper_into(P, R)
            assert np.array_equal(R, ref)
            Q = P.copy()
            assert cholesky_upper_into(Q, Q)
            assert np.array_equal(Q, ref)
    bad = np.diag([4.0, 1.0, 1.0, 1.0, 1.0, 2.0])
    bad[4, 3] = bad[3, 4] = 1.5  # the fifth pivot is 1 - 1.5^2 < 0
    assert _cholesky_right_looking(bad) is None
    assert not cholesky_upper_into(bad, np.zeros((6, 6)))


def _gaussian(n, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return rng.standard_normal(n), A @ A.T / n + 0.1 * np.eye(n)


@pytest.mark.parametrize("alpha,beta,kappa", PARAM_SETS)
def test_transform_exact_on_linear(alpha, beta, kappa):
    mu, P = _gaussian(5, 1)
    A = np.random.default_rng(2).standard_normal((3, 5))
    b = np.array([1.0, -2.0, 0.5])
    y, Pyy, Pxy = unscented_transform(lambda x: A @ x + b, mu, P, alpha, beta, kappa)
    np.testing.assert_allclose(y, A @ mu + b, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(Pyy, A @ P @ A.T, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(Pxy, P @ A.T, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("alpha,beta,kappa", PARAM_SETS)
def test_transform_mean_and_cross_exact_on_quadratic(alpha, beta, kappa):
    n = 4
    mu, P = _gaussian(n, 3)
    rng = np.random.default_rng(4)
    Qs = [(lambda M: M + M.T)(rng.standard_normal((n, n))) for _ in range(2)]
    bs = rng.standard_normal((2, n))

    def f(x):
        return np.array([x @ Q @ x + b @ x + 1.0 for Q, b in zip(Qs, bs)])

    y, _, Pxy = unscented_transform(f, mu, P, alpha, beta, kappa)
    # Gaussian: E[x'Qx] = mu'Q mu + tr(Q P); cov(x, x'Qx + b'x) = P (2 Q mu + b)
    mean = [mu @ Q @ mu + np.trace(Q @ P) + b @ mu + 1.0 for Q, b in zip(Qs, bs)]
    cross = np.stack([P @ (2 * Q @ mu + b) for Q, b in zip(Qs, bs)], axis=1)
    np.testing.assert_allclose(y, mean, rtol=1e-6)
    np.testing.assert_allclose(Pxy, cross, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("alpha,beta,kappa", [(1.0, 1.0, 1.0), (1e-3, 2.0, 0.0)])
def test_transform_covariance_exact_on_scalar_quadratic(alpha, beta, kappa):
    # y = a x^2 + b x, x ~ N(mu, s^2): Var y = 2 a^2 s^4 + (2 a mu + b)^2 s^2, which the
    # transform reproduces when c + beta - alpha^2 = 2 (both parameter sets here)
    a, b, mu, s = 0.7, -1.3, 0.4, 1.5
    y, Pyy, _ = unscented_transform(lambda x: a * x**2 + b * x, [mu], [[s * s]], alpha, beta, kappa)
    np.testing.assert_allclose(y[0], a * (mu**2 + s**2) + b * mu, rtol=1e-9)
    np.testing.assert_allclose(Pyy[0, 0], 2 * a**2 * s**4 + (2 * a * mu + b) ** 2 * s**2, rtol=1e-6)


def test_central_form_equals_textbook_sums():
    n, alpha, beta, kappa = 3, 0.5, 2.0, 0.0
    mu, P = _gaussian(n, 5)

    def f(x):
        return np.array([np.sin(x[0]) * x[1], np.exp(0.3 * x[2]) + x[0] ** 3])

    y, Pyy, Pxy = unscented_transform(f, mu, P, alpha, beta, kappa)
    wm0, wc0, wi = ut_weights(n, alpha, beta, kappa)
    h, _ = ut_spread(n, alpha, beta, kappa)
    L = np.linalg.cholesky(P)
    X = np.vstack([mu, mu + h * L.T, mu - h * L.T])
    Y = np.array([f(x) for x in X])
    wm = np.r_[wm0, np.full(2 * n, wi)]
    wc = np.r_[wc0, np.full(2 * n, wi)]
    ybar = wm @ Y
    np.testing.assert_allclose(y, ybar, rtol=1e-10)
    np.testing.assert_allclose(Pyy, (wc[:, None] * (Y - ybar)).T @ (Y - ybar), rtol=1e-8)
    np.testing.assert_allclose(Pxy, (wc[:, None] * (X - mu)).T @ (Y - ybar), rtol=1e-8, atol=1e-12)


def test_central_form_positive_semidefinite_where_textbook_weights_are_not():
    # alpha = 1e-3 over 48 states: W_0 = 1 - 1/alpha^2 ~ -1e6, yet the covariance is a non-negative sum
    n = 48
    wm0, wc0, _ = ut_weights(n, 1e-3, 2.0, 0.0)
    assert wm0 < -1e5 and wc0 < -1e5
    mu, P = _gaussian(n, 6)
    _, Pyy, _ = unscented_transform(lambda x: np.array([x[0] * x[1], x[2] ** 2, np.cos(x[3])]), mu, P,
                                    1e-3, 2.0, 0.0)
    assert np.all(np.linalg.eigvalsh(Pyy) > 0)
    with pytest.raises(ValueError, match="beta"):
        ut_spread(n, 1.0, 0.5, 0.0)


def _ukf_step(x, P, Phi, Q, H, R, z, h, w2):
    """One predict + update of a UKF assembled from the generic pieces (linear model)."""
    n = x.size
    Rt = np.zeros((n, n))
    assert cholesky_upper_into(P, Rt)
    X = np.empty((2 * n + 1, n))
    sigma_points_into(x, Rt, h, X)
    Y = X @ Phi.T
    m, Pp = np.empty(n), np.empty((n, n))
    ut_moments_into(Y[1:n + 1] - Y[0], Y[n + 1:] - Y[0], h, w2, m, Pp)
    x = Y[0] + m
    P = Pp + Q
    assert cholesky_upper_into(P, Rt)
    sigma_points_into(x, Rt, h, X)
    Z = X @ H.T
    q = H.shape[0]
    mz, Pzz, C = np.empty(q), np.empty((q, q)), np.empty((n, q))
    Dp, Dm = Z[1:n + 1] - Z[0], Z[n + 1:] - Z[0]
    ut_moments_into(Dp, Dm, h, w2, mz, Pzz)
    ut_cross_into(Rt, Dp, Dm, h, C)
    innov = z - (Z[0] + mz)
    K, D = np.empty((q, n)), np.empty((q, n))
    assert joseph_update(x, P, np.ascontiguousarray(C.T), Pzz + R, innov, K, D, np.empty((q, q)),
                         np.empty(q), True)
    return x, P


@pytest.mark.parametrize("alpha,beta,kappa", [(1.0, 2.0, -1.0), (1e-3, 2.0, 0.0)])
def test_ukf_equals_kalman_filter_on_linear_gaussian_problem(alpha, beta, kappa):
    n, q = 4, 3
    rng = np.random.default_rng(8)
    Phi = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    Q = np.diag([1e-3, 2e-3, 0.0, 0.0])
    H = rng.standard_normal((q, n))
    R = np.diag([0.1, 0.2, 0.05])
    h, w2 = ut_spread(n, alpha, beta, kappa)
    x_u, P_u = np.zeros(n), np.diag([10.0, 5.0, 1.0, 2.0])
    x_k, P_k = x_u.copy(), P_u.copy()
    for _ in range(20):
        z = rng.standard_normal(q)
        x_u, P_u = _ukf_step(x_u, P_u, Phi, Q, H, R, z, h, w2)
        x_k, P_k = Phi @ x_k, Phi @ P_k @ Phi.T + Q
        S = H @ P_k @ H.T + R
        K = P_k @ H.T @ np.linalg.inv(S)
        x_k = x_k + K @ (z - H @ x_k)
        P_k = (np.eye(n) - K @ H) @ P_k @ (np.eye(n) - K @ H).T + K @ R @ K.T
    np.testing.assert_allclose(x_u, x_k, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(P_u, P_k, rtol=1e-7, atol=1e-10)


# ------------------------------------------------------------------ centrifuge UKF

def _scheme(dwell):
    return check_scheme("t", {"dwell_s": dwell, "positions": [list(p) for p in TABLE1_POSITIONS]})


def _record(dwell, reps, noise=Noise()):
    """Simulated outputs at the filter instants 20 ms, 40 ms, ... (not the reset instant)."""
    scheme = _scheme(dwell)
    seeds = None if reps is None else [np.random.SeedSequence([11, i]) for i in reps]
    sim = simulate(full_truth(), scheme, CEN.scheme_params(scheme), noise, seeds, keep_every=4)
    keep = sim.t > 0
    K = scheme.n_positions
    return scheme, [sim.A[:, k][:, keep] for k in range(K)], [sim.t[keep]] * K


def _run(scheme, z, t, settings=None, **opts):
    settings = settings or FilterSettings(history_every_s=None)
    return ukf.run_ukf(EstimatorInput(z, t, scheme.angles_deg, CEN.scheme_params(scheme)), settings, **opts)


@pytest.fixture(scope="module")
def short():
    """Two noisy replicates, 2 s per position, filtered as a batch by the default UKF ("update")."""
    scheme, z, t = _record(2.0, [0, 1])
    return scheme, z, t, _run(scheme, z, t)


def _state_after(short, m=40):
    """A state with correlated P: the default UKF over the first m instants of position 1."""
    scheme, z, t, _ = short
    sub = ukf.run_ukf(EstimatorInput([z[0][:1, :m]], [t[0][:m]], scheme.angles_deg[:1], CEN.scheme_params(scheme)[:1]),
                      FilterSettings(history_every_s=None))
    return sub.x[0].copy(), sub.P[0].copy(), t[0][m - 1] + 0.02, z[0][0, m]


def _scratch(n, q):
    return dict(U=np.empty((3, n)), S=np.empty((3, 3)), K=np.empty((3, n)), D=np.empty((3, n)),
                F=np.empty((3, 3)), nu=np.empty(3), innov=np.zeros(3), a=np.empty(3), y0=np.empty(3),
                y=np.empty(3), mz=np.empty(3), Pzz=np.empty((3, 3)))


def test_nonlinear_update_equals_full_update_with_permuted_square_root(short):
    x, P, tm, zrow = _state_after(short)
    fs = FilterSettings()
    n, est = x.size, fs.coef_index
    h, w2, _ = ukf.check_options(n, "nonlinear", 1.0, 2.0, None)
    nl, nl_full, lin = ukf.measurement_structure(est)
    coef = full_truth() * 0.0
    coef[est] = x[:-3]
    fr = specific_force(tm, CEN.params())
    r_var = np.full(3, 1e-10)
    q = nl.size
    x1, P1 = x.copy(), P.copy()
    s1 = _scratch(n, q)
    ok1, nis1 = ukf.update_nonlinear(x1, P1, coef, fr, 9.80665, zrow, r_var, h, w2, nl, nl_full, lin, True,
                                     np.zeros((q, q)), np.empty((q, 3)), np.empty((q, 3)), np.empty((q, 3)),
                                     s1["U"], s1["S"], s1["K"], s1["D"], s1["F"], s1["nu"], s1["innov"],
                                     coef.copy(), s1["a"], np.empty(3), s1["y0"], s1["y"], s1["mz"], s1["Pzz"])
    x2, P2 = x.copy(), P.copy()
    s2 = _scratch(n, q)
    perm = ukf.nonlinear_first_order(n, est)
    mstates = np.arange(27, 45)
    ok2, nis2 = ukf.update_all(x2, P2, coef, fr, 9.80665, zrow, r_var, h, w2, perm, mstates, est, True,
                               np.zeros((n, n)), np.zeros((n, n)), np.empty((n, 3)), np.empty((n, 3)),
                               np.empty((21, n)), s2["U"], s2["S"], s2["K"], s2["D"], s2["F"], s2["nu"],
                               s2["innov"], coef.copy(), s2["y0"], s2["mz"], s2["Pzz"])
    assert ok1 and ok2
    sig = np.sqrt(np.diag(P))
    np.testing.assert_allclose((x1 - x2) / sig, 0.0, atol=1e-6)
    np.testing.assert_allclose(P1 / np.outer(sig, sig), P2 / np.outer(sig, sig), atol=1e-6)
    np.testing.assert_allclose(nis1, nis2, rtol=1e-6)
    # and the update did something: the coefficient sigmas of the accelerometer shrink
    assert np.all(np.diag(P1)[lin] < np.diag(P)[lin])


@pytest.mark.parametrize("angle_sigma", [None, 1e-3])
def test_sigma_points_all_at_once_same_bits_as_one_by_one(short, angle_sigma):
    """The update's sigma-point outputs all at once (the measurement's 18 coefficients in order)
    give the numbers of the point-by-point path (the same states in another order take it), also
    when some angle steps are too large for the Taylor shift (those points are redone one by one)."""
    x, P, tm, zrow = _state_after(short)
    if angle_sigma is not None:  # the angles' sigma 1e-3 rad: many angle steps above SHIFT_SMALL
        s = np.sqrt(np.diag(P))
        P = P.copy()
        P[-3:, :] *= angle_sigma / s[-3:, None]
        P[:, -3:] *= angle_sigma / s[None, -3:]
    fs = FilterSettings()
    n, est = x.size, fs.coef_index
    h, w2, _ = ukf.check_options(n, "update", 1.0, 2.0, None)
    coef = np.zeros(48)
    coef[est] = x[:-3]
    fr = specific_force(tm, CEN.params())
    r_var = np.full(3, 1e-10)
    out = []
    for mstates in (np.arange(27, 45), np.arange(44, 26, -1)):
        x1, P1 = x.copy(), P.copy()
        s1 = _scratch(n, 18)
        ok, nis = ukf.update_all(x1, P1, coef, fr, 9.80665, zrow, r_var, h, w2, np.arange(n), mstates, est, True,
                                 np.zeros((n, n)), np.zeros((n, n)), np.empty((n, 3)), np.empty((n, 3)),
                                 np.empty((21, n)), s1["U"], s1["S"], s1["K"], s1["D"], s1["F"], s1["nu"],
                                 s1["innov"], coef.copy(), s1["y0"], s1["mz"], s1["Pzz"])
        assert ok
        out.append((x1, P1, nis))
    assert np.array_equal(out[0][0], out[1][0]) and np.array_equal(out[0][1], out[1][1])
    assert out[0][2] == out[1][2]
    assert not np.array_equal(out[0][0], x)  # it did update


def test_linearised_propagation_equals_unscented_propagation(short):
    # one 20 ms step from a state with correlated P: the EKF's propagation (used by the default
    # "update" and by "nonlinear") against the unscented one of "all"
    x, P, tm, _ = _state_after(short)
    fs = FilterSettings()
    n, est = x.size, fs.coef_index
    h, w2, _ = ukf.check_options(n, "all", 1.0, 2.0, None)
    pb = CEN.params()
    dt = 0.02
    fr3 = np.stack([specific_force(tm + c * dt, pb) for c in (0.0, 0.5, 1.0)])
    coef = np.zeros(48)
    coef[est] = x[:-3]
    q_rate = (fs.arw_deg_rth * np.pi / 180 / 60.0) ** 2
    x1, P1 = x.copy(), P.copy()
    assert ukf.propagate_all(x1, P1, coef, fr3, dt, pb, q_rate * dt, h, w2, np.arange(n), est,
                             np.zeros((n, n)), np.zeros((n, n)), np.empty((n, 3)), np.empty((n, 3)),
                             coef.copy(), np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty((3, 3)))
    x2, P2 = x.copy(), P.copy()
    pcols, pg = ukf.propagation_structure(est)
    propagate_attitude(P2, x2[-3:], coef, fr3, dt, pb, q_rate, np.arange(n - 3, n), pcols, pg,
                       np.empty(3), np.empty((3, 3)), np.empty((3, 30)), np.empty((3, pcols.size)),
                       np.zeros((3, 3)), np.empty((3, n)), np.empty((3, 3)), make_sc_rk4_scratch())
    sig = np.sqrt(np.diag(P1))
    # the attitude moves ~1e-6 rad in 20 ms: its second-order terms are far below its sigma
    assert np.max(np.abs(x1 - x2) / sig) < 1e-6
    assert np.max(np.abs(P1 - P2) / np.outer(sig, sig)) < 1e-6
    assert np.max(np.abs(x1[-3:] - x[-3:])) > 1e-8  # it did propagate


def test_noise_free_record_converges_to_the_truth():
    scheme, z, t = _record(10.0, None)
    est = _run(scheme, z, t)
    truth = full_truth()[:45]
    err = est.coef[0] - truth
    assert est.failed_updates[0] == 0
    # every coefficient within 3 of its final sigmas, and those sigmas far below P0's
    assert np.all(np.abs(err) < 3 * est.coef_sigma[0])
    assert np.all(est.coef_sigma[0] < 0.2 * FilterSettings().p0_sigma)
    assert np.abs(err[27:42] / truth[27:42]).max() < 0.01  # accelerometer terms within 1 %


def test_each_variant_its_own_kernels_cached_by_value():
    # two pass kernels per sigma-point variant (issue 22 item 4), so that a process compiles only
    # the variant it runs (the filter is inlined into them); each holds its mode alone in its
    # closure, an int numba's cache keys by value (a kernel held there pickles with a per-process
    # id: never a hit)
    assert len(ukf._PASS_KERNELS) == len(ukf.SIGMA_POINT_MODES)
    for mode in range(len(ukf.SIGMA_POINT_MODES)):
        for kernel in ukf._PASS_KERNELS[mode]:
            assert [cell.cell_contents for cell in kernel.py_func.__closure__] == [mode]
            assert kernel.py_func.__code__.co_freevars == ("mode",)


def test_batch_and_threads_bit_identical(short):
    scheme, z, t, both = short
    for b in range(2):
        one = _run(scheme, [zk[b:b + 1] for zk in z], t)
        np.testing.assert_array_equal(one.x[0], both.x[b])
        np.testing.assert_array_equal(one.P[0], both.P[b])
    if max_threads() >= 2:
        with threads(2):
            par = _run(scheme, z, t)
        with threads(1):
            ser = _run(scheme, z, t)
        np.testing.assert_array_equal(par.x, ser.x)
        np.testing.assert_array_equal(par.P, ser.P)
        np.testing.assert_array_equal(par.x, both.x)


def test_covariance_symmetric_positive_definite(short):
    _, _, _, est = short
    assert np.all(est.failed_updates == 0)
    for P in est.P:
        np.testing.assert_array_equal(P, P.T)
        np.linalg.cholesky(P)
    assert np.all(np.isfinite(est.x)) and np.all(np.abs(est.mean_nis - 3.0) < 0.5)


def test_variants_agree(short):
    scheme, z, t, upd = short
    full = _run(scheme, z, t, sigma_points="all")
    sig = full.coef_sigma
    # the default ("update") differs from the textbook UKF only by the linearised 20 ms propagation
    assert np.max(np.abs(upd.coef - full.coef) / sig) < 0.02
    np.testing.assert_allclose(upd.coef_sigma, sig, rtol=1e-4)
    # "nonlinear" is the "update" UKF with the nonlinear states first in the square root ...
    perm = ukf.nonlinear_first_order(48, FilterSettings().coef_index)
    nl = _run(scheme, z, t, sigma_points="nonlinear")
    same_root = _run(scheme, z, t, sigma_points="update", sqrt_order=perm)
    np.testing.assert_allclose((nl.coef - same_root.coef) / sig, 0.0, atol=1e-6)
    np.testing.assert_allclose(nl.coef_sigma, same_root.coef_sigma, rtol=1e-6)
    # ... and the transform's dependence on that choice is a fraction of a sigma, not more
    assert np.max(np.abs(nl.coef - full.coef) / sig) < 0.5
    np.testing.assert_allclose(nl.coef_sigma, sig, rtol=5e-3)
    for est in (full, nl):
        assert np.all(est.failed_updates == 0)
        for P in est.P:
            np.linalg.cholesky(P)


def test_passes_and_history():
    scheme, z, t = _record(1.0, [3])
    est = _run(scheme, z, t, FilterSettings(passes=2, history_every_s=0.5))
    # instants 0.02 .. 0.98 s: one history sample (t = 0.5 s) per position and pass
    assert est.pass_x.shape == (2, 1, 45) and est.history_x.shape[1] == 2 * 6
    np.testing.assert_allclose(est.history_t[:2], [0.5, 1.5])
    assert np.all(est.history_sigma[0, -1] > 0)
    np.testing.assert_array_equal(est.pass_x[-1], est.coef)


@pytest.mark.parametrize("opts,field", [({"sigma_points": "some"}, "ukf.sigma_points"),
                                        ({"beta": 0.5}, "ukf.beta"), ({"alpha": 0.0}, "ukf.alpha"),
                                        ({"kappa": -48.0}, "ukf.kappa"),
                                        ({"sigma_points": "all", "sqrt_order": np.zeros(48)}, "ukf.sqrt_order")])
def test_bad_options_refused(short, opts, field):
    scheme, z, t, _ = short
    with pytest.raises(InputError) as exc:
        _run(scheme, [zk[:1, :2] for zk in z], [tk[:2] for tk in t], **opts)
    assert exc.value.field == field


def test_nees_is_finite_on_short_record(short):
    _, _, _, est = short
    e = nees(est.coef, est.P[:, :45, :45], full_truth()[None, :45])
    assert np.all(np.isfinite(e)) and np.all(e > 0)
