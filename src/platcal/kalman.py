"""Rig-agnostic Kalman-filter primitives for one replicate, compiled with numba.

The covariance ``P`` is (n, n) and symmetric. The kernels exploit the structure of the
identification problems in this package: constant coefficients (only a few "dynamic" states
have a non-identity row in the transition matrix) and a low-dimensional measurement, so every
step costs O(n^2) rather than O(n^3).
"""

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


@njit(cache=True)
def propagate_sparse(P, dyn, cols, phi, q, W, blk):
    """``P <- Phi P Phi^T + Q`` where Phi is the identity except for the rows ``dyn``, and those
    rows are nonzero only in the columns ``cols``.

    Parameters
    ----------
    P : (n, n) symmetric covariance, updated in place (kept exactly symmetric).
    dyn : (d,) int, indices of the dynamic states.
    cols : (m,) int, the columns where the dynamic rows of Phi may be nonzero (``dyn`` among them).
    phi : (d, m) the values of those rows at ``cols``.
    q : (d, d) process-noise covariance of the dynamic states.
    W : (d, n) scratch; receives ``Phi[dyn] P``. blk : (d, d) scratch.

    Cost O(d m n): with m ~ 30 nonzero columns of a 48-state filter, well under one n^3.
    """
    n = P.shape[0]
    d = dyn.shape[0]
    m = cols.shape[0]
    for r in range(d):
        wr = W[r]
        for j in range(n):
            wr[j] = 0.0
    # rows of P are columns of P (symmetric): W[r] = sum_k phi[r, k] P[cols[k]] as axpys,
    # contiguous and vectorisable; with three dynamic states (attitude) one pass over each row
    # of P feeds all three
    if d == 3:
        w0, w1, w2 = W[0], W[1], W[2]
        for k in range(m):
            prow = P[cols[k]]
            c0, c1, c2 = phi[0, k], phi[1, k], phi[2, k]
            for j in range(n):
                p = prow[j]
                w0[j] += c0 * p
                w1[j] += c1 * p
                w2[j] += c2 * p
    else:
        for k in range(m):
            prow = P[cols[k]]
            for r in range(d):
                c = phi[r, k]
                wr = W[r]
                for j in range(n):
                    wr[j] += c * prow[j]
    # the dyn-dyn block, Phi P Phi^T restricted to dyn, before P's rows are overwritten
    for r in range(d):
        for c in range(r + 1):
            s = 0.0
            for k in range(m):
                s += W[r, cols[k]] * phi[c, k]
            v = s + 0.5 * (q[r, c] + q[c, r])
            blk[r, c] = v
            blk[c, r] = v
    for r in range(d):
        dr = dyn[r]
        wr = W[r]
        prow = P[dr]
        for j in range(n):
            prow[j] = wr[j]
            P[j, dr] = wr[j]
    for r in range(d):
        for c in range(d):
            P[dyn[r], dyn[c]] = blk[r, c]


@njit(cache=True)
def joseph_update_sparse(x, P, hcols, hnnz, hval, innov, r_var, U, K, D, S, Sinv, nu, update_x):
    """Kalman update with a 3-dimensional measurement whose Jacobian rows are sparse, in Joseph
    form, O(n^2) with a small constant.

    Row r of H is nonzero only at the states ``hcols[r, :hnnz[r]]`` with values
    ``hval[r, :hnnz[r]]``. With ``U = P H^T`` (n x 3), ``S = H U + R``, ``K = U S^-1`` and
    ``D = U - K S`` the Joseph form ``(I - K H) P (I - K H)^T + K R K^T`` equals
    ``P - K U^T - D K^T`` exactly, for any gain K. Only the lower triangle is computed and it
    is mirrored, so P stays exactly symmetric.

    Parameters
    ----------
    x : (n,) state, updated in place when ``update_x``.
    P : (n, n) symmetric covariance, updated in place.
    hcols, hval : (3, m) int and float; hnnz : (3,) int. The sparse rows of H.
    innov : (3,) innovation ``z - h(x)`` (unused unless ``update_x``).
    r_var : (3,) measurement-noise variances (R diagonal).
    U, K, D : (3, n) scratch (stored transposed for contiguous rows); S, Sinv : (3, 3) scratch.
    nu : (3,) out, the standardised innovation ``L^-1 innov`` (for NIS).

    Returns
    -------
    bool : False if ``S`` was not positive definite (the update is skipped).
    """
    n = P.shape[0]
    for r in range(3):
        ur = U[r]
        for j in range(n):
            ur[j] = 0.0
        for t in range(hnnz[r]):
            c = hval[r, t]
            prow = P[hcols[r, t]]
            for j in range(n):
                ur[j] += c * prow[j]
    for r in range(3):
        for c in range(r + 1):
            s = 0.0
            for t in range(hnnz[c]):
                s += U[r, hcols[c, t]] * hval[c, t]
            S[r, c] = s
            S[c, r] = s
        S[r, r] += r_var[r]
    if not inv_sym3(S, Sinv):
        return False
    l00 = np.sqrt(S[0, 0])
    l10 = S[1, 0] / l00
    l20 = S[2, 0] / l00
    l11 = np.sqrt(S[1, 1] - l10 * l10)
    l21 = (S[2, 1] - l20 * l10) / l11
    l22 = np.sqrt(S[2, 2] - l20 * l20 - l21 * l21)
    nu[0] = innov[0] / l00
    nu[1] = (innov[1] - l10 * nu[0]) / l11
    nu[2] = (innov[2] - l20 * nu[0] - l21 * nu[1]) / l22
    for c in range(3):
        kc = K[c]
        s0, s1, s2 = Sinv[c, 0], Sinv[c, 1], Sinv[c, 2]
        for j in range(n):
            kc[j] = s0 * U[0, j] + s1 * U[1, j] + s2 * U[2, j]
    for c in range(3):
        dc = D[c]
        s0, s1, s2 = S[c, 0], S[c, 1], S[c, 2]
        for j in range(n):
            dc[j] = U[c, j] - (s0 * K[0, j] + s1 * K[1, j] + s2 * K[2, j])
    if update_x:
        i0, i1, i2 = innov[0], innov[1], innov[2]
        for j in range(n):
            x[j] += K[0, j] * i0 + K[1, j] * i1 + K[2, j] * i2
    u0, u1, u2 = U[0], U[1], U[2]
    k0, k1, k2 = K[0], K[1], K[2]
    for i in range(n):
        a0, a1, a2 = K[0, i], K[1, i], K[2, i]
        b0, b1, b2 = D[0, i], D[1, i], D[2, i]
        prow = P[i]
        for j in range(i + 1):
            prow[j] -= (a0 * u0[j] + a1 * u1[j] + a2 * u2[j]) + (b0 * k0[j] + b1 * k1[j] + b2 * k2[j])
    for i in range(n):
        for j in range(i):
            P[j, i] = P[i, j]
    return True
