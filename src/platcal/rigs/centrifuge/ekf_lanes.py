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
cache miss compiles it that way; SLP merges identical scalar operations and changes no number),
and with LLVM's loop vectoriser off: it took loops whose lanes SLP merges across their other index
instead, with gathers and scatters (the gyro-coefficient columns of the RK4 map, :func:`_kg_stage`),
and the kernel's lane loops are short enough to be unrolled and merged by SLP (issue 22, stop 50:
the kernel 7 % faster, ``benchmarks/lanes_commits_ab.py``).
The RK4 map with its exact Jacobian runs for the block's lanes at once (:func:`rk4_jac_lanes`:
the reference's operations per lane on 1-D lane arrays, which SLP merges). The block kernel is
compiled with numpy's error model, so its divisions carry no zero checks and vectorise too; its
divisors are g, cos beta, the Cholesky pivots (1 where not positive) and the coefficients' prior
variances, and only cos beta = 0 exactly, at gimbal lock, would give inf where the reference kernel
raises. The base specific force and the accelerometer outputs and Jacobian stay the reference
kernel's scalar code, the outputs once per live lane, the force once per block when the block's
lanes share one centrifuge (a study's replicates do), else once per lane (issue 22: the step 1927 ->
1772 ns, the model 617 -> 418 ns, `benchmarks/ekf_lanes_ablation.py`; the shared force 3 % of the
step).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from .attitude import (MEAS_COLS, N_GYRO, P_G, P_OMEGA_N, P_OMEGA_U, V_A, V_DU, V_JA, V_RATE, V_T, V_U, _force_p,
                       _shift, c_rp_sc, measure_jac_sc)
from .base import specific_force_into
from ...estimation.kalman import cholesky_inverse
from ...estimation.lanes import (LANES, NoAliasCompiler, innovation_covariance_lanes, joseph_correct_lanes,
                                 packed_index, propagate_rows_lanes, slp_vectorize)
from ...estimation.lanes import cholesky_inverse_lanes as _cholesky_inverse_lanes
from ...model.frames import DEG_PER_HOUR
from ...model.instruments import GYRO_AXES, I_DOO, gyro_axis_components, gyro_drift_terms

FASTMATH = False
"""LLVM fast-math flags of the block kernel: none (``{"contract"}``, fused multiply-adds, was 13 %
faster but made the numbers depend on the build: see the module docstring)."""


