"""Generic pieces of an unscented Kalman filter (the scaled unscented transform), for one
replicate, compiled with numba. Nothing here names a rig.

Scaled unscented transform (Julier 2002; van der Merwe 2004). For ``n`` states with mean ``x0``,
covariance ``P = R^T R`` (``R`` its upper Cholesky factor, rows ``r_j``; the textbook's lower
factor is ``L = R^T``, columns ``L e_j = r_j``) and parameters ``alpha, beta, kappa``::

    c = alpha^2 (n + kappa)          (squared spread; h = sqrt(c) is the spread in sigmas)
    X_0 = x0,  X_j+ = x0 + h r_j,  X_j- = x0 - h r_j          (j = 1..n)
    Wm_0 = 1 - n / c,  Wc_0 = Wm_0 + 1 - alpha^2 + beta,  W_i = 1 / (2 c)  (i > 0)

Central form (used throughout). With ``Y = f(X)`` and the deviations from the central point
``d_j+- = Y_j+- - Y_0``, the textbook sums ``sum_i W_i Y_i`` and ``sum_i Wc_i (Y_i - ybar)(Y_i -
ybar)^T`` are, exactly (algebra, not an approximation)::

    m    = (1 / 2c) sum_j (d_j+ + d_j-)                          ybar = Y_0 + m
    Pyy  = (1 / 2c) sum_j (d_j+ d_j+^T + d_j- d_j-^T) + (beta - alpha^2) m m^T
    Pxy  = (1 / 2h) sum_j r_j^T (d_j+ - d_j-)^T

so no weight ever multiplies a large quantity that must cancel: with alpha << 1 the textbook
``Wm_0 ~ -n/alpha^2`` is huge and negative and the covariance loses positive definiteness to
rounding; here ``Pyy`` is a sum of outer products with non-negative weights whenever
``beta >= alpha^2`` (:func:`check_ut_params` enforces it), so it is symmetric positive
semidefinite for any spread. Only ``h`` and ``beta - alpha^2`` enter.

Exactness (tests/test_ukf.py): for a linear ``f`` the mean, covariance and cross-covariance are
exact for any parameters; for a quadratic ``f`` the mean and the cross-covariance are exact
(symmetric points, Gaussian third moments zero); the covariance of a quadratic is exact for a
scalar input when ``c + beta - alpha^2 = 2`` (the Gaussian kurtosis), not in general: the 2n + 1
axis points cannot see the fourth moments of cross terms such as ``x1 x2``.

A function of a subset. If ``f`` depends on the states ``N`` only, the sigma points over ``N``
with ``R_NN`` (upper Cholesky factor of ``P_NN``) give the same moments as sigma points over all
states with a square root whose first rows are ``[R_NN, R_NN^-T P_NO]`` (the Cholesky factor of P
with ``N`` ordered first), and the cross-covariance of every state with ``f`` is the Gaussian
regression ``P_xN R_NN^-1 G``,
``G = (1/2h) [d_j+ - d_j-]_j`` (:func:`regression_cross_into`). States on which ``f`` depends
linearly (``f = H_L x_L + g(x_N)``) can be left out of the sigma points and added in closed form.

Update (:func:`joseph_update`): with ``U = Pxz^T`` (m, n) and ``S = Pzz + R``, the gain is
``K = U^T S^-1``; ``P - K U^T - D K^T`` with ``D = U - K S`` is the Joseph form
``(I - K H) P (I - K H)^T + K R_e K^T`` of the statistically linearised measurement
``H = U P^-1`` (``R_e = S - H P H^T``), written without ``P^-1``: exactly symmetric (lower
triangle mirrored) and first-order insensitive to rounding in ``K``.
"""

from __future__ import annotations

import numpy as np
from ..jit import njit

from .kalman import add_row_combinations, joseph_update  # joseph_update: the update from U and S (below)


def ut_spread(n: int, alpha: float, beta: float, kappa: float) -> tuple[float, float]:
    """``(h, w2)``: the spread ``h = alpha sqrt(n + kappa)`` (sigmas) and the weight
    ``w2 = beta - alpha^2`` of the central form's ``m m^T`` term, for ``n`` states."""
    check_ut_params(n, alpha, beta, kappa)
    return float(alpha * np.sqrt(n + kappa)), float(beta - alpha * alpha)


