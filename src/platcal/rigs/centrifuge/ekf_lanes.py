"""The centrifuge EKF's state-major kernel: replicates in SIMD lanes (issue 22 item 1;
docs/centrifuge-model.md §9-11, the filter of :mod:`platcal.rigs.centrifuge.ekf`).

The same filter as :func:`platcal.rigs.centrifuge.ekf._filter_one` (propagation of the 3 attitude
rows through the RK4 map's exact Jacobian, Joseph update with the 3 accelerometer outputs,
position resets, the iterated update, the covariance-only run, segments of a streamed record),
with the batch laid out replicate-innermost: the replicates go in blocks of :data:`LANES`, and
a block's covariance is ``P[e, l]``, entry ``e`` of the lower triangle packed by rows
(:func:`packed_index`), lane ``l`` = replicate ``block * LANES + l``. Every covariance
operation is then one vector instruction over the lanes of a block, and a symmetric P is
stored once (no mirror, 1176 entries at n = 48: the block's P is 37.6 kB at 4 lanes, in L1).

Arithmetic: every product and sum rounds on its own, as in the reference kernel (no fused
multiply-add: LLVM contracts a product and a sum, or not, depending on how it vectorised a
loop, which differs between the threaded and the serial build of the same code, so with FMAs
a replicate's numbers depended on the thread count); every lane runs the same instructions,
so a replicate's numbers do not depend on its lane, on the batch size or on the number of
threads (a short last block is filled with copies of its first replicate, whose results are
dropped). Every entry is the reference kernel's operations in its order, so x, P, the history,
NIS and the innovations equal the reference kernel's bit for bit (``tests/test_ekf_lanes.py``;
``benchmarks/ekf_lanes_ab.py --check``: EKF, warm-up, 2 passes, IEKF, covariance-only run).

How the code is made to vectorise (issue 22): numba runs LLVM's loop vectoriser but not its SLP
vectoriser, and a loop over 4 lanes is unrolled before the loop vectoriser sees it; and without
knowing that the arrays do not overlap LLVM cannot merge the lanes' loads and stores. The block
kernel is therefore compiled with every array argument declared ``noalias``
(:class:`NoAliasCompiler`: all its arrays, scratch included, are distinct arguments) and with
SLP vectorisation on (:func:`slp_vectorize` around every call, so that a first compile or a
cache miss compiles it that way; SLP merges identical scalar operations and changes no number).
The model (the RK4 map with its Jacobian, the accelerometer outputs and Jacobian) stays the
reference kernel's scalar code, run once per live lane.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .attitude import MEAS_COLS, N_GYRO, P_G, make_sc_rk4_scratch, measure_jac_sc, rk4_jac_sc
from .base import specific_force_into
from ...estimation.kalman import cholesky_inverse
from ...estimation.lanes import (LANES, NoAliasCompiler, innovation_covariance_lanes, joseph_correct_lanes,
                                 packed_index, propagate_rows_lanes, slp_vectorize)
from ...estimation.lanes import cholesky_inverse_lanes as _cholesky_inverse_lanes

FASTMATH = False
"""LLVM fast-math flags of the block kernel: none (``{"contract"}``, fused multiply-adds, was 13 %
faster but made the numbers depend on the build: see the module docstring)."""


@njit(cache=True)
def _to_lanes(x, P, blk, xl, Pl, pidx):
    """Block ``blk`` of the batch (x (B, n), P (B, n, n)) into lane layout; lanes past the batch
    take a copy of the block's first replicate."""
    B, n = x.shape
    L = LANES
    for l in range(L):
        b = blk * L + l
        src = b if b < B else blk * L
        for i in range(n):
            xl[i, l] = x[src, i]
            for j in range(i + 1):
                Pl[pidx[i, j], l] = P[src, i, j]


