"""Truth simulator and the 27-state EKF, batched over replicates (docs/multiposition-1g.md §9, §12).

**Simulator** (§12): per position phi(0) ~ N(0, sigma_set^2) per angle; RK4 of §4 at ts
(``n_sub`` substeps) with the gyro white rate held constant over each sample step
(N(0, ARW^2/ts)); ``z = h(x) + v`` at t = 0, ts, ..., dwell.

**Seeds** (docs/multiposition-1g.md §14, §16): each replicate draws from its own
``numpy.random.SeedSequence``, in §14's order of use: all setting errors, then all ARW, then all
sensor noise, from one ``default_rng`` of that sequence. Replicate r of scheme S at
accelerometer noise sigma_a is ``SeedSequence(seed, spawn_key=(stable_key(S), round(1000 sigma_a),
r))`` (:func:`replicate_seeds`, the generic runner's
:func:`platcal.study.sweep.replicate_seed`; ``seed`` is the config's root ``seed``), so a
replicate's numbers do not depend on the batch it runs in, the thread count or the job order,
and ``platcal simulate --seed r`` draws replicate r of the study's cell of that scheme and noise.

**EKF** (§9): state propagated by RK4 of §4 over each sample interval, ``Phi = I + F dt +
F^2 dt^2/2`` with F analytic (:func:`model.rate_k`; the spec allows central differences for the
angle columns, analytic ones are exact and checked against differences in the tests),
``Q = T T^T ARW^2 dt`` on phi. The 6-D update is done as two 3-D Joseph updates with the
centrifuge's :func:`platcal.kalman.joseph_update_sparse`: first the accelerometers (H and the
innovation at the prior), then the angle sensors, whose measurement is linear, with the innovation
recomputed from the updated state (wrapped to +-180 deg). With R diagonal this equals the one
6-D update exactly. At each position phi is reset to 0 with variance sigma_set^2 and no cross
covariance; ``passes`` restart from the previous estimate with P0 = 100 x its coefficient
covariance. Replicates run in blocks of :data:`platcal.estimation.lanes.LANES` with the replicates
in SIMD lanes (:func:`.filter_lanes._ekf_block`: P packed, every covariance operation one vector instruction over
the block; issue 22 item 2), the same operations in the same order as the one-replicate reference
kernel :func:`_ekf_one`, so the numbers are its numbers bit for bit and a replicate's numbers do not
depend on its lane, the batch or the thread count; blocks run in ``nogil`` compiled loops on a
thread pool (see :func:`platcal.parallel.run_threaded`).

**Covariance-only** (§8, §14): the same kernel with ``update_x = False`` started at the truth:
the state then follows the noise-free truth trajectory and F, H are evaluated on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...estimation.iterated import gauss_newton_point, make_iterated_scratch
from ...estimation.kalman import joseph_update_sparse, propagate_sparse, update_scratch
from ...jit import njit
from ...model.frames import ARCSEC, DEG
from ...parallel import run_threaded
from ...rig import resolve
from ...study.sweep import replicate_seed
from .aot_kernels import one_replicate
from .model import gyro_coefs, layout_index, make_scratch, meas_k, rate_k, rk4_k, rk4_s

EKF_LANES = f"{__package__}.filter_lanes:ekf_lanes"
"""The JIT's pass of a batch, replicates in SIMD lanes (:func:`.filter_lanes.ekf_lanes`), by path:
its module imports numba, which an identify on kernels compiled ahead of time does not load."""


# ------------------------------------------------------------------ simulator

@njit(cache=True)
def _simulate_one(phi0s, coef, lay, wn, wu, h, n_sub, phi_init, wnoise, out_phi, out_z):
    K = phi0s.shape[0]
    ns = out_phi.shape[1]
    n = 3 + coef.shape[0]
    C, dC, T, dT, f, eps, deps, greg = make_scratch(n)
    x = np.empty(n)
    # element copies, not slice assignments: a slice assignment brings numba's shape-mismatch
    # error (its message formatting: str, repr, unicode) into the kernel, about 5 s of CPU of
    # cold compile per study for the same copies (issue 22 item 4)
    for i in range(n - 3):
        x[3 + i] = coef[i]
    nxt = np.empty(3)
    z = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.empty((3, 10), dtype=np.int64)
    nn = np.empty(3, dtype=np.int64)
    for k in range(K):
        for i in range(3):
            x[i] = phi_init[k, i]
        for s in range(ns):
            if s > 0:
                for _ in range(n_sub):
                    rk4_k(phi0s[k], x, lay, wn, wu, wnoise[k, s - 1], h / n_sub, nxt)
                    for i in range(3):
                        x[i] = nxt[i]
            for i in range(3):
                out_phi[k, s, i] = x[i]
            meas_k(phi0s[k], x, lay, z, Hs, hc, nn, C, dC)
            for i in range(6):
                out_z[k, s, i] = z[i]


@njit(cache=True, nogil=True)
def _simulate_range(lo, hi, phi0s, coef, lay, wn, wu, h, n_sub, init, w, phi, z):
    for r in range(lo, hi):
        _simulate_one(phi0s, coef, lay, wn, wu, h, n_sub, init[r], w[r], phi[r], z[r])


def replicate_seeds(cfg, scheme_name: str, replicates) -> list[np.random.SeedSequence]:
    """The SeedSequences of replicates ``replicates`` (ints >= 0) of the Monte Carlo cell of
    scheme ``scheme_name`` at the config's accelerometer noise ``cfg.sigma_a_ug``, under the
    config's root ``seed`` (:func:`platcal.study.sweep.replicate_seed`)."""
    return [replicate_seed(cfg.seed, scheme_name, cfg.sigma_a_ug, int(r)) for r in replicates]