def check_ut_params(n: int, alpha: float, beta: float, kappa: float) -> None:
    """Refuse parameters without a real spread or with a covariance that may not be positive
    semidefinite (ValueError naming the parameter)."""
    if not (np.isfinite(alpha) and alpha > 0):
        raise ValueError(f"alpha = {alpha}: must be > 0 (the spread of the sigma points)")
    if not (np.isfinite(kappa) and n + kappa > 0):
        raise ValueError(f"kappa = {kappa}: n + kappa must be > 0 (n = {n})")
    if not (np.isfinite(beta) and beta >= alpha * alpha):
        raise ValueError(f"beta = {beta}: must be >= alpha^2 = {alpha * alpha:g} so that the "
                         "covariance is a sum with non-negative weights")


def ut_weights(n: int, alpha: float, beta: float, kappa: float) -> tuple[float, float, float]:
    """Textbook weights ``(Wm_0, Wc_0, W_i)`` of the scaled transform (for reference and tests;
    the kernels use the central form, which needs only :func:`ut_spread`)."""
    c = alpha * alpha * (n + kappa)
    wm0 = 1.0 - n / c
    return wm0, wm0 + 1.0 - alpha * alpha + beta, 0.5 / c


@njit(cache=True)
def cholesky_upper_into(A, R):
    """Upper Cholesky factor ``R`` of the symmetric ``A`` (``A = R^T R``; its lower triangle is
    read; ``R`` may be ``A`` itself, strict lower triangle zeroed). Returns False if ``A`` is not
    positive definite.

    Up-looking (row by row) form: row k of ``R`` is ``A[k:, k]`` less ``R[j, k] R[j, k:]`` for
    j = 0, 1, ..., k - 1 in that order, then divided by its pivot's square root; rows of ``R``
    are the sigma directions. Every entry gets the same operations in the same order as in the
    right-looking (outer-product) form, so the factor is the same to the last bit; the row being
    built stays in a small accumulator and takes four rows above it per pass, which the compiler
    vectorises (about 3x faster at n = 48, issue 22).
    """
    n = A.shape[0]
    # the row under construction, apart from R: R may be A itself, whose lower triangle is read
    acc = np.empty(n)
    for k in range(n):
        m = n - k
        for i in range(m):
            acc[i] = A[k + i, k]
        j = 0
        while j + 4 <= k:
            c0, c1, c2, c3 = R[j, k], R[j + 1, k], R[j + 2, k], R[j + 3, k]
            for i in range(m):
                # the parentheses keep the order j, j + 1, j + 2, j + 3 of each entry's updates
                acc[i] = (((acc[i] - c0 * R[j, k + i]) - c1 * R[j + 1, k + i]) - c2 * R[j + 2, k + i]) \
                    - c3 * R[j + 3, k + i]
            j += 4
        while j < k:
            c = R[j, k]
            for i in range(m):
                acc[i] -= c * R[j, k + i]
            j += 1
        v = acc[0]
        if not v > 0.0:
            return False
        d = np.sqrt(v)
        R[k, k] = d
        inv = 1.0 / d
        for i in range(1, m):
            R[k, k + i] = acc[i] * inv
    for i in range(n):
        for j in range(i):
            R[i, j] = 0.0
    return True


@njit(cache=True)
def sigma_points_into(x, R, h, X):
    """Sigma points ``X`` (2 nl + 1, n): ``x``, then ``x + h R[j]``, then ``x - h R[j]`` for the
    ``nl`` rows of a square root ``R`` (nl, n) of P (``P = R^T R``; e.g. the upper Cholesky factor)."""
    nl, n = R.shape
    for i in range(n):
        X[0, i] = x[i]
    for j in range(nl):
        for i in range(n):
            d = h * R[j, i]
            X[1 + j, i] = x[i] + d
            X[1 + nl + j, i] = x[i] - d