@njit(cache=True)
def _from_lanes(xl, Pl, blk, x, P, pidx):
    """Block ``blk`` back into the batch's (B, n) and (B, n, n) arrays (live lanes only; P full
    and exactly symmetric)."""
    B, n = x.shape
    L = LANES
    for l in range(L):
        b = blk * L + l
        if b >= B:
            break
        for i in range(n):
            x[b, i] = xl[i, l]
            for j in range(n):
                P[b, i, j] = Pl[pidx[i, j], l]


@njit(cache=True, fastmath=FASTMATH, pipeline_class=NoAliasCompiler)
def _filter_block(blk, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                  update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl,
                  rec, seg_k, seg_t0, seg_last, seg_nis,
                  pidx, xl, Pl, W, U, K, D, phi, hval, innov, S, Sinv, nu, ok, acc, nis, bad,
                  coef_l, ang_l, fr_now, fr_mid, fr3, pb_l, ang_new, pa, pgyro, out, hm, ha,
                  rk_k, rk_ka, rk_kg, rk_v, S1, F1, nu1, in1, it_on, w1, xi, xnew, coef_i):
    """Block ``blk`` (replicates ``blk * L .. blk * L + L - 1``) through every segment of one pass:
    :func:`platcal.rigs.centrifuge.ekf._filter_replicate` and ``_filter_one`` with the lanes
    innermost. Arguments up to ``seg_nis`` are those of the reference kernel (batch layout,
    read and written for the live lanes only); the rest are the block's lane-layout state and
    scratch (:func:`_block_scratch`), distinct arrays as the ``noalias`` compile requires.

    The lane loops run over the constant :data:`LANES` (so that LLVM unrolls them and merges
    the lanes into vector instructions); the sums over a row of Phi or H accumulate into the
    output arrays column by column (a running sum in an array entry would be a chain of
    dependent loads and stores).
    """
    B, n = x.shape
    L = LANES
    nc = n - 3
    npc = pcols.shape[0]
    b0 = blk * L
    nact = min(L, B - b0)
    it_max = int(it_ctl[0])
    it_tol = it_ctl[1]
    it_until = it_ctl[2]
    it_ratio = it_ctl[3]
    keep_rec = rec.shape[1] > 0
    # packed positions of the attitude block's lower triangle
    e00, e10, e11 = pidx[nc, nc], pidx[nc + 1, nc], pidx[nc + 1, nc + 1]
    e20, e21, e22 = pidx[nc + 2, nc], pidx[nc + 2, nc + 1], pidx[nc + 2, nc + 2]
    _to_lanes(x, P, blk, xl, Pl, pidx)
    for l in range(nact):
        for i in range(coef_fixed.shape[1]):
            coef_l[l, i] = coef_fixed[b0 + l, i]
    for s in range(offs.shape[0] - 1):
        o0, o1 = offs[s], offs[s + 1]
        k = seg_k[s]
        reset = np.isnan(seg_t0[s])
        t_prev = 0.0 if reset else seg_t0[s]
        for l in range(nact):
            b = b0 + l
            nis[l] = 0.0 if reset else seg_nis[b]
            bad[l] = 0.0
            for c in range(params.shape[2]):
                pb_l[l, c] = params[b, k, c]
            specific_force_into(t_prev, pb_l[l], fr_now[l])
        if reset:
            # the position's start (docs/centrifuge-model.md §9): attitude = commanded angles,
            # variance reset_var, no cross-covariance
            for r in range(3):
                for l in range(L):
                    b = b0 + l if l < nact else b0
                    xl[nc + r, l] = cmd[b, k, r]
                for i in range(n):
                    e = pidx[nc + r, i]
                    for l in range(L):
                        Pl[e, l] = 0.0
                e = pidx[nc + r, nc + r]
                for l in range(L):
                    Pl[e, l] = reset_var
        for m in range(o1 - o0):
            tm = t[o0 + m]
            for l in range(nact):
                for kk in range(nc):
                    coef_l[l, est_idx[kk]] = xl[kk, l]
                for r in range(3):
                    ang_l[l, r] = xl[nc + r, l]
            if tm > t_prev:
                h = tm - t_prev
                for l in range(nact):
                    for r in range(3):
                        fr3[l, 0, r] = fr_now[l, r]
                    specific_force_into(t_prev + 0.5 * h, pb_l[l], fr_mid[l])
                    specific_force_into(tm, pb_l[l], fr_now[l])
                    for r in range(3):
                        fr3[l, 1, r] = fr_mid[l, r]
                        fr3[l, 2, r] = fr_now[l, r]
                    rk4_jac_sc(ang_l[l], coef_l[l], fr3[l], h, pb_l[l], ang_new[l], pa[l], pgyro[l],
                               (rk_k, rk_ka, rk_kg, rk_v))
                    for r in range(3):
                        for kk in range(npc - 3):
                            phi[r, kk, l] = pgyro[l, r, pg[kk]]
                        for i in range(3):
                            phi[r, npc - 3 + i, l] = pa[l, r, i]
                        ang_l[l, r] = ang_new[l, r]
                        xl[nc + r, l] = ang_new[l, r]
                for l in range(nact, L):  # the filler lanes repeat lane 0
                    for r in range(3):
                        for kk in range(npc):
                            phi[r, kk, l] = phi[r, kk, 0]
                        xl[nc + r, l] = xl[nc + r, 0]
                # P <- Phi P Phi^T + Q on the 3 attitude rows: W = Phi[dyn] P (rows through
                # the packed index), the 3 x 3 block, then the rows (= the columns) written
                qd = q_rate * h
                propagate_rows_lanes(Pl, pidx, pcols, phi, W, acc, nc)
                for l in range(L):
                    Pl[e00, l] = acc[0, l] + qd
                    Pl[e10, l] = acc[1, l]
                    Pl[e11, l] = acc[2, l] + qd
                    Pl[e20, l] = acc[3, l]
                    Pl[e21, l] = acc[4, l]
                    Pl[e22, l] = acc[5, l] + qd
                t_prev = tm
            # the outputs and H at the predicted state, lane by lane
            for l in range(nact):
                b = b0 + l
                g = pb_l[l, P_G]
                measure_jac_sc(ang_l[l], coef_l[l], fr_now[l, 0], fr_now[l, 1], fr_now[l, 2], g, out[l], hm[l],
                               ha[l])
                for r in range(3):
                    for kk in range(hnnz[r]):
                        src = hsrc[r, kk]
                        hval[r, kk, l] = hm[l, r, src] if src >= 0 else ha[l, r, -1 - src]
                    innov[r, l] = z[b, o0 + m, r] - out[l, r] if update_x else 0.0
            if it_max > 1 and update_x and tm < it_until:
                # the iterated update: each Gauss-Newton step's H_i P and S for every lane at once
                # (vectors, the final update's own sums), then each lane still iterating steps on
                # its own (issue 22: 0.85x the IEKF's CPU against H_i P per lane through the index)
                n_on = 0
                for l in range(nact):
                    it_on[l] = 1.0 if _coef_ratio_lane(Pl, pidx, it_ctl, nc, l) > it_ratio else 0.0
                    n_on += int(it_on[l])
                    for i in range(n):
                        xi[l, i] = xl[i, l]
                for it in range(it_max - 1):
                    if n_on == 0:
                        break
                    innovation_covariance_lanes(Pl, pidx, hcols, hnnz, hval, r_var, U, S, acc[0])
                    for l in range(nact):
                        if it_on[l] > 0.0 and not _relinearise_lane(
                                l, b0 + l, o0 + m, it_tol, z, Pl, xl, pidx, est_idx, hcols, hnnz, hsrc, hval,
                                innov, U, S, coef_l, fr_now, pb_l[l, P_G], S1, F1, nu1, in1, w1, xi, xnew,
                                coef_i, out[l], hm[l], ha[l]):
                            it_on[l] = 0.0
                            n_on -= 1
            for l in range(nact, L):
                for r in range(3):
                    for kk in range(hnnz[r]):
                        hval[r, kk, l] = hval[r, kk, 0]
                    innov[r, l] = innov[r, 0]
            # U = H P (3 x n), through the packed index; S = H U^T + R
            innovation_covariance_lanes(Pl, pidx, hcols, hnnz, hval, r_var, U, S, acc[0])
            _cholesky_inverse_lanes(S, Sinv, innov, nu, ok)
            # K = S^-1 U, D = U - S K, x += K innov, P -= K U^T + D K^T (packed lower triangle)
            joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, update_x)
            for l in range(nact):
                b = b0 + l
                if ok[l] > 0.0:
                    nis[l] += nu[0, l] * nu[0, l] + nu[1, l] * nu[1, l] + nu[2, l] * nu[2, l]
                else:
                    bad[l] += 1.0
                if keep_rec:
                    for r in range(3):
                        rec[b, o0 + m, r] = innov[r, l]
                        rec[b, o0 + m, 3 + r] = S[r, r, l] if ok[l] > 0.0 else np.nan
                hi = hist_idx[o0 + m]
                if hi >= 0:
                    for i in range(n):
                        v = Pl[pidx[i, i], l]
                        hist_x[b, hi, i] = xl[i, l]
                        hist_s[b, hi, i] = np.sqrt(v) if v > 0.0 else -1.0
        for l in range(nact):
            b = b0 + l
            if seg_last[s]:
                nis_sum[b] += nis[l]
            else:
                seg_nis[b] = nis[l]
            n_bad[b] += int(bad[l])
    _from_lanes(xl, Pl, blk, x, P, pidx)


