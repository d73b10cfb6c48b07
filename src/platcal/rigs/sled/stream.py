"""A long sled record in bounded memory: ``identify`` and ``simulate`` block by block (issue 22
item 3; docs/rocket-sled.md §4-8, §10, §12).

``identify`` reads the record three times through :func:`platcal.records.iter_table`
(``--chunk-rows`` rows at a time):

1. the times: the read's time checks, the clock's origin, the filter epochs and the stop take
   medians and nearest samples over the whole record, so ``t`` is spilled to a temporary file
   (8 bytes a sample on disk) and those are taken by passes over it (exact medians by radix
   selection, :class:`platcal.records.PassMedian`; nearest samples block by block); the spill
   is kept to the end, and the filter epochs are taken from it again as pass 3 reaches them
   (:class:`EpochStream`): only those up to the stop are held (the run filter's, fixed by the
   trajectory), so nothing held grows with the record (issue 22 item 3; the whole record's
   epochs were 16 bytes an epoch, 17 MB for 6 h at 20 ms);
2. the checks (:mod:`.record`) from sums: the median ``fz`` and each phase's median ``fx`` are
   judged by counting the samples below and above the tolerance (a median is inside when its
   middle samples are: exact), the nominal output's regression (:class:`Moments`), the gyros'
   mean at rest and the Coriolis regression's normal equations; a median the counts cannot
   settle (its two middle samples on either side of a bound) or refuse is taken from the whole
   record (:func:`.record.read_record`, which then refuses it with the whole read's message);
3. the filters: the mechanisation carried from block to block (:class:`.ins.Navigator`); the
   record up to the stop (the run filter's epochs and metric B) is held, then the run filter,
   metric B's model and the X compensation up to there run as for a whole record; beyond, the
   stop filter steps block by block (:class:`.filters.KalmanRun`), the X compensation continues
   its sums, and the metrics beyond the stop are running values (:class:`.identify.Tail`).

The record and the three gyro offsets of ``metrics.json``'s ``gyro_rate_error`` block run as
four lanes of one batch. Estimates and metrics equal the whole read's
(``tests/sled/test_sled_stream.py``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from ...estimation.fit import Moments
from ...plausibility import refuse_recognised_moments
from ...records import (ColumnSpill, NearestSamples, iter_table, record_writer, spilled_grid_origin,
                        spilled_median_step, spilled_times)
from .config import G, SledConfig
from .errmodel import propagate_run_model
from .filters import Dynamics, Epochs, FilterOut, KalmanRun, epoch_mean, run_filter, stop_tuning
from .identify import (Identification, Tail, end_errors, gyro_offsets, gyro_rate_sigma, phi_columns, phi_per_sample,
                       run_attitude, x_corrections)
from .ins import Navigator
from .record import (IMU_COLUMNS, NOMINAL_FIX, RECORD_FLOATS, TRUTH_COLUMNS, check_out_path, check_span,
                     gain_and_error, incremental, nominal_imu, phase_off, phase_windows, read_record, record_frame,
                     refuse_lateral, refuse_static_rates, rest_samples, rest_tolerance, samples_per_phase,
                     table_options, truth_params, truth_side)
from .sensors import ErrorParams, accel_error, draw_errors, measure, noise_sigmas
from .simulate import Truth, record_rotation
from .trajectory import Timeline


class EpochStream:
    """The filter epochs of a spilled ``t`` (s; ``origin`` taken off; docs/rocket-sled.md §12,
    recorded times): the samples nearest the multiples of ``period_s`` (s) within ``tol_s`` (s)
    (:class:`platcal.records.NearestSamples`), epoch 0
    the first sample (at ``first``), as the whole record's :func:`platcal.records.nearest_samples`
    gives them, produced from the spill in order as far as they are asked for (:meth:`below`):
    held, the epochs of one spill block at most (16 bytes an epoch)."""

    def __init__(self, spill: ColumnSpill, origin: float, first: float, last: float, period_s: float, tol_s: float):
        self._pieces = self._generate(spill, origin, first, last, period_s, tol_s)
        self._k, self._at = np.zeros(0, np.int64), np.zeros(0)     # produced, not yet taken
        self._done = False

    @staticmethod
    def _generate(spill, origin, first, last, period_s, tol_s) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        near = NearestSamples(first, last, period_s, tol_s)
        prev = None                      # the last index given

        def fresh(final: bool = False):
            nonlocal prev
            if final:                    # after the last sample (the lists are empty but for it)
                idx, at = near.result()
            else:
                idx = np.concatenate(near.idx) if near.idx else np.zeros(0, np.int64)
                at = np.concatenate(near.at) if near.at else np.zeros(0)
                near.idx, near.at = [], []
            # the indices never decrease: the whole record's np.unique keeps the first of each run
            keep = idx != np.r_[-1 if prev is None else prev, idx[:-1]]
            idx, at = idx[keep].astype(np.int64), at[keep]
            if prev is None and idx.size and idx[0] != 0:   # epoch 0 (the prior) is the first sample
                idx, at = np.r_[0, idx], np.r_[first, at]
            if idx.size:
                prev = int(idx[-1])
            return idx, at

        for g, ahead, _ in spill.steps(origin):
            near.add(g, ahead)
            yield fresh()
        yield fresh(final=True)
        if prev is None:                 # no sample near a multiple: the first sample alone
            yield np.zeros(1, np.int64), np.array([first])

    def _fill(self, limit: int) -> None:
        """Produce epochs until one at sample ``limit`` or later is held, or there are no more."""
        while not self._done and (self._k.size == 0 or self._k[-1] < limit):
            piece = next(self._pieces, None)
            if piece is None:
                self._done = True
            else:
                self._k, self._at = np.r_[self._k, piece[0]], np.r_[self._at, piece[1]]

    def below(self, limit: int, one_more: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The next epochs ``(k, at)`` (sample indices, times s) at samples before ``limit``
        (``one_more``: and the first one after them, if there is one); they are taken."""
        self._fill(limit)
        n = int(np.searchsorted(self._k, limit))
        n += int(one_more and n < self._k.size)
        out = self._k[:n], self._at[:n]
        self._k, self._at = self._k[n:], self._at[n:]
        return out

    def count_rest(self) -> int:
        """The number of epochs not taken yet (all of them produced and dropped)."""
        n = self._k.size
        self._k, self._at = np.zeros(0, np.int64), np.zeros(0)
        for k, _ in self._pieces:
            n += k.size
        self._done = True
        return n


