"""The multi-position EKF with its replicates in SIMD lanes (issue 22 item 2; docs/multiposition-1g.md §9).

:func:`_ekf_block` runs :func:`.filter._ekf_one`'s pass for a block of
:data:`platcal.estimation.lanes.LANES` replicates with the replicates innermost, compiled with its
arrays ``noalias`` (:class:`platcal.estimation.lanes.NoAliasCompiler`) and LLVM's SLP vectoriser
on: each replicate's numbers are the one-replicate kernel's bit for bit
(``tests/multiposition/test_multiposition_lanes.py``).

A module of its own because its compiler pipeline subclasses numba's, so importing it imports
numba (issue 22 item 3): :mod:`.filter` names it by path (:func:`platcal.rig.resolve`) and imports
it only when a batch runs on the JIT; an identify on kernels compiled ahead of time
(:mod:`.aot_kernels`: one replicate on :func:`.filter._ekf_one`) never does.
"""

from __future__ import annotations

import numpy as np

from ...estimation.iterated import gauss_newton_point, make_iterated_scratch
from ...estimation.lanes import (LANES, NoAliasCompiler, cholesky_inverse_lanes, innovation_covariance_lanes,
                                 joseph_correct_lanes, packed_index, propagate_rows_lanes, slp_vectorize)
from ...jit import njit
from ...model.frames import ARCSEC
from ...parallel import run_threaded
from .filter import resid6_k, transition_rows
from .model import gyro_coefs, make_scratch, meas_k, rate_k, rk4_s


@njit(cache=True, inline="always")
def _update_lanes(xl, Pl, pidx, hc, nn, hval, innov, r_var, U, Kg, D, S, Sinv, nu, ok, acc, live, update_x):
    """:func:`platcal.estimation.kalman.joseph_update_sparse` for m = 3 on every lane of a block
    (``xl`` (n, LANES), packed ``Pl`` (n (n + 1) / 2, LANES); H's sparse rows ``hc``, ``nn`` shared
    by the lanes, values ``hval`` (3, w, LANES)), the same operations in the same order, so each
    lane's numbers are the reference kernel's bit for bit. A lane whose S is not positive definite
    gets ``ok = 0`` and a zero gain: x and P stay as they were (the reference skips the update);
    so does a lane with ``live = 0`` (its step skipped: the iterated update's S failed)."""
    innovation_covariance_lanes(Pl, pidx, hc, nn, hval, r_var, U, S, acc)
    cholesky_inverse_lanes(S, Sinv, innov, nu, ok)
    for l in range(LANES):
        if live[l] == 0.0:
            ok[l] = 0.0
            for r in range(3):
                innov[r, l] = 0.0  # a skipped step's innovation may be anything: 0 * inf is no zero
                for c in range(3):
                    Sinv[r, c, l] = 0.0
    joseph_correct_lanes(xl, Pl, U, Kg, D, S, Sinv, innov, update_x)


