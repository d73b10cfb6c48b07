"""The iterated EKF measurement update (Gauss-Newton form), for any measurement function.

Rig-independent: a rig passes its measurement as a numba-compiled function ``resid_fn`` and a
context tuple; nothing here names a rig. The propagation is left to the rig (an iterated EKF
relinearises the update only).

Gauss-Newton IEKF (Bell and Cathey, IEEE TAC 38(2), 1993): with the prior ``(x-, P-)``, the
update is the Gauss-Newton minimiser of

    (x - x-)^T P-^-1 (x - x-) + (z - h(x))^T R^-1 (z - h(x)),

iterated from ``x_0 = x-`` as

    H_i = dh/dx (x_i),   r_i = z - h(x_i) - H_i (x- - x_i),   x_{i+1} = x- + K_i r_i,
    K_i = P- H_i^T (H_i P- H_i^T + R)^-1,

stopping after ``max_iter`` linearisations or when the step ``max_j |x_{i+1,j} - x_{i,j}| /
sqrt(P-_jj)`` (prior sigmas) is below ``tol``; the covariance is updated once, in Joseph form,
with the gain and Jacobian of the last linearisation (``(I - K H) P- (I - K H)^T + K R K^T``,
:func:`platcal.estimation.kalman.joseph_update_sparse`). ``max_iter = 1`` (or ``tol = inf``) is
the EKF update exactly. Linear rows of h (e.g. angle sensors) are carried through unchanged: for
them ``r_i`` does not depend on ``x_i``, so a measurement split into linear and nonlinear parts
gives the same iterates as the joint update.

The Jacobian has sparse rows in the layout of :func:`~platcal.estimation.kalman.joseph_update_sparse`:
row ``r`` is nonzero at the states ``hcols[r, :hnnz[r]]`` with values ``hval[r, :hnnz[r]]``.

The measurement function
------------------------
``resid_fn(ctx, x, z, res, hval, hcols, hnnz)`` (``@njit``) writes the residual
``res = z - h(x)`` (m,), already wrapped where a component is an angle, and the sparse Jacobian
rows of ``h`` at ``x``. ``ctx`` is any tuple the function needs (e.g. the commanded attitude and
scratch arrays).

Compiled ``inline="always"``: the measurement function then reaches the caller as a direct call
(passing a numba dispatcher as a value would embed its address and stop the caller from being
cached).

Cost per extra iteration: one evaluation of h and ``U = P H^T`` (O(m w n)), the Cholesky factor
of S and ``K r`` (O(m^2 n)); the O(m n^2) covariance update is done once.
"""

from __future__ import annotations

import numpy as np
from ..jit import njit

from .kalman import cholesky_inverse, innovation_covariance, joseph_update_sparse


@njit(cache=True)
def make_iterated_scratch(n, m, w):
    """Scratch of :func:`iterated_update_sparse` for n states, an m-D measurement and at most w
    nonzeros per Jacobian row: ``(xp, xi, xn, res, innov, hval, hcols, hnnz, U, K, D, S, Sinv, nu)``."""
    return (np.empty(n), np.empty(n), np.empty(n), np.empty(m), np.empty(m), np.zeros((m, w)),
            np.zeros((m, w), dtype=np.int64), np.zeros(m, dtype=np.int64), np.empty((m, n)),
            np.empty((m, n)), np.empty((m, n)), np.empty((m, m)), np.empty((m, m)), np.empty(m))


@njit(cache=True)
def gn_innovation(res, hval, hcols, hnnz, xp, xi, innov):
    """``innov = res - H (xp - xi)``: the Gauss-Newton innovation at the linearisation point xi."""
    for r in range(hnnz.shape[0]):
        v = res[r]
        for t in range(hnnz[r]):
            c = hcols[r, t]
            v -= hval[r, t] * (xp[c] - xi[c])
        innov[r] = v


