"""Rig-agnostic Kalman-filter primitives for one replicate, compiled with numba.

The covariance ``P`` is (n, n) and symmetric. The kernels exploit the structure of the
identification problems of every rig: constant coefficients (only a few "dynamic" states have a
non-identity row in the transition matrix) and a small measurement of any dimension m (the
centrifuge's accelerometer triad has m = 3), so every step costs O(n^2) rather than O(n^3).

The update factors the innovation covariance ``S = L L^T`` (Cholesky): ``L^-1 innov`` is the
standardised innovation (NIS = its squared norm) and ``S^-1 = L^-T L^-1`` gives the gain. For
m = 3 (one O(n^2) pass over P feeding all three rows) and d = 3 the loops are written out, which
is worth a third of the filter's time; the general loops give the same numbers to rounding
(``tests/test_batch.py``). The dense textbook forms these kernels are checked against live in
``tests/kalman_oracles.py``.
"""

from __future__ import annotations

import numpy as np
from ..jit import njit

_LANES = 4
"""Width (float64 entries) to which the rows of the lower-triangle update are padded: one AVX2
register of doubles, so that every row runs in whole vectors, with the fewest padding entries
(issue 22: 1248 entries per update at n = 48 against 1536 when padded to 16, and 1176 exact
with scalar tails; the loop is bound by the FP ports, so time follows the entries: 0.80x the
16-padded loop's CPU time, bit-identical)."""


@njit(cache=True, inline="always")
def add_row_combinations(coef, P, rows, count, out):
    """``out[r] += sum_{k < count} coef[r, k] P[rows[k]]`` for every r (``coef`` (d, >= count)).

    Rows of a symmetric P are its columns, so this is ``coef P[:, rows]^T`` as axpys over
    contiguous rows (vectorisable); with d = 3 (an attitude, a 3-axis output) one pass over each
    row of P feeds all three.
    """
    n = P.shape[0]
    d = out.shape[0]
    # 2-D indexing rather than row views: a view per row costs two atomic reference-count
    # updates that numba does not always prune (issue 22)
    if d == 3:
        # two rows of P per pass over out: each entry still adds its terms one by one in k
        # order (the same numbers), with out's rows loaded and stored half as often (issue 22)
        for k in range(0, count - 1, 2):
            ra, rb = rows[k], rows[k + 1]
            a0, a1, a2 = coef[0, k], coef[1, k], coef[2, k]
            b0, b1, b2 = coef[0, k + 1], coef[1, k + 1], coef[2, k + 1]
            for j in range(n):
                pa = P[ra, j]
                pb = P[rb, j]
                out[0, j] = (out[0, j] + a0 * pa) + b0 * pb
                out[1, j] = (out[1, j] + a1 * pa) + b1 * pb
                out[2, j] = (out[2, j] + a2 * pa) + b2 * pb
        if count % 2 == 1:
            rk = rows[count - 1]
            c0, c1, c2 = coef[0, count - 1], coef[1, count - 1], coef[2, count - 1]
            for j in range(n):
                p = P[rk, j]
                out[0, j] += c0 * p
                out[1, j] += c1 * p
                out[2, j] += c2 * p
    else:
        for k in range(count):
            rk = rows[k]
            for r in range(d):
                c = coef[r, k]
                for j in range(n):
                    out[r, j] += c * P[rk, j]


@njit(cache=True, inline="always")
def _block3(W, cols, phi, q, blk):
    """The dyn-dyn block of :func:`propagate_sparse` for d = 3: its six sums in one loop over
    ``cols``, so that they are six independent chains the core overlaps, rather than six serial
    chains of m dependent additions one after the other (each sum in the same order as the
    general loop: the same numbers; issue 22: 0.3 us of a 48-state step)."""
    s00 = s10 = s11 = s20 = s21 = s22 = 0.0
    for k in range(cols.shape[0]):
        c = cols[k]
        w0, w1, w2 = W[0, c], W[1, c], W[2, c]
        p0, p1, p2 = phi[0, k], phi[1, k], phi[2, k]
        s00 += w0 * p0
        s10 += w1 * p0
        s11 += w1 * p1
        s20 += w2 * p0
        s21 += w2 * p1
        s22 += w2 * p2
    blk[0, 0] = s00 + 0.5 * (q[0, 0] + q[0, 0])
    blk[1, 1] = s11 + 0.5 * (q[1, 1] + q[1, 1])
    blk[2, 2] = s22 + 0.5 * (q[2, 2] + q[2, 2])
    v = s10 + 0.5 * (q[1, 0] + q[0, 1])
    blk[1, 0] = v
    blk[0, 1] = v
    v = s20 + 0.5 * (q[2, 0] + q[0, 2])
    blk[2, 0] = v
    blk[0, 2] = v
    v = s21 + 0.5 * (q[2, 1] + q[1, 2])
    blk[2, 1] = v
    blk[1, 2] = v


