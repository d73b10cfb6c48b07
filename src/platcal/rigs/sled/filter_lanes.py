"""The sled filters' lanes kernel: the seeds in SIMD lanes (issue 22 item 2; docs/rocket-sled.md §6).

:func:`_kalman_block` runs :func:`.filters._kalman`'s filter for a block of :data:`LANES` seeds
with the seeds innermost (:mod:`platcal.estimation.lanes`), compiled with its arrays ``noalias``
(:class:`platcal.estimation.lanes.NoAliasCompiler`) and LLVM's SLP vectoriser on: each seed's
numbers are the one-seed kernel's bit for bit (``tests/sled/test_sled_lanes.py``).

A module of its own because its compiler pipeline subclasses numba's, so importing it imports
numba: :mod:`.filters` imports it only when a batch runs on the JIT, and an identify on kernels
compiled ahead of time (:mod:`.aot_kernels`, one seed at a time on :func:`.filters._kalman`)
never does (issue 22 item 3).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ...estimation.kalman import joseph_update_sparse, propagate_sparse
from ...estimation.lanes import LANES, NoAliasCompiler, slp_vectorize
from ...parallel import run_threaded
from .errmodel import fill_F, system_matrices
from .filters import Dynamics, _kalman, _structure


@nb.njit(cache=True, inline="always")
def _row_dot(A, a, B, b, cols, lo, hi, out):
    """``out[l] = Σ A[a, k, l] B[b, k, l]`` over ``k = cols[lo:hi]`` in that order, from 0.0, per lane."""
    for l in range(LANES):
        out[l] = 0.0
    for t in range(lo, hi):
        k = cols[t]
        for l in range(LANES):
            out[l] += A[a, k, l] * B[b, k, l]


@nb.njit(cache=True, inline="always")
def _tri_sum(Fc, i, c, hi, row, out):
    """Per lane, the triangular sums of :func:`platcal.estimation.kalman.cholesky_inverse` in its
    order: ``out = A[i, c] Fc[c, c] + Σ_{c<k<hi} A[i, k] Fc[k, c]`` with ``A = Fc`` (``row``: the
    L⁻¹ step, along row i) or ``A = Fcᵀ`` (the S⁻¹ = L⁻ᵀ L⁻¹ step, down column i)."""
    for l in range(LANES):
        out[l] = (Fc[i, c, l] if row else Fc[c, i, l]) * Fc[c, c, l]
    for k in range(c + 1, hi):
        for l in range(LANES):
            out[l] += (Fc[i, k, l] if row else Fc[k, i, l]) * Fc[k, c, l]


@nb.njit(cache=True, inline="always")
def _times_lanes(M, A, out):
    """``out = M A`` per lane for (m, m, LANES) ``M`` and (m, n, LANES) ``A``: the sums of
    :func:`platcal.estimation.kalman._small_times` in its order (the first term, then the rest)."""
    m, n = M.shape[0], A.shape[1]
    for c in range(m):
        for k in range(n):
            for l in range(LANES):
                out[c, k, l] = M[c, 0, l] * A[0, k, l]
        for i in range(1, m):
            for k in range(n):
                for l in range(LANES):
                    out[c, k, l] += M[c, i, l] * A[i, k, l]


@nb.njit(cache=True, nogil=True, error_model="numpy", pipeline_class=NoAliasCompiler)
def _kalman_block(blk, kind, fm, w, wc, Ts, z, X, PP, Qd, r_var, xs, sig, acc, failed, innov_out, svar_out, bad,
                  fa, fb, pa, pb, pptr, pcs, rptr, rcols, src, Fl, FT, FTt, Phi, xl, xn, Pl, W, U, Kg, D, Sm, Fc, inn, nu,
                  av, bv, okl, tot, made, nfail, x1, P1, i1, hcols, hnnz, hval, U1, K1, D1, S1, Si1, nu1):
    """:func:`_kalman` for the seeds ``blk * LANES ..`` with the seeds in SIMD lanes
    (:mod:`platcal.estimation.lanes`; docs/rocket-sled.md §6): state-major x (n, LANES) and P
    (n, n, LANES), every operation one vector over the lanes, each epoch's F formed from the mean
    force ``fm`` (S,J,3) (:func:`.errmodel.fill_F`, kind ``kind``, rates ``w``, ``wc``) and its
    zero products left out (:func:`_structure`). Every sum runs in :func:`_kalman`'s order with
    no fused multiply-adds, so each seed's numbers are the reference's bit for bit, whatever its
    lane. An epoch where some lane's innovation covariance is not positive definite updates
    every lane with the reference's own update (:func:`joseph_update_sparse`, which skips it).
    Non-finite numbers are left to the reference: ``bad[blk] = 1`` (nothing written) when an
    input of the block is not finite, or when an output is (the caller then reruns the block
    with :func:`_kalman` from its start). Lanes past the batch repeat its first seed. The
    arguments from ``src`` on are the block's lane-layout state and scratch (:func:`_kalman_blocks`),
    distinct arrays as the ``noalias`` compile requires (scratch allocated here could alias the
    arguments for all LLVM knows, which keeps the lanes from merging into vectors)."""
    S, J, n = fm.shape[0], fm.shape[1], X.shape[1]
    m = z.shape[2]
    L = LANES
    off = xs.shape[1] - J   # 1: xs, sig hold the prior at epoch 0 (the caller's), the posteriors after it
    b0 = blk * L
    nact = min(L, S - b0)
    for l in range(nact):
        s = b0 + l
        ok = True
        for j in range(J):
            for i in range(3):
                ok = ok and np.isfinite(fm[s, j, i])
            for i in range(m):
                ok = ok and np.isfinite(z[s, j, i])
        for i in range(n):
            ok = ok and np.isfinite(X[s, i])
            for k in range(n):
                ok = ok and np.isfinite(PP[s, i, k])
        if not ok:
            bad[blk] = 1
            return
    for l in range(L):
        src[l] = b0 + (l if l < nact else 0)
        nfail[l] = 0
    for l in range(L):
        for a in range(n):
            for b in range(n):
                Fl[l, a, b] = 0.0
                FT[a, b, l] = 0.0
                FTt[a, b, l] = 0.0
                Phi[a, b, l] = 0.0
    for l in range(L):
        s = src[l]
        tot[l] = acc[s, 0]
        made[l] = acc[s, 1]
        for i in range(n):
            xl[i, l] = X[s, i]
            for k in range(n):
                Pl[i, k, l] = PP[s, i, k]
    nF = fa.shape[0]
    nP = pa.shape[0]
    for j in range(J):
        T = Ts[j]
        for l in range(L):
            s = src[l]
            fill_F(kind, fm[s, j, 0], fm[s, j, 1], fm[s, j, 2], w, wc, Fl, l)
        for e in range(nF):
            a, b = fa[e], fb[e]
            for l in range(L):
                v = Fl[l, a, b] * T
                FT[a, b, l] = v
                FTt[b, a, l] = v
        # Φ = I + F T + (F T)²/2
        for p in range(nP):
            a, b = pa[p], pb[p]
            _row_dot(FT, a, FTt, b, pcs, pptr[p], pptr[p + 1], av)
            d = 1.0 if a == b else 0.0
            for l in range(L):
                Phi[a, b, l] = (d + FT[a, b, l]) + av[l] / 2
        # x <- Φ x; W = Φ P; P <- W Φᵀ + Q (propagate_sparse with every row dynamic)
        for a in range(n):
            for l in range(L):
                av[l] = 0.0
            for t in range(rptr[a], rptr[a + 1]):
                k = rcols[t]
                for l in range(L):
                    av[l] += Phi[a, k, l] * xl[k, l]
            for l in range(L):
                xn[a, l] = av[l]
        for a in range(n):
            for l in range(L):
                xl[a, l] = xn[a, l]
        for r in range(n):
            for c in range(n):
                for l in range(L):
                    W[r, c, l] = 0.0
            for t in range(rptr[r], rptr[r + 1]):
                k = rcols[t]
                for c in range(n):
                    for l in range(L):
                        W[r, c, l] += Phi[r, k, l] * Pl[k, c, l]
        for r in range(n):
            for c in range(r + 1):
                _row_dot(W, r, Phi, c, rcols, rptr[c], rptr[c + 1], av)
                q = 0.5 * (Qd[j, r, c] + Qd[j, c, r])
                for l in range(L):
                    v = av[l] + q
                    Pl[r, c, l] = v
                    Pl[c, r, l] = v
        # the update with H = [I_m 0]: U = H P, S = H P Hᵀ + R (innovation_covariance)
        for b in range(m):
            for l in range(L):
                inn[b, l] = z[src[l], j, b] - xl[b, l]
        for r in range(m):
            for c in range(n):
                for l in range(L):
                    U[r, c, l] = Pl[r, c, l]
            for c in range(r + 1):
                for l in range(L):
                    Sm[r, c, l] = Pl[r, c, l]
                    Sm[c, r, l] = Pl[r, c, l]
            for l in range(L):
                Sm[r, r, l] += r_var[r]
        for l in range(nact):
            for b in range(m):
                innov_out[b0 + l, j, b] = inn[b, l]
                svar_out[b0 + l, j, b] = Sm[b, b, l]
        # cholesky_inverse per lane: L into Fc's lower triangle (a lane that fails goes on with
        # 1.0 for its pivot and is flagged), nu = L⁻¹ innov, L⁻¹ in place, S⁻¹ = L⁻ᵀ L⁻¹
        for l in range(L):
            okl[l] = 1.0
        for i in range(m):
            for c in range(i + 1):
                for l in range(L):
                    av[l] = Sm[i, c, l]
                for k in range(c):
                    for l in range(L):
                        av[l] -= Fc[i, k, l] * Fc[c, k, l]
                if i == c:
                    for l in range(L):
                        v = av[l]
                        good = v > 0.0
                        okl[l] = okl[l] if good else 0.0
                        Fc[i, i, l] = np.sqrt(v if good else 1.0)
                else:
                    for l in range(L):
                        Fc[i, c, l] = av[l] / Fc[c, c, l]
        allok = True
        for l in range(L):
            allok = allok and okl[l] > 0.0
        if allok:
            for i in range(m):
                for l in range(L):
                    av[l] = inn[i, l]
                for k in range(i):
                    for l in range(L):
                        av[l] -= Fc[i, k, l] * nu[k, l]
                for l in range(L):
                    nu[i, l] = av[l] / Fc[i, i, l]
            for i in range(m):
                for l in range(L):
                    bv[l] = 1.0 / Fc[i, i, l]
                for c in range(i):
                    _tri_sum(Fc, i, c, i, True, av)
                    for l in range(L):
                        Fc[i, c, l] = -av[l] * bv[l]
                for l in range(L):
                    Fc[i, i, l] = bv[l]
            for r in range(m):
                # row r of S⁻¹ (upper triangle) reads L⁻¹ only at rows below r and the diagonals
                # after it: its diagonal first gives the reference's numbers (which has it last)
                for c in range(r, m):
                    _tri_sum(Fc, r, c, m, False, av)
                    for l in range(L):
                        Fc[r, c, l] = av[l]
            for r in range(m):
                for c in range(r + 1, m):
                    for l in range(L):
                        Fc[c, r, l] = Fc[r, c, l]
            # _correct: K = S⁻¹ U, D = U − S K, x += K innov, P −= K Uᵀ + D Kᵀ (lower, mirrored)
            _times_lanes(Fc, U, Kg)
            _times_lanes(Sm, Kg, D)
            for c in range(m):
                for k in range(n):
                    for l in range(L):
                        D[c, k, l] = U[c, k, l] - D[c, k, l]
            for k in range(n):
                for l in range(L):
                    av[l] = Kg[0, k, l] * inn[0, l]
                for i in range(1, m):
                    for l in range(L):
                        av[l] += Kg[i, k, l] * inn[i, l]
                for l in range(L):
                    xl[k, l] += av[l]
            for i in range(n):
                for c in range(i + 1):
                    for l in range(L):
                        av[l] = Kg[0, i, l] * U[0, c, l]
                        bv[l] = D[0, i, l] * Kg[0, c, l]
                    for t in range(1, m):
                        for l in range(L):
                            av[l] += Kg[t, i, l] * U[t, c, l]
                            bv[l] += D[t, i, l] * Kg[t, c, l]
                    for l in range(L):
                        v = Pl[i, c, l] - (av[l] + bv[l])
                        Pl[i, c, l] = v
                        Pl[c, i, l] = v
            for l in range(L):
                v = tot[l]
                for b in range(m):
                    v += nu[b, l] * nu[b, l]
                tot[l] = v
                made[l] += 1.0
        else:
            for l in range(L):
                for i in range(n):
                    x1[i] = xl[i, l]
                    for k in range(n):
                        P1[i, k] = Pl[i, k, l]
                for b in range(m):
                    i1[b] = inn[b, l]
                if joseph_update_sparse(x1, P1, hcols, hnnz, hval, i1, r_var, U1, K1, D1, S1, Si1, nu1, True):
                    v = tot[l]
                    for b in range(m):
                        v += nu1[b] * nu1[b]
                    tot[l] = v
                    made[l] += 1.0
                    for i in range(n):
                        xl[i, l] = x1[i]
                        for k in range(n):
                            Pl[i, k, l] = P1[i, k]
                else:
                    nfail[l] += 1
                    if l < nact:
                        for b in range(m):
                            svar_out[b0 + l, j, b] = np.nan
        for l in range(nact):
            s = b0 + l
            for i in range(n):
                xs[s, off + j, i] = xl[i, l]
                sig[s, off + j, i] = np.sqrt(max(Pl[i, i, l], 0.0))
    fin = True
    for l in range(nact):
        s = b0 + l
        for i in range(n):
            X[s, i] = xl[i, l]
            fin = fin and np.isfinite(xl[i, l])
            for k in range(n):
                PP[s, i, k] = Pl[i, k, l]
                fin = fin and np.isfinite(Pl[i, k, l])
        for j in range(J):
            for i in range(n):
                fin = fin and np.isfinite(xs[s, off + j, i]) and np.isfinite(sig[s, off + j, i])
        acc[s, 0] = tot[l]
        acc[s, 1] = made[l]
        failed[s] += nfail[l]
    if not fin:
        bad[blk] = 1


def _kalman_blocks(lo, hi, kind, fm, w, wc, Ts, z, X, PP, Qd, r_var, xs, sig, acc, failed, innov_out, svar_out, bad,
                   fa, fb, pa, pb, pptr, pcs, rptr, rcols):
    """Blocks ``lo .. hi - 1`` of :func:`_kalman_block` (one thread's share), each with its own
    scratch. The loop runs in Python, one dispatch per block of :data:`LANES` seeds: a compiled
    loop linked the block kernel's whole module and optimised it again, about 5 s of every cold
    compile (issue 22 item 4; ``python benchmarks/compile_events.py --rig sled``), for a loop of a
    few blocks per filter run. The kernel releases the GIL, so the threads still run side by side."""
    n, m, L = X.shape[1], z.shape[2], LANES
    e = np.empty
    hcols = np.arange(m, dtype=np.int64).reshape(m, 1)   # H = [I_m 0] as the reference's sparse rows
    for blk in range(lo, hi):
        _kalman_block(blk, kind, fm, w, wc, Ts, z, X, PP, Qd, r_var, xs, sig, acc, failed, innov_out, svar_out, bad,
                      fa, fb, pa, pb, pptr, pcs, rptr, rcols, e(L, dtype=np.int64), e((L, n, n)), e((n, n, L)),
                      e((n, n, L)), e((n, n, L)), e((n, L)), e((n, L)), e((n, n, L)), e((n, n, L)), e((m, n, L)), e((m, n, L)),
                      e((m, n, L)), e((m, m, L)), e((m, m, L)), e((m, L)), e((m, L)), e(L), e(L), e(L), e(L), e(L),
                      e(L, dtype=np.int64), e(n), e((n, n)), e(m), hcols, np.ones(m, dtype=np.int64), np.ones((m, 1)),
                      e((m, n)), e((m, n)), e((m, n)), e((m, m)), e((m, m)), e(m))


def kalman_lanes(dyn: Dynamics, Ts, z, X, PP, Qs, r_var, xs, sig, acc, failed, innov, s_var,
                  threads: int | None = None) -> None:
    """:func:`_kalman`'s work for the epochs of ``dyn`` with the seeds in lanes
    (:func:`_kalman_block`), blocks of seeds over ``threads`` threads (default: the numba
    threads set, :func:`platcal.parallel.set_threads`); a block with a non-finite number is
    rerun from its start by :func:`_kalman` on the dense F: the same numbers as :func:`_kalman`
    for every seed, whatever the threads."""
    S = X.shape[0]
    nblk = -(-S // LANES)
    fm = np.ascontiguousarray(dyn.f, dtype=np.float64)
    w, wc = (np.ascontiguousarray(v, dtype=np.float64) for v in (dyn.w, dyn.wc))
    if not (np.all(np.isfinite(Ts)) and np.all(np.isfinite(Qs)) and np.all(np.isfinite(r_var))
            and np.all(np.isfinite(w)) and np.all(np.isfinite(wc))):
        bad = np.ones(nblk, dtype=np.int64)
    else:
        bad = np.zeros(nblk, dtype=np.int64)
    start = (X.copy(), PP.copy(), acc.copy(), failed.copy())
    if not bad.all():
        with slp_vectorize():  # a first compile (or a cache miss) compiles the lanes as vectors
            run_threaded(_kalman_blocks, nblk, threads, dyn.kind, fm, w, wc, Ts, z,
                         X, PP, Qs, r_var, xs, sig, acc, failed, innov, s_var, bad, *_structure(dyn.kind))
    for blk in np.flatnonzero(bad):
        sl = slice(blk * LANES, min(S, (blk + 1) * LANES))
        for cur, st in zip((X, PP, acc, failed), start):
            cur[sl] = st[sl]
        off = xs.shape[1] - Ts.shape[0]
        Xb, Pb, ab, fb_ = X[sl].copy(), PP[sl].copy(), acc[sl].copy(), failed[sl].copy()
        xb, sb, ib, vb = xs[sl, off:].copy(), sig[sl, off:].copy(), innov[sl].copy(), s_var[sl].copy()
        Fd = system_matrices(dyn.kind, fm[sl], w, wc)
        _kalman(Fd, Ts, np.ascontiguousarray(z[sl]), Xb, Pb, Qs, r_var, xb, sb, ab, fb_, ib, vb)
        X[sl], PP[sl], acc[sl], failed[sl], innov[sl], s_var[sl] = Xb, Pb, ab, fb_, ib, vb
        xs[sl, off:], sig[sl, off:] = xb, sb