@njit(cache=True, error_model="numpy", pipeline_class=NoAliasCompiler)
def _ekf_block(blk, X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol, sums,
               rec, pidx, xl, Pl, xm, Pm, W, U, Kg, D, phiL, qL, hval, hvala, innov, S, Sinv, nu, ok, acc, cnt, gn,
               nu6L, F, nxt, C, dC, T, dT, f, eps, deps, greg, phi1, q1, zp, Hs, hc, nn, hca, nna, zero3,
               scr, nu6):
    """:func:`.filter._ekf_one` for the replicates ``blk * LANES ..`` of the batch, replicates in SIMD
    lanes (:mod:`platcal.estimation.lanes`; docs/multiposition-1g.md §9): the covariance work
    (propagation, both 3-row Joseph updates) is one vector operation over the lanes on the
    packed lower triangle ``Pl``; the model (§4 rate and RK4, §7 measurement; with ``iters >= 1``
    the iterated update's Gauss-Newton point, on the lane's P unpacked) is the reference's
    scalar code once per live lane. Lanes past the batch repeat the block's first replicate and
    are not written back. Every sum runs in the reference kernel's order without fused
    multiply-adds, so x, P, the NIS and the innovations record are bit-identical to
    :func:`.filter._ekf_one`'s and a replicate's numbers depend neither on its lane nor on the batch.

    ``phi0s`` (1, K, 3) commanded angles (rad) shared by the batch, or (R, K, 3) per replicate
    (the covariance-only run of one position per batch entry). ``sums`` (R, 4) receives per
    replicate the NIS sum, the updates, the linearisations and the skipped updates
    (``_ekf_one``'s return values); the arguments from ``pidx`` on are the block's lane-layout
    state and scratch (:func:`_ekf_blocks`), distinct arrays as the ``noalias`` compile requires.
    """
    B, n = X.shape
    L = LANES
    K = phi0s.shape[1]
    m = cols.shape[0]
    b0 = blk * L
    nact = min(L, B - b0)
    keep = rec.shape[1] > 0
    own = phi0s.shape[0] > 1  # angles per replicate
    for l in range(L):
        src = b0 + l if l < nact else b0
        for i in range(n):
            xl[i, l] = X[src, i]
            for j in range(i + 1):
                Pl[pidx[i, j], l] = Ps[src, i, j]
        for i in range(4):
            cnt[i, l] = 0.0
    for k in range(K):
        # the position's start (§9): phi = 0 with variance sigma_set^2, no cross covariance
        for r in range(3):
            for l in range(L):
                xl[r, l] = 0.0
            for i in range(n):
                e = pidx[r, i]
                for l in range(L):
                    Pl[e, l] = 0.0
            e = pidx[r, r]
            for l in range(L):
                Pl[e, l] = set_var
        for s in range(nk[k]):
            if s > 0:
                dt = tk[k, s] - tk[k, s - 1]
                for l in range(nact):
                    a0 = phi0s[b0 + l if own else 0, k]
                    for i in range(n):
                        xm[i] = xl[i, l]
                    rate_k(a0, xm, lay, wn, wu, zero3, nxt, F, True, C, dC, T, dT, f, eps, deps, greg)
                    transition_rows(F, T, cols, dt, arw2, phi1, q1)
                    # RK4 from the rate at x (its first stage), without noise
                    g0, g1, g2, on = gyro_coefs(xm, lay)
                    xl[0, l], xl[1, l], xl[2, l] = rk4_s(a0[0], a0[1], a0[2], xm[0], xm[1], xm[2], g0, g1, g2, on,
                                                         wn, wu, 0.0, 0.0, 0.0, dt, nxt[0], nxt[1], nxt[2])
                    for r in range(3):
                        for c in range(m):
                            phiL[r, c, l] = phi1[r, c]
                        for c in range(3):
                            qL[r, c, l] = q1[r, c]
                for l in range(nact, L):
                    for r in range(3):
                        xl[r, l] = xl[r, 0]
                        for c in range(m):
                            phiL[r, c, l] = phiL[r, c, 0]
                        for c in range(3):
                            qL[r, c, l] = qL[r, c, 0]
                # P <- Phi P Phi^T + Q on phi's rows (propagate_sparse): the rows through the
                # packed index, then the 3 x 3 block with Q (kalman._block3's sums)
                propagate_rows_lanes(Pl, pidx, cols, phiL, W, acc, 0)
                e00, e10, e11, e20, e21, e22 = pidx[0, 0], pidx[1, 0], pidx[1, 1], pidx[2, 0], pidx[2, 1], pidx[2, 2]
                for l in range(L):
                    Pl[e00, l] = acc[0, l] + 0.5 * (qL[0, 0, l] + qL[0, 0, l])
                    Pl[e11, l] = acc[2, l] + 0.5 * (qL[1, 1, l] + qL[1, 1, l])
                    Pl[e22, l] = acc[5, l] + 0.5 * (qL[2, 2, l] + qL[2, 2, l])
                    Pl[e10, l] = acc[1, l] + 0.5 * (qL[1, 0, l] + qL[0, 1, l])
                    Pl[e20, l] = acc[3, l] + 0.5 * (qL[2, 0, l] + qL[0, 2, l])
                    Pl[e21, l] = acc[4, l] + 0.5 * (qL[2, 1, l] + qL[1, 2, l])
            # the accelerometer outputs and H at the predicted state (iters >= 1: at the
            # Gauss-Newton point, with its innovation), lane by lane
            for l in range(nact):
                a0 = phi0s[b0 + l if own else 0, k]
                for i in range(n):
                    xm[i] = xl[i, l]
                gn[0, l] = 1.0  # linearisations; 0: the step is skipped (_ekf_one's continue)
                gn[1, l] = 0.0  # a gain step ran: NIS from the first linearisation (nu6L)
                if iters > 0:
                    for i in range(n):
                        for j in range(n):
                            Pm[i, j] = Pl[pidx[i, j], l]
                    used, gained = gauss_newton_point(xm, Pm, Z[b0 + l, k, s], r_var, resid6_k,
                                                      (a0, lay, zp, Hs, hc, nn, C, dC), iters, tol, scr, nu6)
                    gn[0, l] = used
                    gn[1, l] = 1.0 if gained else 0.0
                    hv6, hc6, nn6, in6 = scr[5], scr[6], scr[7], scr[4]
                    for r in range(3):
                        nn[r] = nn6[r]
                        innov[r, l] = in6[r]
                        for t in range(nn6[r]):
                            hval[r, t, l] = hv6[r, t]
                            hc[r, t] = hc6[r, t]
                    for i in range(6):
                        nu6L[i, l] = nu6[i]
                else:
                    meas_k(a0, xm, lay, zp, Hs, hc, nn, C, dC)
                    for r in range(3):
                        for t in range(nn[r]):
                            hval[r, t, l] = Hs[r, t]
                        innov[r, l] = Z[b0 + l, k, s, r] - zp[r]
            for l in range(nact, L):
                gn[0, l] = gn[0, 0]
                for r in range(3):
                    for t in range(nn[r]):
                        hval[r, t, l] = hval[r, t, 0]
                    innov[r, l] = innov[r, 0]
            _update_lanes(xl, Pl, pidx, hc, nn, hval, innov, r_var[:3], U, Kg, D, S, Sinv, nu, ok, acc[0], gn[0],
                          update_x)
            for l in range(nact):
                if gn[0, l] == 0.0:
                    continue
                cnt[2, l] += gn[0, l]
                if ok[l] > 0.0:
                    if gn[1, l] == 0.0:
                        cnt[0, l] += nu[0, l] * nu[0, l] + nu[1, l] * nu[1, l] + nu[2, l] * nu[2, l]
                    cnt[1, l] += 1.0
                else:
                    cnt[3, l] += 1.0
                if keep:
                    for i in range(3):
                        rec[b0 + l, k, s, i] = innov[i, l]
                        rec[b0 + l, k, s, 6 + i] = S[i, i, l] if ok[l] > 0.0 else np.nan
            # the angle sensors (H = 1/arcsec on phi), innovation from the updated state
            for l in range(L):
                src = b0 + l if l < nact else b0
                for i in range(3):
                    d = Z[src, k, s, 3 + i] - (phi0s[src if own else 0, k, i] + xl[i, l]) / ARCSEC
                    innov[i, l] = (d + 648000.0) % 1296000.0 - 648000.0
            _update_lanes(xl, Pl, pidx, hca, nna, hvala, innov, r_var[3:], U, Kg, D, S, Sinv, nu, ok, acc[0], gn[0],
                          update_x)
            for l in range(nact):
                if gn[0, l] == 0.0:
                    continue
                if ok[l] > 0.0:
                    if gn[1, l] == 0.0:
                        cnt[0, l] += nu[0, l] * nu[0, l] + nu[1, l] * nu[1, l] + nu[2, l] * nu[2, l]
                else:
                    cnt[3, l] += 1.0
                if keep:
                    for i in range(3):
                        rec[b0 + l, k, s, 3 + i] = innov[i, l]
                        rec[b0 + l, k, s, 9 + i] = S[i, i, l] if ok[l] > 0.0 else np.nan
                if gn[1, l] > 0.0:
                    for i in range(6):
                        cnt[0, l] += nu6L[i, l] * nu6L[i, l]
    for l in range(nact):
        b = b0 + l
        for i in range(n):
            X[b, i] = xl[i, l]
            for j in range(n):
                Ps[b, i, j] = Pl[pidx[i, j], l]
        for i in range(4):
            sums[b, i] = cnt[i, l]