def draw_noise(cfg, seeds, K: int, ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random inputs of each replicate (§12, §14 order of use): setting errors phi(0) (R, K, 3)
    rad, ARW rates (R, K, ns - 1, 3) rad/s held over each sample step, sensor noise (R, K, ns, 6)
    ug / arcsec. Replicate r draws only from ``default_rng(seeds[r])``."""
    R = len(seeds)
    sig = np.array([cfg.sigma_a_ug] * 3 + [cfg.sigma_an_arcsec] * 3)
    init = np.empty((R, K, 3))
    w = np.empty((R, K, ns - 1, 3))
    v = np.empty((R, K, ns, 6))
    for r, ss in enumerate(seeds):
        rng = np.random.default_rng(ss)
        init[r] = rng.standard_normal((K, 3)) * cfg.sigma_set_rad
        w[r] = rng.standard_normal((K, ns - 1, 3)) * (cfg.arw_rad / math.sqrt(cfg.ts))
        v[r] = rng.standard_normal((K, ns, 6)) * sig
    return init, w, v


def simulate(cfg, scheme, seeds, noise_free: bool = False, ext: int = 0, truth=None, threads: int | None = None):
    """Simulate replicates of ``scheme`` (§12), one per entry of ``seeds``.

    ``seeds``: ``numpy.random.SeedSequence`` objects (the generic Monte Carlo runner's), or
    replicate numbers (ints >= 0): r stands for replicate r of the study's cell of this scheme
    at the config's ``sigma_a_ug`` (:func:`replicate_seeds`). Ignored when ``noise_free``.
    Returns ``(t (n,), phi (R, K, n, 3) rad, z (R, K, n, 6) ug / arcsec)``; z includes noise.
    Raises InputError if beta leaves the gimbal range (+ margin) during a dwell (§3).
    """
    t, phi0s, coef, lay, wn, wu = _sim_setup(cfg, scheme.dwell_s, scheme.angles_deg, ext, truth)
    ns, K = t.size, phi0s.shape[0]
    R = len(seeds)
    phi = np.empty((R, K, ns, 3))
    z = np.empty((R, K, ns, 6))
    if noise_free:
        init, w, v = np.zeros((R, K, 3)), np.zeros((R, K, ns - 1, 3)), np.zeros((R, K, ns, 6))
    else:
        init, w, v = draw_noise(cfg, _seed_sequences(cfg, scheme, seeds), K, ns)
    run_threaded(_simulate_range, R, threads, phi0s, coef, lay, wn, wu, cfg.ts, cfg.n_sub, init, w, phi, z)
    z += v
    _check_gimbal(cfg, scheme, phi0s, phi)
    return t, phi, z


def _sim_setup(cfg, dwell_s: float, angles_deg: np.ndarray, ext: int, truth):
    """``(t (n,) s, commanded angles (K, 3) rad, coefficients, layout, site rates)`` of a simulation
    (§12) of positions ``angles_deg`` (K, 3) deg dwelling ``dwell_s`` s each."""
    t = np.arange(int(round(dwell_s / cfg.ts)) + 1) * cfg.ts
    coef = cfg.truth(ext) if truth is None else np.asarray(truth, float)
    wn, wu = cfg.site.params()
    return t, angles_deg * DEG, coef, layout_index(ext), wn, wu


def _seed_sequences(cfg, scheme, seeds) -> list:
    """``seeds`` as SeedSequences (a replicate number r: replicate r of the study's cell, :func:`replicate_seeds`)."""
    return [s if isinstance(s, np.random.SeedSequence) else replicate_seeds(cfg, scheme.name, [s])[0] for s in seeds]


def _check_gimbal(cfg, scheme, phi0s, phi, first: int = 0) -> None:
    """InputError naming the scheme's position when beta (commanded ``phi0s`` (K, 3) rad plus the
    simulated ``phi`` (R, K, n, 3) rad) leaves the gimbal range during a dwell (docs/multiposition-1g.md
    §3); ``first``:
    the 0-based scheme position of ``phi0s[0]``."""
    beta = np.abs(phi0s[None, :, None, 1] + phi[..., 1]) / DEG
    lim = cfg.beta_max_deg + cfg.beta_margin_deg
    if np.any(beta > lim):
        k = first + int(np.argwhere(beta > lim)[0][1]) + 1
        raise InputError(f"schemes.{scheme.name}.positions[{k}]",
                         f"beta leaves the gimbal range {lim:g} deg during the dwell (§3)")


NORMAL_BLOCK = 1 << 16
"""Normal draws skipped at a time when :func:`simulate_positions` moves a stream past the draws of
the other positions (0.5 MB: the skip of a long record's ARW draws is then no peak of its own)."""

SIM_BLOCK = 1 << 12
"""Samples of a position :func:`simulate_positions` holds at a time (docs/multiposition-1g.md §12):
its phi, z and noise draws and the record rows formatted from them (about 2 MB), the same whatever
the dwell, so a long record is simulated in bounded memory (peak RSS of ``simulate``,
``benchmarks/bench_memory.py``: 251, 259, 260, 262 MB at 1 min, 10 min, 1 h, 6 h; blocks of 16384
samples gave 273 MB at 1 h and 275 at 6 h, the CSV text of a block growing with it)."""


def simulate_positions(cfg, scheme, seed, noise_free: bool = False, block: int = SIM_BLOCK):
    """:func:`simulate` of one replicate (``seed``: a SeedSequence or replicate number), position by
    position in blocks of at most ``block`` samples: yields ``(k, t (m,) s, phi (m, 3) rad,
    z (m, 6) ug / arcsec)``, consecutive samples of position k = 0 .. K-1, with the numbers
    :func:`simulate` gives, holding one block (:func:`simulate_blocks`; docs/multiposition-1g.md
    §12). The draws are §14's order of use (:func:`draw_noise`: setting errors, then every
    position's ARW, then every position's sensor noise, from one stream): the sensor noise comes
    from a copy of the stream moved past all the ARW draws (drawn in blocks and dropped), and a
    Generator's draws in consecutive blocks are the draws of one call, so each block's ARW and
    noise are the rows of the whole draw. Raises InputError naming the position when beta leaves
    the gimbal range (+ margin) during its dwell (§3)."""
    t, phi0s, _, _, _, _ = _sim_setup(cfg, scheme.dwell_s, scheme.angles_deg, 0, None)
    ns, K = t.size, phi0s.shape[0]
    sig = np.array([cfg.sigma_a_ug] * 3 + [cfg.sigma_an_arcsec] * 3)
    if noise_free:
        init = np.zeros((K, 3))

        def noise(steps: int, samples: int):
            # z + 0.0, as the whole-position simulator always added: it writes -0.0 as 0.0
            return np.zeros((steps, 3)), 0.0
    else:
        rng_w = np.random.default_rng(_seed_sequences(cfg, scheme, [seed])[0])
        init = rng_w.standard_normal((K, 3)) * cfg.sigma_set_rad
        rng_v = np.random.Generator(type(rng_w.bit_generator)())
        rng_v.bit_generator.state = rng_w.bit_generator.state
        skip = K * (ns - 1) * 3
        while skip > 0:  # draws of a Generator in blocks are the draws of one call
            rng_v.standard_normal(min(skip, NORMAL_BLOCK))
            skip -= NORMAL_BLOCK

        def noise(steps: int, samples: int):
            return (rng_w.standard_normal((steps, 3)) * (cfg.arw_rad / math.sqrt(cfg.ts)),
                    rng_v.standard_normal((samples, 6)) * sig)
    for k in range(K):
        for j0, phi, z in simulate_blocks(cfg, scheme.angles_deg[k], scheme.dwell_s, block=block,
                                          phi_init=init[k], noise=noise):
            _check_gimbal(cfg, scheme, phi0s[k:k + 1], phi[None, None], k)
            yield k, t[j0:j0 + len(z)], phi, z


def simulate_blocks(cfg, cmd_deg, dwell_s: float, truth=None, block: int = 100_000, phi_init=None, noise=None):
    """The simulation (docs/multiposition-1g.md §12) of one position (commanded angles ``cmd_deg``
    (3,) deg, dwell ``dwell_s`` s, coefficients ``truth`` (default the config's), setting error
    ``phi_init`` (3,) rad, default 0) in blocks of at most ``block`` samples: yields
    ``(j0, phi (m, 3) rad, z (m, 6) ug / arcsec)``, samples j0 .. j0 + m - 1. ``noise(steps, m)``,
    when given, returns a block's ARW rates (steps, 3) rad/s, held over its sample steps in order,
    and the sensor noise added to its z ((m, 6) ug / arcsec, or a scalar); without, the
    simulation is noise-free. Each block starts from the attitude the previous one ended at (the
    state is phi and the constant coefficients, so the numbers are :func:`simulate`'s) and only
    one block is held."""
    t, phi0s, coef, lay, wn, wu = _sim_setup(cfg, dwell_s, np.asarray(cmd_deg, float).reshape(1, 3), 0, truth)
    ns = t.size
    phi_start = np.zeros((1, 1, 3)) if phi_init is None else np.array(phi_init, float).reshape(1, 1, 3)
    j0 = 0
    while j0 < ns:
        skip = 1 if j0 else 0  # a later block repeats the sample it starts from
        m = min(block, ns - j0) + skip
        if noise is None:
            w, v = np.zeros((m - 1, 3)), None
        else:
            w, v = noise(m - 1, m - skip)
        phi = np.empty((1, 1, m, 3))
        z = np.empty((1, 1, m, 6))
        # one replicate: the kernel compiled ahead of time when an identify enabled it (.aot_kernels)
        one_replicate("simulate_range", _simulate_range)(0, 1, phi0s, coef, lay, wn, wu, float(cfg.ts), int(cfg.n_sub),
                                                         phi_start, np.ascontiguousarray(w)[None, None], phi, z)
        phi_start = phi[:, :, -1].copy()
        zb = z[0, 0, skip:]
        if v is not None:
            zb += v
        yield j0, phi[0, 0, skip:], zb
        j0 += m - skip


# ------------------------------------------------------------------ EKF kernel

@njit(cache=True)
def resid6_k(ctx, x, z, res, hval, hcols, hnnz):
    """Residual ``z - h(x)`` of the 6-D measurement (§7; angles wrapped to +-180 deg) and its
    sparse Jacobian rows, in the form :func:`platcal.estimation.iterated.iterated_update_sparse`
    takes. ``ctx = (phi0, lay, zp, Hs, hc, nn, C, dC)`` (commanded angles, layout, scratch)."""
    phi0, lay, zp, Hs, hc, nn, C, dC = ctx
    meas_k(phi0, x, lay, zp, Hs, hc, nn, C, dC)
    for j in range(3):
        res[j] = z[j] - zp[j]
        hnnz[j] = nn[j]
        for t in range(nn[j]):
            hval[j, t] = Hs[j, t]
            hcols[j, t] = hc[j, t]
        d = z[3 + j] - zp[3 + j]
        res[3 + j] = (d + 648000.0) % 1296000.0 - 648000.0
        hval[3 + j, 0] = 1.0 / ARCSEC
        hcols[3 + j, 0] = j
        hnnz[3 + j] = 1


@njit(cache=True, inline="always")
def transition_rows(F, T, cols, dt, arw2, phi, q):
    """Phi's 3 phi rows at the dynamic columns ``cols``, ``phi (3, m) = (I + F dt + F^2 dt^2 / 2)``
    (F's nonzero columns are phi's and the gyro coefficients', so ``F^2`` needs F's phi columns
    only), and ``q (3, 3) = T T^T ARW^2 dt`` (rad^2), §9 of docs/multiposition-1g.md; ``dt`` s,
    ``arw2`` rad^2/s."""
    m = cols.shape[0]
    for r in range(3):
        for c in range(m):
            v = F[r, cols[c]] * dt
            v += 0.5 * dt * dt * (F[r, 0] * F[0, cols[c]] + F[r, 1] * F[1, cols[c]]
                                  + F[r, 2] * F[2, cols[c]])
            if cols[c] == r:
                v += 1.0
            phi[r, c] = v
    for r in range(3):
        for c in range(3):
            q[r, c] = arw2 * dt * (T[r, 0] * T[c, 0] + T[r, 1] * T[c, 1] + T[r, 2] * T[c, 2])


@njit(cache=True, error_model="numpy")  # numpy errors: no raise paths, see model.py's kernels
def _ekf_one(x, P, phi0s, tk, zk, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol, rec, s0=0):
    """One pass over K positions for one replicate; x (n,), P (n, n) updated in place. The
    reference kernel: a batch runs :func:`.filter_lanes._ekf_block` (the same numbers, replicates
    in lanes), one replicate runs this one (:func:`_ekf_pass`, the kernel compiled ahead of time);
    also the lanes' test oracle and the per-part profile (``benchmarks/profile_multiposition.py``).

    ``tk`` (K, m) sample times, ``zk`` (K, m, 6) outputs (ug, arcsec), ``nk`` (K,) samples used.
    ``iters`` 0: the EKF update (two 3-D Joseph updates); >= 1: the Gauss-Newton iterated update
    of the 6-D measurement with at most ``iters`` linearisations and step tolerance ``tol``
    (prior sigmas): :func:`platcal.estimation.iterated.gauss_newton_point` finds the last
    linearisation point, then the same two 3-D Joseph updates apply its Jacobian and innovation
    (``iters = 1`` is the EKF, bit for bit).
    ``s0`` 1: position 0 goes on from a previous call (a block of a position fed in blocks,
    :func:`run_filter_positions`): no reset at its start, and its instant 0 (the previous block's
    last, ``tk[0, 0]`` its time) is not updated again, the pass starts by propagating from it.
    ``rec`` (K, m, 12), when it is not empty, receives at each update the innovation of the six
    channels (ug, arcsec) and the diagonal of their predicted covariance S (NaN: update skipped).
    Returns the sum of squared standardised innovations (NIS), the number of updates and the
    number of measurement linearisations.
    """
    n = x.shape[0]
    K = phi0s.shape[0]
    C, dC, T, dT, f, eps, deps, greg = make_scratch(n)
    F = np.zeros((3, n))
    nxt = np.empty(3)
    dyn = np.arange(3)
    m = cols.shape[0]
    phi = np.empty((3, m))
    q = np.empty((3, 3))
    W = np.empty((3, n))
    blk = np.empty((3, 3))
    zp = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.empty((3, 10), dtype=np.int64)
    nn = np.empty(3, dtype=np.int64)
    ha = np.empty((3, 1))
    hca = np.empty((3, 1), dtype=np.int64)
    nna = np.ones(3, dtype=np.int64)
    for i in range(3):
        hca[i, 0] = i
        ha[i, 0] = 1.0 / ARCSEC
    U, Kg, D, S, Sinv, nu = update_scratch(3, n)
    innov = np.empty(3)
    ra = r_var[:3].copy()
    rn = r_var[3:].copy()
    zero3 = np.zeros(3)
    scr = make_iterated_scratch(n, 6, 10)
    nu6 = np.empty(6)
    nis = 0.0
    nup = 0
    nlin = 0
    nbad = 0
    keep = rec.shape[0] > 0
    for k in range(K):
        first = s0 if k == 0 else 0
        if first == 0:
            x[:3] = 0.0
            for i in range(3):
                for j in range(n):
                    P[i, j] = 0.0
                    P[j, i] = 0.0
                P[i, i] = set_var
        ctx = (phi0s[k], lay, zp, Hs, hc, nn, C, dC)
        for s in range(first, nk[k]):
            if s > 0:
                dt = tk[k, s] - tk[k, s - 1]
                rate_k(phi0s[k], x, lay, wn, wu, zero3, nxt, F, True, C, dC, T, dT, f, eps, deps, greg)
                transition_rows(F, T, cols, dt, arw2, phi, q)
                propagate_sparse(P, dyn, cols, phi, q, W, blk)
                # RK4 from the rate at x (its first stage), without noise
                g0, g1, g2, on = gyro_coefs(x, lay)
                x[0], x[1], x[2] = rk4_s(phi0s[k, 0], phi0s[k, 1], phi0s[k, 2], x[0], x[1], x[2], g0, g1, g2, on,
                                         wn, wu, 0.0, 0.0, 0.0, dt, nxt[0], nxt[1], nxt[2])
            gained = False
            if iters > 0:
                # the Gauss-Newton linearisation point of the 6-D update; the update itself is
                # then the EKF's two 3-D Joseph updates with that point's accelerometer rows and
                # innovation (R diagonal and the angle rows linear: equal to the 6-D update)
                used, gained = gauss_newton_point(x, P, zk[k, s], r_var, resid6_k, ctx, iters, tol, scr, nu6)
                if used == 0:
                    continue
                nlin += used
                hv6, hc6, nn6, in6 = scr[5], scr[6], scr[7], scr[4]
                for j in range(3):
                    nn[j] = nn6[j]
                    innov[j] = in6[j]
                    for t in range(nn6[j]):
                        Hs[j, t] = hv6[j, t]
                        hc[j, t] = hc6[j, t]
            else:
                meas_k(phi0s[k], x, lay, zp, Hs, hc, nn, C, dC)
                nlin += 1
                for i in range(3):
                    innov[i] = zk[k, s, i] - zp[i]
            ok = joseph_update_sparse(x, P, hc, nn, Hs, innov, ra, U, Kg, D, S, Sinv, nu, update_x)
            if ok:
                if not gained:
                    nis += nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]
                nup += 1
            else:
                nbad += 1
            if keep:
                for i in range(3):
                    rec[k, s, i] = innov[i]
                    rec[k, s, 6 + i] = S[i, i] if ok else np.nan
            for i in range(3):
                d = zk[k, s, 3 + i] - (phi0s[k, i] + x[i]) / ARCSEC
                innov[i] = (d + 648000.0) % 1296000.0 - 648000.0
            ok = joseph_update_sparse(x, P, hca, nna, ha, innov, rn, U, Kg, D, S, Sinv, nu, update_x)
            if ok:
                if not gained:
                    nis += nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]
            else:
                nbad += 1
            if keep:
                for i in range(3):
                    rec[k, s, 3 + i] = innov[i]
                    rec[k, s, 9 + i] = S[i, i] if ok else np.nan
            if gained:
                for i in range(6):
                    nis += nu6[i] * nu6[i]
    return nis, nup, nlin, nbad


@njit(cache=True, nogil=True, error_model="numpy")
def _ekf_range(lo, hi, X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol,
               nis, nlin, nbad, rec):
    for b in range(lo, hi):
        s, u, nl, nb = _ekf_one(X[b], Ps[b], phi0s, tk, Z[b], nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x,
                            iters, tol, rec[b] if rec.shape[0] > 0 else rec[0])
        nis[b] = s / max(u, 1) / 6.0
        nlin[b] += nl
        nbad[b] += nb  # updates skipped because S was not positive definite


@njit(cache=True, error_model="numpy")
def _ekf_pass_one(x, P, phi0s, tk, zk, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol, s0, sums,
                  rec):
    """:func:`_ekf_one` of one replicate (``s0`` as there), its returns added into ``sums`` (4,):
    the NIS sum, the updates, the linearisations and the skipped updates, as
    :func:`.filter_lanes.ekf_lanes` gives them per replicate. The kernel an identify runs
    (compiled ahead of time: :mod:`.aot_kernels`)."""
    s, u, nl, nb = _ekf_one(x, P, phi0s, tk, zk, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters, tol,
                            rec, s0)
    sums[0] += s
    sums[1] += u
    sums[2] += nl
    sums[3] += nb


def _ekf_pass(X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x=True, iters=0, tol=0.0,
              rec=None, threads=None, s0: int = 0, lanes: bool = False):
    """One pass (docs/multiposition-1g.md §9) of the batch ``X`` (R, n), ``Ps`` (R, n, n) in place;
    returns ``sums`` (R, 4) (:func:`.filter_lanes.ekf_lanes`: arguments and returns as there). One
    replicate runs :func:`_ekf_pass_one` (compiled ahead of time when an identify enabled it and it
    is built, :func:`.aot_kernels.one_replicate`), a batch the lanes kernel on the JIT; the same
    numbers bit for bit (``tests/multiposition/test_multiposition_lanes.py``). ``lanes``: one
    replicate in the lanes kernel too (a job whose cells compiled it then compiles no second EKF).
    ``s0`` (one replicate only, not with ``lanes``): see :func:`_ekf_one`."""
    R = X.shape[0]
    phi0s = np.ascontiguousarray(phi0s, dtype=float).reshape(-1, tk.shape[0], 3)
    if R > 1 or phi0s.shape[0] > 1 or lanes:
        if s0:
            raise ValueError("a pass fed in blocks (s0 = 1) runs one replicate")
        return resolve(EKF_LANES)(X, Ps, phi0s, tk, Z, nk, lay, wn, wu, r_var, arw2, set_var, cols, update_x, iters,
                                  tol, rec, threads)
    if Z.shape[:2] != (1, tk.shape[0]):  # the kernel does not check bounds
        raise ValueError(f"outputs {Z.shape} and times {tk.shape} do not match one replicate")
    sums = np.zeros((1, 4))
    rec = np.zeros((1, 0, 0, 12)) if rec is None else rec
    one_replicate("ekf_pass_one", _ekf_pass_one)(
        X[0], Ps[0], phi0s[0], np.ascontiguousarray(tk, dtype=float), Z[0], np.ascontiguousarray(nk, dtype=np.int64),
        lay, wn, wu, r_var, float(arw2), float(set_var), cols, bool(update_x), int(iters), float(tol), int(s0), sums[0],
        rec[0])
    return sums


def dynamic_cols(ext: int) -> np.ndarray:
    """State columns where the phi rows of Phi can be nonzero: phi and the gyro coefficients."""
    lay = layout_index(ext)
    gy = [3 + lay[m] + j for m in range(10) if lay[m] >= 0 for j in range(3)]
    return np.array([0, 1, 2] + sorted(gy), dtype=np.int64)


def run_filter(cfg, positions_deg, t, Z, nk=None, passes: int | None = None, ext: int = 0,
               threads: int | None = None, sigma_a_ug: float | None = None, iterations: int = 0,
               tolerance: float = 0.0, innovations: np.ndarray | None = None, prior_x=None, prior_P=None,
               lanes: bool = False, on_pass=None):
    """Identify the coefficients from outputs ``Z`` (R, K, n, 6) (ug, arcsec) at times ``t``.

    ``positions_deg`` (K, 3) commanded angles; ``t`` is (n,) shared by all positions, or (K, n)
    with ``nk`` (K,) samples used per position (records of unequal length). ``iterations`` 0: the
    EKF of §9; >= 1: the iterated EKF (at most ``iterations`` linearisations per update, step
    tolerance ``tolerance`` prior sigmas; 1 = the EKF as one 6-D update). Returns ``(coef (R, nc),
    cov (R, nc, nc), mean NIS per measurement (R,), linearisations per update (R,), updates skipped
    because S was not positive definite (R,))`` (linearisations averaged over the passes, skipped
    updates summed). Filter R uses the config's noise (``sigma_a_ug`` overrides). ``innovations``
    (R, K, n, 12), when given, receives the last pass's innovations and S diagonals
    (:func:`_ekf_one`; the fit check, issue 25). ``prior_x`` ((nc,) or (R, nc)) and ``prior_P``
    ((nc, nc) or (R, nc, nc)), engineering units: the start of the coefficient states (a previous
    test's posterior handed on); None: 0 and diag(P0^2) (§9). ``lanes``: one replicate on the batch
    kernel as well (:func:`_ekf_pass`; the same numbers). ``on_pass(p, result, innovations)``,
    when given, is called after each pass p = 1 .. passes - 1 with what a run of p passes returns
    (copies, bit for bit: pass p reads nothing of the passes after it) and a copy of
    ``innovations`` (None when not given): an estimator of fewer passes taken on the way
    (:mod:`platcal.estimation.passes`).
    """
    Z = np.ascontiguousarray(Z, dtype=float)
    R, K, ns, _ = Z.shape
    tk = np.broadcast_to(np.asarray(t, float), (K, ns)).copy()
    nk = np.full(K, ns, dtype=np.int64) if nk is None else np.asarray(nk, dtype=np.int64)
    st = FilterStart.of(cfg, R, ext, sigma_a_ug, prior_x, prior_P)
    X, Ps = st.X, st.Ps
    phi0s = np.asarray(positions_deg, float).reshape(-1, 3) * DEG
    nis = np.empty(R)
    nlin = np.zeros(R)
    nbad = np.zeros(R, dtype=np.int64)
    npass = int(passes or cfg.passes)
    for p in range(npass):
        if p > 0:
            st.next_pass()
        # a batch in lanes, one replicate on the reference kernel: the same numbers bit for bit
        sums = _ekf_pass(X, Ps, phi0s, tk, Z, nk, st.lay, st.wn, st.wu, st.r_var, cfg.arw_rad**2,
                         cfg.sigma_set_rad**2, st.cols, True, iterations, tolerance, innovations, threads,
                         lanes=lanes)
        nis[:] = sums[:, 0] / np.maximum(sums[:, 1], 1) / 6.0
        nlin += sums[:, 2]
        nbad += sums[:, 3].astype(np.int64)
        if on_pass is not None and p + 1 < npass:
            on_pass(p + 1, _filter_result(X, Ps, nis, nlin, nbad, p + 1, nk),
                    None if innovations is None else innovations.copy())
    return _filter_result(X, Ps, nis, nlin, nbad, npass, nk)


def _filter_result(X, Ps, nis, nlin, nbad, npass: int, nk) -> tuple:
    """:func:`run_filter`'s return after ``npass`` passes, as copies of the running arrays."""
    return X[:, 3:].copy(), Ps[:, 3:, 3:].copy(), nis.copy(), nlin / (npass * int(nk.sum())), nbad.copy()


@dataclass
class FilterStart:
    """The EKF's start (docs/multiposition-1g.md §9) for R replicates: state X (R, n), covariance
    Ps (R, n, n) (coefficients at ``prior_x``/``prior_P`` or 0 and diag(P0^2)), the measurement
    variances ``r_var`` (6,) ug^2 and arcsec^2 and the model's layout, site rates and dynamic
    columns; shared by :func:`run_filter` (all positions at once) and :func:`run_filter_positions`
    (a streamed record, one position at a time)."""

    X: np.ndarray
    Ps: np.ndarray
    r_var: np.ndarray
    lay: np.ndarray
    wn: object
    wu: object
    cols: np.ndarray

    @classmethod
    def of(cls, cfg, R: int, ext: int = 0, sigma_a_ug: float | None = None, prior_x=None,
           prior_P=None) -> "FilterStart":
        p0 = cfg.p0(ext)
        n = p0.size + 3
        sa = cfg.sigma_a_ug if sigma_a_ug is None else sigma_a_ug
        r_var = np.array([sa**2] * 3 + [cfg.sigma_an_arcsec**2] * 3)
        if sa <= 0:
            r_var[:3] = 1e-6  # a noise-free record still needs R > 0: 0.001 ug, far below any signal
        X = np.zeros((R, n))
        Ps = np.zeros((R, n, n))
        Ps[:, 3:, 3:] = np.diag(p0**2)
        if prior_x is not None:
            X[:, 3:] = prior_x
        if prior_P is not None:
            Ps[:, 3:, 3:] = prior_P
        wn, wu = cfg.site.params()
        return cls(X, Ps, r_var, layout_index(ext), wn, wu, dynamic_cols(ext))

    def next_pass(self) -> None:
        """A later pass (§9): from the previous estimate with P0 = 100 x its coefficient covariance."""
        C = self.Ps[:, 3:, 3:].copy()
        self.Ps[:] = 0.0
        self.Ps[:, 3:, 3:] = 100.0 * C


def run_filter_positions(cfg, positions_deg, source, passes: int | None = None, iterations: int = 0,
                         tolerance: float = 0.0, on_innovations=None):
    """:func:`run_filter` (docs/multiposition-1g.md §9) of one record (R = 1) fed one position at a
    time and each position in blocks, so only one block of instants is held: ``source()`` is
    called once per pass and yields, per position in the order of ``positions_deg`` (K, 3) deg,
    an iterable of its blocks ``(t (m,) s, z (m, 6) ug, arcsec)`` in time order (the filter
    instants and outputs); ``on_innovations(k, rec)`` (last pass only) receives each block's
    innovations and S diagonals (m, 12) of position k (:func:`_ekf_one`). x and P carry from
    block to block and position to position exactly as in the whole record's kernel call (the
    same kernel, the same operations: a later block of a position starts from the previous
    block's last instant, ``s0 = 1``), so the estimate and covariance are bit-identical; the mean
    NIS is summed per block (equal to rounding). Returns run_filter's tuple for R = 1."""
    st = FilterStart.of(cfg, 1)
    phi0s = np.asarray(positions_deg, float).reshape(-1, 3) * DEG
    npass = int(passes or cfg.passes)
    args = (st.lay, st.wn, st.wu, st.r_var, cfg.arw_rad**2, cfg.sigma_set_rad**2, st.cols, True, iterations,
            tolerance)
    totals = np.zeros(4)  # over the passes: the linearisations and skipped updates
    count = 0
    for p in range(npass):
        if p > 0:
            st.next_pass()
        sums = np.zeros(4)
        last = p == npass - 1 and on_innovations is not None
        k = -1
        for k, blocks in enumerate(source()):
            if k >= phi0s.shape[0]:
                raise ValueError(f"the record's source gave more positions than {phi0s.shape[0]}")
            t_prev = None
            for t, z in blocks:
                m = t.size
                if m == 0:
                    continue
                s0 = 0 if t_prev is None else 1
                # a later block leads with the previous block's last instant: the kernel propagates from it
                tk = np.empty((1, m + s0))
                tk[0, s0:] = t
                zk = np.zeros((1, 1, m + s0, 6))
                zk[0, 0, s0:] = z
                if s0:
                    tk[0, 0] = t_prev
                rec = np.zeros((1, 1, m + s0, 12)) if last else None
                blk = _ekf_pass(st.X, st.Ps, phi0s[k:k + 1], tk, zk, np.array([m + s0], dtype=np.int64), *args,
                                rec=rec, s0=s0)[0]
                sums += blk
                count += m
                t_prev = float(t[-1])
                if last:
                    on_innovations(k, rec[0, 0, s0:])
        if k + 1 != phi0s.shape[0]:
            raise ValueError(f"the record's source gave {k + 1} positions, not {phi0s.shape[0]}")
        totals += sums
    return (st.X[:, 3:].copy(), st.Ps[:, 3:, 3:].copy(), np.array([sums[0] / max(sums[1], 1) / 6.0]),
            np.array([totals[2] / max(count, 1)]), np.array([int(totals[3])], dtype=np.int64))


def run_ekf(cfg, positions_deg, t, Z, nk=None, passes: int | None = None, ext: int = 0,
            threads: int | None = None, sigma_a_ug: float | None = None, lanes: bool = False):
    """The EKF of §9 (:func:`run_filter` with ``iterations = 0``): ``(coef, cov, mean NIS)``."""
    return run_filter(cfg, positions_deg, t, Z, nk, passes, ext, threads, sigma_a_ug, lanes=lanes)[:3]


def covariance_only(cfg, positions_deg, dwell_s: float, ext: int = 0, step_s: float | None = None,
                    truth=None, omega_on: bool = True, sequential: bool = True,
                    threads: int | None = None) -> np.ndarray:
    """Coefficient covariance of a covariance-only run (§8, §14): no data, Jacobians on the truth.

    Step ``step_s`` (default ``observability.cov_step_s`` = 0.1 s) with the sensor variances
    scaled by ``ts/step`` (same noise densities as the filter). ``positions_deg`` (K, 3), or
    (D, K, 3) for D schemes of K positions each (``sequential`` only: P (D, nc, nc), one lane
    of the lanes kernel per scheme, each bit for bit its own run; one scheme leaves 3 of a
    block's 4 lanes idle). ``sequential``: one run through all positions (P (nc, nc)); otherwise
    one run per position from P0, returning (K, nc, nc) (the per-position posteriors, for the
    information sums).
    """
    step = cfg.cov_step_s if step_s is None else float(step_s)
    ns = int(round(dwell_s / step)) + 1
    sets = np.asarray(positions_deg, float)
    if sets.ndim == 3:
        if not sequential:
            raise ValueError("schemes (D, K, 3) run sequentially only")
        phi0s = sets * DEG
        K = phi0s.shape[1]
    else:
        phi0s = sets.reshape(-1, 3) * DEG
        K = phi0s.shape[0]
    p0 = cfg.p0(ext)
    nc = p0.size
    coef = cfg.truth(ext) if truth is None else np.asarray(truth, float)
    scale = cfg.ts / step
    r_var = np.array([cfg.sigma_a_ug**2 * scale] * 3 + [cfg.sigma_an_arcsec**2 * scale] * 3)
    lay = layout_index(ext)
    wn, wu = cfg.site.params(omega_on)
    cols = dynamic_cols(ext)
    tk = np.tile(np.arange(ns) * step, (K, 1))
    nk = np.full(K, ns, dtype=np.int64)
    x0 = np.concatenate([np.zeros(3), coef])
    Pinit = np.zeros((nc + 3, nc + 3))
    Pinit[3:, 3:] = np.diag(p0**2)
    if sequential:
        D = phi0s.shape[0] if phi0s.ndim == 3 else 1
        X = np.repeat(x0[None], D, axis=0)
        Ps = np.repeat(Pinit[None], D, axis=0)
        resolve(EKF_LANES)(X, Ps, phi0s, tk, np.zeros((D, K, ns, 6)), nk, lay, wn, wu, r_var, cfg.arw_rad**2,
                           cfg.sigma_set_rad**2, cols, update_x=False)
        return Ps[:, 3:, 3:].copy() if phi0s.ndim == 3 else Ps[0, 3:, 3:]
    # one run per position: position k is batch entry k with its own commanded angles
    X = np.repeat(x0[None], K, axis=0)
    Ps = np.repeat(Pinit[None], K, axis=0)
    resolve(EKF_LANES)(X, Ps, phi0s[:, None], tk[:1], np.zeros((K, 1, ns, 6)), nk[:1], lay, wn, wu, r_var,
                       cfg.arw_rad**2, cfg.sigma_set_rad**2, cols, update_x=False, threads=threads)
    return Ps[:, 3:, 3:].copy()


def position_information(cfg, positions_deg, dwell_s: float, ext: int = 0, step_s: float | None = None,
                         omega_on: bool = True) -> np.ndarray:
    """Per-position Fisher information ``I_k = P_k^-1 - P0^-1`` (K, nc, nc), normalised by P0.

    Exact for the linearised model: the phi reset at each position makes the positions'
    information independent and additive (as the centrifuge's :mod:`platcal.observability`
    argues), so a scheme's covariance is ``(P0^-1 + sum_k I_k)^-1``.
    """
    p0 = cfg.p0(ext)
    Pk = covariance_only(cfg, positions_deg, dwell_s, ext, step_s, omega_on=omega_on, sequential=False)
    Pn = Pk / np.outer(p0, p0)
    return np.linalg.inv(Pn) - np.eye(p0.size)


def scheme_covariance_from_info(cfg, info: np.ndarray, ext: int = 0) -> np.ndarray:
    """Coefficient covariance (engineering units) from summed normalised information."""
    p0 = cfg.p0(ext)
    Pn = np.linalg.inv(np.eye(p0.size) + info)
    Pn = 0.5 * (Pn + Pn.T)
    return Pn * np.outer(p0, p0)


def nees(est: np.ndarray, cov: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``e^T P^-1 e`` over the coefficients (§14), per replicate."""
    e = est - truth
    return np.einsum("ri,ri->r", e, np.linalg.solve(cov, e[..., None])[..., 0])
