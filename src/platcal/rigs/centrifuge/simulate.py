"""Truth simulation of a centrifuge test (docs/centrifuge-model.md §8), batched over replicates.

At the start of each position the platform is set to the commanded angles plus a white
setting error (sigma_set per angle); the attitude ODE (eq. 18) is integrated with RK4 at the
sample period (5 ms); accelerometer outputs (eq. 13) are sampled at ``t = 0, dt, ...,
dwell - dt`` with white noise sigma_a; the gyro rate noise enters as an angle random walk.

Randomness: each replicate has its own ``SeedSequence``, spawned into three independent
streams (setting errors, accelerometer noise, gyro noise) that are drawn position by
position, so a replicate's numbers do not depend on the batch it runs in.

Speed: replicates run in parallel numba threads (:mod:`platcal.parallel`), each with the same
sequential kernel; the centrifuge's specific force is tabulated once per position for all
replicates that share it; one set of sin/cos per sample serves the measurement and the RK4
step (the stages move the angles by ~1e-9 rad, handled by exact-to-rounding Taylor shifts).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ...aot import pick as aot_pick
from ...jit import njit, parallel_chunksize, prange
from ...model.frames import ARCSEC, DEG
from ...model.instruments import N_FULL
from ...parallel import get_threads
from ...scheme import Scheme, whole_periods
from .aot_kernels import KERNELS
from .attitude import P_G, measure_scalar, rk4_scalar_sc
from .base import broadcast_params


@dataclass(frozen=True)
class Noise:
    """Truth noise levels: sigma_a (ug per sample), ARW (deg/sqrt(h)), sigma_set (arcsec)."""

    sigma_a_ug: float = 10.0
    arw_deg_rth: float = 0.001
    sigma_set_arcsec: float = 10.0

    @property
    def is_zero(self) -> bool:
        return self.sigma_a_ug == 0 and self.arw_deg_rth == 0 and self.sigma_set_arcsec == 0


@dataclass
class SimResult:
    """Simulated test data for B replicates of one scheme.

    ``A`` and ``angles`` are (B, K, N, 3): outputs in g and true angles in rad at the kept
    sample times ``t`` (N,) s; ``set_error`` (B, K, 3) is the setting error in rad.
    """

    A: np.ndarray
    angles: np.ndarray
    t: np.ndarray
    set_error: np.ndarray


@njit(parallel=True, cache=True)
def _simulate_position(theta0, coef, n, dt, params, fr_tab, tab_of, acc_noise, acc_sd, arw, arw_sd, keep,
                       out_a, out_ang, i0, n_total):
    """Integrate every replicate of the batch through one position (see :func:`_simulate_one`).

    ``fr_tab`` (U, n, 3, 3) tabulates the base specific force per distinct parameter row;
    replicate b uses ``fr_tab[tab_of[b]]``. ``i0``, ``n_total``: the chunk's first sample and the
    position's samples (a position simulated in chunks, :func:`simulate_chunks`); ``theta0`` ends
    holding the angles at sample ``i0 + n``, where the next chunk starts.
    """
    B = theta0.shape[0]
    for b in prange(B):
        _simulate_one(theta0[b], coef[b], n, dt, params[b], fr_tab[tab_of[b]], acc_noise, acc_sd, arw,
                      arw_sd, b, keep, out_a[b], out_ang[b], i0, n_total)


@njit(cache=True)
def _simulate_position_serial(theta0, coef, n, dt, params, fr_tab, tab_of, acc_noise, acc_sd, arw, arw_sd,
                              keep, out_a, out_ang, i0, n_total):
    """:func:`_simulate_position` without threads (a batch of one, or one thread): same kernel,
    no parallel region to start and join."""
    for b in range(theta0.shape[0]):
        _simulate_one(theta0[b], coef[b], n, dt, params[b], fr_tab[tab_of[b]], acc_noise, acc_sd, arw,
                      arw_sd, b, keep, out_a[b], out_ang[b], i0, n_total)


# error_model="numpy": no zero-divisor test (and exception exit) at each division of the inlined
# model (g, cos beta: never zero here); without those exits numba prunes the reference counts of
# the arrays the model reads, which cost a third of the kernel (issue 22). Same IEEE arithmetic.
@njit(cache=True, error_model="numpy")
def _simulate_one(theta0, coef, n, dt, params, fr_tab, acc_noise, acc_sd, arw, arw_sd, b, keep, out_a, out_ang,
                  i0, n_total):
    """One replicate: RK4 of eq. 18 over the ``n`` samples ``i0 .. i0 + n - 1`` (of ``n_total``
    in the position) of ``dt`` s from ``theta0`` (rad, the angles at sample ``i0``; left holding
    those at sample ``i0 + n``), keeping the outputs of the samples that are multiples of
    ``keep``. ``fr_tab[i, s]`` is the base specific force (m/s^2) at the chunk's sample i's
    start, middle and end (s = 0, 1, 2). Noise arrays are (B, n, 3) standard normal draws, or
    (B, 0, 3) for none, scaled here by ``acc_sd`` (ug, then to g) and ``arw_sd`` (rad per step)."""
    g = params[P_G]
    ang = theta0.copy()
    new = np.empty(3)
    noisy_a = acc_noise.shape[1] > 0
    noisy_g = arw.shape[1] > 0
    fr3 = np.empty((3, 3))
    j0 = (i0 + keep - 1) // keep  # the first kept sample's slot in the position
    for i in range(n):
        # one set of sin/cos per sample serves the measurement and the RK4 step
        sa, ca = np.sin(ang[0]), np.cos(ang[0])
        sb, cb = np.sin(ang[1]), np.cos(ang[1])
        sg, cg = np.sin(ang[2]), np.cos(ang[2])
        # the sample's forces copied, not viewed: a view per sample costs two atomic
        # reference-count updates, more than the copy (issue 22)
        for s in range(3):
            for c in range(3):
                fr3[s, c] = fr_tab[i, s, c]
        if (i0 + i) % keep == 0:
            j = (i0 + i) // keep - j0
            m0, m1, m2 = measure_scalar(sa, ca, sb, cb, sg, cg, coef, fr3[0, 0], fr3[0, 1], fr3[0, 2], g)
            # scaled as the draws are used (x sigma, then ug -> g), not in passes over the
            # buffers, most of whose accelerometer draws are not kept
            out_a[j, 0] = m0 + (acc_noise[b, i, 0] * acc_sd * 1e-6 if noisy_a else 0.0)
            out_a[j, 1] = m1 + (acc_noise[b, i, 1] * acc_sd * 1e-6 if noisy_a else 0.0)
            out_a[j, 2] = m2 + (acc_noise[b, i, 2] * acc_sd * 1e-6 if noisy_a else 0.0)
            for r in range(3):
                out_ang[j, r] = ang[r]
        if i0 + i < n_total - 1:
            rk4_scalar_sc(sa, ca, sb, cb, sg, cg, ang, coef, fr3, dt, params, new)
            for r in range(3):
                ang[r] = new[r] + (arw[b, i, r] * arw_sd if noisy_g else 0.0)
    for r in range(3):
        theta0[r] = ang[r]


def _force_tables(params: np.ndarray, n: int, dt: float, i0: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Base specific force (eq. 10, m/s^2) at the start, middle and end of samples ``i0 .. i0 +
    n - 1``, per distinct row of ``params`` (B, 5): ``(tables (U, n, 3, 3), index (B,) of each
    replicate's table)``.

    Replicates normally share the centrifuge, so this is computed once, not B times; the times
    are formed exactly as the step's stage times ``t, t + dt/2, t + dt`` with ``t = i dt``.
    """
    uniq, tab_of = np.unique(params, axis=0, return_inverse=True)
    t0 = np.arange(i0, i0 + n) * dt
    times = np.stack([t0, t0 + 0.5 * dt, t0 + dt], axis=1)  # (n, 3)
    out = np.empty((uniq.shape[0], n, 3, 3))
    for u, p in enumerate(uniq):
        wc, ro, g, wn, wu = p
        amp = wc * wc * ro + 2.0 * wc * ro * wu
        ph = wc * times
        c, s = np.cos(ph), np.sin(ph)
        out[u, :, :, 0] = -amp * c
        out[u, :, :, 1] = -amp * s
        out[u, :, :, 2] = 2.0 * wc * ro * wn * s + g
    return out, np.ascontiguousarray(tab_of.reshape(-1), dtype=np.int64)