@dataclass(frozen=True)
class Times:
    """What the first pass keeps of a record's times: rows, the clock's origin taken off (s), the
    median step of the time check ``med`` and of the record's own intervals ``med_t`` (s), the
    first and last times from the origin (s), the filter epochs up to the stop's ``k`` (j_stop+1,),
    their intervals ``T`` (j_stop,) s and the stop epoch's time ``at_stop`` (s; the later epochs:
    :meth:`epochs`), the stop's sample and
    epoch, the last epoch ``j_end``, the samples per phase, the seconds at rest and whether the
    truth columns are there."""

    rows: int
    origin: float
    med: float
    med_t: float
    first: float
    last: float
    k: np.ndarray
    T: np.ndarray
    at_stop: float
    n_stop: int
    j_stop: int
    j_end: int
    per_phase: dict
    rest_s: float
    tolerance: np.ndarray
    truth_columns: bool

    def epochs(self, spill: ColumnSpill, period_s: float) -> EpochStream:
        """The record's filter epochs from the spilled ``t`` (:class:`EpochStream`), from epoch 0."""
        return EpochStream(spill, self.origin, self.first, self.last, period_s, 0.5 * self.med_t)


def _chunks(path, cfg: SledConfig, chunk_rows: int):
    """The record's tables, read :data:`BLOCK` rows at a time (fewer with a smaller
    ``--chunk-rows``, which decides whether the record is streamed): the passes work a block at a
    time, and chunks of the default 100 000 rows (8 MB each, two alive while the next is read)
    made the peak grow from a 10-minute record to an hour-long one (issue 22 item 3)."""
    return iter_table(path, **table_options(cfg), chunk_rows=min(chunk_rows, BLOCK))


