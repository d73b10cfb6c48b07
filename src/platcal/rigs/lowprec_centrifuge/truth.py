"""Truth simulator: drawn residuals, the independent INS simulation and the record
(docs/lowprec-centrifuge.md §4, §5, §8, §9, §12).

One call simulates one run of one platform for a batch of replicates (leading axis): the platform
INS navigated at ``profile.truth_steps`` RK4 steps per data sample through the centrifuge's true
motion (:mod:`.insim`: nonlinear mechanization, exact platform rotation, the accelerometer errors
and the gyro drift with its g-sensitive terms acting on the drifting platform), *not* the
filter's linear model. In lock-step, the four unit-coefficient variants of §8 (v1..v4: the same
INS with 1 ug/g kA_x, 1 ug/g^2 k2_x, 1 ug/g kA_y, 1 ug/g^2 k2_y alone; no other error, no noise)
give the responses S_k. The INS is not exactly linear in the coefficients (the transport-rate and
Coriolis terms of velocity errors of up to 20 m/s): ``floor=True`` also navigates each replicate
with its coefficients removed (the exact compensation, same draws and noise), and a calibration
c_hat is compensated about that floor, e_after = e_floor + sum_k (c - c_hat)_k S_k, whose error is
second order in the estimate's error (measured in the tests against re-navigation).

Seeding (§9, [D] §12): a replicate is one ``numpy.random.SeedSequence``, the generic runner's
(:func:`platcal.study.sweep.replicate_seed`); :func:`run_streams` derives from it, per
(platform, run), one stream for the error parameters (in this order: k0 x,y; scale x,y; gyro
drift x,y,z; tilt x,y; azimuth; then the gyros' g-sensitive terms DI, DO, DS and DIO, DIS, DOS,
each x,y,z) and one for the noise (accelerometer x,y; gyro x,y,z; velocity E,N; position E,N;
heading, each a full-length block in that order). A replicate's numbers do not depend on the
batch it runs in, and they are common across centrifuge scenarios (the scenarios share one seed
key, :mod:`.montecarlo`). Platform keys are 1-based positions in ``platforms``; run keys 1, 2, ...
for the proposed runs in config order and 0 for the traditional run.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ...model.instruments import INDEX, N_FULL
from ...records import CHUNK_ROWS
from .config import G0, Study
from .insim import W, FineTruth, LaneOutputs, _lanes_init, _navigate_block, quaternion_of, truth_table
from .profile import (Kinematics, Profile, build_profile, grid_gradient, kinematics, motion, profile_grid,
                      segments)

ARCSEC = np.pi / 180 / 3600
DEG_H = np.pi / 180 / 3600
"""1 deg/h in rad/s."""
TILT_SIGMA_ARCSEC = 5.0
"""Levelling residual of the alignment (§5), arcsec."""
VARIANTS = 4
G_TERMS = ("DI", "DO", "DS")
"""The gyros' drift terms linear in the specific force (deg/h/g; the paper's K a terms, §4)."""
GG_TERMS = ("DIO", "DIS", "DOS")
"""[D] Its product terms (deg/h/g^2; the paper's a_X a_Y, a_Z a_X: zero mean over a revolution).
The squared terms DII, DSS, DOO, not in the paper's model, are zero."""


@dataclass(frozen=True)
class Draws:
    """Drawn residuals per seed (§4, §5), shape (S, ...)."""

    k0_ug: np.ndarray         # (S, 2) accelerometer bias x, y, ug
    scale_ppm: np.ndarray     # (S, 2) scale-factor residual x, y, ppm
    drift_deg_h: np.ndarray   # (S, 3) gyro drift x, y, z, deg/h
    phi0_rad: np.ndarray      # (S, 3) initial attitude error x, y, z, rad
    gyro_g: np.ndarray        # (S, 18) DI, DO, DS (deg/h/g), DIO, DIS, DOS (deg/h/g^2), each x, y, z

    def gyro_coefficients(self, i: int) -> dict:
        """Replicate i's g-sensitive gyro terms by the shared model's names (``DI_x`` ...)."""
        return {f"{t}_{a}": float(v) for (t, a), v in
                zip(((t, a) for t in G_TERMS + GG_TERMS for a in "xyz"), self.gyro_g[i])}


@dataclass
class RunBatch:
    """One run of one platform simulated for a batch of seeds (+ the 4 variants of §8)."""

    platform: str
    run: str
    seeds: np.ndarray
    coeffs: np.ndarray        # (4,) true kA_x, k2_x, kA_y, k2_y
    prof: Profile
    kin: Kinematics
    draws: Draws
    err: np.ndarray           # (S, N, 4) true dVE, dVN, dpE, dpN
    phi: np.ndarray | None    # (S, N, 3) true attitude errors (when asked for)
    sens: np.ndarray | None   # (4, N, 4) unit-coefficient responses (v1..v4); None: not asked for
    v_ind: np.ndarray         # (S, N, 2) INS velocity output, m/s
    f_meas: np.ndarray        # (S, N, 2) measured horizontal specific force (accelerometer outputs), m/s^2
    p_ind: np.ndarray         # (S, N, 2) INS position output relative to the start, m
    psi: np.ndarray           # (S, N) heading output, rad (not wrapped)
    final_floor: np.ndarray | None = None  # (S, 4) end-of-run errors with the coefficients removed

    @property
    def final(self) -> np.ndarray:
        """(S, 4) errors at the end of the run (dVE, dVN, pE, pN) before compensation."""
        return self.err[:, -1, :]

    @property
    def sens_final(self) -> np.ndarray:
        """(4 coefficients, 4 errors) end-of-run sensitivities S_jk (§8)."""
        return self.sens[:, -1, :]


def run_streams(seed: np.random.SeedSequence, platform_key: int, run_key: int) -> tuple:
    """The (parameters, noise) SeedSequences of one (platform, run) of a replicate: children of the
    replicate's ``seed`` keyed by the platform and run keys (§9, [D] §12), built directly rather
    than by ``spawn`` so that they do not depend on what was spawned before."""
    base = tuple(seed.spawn_key) + (int(platform_key), int(run_key))
    return (np.random.SeedSequence(seed.entropy, spawn_key=base + (0,)),
            np.random.SeedSequence(seed.entropy, spawn_key=base + (1,)))


def draw_params(study: Study, rng: np.random.Generator) -> tuple:
    """(k0_ug(2), scale_ppm(2), drift_deg_h(3), phi0_rad(3), gyro_g(18)) drawn from ``rng``, the
    parameter stream of one (replicate, platform, run) (§4, §5, §9; the g-sensitive terms last, so
    the others are the draws of the former order)."""
    res = study.residuals
    k0 = rng.normal(0.0, res["k0_ug"], 2)
    sk = rng.normal(0.0, res["scale_ppm"], 2)
    eps = rng.normal(0.0, res["gyro_bias_deg_h"], 3)
    tilt = rng.normal(0.0, TILT_SIGMA_ARCSEC * ARCSEC, 2)
    az = rng.normal(0.0, res["azimuth_sigma_arcmin"] * 60 * ARCSEC)
    # levelled by the alignment: the tilt balances the bias (phi_y = k0x, phi_x = -k0y)
    phi0 = np.array([-k0[1] * 1e-6 + tilt[0], k0[0] * 1e-6 + tilt[1], az])
    gg = np.concatenate([rng.normal(0.0, res["gyro_g_deg_h_g"], 3 * len(G_TERMS)),
                         rng.normal(0.0, res["gyro_gg_deg_h_g2"], 3 * len(GG_TERMS))])
    return k0, sk, eps, phi0, gg


def gyro_vector(gyro_g: np.ndarray) -> np.ndarray:
    """The shared gyro model's (48,) coefficient vector (:mod:`platcal.model.instruments`) holding
    the g-sensitive terms ``gyro_g`` (18,), every other term 0 (the constant drift is separate)."""
    c = np.zeros(N_FULL)
    for k, (t, a) in enumerate((t, a) for t in G_TERMS + GG_TERMS for a in "xyz"):
        c[INDEX[f"{t}_{a}"]] = gyro_g[k]
    return c


def coeff_vector(study: Study, platform: str) -> np.ndarray:
    c = study.platforms[platform]
    return np.array([c["kA_x"], c["k2_x"], c["kA_y"], c["k2_y"]], dtype=float)


def fine_truth(study: Study, platform: str, run: str) -> tuple[Profile, Kinematics, FineTruth]:
    """The run's profile on the data grid, the true motion there and on the truth's fine grid (§2)."""
    steps = int(study.profile["truth_steps"])
    prof = build_profile(study, platform, run)
    fine = kinematics(build_profile(study, platform, run, 2 * steps), study.centrifuge, study.latitude_deg)
    return prof, fine.subsample(2 * steps), FineTruth(fine, steps, prof.dt, study.latitude_deg)


class TruthCache:
    """The true motions (:func:`fine_truth`) of the runs one Monte Carlo cell simulates (``runs``:
    (platform, run) pairs of ``study``), each distinct profile (its segments, §3: platforms with
    the same levels, every platform's traditional run) built once and dropped after the last run
    that uses it, so that no more than the runs still to come are held. The runs' batches share
    its arrays (read only). docs/lowprec-centrifuge.md §2, §12 (truth simulation)."""

    def __init__(self, study: Study, runs):
        self.study = study
        self.left: dict = {}
        for p, r in runs:
            key = tuple(segments(study, p, r))
            self.left[key] = self.left.get(key, 0) + 1
        self.built: dict = {}

    def take(self, platform: str, run: str) -> tuple[Profile, Kinematics, FineTruth]:
        """:func:`fine_truth` of one of the runs (built at its first use)."""
        key = tuple(segments(self.study, platform, run))
        got = self.built.pop(key, None) or fine_truth(self.study, platform, run)
        self.left[key] = self.left.get(key, 1) - 1
        if self.left[key] > 0:
            self.built[key] = got
        return got


def simulate_batch(study: Study, platform: str, run: str, seeds, replicates=None, keep_phi: bool = False,
                   noise_free: bool = False, floor: bool = False, sens: bool = True,
                   truths: TruthCache | None = None) -> RunBatch:
    """Simulate ``run`` of ``platform`` for every replicate SeedSequence of ``seeds`` (§2-§5, §8, §9);
    ``replicates``: their numbers (``RunBatch.seeds``; 0, 1, ... by default).

    ``noise_free``: no drawn residual and no noise (truth coefficients only). ``floor``: also the
    end-of-run errors of the same INS (draws, noise) with its coefficients removed
    (``RunBatch.final_floor``, the exact-coefficient compensation of §8). ``sens``: the four
    unit-coefficient responses (``RunBatch.sens``; None without). ``truths``: a :class:`TruthCache` of
    the same ``study`` (one Monte Carlo cell) that builds the run's true motion once for every
    run with its profile (None: built here).

    Every INS of the run (each replicate, its floor, the variants) is navigated as a lane of one
    kernel call per block of :data:`.insim.W` lanes (:meth:`.insim.FineTruth.navigate_lanes`),
    a replicate and its floor in the same block; each lane's numbers are those of navigating it
    alone, and a replicate's noise stream is drawn in the same order (accelerometer, gyro, then
    the outputs' noises), so nothing depends on the batch.
    """
    streams = [run_streams(s, study.platform_index(platform), study.run_index(platform, run)) for s in seeds]
    seeds = np.arange(len(streams)) if replicates is None else np.asarray(replicates, dtype=np.int64)
    prof, kin, ft = fine_truth(study, platform, run) if truths is None else truths.take(platform, run)
    n = prof.t.size
    dt = prof.dt
    res = study.residuals
    coeffs = coeff_vector(study, platform)
    s_acc = res["accel_noise_ug_rthz"] * 1e-6 * G0 / np.sqrt(dt)
    s_gyro = res["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(dt)
    nseed = seeds.size
    nvar = VARIANTS if sens else 0
    # the replicates' errors then the variants' responses: one array the kernel writes in place
    errs = np.empty((nseed + nvar, n, 4))
    err, sens_out = errs[:nseed], (errs[nseed:] if sens else None)
    phi = np.empty((nseed if keep_phi else 0, n, 3))
    v_ind = np.empty((nseed, n, 2))
    p_ind = np.empty((nseed, n, 2))
    f_meas = np.empty((nseed, n, 2))
    final_floor = np.empty((nseed, 4)) if floor else None
    psi = np.empty((nseed, n))
    dr = {k: np.zeros((nseed, m)) for k, m in (("k0", 2), ("sk", 2), ("eps", 3), ("phi0", 3), ("gg", 18))}
    rngs = [None if noise_free else np.random.default_rng(noise_seed) for _, noise_seed in streams]
    # the lanes: (replicate or -1, what: "ins" | "floor" | variant j, coef, gcoef, eps rad/s, phi0 rad)
    lanes = []
    for i, (param_seed, _) in enumerate(streams):
        if noise_free:
            k0, sk, eps, phi0, gg = np.zeros(2), np.zeros(2), np.zeros(3), np.zeros(3), np.zeros(18)
        else:
            k0, sk, eps, phi0, gg = draw_params(study, np.random.default_rng(param_seed))
        for key, val in (("k0", k0), ("sk", sk), ("eps", eps), ("phi0", phi0), ("gg", gg)):
            dr[key][i] = val
        lanes.append((i, "ins", np.concatenate([k0, sk, coeffs]) * 1e-6, gyro_vector(gg), eps * DEG_H, phi0))
        if floor:
            lanes.append((i, "floor", np.concatenate([k0, sk, np.zeros(4)]) * 1e-6, gyro_vector(gg), eps * DEG_H,
                          phi0))
    for j in range(nvar):
        coef = np.zeros(8)
        coef[4 + j] = 1e-6
        lanes.append((-1, j, coef, np.zeros(N_FULL), np.zeros(3), np.zeros(3)))
    # one set of noise buffers reused by every block: tens of MB that fresh arrays would take as
    # new zeroed pages for each block
    nbuf = min(W, len(lanes))
    bufs = {"acc": np.empty((nbuf, n, 2)), "gyro": np.empty((nbuf, n, 3))}
    for a in range(0, len(lanes), W):
        block = lanes[a:a + W]
        reps = sorted({ln[0] for ln in block if ln[0] >= 0 and not noise_free})
        local = {i: k for k, i in enumerate(reps)}
        # each replicate's white noises, drawn from its stream in the scalar order (accelerometer,
        # gyro) straight into the block's arrays and scaled in place (no per-replicate temporaries
        # stacked: the same draws and the same products)
        acc_w = _draw_scaled([rngs[i] for i in reps], bufs["acc"][:len(reps)], s_acc) if reps else None
        gyro_w = _draw_scaled([rngs[i] for i in reps], bufs["gyro"][:len(reps)], s_gyro) if reps else None
        # the kernel writes each replicate's errors, force and attitude into its rows of the
        # outputs, each variant's into its row after the replicates; a floor keeps its last errors
        err_row = [i if what == "ins" else -1 if what == "floor" else nseed + what for i, what, *_ in block]
        f_row = [i if what == "ins" else -1 for i, what, *_ in block]
        dest = LaneOutputs(err=errs, err_row=np.array(err_row, np.int64), f=f_meas, phi=phi,
                           f_row=np.array(f_row, np.int64), last=np.empty((len(block), 4)))
        ft.navigate_lanes(n, np.array([ln[2] for ln in block]), np.array([ln[3] for ln in block]),
                          np.array([ln[4] for ln in block]), np.array([ln[5] for ln in block]),
                          acc_w, gyro_w, np.array([local.get(ln[0], -1) for ln in block]), out=dest)
        for k, (i, what, *_) in enumerate(block):
            if what == "floor":
                final_floor[i] = dest.last[k]
    bufs = acc_w = gyro_w = None   # the noise buffers (and views of them) freed
    # the outputs: truth + error (+ noise), every replicate at once; each replicate's noises drawn
    # in its stream's order (velocity, position, heading) into one reused buffer
    np.add(kin.v, err[:, :, :2], out=v_ind)
    np.add(kin.p - kin.p[0], err[:, :, 2:], out=p_ind)
    psi[:] = kin.theta
    if not noise_free:
        buf, buf1 = np.empty((n, 2)), np.empty(n)
        for i, rng in enumerate(rngs):
            for out, sigma in ((v_ind[i], res["velocity_noise_m_s"]), (p_ind[i], res["position_noise_m"])):
                rng.standard_normal(out=buf)
                buf *= sigma
                out += buf
            rng.standard_normal(out=buf1)
            buf1 *= res["heading_noise_arcsec"]   # two products, in the order of the scalar draw's
            buf1 *= ARCSEC
            psi[i] += buf1
    draws = Draws(k0_ug=dr["k0"], scale_ppm=dr["sk"], drift_deg_h=dr["eps"], phi0_rad=dr["phi0"], gyro_g=dr["gg"])
    return RunBatch(platform=platform, run=run, seeds=seeds, coeffs=coeffs, prof=prof, kin=kin, draws=draws,
                    err=err, phi=phi if keep_phi else None, sens=sens_out, v_ind=v_ind, f_meas=f_meas, p_ind=p_ind,
                    psi=psi, final_floor=final_floor)


def _draw_scaled(rngs: list, out: np.ndarray, sigma: float) -> np.ndarray:
    """``out`` (len(rngs), ...) C-contiguous: one block of standard normals from each generator in
    turn, times ``sigma`` (the noises of a block of lanes, :func:`simulate_batch`)."""
    for k, rng in enumerate(rngs):
        rng.standard_normal(out=out[k])
    out *= sigma
    return out


@dataclass
class RecordBlock:
    """Data samples k0 .. k0 + n - 1 of one replicate's run (:func:`simulate_record`), the arrays
    of :class:`RunBatch` for one seed: t (n,) s, schedule (n,) codes, theta (n,) true arm angle
    rad, err (n, 4), phi (n, 3) or None, v_ind (n, 2), f_meas (n, 2), p_ind (n, 2), psi (n,)."""

    t: np.ndarray
    schedule: np.ndarray
    theta: np.ndarray
    err: np.ndarray
    phi: np.ndarray | None
    v_ind: np.ndarray
    f_meas: np.ndarray
    p_ind: np.ndarray
    psi: np.ndarray


@dataclass
class SpanCarry:
    """What :meth:`RecordRun._piece` carries from one span to the next: the arm angle ``theta``
    (rad) at the next span's first fine row, and the position at the run's start ``p0`` (m; None
    before the first span)."""

    theta: float = 0.0
    p0: np.ndarray | None = None


SIM_ROWS = 10_000
"""Data samples :class:`RecordRun` simulates at a time (its internal block, at most the output
block of ``rows``). The fine grid of 2 ``truth_steps`` samples per data sample, its true motion
(some 30 arrays while :func:`.profile.motion` runs) and the kernel's truth table (13 columns)
take over 1 kB a data sample: a block of :data:`platcal.records.CHUNK_ROWS` (100 000) simulated
at once took some 130 MB of RSS, and the previous block's arrays were still held while the next
was simulated (``platcal simulate`` of a 1 h record: 502 MB peak RSS, 339 MB at this size; the
output block then holds only the data grid's 16 columns, 128 bytes a sample). The numbers do not
depend on it (docs/lowprec-centrifuge.md §12; issue 22 item 3)."""


class RecordRun:
    """One replicate's run simulated block by block (:meth:`blocks`): the numbers of
    :func:`simulate_batch` for that replicate alone (``sens=False``, no floor), bit for bit, in
    memory of one block of ``rows`` data samples, not the run's (docs/lowprec-centrifuge.md §12;
    issue 22 item 3). Simulated ``work`` data samples at a time (:data:`SIM_ROWS`; the fine grid
    of a block is the cost) and copied into the block. Holds the run's draws and, once
    :meth:`blocks` is exhausted, its final errors (``final``: dVE, dVN m/s, dpE, dpN m)."""

    def __init__(self, study: Study, platform: str, run: str, seed: np.random.SeedSequence,
                 noise_free: bool = False, keep_phi: bool = True, rows: int = CHUNK_ROWS, work: int = SIM_ROWS):
        self.study, self.platform, self.run = study, platform, run
        self.noise_free, self.keep_phi, self.rows = bool(noise_free), bool(keep_phi), max(int(rows), 1)
        self.work = min(max(int(work), 1), self.rows)
        self.param_seed, self.noise_seed = run_streams(seed, study.platform_index(platform),
                                                       study.run_index(platform, run))
        self.coeffs = coeff_vector(study, platform)
        self.levels = build_profile(study, platform, run, rows=(0, 2)).levels
        self.n, self.dt = profile_grid(study, platform, run)
        zeros = (np.zeros(2), np.zeros(2), np.zeros(3), np.zeros(3), np.zeros(18))
        k0, sk, eps, phi0, gg = zeros if noise_free else draw_params(study, np.random.default_rng(self.param_seed))
        self.draws = Draws(k0_ug=k0[None], scale_ppm=sk[None], drift_deg_h=eps[None], phi0_rad=phi0[None],
                           gyro_g=gg[None])
        self.lane = (np.concatenate([k0, sk, self.coeffs]) * 1e-6, gyro_vector(gg), eps * DEG_H, phi0)
        self.final = None

    def _noise_generators(self) -> list:
        """Five generators on the replicate's noise stream, each at the start of one of its
        full-length blocks (accelerometer (n, 2), gyro (n, 3), velocity (n, 2), position (n, 2),
        heading (n,): :func:`simulate_batch`'s order), reached by drawing the blocks before it
        ``work`` samples at a time (the normals do not depend on how a draw is split)."""
        rng = np.random.default_rng(self.noise_seed)
        out = []
        for width in (2, 3, 2, 2, 1):
            out.append(copy.deepcopy(rng))
            for a in range(0, self.n, self.work):
                rng.standard_normal((min(a + self.work, self.n) - a) * width)
        return out

    def _uniform_step(self, substeps: int) -> float | None:
        """The fine grid's constant step (s) if all its steps are equal, else None (the spacing
        np.gradient chooses for the whole grid, :func:`.profile.grid_gradient`); checked
        ``work`` x substeps samples at a time."""
        n, dt = profile_grid(self.study, self.platform, self.run, substeps)
        step, first = self.work * substeps, None
        for a in range(0, n - 1, step):
            d = np.diff(np.arange(a, min(a + step + 1, n)) * dt)
            first = d[0] if first is None else first
            if not (d == first).all():
                return None
        return first

    def blocks(self):
        """Yield the run's :class:`RecordBlock` s in order, ``rows`` data samples each, each
        simulated ``work`` samples at a time (:meth:`_pieces`) into the block's arrays."""
        n, rows, work = self.n, self.rows, self.work
        spans = [(a, min(a + work, k0 + rows, n)) for k0 in range(0, n, rows)
                 for a in range(k0, min(k0 + rows, n), work)]
        pieces = self._pieces(spans)
        for k0 in range(0, n, rows):
            k1 = min(k0 + rows, n)
            grid = build_profile(self.study, self.platform, self.run, rows=(k0, k1))
            if k1 - k0 <= work:
                got = next(pieces)   # one piece: its arrays are the block's (no copy)
            else:
                m = k1 - k0
                got = {"theta": np.empty(m), "err": np.empty((m, 4)),
                       "phi": np.empty((m, 3)) if self.keep_phi else None, "v_ind": np.empty((m, 2)),
                       "f_meas": np.empty((m, 2)), "p_ind": np.empty((m, 2)), "psi": np.empty(m)}
                for a in range(0, m, work):
                    for f, v in next(pieces).items():
                        if v is not None:
                            got[f][a:a + v.shape[0]] = v
            yield RecordBlock(t=grid.t, schedule=grid.schedule, **got)

    def _pieces(self, spans):
        """The run's data samples a .. b - 1 of each of ``spans`` (consecutive, from 0 to n):
        per span a dict of the :class:`RecordBlock` arrays but t and schedule (theta, err, phi,
        v_ind, f_meas, p_ind, psi). The INS state, the arm angle and the noise generators run on
        from span to span, so the numbers are the whole run's (§12)."""
        study, n = self.study, self.n
        steps = int(study.profile["truth_steps"])
        sub = 2 * steps
        nf, _ = profile_grid(study, self.platform, self.run, sub)
        dx = self._uniform_step(sub)
        res = study.residuals
        s_acc = res["accel_noise_ug_rthz"] * 1e-6 * G0 / np.sqrt(self.dt)
        s_gyro = res["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(self.dt)
        gens = None if self.noise_free else self._noise_generators()
        coef, gcoef, eps, phi0 = self.lane
        L, y = _lanes_init(coef[:, None], gcoef[:, None], eps[:, None], quaternion_of(phi0)[:, None])
        carry = SpanCarry()
        for k0, k1 in spans:
            yield self._piece(k0, k1, sub, nf, dx, s_acc, s_gyro, gens, L, y, carry)

    def _piece(self, k0: int, k1: int, sub: int, nf: int, dx, s_acc: float, s_gyro: float, gens, L, y,
               carry: SpanCarry) -> dict:
        """Data samples k0 .. k1 - 1 (:meth:`_pieces`): the fine grid's true motion there, the INS
        through it (L, y: the lane's input and state, y advanced in place) and the outputs with
        their noises (``gens``: :meth:`_noise_generators`, None: noise-free; s_acc m/s^2, s_gyro
        rad/s per data interval). ``carry`` (:class:`SpanCarry`): the arm angle (rad) at k0's fine row and the
        position at the run's start, carried to the next span. A function so that the fine
        grid's arrays are freed when it returns (§12)."""
        study, n, steps = self.study, self.n, sub // 2
        cen, lat, res = study.centrifuge, study.latitude_deg, study.residuals
        last = k1 == n
        fa, fb = sub * k0, (sub * (k1 - 1) + 1 if last else sub * k1 + 1)
        # the fine rows fa .. fb - 1 (through the next span's first sample), with one row of
        # context each side for w'' (central differences)
        ca, cb = max(fa - 1, 0), min(fb + 1, nf)
        prof = build_profile(study, self.platform, self.run, sub, rows=(ca, cb))
        w = prof.omega_nom * (1.0 + cen.rate_error)
        wd = prof.omegadot_nom * (1.0 + cen.rate_error)
        wdd = grid_gradient(wd, prof.t, dx)[fa - ca:fb - ca]
        w, wd = w[fa - ca:fb - ca], wd[fa - ca:fb - ca]
        # theta: the whole run's cumulative trapezoid continued from the span's first row
        inc = 0.5 * (self.dt / sub) * (w[1:] + w[:-1])
        theta = np.cumsum(np.concatenate([[carry.theta], inc]))
        if not last:
            carry.theta = theta[-1]
        kin = motion(w, wd, wdd, theta, cen, lat)
        m = k1 - k0
        err, fm = np.empty((1, m, 4)), np.empty((1, m, 2))
        phi = np.empty((1, m, 3)) if self.keep_phi else np.empty((0, m, 3))
        if gens is None:
            acc_w, gyro_w, noise_of = np.zeros((0, m, 2)), np.zeros((0, m, 3)), np.array([-1])
        else:
            acc_w = (gens[0].standard_normal((m, 2)) * s_acc)[None]
            gyro_w = (gens[1].standard_normal((m, 3)) * s_gyro)[None]
            noise_of = np.array([0])
        row0 = np.zeros(1, np.int64)   # the one lane's row of the span's outputs
        _navigate_block(self.dt / steps, steps, truth_table(kin), float(np.cos(np.radians(lat))), L, y, acc_w,
                        gyro_w, noise_of, err, row0, phi, fm, row0, np.empty((1, 4)), last)
        data = Kinematics(**{f: getattr(kin, f)[:sub * (m - 1) + 1:sub] for f in Kinematics.__dataclass_fields__})
        if carry.p0 is None:
            carry.p0 = data.p[0].copy()
        v_ind = data.v + err[0, :, :2]
        p_ind = data.p - carry.p0 + err[0, :, 2:]
        psi = data.theta.copy()
        if gens is not None:
            v_ind += gens[2].standard_normal((m, 2)) * res["velocity_noise_m_s"]
            p_ind += gens[3].standard_normal((m, 2)) * res["position_noise_m"]
            psi += gens[4].standard_normal(m) * res["heading_noise_arcsec"] * ARCSEC
        if last:
            self.final = err[0, -1].copy()
        # theta a copy: a view would hold the span's whole fine angle
        return {"theta": data.theta.copy(), "err": err[0], "phi": phi[0] if self.keep_phi else None, "v_ind": v_ind,
                "f_meas": fm[0], "p_ind": p_ind, "psi": psi}