def replicate_streams(seeds: list[np.random.SeedSequence]) -> list[tuple[np.random.Generator, ...]]:
    """Three generators (setting error, accelerometer noise, gyro noise) per replicate."""
    return [tuple(np.random.default_rng(s) for s in ss.spawn(3)) for ss in seeds]


def simulate(
    truth: np.ndarray,
    scheme: Scheme,
    centrifuge_params: np.ndarray,
    noise: Noise,
    seeds: list[np.random.SeedSequence] | None,
    *,
    sample_s: float = 0.005,
    keep_every: int = 1,
) -> SimResult:
    """Simulate B replicates of a scheme.

    Parameters
    ----------
    truth : (B, 48) or (48,) true full coefficient vectors (engineering units).
    scheme : the positions and dwell.
    centrifuge_params : (5,), (K, 5) or (B, K, 5) packed centrifuge parameters
        (``Centrifuge.params()``, or ``Centrifuge.scheme_params`` for a multi-g-level scheme).
    noise : truth noise levels; ignored when ``seeds`` is None (noise-free run).
    seeds : one SeedSequence per replicate, or None for a noise-free run.
    sample_s : sample period, s (5 ms).
    keep_every : keep one sample in this many (the filter's period / sample period);
        the noise streams are the same whatever this is.

    The whole of :func:`simulate_chunks` (each position one chunk) in arrays.
    """
    parts = list(simulate_chunks(truth, scheme, centrifuge_params, noise, seeds, sample_s=sample_s,
                                 keep_every=keep_every))
    K = scheme.n_positions
    B = parts[0].A.shape[0]
    nk = sum(p.A.shape[1] for p in parts if p.position == 0)
    A = np.empty((B, K, nk, 3))
    ang = np.empty((B, K, nk, 3))
    for p in parts:
        A[:, p.position, p.j0:p.j0 + p.A.shape[1]] = p.A
        ang[:, p.position, p.j0:p.j0 + p.A.shape[1]] = p.angles
    n = whole_periods(scheme.dwell_s, sample_s, f"schemes.{scheme.name}.dwell_s")
    t = np.arange(0, n, keep_every) * sample_s
    return SimResult(A=A, angles=ang, t=t, set_error=parts[0].set_error)