def scan_times(path, cfg: SledConfig, tl: Timeline, chunk_rows: int, spill: ColumnSpill) -> Times:
    """Pass 1: the record's ``t`` spilled to ``spill`` (:class:`platcal.records.ColumnSpill`,
    the rows' own checks as each chunk is read), checked and counted from its start as
    :func:`.record.read_record` does (:func:`platcal.records.spilled_times`, the same medians by
    passes over the spilled ``t``: :class:`platcal.records.PassMedian`), then reduced to
    :class:`Times` in two more passes (the stop, the rest and the samples per phase by counts;
    the epochs by :class:`EpochStream`, those up to the stop's kept and the rest counted). Held:
    the epochs up to the stop (16 bytes an epoch), whatever the record's length."""
    max_gap = float(cfg.raw["record"]["max_gap_s"])
    has_truth = None
    for df in _chunks(path, cfg, chunk_rows):
        has_truth = all(c in df.columns for c in TRUTH_COLUMNS) if has_truth is None else has_truth
        spill.write(df["t"].to_numpy(dtype=float))
    med = spilled_times(spill, cfg.dt, max_gap, "--data column t",
                        f"imu.rate_hz = {cfg.rate_hz:g} Hz, a step of {cfg.dt:g} s")
    origin = 0.0 if abs(spill.first) <= max_gap else spilled_grid_origin(spill, med)
    first, last = spill.first - origin, spill.last - origin
    check_span(cfg, tl.n, first, last, spill.rows, med)
    # the median step of t - origin: that of t when the origin is 0 (the same numbers)
    med_t = med if origin == 0.0 else spilled_median_step(spill, origin)
    before_stop, rest_n, per_phase = 0, 0, dict.fromkeys(tl.phase_names, 0)
    for g, ahead, _ in spill.steps(origin):
        t = ahead if g == 0 else ahead[1:]          # this block's own samples
        before_stop += int(np.count_nonzero(t < tl.stop_time_s - 0.5 * med_t))
        rest_n += int(rest_samples(cfg, tl, t, med_t).sum())
        for name, count in samples_per_phase(tl, t, cfg.dt).items():
            per_phase[name] += count
    n_stop = min(before_stop, spill.rows - 1)  # :func:`.identify.stop_index`
    rest_s = float(rest_n) * med_t
    tm = Times(rows=spill.rows, origin=origin, med=med, med_t=med_t, first=first, last=last, k=np.zeros(0, np.int64),
               T=np.zeros(0), at_stop=first, n_stop=n_stop, j_stop=0, j_end=0, per_phase=per_phase, rest_s=rest_s,
               tolerance=rest_tolerance(cfg, rest_s), truth_columns=bool(has_truth))
    # the stop epoch: the first at or after the stop's sample, else the last (:func:`.identify.identify`)
    ep = tm.epochs(spill, cfg.period_ms / 1000.0)
    k, at = ep.below(n_stop, one_more=True)
    return replace(tm, k=k, T=np.diff(at), at_stop=float(at[-1]), j_stop=k.size - 1,
                   j_end=k.size - 1 + ep.count_rest())


BLOCK = 16384
"""Samples handled at a time inside a chunk (pass 2 and 3): the filters' pass holds some 1.2 kB
of arrays per sample and lane (four lanes: the record and its gyro offsets), so a chunk of
``--chunk-rows`` is worked through in blocks of this many samples (the results do not depend on
the cut, ``tests/sled/test_sled_stream.py``)."""


