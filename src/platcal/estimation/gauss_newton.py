"""Gauss-Newton / Levenberg-Marquardt on normal equations, with a Gaussian prior (MAP), batched.

The caller supplies the data part of the normal equations at a parameter vector ``theta``::

    N = J' W J,    g = J' W r,    c = r' W r,        r = z - h(theta)

(``W`` the inverse measurement covariance, or the whitening of any Gaussian error model), for
a batch of independent problems. The prior is ``theta ~ N(mu, diag(sigma^2))``. Every solve
happens in prior-normalised units ``u = (theta - mu) / sigma`` (``u = 0`` where ``sigma = 0``,
i.e. a parameter held at its prior mean), where the MAP normal equations read::

    A = D N D + I,      b = D g - u,        A du = b,     D = diag(sigma)

so parameters of very different units (deg/h, ug, rad) give a well-conditioned ``A``. The
objective is ``c + u'u``. The covariance returned is ``D A^-1 D`` at the estimate: the inverse
of the Gauss-Newton information plus the prior's (the Laplace approximation of the posterior,
and the Bayesian Cramer-Rao bound of the linearised model).

Convergence: the Newton decrement ``sqrt(du' A du)`` below ``tol``. It bounds the step of
every parameter in units of its posterior sigma (``|du_i| <= sqrt(du'A du) sqrt(A^-1_ii)``),
so ``tol = 1e-3`` stops when no parameter would move by more than a thousandth of its sigma;
that last step is not taken and the covariance is the one at the returned estimate.

Damping (Levenberg-Marquardt, optional): the step solves ``(A + lam diag(A)) du = b`` and is
accepted only if the objective decreases; ``lam`` is divided by 10 after an accepted step and
multiplied by 10 after a rejected one. Plain Gauss-Newton (no damping) takes every step.

Each problem of the batch is solved on its own (``scipy.linalg.cho_factor`` / ``cho_solve``
per problem), so its numbers do not depend on the batch it is in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.linalg import cho_factor, cho_solve

Evaluate = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""``evaluate(theta (Ba, n), rows (Ba,)) -> (N (Ba, n, n), g (Ba, n), c (Ba,))``: the data part
of the normal equations of the problems ``rows`` of the batch at ``theta``."""


@dataclass
class GNResult:
    """Result of :func:`solve_map` for a batch of B problems.

    Attributes
    ----------
    theta : (B, n) MAP estimate.
    cov : (B, n, n) inverse of (information + prior information) at ``theta``, symmetric.
    steps : (B,) accepted steps taken.
    evaluations : (B,) calls of the normal equations (rejected damped steps included).
    converged : (B,) the Newton decrement fell below ``tol`` within ``max_iter`` steps.
    cost : (B,) objective ``c + u'u`` at ``theta``.
    data_cost : (B,) its data part ``c``.
    decrement : (B,) last Newton decrement (posterior sigmas).
    """

    theta: np.ndarray
    cov: np.ndarray
    steps: np.ndarray
    evaluations: np.ndarray
    converged: np.ndarray
    cost: np.ndarray
    data_cost: np.ndarray
    decrement: np.ndarray


def _normalised(N, g, theta, mu, sigma):
    """``(A, b, u)`` of the MAP normal equations in prior-normalised units (module docstring)."""
    safe = np.where(sigma > 0, sigma, 1.0)
    u = np.where(sigma > 0, (theta - mu) / safe, 0.0)
    A = N * (sigma[:, None] * sigma[None, :])
    A[np.diag_indices_from(A)] += 1.0
    b = sigma * g - u
    return 0.5 * (A + A.T), b, u