@njit(cache=True)
def ut_moments_into(Dp, Dm, h, w2, m, cov):
    """Mean shift ``m`` (q,) and covariance ``cov`` (q, q) of the central form from the
    deviations ``Dp``, ``Dm`` (nl, q) of the outputs at ``X_j+`` and ``X_j-`` from the output at
    the central point; the mean is ``Y_0 + m``. ``cov`` is exactly symmetric."""
    nl, q = Dp.shape
    ic = 0.5 / (h * h)
    for r in range(q):
        s = 0.0
        for j in range(nl):
            s += Dp[j, r] + Dm[j, r]
        m[r] = ic * s
    for r in range(q):
        for c in range(r + 1):
            s = 0.0
            for j in range(nl):
                s += Dp[j, r] * Dp[j, c] + Dm[j, r] * Dm[j, c]
            v = ic * s + w2 * m[r] * m[c]
            cov[r, c] = v
            cov[c, r] = v


@njit(cache=True)
def ut_cross_into(R, Dp, Dm, h, C):
    """Cross-covariance ``C`` (n, q) of the states with the outputs: ``(1/2h) sum_j R[j]^T
    (Dp[j] - Dm[j])`` for the square root ``R`` (nl, n) the sigma points were drawn with."""
    nl, n = R.shape
    q = Dp.shape[1]
    i2h = 0.5 / h
    for i in range(n):
        for r in range(q):
            C[i, r] = 0.0
    for j in range(nl):
        rj = R[j]
        for r in range(q):
            g = i2h * (Dp[j, r] - Dm[j, r])
            for i in range(n):
                C[i, r] += rj[i] * g


@njit(cache=True)
def regression_cross_into(P, idx, R, Dp, Dm, h, Y, C):
    """Cross-covariance ``C`` (q, n) (transposed: one contiguous row per output) of every state
    with a function of the states ``idx`` only, from sigma points drawn with ``R``, the upper
    Cholesky factor of ``P[idx][:, idx]``: ``C^T = P[:, idx] R^-1 G`` with ``G = (Dp - Dm) / 2h``
    (the Gaussian linear regression of the other states on ``x[idx]``). ``Y`` (nl, q) scratch.

    For the states in ``idx`` this is ``R^T G``, the plain cross-covariance of the transform.
    """
    nl = idx.shape[0]
    q = Dp.shape[1]
    n = P.shape[0]
    i2h = 0.5 / h
    # R Y = G by back substitution, all outputs at once
    for i in range(nl - 1, -1, -1):
        yi = Y[i]
        ri = R[i]
        for r in range(q):
            yi[r] = i2h * (Dp[i, r] - Dm[i, r])
        for k in range(i + 1, nl):
            c = ri[k]
            yk = Y[k]
            for r in range(q):
                yi[r] -= c * yk[r]
        d = 1.0 / ri[i]
        for r in range(q):
            yi[r] *= d
    for r in range(q):
        cr = C[r]
        for j in range(n):
            cr[j] = 0.0
    add_row_combinations(Y.T, P, idx, nl, C)


def unscented_transform(f, mean, cov, alpha=1.0, beta=2.0, kappa=None):
    """Mean, covariance and state cross-covariance of ``y = f(x)`` for ``x ~ N(mean, cov)`` by the
    scaled unscented transform (central form). ``f`` maps an (n,) array to a (q,) array; ``kappa``
    None means ``3 - n``. Returns ``(ybar (q,), Pyy (q, q), Pxy (n, q))``. For tests and small
    problems; the filters call the compiled pieces directly.
    """
    x0 = np.asarray(mean, float)
    n = x0.size
    kappa = 3.0 - n if kappa is None else float(kappa)
    h, w2 = ut_spread(n, alpha, beta, kappa)
    R = np.zeros((n, n))
    if not cholesky_upper_into(np.asarray(cov, float), R):
        raise ValueError("cov is not positive definite")
    X = np.empty((2 * n + 1, n))
    sigma_points_into(x0, R, h, X)
    Y = np.array([np.atleast_1d(f(X[i])) for i in range(2 * n + 1)], float)
    Dp, Dm = Y[1:n + 1] - Y[0], Y[n + 1:] - Y[0]
    q = Y.shape[1]
    m, Pyy, Pxy = np.empty(q), np.empty((q, q)), np.empty((n, q))
    ut_moments_into(Dp, Dm, h, w2, m, Pyy)
    ut_cross_into(R, Dp, Dm, h, Pxy)
    return Y[0] + m, Pyy, Pxy