def blocks(path, cfg: SledConfig, tm: Times, chunk_rows: int):
    """The record's samples as ``(row0, t, dts, f, w, truth)`` of at most :data:`BLOCK` rows: the
    first row's index, the times from the record's start (s), the interval each sample covers
    (the next chunk's first sample read ahead; the last sample the median step), f (N,3) m/s^2
    and w (N,3) rad/s (increments turned into rates over those intervals), and the truth
    columns present (name -> (N,))."""
    inc = incremental(cfg)
    cols_f, cols_w = list(IMU_COLUMNS[1:4]), list(IMU_COLUMNS[4:])

    def done(item, t_next):
        row0, df, t = item
        dts = np.diff(np.r_[t, t_next]) if t_next is not None else np.r_[np.diff(t), tm.med_t]
        f, w = df[cols_f].to_numpy(dtype=float), df[cols_w].to_numpy(dtype=float)
        if inc:  # delta-v, delta-theta over each sample's interval (platcal.logs.increments)
            f, w = f / dts[:, None], w / dts[:, None]
        truth = {c: df[c].to_numpy(dtype=float) for c in TRUTH_COLUMNS if c in df.columns}
        for i in range(0, t.size, BLOCK):
            j = slice(i, i + BLOCK)
            yield row0 + i, t[j], dts[j], f[j], w[j], {c: a[j] for c, a in truth.items()}

    pending, row = None, 0
    for df in _chunks(path, cfg, chunk_rows):
        t = df["t"].to_numpy(dtype=float) - tm.origin
        if pending is not None:
            yield from done(pending, t[0])
        pending = (row, df, t)
        row += len(df)
    yield from done(pending, None)


class _Median:
    """Whether the median of values seen in blocks is inside an interval, from counts: below and
    above are monotone sets (every value below a value below is below), so the median (the mean
    of the two middle values) is inside when neither middle value is below or above (exact);
    ``clear`` is False when the counts cannot say so."""

    def __init__(self):
        self.n = self.below = self.above = 0

    def add(self, below: np.ndarray, above: np.ndarray) -> None:
        self.n += below.size
        self.below += int(below.sum())
        self.above += int(above.sum())

    def clear(self) -> bool:
        i1, i2 = (self.n - 1) // 2, self.n // 2
        return self.below <= i1 and self.n - self.above >= i2 + 1


def check_streamed(path, cfg: SledConfig, tl: Timeline, tm: Times, chunk_rows: int) -> None:
    """Pass 2: :func:`.record.read_record`'s value checks and :func:`.record.check_plausible` from
    sums over the blocks, in their order, with their messages (a median the counts cannot settle
    is read whole; the Coriolis regression from its normal equations)."""
    fz = _Median()
    phases: dict[int, _Median] = {}
    mom_f, mom_w = Moments.zero(3), Moments.zero(3)
    rest_n, rest_w, rest_fx = 0, np.zeros(3), 0.0
    # fy on [1, fx, 2 omega_z v], v = U - m Tm: U and Tm the mid-interval sums of fx dt and dt, m
    # the mean fx at rest (known at the end): the sums of [1, fx, U, Tm] give the regression's
    gram, by, yy = np.zeros((4, 4)), np.zeros(4), 0.0
    u0 = tm0 = 0.0
    for _, t, dts, f, w, _ in blocks(path, cfg, tm, chunk_rows):
        fz.add(f[:, 2] < 0.9 * G, f[:, 2] > 1.1 * G)
        for p, (_, _, inside, level) in phase_windows(cfg, tl, t, tm.med):
            off = phase_off(f[inside, 0], level)
            phases.setdefault(p, _Median()).add(off & (f[inside, 0] < level), off & (f[inside, 0] > level))
        f_nom, w_nom = nominal_imu(cfg, tl, t)
        mom_f.add(f, f_nom)
        mom_w.add(w, w_nom)
        rest = rest_samples(cfg, tl, t, tm.med_t)
        rest_n += int(rest.sum())
        rest_w += w[rest].sum(axis=0)
        rest_fx += float(f[rest, 0].sum())
        cu = np.cumsum(np.r_[u0, f[:, 0] * dts])
        ct = np.cumsum(np.r_[tm0, dts])
        u0, tm0 = cu[-1], ct[-1]
        B = np.column_stack([np.ones_like(dts), f[:, 0], cu[1:] - 0.5 * f[:, 0] * dts, ct[1:] - 0.5 * dts])
        gram += B.T @ B
        by += B.T @ f[:, 1]
        yy += float(f[:, 1] @ f[:, 1])
    if not (fz.clear() and all(m.clear() for m in phases.values())):
        read_record(path, cfg)    # the whole read's verdict and message
    refuse_recognised_moments(mom_f, ("fx", "fy", "fz"), "m/s^2", NOMINAL_FIX["f"])
    refuse_recognised_moments(mom_w, ("wx", "wy", "wz"), "rad/s", NOMINAL_FIX["w"])
    if rest_n >= 2:
        refuse_static_rates(cfg, rest_w / rest_n, tm.rest_s)
    m = rest_fx / rest_n if rest_n else 0.0
    c = 2.0 * cfg.omega_ie[2]
    M = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, c], [0, 0, -c * m]])
    A_A, A_y = M.T @ gram @ M, M.T @ by
    scale = np.sqrt(np.diag(A_A))
    scale[scale == 0] = 1.0
    coef = np.linalg.lstsq(A_A / np.outer(scale, scale), A_y / scale, rcond=None)[0] / scale
    rss = max(yy - 2.0 * coef @ A_y + coef @ A_A @ coef, 0.0)
    refuse_lateral(cfg, *gain_and_error(coef, A_A, rss, tm.rows))