def solve_map(evaluate: Evaluate, theta0: np.ndarray, prior_mean: np.ndarray, prior_sigma: np.ndarray, *,
              max_iter: int = 20, tol: float = 1e-3, damping: bool = False, lam0: float = 1e-3,
              max_rejections: int = 10) -> GNResult:
    """MAP estimate by Gauss-Newton (or Levenberg-Marquardt with ``damping``) for a batch.

    Parameters
    ----------
    evaluate : the data part of the normal equations (:data:`Evaluate`).
    theta0 : (B, n) starting points.
    prior_mean : (n,) or (B, n) prior means; prior_sigma : (n,) or (B, n) prior 1-sigma (>= 0).
    max_iter : most accepted steps per problem.
    tol : Newton decrement (in posterior sigmas) at which a problem has converged.
    damping : Levenberg-Marquardt instead of plain Gauss-Newton.
    lam0 : initial damping; max_rejections : rejected damped steps in a row before giving up.
    """
    theta = np.array(theta0, float, copy=True)
    B, n = theta.shape
    mu = np.broadcast_to(np.asarray(prior_mean, float), (B, n))
    sig = np.broadcast_to(np.asarray(prior_sigma, float), (B, n))
    if np.any(sig < 0) or not np.all(np.isfinite(sig)):
        raise ValueError("prior_sigma must be finite and >= 0")
    steps = np.zeros(B, dtype=np.int64)
    evals = np.zeros(B, dtype=np.int64)
    converged = np.zeros(B, dtype=bool)
    cost = np.full(B, np.nan)
    data_cost = np.full(B, np.nan)
    dec = np.full(B, np.nan)
    cov = np.full((B, n, n), np.nan)
    lam = np.full(B, lam0)
    rejections = np.zeros(B, dtype=np.int64)
    # state at the current accepted point of each problem
    A_cur = np.zeros((B, n, n))
    b_cur = np.zeros((B, n))
    active = np.arange(B)
    pending = theta.copy()          # point to evaluate next, per problem
    have_point = np.zeros(B, dtype=bool)
    while active.size:
        N, g, c = evaluate(pending[active], active)
        evals[active] += 1
        still = []
        for i, b in enumerate(active):
            A, bb, u = _normalised(N[i], g[i], pending[b], mu[b], sig[b])
            new_cost = float(c[i] + u @ u)
            finite = np.isfinite(new_cost)
            if have_point[b] and (not finite or (damping and new_cost >= cost[b])):
                # a damped step into non-finite territory or uphill: reject it, retry shorter
                lam[b] *= 10.0
                rejections[b] += 1
                if rejections[b] > max_rejections:
                    continue
                pending[b] = _step(A_cur[b], b_cur[b], theta[b], sig[b], lam[b], damping)
                still.append(b)
                continue
            if not finite:  # the starting point itself is not finite: the problem stops here
                continue
            if have_point[b]:
                steps[b] += 1
                lam[b] = max(lam[b] / 10.0, 1e-12)
                rejections[b] = 0
            have_point[b] = True
            theta[b] = pending[b]
            cost[b], data_cost[b] = new_cost, float(c[i])
            A_cur[b], b_cur[b] = A, bb
            solved = _newton_solve(A, bb, sig[b])
            if solved is None:
                continue
            cf, _, dec[b], cov[b] = solved
            if dec[b] < tol:
                converged[b] = True
                continue
            if steps[b] >= max_iter:
                continue
            pending[b] = _step(A, bb, theta[b], sig[b], lam[b], damping, cf)
            still.append(b)
        active = np.array(still, dtype=np.int64)
    return GNResult(theta=theta, cov=cov, steps=steps, evaluations=evals, converged=converged, cost=cost,
                    data_cost=data_cost, decrement=dec)


def _newton_solve(A, b, sigma):
    """Newton step of the normalised normal equations ``A du = b``: ``(cho_factor(A), du, Newton
    decrement sqrt(du^T A du), covariance A^-1 in the states' units (symmetrised))``, or None when
    A is not positive definite."""
    try:
        cf = cho_factor(A, lower=True)
    except np.linalg.LinAlgError:
        return None
    du = cho_solve(cf, b)
    Ainv = cho_solve(cf, np.eye(A.shape[0]))
    return cf, du, float(np.sqrt(max(du @ A @ du, 0.0))), 0.5 * (Ainv + Ainv.T) * (sigma[:, None] * sigma[None, :])


def _step(A, b, theta, sigma, lam, damping, cf=None):
    """The next point: ``theta + sigma du`` with ``du`` the (damped) solution of ``A du = b``."""
    if damping:
        Ad = A + lam * np.diag(np.diag(A))
        du = cho_solve(cho_factor(Ad, lower=True), b)
    else:
        du = cho_solve(cf if cf is not None else cho_factor(A, lower=True), b)
    return theta + sigma * du


def one_step(N: np.ndarray, g: np.ndarray, c: np.ndarray, theta: np.ndarray, prior_mean: np.ndarray,
             prior_sigma: np.ndarray) -> GNResult:
    """One undamped Gauss-Newton step from ``theta`` (B, n) given the normal equations there.

    The one-step estimator: from a consistent preliminary estimate, a single Newton step on the
    full likelihood is asymptotically as good as iterating to convergence (Le Cam). The
    covariance is the inverse information (plus prior) at the linearisation point ``theta``, the
    objective and ``decrement`` those at ``theta`` (nothing is evaluated after the step).
    """
    theta = np.asarray(theta, float)
    B, n = theta.shape
    mu = np.broadcast_to(np.asarray(prior_mean, float), (B, n))
    sig = np.broadcast_to(np.asarray(prior_sigma, float), (B, n))
    out = theta.copy()
    cov = np.full((B, n, n), np.nan)
    cost = np.full(B, np.nan)
    dec = np.full(B, np.nan)
    ok = np.zeros(B, dtype=bool)
    for b in range(B):
        A, bb, u = _normalised(N[b], g[b], theta[b], mu[b], sig[b])
        cost[b] = float(c[b] + u @ u)
        solved = _newton_solve(A, bb, sig[b])
        if solved is None:
            continue
        _, du, dec[b], cov[b] = solved
        out[b] = theta[b] + sig[b] * du
        ok[b] = True
    return GNResult(theta=out, cov=cov, steps=ok.astype(np.int64), evaluations=np.ones(B, dtype=np.int64),
                    converged=ok, cost=cost, data_cost=np.asarray(c, float).copy(), decrement=dec)