# The same map for a block of replicates in SIMD lanes (the state-major EKF kernel, issue 22):
# every lane's operations are rk4_jac_sc's, so its numbers are too (tests/test_ekf_lanes.py).
@njit(cache=True, inline="always")
def rate_jac_lanes(sc, coef, fr, g, wn, wu, v, w):
    """:func:`rate_jac_sc` for :data:`LANES` replicates at once, the same operations in the same
    order per lane (bit for bit). Every array is 1-D with the lanes innermost, entry ``q`` of lane
    ``l`` at ``[q * LANES + l]``: ``sc`` (6 LANES) the sines and cosines of alpha, beta, gamma,
    ``coef`` (ncoef LANES), ``fr`` (3 LANES) the base specific force (m/s^2), ``g``, ``wn``, ``wu``
    (LANES) m/s^2 and rad/s; results into ``v`` (42 LANES) as :data:`V_RATE` ...; ``w`` (40 LANES)
    scratch (C, dC/dbeta, f, d f / d alpha, d f / d beta, T, 1 / cos beta, tan beta, slopes).

    Why this form (issue 22): LLVM's SLP vectoriser merges the lanes' identical operations only
    where it can tell their memory apart, i.e. at constant offsets from one base (a 2-D array's row
    stride is a run-time value), and only in lane loops small enough to be unrolled; hence 1-D
    arrays and the body cut into short lane loops that hand their values on through ``w``."""
    L = LANES
    for l in range(L):
        sa, ca, sb = sc[l], sc[L + l], sc[2 * L + l]
        cb, sg, cg = sc[3 * L + l], sc[4 * L + l], sc[5 * L + l]
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = c_rp_sc(sa, ca, sb, cb, sg, cg)
        w[l] = c00
        w[L + l] = c01
        w[2 * L + l] = c02
        w[3 * L + l] = c10
        w[4 * L + l] = c11
        w[5 * L + l] = c12
        w[6 * L + l] = c20
        w[7 * L + l] = c21
        w[8 * L + l] = c22
        w[9 * L + l] = -cg * sb
        w[10 * L + l] = cg * cb * sa
        w[11 * L + l] = -cg * cb * ca
        w[12 * L + l] = sg * sb
        w[13 * L + l] = -sg * cb * sa
        w[14 * L + l] = sg * cb * ca
        w[15 * L + l] = cb
        w[16 * L + l] = sb * sa
        w[17 * L + l] = -sb * ca
    for l in range(L):
        fr0, fr1, fr2 = fr[l], fr[L + l], fr[2 * L + l]
        gl = g[l]
        f0, f1, f2 = _force_p(w[l], w[L + l], w[2 * L + l], w[3 * L + l], w[4 * L + l], w[5 * L + l],
                              w[6 * L + l], w[7 * L + l], w[8 * L + l],
                              fr0, fr1, fr2, gl)
        w[18 * L + l] = f0
        w[19 * L + l] = f1
        w[20 * L + l] = f2
    for l in range(L):  # short lane loops, which LLVM unrolls and SLP merges (as below)
        fr1, fr2 = fr[L + l], fr[2 * L + l]
        gl = g[l]
        w[21 * L + l] = (-w[2 * L + l] * fr1 + w[L + l] * fr2) / gl
        w[22 * L + l] = (-w[5 * L + l] * fr1 + w[4 * L + l] * fr2) / gl
        w[23 * L + l] = (-w[8 * L + l] * fr1 + w[7 * L + l] * fr2) / gl
    for l in range(L):
        fr0, fr1, fr2 = fr[l], fr[L + l], fr[2 * L + l]
        gl = g[l]
        w[24 * L + l] = (w[9 * L + l] * fr0 + w[10 * L + l] * fr1 + w[11 * L + l] * fr2) / gl
        w[25 * L + l] = (w[12 * L + l] * fr0 + w[13 * L + l] * fr1 + w[14 * L + l] * fr2) / gl
        w[26 * L + l] = (w[15 * L + l] * fr0 + w[16 * L + l] * fr1 + w[17 * L + l] * fr2) / gl
    for l in range(L):
        sb, cb, sg, cg = sc[2 * L + l], sc[3 * L + l], sc[4 * L + l], sc[5 * L + l]
        ib = 1.0 / cb
        tb = sb * ib
        w[27 * L + l] = cg * ib
        w[28 * L + l] = -sg * ib
        w[29 * L + l] = sg
        w[30 * L + l] = cg
        w[31 * L + l] = -tb * cg
        w[32 * L + l] = tb * sg
        w[33 * L + l] = ib
        w[34 * L + l] = tb
    for j in range(3):
        for l in range(L):
            f0, f1, f2 = w[18 * L + l], w[19 * L + l], w[20 * L + l]
            aI, aO, aS = gyro_axis_components(j, f0, f1, f2)
            v[(V_A + 3 * j) * L + l] = aI
            v[(V_A + 3 * j + 1) * L + l] = aO
            v[(V_A + 3 * j + 2) * L + l] = aS
        # short lane loops, which LLVM unrolls and SLP merges (one loop with the drift and its
        # gradient was left rolled, and ran scalar with the loop vectoriser off)
        for l in range(L):
            aI, aO, aS = v[(V_A + 3 * j) * L + l], v[(V_A + 3 * j + 1) * L + l], v[(V_A + 3 * j + 2) * L + l]
            D, DI = coef[j * L + l], coef[(3 + j) * L + l]
            DO, DS = coef[(6 + j) * L + l], coef[(9 + j) * L + l]
            DII, DSS, DIO = coef[(12 + j) * L + l], coef[(15 + j) * L + l], coef[(18 + j) * L + l]
            DIS, DOS, DOO = coef[(21 + j) * L + l], coef[(24 + j) * L + l], coef[(I_DOO + j) * L + l]
            e = gyro_drift_terms(D, DI, DO, DS, DII, DSS, DIO, DIS, DOS, DOO, aI, aO, aS)
            v[(V_U + j) * L + l] = e * DEG_PER_HOUR
        for l in range(L):
            aI, aO, aS = v[(V_A + 3 * j) * L + l], v[(V_A + 3 * j + 1) * L + l], v[(V_A + 3 * j + 2) * L + l]
            DI, DO, DS = coef[(3 + j) * L + l], coef[(6 + j) * L + l], coef[(9 + j) * L + l]
            DII, DSS, DIO = coef[(12 + j) * L + l], coef[(15 + j) * L + l], coef[(18 + j) * L + l]
            DIS, DOS, DOO = coef[(21 + j) * L + l], coef[(24 + j) * L + l], coef[(I_DOO + j) * L + l]
            w[35 * L + l] = DI + 2.0 * DII * aI + DIO * aO + DIS * aS
            w[36 * L + l] = DO + 2.0 * DOO * aO + DIO * aI + DOS * aS
            w[37 * L + l] = DS + 2.0 * DSS * aS + DIS * aI + DOS * aO
        for l in range(L):
            gI, gO, gS = w[35 * L + l], w[36 * L + l], w[37 * L + l]
            d0 = gI * GYRO_AXES[j, 0, 0] + gO * GYRO_AXES[j, 1, 0] + gS * GYRO_AXES[j, 2, 0]
            d1 = gI * GYRO_AXES[j, 0, 1] + gO * GYRO_AXES[j, 1, 1] + gS * GYRO_AXES[j, 2, 1]
            d2 = gI * GYRO_AXES[j, 0, 2] + gO * GYRO_AXES[j, 1, 2] + gS * GYRO_AXES[j, 2, 2]
            fg0 = w[19 * L + l]
            fg1 = -w[18 * L + l]
            fg2 = 0.0
            v[(V_DU + 3 * j) * L + l] = DEG_PER_HOUR * (d0 * w[21 * L + l] + d1 * w[22 * L + l]
                                                        + d2 * w[23 * L + l])
            v[(V_DU + 3 * j + 1) * L + l] = DEG_PER_HOUR * (d0 * w[24 * L + l] + d1 * w[25 * L + l]
                                                            + d2 * w[26 * L + l])
            v[(V_DU + 3 * j + 2) * L + l] = DEG_PER_HOUR * (d0 * fg0 + d1 * fg1 + d2 * fg2)
    for l in range(L):
        wnl = wn[l]
        wul = wu[l]
        c01, c02, c11 = w[L + l], w[2 * L + l], w[4 * L + l]
        c12, c21, c22 = w[5 * L + l], w[7 * L + l], w[8 * L + l]
        b01, b02, b11 = w[10 * L + l], w[11 * L + l], w[13 * L + l]
        b12, b21, b22 = w[14 * L + l], w[16 * L + l], w[17 * L + l]
        w[35 * L + l] = v[V_U * L + l] + c01 * wnl + c02 * wul
        w[36 * L + l] = v[(V_U + 1) * L + l] + c11 * wnl + c12 * wul
        w[37 * L + l] = v[(V_U + 2) * L + l] + c21 * wnl + c22 * wul
        v[V_DU * L + l] += -c02 * wnl + c01 * wul
        v[(V_DU + 3) * L + l] += -c12 * wnl + c11 * wul
        v[(V_DU + 6) * L + l] += -c22 * wnl + c21 * wul
        v[(V_DU + 1) * L + l] += b01 * wnl + b02 * wul
        v[(V_DU + 4) * L + l] += b11 * wnl + b12 * wul
        v[(V_DU + 7) * L + l] += b21 * wnl + b22 * wul
        v[(V_DU + 2) * L + l] += c11 * wnl + c12 * wul
        v[(V_DU + 5) * L + l] += -c01 * wnl - c02 * wul
    for l in range(L):
        u0, u1, u2 = w[35 * L + l], w[36 * L + l], w[37 * L + l]
        t00, t01, t10 = w[27 * L + l], w[28 * L + l], w[29 * L + l]
        t11, t20, t21 = w[30 * L + l], w[31 * L + l], w[32 * L + l]
        sg, cg = sc[4 * L + l], sc[5 * L + l]
        ib, tb = w[33 * L + l], w[34 * L + l]
        v[V_RATE * L + l] = -(t00 * u0 + t01 * u1)
        v[(V_RATE + 1) * L + l] = -(t10 * u0 + t11 * u1)
        v[(V_RATE + 2) * L + l] = -(t20 * u0 + t21 * u1 + u2)
        w[38 * L + l] = cg * tb * ib * u0 - sg * tb * ib * u1
        w[39 * L + l] = -cg * ib * ib * u0 + sg * ib * ib * u1
    for i in range(3):
        for l in range(L):
            t00, t01, t10 = w[27 * L + l], w[28 * L + l], w[29 * L + l]
            t11, t20, t21 = w[30 * L + l], w[31 * L + l], w[32 * L + l]
            v[(V_JA + i) * L + l] = -(t00 * v[(V_DU + i) * L + l] + t01 * v[(V_DU + 3 + i) * L + l])
            v[(V_JA + 3 + i) * L + l] = -(t10 * v[(V_DU + i) * L + l] + t11 * v[(V_DU + 3 + i) * L + l])
            v[(V_JA + 6 + i) * L + l] = -(t20 * v[(V_DU + i) * L + l] + t21 * v[(V_DU + 3 + i) * L + l]
                                          + v[(V_DU + 6 + i) * L + l])
    for l in range(L):
        u0, u1 = w[35 * L + l], w[36 * L + l]
        sg, cg = sc[4 * L + l], sc[5 * L + l]
        ib, tb = w[33 * L + l], w[34 * L + l]
        dtg0 = -sg * ib * u0 - cg * ib * u1
        dtg1 = cg * u0 - sg * u1
        dtg2 = tb * sg * u0 + tb * cg * u1
        v[(V_JA + 1) * L + l] -= w[38 * L + l]
        v[(V_JA + 7) * L + l] -= w[39 * L + l]
        v[(V_JA + 2) * L + l] -= dtg0
        v[(V_JA + 5) * L + l] -= dtg1
        v[(V_JA + 8) * L + l] -= dtg2
        v[V_T * L + l] = w[27 * L + l]
        v[(V_T + 1) * L + l] = w[28 * L + l]
        v[(V_T + 2) * L + l] = 0.0
        v[(V_T + 3) * L + l] = w[29 * L + l]
        v[(V_T + 4) * L + l] = w[30 * L + l]
        v[(V_T + 5) * L + l] = 0.0
        v[(V_T + 6) * L + l] = w[31 * L + l]
        v[(V_T + 7) * L + l] = w[32 * L + l]
        v[(V_T + 8) * L + l] = 1.0