@dataclass
class Streamed:
    """A streamed identification: ``idn`` (lanes: the record, then with a constant gyro error
    the record with each gyro offset, :func:`.identify.gyro_offsets`) holding the record up to
    the stop, ``tail`` its values beyond, ``truth`` the simulation's (held part) or None, and
    the first pass's :class:`Times`."""

    idn: Identification
    tail: Tail
    truth: Truth | None
    times: Times

    @property
    def gyro_lanes(self) -> bool:
        return self.idn.r.shape[0] == 4

    def first(self) -> tuple[Identification, Tail]:
        """The record's own lane (lane 0) of ``idn`` and ``tail``, for :func:`.identify.metrics`."""
        one = lambda a: None if a is None else a[:1]  # noqa: E731
        fo = lambda o: replace(o, x=o.x[:1], sigma=o.sigma[:1], P=o.P[:1], mean_nis=o.mean_nis[:1],  # noqa: E731
                               failed_updates=o.failed_updates[:1], innov=one(o.innov), s_var=one(o.s_var))
        i = self.idn
        idn = replace(i, v=i.v[:1], r=i.r[:1], fl=i.fl[:1], run=fo(i.run), stop=fo(i.stop), phi_run=i.phi_run[:1],
                      sig_run=i.sig_run[:1], r_model=i.r_model[:1], x_con=i.x_con[:1], x_con_other=i.x_con_other[:1],
                      nabla_x_hat=i.nabla_x_hat[:1], tail_finite=one(i.tail_finite))
        end = None if self.tail.end is None else {k: v[:1] for k, v in self.tail.end.items()}
        return idn, Tail(self.tail.yz_max[:1], self.tail.y_static_max[:1], end)


def identify_streamed(path, cfg: SledConfig, chunk_rows: int, with_truth: bool = True, checked=None) -> Streamed:
    """Passes 1-3 of the module's docstring on the record at ``path``; ``with_truth``: read the
    simulation's truth when the record has it. ``checked(times)`` is called after the checks,
    before the filters (the command's clock)."""
    tl = Timeline.of(cfg)
    with ColumnSpill() as spill:   # the record's t, on disk until the filters have taken their epochs
        tm = scan_times(path, cfg, tl, chunk_rows, spill)
        check_streamed(path, cfg, tl, tm, chunk_rows)
        drawn = truth_params(path, TRUTH_COLUMNS if tm.truth_columns else ()) if with_truth else None
        if checked is not None:
            checked(tm)
        return _filters(path, cfg, tl, tm, chunk_rows, drawn, spill)