@njit(cache=True)
def gain_step(P, hval, hcols, hnnz, r_var, innov, xp, xout, U, S, Sinv, nu):
    """``xout = xp + P H^T (H P H^T + R)^-1 innov`` without touching P.

    ``nu`` receives the standardised innovation ``L^-1 innov`` (S = L L^T). Returns False if S is
    not positive definite.
    """
    innovation_covariance(P, hcols, hnnz, hval, r_var, U, S)
    if not cholesky_inverse(S, Sinv, nu, innov):
        return False
    n = P.shape[0]
    m = hnnz.shape[0]
    for j in range(n):
        xout[j] = xp[j]
    for r in range(m):
        a = 0.0
        for c in range(m):
            a += Sinv[r, c] * innov[c]
        ur = U[r]
        for j in range(n):
            xout[j] += ur[j] * a
    return True


@njit(cache=True, inline="always")
def gauss_newton_point(x, P, z, r_var, resid_fn, ctx, max_iter, tol, scratch, nis_out):
    """The iterations of :func:`iterated_update_sparse` without the final update.

    x and P (the prior) are left unchanged; the scratch's ``hval, hcols, hnnz`` hold the Jacobian
    rows at the last linearisation point x_i and ``innov`` the Gauss-Newton innovation
    ``z - h(x_i) - H_i (x - x_i)``. The update of x and P is then the linear Kalman update of the
    prior with that H and innovation, which a caller may split into independent measurement
    blocks (R diagonal: sequential blocks give the same result; a linear block's innovation is
    recomputed at the state the previous block left).

    Returns ``(used, gained)``: the linearisations used (0 if an innovation covariance was not
    positive definite) and whether a gain step ran (then ``nis_out`` holds the standardised
    innovation of the first linearisation, at the prior).
    """
    xp, xi, xn, res, innov, hval, hcols, hnnz, U, K, D, S, Sinv, nu = scratch
    n = x.shape[0]
    m = z.shape[0]
    for j in range(n):
        xp[j] = x[j]
        xi[j] = x[j]
    used = 0
    gained = False
    for it in range(max_iter):
        resid_fn(ctx, xi, z, res, hval, hcols, hnnz)
        gn_innovation(res, hval, hcols, hnnz, xp, xi, innov)
        used = it + 1
        if it == max_iter - 1:
            break
        if not gain_step(P, hval, hcols, hnnz, r_var, innov, xp, xn, U, S, Sinv, nu):
            return 0, gained
        if it == 0:
            gained = True
            for r in range(m):
                nis_out[r] = nu[r]
        step = 0.0
        for j in range(n):
            pj = P[j, j]
            if pj > 0.0:
                d = abs(xn[j] - xi[j]) / np.sqrt(pj)
                if d > step:
                    step = d
        if step < tol:
            break
        for j in range(n):
            xi[j] = xn[j]
    return used, gained


@njit(cache=True, inline="always")
def iterated_update_sparse(x, P, z, r_var, resid_fn, ctx, max_iter, tol, scratch, nis_out):
    """One Gauss-Newton iterated EKF update (see the module docstring), in place on x and P.

    Parameters
    ----------
    x : (n,) prior state, replaced by the posterior. P : (n, n) prior covariance, replaced by
        the Joseph-form posterior (exactly symmetric).
    z : (m,) measurement. r_var : (m,) measurement-noise variances (R diagonal).
    resid_fn, ctx : the measurement function and its context (module docstring).
    max_iter : linearisations at most (>= 1; 1 = EKF). tol : stop when the step is below ``tol``
        prior sigmas in every state.
    scratch : :func:`make_iterated_scratch` (n, m, w).
    nis_out : (m,) receives the standardised innovation of the first linearisation (at the
        prior: the EKF's innovation, whose squared norm is the NIS).

    Returns
    -------
    int : the number of linearisations used (>= 1), or 0 if an innovation covariance was not
    positive definite (x and P then unchanged).
    """
    used, gained = gauss_newton_point(x, P, z, r_var, resid_fn, ctx, max_iter, tol, scratch, nis_out)
    if used == 0:
        return 0
    xp, xi, xn, res, innov, hval, hcols, hnnz, U, K, D, S, Sinv, nu = scratch
    # the covariance (and the returned state, = xn when the loop stopped on tol) from the last
    # linearisation, Joseph form
    if not joseph_update_sparse(x, P, hcols, hnnz, hval, innov, r_var, U, K, D, S, Sinv, nu, True):
        return 0
    if not gained:
        for r in range(z.shape[0]):
            nis_out[r] = nu[r]
    return used
