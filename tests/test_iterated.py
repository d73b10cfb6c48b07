"""The generic Gauss-Newton iterated EKF update (platcal.estimation.iterated) against dense forms."""

import numpy as np
from numba import njit

from platcal.estimation.iterated import iterated_update_sparse, make_iterated_scratch
from platcal.estimation.kalman import joseph_update_sparse


@njit(cache=True)
def _range_bearing(ctx, x, z, res, hval, hcols, hnnz):
    """Range to a beacon at ``ctx[0]`` (nonlinear in x0, x1) and a linear row x2 + x3 (test model)."""
    b, = ctx
    dx = x[0] - b[0]
    dy = x[1] - b[1]
    r = np.sqrt(dx * dx + dy * dy)
    res[0] = z[0] - r
    hcols[0, 0] = 0
    hval[0, 0] = dx / r
    hcols[0, 1] = 1
    hval[0, 1] = dy / r
    hnnz[0] = 2
    res[1] = z[1] - (x[2] + x[3])
    hcols[1, 0] = 2
    hval[1, 0] = 1.0
    hcols[1, 1] = 3
    hval[1, 1] = 1.0
    hnnz[1] = 2


@njit(cache=True)
def _run(x, P, z, r_var, beacon, iters, tol):
    scr = make_iterated_scratch(x.shape[0], 2, 2)
    nu = np.empty(2)
    used = iterated_update_sparse(x, P, z, r_var, _range_bearing, (beacon,), iters, tol, scr, nu)
    return used, nu


def _h(x, b):
    dx, dy = x[0] - b[0], x[1] - b[1]
    r = np.hypot(dx, dy)
    H = np.zeros((2, 4))
    H[0, :2] = dx / r, dy / r
    H[1, 2:] = 1.0
    return np.array([r, x[2] + x[3]]), H


def _dense_iekf(x, P, z, R, b, iters):
    """Textbook Gauss-Newton IEKF (Bell and Cathey 1993) with the Joseph covariance."""
    xi = x.copy()
    for _ in range(iters):
        h, H = _h(xi, b)
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        xn = x + K @ (z - h - H @ (x - xi))
        last = (K, H)
        xi = xn
    K, H = last
    A = np.eye(x.size) - K @ H
    return xi, A @ P @ A.T + K @ R @ K.T


def _problem():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((4, 4))
    P = A @ A.T + np.diag([4.0, 4.0, 1.0, 1.0])
    return np.array([1.0, 2.0, 0.5, -0.3]), P, np.array([4.0, 0.4]), np.array([0.01, 0.04]), np.array([-1.0, 0.5])


def test_matches_dense_gauss_newton_iekf():
    x0, P0, z, r, b = _problem()
    for iters in (1, 2, 4):
        x, P = x0.copy(), P0.copy()
        used, _ = _run(x, P, z, r, b, iters, 0.0)
        xd, Pd = _dense_iekf(x0, P0, z, np.diag(r), b, iters)
        assert used == iters
        np.testing.assert_allclose(x, xd, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(P, Pd, rtol=1e-9, atol=1e-12)
        assert np.array_equal(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)


def test_one_iteration_is_the_ekf_update():
    x0, P0, z, r, b = _problem()
    x, P = x0.copy(), P0.copy()
    _run(x, P, z, r, b, 1, 0.0)
    xe, Pe = x0.copy(), P0.copy()
    h, H = _h(x0, b)
    hc = np.array([[0, 1], [2, 3]])
    hv = np.array([H[0, :2], H[1, 2:]])
    n = 4
    joseph_update_sparse(xe, Pe, hc, np.array([2, 2]), hv, z - h, r, np.empty((2, n)), np.empty((2, n)),
                         np.empty((2, n)), np.empty((2, 2)), np.empty((2, 2)), np.empty(2), True)
    np.testing.assert_allclose(x, xe, rtol=1e-13)
    np.testing.assert_allclose(P, Pe, rtol=1e-12)


def test_converged_iterate_is_the_map_estimate():
    """Iterated to convergence, x minimises the Gauss-Newton cost: its gradient vanishes."""
    x0, P0, z, r, b = _problem()
    x, P = x0.copy(), P0.copy()
    used, _ = _run(x, P, z, r, b, 50, 1e-12)
    assert 2 < used < 50
    h, H = _h(x, b)
    grad = np.linalg.solve(P0, x - x0) - H.T @ ((z - h) / r)
    assert np.max(np.abs(grad)) < 1e-8 * np.max(np.abs(np.linalg.solve(P0, x - x0)))
    # the EKF (one linearisation) does not reach it on this strongly nonlinear problem
    xe, Pe = x0.copy(), P0.copy()
    _run(xe, Pe, z, r, b, 1, 0.0)
    he, He = _h(xe, b)
    assert np.max(np.abs(np.linalg.solve(P0, xe - x0) - He.T @ ((z - he) / r))) > 1e-3


def test_tolerance_stops_early():
    x0, P0, z, r, b = _problem()
    x, P = x0.copy(), P0.copy()
    used, _ = _run(x, P, z, r, b, 50, np.inf)
    assert used == 1  # any step is below an infinite tolerance: the EKF update