@njit(cache=True, inline="always")
def _coef_ratio_lane(Pl, pidx, it_ctl, nc, l):
    """Lane l's mean over the coefficients of P_ii / P0_ii (the reference kernel's
    ``_coef_ratio``); inf when the iteration does not depend on it."""
    if it_ctl[3] <= 0.0:
        return np.inf
    s = 0.0
    for k in range(nc):
        s += Pl[pidx[k, k], l] / it_ctl[4 + k]
    return s / nc


@njit(cache=True)
def _relinearise_lane(l, b, mz, it_tol, z, Pl, xl, pidx, est_idx, hcols, hnnz, hsrc, hval, innov, U, S,
                      coef_l, fr_now, g, S1, F1, nu1, in1, w1, xi, xnew, coef_i, out, hm, ha):
    """One Gauss-Newton step of the iterated EKF (the reference kernel's loop in ``_filter_one``)
    for lane ``l`` (replicate ``b``, output row ``mz``), from ``U = H_i P`` and ``S`` (n, 3 * LANES),
    (3, 3, LANES) at its current linearisation: ``x_{i+1} = x_pred + U^T S^-1 innov`` into
    ``xi[l]``, then H and the innovation at ``x_{i+1}`` into ``hval[:, :, l]`` and ``innov[:, l]``.
    x and P are untouched (the Joseph update that follows uses them). Returns whether the lane
    iterates on: False when S is not positive definite (nothing changed) or the step moved no
    state by ``it_tol`` sigmas or more."""
    n = xi.shape[1]
    nc = n - 3
    for r in range(3):
        for c in range(3):
            S1[r, c] = S[r, c, l]
        in1[r] = innov[r, l]
    if not cholesky_inverse(S1, F1, nu1, in1):
        return False
    for r in range(3):
        w1[r] = F1[r, 0] * in1[0] + F1[r, 1] * in1[1] + F1[r, 2] * in1[2]
    dmax = 0.0
    for j in range(n):
        xnew[j] = xl[j, l] + U[j, l] * w1[0] + U[j, LANES + l] * w1[1] + U[j, 2 * LANES + l] * w1[2]
        d = abs(xnew[j] - xi[l, j]) / np.sqrt(Pl[pidx[j, j], l])
        if d > dmax:
            dmax = d
        xi[l, j] = xnew[j]
    for i in range(coef_i.shape[0]):
        coef_i[i] = coef_l[l, i]
    for kk in range(nc):
        coef_i[est_idx[kk]] = xnew[kk]
    measure_jac_sc(xnew[nc:], coef_i, fr_now[l, 0], fr_now[l, 1], fr_now[l, 2], g, out, hm, ha)
    for r in range(3):
        v = z[b, mz, r] - out[r]
        for kk in range(hnnz[r]):
            src = hsrc[r, kk]
            hv = hm[r, src] if src >= 0 else ha[r, -1 - src]
            hval[r, kk, l] = hv
            c = hcols[r, kk]
            v -= hv * (xl[c, l] - xnew[c])
        innov[r, l] = v
    return dmax >= it_tol


