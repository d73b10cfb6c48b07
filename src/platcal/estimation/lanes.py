"""Replicates in SIMD lanes: the shared parts of the state-major filter kernels (issue 22).

A state-major kernel runs a block of :data:`LANES` replicates with the lanes innermost: a
block's symmetric covariance is ``P[e, l]``, entry ``e`` of the lower triangle packed by rows
(:func:`packed_index`), lane ``l``; every covariance operation is then one vector instruction
over the lanes, and P is stored once (no mirror). A 3 x n matrix of the update or the propagation
(``U = H P``, the gain ``K``, ``D``, ``W = Phi[rows] P``) is held column-major as ``A[j, r * LANES + l]``
(shape ``(n, 3 * LANES)``): entry (r, j) of lane l. Its three rows at column j are then at fixed
offsets from one address, the last axis's stride being the item size, which the compiler knows;
in a (3, n, LANES) array each row's offset is a stride known only at run time, and the Joseph
update's loop spilled those to the stack (issue 22: the update 23 % faster in this layout, bit for
bit). The kernels are compiled with their array arguments ``noalias`` (:class:`NoAliasCompiler`)
and LLVM's SLP vectoriser on (:func:`slp_vectorize`), which is what merges the lanes' scalar
operations into vectors.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
from numba import njit
from numba.core import config as numba_config
from numba.core.compiler import CompilerBase, DefaultPassBuilder

LANES = 4
"""Replicates per block: one AVX2 register of doubles. A block's packed P (1176 x 4 doubles,
37.6 kB) fits a 48 kB L1 data cache, not a 32 kB one (AMD Zen 4)."""



class NoAliasCompiler(CompilerBase):
    """numba's nopython pipeline with the compiled function's pointer arguments (the arrays'
    data) marked ``noalias``: the callers pass distinct arrays, so LLVM may keep values in
    registers across stores and merge the lanes' loads and stores into vectors."""

    def define_pipelines(self):
        self.state.flags.noalias = True
        return [DefaultPassBuilder.define_nopython_pipeline(self.state)]


@contextmanager
def slp_vectorize(loop_vectorize: bool = True):
    """LLVM's SLP vectoriser on for numba compilations in this block (numba's default is off).
    It turns identical scalar operations on adjacent lanes into vector operations; it changes
    no floating-point result (no reassociation), so it is safe for any function compiled
    meanwhile.

    numba rereads every ``NUMBA_*`` setting from the environment at a compile whenever the
    environment changed since its last reading, which would put SLP back off for the first
    compile inside this block (numba imported before platcal set ``NUMBA_CACHE_LOCATOR_CLASSES``,
    or any ``NUMBA_*`` variable set since); so that reading is done here first.

    ``loop_vectorize=False`` turns LLVM's loop vectoriser off meanwhile (numba's default is on): a
    kernel whose lane loops SLP merges can lose to it, when it takes such a loop across its other
    index with gathers (the centrifuge's block kernel, issue 22). Neither changes a number."""
    numba_config.reload_config()
    old = numba_config.SLP_VECTORIZE, numba_config.LOOP_VECTORIZE
    numba_config.SLP_VECTORIZE = 1
    numba_config.LOOP_VECTORIZE = int(loop_vectorize)
    try:
        yield
    finally:
        numba_config.SLP_VECTORIZE, numba_config.LOOP_VECTORIZE = old