@njit(cache=True, inline="always")
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
    # a loop, not the slice fill W[:, :] = 0.0 (numba's generic slice assignment is several times
    # slower for so small an array; issue 22)
    for r in range(d):
        for j in range(n):
            W[r, j] = 0.0
    add_row_combinations(phi, P, cols, m, W)
    # the dyn-dyn block, Phi P Phi^T restricted to dyn, before P's rows are overwritten
    if d == 3:
        _block3(W, cols, phi, q, blk)
    else:
        for r in range(d):
            for c in range(r + 1):
                s = 0.0
                for k in range(m):
                    s += W[r, cols[k]] * phi[c, k]
                v = s + 0.5 * (q[r, c] + q[c, r])
                blk[r, c] = v
                blk[c, r] = v
    # the rows as contiguous (vectorised) copies, then the columns as strided stores
    for r in range(d):
        dr = dyn[r]
        for j in range(n):
            P[dr, j] = W[r, j]
    for r in range(d):
        dr = dyn[r]
        for j in range(n):
            P[j, dr] = W[r, j]
    for r in range(d):
        for c in range(d):
            P[dyn[r], dyn[c]] = blk[r, c]


@njit(cache=True, inline="always")
def cholesky_inverse(S, F, nu, innov):
    """Cholesky factor ``L`` of the symmetric (m, m) ``S``, the standardised innovation
    ``nu = L^-1 innov`` and ``S^-1``, all in place in ``F`` (m, m) without allocation.

    Returns False (``F`` and ``nu`` undefined) if ``S`` is not positive definite.
    """
    m = S.shape[0]
    for i in range(m):  # L into the lower triangle of F
        for j in range(i + 1):
            v = S[i, j]
            for k in range(j):
                v -= F[i, k] * F[j, k]
            if i == j:
                if not v > 0.0:
                    return False
                F[i, i] = np.sqrt(v)
            else:
                F[i, j] = v / F[j, j]
    for i in range(m):  # nu = L^-1 innov
        v = innov[i]
        for k in range(i):
            v -= F[i, k] * nu[k]
        nu[i] = v / F[i, i]
    for i in range(m):  # L^-1 in place, row by row (columns ascending only read L[i, k >= j])
        dii = 1.0 / F[i, i]
        for j in range(i):
            v = F[i, j] * F[j, j]
            for k in range(j + 1, i):
                v += F[i, k] * F[k, j]
            F[i, j] = -v * dii
        F[i, i] = dii
    for r in range(m):  # S^-1 = L^-T L^-1: upper triangle, each diagonal last (it is still read)
        for c in range(r + 1, m):
            v = F[c, r] * F[c, c]
            for k in range(c + 1, m):
                v += F[k, r] * F[k, c]
            F[r, c] = v
        v = F[r, r] * F[r, r]
        for k in range(r + 1, m):
            v += F[k, r] * F[k, r]
        F[r, r] = v
    for r in range(m):
        for c in range(r + 1, m):
            F[c, r] = F[r, c]
    return True


@njit(cache=True, inline="always")
def innovation_covariance(P, hcols, hnnz, hval, r_var, U, S):
    """``U = H P`` (m, n) and ``S = H P H^T + R`` (m, m) for the sparse rows of H (``hcols``,
    ``hval``, ``hnnz``) and diagonal R (``r_var``); S is exactly symmetric."""
    n = P.shape[0]
    m = hnnz.shape[0]
    # U[r, j] = ((0 + c_0 P[h_0, j]) + c_1 P[h_1, j]) + ..., the terms in t order as a sum
    # kept in a register over four terms per pass, rather than U's row loaded and stored once
    # per term (the same operations in the same order: the same numbers; issue 22)
    for r in range(m):
        nn = hnnz[r]
        if nn == 0:
            for j in range(n):
                U[r, j] = 0.0
        for t0 in range(0, nn, 4):
            k = min(4, nn - t0)
            c0 = hval[r, t0]
            r0 = hcols[r, t0]
            if k == 4:
                c1, c2, c3 = hval[r, t0 + 1], hval[r, t0 + 2], hval[r, t0 + 3]
                r1, r2, r3 = hcols[r, t0 + 1], hcols[r, t0 + 2], hcols[r, t0 + 3]
                for j in range(n):
                    u = 0.0 if t0 == 0 else U[r, j]
                    u += c0 * P[r0, j]
                    u += c1 * P[r1, j]
                    u += c2 * P[r2, j]
                    U[r, j] = u + c3 * P[r3, j]
            else:
                for t in range(t0, nn):
                    c = hval[r, t]
                    rt = hcols[r, t]
                    for j in range(n):
                        U[r, j] = (0.0 if t == 0 else U[r, j]) + c * P[rt, j]
    for r in range(m):
        for c in range(r + 1):
            s = 0.0
            for t in range(hnnz[c]):
                s += U[r, hcols[c, t]] * hval[c, t]
            S[r, c] = s
            S[c, r] = s
        S[r, r] += r_var[r]