@njit(cache=True)
def _block_scratch(n, npc, mh, nco, npar):
    """A block's lane-layout state and scratch: :func:`_filter_block`'s arguments after ``pidx``,
    for ``n`` states, ``npc`` columns of Phi's attitude rows, ``mh`` nonzeros per row of H, ``nco``
    coefficients and ``npar`` centrifuge parameters per position; distinct arrays, as the block
    kernel's ``noalias`` compile requires."""
    L = LANES
    f3 = np.empty
    return (f3((n, L)), f3((n * (n + 1) // 2, L)), f3((n, 3 * L)), f3((n, 3 * L)), f3((n, 3 * L)),
            f3((n, 3 * L)), f3((3, npc, L)), np.zeros((3, mh, L)), np.zeros((3, L)), f3((3, 3, L)),
            f3((3, 3, L)), f3((3, L)), f3(L), f3((6, L)), f3(L), f3(L),
            f3((L, nco)), f3((L, 3)), f3((L, 3)), f3((L, 3)), f3((L, 3, 3)), f3((L, npar)),
            f3((L, 3)), f3((L, 3, 3)), f3((L, 3, N_GYRO)), f3((L, 3)), np.zeros((L, 3, MEAS_COLS.shape[1])),
            f3((L, 3, 3)),
            f3((4, 3)), f3((4, 3, 3)), f3((4, 3, N_GYRO)), f3(42), f3((3, 3)), f3((3, 3)), f3(3), f3(3),
            f3(L), f3(3), f3((L, n)), f3(n), f3(nco))


@njit(parallel=True, cache=True)
def _run_blocks(nblk, sizes, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec, seg_k,
                seg_t0, seg_last, seg_nis, pidx):
    """Every block of one pass, one block per ``prange`` iteration (threads); ``sizes``: the
    arguments of :func:`_block_scratch`."""
    for blk in prange(nblk):
        # prange's index is unsigned: int64 as the serial loop's, so the block kernels compile once
        _filter_block(np.int64(blk), x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                      update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec,
                      seg_k, seg_t0, seg_last, seg_nis, pidx, *_block_scratch(*sizes))


def run_pass_lanes(x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate, update_x,
                   hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec, seg):
    """One pass of the EKF over a batch, in place: the reference kernel's arguments and effect
    (:func:`platcal.rigs.centrifuge.ekf._run_pass`), computed block by block in lanes."""
    B, n = x.shape
    nblk = -(-B // LANES)
    args = (x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate, update_x, hist_idx, hist_x,
            hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec, *seg, packed_index(n))
    sizes = (n, pcols.shape[0], hcols.shape[1], coef_fixed.shape[1], params.shape[2])
    with slp_vectorize():
        if nblk == 1 or numba.get_num_threads() == 1:
            # block by block from here, the block kernel called directly: a compiled caller (a
            # serial loop, or a function allocating the scratch) links and optimises the block
            # kernel's whole module again (3.7 s of a cold compile) to save a few us per block
            for blk in range(nblk):
                _filter_block(blk, *args, *_block_scratch(*sizes))
        else:
            _run_blocks(nblk, sizes, *args)