@dataclass
class SimChunk:
    """Samples ``i0 .. i0 + n - 1`` of one position of a simulation (:func:`simulate_chunks`):
    ``A`` and ``angles`` (B, m, 3) in g and rad at the kept samples (slots ``j0 .. j0 + m - 1``
    of the position), their times ``t`` (m,) s since the position's start, and the setting
    errors (B, K, 3) rad of the whole run."""

    position: int
    j0: int
    A: np.ndarray
    angles: np.ndarray
    t: np.ndarray
    set_error: np.ndarray


def simulate_chunks(truth: np.ndarray, scheme: Scheme, centrifuge_params: np.ndarray, noise: Noise,
                    seeds: list[np.random.SeedSequence] | None, *, sample_s: float = 0.005, keep_every: int = 1,
                    chunk_samples: int | None = None, positions=None) -> Iterator[SimChunk]:
    """:func:`simulate` position by position, each in chunks of at most ``chunk_samples`` samples
    (None: a position at a time), so a long test is written without being held: the noise of a
    chunk is drawn from the replicate's streams where the previous chunk stopped and the attitude
    carries over, so the numbers are those of :func:`simulate` whatever the chunk size
    (docs/centrifuge-model.md §8). Arguments as :func:`simulate`; ``positions`` (0-based, a
    noise-free run only, whose positions are independent): only those positions."""
    if positions is not None and seeds is not None:
        raise ValueError("positions: a noisy run draws its noise position after position; simulate them all")
    truth = np.atleast_2d(np.asarray(truth, float))
    B = truth.shape[0] if seeds is None else len(seeds)
    if truth.shape[0] == 1 and B > 1:
        truth = np.repeat(truth, B, axis=0)
    if truth.shape != (B, N_FULL):
        raise ValueError(f"truth must be (B, {N_FULL}), got {truth.shape}")
    K = scheme.n_positions
    n = whole_periods(scheme.dwell_s, sample_s, f"schemes.{scheme.name}.dwell_s")
    step = n if chunk_samples is None else max(1, int(chunk_samples))
    cmd = scheme.angles_deg * DEG
    params = broadcast_params(centrifuge_params, B, K)
    streams = replicate_streams(seeds) if seeds is not None else None
    set_err = np.zeros((B, K, 3))
    if streams is not None and noise.sigma_set_arcsec > 0:
        for b, (g_set, _, _) in enumerate(streams):
            set_err[b] = g_set.standard_normal((K, 3)) * noise.sigma_set_arcsec * ARCSEC
    arw_step = noise.arw_deg_rth * DEG / 60.0 * np.sqrt(sample_s)  # rad per step
    kernel = aot_pick(KERNELS, "simulate_position_serial", _simulate_position_serial, _simulate_position, B)
    use_acc = streams is not None and noise.sigma_a_ug > 0
    use_arw = streams is not None and arw_step > 0
    n_workers = 1 if B == 1 else min(B, get_threads())  # B = 1 asks no thread count: numba stays unloaded
    pool = ThreadPoolExecutor(n_workers) if n_workers > 1 and (use_acc or use_arw) else None
    # noise buffers for the largest chunk, reused by every chunk (no fresh pages per chunk)
    acc_buf = np.empty(B * min(step, n) * 3 if use_acc else 0)
    arw_buf = np.empty(B * min(step, n) * 3 if use_arw else 0)
    try:
        for k in range(K) if positions is None else positions:
            theta0 = np.ascontiguousarray(cmd[k][None, :] + set_err[:, k])
            pk = np.ascontiguousarray(params[:, k])
            for i0 in range(0, n, step):
                m = min(step, n - i0)
                # the chunk's noise buffers (C-contiguous views of the reused ones), filled in place
                # by each replicate's stream
                acc = acc_buf[:B * m * 3].reshape(B, m if use_acc else 0, 3)
                arw = arw_buf[:B * m * 3].reshape(B, m if use_arw else 0, 3)

                def draw(b: int) -> None:
                    # numpy releases the GIL while filling, so replicates draw in parallel threads; each
                    # replicate has its own generators, so the numbers do not depend on the threading
                    # (nor on the chunks: a stream drawn in pieces gives the numbers drawn at once)
                    if use_acc:
                        streams[b][1].standard_normal(out=acc[b])
                    if use_arw:
                        streams[b][2].standard_normal(out=arw[b])

                if use_acc or use_arw:
                    if pool is None:
                        for b in range(B):
                            draw(b)
                    else:
                        list(pool.map(draw, range(B)))
                j0 = (i0 + keep_every - 1) // keep_every
                kept = np.arange(j0 * keep_every, i0 + m, keep_every)
                A = np.empty((B, kept.size, 3))
                ang = np.empty((B, kept.size, 3))
                fr_tab, tab_of = _force_tables(pk, m, sample_s, i0)
                with parallel_chunksize(1):  # dynamic: balances threads slowed by other load
                    kernel(theta0, truth, m, sample_s, pk, fr_tab, tab_of, acc, float(noise.sigma_a_ug), arw,
                           float(arw_step), keep_every, A, ang, i0, n)
                yield SimChunk(position=k, j0=j0, A=A, angles=ang, t=kept * sample_s, set_error=set_err)
    finally:
        if pool is not None:
            pool.shutdown()