@njit(cache=True)
def update_scratch(m, n):
    """The scratch arrays of a measurement update of ``m`` measurements on ``n`` states:
    ``(U, K, D)`` (m, n), ``(S, Sinv)`` (m, m) and ``nu`` (m,), as :func:`joseph_update` and
    :func:`joseph_update_sparse` take them (allocated once per filter run, not per update)."""
    return (np.empty((m, n)), np.empty((m, n)), np.empty((m, n)), np.empty((m, m)), np.empty((m, m)),
            np.empty(m))


@njit(cache=True, inline="always")  # inlined: the sparse update's code stays as before the split
def joseph_update(x, P, U, S, innov, K, D, F, nu, update_x):
    """Measurement update from the cross-covariance ``U`` (m, n) (``U[r, i] = cov(x_i, z_r)``)
    and the innovation covariance ``S`` (m, m) (noise included), Joseph-safe (module docstring).

    ``K``, ``D`` (m, n) and ``F`` (m, m) are scratch; ``nu`` (m,) receives the standardised
    innovation ``L_S^-1 innov`` (NIS = its squared norm). ``x`` moves by ``K innov`` when
    ``update_x``. Returns False (nothing changed) if ``S`` is not positive definite.

    The correction is ``P - K U^T - D K^T`` on the lower triangle, mirrored (written out for
    m = 3): the EKF's :func:`joseph_update_sparse` calls it with ``U = P H^T``, the unscented
    filters (:mod:`platcal.estimation.unscented`) with the transform's cross-covariance.
    """
    if not cholesky_inverse(S, F, nu, innov):
        return False
    if S.shape[0] == 3:
        _correct3(x, P, innov, U, K, D, S, F, update_x)
    else:
        _correct(x, P, innov, U, K, D, S, F, update_x)
    return True


@njit(cache=True, inline="always")
def joseph_update_sparse(x, P, hcols, hnnz, hval, innov, r_var, U, K, D, S, Sinv, nu, update_x):
    """Kalman update with an m-dimensional measurement whose Jacobian rows are sparse, in Joseph
    form, O(m n^2) with a small constant.

    Row r of H is nonzero only at the states ``hcols[r, :hnnz[r]]`` with values
    ``hval[r, :hnnz[r]]``. With ``U = P H^T`` (n x m), ``S = H U + R``, ``K = U S^-1`` and
    ``D = U - K S`` the Joseph form ``(I - K H) P (I - K H)^T + K R K^T`` equals
    ``P - K U^T - D K^T`` exactly, for any gain K. Only the lower triangle is computed and it
    is mirrored, so P stays exactly symmetric.

    Parameters
    ----------
    x : (n,) state, updated in place when ``update_x``.
    P : (n, n) symmetric covariance, updated in place.
    hcols, hval : (m, w) int and float; hnnz : (m,) int. The sparse rows of H.
    innov : (m,) innovation ``z - h(x)`` (unused unless ``update_x``).
    r_var : (m,) measurement-noise variances (R diagonal).
    U, K, D : (m, n) scratch (stored transposed for contiguous rows); S, Sinv : (m, m) scratch.
    nu : (m,) out, the standardised innovation ``L^-1 innov`` (for NIS).

    Returns
    -------
    bool : False if ``S`` was not positive definite (the update is skipped).
    """
    innovation_covariance(P, hcols, hnnz, hval, r_var, U, S)
    return joseph_update(x, P, U, S, innov, K, D, Sinv, nu, update_x)


@njit(cache=True)
def _small_times(M, A, out):
    """``out = M A`` for a small (m, m) ``M`` and (m, n) ``A``, row by row (contiguous, vectorisable)."""
    m = M.shape[0]
    n = A.shape[1]
    for c in range(m):
        oc = out[c]
        for j in range(n):
            oc[j] = M[c, 0] * A[0, j]
        for i in range(1, m):
            for j in range(n):
                oc[j] += M[c, i] * A[i, j]


