"""Dense Kalman-filter oracles (numba): the plain forms the structured production kernels of
:mod:`platcal.estimation.kalman` are checked against (``test_ekf.py``)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def propagate_rows(P, dyn, phi_rows, q, W):
    """``P <- Phi P Phi^T + Q`` where Phi is the identity except for the rows ``dyn``.

    Parameters
    ----------
    P : (n, n) covariance, updated in place.
    dyn : (d,) int, indices of the dynamic states (the only rows of Phi that are not I).
    phi_rows : (d, n) those rows of Phi.
    q : (d, d) process-noise covariance of the dynamic states.
    W : (n, d) scratch.

    Only the ``dyn`` rows and columns of ``P`` change, so the cost is O(d n^2).
    """
    n = P.shape[0]
    d = dyn.shape[0]
    for i in range(n):
        for r in range(d):
            s = 0.0
            for k in range(n):
                s += P[i, k] * phi_rows[r, k]
            W[i, r] = s
    for r in range(d):
        for i in range(n):
            P[i, dyn[r]] = W[i, r]
            P[dyn[r], i] = W[i, r]
    for r in range(d):
        for c in range(r, d):
            s = 0.0
            for k in range(n):
                s += phi_rows[r, k] * W[k, c]
            v = s + 0.5 * (q[r, c] + q[c, r])
            if c != r:
                s2 = 0.0
                for k in range(n):
                    s2 += phi_rows[c, k] * W[k, r]
                v = 0.5 * (v + s2 + 0.5 * (q[r, c] + q[c, r]))
            P[dyn[r], dyn[c]] = v
            P[dyn[c], dyn[r]] = v


@njit(cache=True)
def inv_sym3(S, out):
    """Inverse of a symmetric positive-definite 3x3 matrix via its Cholesky factor.

    Returns False (and leaves ``out`` undefined) if S is not positive definite.
    """
    l00 = S[0, 0]
    if not l00 > 0.0:
        return False
    l00 = np.sqrt(l00)
    l10 = S[1, 0] / l00
    l20 = S[2, 0] / l00
    d1 = S[1, 1] - l10 * l10
    if not d1 > 0.0:
        return False
    l11 = np.sqrt(d1)
    l21 = (S[2, 1] - l20 * l10) / l11
    d2 = S[2, 2] - l20 * l20 - l21 * l21
    if not d2 > 0.0:
        return False
    l22 = np.sqrt(d2)
    # inverse of the lower factor L
    i00 = 1.0 / l00
    i11 = 1.0 / l11
    i22 = 1.0 / l22
    i10 = -l10 * i00 * i11
    i21 = -l21 * i11 * i22
    i20 = -(l20 * i00 + l21 * i10) * i22
    # S^-1 = L^-T L^-1
    out[0, 0] = i00 * i00 + i10 * i10 + i20 * i20
    out[1, 1] = i11 * i11 + i21 * i21
    out[2, 2] = i22 * i22
    out[0, 1] = out[1, 0] = i10 * i11 + i20 * i21
    out[0, 2] = out[2, 0] = i20 * i22
    out[1, 2] = out[2, 1] = i21 * i22
    return True


@njit(cache=True)
def joseph_update(x, P, H, innov, r_var, U, K, D, S, Sinv, nu, update_x):
    """Kalman update with a 3-dimensional measurement in Joseph form, O(n^2).

    ``P <- (I - K H) P (I - K H)^T + K R K^T`` evaluated exactly through ``U = P H^T`` and
    ``S = H U + R`` as ``P - K U^T - (U - K S) K^T`` (valid for any gain K, symmetric by
    construction and symmetrised on write).

    Parameters
    ----------
    x : (n,) state, updated in place when ``update_x``.
    P : (n, n) covariance, updated in place.
    H : (3, n) measurement Jacobian.
    innov : (3,) innovation ``z - h(x)``.
    r_var : (3,) measurement-noise variances (R diagonal).
    U, K, D : (n, 3) scratch; S, Sinv : (3, 3) scratch.
    nu : (3,) out, the standardised innovation ``L^-1 innov`` (for NIS).

    Returns
    -------
    bool : False if ``S`` was not positive definite (the update is skipped).
    """
    n = P.shape[0]
    for i in range(n):
        for r in range(3):
            s = 0.0
            for k in range(n):
                s += P[i, k] * H[r, k]
            U[i, r] = s
    for r in range(3):
        for c in range(3):
            s = 0.0
            for k in range(n):
                s += H[r, k] * U[k, c]
            S[r, c] = s
    for r in range(3):
        for c in range(r + 1, 3):
            v = 0.5 * (S[r, c] + S[c, r])
            S[r, c] = v
            S[c, r] = v
        S[r, r] += r_var[r]
    if not inv_sym3(S, Sinv):
        return False
    # standardised innovation via the Cholesky factor of S (recomputed: 3x3, cheap)
    l00 = np.sqrt(S[0, 0])
    l10 = S[1, 0] / l00
    l20 = S[2, 0] / l00
    l11 = np.sqrt(S[1, 1] - l10 * l10)
    l21 = (S[2, 1] - l20 * l10) / l11
    l22 = np.sqrt(S[2, 2] - l20 * l20 - l21 * l21)
    nu[0] = innov[0] / l00
    nu[1] = (innov[1] - l10 * nu[0]) / l11
    nu[2] = (innov[2] - l20 * nu[0] - l21 * nu[1]) / l22
    for i in range(n):
        for c in range(3):
            K[i, c] = U[i, 0] * Sinv[0, c] + U[i, 1] * Sinv[1, c] + U[i, 2] * Sinv[2, c]
        for c in range(3):
            D[i, c] = U[i, c] - (K[i, 0] * S[0, c] + K[i, 1] * S[1, c] + K[i, 2] * S[2, c])
        if update_x:
            x[i] += K[i, 0] * innov[0] + K[i, 1] * innov[1] + K[i, 2] * innov[2]
    for i in range(n):
        for j in range(i + 1):
            a = 0.0
            b = 0.0
            for c in range(3):
                a += K[i, c] * U[j, c] + D[i, c] * K[j, c]
                b += K[j, c] * U[i, c] + D[j, c] * K[i, c]
            v = 0.5 * ((P[i, j] - a) + (P[j, i] - b))
            P[i, j] = v
            P[j, i] = v
    return True