def _filters(path, cfg: SledConfig, tl: Timeline, tm: Times, chunk_rows: int, drawn, spill: ColumnSpill) -> Streamed:
    """Pass 3 (the module's docstring)."""
    lanes = 4 if gyro_rate_sigma(cfg) > 0 else 1
    k, T, j_stop, n_stop, j_end = tm.k, tm.T, tm.j_stop, tm.n_stop, tm.j_end
    later = tm.epochs(spill, cfg.period_ms / 1000.0)
    later.below(int(k[j_stop]) + 1)         # the run part's epochs, held in tm: the stop part takes the rest
    ks = int(k[j_stop])
    K = max(ks, n_stop) + 1                    # the held run part: samples 0 … K-1
    states = cfg.states
    iy = phi_columns(states)["phi_y"]
    period = cfg.period_ms / 1000.0
    nav = Navigator(np.zeros((lanes, 3)), cfg.omega_ie)
    held: dict[str, list] = {n: [] for n in ("fl", "v", "r", "dts", "t", "x_true", "vx_true", "x_inst")}
    yz_max = np.zeros(lanes)
    finite = np.ones(lanes, bool)
    st: dict = {}
    end: dict = {}
    for row0, t, dts, f, w, cols in blocks(path, cfg, tm, chunk_rows):
        nb = t.size
        wl = np.concatenate([w[None], gyro_offsets(cfg, w[None])]) if lanes == 4 else w[None]
        v, r, fl = nav.step(np.broadcast_to(f, (lanes, nb, 3)), wl, dts)
        v, r = v[:, :nb], r[:, :nb]           # the states at this block's samples
        finite &= np.isfinite(v).all(axis=(1, 2)) & np.isfinite(r).all(axis=(1, 2))
        yz_max = np.maximum(yz_max, np.abs(r[..., 1:]).max(axis=(1, 2)))
        truth_cols = cols if drawn is not None else {}
        a = 0
        if row0 < K:
            a = min(nb, K - row0)
            for name, arr in (("fl", fl[:, :a]), ("v", v[:, :a]), ("r", r[:, :a]), ("dts", dts[:a]), ("t", t[:a])):
                held[name].append(arr.copy())
            for c, arr in truth_cols.items():
                held[c].append(arr[:a].copy())
            if row0 + nb >= K:
                st = _run_part(cfg, held, k, T, j_stop, n_stop, K, lanes)
                st["epochs"], st["at_done"] = later, tm.at_stop
                held = {}
        if st and a < nb:
            _stop_part(cfg, st, row0 + a, fl[:, a:], v[:, a:], r[:, a:], dts[a:])
        # the last sample's along-track position and truths (metrics' "end"): the last block's win
        end = {"x_nav": r[:, -1, 0].copy(), **{c: arr[-1:] for c, arr in truth_cols.items()}}
    if st["j_done"] < j_end:   # stop epochs inside the held part of a record that ends there
        z3 = np.zeros((lanes, 0, 3))
        _stop_part(cfg, st, tm.rows, z3, z3, z3, np.zeros(0))
    end["con"] = {mode: end["x_nav"] - st["dr_last"][mode] for mode in ("realtime", "post")}
    other = "post" if cfg.compensation == "realtime" else "realtime"
    run = st["run"]
    x_fin, s_fin = st["x_last"], st["s_last"]
    rows = [st["x0"]] + ([np.full_like(x_fin, np.nan)] if not st["stop_finite"].all() else []) + [x_fin]
    srows = [st["s0"]] + ([np.full_like(s_fin, np.nan)] if not st["stop_finite"].all() else []) + [s_fin]
    kf = st["kf"]
    stop = FilterOut(np.stack(rows, axis=1), np.stack(srows, axis=1), kf.P, kf.mean_nis(), kf.failed)
    idn = Identification(cfg=cfg, traj=tl, v=st["v"], r=st["r"], fl=st["fl"], run=run, stop=stop, j_stop=j_stop,
                         j_end=j_end, phi_run=st["phi_run"], sig_run=st["sig_run"], r_model=st["r_model"],
                         x_con=st["xc"][cfg.compensation], x_con_other=st["xc"][other],
                         nabla_x_hat=G * (run.x[:, -1, iy] - x_fin[:, 5]), t=st["t"], epochs=st["ep"],
                         n_stop=n_stop, tail_finite=finite)
    truth, tail_end = None, None
    if drawn is not None:
        params, nab = drawn
        truth = Truth(params=params, x_true=st["x_true"][None], vx_true=st["vx_true"][None],
                      x_inst=st["x_inst"][None], nabla_static=nab)
        tail_end = end_errors(end["x_nav"], end["con"][cfg.compensation], end["con"][other], end["x_inst"],
                              end["x_true"])
    return Streamed(idn, Tail(yz_max, st["y_static_max"], tail_end), truth, tm)