def packed_index(n: int) -> np.ndarray:
    """(n, n) int64: the packed position of entry (i, j) of a symmetric n x n matrix stored as its
    lower triangle by rows (``i (i + 1) / 2 + j`` for j <= i; symmetric)."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    hi, lo = np.maximum(i, j), np.minimum(i, j)
    return np.ascontiguousarray(hi * (hi + 1) // 2 + lo, dtype=np.int64)


@njit(cache=True, inline="always")
def cholesky_inverse_lanes(S, Sinv, innov, nu, ok):
    """Per lane, :func:`platcal.estimation.kalman.cholesky_inverse` of the 3 x 3 ``S`` (3, 3, LANES):
    ``Sinv`` = S^-1 and ``nu`` = L^-1 innov (the standardised innovation), written out so that
    the lanes run as vectors. A lane whose S is not positive definite gets ``ok = 0`` and
    ``Sinv = 0``, ``nu = 0``: its gain is then zero and the update leaves x and P as they were
    (the reference kernel skips it)."""
    for l in range(LANES):  # the constant: unrolled, then merged into vectors
        a00 = S[0, 0, l]
        p0 = a00 > 0.0
        f00 = np.sqrt(a00 if p0 else 1.0)
        f10 = S[1, 0, l] / f00
        f20 = S[2, 0, l] / f00
        a11 = S[1, 1, l] - f10 * f10
        p1 = a11 > 0.0
        f11 = np.sqrt(a11 if p1 else 1.0)
        f21 = (S[2, 1, l] - f20 * f10) / f11
        a22 = S[2, 2, l] - f20 * f20 - f21 * f21
        p2 = a22 > 0.0
        f22 = np.sqrt(a22 if p2 else 1.0)
        good = p0 and p1 and p2
        n0 = innov[0, l] / f00
        n1 = (innov[1, l] - f10 * n0) / f11
        n2 = (innov[2, l] - f20 * n0 - f21 * n1) / f22
        # L^-1 (lower): diagonal reciprocals, then the two sub-diagonals and the corner
        i00 = 1.0 / f00
        i11 = 1.0 / f11
        i22 = 1.0 / f22
        i10 = -(f10 * i00) * i11
        i21 = -(f21 * i11) * i22
        i20 = -(f20 * i00 + f21 * i10) * i22
        # S^-1 = L^-T L^-1
        s00 = i00 * i00 + i10 * i10 + i20 * i20
        s01 = i10 * i11 + i20 * i21
        s02 = i20 * i22
        s11 = i11 * i11 + i21 * i21
        s12 = i21 * i22
        s22 = i22 * i22
        z = 1.0 if good else 0.0
        Sinv[0, 0, l] = s00 * z
        Sinv[0, 1, l] = s01 * z
        Sinv[0, 2, l] = s02 * z
        Sinv[1, 0, l] = s01 * z
        Sinv[1, 1, l] = s11 * z
        Sinv[1, 2, l] = s12 * z
        Sinv[2, 0, l] = s02 * z
        Sinv[2, 1, l] = s12 * z
        Sinv[2, 2, l] = s22 * z
        nu[0, l] = n0 * z
        nu[1, l] = n1 * z
        nu[2, l] = n2 * z
        ok[l] = z


@njit(cache=True, inline="always")
def innovation_covariance_lanes(Pl, pidx, hcols, hnnz, hval, r_var, U, S, acc):
    """Per lane, :func:`platcal.estimation.kalman.innovation_covariance` for a 3-row sparse H:
    ``U = H P`` (n, 3 * LANES: entry (r, j) of lane l at ``U[j, r * LANES + l]``) through the packed
    index ``pidx`` and ``S = H U^T + R`` (3, 3, LANES), the same sums in the same order. H's rows
    ``hcols``, ``hnnz`` are shared by the lanes, their values ``hval`` (3, w, LANES) are the lanes'
    own; ``r_var`` (3,) the noise variances; ``acc`` (LANES,) scratch."""
    n = U.shape[0]
    for r in range(3):
        u0 = r * LANES
        if hnnz[r] == 0:
            for j in range(n):
                for l in range(LANES):
                    U[j, u0 + l] = 0.0
            continue
        # the first term starts each sum at 0.0 instead of reading U zeroed beforehand (the same
        # rounding and sign of a zero, a load and a store less per entry)
        _u_term_pass(Pl, pidx, hcols, hval, U, r, 0, True)
        for kk in range(1, hnnz[r]):
            _u_term_pass(Pl, pidx, hcols, hval, U, r, kk, False)
    for r in range(3):
        u0 = r * LANES
        for c in range(r + 1):
            for l in range(LANES):
                acc[l] = 0.0
            for kk in range(hnnz[c]):
                hc = hcols[c, kk]
                for l in range(LANES):
                    acc[l] += U[hc, u0 + l] * hval[c, kk, l]
            for l in range(LANES):
                S[r, c, l] = acc[l]
                S[c, r, l] = acc[l]
        for l in range(LANES):
            S[r, r, l] += r_var[r]


@njit(cache=True, inline="always")
def _u_term_pass(Pl, pidx, hcols, hval, U, r, kk, first):
    """Term ``kk`` of H's row ``r`` added into row r of ``U = H P`` (:func:`innovation_covariance_lanes`);
    ``first``, a constant at each call: the sums start at 0.0."""
    u0 = r * LANES
    hc = hcols[r, kk]
    for j in range(U.shape[0]):
        e = pidx[hc, j]
        for l in range(LANES):
            u = 0.0 if first else U[j, u0 + l]
            U[j, u0 + l] = u + hval[r, kk, l] * Pl[e, l]


@njit(cache=True, inline="always")
def joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, update_x):
    """Per lane, the Joseph-form correction of :func:`platcal.estimation.kalman._correct3`:
    ``K = S^-1 U``, ``D = U - S K``, ``x += K innov`` (with ``update_x``) and ``P -= K U^T + D K^T``
    on the packed lower triangle (``xl`` (n, LANES), ``Pl`` (n (n + 1) / 2, LANES); ``U``, ``K``, ``D``
    (n, 3 * LANES), entry (r, j) of lane l at ``[j, r * LANES + l]``), the same operations in the same
    order. A lane with ``Sinv = 0`` keeps its x and P."""
    n = xl.shape[0]
    L = LANES
    gain_lanes(U, S, Sinv, K, D)
    if update_x:
        for j in range(n):
            for l in range(L):
                xl[j, l] += K[j, l] * innov[0, l] + K[j, L + l] * innov[1, l] + K[j, 2 * L + l] * innov[2, l]
    # two rows of P a pass: column j's K and U are loaded once for both (4 vector loads an entry
    # instead of 7); each row is a view, so its entries' indices are the loop's own (no
    # negative-index code) and the two rows' stores and loads stay apart for the vectoriser
    for ii in range(n // 2):
        i = 2 * ii
        e = i * (i + 1) // 2
        Pa = Pl[e:e + i + 1]
        Pb = Pl[e + i + 1:e + 2 * i + 3]
        for j in range(i + 1):
            _joseph_entry(Pa, K, U, D, i, j)
            _joseph_entry(Pb, K, U, D, i + 1, j)
        _joseph_entry(Pb, K, U, D, i + 1, i + 1)
    if n % 2:
        i = n - 1
        Pa = Pl[i * (i + 1) // 2:]
        for j in range(i + 1):
            _joseph_entry(Pa, K, U, D, i, j)


@njit(cache=True, inline="always")
def gain_lanes(U, S, Sinv, K, D):
    """Per lane, the gain ``K = S^-1 U`` and ``D = U - S K`` of :func:`joseph_correct_lanes` (``U``,
    ``K``, ``D`` (n, 3 * LANES), entry (r, j) of lane l at ``[j, r * LANES + l]``; ``S``, ``Sinv``
    (3, 3, LANES)), the operations of :func:`platcal.estimation.kalman.gain3` in its order."""
    L = LANES
    for j in range(U.shape[0]):
        for c in range(3):
            for l in range(L):
                K[j, c * L + l] = (Sinv[c, 0, l] * U[j, l] + Sinv[c, 1, l] * U[j, L + l]
                                   + Sinv[c, 2, l] * U[j, 2 * L + l])
    for j in range(U.shape[0]):
        for c in range(3):
            for l in range(L):
                D[j, c * L + l] = U[j, c * L + l] - (S[c, 0, l] * K[j, l] + S[c, 1, l] * K[j, L + l]
                                                     + S[c, 2, l] * K[j, 2 * L + l])


@njit(cache=True, inline="always")
def _joseph_entry(Prow, K, U, D, i, j):
    """Entry (i, j) of the Joseph correction (:func:`joseph_correct_lanes`), ``Prow`` row i of the
    packed P: ``P[i, j] -= K[i] . U[j] + D[i] . K[j]`` per lane, the terms in this order."""
    L = LANES
    for l in range(L):
        Prow[j, l] -= ((K[i, l] * U[j, l] + K[i, L + l] * U[j, L + l] + K[i, 2 * L + l] * U[j, 2 * L + l])
                       + (D[i, l] * K[j, l] + D[i, L + l] * K[j, L + l] + D[i, 2 * L + l] * K[j, 2 * L + l]))


@njit(cache=True, inline="always")
def phi_rows_times_p_lanes(Pl, pidx, pcols, phi, W):
    """Per lane, ``W = Phi[rows] P`` (n, 3 * LANES: entry (r, j) of lane l at ``W[j, r * LANES + l]``):
    the 3 rows of Phi nonzero at the columns ``pcols`` with the values ``phi`` (3, len(pcols), LANES),
    P packed (``Pl``, through the index ``pidx``). Every entry sums in column order (``pcols`` as
    given), as :func:`platcal.estimation.kalman.propagate_sparse` does. The first part of
    :func:`propagate_rows_lanes`; apart so that ``benchmarks/w_columns_probe.py`` times this loop."""
    n = W.shape[0]
    npc = pcols.shape[0]
    L = LANES
    # two columns of Phi per pass over W (half its loads and stores); the first pass starts each
    # sum at 0.0 instead of reading W zeroed beforehand (the same rounding and sign of a zero, a
    # load and a store less per entry)
    if npc < 2:
        W[:] = 0.0  # a lone column of Phi (or none) is added to zeros below
    else:
        _w_pair_pass(Pl, pidx, pcols, phi, W, 0, True)
    for kk in range(2, npc - 1, 2):
        _w_pair_pass(Pl, pidx, pcols, phi, W, kk, False)
    if npc % 2:
        kk = npc - 1
        ea0 = pcols[kk]
        for j in range(n):
            ea = pidx[ea0, j]
            for r in range(3):
                c = r * L
                for l in range(L):
                    W[j, c + l] = W[j, c + l] + phi[r, kk, l] * Pl[ea, l]


@njit(cache=True, inline="always")
def _w_pair_pass(Pl, pidx, pcols, phi, W, kk, first):
    """Columns ``kk`` and ``kk + 1`` of Phi's rows added into every entry of W, in that order
    (:func:`phi_rows_times_p_lanes`), each row of W in its own lane loop (one lane loop updating
    three rows is not vectorised); ``first``, a constant at each call: the sums start at 0.0."""
    n = W.shape[0]
    L = LANES
    ea0 = pcols[kk]
    eb0 = pcols[kk + 1]
    for j in range(n):
        ea = pidx[ea0, j]
        eb = pidx[eb0, j]
        for r in range(3):
            c = r * L
            for l in range(L):
                w = 0.0 if first else W[j, c + l]
                W[j, c + l] = (w + phi[r, kk, l] * Pl[ea, l]) + phi[r, kk + 1, l] * Pl[eb, l]


@njit(cache=True, inline="always")
def propagate_rows_lanes(Pl, pidx, pcols, phi, W, acc, r0):
    """Per lane, ``P <- Phi P Phi^T`` where Phi is the identity but for the 3 rows ``r0 .. r0 + 2``,
    nonzero at the columns ``pcols`` with the values ``phi`` (3, len(pcols), LANES): ``W = Phi[rows] P``
    (n, 3 * LANES, as :func:`phi_rows_times_p_lanes`) through the packed index, written as the rows
    (= the columns) of the packed ``Pl``, and in ``acc`` (6, LANES) the six sums of the 3 x 3 block
    ``Phi P Phi^T`` on those rows (rows 00, 10, 11, 20, 21, 22), which the caller writes with its
    process noise. Every entry sums in column order, as
    :func:`platcal.estimation.kalman.propagate_sparse` does (the same numbers)."""
    phi_rows_times_p_lanes(Pl, pidx, pcols, phi, W)
    npc = pcols.shape[0]
    n = W.shape[0]
    L = LANES
    for l in range(L):
        acc[0, l] = 0.0
        acc[1, l] = 0.0
        acc[2, l] = 0.0
        acc[3, l] = 0.0
        acc[4, l] = 0.0
        acc[5, l] = 0.0
    for kk in range(npc):
        c = pcols[kk]
        for l in range(L):
            w0, w1_, w2 = W[c, l], W[c, L + l], W[c, 2 * L + l]
            p0, p1, p2 = phi[0, kk, l], phi[1, kk, l], phi[2, kk, l]
            acc[0, l] += w0 * p0
            acc[1, l] += w1_ * p0
            acc[2, l] += w1_ * p1
            acc[3, l] += w2 * p0
            acc[4, l] += w2 * p1
            acc[5, l] += w2 * p2
    for r in range(3):
        for j in range(n):
            e = pidx[r0 + r, j]
            for l in range(L):
                Pl[e, l] = W[j, r * L + l]