@njit(cache=True, nogil=True, error_model="numpy")
def _ekf_blocks(lo, hi, X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol, sums,
                rec, pidx):
    """Blocks ``lo .. hi - 1`` of the batch through :func:`_ekf_block`, with their scratch."""
    n = X.shape[1]
    L = LANES
    m = cols.shape[0]
    C, dC, T, dT, f, eps, deps, greg = make_scratch(n)
    hvala = np.full((3, 1, L), 1.0 / ARCSEC)
    hca = np.empty((3, 1), dtype=np.int64)
    for i in range(3):
        hca[i, 0] = i
    e = np.empty
    for blk in range(lo, hi):
        _ekf_block(blk, X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol, sums,
                   rec, pidx, e((n, L)), e((n * (n + 1) // 2, L)), e(n), e((n, n)), e((n, 3 * L)), e((n, 3 * L)),
                   e((n, 3 * L)), e((n, 3 * L)), e((3, m, L)), e((3, 3, L)), np.zeros((3, 10, L)), hvala, e((3, L)),
                   e((3, 3, L)), e((3, 3, L)), e((3, L)), e(L), e((6, L)), e((4, L)), e((2, L)), e((6, L)),
                   np.zeros((3, n)), e(3), C, dC, T, dT, f, eps, deps, greg, e((3, m)), e((3, 3)), e(6),
                   e((3, 10)), np.empty((3, 10), dtype=np.int64), np.empty(3, dtype=np.int64), hca,
                   np.ones(3, dtype=np.int64), np.zeros(3), make_iterated_scratch(n, 6, 10), e(6))


def ekf_lanes(X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x=True, iters=0, tol=0.0,
               rec=None, threads=1):
    """One pass (§9) of the batch ``X`` (R, n), ``Ps`` (R, n, n) in place, replicates in lanes
    (:func:`_ekf_block`; arguments as :func:`.filter._ekf_one`'s, ``phi0s`` (K, 3) rad shared or
    (R, K, 3) per replicate); returns ``sums`` (R, 4): per replicate the NIS sum, the updates,
    the linearisations and the skipped updates. ``rec`` (R, K, m, 12) or None (none kept)."""
    R = X.shape[0]
    sums = np.zeros((R, 4))
    nblk = -(-R // LANES)
    phi0s = np.ascontiguousarray(phi0s, dtype=float).reshape(-1, tk.shape[0], 3)
    if phi0s.shape[0] not in (1, R) or Z.shape[:2] != (R, tk.shape[0]):  # the kernel does not check bounds
        raise ValueError(f"angles {phi0s.shape}, outputs {Z.shape} and times {tk.shape} do not match {R} replicates")
    rec = np.zeros((1, 0, 0, 12)) if rec is None else rec
    with slp_vectorize():  # a first compile (or a cache miss) compiles the lanes as vectors
        run_threaded(_ekf_blocks, nblk, threads, X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols,
                  bool(update_x), int(iters), float(tol), sums, rec, packed_index(X.shape[1]))
    return sums