def _run_part(cfg: SledConfig, held: dict, k, T, j_stop: int, n_stop: int, K: int, lanes: int) -> dict:
    """The record up to the stop, held: the run filter, metric B's model and the X compensation
    as :func:`.identify.identify` runs them; the stop filter's prior. Returns the streamed
    pass's state."""
    cat = lambda name, axis: np.concatenate(held[name], axis=axis)  # noqa: E731
    fl, v, r, dts, t = cat("fl", 1), cat("v", 1), cat("r", 1), cat("dts", 0), cat("t", 0)
    ep = Epochs(k=k[:j_stop + 1], T=T[:j_stop], dts=dts)
    run = run_filter(cfg, fl, v, r, j_stop, ep)
    phi_run, sig_run = run_attitude(run, cfg.states)
    iy = phi_columns(cfg.states)["phi_y"]
    r_model = propagate_run_model(fl[:, :n_stop], cfg.omega_ie, np.nan_to_num(phi_run), cfg.states, dts[:n_stop])
    xc, carry, dr_last = {}, {}, {}
    for mode in ("realtime", "post"):
        dv, dr = x_corrections(fl, phi_per_sample(run, cfg.states, ep.k, j_stop, K, mode), dts)
        xc[mode] = r[..., 0] - dr[:, :K]
        carry[mode] = (dv[:, K], dr[:, K])
        dr_last[mode] = dr[:, K - 1]
    ks = int(k[j_stop])
    x0 = np.zeros((lanes, 6))
    x0[:, 0], x0[:, 1], x0[:, 2] = v[:, ks, 1], r[:, ks, 1], v[:, ks, 0]
    x0[:, 5] = run.x[:, -1, iy]
    kf = KalmanRun(x0, stop_tuning(cfg, run.P[:, iy, iy]), cfg.period_ms / 1000.0)
    x_prior, s_prior = kf.prior()
    st = dict(run=run, phi_run=phi_run, sig_run=sig_run, r_model=r_model, xc=xc, carry=carry, dr_last=dr_last,
              fl=fl, v=v, r=r, t=t, ep=ep, kf=kf, x0=x_prior, s0=s_prior, x_last=x_prior, s_last=s_prior,
              stop_finite=np.isfinite(x_prior).all(axis=1) & np.isfinite(s_prior).all(axis=1),
              y_static_max=np.abs(r[:, ks, 1] - x_prior[:, 1]), rx_stop=r[:, ks, 0].copy(),
              phi_post=phi_per_sample(run, cfg.states, ep.k, j_stop, 1, "post")[:, :1],
              j_done=j_stop, base=ks, buf=(fl[:, ks:], v[:, ks:], r[:, ks:], dts[ks:]))
    for name in ("x_true", "vx_true", "x_inst"):
        if held.get(name):
            st[name] = np.concatenate(held[name])
    return st


def _stop_part(cfg: SledConfig, st: dict, s0: int, fl, v, r, dts) -> None:
    """Samples ``s0`` … of a block beyond the held run part: the X compensation continued with
    the final run estimate, the stop filter stepped over the epochs whose samples are in (taken
    from the record's :class:`EpochStream` as they come)."""
    n = dts.size
    phi = np.broadcast_to(st["phi_post"], (fl.shape[0], n, 3))
    for mode in ("realtime", "post") if n else ():
        dv, dr = x_corrections(fl, phi, dts, st["carry"][mode])
        st["carry"][mode] = (dv[:, n], dr[:, n])
        st["dr_last"][mode] = dr[:, n - 1]
    bfl, bv, br, bd = st["buf"]
    bfl, bv, br, bd = (np.concatenate([bfl, fl], 1), np.concatenate([bv, v], 1), np.concatenate([br, r], 1),
                       np.r_[bd, dts])
    base, j0 = st["base"], st["j_done"]
    new_k, new_at = st["epochs"].below(s0 + n)                   # the epochs whose samples are in
    if new_k.size:
        j1 = j0 + new_k.size
        T = np.diff(np.r_[st["at_done"], new_at])                 # the whole record's np.diff(at)[j0:j1]
        ep = Epochs(k=np.r_[base, new_k] - base, T=T, dts=bd)
        Fs = Dynamics.stop(epoch_mean(bfl, ep, 0, j1 - j0), cfg.omega_ie)
        kk = ep.k[1:]
        z = np.stack([bv[:, kk, 1], br[:, kk, 1], bv[:, kk, 0], br[:, kk, 0] - st["rx_stop"][:, None]], axis=-1)
        xs, sig, _, _ = st["kf"].step(Fs, z, T)
        st["y_static_max"] = np.maximum(st["y_static_max"], np.abs(br[:, kk, 1] - xs[:, :, 1]).max(axis=1))
        st["stop_finite"] &= np.isfinite(xs).all(axis=(1, 2)) & np.isfinite(sig).all(axis=(1, 2))
        st["x_last"], st["s_last"] = xs[:, -1], sig[:, -1]
        cut = int(new_k[-1]) - base
        bfl, bv, br, bd = bfl[:, cut:].copy(), bv[:, cut:].copy(), br[:, cut:].copy(), bd[cut:].copy()
        st["base"], st["j_done"], st["at_done"] = int(new_k[-1]), j1, float(new_at[-1])
    st["buf"] = (bfl, bv, br, bd)