@njit(cache=True)
def _correct(x, P, innov, U, K, D, S, Sinv, update_x):
    """``K = U S^-1``, ``D = U - K S``, ``x += K innov``, ``P -= K U^T + D K^T`` (lower, mirrored)."""
    n = P.shape[0]
    m = S.shape[0]
    _small_times(Sinv, U, K)
    _small_times(S, K, D)
    for c in range(m):
        for j in range(n):
            D[c, j] = U[c, j] - D[c, j]
    if update_x:
        for j in range(n):
            v = K[0, j] * innov[0]
            for i in range(1, m):
                v += K[i, j] * innov[i]
            x[j] += v
    for i in range(n):
        prow = P[i]
        for j in range(i + 1):
            a = K[0, i] * U[0, j]
            b = D[0, i] * K[0, j]
            for c in range(1, m):
                a += K[c, i] * U[c, j]
                b += D[c, i] * K[c, j]
            prow[j] -= a + b
    for i in range(n):
        for j in range(i):
            P[j, i] = P[i, j]


@njit(cache=True, inline="always")
def _correct3(x, P, innov, U, K, D, S, Sinv, update_x):
    """:func:`_correct` for m = 3, the loops over the measurement written out (same numbers)."""
    n = P.shape[0]
    gain3(U, S, Sinv, K, D)
    if update_x:
        i0, i1, i2 = innov[0], innov[1], innov[2]
        for j in range(n):
            x[j] += K[0, j] * i0 + K[1, j] * i1 + K[2, j] * i2
    joseph_lower3(P, U, K, D)
    mirror_lower(P)


@njit(cache=True, inline="always")
def gain3(U, S, Sinv, K, D):
    """``K = U S^-1`` and ``D = U - K S`` (3, n) for m = 3 (:func:`_correct3`)."""
    n = U.shape[1]
    for c in range(3):
        s0, s1, s2 = Sinv[c, 0], Sinv[c, 1], Sinv[c, 2]
        for j in range(n):
            K[c, j] = s0 * U[0, j] + s1 * U[1, j] + s2 * U[2, j]
    for c in range(3):
        s0, s1, s2 = S[c, 0], S[c, 1], S[c, 2]
        for j in range(n):
            D[c, j] = U[c, j] - (s0 * K[0, j] + s1 * K[1, j] + s2 * K[2, j])


@njit(cache=True, inline="always")
def joseph_lower3(P, U, K, D):
    """``P -= K U^T + D K^T`` on the lower triangle of P (rows padded to whole vectors), m = 3
    (:func:`_correct3`; the upper triangle is left for :func:`mirror_lower`)."""
    n = P.shape[0]
    for i in range(n):
        a0, a1, a2 = K[0, i], K[1, i], K[2, i]
        b0, b1, b2 = D[0, i], D[1, i], D[2, i]
        # rows run on to a multiple of _LANES: whole vector blocks instead of a scalar tail;
        # the extra upper-triangle entries are overwritten by the mirror below
        for j in range(min(n, (i // _LANES + 1) * _LANES)):
            P[i, j] -= ((a0 * U[0, j] + a1 * U[1, j] + a2 * U[2, j])
                        + (b0 * K[0, j] + b1 * K[1, j] + b2 * K[2, j]))


@njit(cache=True, inline="always")
def mirror_lower(P):
    """Copy the lower triangle of the square ``P`` onto its upper triangle.

    Four rows of the lower triangle at a time: their entries of column j are loaded, then
    stored as four adjacent entries of row j, so the stores go to one cache line instead of
    four (issue 22: 0.70x the CPU time of the entry-by-entry strided copy at n = 48,
    ``benchmarks/profile_ekf_joseph.py``); copies only, so the same numbers.
    """
    n = P.shape[0]
    for i0 in range(0, n - 3, 4):
        for j in range(i0):
            p0, p1, p2, p3 = P[i0, j], P[i0 + 1, j], P[i0 + 2, j], P[i0 + 3, j]
            P[j, i0] = p0
            P[j, i0 + 1] = p1
            P[j, i0 + 2] = p2
            P[j, i0 + 3] = p3
        for i in range(i0 + 1, i0 + 4):  # the 4 x 4 block on the diagonal
            for j in range(i0, i):
                P[j, i] = P[i, j]
    for i in range(n - n % 4, n):
        for j in range(i):
            P[j, i] = P[i, j]