@njit(cache=True, inline="always")
def _kg_stage(kg, phi_g, v, w, step, h6, kind):
    """RK4 stage's columns of the gyro coefficients in :func:`rk4_jac_lanes`, for the 3 rows at once:
    ``k_s = T_s dm + step J_s k_{s-1}`` (the drift terms' monomials ``dm``, ``v`` the stage's
    :func:`rate_jac_lanes` values), written over ``k_{s-1}`` in ``kg[:3 N_GYRO LANES]`` (row r,
    coefficient i of lane l at ``[(r N_GYRO + i) LANES + l]``) and summed into ``phi_g`` with RK4's
    weights, ``phi_g = h6 (k_0 + 2 k_1 + 2 k_2 + k_3)`` summed left to right as that expression is;
    ``kind`` (a constant at each call): 0 the first stage (no k_{s-1}), 1 the middle two, 2 the
    last. ``w`` holds T's rows and the monomials (the stage's :func:`rate_jac_lanes` scratch, free
    by then). The operations and their order are :func:`rk4_jac_sc`'s, each entry's own.

    Why this form (issue 22): a stage's coefficients at offsets from one base that depend only on
    the loop's own indices, and T and the monomials in another array, so that LLVM can tell the
    stores from the loads and merge the lanes; with each stage in its own rows of ``kg`` (offsets
    that depend on the stage) the recursion ran scalar, 35 % of the map's time (``perf`` samples).
    The map 16 % faster (1328 against 1576 ns a 4-lane call, each compiled as its kernel is:
    ``benchmarks/rk4_map_ab.py``), the block kernel 7 % (issue 22, stop 50)."""
    L = LANES
    G = N_GYRO
    for r in range(3):
        for j in range(3):
            for l in range(L):
                w[(3 * r + j) * L + l] = -v[(V_T + 3 * r + j) * L + l] * DEG_PER_HOUR
    for j in range(3):
        for l in range(L):
            aI, aO, aS = v[(V_A + 3 * j) * L + l], v[(V_A + 3 * j + 1) * L + l], v[(V_A + 3 * j + 2) * L + l]
            w[(9 + j) * L + l] = 1.0  # t * 1.0 is t: the constant term's column
            w[(12 + j) * L + l] = aI
            w[(15 + j) * L + l] = aO
            w[(18 + j) * L + l] = aS
            w[(21 + j) * L + l] = aI * aI
            w[(24 + j) * L + l] = aS * aS
            w[(27 + j) * L + l] = aI * aO
            w[(30 + j) * L + l] = aI * aS
            w[(33 + j) * L + l] = aO * aS
            w[(36 + j) * L + l] = aO * aO
    # the block kernel compiles with LLVM's loop vectoriser off (run_pass_lanes): it took this loop
    # across the coefficients with gathers and scatters, 2.5-3x slower than the lanes merged by SLP
    for m in range(G // 3):
        for j in range(3):
            i = 3 * m + j
            for l in range(L):
                dm = w[(9 + i) * L + l]
                k0, k1, k2 = kg[i * L + l], kg[(G + i) * L + l], kg[(2 * G + i) * L + l]
                for r in range(3):
                    d = w[(3 * r + j) * L + l] * dm
                    if kind > 0:
                        d += step * (v[(V_JA + 3 * r) * L + l] * k0 + v[(V_JA + 3 * r + 1) * L + l] * k1
                                     + v[(V_JA + 3 * r + 2) * L + l] * k2)
                    e = (r * G + i) * L + l
                    kg[e] = d
                    if kind == 0:
                        phi_g[e] = d
                    elif kind == 1:
                        phi_g[e] += 2.0 * d
                    else:
                        phi_g[e] = h6 * (phi_g[e] + d)


@njit(cache=True, inline="always")
def rk4_jac_lanes(ang, coef, fr3, h, g, wn, wu, out, phi_a, phi_g, k, ka, kg, v, sc0, sc, fr, w):
    """:func:`rk4_jac_sc` for :data:`LANES` replicates at once, the same operations in the same order
    per lane (bit for bit), on 1-D lane arrays as :func:`rate_jac_lanes` takes them: ``ang`` (3 LANES)
    rad, ``coef`` (ncoef LANES), ``fr3`` (3 stages x 3 LANES) the base specific force at the step's
    start, middle and end (m/s^2), ``h`` s, ``g``, ``wn``, ``wu`` (LANES); writes ``out`` (3 LANES)
    rad, ``phi_a`` (3 x 3 LANES) and ``phi_g`` (3 x :data:`N_GYRO` LANES); scratch ``k`` (4 x 3 LANES),
    ``ka`` (4 x 9 LANES), ``kg`` (3 x N_GYRO LANES: :func:`_kg_stage`), ``v`` (42 LANES), ``sc0``, ``sc`` (6 LANES),
    ``fr`` (3 LANES), ``w`` (40 LANES)."""
    L = LANES
    h6 = h / 6.0
    for l in range(L):
        sc0[l], sc0[L + l] = np.sin(ang[l]), np.cos(ang[l])
        sc0[2 * L + l], sc0[3 * L + l] = np.sin(ang[L + l]), np.cos(ang[L + l])
        sc0[4 * L + l], sc0[5 * L + l] = np.sin(ang[2 * L + l]), np.cos(ang[2 * L + l])
    for s in range(4):
        fs = 0 if s == 0 else (1 if s < 3 else 2)
        step = 0.0 if s == 0 else (0.5 * h if s < 3 else h)
        for l in range(L):
            for r in range(3):
                fr[r * L + l] = fr3[(fs * 3 + r) * L + l]
        if s == 0:
            for q in range(6):
                for l in range(L):
                    sc[q * L + l] = sc0[q * L + l]
        else:
            for a in range(3):
                for l in range(L):
                    i0, i1 = 2 * a * L + l, (2 * a + 1) * L + l
                    sc[i0], sc[i1] = _shift(sc0[i0], sc0[i1], step * k[((s - 1) * 3 + a) * L + l])
        rate_jac_lanes(sc, coef, fr, g, wn, wu, v, w)
        for r in range(3):
            for l in range(L):
                k[(s * 3 + r) * L + l] = v[(V_RATE + r) * L + l]
        # the gyro coefficients' columns: this stage's over the last one's, in place, and into phi_g
        if s == 0:
            _kg_stage(kg, phi_g, v, w, step, h6, 0)
        elif s < 3:
            _kg_stage(kg, phi_g, v, w, step, h6, 1)
        else:
            _kg_stage(kg, phi_g, v, w, step, h6, 2)
        for r in range(3):
            j0, j1, j2 = (V_JA + 3 * r) * L, (V_JA + 3 * r + 1) * L, (V_JA + 3 * r + 2) * L
            for i in range(3):
                p0, p1, p2 = ((s - 1) * 9 + i) * L, ((s - 1) * 9 + 3 + i) * L, ((s - 1) * 9 + 6 + i) * L
                for l in range(L):
                    d = v[(V_JA + 3 * r + i) * L + l]
                    if s > 0:
                        d += step * (v[j0 + l] * ka[p0 + l] + v[j1 + l] * ka[p1 + l] + v[j2 + l] * ka[p2 + l])
                    ka[(s * 9 + 3 * r + i) * L + l] = d
    for r in range(3):
        for l in range(L):
            out[r * L + l] = ang[r * L + l] + h6 * (k[r * L + l] + 2.0 * k[(3 + r) * L + l] + 2.0 * k[(6 + r) * L + l]
                                                    + k[(9 + r) * L + l])
        for i in range(3):
            e = 3 * r + i
            for l in range(L):
                phi_a[e * L + l] = (1.0 if r == i else 0.0) + h6 * (
                    ka[e * L + l] + 2.0 * ka[(9 + e) * L + l] + 2.0 * ka[(18 + e) * L + l] + ka[(27 + e) * L + l])


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


@njit(cache=True, fastmath=FASTMATH, error_model="numpy", pipeline_class=NoAliasCompiler)
def _filter_block(blk, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
                  update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl,
                  rec, seg_k, seg_t0, seg_last, seg_nis,
                  pidx, xl, Pl, W, U, K, D, phi, hval, innov, S, Sinv, nu, ok, acc, nis, bad,
                  coef_l, ang_l, fr_now, fr_mid, fr3, pb_l, out, hm, ha,
                  S1, F1, nu1, in1, it_on, w1, xi, xnew, coef_i, m_coef, m_ang, m_fr3, m_g, m_wn, m_wu,
                  m_out, m_pa, m_pg, m_k, m_ka, m_kg, m_v, m_sc0, m_sc, m_fr, m_w):
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
    for i in range(coef_fixed.shape[1]):
        for l in range(L):
            m_coef[i * L + l] = coef_fixed[b0 + l if l < nact else b0, i]
    for s in range(offs.shape[0] - 1):
        o0, o1 = offs[s], offs[s + 1]
        k = seg_k[s]
        reset = np.isnan(seg_t0[s])
        t_prev = 0.0 if reset else seg_t0[s]
        # one centrifuge for the block's lanes (a study's replicates share it): its specific
        # force is then computed once a step, for lane 0, and copied
        one_base = True
        for l in range(nact):
            b = b0 + l
            nis[l] = 0.0 if reset else seg_nis[b]
            bad[l] = 0.0
            for c in range(params.shape[2]):
                pb_l[l, c] = params[b, k, c]
                one_base = one_base and params[b, k, c] == params[b0, k, c]
            specific_force_into(t_prev, pb_l[l], fr_now[l])
        for l in range(L):
            b = b0 + l if l < nact else b0
            m_g[l] = params[b, k, P_G]
            m_wn[l] = params[b, k, P_OMEGA_N]
            m_wu[l] = params[b, k, P_OMEGA_U]
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
                    if l == 0 or not one_base:
                        specific_force_into(t_prev + 0.5 * h, pb_l[l], fr_mid[l])
                        specific_force_into(tm, pb_l[l], fr_now[l])
                    else:
                        for r in range(3):
                            fr_mid[l, r] = fr_mid[0, r]
                            fr_now[l, r] = fr_now[0, r]
                    for r in range(3):
                        fr3[l, 1, r] = fr_mid[l, r]
                        fr3[l, 2, r] = fr_now[l, r]
                # the RK4 map and its Jacobian for every lane at once (the filler lanes on lane 0's
                # inputs, so with lane 0's numbers)
                for l in range(L):
                    src = l if l < nact else 0
                    for q in range(3):
                        for r in range(3):
                            m_fr3[(q * 3 + r) * L + l] = fr3[src, q, r]
                    for r in range(3):
                        m_ang[r * L + l] = xl[nc + r, l]
                for kk in range(nc):
                    for l in range(L):
                        m_coef[est_idx[kk] * L + l] = xl[kk, l]
                rk4_jac_lanes(m_ang, m_coef, m_fr3, h, m_g, m_wn, m_wu, m_out, m_pa, m_pg, m_k, m_ka, m_kg, m_v,
                              m_sc0, m_sc, m_fr, m_w)
                for r in range(3):
                    for kk in range(npc - 3):
                        for l in range(L):
                            phi[r, kk, l] = m_pg[(r * N_GYRO + pg[kk]) * L + l]
                    for i in range(3):
                        for l in range(L):
                            phi[r, npc - 3 + i, l] = m_pa[(r * 3 + i) * L + l]
                    for l in range(L):
                        xl[nc + r, l] = m_out[r * L + l]
                for l in range(nact):
                    for r in range(3):
                        ang_l[l, r] = xl[nc + r, l]
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
            f3((L, 3)), np.zeros((L, 3, MEAS_COLS.shape[1])), f3((L, 3, 3)),
            f3((3, 3)), f3((3, 3)), f3(3), f3(3), f3(L), f3(3), f3((L, n)), f3(n), f3(nco),
            f3(nco * L), f3(3 * L), f3(9 * L), f3(L), f3(L), f3(L), f3(3 * L), f3(9 * L), f3(3 * N_GYRO * L),
            f3(12 * L), f3(36 * L), f3(3 * N_GYRO * L), f3(42 * L), f3(6 * L), f3(6 * L), f3(3 * L), f3(40 * L))


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
    with slp_vectorize(loop_vectorize=False):
        if nblk == 1 or numba.get_num_threads() == 1:
            # block by block from here, the block kernel called directly: a compiled caller (a
            # serial loop, or a function allocating the scratch) links and optimises the block
            # kernel's whole module again (3.7 s of a cold compile) to save a few us per block
            for blk in range(nblk):
                _filter_block(blk, *args, *_block_scratch(*sizes))
        else:
            _run_blocks(nblk, sizes, *args)