def simulate_streamed(cfg: SledConfig, seed: np.random.SeedSequence, path, chunk_rows: int,
                      noise_free: bool = False) -> Timeline:
    """:func:`.simulate.simulate` of one replicate written ``chunk_rows`` samples at a time
    (:func:`platcal.records.record_writer`: a temporary file renamed with its truth side file at
    the end): the trajectory's error-free output per block (:class:`.trajectory.Timeline`), the
    accelerometer noise from the replicate's generator and the gyro noise from a copy of it moved
    past the record's accelerometer draws (§3's draw order: the whole record's accelerometer noise,
    then its gyro noise), the truths' mechanisations carried from block to block. The CSV text
    is the whole simulation's. Returns the trajectory."""
    path = check_out_path(path)
    tl = Timeline.of(cfg)
    rng = np.random.default_rng(seed)
    p = draw_errors(cfg, [rng])
    rng_g = np.random.Generator(type(rng.bit_generator)())
    rng_g.bit_generator.state = rng.bit_generator.state
    for a in range(0, tl.n, chunk_rows):     # past the accelerometer noise, a block at a time
        rng_g.standard_normal((min(chunk_rows, tl.n - a), 3))
    if noise_free:
        p = ErrorParams(*(np.zeros_like(a) for a in (p.bias_a, p.scale, p.k2, p.M, p.bias_g, p.g_sens, p.phi0)))
    sa, sg = noise_sigmas(cfg)
    R = record_rotation(p.phi0)
    nav_true, nav_inst = Navigator(np.zeros((1, 3)), cfg.omega_ie), Navigator(np.zeros((1, 3)), cfg.omega_ie)
    nabla = accel_error(p, np.array([[0.0, 0.0, 9.80665]]))[:, 0]
    with record_writer(path, truth=truth_side(seed, p, nabla), float_format=RECORD_FLOATS) as write:
        for a in range(0, tl.n, chunk_rows):
            k = np.arange(a, min(a + chunk_rows, tl.n))
            f, w = tl.true_imu_at(k, cfg.omega_ie)
            if noise_free:
                wa = wg = np.zeros((1, k.size, 3))
            else:
                wa = (rng.standard_normal((k.size, 3)) * sa)[None]
                wg = (rng_g.standard_normal((k.size, 3)) * sg)[None]
            fm, wm = measure(p, f, w, wa, wg)
            f_rec = np.einsum("sij,snj->sni", R, fm)
            w_rec = np.einsum("sij,snj->sni", R, wm)
            vt, rt, _ = nav_true.step(f[None], w[None], cfg.dt)
            f_inst = f + accel_error(p, f) + wa
            _, ri, _ = nav_inst.step(f_inst, np.broadcast_to(w, f_inst.shape), cfg.dt)
            write(record_frame(k * cfg.dt, f_rec[0], w_rec[0], rt[0, :-1, 0], vt[0, :-1, 0], ri[0, :-1, 0]))
    return tl
