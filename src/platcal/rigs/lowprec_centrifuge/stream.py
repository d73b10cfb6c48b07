"""A low-precision centrifuge record identified in bounded memory (issue 22 item 3;
docs/lowprec-centrifuge.md §7, §10, §12).

:func:`scan_record` reads the record once, ``--chunk-rows`` rows at a time, and keeps only what the
identification needs after the read: the spins' levels and sample counts, the plausibility
check's sums (:class:`platcal.estimation.fit.Moments`), the plateaus' end samples (the
traditional method, eq. (2)) and, per filter window, the integrals at its ends (§7). Everything
that spans samples is carried from chunk to chunk so that the numbers are the whole record's:

* the heading is unwrapped with its running correction (numpy's :func:`numpy.unwrap`, its
  cumulative sum continued), the trapezoid integrals of the window observations and of the force
  terms with their running sums (``cumsum`` continued from the last value: the same additions in
  the same order), so the window means, and the filter's estimates, are bit-identical to the
  whole read's;
* a chunk is processed with :data:`CONTEXT` samples of the chunks around it: the velocity's cubic
  spline (:func:`.record.velocity_derivative`'s windows), the heading rate over +-5 samples
  (:func:`.record.check_against_config`) and the nominal velocity's gradient
  (:func:`.record.nominal_velocity`) see the samples they see in the whole record;
* a window boundary's integral reads the two samples around it
  (:func:`.proposed.boundary_integrals`) and is evaluated when they are both read.

Held, besides two chunks and their context (:data:`WORK_ROWS` rows each by default): per filter
window its ends' integrals and times in doubling arrays (:class:`_Rows`: 112 bytes a window, up to
twice that as they double; 1 s windows while static, one per revolution: 2.4 MB for the 21 578
windows of a 6 h record), per spin its times and, with recorded fE, fN, its specific force and
velocity derivative (40 bytes a spinning sample, for the spin's median step and the
specific-force check), per traditional plateau its heading rates. Only the windows grow with the
static parts of a record; nothing is kept per sample.

The specific-force check (:func:`.record.check_plausible`) takes the median of fE / (dVE/dt) over
each spin's samples where the derivative exceeds half the spin's own 99th percentile (the whole
read took the 99th percentile over the whole record, rests included, which a record's length
moved).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from ...errors import InputError
from ...estimation.fit import Moments
from ... import records
from ...records import TimeCheck, check_gap, check_time_unit, iter_table
from .profile import HOLD, SCHEDULE_NAMES, SPINNING, STATIC
from .proposed import (MIN_STATIC_TAIL_S, STATIC_WINDOW_S, arm_offset, boundary_integrals, force_integrand,
                       window_means)
from .record import (NUMERIC, POSITIONS, REQUIRED, SCHEDULE_CODES, SPLINE_OVERLAP, TRUTH_COLUMNS, UNITS,
                     large_force_ratios, level_g, nominal_velocity)

RATE_HALF = 5
"""Samples each side of the heading-rate difference (the levels of :func:`.record.check_against_config`)."""
CONTEXT = SPLINE_OVERLAP
"""Samples of the neighbouring chunks a chunk is processed with (the spline's overlap, which
covers the heading rate's 5 and the gradient's 1)."""
CARRY = ("t", "y", "c", "yf", "cf", "psi_u")
"""The per-sample arrays whose last two samples are carried to the next chunk (window boundaries
between chunks and at the record's end)."""
WORK_ROWS = 10_000
"""Rows a streamed identify reads and processes at a time when ``--chunk-rows`` is not given: its
working set (the block with its context, the integrands, their integrals, the spline) is about
1.1 kB a row (tracemalloc around :func:`scan_record`: 13 MB at 10 000 rows, 115 MB at
:data:`platcal.records.CHUNK_ROWS`, 100 000; 1 h record). A 6 h record on ahead-of-time kernels
peaks at 150-156 MB of RSS against 292. Every output is the same: the integrals are running
sums and the spline's context decays below round-off (:data:`.record.SPLINE_OVERLAP`)."""


class _Rows:
    """A float64 (or ``dtype``) table of ``width`` columns grown by doubling: per-window values
    held in one array of 8 bytes a value, not as Python tuples of small arrays (some 400 bytes a
    window), so what a long record's windows hold stays small."""

    def __init__(self, width: int, dtype=float):
        self.data = np.empty((64, width), dtype)
        self.n = 0

    def append(self, row) -> int:
        """Add ``row`` (NaN-filled when None, float tables only); returns its index."""
        if self.n == self.data.shape[0]:
            grown = np.empty((2 * self.n, self.data.shape[1]), self.data.dtype)
            grown[:self.n] = self.data
            self.data = grown
        self.data[self.n] = np.nan if row is None else row
        self.n += 1
        return self.n - 1

    def view(self) -> np.ndarray:
        """The rows added so far (a view)."""
        return self.data[:self.n]


@dataclass
class Scan:
    """What a streamed read keeps of a record (see the module docstring)."""

    samples: int = 0
    counts: dict = field(default_factory=lambda: {"static": 0, "spinning": 0, "hold": 0})
    spins: list = field(default_factory=list)       # (level g, t start, t end, samples) per non-static stretch
    holds: list = field(default_factory=list)       # (level g, t start, t end, samples, median step s)
    plateau_ends: list = field(default_factory=list)  # ((t, VE, VN, psi) first, (...) last) per hold plateau
    velocity: Moments = field(default_factory=lambda: Moments.zero(2))   # VE, VN against the arm's motion
    position: Moments = field(default_factory=lambda: Moments.zero(2))   # pE, pN against the integral of VE, VN
    force_ratios: tuple = ((), ())                  # fE/(dVE/dt), fN/(dVN/dt) of the spins' large samples
    f_recorded: bool = True
    truth: dict | None = None
    windows: tuple | None = None                    # (T, z, m, spinning) of §7, when windows were asked for
    window_error: InputError | None = None          # why the windows cannot be cut (raised by the caller)


def _unwrap_tail(prev: float | None, corr: float, psi: np.ndarray) -> tuple[np.ndarray, float]:
    """``psi`` (rad) unwrapped after the sample ``prev`` (None: the record's first) whose
    cumulative correction is ``corr``: :func:`numpy.unwrap`'s arithmetic with its cumulative sum
    continued, so the chunks give the whole record's values bit for bit. Returns (unwrapped, the
    last sample's correction)."""
    if prev is None:   # the first sample stays as it is
        if psi.size == 1:
            return psi.copy(), 0.0
        out, last = _unwrap_tail(float(psi[0]), 0.0, psi[1:])
        return np.r_[psi[:1], out], last
    dd = np.diff(np.r_[prev, psi])
    ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi
    np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
    ph = ddmod - dd
    np.copyto(ph, 0, where=abs(dd) < np.pi)
    cum = np.cumsum(np.r_[corr, ph])[1:]
    return psi + cum, float(cum[-1])


def _cumtrap_tail(t_prev, y_prev, c_prev, t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`.proposed.cumtrap` of the samples ``t, y`` continued after the sample (t_prev,
    y_prev) with integral c_prev (None: the record's first sample, integral 0)."""
    if t_prev is None:
        c = np.empty_like(y)
        c[0] = 0.0
        if t.size > 1:
            c[1:] = _cumtrap_tail(t[0], y[0], c[0], t[1:], y[1:])
        return c
    tt = np.r_[t_prev, t]
    yy = np.vstack([y_prev, y])
    terms = 0.5 * np.diff(tt)[:, None] * (yy[1:] + yy[:-1])
    return np.cumsum(np.vstack([c_prev, terms]), axis=0)[1:]


def _chunks(path, rate_hz: float, max_gap_s: float, mapping, chunk_rows: int | None, scan: Scan):
    """The record's chunks as the arrays the identification uses (65 bytes a sample), times and
    schedule checked as they are read (InputError naming the column and row)."""
    times = TimeCheck("--data column t")
    last_t, row = None, 0
    for df in iter_table(path, REQUIRED, tuple(c for c in NUMERIC if c not in REQUIRED) + TRUTH_COLUMNS,
                         text=("schedule",), what="a lowprec_centrifuge record", min_rows=3, mapping=mapping,
                         units=UNITS, positions=POSITIONS, chunk_rows=chunk_rows, unused=TRUTH_COLUMNS):
        if row == 0:
            has_f = ("fE" in df.columns, "fN" in df.columns)
            if any(has_f) and not all(has_f):
                raise InputError(f"--data column {'fN' if has_f[0] else 'fE'}",
                                 "the specific force comes as both fE and fN or not at all")
            scan.f_recorded = all(has_f)
        t = df["t"].to_numpy(float)
        times(t)
        ahead = t if last_t is None else np.r_[last_t, t]
        if ahead.size >= 2:
            # the whole read's median step, here per chunk (a record's rate does not change in it)
            check_time_unit(ahead, 1.0 / rate_hz, "--data column t",
                            f"profile.rate_hz = {rate_hz:g} Hz, a step of {1.0 / rate_hz:g} s")
            check_gap(ahead, max_gap_s, "--data column t", "record.max_gap_s", 1.0 / rate_hz)
        sched_s = df["schedule"].astype(str)
        code = sched_s.map(SCHEDULE_CODES)
        if code.isna().any():
            i = int(np.flatnonzero(code.isna().to_numpy())[0])
            raise InputError(f"--data column schedule, row {row + i + 2}",
                             f"{sched_s.iloc[i]!r} is not one of {list(SCHEDULE_NAMES)}")
        out = {"t": t, "v": np.column_stack([df["VE"].to_numpy(float), df["VN"].to_numpy(float)]),
               "p": np.column_stack([df["pE"].to_numpy(float), df["pN"].to_numpy(float)]),
               "psi": np.radians(df["heading_deg"].to_numpy(float)), "sched": code.to_numpy(np.int8)}
        if scan.f_recorded:
            out["f"] = np.column_stack([df["fE"].to_numpy(float), df["fN"].to_numpy(float)])
        del df, sched_s, code
        last_t = float(t[-1])
        row += t.size
        yield out


def _with_context(chunks, context: int):
    """``(block, a, b)`` per chunk: the chunk's arrays as rows ``a:b`` of ``block``, which holds
    up to ``context`` rows of the record before and after it (fewer only at the record's ends)."""
    buf, start, lengths = None, 0, []
    done = False
    it = iter(chunks)
    while True:
        try:
            nxt = next(it)
            buf = nxt if buf is None else {k: np.concatenate([buf[k], nxt[k]]) for k in buf}
            lengths.append(next(iter(nxt.values())).shape[0])
        except StopIteration:
            done = True
        n = 0 if buf is None else buf["t"].shape[0]
        while lengths and (done or n - (start + lengths[0]) >= context):
            a, b = start, start + lengths.pop(0)
            hi = min(b + context, n)
            yield {k: x[:hi] for k, x in buf.items()}, a, b
            cut = max(b - context, 0)
            buf = {k: x[cut:] for k, x in buf.items()}
            n -= cut
            start = b - cut
        if done:
            return


def scan_record(path, arm_m: float, rate_hz: float, max_gap_s: float, mapping, chunk_rows: int | None,
                windows: bool, use_truth: bool = True) -> Scan:
    """Read and check the record at ``path`` ``chunk_rows`` rows at a time (None: whole) and keep
    what :func:`.commands.identify` needs (:class:`Scan`): ``windows`` cuts the proposed filter's
    windows (§7) and evaluates their observations; a record whose windows cannot be cut keeps the
    reason in ``window_error`` (raised after the record's other checks, as the whole read did).
    The arm ``arm_m`` (m) sets the nominal motion and the levels (A = w^2 r / g0)."""
    scan = Scan()
    st = _State(scan, arm_m, windows)
    for block, a, b in _with_context(_unwrapped(_chunks(path, rate_hz, max_gap_s, mapping, chunk_rows, scan)),
                                           CONTEXT):
        st.chunk(block, a, b)
    st.finish()
    if use_truth:
        scan.truth = records.read_truth(Path(path))
    return scan


def _unwrapped(chunks):
    """Each chunk with ``psi_u``, its heading unwrapped as the whole record's (:func:`_unwrap_tail`)."""
    prev, corr = None, 0.0
    for ch in chunks:
        ch["psi_u"], corr = _unwrap_tail(prev, corr, ch["psi"])
        prev = float(ch["psi"][-1])
        yield ch


class _State:
    """The running state of :func:`scan_record` between chunks."""

    def __init__(self, scan: Scan, arm_m: float, windows: bool):
        self.scan, self.arm, self.want_windows = scan, arm_m, windows
        self.tail = None          # CARRY arrays of the last two samples read
        self.u0 = None            # (cos, sin) of the first heading
        self.p0 = None
        self.prev = None          # the last sample: t, moving, hold, v, psi, psi_u
        self.first_moving = None
        self.spin = None          # the spin being read
        self.hold = None          # the plateau being read
        self.stretch = None       # the static stretch being read: [a, next candidate index, first slot]
        self.pending = []         # (instant, slot) of window boundaries not evaluated yet
        self.values = _Rows(9)    # per slot: integral of y (4), of the force terms (4), heading
        self.win = _Rows(2, np.int64)   # per window: slot of its start, of its end
        self.win_t = _Rows(3)     # per window: ts, te (s), spinning (1.0) or not (0.0)
        self.ratios = ([], [])
        self.any_moving = False

    # -- boundaries ---------------------------------------------------------------------------
    def boundary(self, tb: float) -> int:
        slot = self.values.append(None)
        self.pending.append((tb, slot))
        return slot

    def resolve(self, loc: dict, final: bool = False) -> None:
        """Evaluate the pending boundaries the samples ``loc`` bracket (all of them at the end)."""
        if not self.pending:
            return
        t = loc["t"]
        ready = [(tb, s) for tb, s in self.pending if final or tb < t[-1]]
        if not ready:
            return
        self.pending = [(tb, s) for tb, s in self.pending if not (final or tb < t[-1])]
        tb = np.array([r[0] for r in ready])
        iy = boundary_integrals(t, loc["y"], loc["c"], tb)
        if_ = boundary_integrals(t, loc["yf"], loc["cf"], tb)
        ps = np.interp(tb, t, loc["psi_u"])
        vals = self.values.data
        for j, (_, s) in enumerate(ready):
            vals[s, 0:4], vals[s, 4:8], vals[s, 8] = iy[j], if_[j], ps[j]

    # -- static stretches and spins -----------------------------------------------------------
    def static_candidates(self, upto: float) -> None:
        """Queue the 1 s window edges a + i delta (numpy.arange's values) of the static stretch up to ``upto``."""
        a, i, first = self.stretch
        delta = (a + STATIC_WINDOW_S) - a
        while a + i * delta <= upto:
            slot = self.boundary(a + i * delta)
            # a stretch's candidates take consecutive slots (nothing else is cut while static)
            first = slot if first is None else first
            i += 1
        self.stretch[1:] = [i, first]

    def close_stretch(self, b: float) -> None:
        """The static stretch's windows (:func:`.proposed._static_windows`) from its end ``b`` (s)."""
        a, _, first = self.stretch
        self.stretch = None
        if b - a <= 1e-9:
            return
        edges = np.arange(a, b - 1e-9, STATIC_WINDOW_S)
        ids = ([] if first is None else list(range(first, first + edges.size))) + [self.boundary(b)]
        times = list(edges) + [b]
        if len(times) > 2 and times[-1] - times[-2] < MIN_STATIC_TAIL_S:
            del times[-2], ids[-2]
        for k in range(len(ids) - 1):
            self.win.append((ids[k], ids[k + 1]))
            self.win_t.append((times[k], times[k + 1], 0.0))

    def spin_samples(self, t, psi_u) -> None:
        """Running max of the heading from the spin's start and its crossings of g0 + 2 pi k
        (:func:`.proposed.revolution_crossings`), for the samples ``t, psi_u`` of the spin."""
        sp = self.spin
        rm = np.maximum.accumulate(np.r_[sp["rm"], psi_u])
        tt = np.r_[sp["t_prev"], t]
        while True:
            target = sp["g0"] + 2 * np.pi * sp["k"]
            if not target <= rm[-1]:
                break
            j = int(np.searchsorted(rm, target, side="left"))
            frac = (target - rm[j - 1]) / (rm[j] - rm[j - 1])
            tc = tt[j - 1] + frac * (tt[j] - tt[j - 1])
            sp["cross"].append((tc, self.boundary(tc)))
            sp["k"] += 1
        sp["rm"], sp["t_prev"] = rm[-1], tt[-1]
        sp["t"].append(t)

    def close_spin(self, t_ib: float) -> None:
        sp = self.spin
        self.spin = None
        if not self.want_windows or self.scan.window_error is not None:
            return
        k = int(np.floor((sp["rm"] - sp["g0"]) / (2 * np.pi)))
        if k < 1:
            self.scan.window_error = InputError(
                "heading_deg", f"the heading never completes a revolution during the spin from t = {sp['t_ia']:.2f} s "
                f"to {t_ib:.2f} s (it turns {np.degrees(sp['rm'] - sp['g0']):.1f} deg)")
            return
        cross = sp["cross"][:k]
        edges = [(sp["t_ia"], sp["slot_ia"]), *cross]
        ib = (t_ib, self.boundary(t_ib))
        if t_ib - edges[-1][0] < 0.5 * float(np.median(np.diff(np.concatenate(sp["t"])))):
            edges[-1] = ib
        else:
            edges.append(ib)
        for (ta, sa), (tb, sb) in zip(edges[:-1], edges[1:]):
            self.win.append((sa, sb))
            self.win_t.append((ta, tb, 1.0))

    # -- a chunk ------------------------------------------------------------------------------
    def chunk(self, blk: dict, a: int, b: int) -> None:
        scan, arm = self.scan, self.arm
        t, sched = blk["t"][a:b], blk["sched"][a:b]
        n = t.size
        scan.samples += n
        moving = sched != STATIC
        hold = sched == HOLD
        scan.counts["static"] += int(np.sum(sched == STATIC))
        scan.counts["spinning"] += int(np.sum(sched == SPINNING))
        scan.counts["hold"] += int(np.sum(hold))
        if self.first_moving is None:
            self.first_moving = bool(moving[0])
        self.any_moving |= bool(moving.any())
        psi_u = blk["psi_u"][a:b]
        v, p = blk["v"][a:b], blk["p"][a:b]
        lo, hi = max(a - CONTEXT, 0), min(b + CONTEXT, blk["t"].shape[0])
        need_d = not scan.f_recorded or bool(moving.any())
        d = CubicSpline(blk["t"][lo:hi], blk["v"][lo:hi], axis=0).derivative()(t) if need_d else None
        f = blk["f"][a:b] if scan.f_recorded else d
        # heading rate over +-5 samples, 0 within 5 samples of the record's ends
        rate = np.zeros(n)
        i = np.arange(a, b)
        ok = (i - RATE_HALF >= 0) & (i + RATE_HALF < blk["t"].shape[0])
        pu, tb_ = blk["psi_u"], blk["t"]
        rate[ok] = (pu[i[ok] + RATE_HALF] - pu[i[ok] - RATE_HALF]) / (tb_[i[ok] + RATE_HALF] - tb_[i[ok] - RATE_HALF])
        # the plausibility sums: the velocities against the arm's motion (np.gradient, one sample of context)
        g0, g1 = max(a - 1, 0), min(b + 1, blk["t"].shape[0])
        nominal = nominal_velocity(tb_[g0:g1], pu[g0:g1], arm)
        scan.velocity.add(v, nominal[a - g0:a - g0 + n])
        # the window observations' integrands and their running trapezoid integrals
        if self.u0 is None:
            self.u0 = np.array([np.cos(psi_u[0]), np.sin(psi_u[0])])
            self.p0 = p[0].copy()
        y = np.concatenate([v, arm_offset(p, psi_u, self.u0, arm)], axis=1)
        yf = force_integrand(f)
        tl = self.tail
        c = _cumtrap_tail(*((None,) * 3 if tl is None else (tl["t"][-1], tl["y"][-1], tl["c"][-1])), t, y)
        cf = _cumtrap_tail(*((None,) * 3 if tl is None else (tl["t"][-1], tl["yf"][-1], tl["cf"][-1])), t, yf)
        scan.position.add(p - self.p0, c[:, 0:2])
        self.runs(t, moving, hold, v, blk["psi"][a:b], psi_u, rate, f if scan.f_recorded else None, d)
        cur = {"t": t, "y": y, "c": c, "yf": yf, "cf": cf, "psi_u": psi_u}
        loc = cur if tl is None else {k: np.concatenate([tl[k][-1:], cur[k]]) for k in CARRY}
        self.resolve(loc)
        self.tail = {k: np.concatenate([tl[k], cur[k]])[-2:] if tl is not None else cur[k][-2:] for k in CARRY}

    def runs(self, t, moving, hold, v, psi, psi_u, rate, f, d) -> None:
        """The chunk's stretches of constant state: spins (non-static), plateaus (hold) and rests."""
        n = t.size
        prev = self.prev
        cuts = np.flatnonzero(np.diff(moving.astype(np.int8))) + 1
        starts = np.r_[0, cuts]
        stops = np.r_[cuts, n]
        for r0, r1 in zip(starts, stops):
            mv = bool(moving[r0])
            if mv:
                if self.spin is None:   # a spin starts: ia is the sample before (static, or none)
                    t_ia = prev["t"] if prev is not None else None
                    self.spin = {"peak": 0.0, "t_a": float(t[r0]), "count": 0, "rm": None, "k": 1,
                                 "cross": [], "t": [], "d": [], "f": []}
                    if self.stretch is not None:
                        self.close_stretch(t_ia)
                    if t_ia is not None:
                        sp = self.spin
                        sp.update(g0=prev["psi_u"], rm=prev["psi_u"], t_prev=t_ia, t_ia=t_ia, t=[np.array([t_ia])])
                        if self.want_windows:
                            sp["slot_ia"] = self.boundary(t_ia)
                sp = self.spin
                sp["peak"] = max(sp["peak"], float(np.max(np.abs(rate[r0:r1]))))
                sp["count"] += r1 - r0
                sp["t_b"] = float(t[r1 - 1])
                if sp["rm"] is not None and self.want_windows:
                    self.spin_samples(t[r0:r1], psi_u[r0:r1])
                if f is not None:
                    sp["d"].append(d[r0:r1])
                    sp["f"].append(f[r0:r1])
            else:
                if self.spin is not None:   # the spin ends at this first static sample ib
                    sp = self.spin
                    self.scan.spins.append((level_g(sp["peak"], self.arm), sp["t_a"], sp["t_b"], sp["count"]))
                    self.force_check(sp)
                    if sp["rm"] is not None and self.want_windows:
                        self.spin_samples(t[r0:r0 + 1], psi_u[r0:r0 + 1])
                    if sp["rm"] is not None:
                        self.close_spin(float(t[r0]))
                    else:
                        self.spin = None
                if self.stretch is None and self.want_windows:
                    self.stretch = [float(t[r0]), 0, None]
                if self.stretch is not None:
                    self.static_candidates(float(t[r1 - 1]))
            prev = {"t": float(t[r1 - 1]), "psi_u": float(psi_u[r1 - 1])}
        self.prev = prev
        self.plateaus(t, moving, hold, v, psi, rate)

    def plateaus(self, t, moving, hold, v, psi, rate) -> None:
        """The traditional run's hold plateaus: median heading rate, first and last samples."""
        n = t.size
        cuts = np.flatnonzero(np.diff(hold.astype(np.int8))) + 1
        for r0, r1 in zip(np.r_[0, cuts], np.r_[cuts, n]):
            if not hold[r0]:
                if self.hold is not None:
                    self.close_hold()
                continue
            if self.hold is None:
                self.hold = {"rate": [], "t": [], "first": (float(t[r0]), v[r0].copy(), float(psi[r0]))}
            self.hold["rate"].append(np.abs(rate[r0:r1]))
            self.hold["t"].append(t[r0:r1])
            self.hold["last"] = (float(t[r1 - 1]), v[r1 - 1].copy(), float(psi[r1 - 1]))

    def close_hold(self) -> None:
        h = self.hold
        self.hold = None
        w = float(np.median(np.concatenate(h["rate"])))
        tt = np.concatenate(h["t"])
        step = float(np.median(np.diff(tt))) if tt.size > 1 else 0.0
        self.scan.holds.append((level_g(w, self.arm), h["first"][0], h["last"][0], int(tt.size), step))
        self.scan.plateau_ends.append((h["first"], h["last"]))

    def force_check(self, sp: dict) -> None:
        """The spin's ratios of f to the velocity's derivative (:func:`.record.large_force_ratios`)."""
        if not sp["d"]:
            return
        for c, r in enumerate(large_force_ratios(np.concatenate(sp["f"]), np.concatenate(sp["d"]))):
            self.ratios[c].append(r)

    def finish(self) -> None:
        scan = self.scan
        if self.hold is not None:
            self.close_hold()
        ends_moving = self.spin is not None
        if ends_moving:
            sp = self.spin
            scan.spins.append((level_g(sp["peak"], self.arm), sp["t_a"], sp["t_b"], sp["count"]))
            self.force_check(sp)
            self.spin = None
        scan.force_ratios = tuple(np.concatenate(r) if r else np.zeros(0) for r in self.ratios)
        if not self.want_windows:
            return
        if not self.any_moving:
            scan.window_error = InputError("schedule", "the record never spins (no non-static sample)")
        elif self.first_moving:
            scan.window_error = InputError("schedule", "the record starts while spinning; it must start at rest")
        elif ends_moving:
            scan.window_error = InputError("schedule", "the record ends while spinning; it must end at rest")
        if scan.window_error is not None:
            return
        self.close_stretch(float(self.tail["t"][-1]))
        self.resolve(self.tail, final=True)
        ia, ib = self.win.view().T
        vals, wt = self.values.view(), self.win_t.view()
        iy, if_, ps = vals[:, 0:4], vals[:, 4:8], vals[:, 8]
        tt, z, m = window_means(wt[:, 0].copy(), wt[:, 1].copy(), iy[ia], iy[ib], if_[ia], if_[ib], ps[ia], ps[ib],
                                self.arm)
        scan.windows = (tt, z, m, wt[:, 2] == 1.0)
