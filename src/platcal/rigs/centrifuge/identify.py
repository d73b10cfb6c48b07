"""Identification of one test record: record -> EKF estimate -> tables on disk."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from ...estimation.consistency import chi2_quantile, estimate_problems, nees
from ...estimation.fit import FitCheck, FitSums, Moments, fit_check, gross_errors_moments
from ...estimation.passes import pass_prefixes as shared_pass_prefixes
from ...io import atomic_files, json_text, write_csv, write_csv_blocks
from ...logs.calibration import Calibration, calibration_of, write_calibration_files, write_covariance
from ...logs.dwells import DWELL_FIGURE, dwells_found
from ...model.instruments import unit_of
from ...plausibility import (ClockRate, clock_rate, clock_rate_tolerance, refuse_clock_rate, refuse_recognised,
                             refuse_recognised_moments, spilled_jitter, spilled_segment_rate, timestamp_jitter)
from ... import records
from ...records import ColumnSpill, RowsAt
from ...rig import resolve
from .catalogue import load_catalogue
from .config import Study
from .ekf import Estimate, EstimatorInput, FilterSettings, StreamedInstants, first_instant
from .estimators import check_kind, run_estimator
from .record import (COMMANDED_COLUMNS, CONTINUOUS_COLUMNS, OPTIONAL_COLUMNS, UNITS, FilterInput, check_commanded,
                     check_every_position, check_position_numbers, check_position_spilled, check_record,
                     continuous_record, filter_input, has_truth_columns, instants_spilled_blocks)
from ...records import read_table, spilled_positions
from ...scheme import Scheme, whole_periods
from .simulate import simulate, simulate_chunks
from .tables import estimates_columns, table2_markdown

if TYPE_CHECKING:  # annotations only: an identify loads no pandas (issue 22 item 3)
    import pandas as pd
    from ...mapping import RecordMapping  # and a Monte Carlo cell no pint (issue 22 item 4)


def simulate_identify(study: Study, scheme: Scheme, seeds, settings: FilterSettings | None = None,
                      truth: np.ndarray | None = None) -> Estimate:
    """Simulate a batch (one run per SeedSequence; ``seeds=None``: one noise-free run) and identify
    it with the study's estimator (``filter.estimator``, the EKF by default): the one simulate ->
    identify path of the centrifuge (Monte Carlo, design studies, observability checks), its EKF
    passes on the state-major kernel (``FilterSettings.lanes``). ``settings`` defaults to the
    study's filter without history; ``truth`` (48,) to the study's. Runs are independent: a batch
    gives the numbers of B runs of one.
    """
    outputs, times = simulate_outputs(study, scheme, seeds, truth)
    return identify_simulated(study, scheme, outputs, times, settings)


def simulate_outputs(study: Study, scheme: Scheme, seeds, truth: np.ndarray | None = None,
                     keep_every: int | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The simulated batch of :func:`simulate_identify`: each position's accelerometer outputs
    (K arrays (B, M, 3), g) at every ``keep_every``-th sample (default the study's filter period,
    ``study.keep_every``) and their instants (K arrays (M,), s since the position's start, the
    reset instant t = 0 first) (docs/centrifuge-model.md §8). The outputs at every k-th instant of
    a batch kept at ``keep_every`` are those of the batch kept at k x ``keep_every``, bit for bit:
    the simulation steps every sample whatever it keeps."""
    truth = study.truth if truth is None else truth
    keep = study.keep_every if keep_every is None else int(keep_every)
    # each position's outputs as the simulation yields them (one chunk per position: the numbers
    # of simulate()), not copied into simulate()'s (B, K, N, 3) outputs and true angles first:
    # the filter reads only the outputs, and end to end (issue 22 item 4)
    parts = list(simulate_chunks(truth, scheme, study.centrifuge.scheme_params(scheme), study.noise, seeds,
                                 sample_s=study.sample_s, keep_every=keep))
    return [p.A for p in parts], [p.t for p in parts]


def identify_simulated(study: Study, scheme: Scheme, outputs: list, times: list,
                       settings: FilterSettings | None = None, on_pass=None) -> Estimate:
    """Identify a simulated batch with the study's estimator: ``outputs`` and ``times`` as
    :func:`simulate_outputs` gives them at the study's filter period (docs/centrifuge-model.md
    §8-9); ``settings`` as :func:`simulate_identify`'s; ``on_pass`` as
    :func:`~.estimators.run_estimator`'s."""
    # the state-major kernel: the same numbers bit for bit, a third less CPU at B >= 8, and every
    # job of a study (cells, design, campaign, single run) then loads the one kernel the study's
    # kernels job compiled (issue 22 item 4); an identify of one record keeps the default kernel
    fs = replace(replace(study.filter, history_every_s=None) if settings is None else settings, lanes=True)
    # the samples at the reset instant (t = 0) are not used unless filter.update_at_reset
    i0 = first_instant(fs.update_at_reset)
    return run_estimator(EstimatorInput([a[:, i0:] for a in outputs], [t[i0:] for t in times], scheme.angles_deg,
                                        study.centrifuge.scheme_params(scheme)), fs, on_pass)


@dataclass(frozen=True)
class SharedRecords:
    """A batch simulated once for several estimators (:func:`simulate_shared`): each position's
    outputs (K arrays (B, M, 3), g) and instants (K arrays (M,), s) kept at every
    ``keep_every``-th sample, the greatest common divisor of the estimators' filter periods in
    samples (docs/centrifuge-model.md §8)."""

    keep_every: int
    outputs: list
    times: list


def simulate_shared(studies: list[Study], scheme: Scheme, seeds) -> SharedRecords:
    """One simulated batch (one run per SeedSequence) for every study of ``studies`` (the same
    model, truth and noise; estimators and filter periods of their own): the simulation reads no
    filter setting, so the first study simulates for all, kept at the gcd of their periods."""
    keep = math.gcd(*(st.keep_every for st in studies))
    outputs, times = simulate_outputs(studies[0], scheme, seeds, keep_every=keep)
    return SharedRecords(keep, outputs, times)


def identify_shared(study: Study, scheme: Scheme, records: SharedRecords, on_pass=None) -> Estimate:
    """:func:`identify_simulated` of ``study`` on shared records, reading every k-th kept sample
    (k = its period over theirs): the numbers of :func:`simulate_identify` with the same seeds, bit
    for bit (the simulation steps every sample whatever it keeps). ``on_pass`` as
    :func:`~.estimators.run_estimator`'s."""
    k = study.keep_every // records.keep_every
    return identify_simulated(study, scheme, [a[:, ::k] for a in records.outputs], [t[::k] for t in records.times],
                              on_pass=on_pass)


def same_but_passes(a: FilterSettings, b: FilterSettings) -> bool:
    """Whether two filters differ in ``passes`` at most (every other setting equal, arrays by value)."""
    for f in fields(FilterSettings):
        if f.name == "passes":
            continue
        u, v = getattr(a, f.name), getattr(b, f.name)
        if isinstance(u, np.ndarray) or isinstance(v, np.ndarray):
            if u is None or v is None or not np.array_equal(u, v):
                return False
        elif u != v:
            return False
    return True


def pass_prefixes(filters: dict[str, FilterSettings]) -> dict[str, tuple[str, int]]:
    """Which estimators' runs another's gives on the way (docs/centrifuge-model.md §9: pass p
    reads nothing of the passes after it): name -> (the estimator of ``filters`` (name -> its
    filter) whose settings differ only by more passes, the name's passes), for a kind with pass snapshots
    (:func:`platcal.estimation.passes.pass_prefixes`: the most passes, the first listed on a tie).
    The estimators of one noise level run on the same records (:func:`simulate_shared`), so such a
    name's numbers are that run's after its own passes, bit for bit. Names that run themselves are
    not keys."""
    return shared_pass_prefixes({n: f.passes for n, f in filters.items()},
                                lambda a, b: (check_kind(filters[a].estimator).pass_snapshots
                                              and same_but_passes(filters[a], filters[b])))


FIT_CHANNELS = ("Ax", "Ay", "Az")
"""The measured channels, as the record names them (docs/centrifuge-model.md §13)."""


def record_input(study: Study, scheme: Scheme, df: pd.DataFrame) -> FilterInput:
    """Check a read test record against the scheme and sampling (InputError before any work) and
    select the samples the filter uses; then its plausibility: no unit, sign or swap of Ax, Ay, Az
    against the nominal output (:func:`nominal_output`)."""
    check_record(df, scheme, study.sample_s, float(study.config["record"]["max_gap_s"]),
                 expected_g=expected_g(study, scheme))
    fin = filter_input(df, scheme, study.filter.period_s, float(study.config["record"]["max_gap_s"]),
                       update_at_reset=study.filter.update_at_reset)
    refuse_recognised(np.concatenate(fin.z, axis=1)[0], nominal_output(study, scheme, fin), FIT_CHANNELS, "g",
                      "the record's Ax, Ay, Az must be the platform's x, y, z accelerometers in g")
    return fin


JITTER_SHARE = 0.3
"""The largest acceleration error a timestamp jitter may cause, as a share of sigma_a: 0.3 adds
at most 9 % to the measurement noise variance (docs/centrifuge-model.md §13)."""


def jitter_tolerance_s(study: Study, scheme: Scheme) -> float:
    """The largest RMS timestamp jitter, s, the record may carry (docs/centrifuge-model.md §13):
    a time error dt turns the table by omega dt, which moves the g_level centripetal force by
    omega dt g_level g, so omega jitter G <= JITTER_SHARE sigma_a (omega rad/s, sigma_a in g,
    G the largest g-level of the scheme); inf when the table does not turn."""
    cen = study.centrifuge
    omega = np.radians(abs(cen.rate_deg_s))
    level = float(np.max(expected_g(study, scheme)))
    if omega == 0:
        return np.inf
    return JITTER_SHARE * study.filter.sigma_a_ug * 1e-6 / (omega * level)


def clock_finding(study: Study, scheme: Scheme, df: pd.DataFrame) -> str | None:
    """The diagnosis of a record whose timestamps jitter more than :func:`jitter_tolerance_s`
    about their regular grid (sampling.sample_ms), naming column t; None otherwise. Not a
    refusal: stamps that are the true sample times are used as recorded (§13), so the jitter
    explains a record only when it does not fit."""
    pos = df["position"].to_numpy(float)
    jit = max(timestamp_jitter(df["t"].to_numpy(float)[pos == k], study.sample_s) for k in sorted({int(p) for p in pos}))
    return clock_text(study, scheme, jit)


def clock_text(study: Study, scheme: Scheme, jit: float) -> str | None:
    """:func:`clock_finding` from the largest RMS jitter ``jit`` (s) of the record's positions."""
    tol = jitter_tolerance_s(study, scheme)
    if jit <= tol:
        return None
    return (f"clock: column t jitters by {jit * 1e6:.3g} us RMS about the {study.sample_s * 1e3:g} ms grid; at "
            f"{study.centrifuge.rate_deg_s:g} deg/s and {np.max(expected_g(study, scheme)):.3g} g a timestamp error moves "
            f"the force by rate x jitter x g-level, so stamps that are not the true sample times must err by less than "
            f"{tol * 1e6:.3g} us ({JITTER_SHARE:g} sigma_a, docs/centrifuge-model.md §13): use the recorder's sample "
            "clock (or the table's encoder angle), not the host's")


def record_clock(study: Study, df: pd.DataFrame) -> ClockRate:
    """The record's clock-rate error against ``sampling.sample_ms`` (:func:`platcal.plausibility.clock_rate`),
    from every sample's stamp, position by position (each position's clock may restart)."""
    pos = df["position"].to_numpy(float)
    t = df["t"].to_numpy(float)
    return clock_rate([t[pos == k] for k in sorted({int(p) for p in pos})], study.sample_s)


def drift_gain(name: str, force_g: float) -> float:
    """The largest drift, deg/h, one unit of gyro coefficient ``name`` makes at a specific force of
    ``force_g`` g (docs/centrifuge-model.md §4): DF 1, DI, DO, DS |f|, DII, DOO, DSS |f|^2, a cross
    term DIO, DIS, DOS |f|^2 / 2 (the product of two components of |f| at most); 0 for a
    coefficient that is not a drift."""
    term = name.rsplit("_", 1)[0]
    if not unit_of(name).startswith("deg/h"):
        return 0.0
    axes = term[1:] if term != "DF" else ""
    return force_g ** len(axes) * (0.5 if len(set(axes)) == 2 else 1.0)


def check_clock_rate(study: Study, scheme: Scheme, est: Estimate, rate: ClockRate) -> dict:
    """Refuse (exit 2, column t) a record whose clock runs off ``sampling.sample_ms`` by more than
    the rate error that moves the most sensitive coefficient by 0.3 of its sigma
    (docs/centrifuge-model.md §13, :func:`platcal.plausibility.clock_rate_tolerance`): a clock
    1 + e fast turns the model's table e x rate off the real one, an azimuth drift that any drift
    coefficient c reads as e x rate / gain_c (:func:`drift_gain` at the scheme's largest |f|), and
    stretches every drift's time by 1 + e. Needs the run's sigmas, so it follows the filter (the
    outputs are not written). Returns the summary's ``clock`` block when it passes."""
    nc = est.n_coef
    names = est.names[:nc]
    force = float(np.max(expected_g(study, scheme)))
    per_hour = [unit_of(n).startswith("deg/h") for n in names]
    gain = [drift_gain(n, force) for n in names]
    omega_deg_h = abs(study.centrifuge.rate_deg_s) * 3600.0
    tol, most = clock_rate_tolerance(names, est.coef[0], est.coef_sigma[0], per_hour, omega_deg_h, gain)
    return refuse_clock_rate(rate, tol, most, "sampling.sample_ms", "docs/centrifuge-model.md §13",
                             " (or the table's encoder angle)")


def expected_g(study: Study, scheme: Scheme) -> np.ndarray:
    """(K,) magnitude of the specific force at each position, g: centripetal level and gravity
    at right angles (docs/centrifuge-model.md §2, eq. 10; 1 g when the centrifuge is off)."""
    cen = study.centrifuge
    levels = np.array(scheme.g_levels if scheme.g_levels else [cen.g_level] * scheme.n_positions, float)
    if cen.rate_deg_s == 0:
        levels = np.zeros_like(levels)
    return np.hypot(levels, 1.0)


def continuous_input(study: Study, scheme: Scheme, path, mapping: RecordMapping | None) -> tuple[pd.DataFrame, tuple]:
    """A continuous log (one clock, no ``position`` column; docs/centrifuge-model.md §13) read
    whole and cut into the scheme's positions (:func:`.record.continuous_record`): the dwells
    at the positions' specific-force levels (:func:`expected_g`), matched by the commanded angles
    or, without them, by the mean outputs of the nominal instrument (every coefficient 0) over
    each position. Returns the labelled record, which then takes every check of a labelled one,
    and ``(t, |A|, dwells)`` for the figure."""
    df = read_table(path, CONTINUOUS_COLUMNS, COMMANDED_COLUMNS + OPTIONAL_COLUMNS, what="a continuous centrifuge log",
                    mapping=mapping, units=UNITS)
    has_truth_columns(df.columns)
    run = simulate(np.zeros_like(study.truth), scheme, study.centrifuge.scheme_params(scheme), study.noise, None,
                   sample_s=study.sample_s)
    return continuous_record(df, scheme, expected_g(study, scheme), run.A[0].mean(axis=1),
                             turning=study.centrifuge.rate_deg_s != 0)


def identify_input(study: Study, scheme: Scheme, fin: FilterInput) -> Estimate:
    """Run the study's estimator (``filter.estimator``) over the selected samples of a record (one
    run: a batch of one), keeping the innovations for the fit check (EKF, IEKF)."""
    params = study.centrifuge.scheme_params(scheme)[np.array(fin.positions) - 1]
    return run_estimator(EstimatorInput(fin.z, fin.t, fin.cmd_deg, params), replace(study.filter, innovations=True))


def nominal_output(study: Study, scheme: Scheme, fin: FilterInput) -> np.ndarray:
    """(M, 3) g: the noise-free output of the nominal instrument (every coefficient 0) at the
    commanded angles and the filter instants of ``fin`` (docs/centrifuge-model.md §2)."""
    params = study.centrifuge.scheme_params(scheme)
    run = simulate(np.zeros_like(study.truth), scheme, params, study.noise, None, sample_s=study.sample_s)
    return np.concatenate([run.A[0, k - 1, np.clip(np.rint(tk / study.sample_s).astype(int), 0, run.t.size - 1)]
                           for k, tk in zip(fin.positions, fin.t)])


def record_fit(est: Estimate, fin: FilterInput, study: Study, scheme: Scheme,
               clock: str | None = None) -> FitCheck | None:
    """The fit check (:func:`platcal.estimation.fit.fit_check`) of one run from the last pass's
    innovations of Ax, Ay, Az (g) and their predicted variances (docs/centrifuge-model.md §9);
    the diagnosis regresses the record on the noise-free output of the nominal instrument
    (all coefficients 0) at the commanded angles; ``clock`` (:func:`clock_finding`) joins the
    diagnosis of a record that does not fit. None for an estimator that keeps no innovations
    (UKF, ML)."""
    if est.innovations is None:
        return None
    rec = est.innovations[0]
    z = np.concatenate(fin.z, axis=1)[0]
    innov = rec[:, :3]
    nominal = nominal_output(study, scheme, fin)
    segment = np.concatenate([np.full(len(tk), k) for k, tk in zip(fin.positions, fin.t)])
    fit = fit_check(innov, rec[:, 3:], FIT_CHANNELS, predicted=z - innov, nominal=nominal, t=np.concatenate(fin.t),
                    segment=segment)
    if clock is not None and not fit.passed:
        fit = replace(fit, diagnosis=fit.diagnosis + (clock,))
    return fit


STREAMED_KINDS = ("ekf", "iekf")
"""The estimators that filter a streamed record block by block (the UKF keeps its own kernel and
the ML estimate needs the whole record at once: they read it whole)."""


@dataclass
class StreamScan:
    """What the first read of a streamed record gives (:func:`scan_record`): per position (in
    order) the number of filter instants ``counts`` and the last one ``last`` (s since its
    start), the record's row and instant (s since its position's start) of every filter
    instant end to end spilled to a temporary file ``instants`` (two columns; 16 bytes an
    instant on disk, none held: :meth:`close` removes it), whether the true angles are there,
    the largest timestamp jitter (s), and the sums of Ax, Ay, Az at the instants against the
    nominal output (the plausibility check and the fit's diagnosis)."""

    positions: list[int]
    counts: list[int]
    last: list[float]
    instants: ColumnSpill
    truth: bool
    jitter_s: float
    moments: Moments
    cmd_deg: np.ndarray
    clock: ClockRate
    """The clock-rate error of every sample's stamp against ``sampling.sample_ms`` (:func:`record_clock`)."""

    def close(self) -> None:
        """Remove the spilled instants."""
        self.instants.close()


class InstantCursor:
    """The spilled filter instants of a :class:`StreamScan` read back in order, a chunk of the
    record at a time (:meth:`below`), :data:`platcal.records.SPILL_BLOCK` of them held at most."""

    def __init__(self, spill: ColumnSpill):
        self._blocks = (v for _, v in spill.blocks())
        self._buf = np.zeros((0, 2))

    def below(self, row: int) -> tuple[np.ndarray, np.ndarray]:
        """``(rows, t)`` of the instants not yet taken whose record row is below ``row``."""
        parts = []
        while True:
            j = int(np.searchsorted(self._buf[:, 0], row))
            parts.append(self._buf[:j])
            if j < len(self._buf):
                self._buf = self._buf[j:]
                break
            nxt = next(self._blocks, None)
            self._buf = np.zeros((0, 2)) if nxt is None else nxt
            if nxt is None:
                break
        got = np.concatenate(parts) if len(parts) > 1 else parts[0]
        return got[:, 0].astype(np.int64), np.ascontiguousarray(got[:, 1])


def scan_record(chunks, study: Study, scheme: Scheme) -> StreamScan:
    """Check a record read in ``chunks`` (:func:`platcal.records.iter_table` tables, in file
    order) as :func:`record_input` checks a whole one, holding one position at a time.

    A streamed record holds each position as one block of rows, positions in increasing order
    (a logger's order; a record in any other order is read whole, ``--chunk-rows 0``). Every
    chunk's position numbers and commanded angles are checked as it comes; a position's checks
    (:func:`~.record.check_position`), clock figures and filter instants
    (:func:`~.record.select_instants`) need its times whole (their medians, the clock's line), so
    the position's ``t`` and ``Ax, Ay, Az`` are spilled to temporary files (32 bytes a sample on
    disk, :class:`platcal.records.ColumnSpill`) and taken by passes over them
    (:func:`~.record.check_position_spilled`, :func:`platcal.plausibility.spilled_segment_rate`,
    :func:`~.record.instants_spilled_blocks`), and the position's filter instants and their
    rows go to a temporary file as they are found (:attr:`StreamScan.instants`, 16 bytes an
    instant on disk); one more pass over them, the spilled outputs and a noise-free simulation
    of the position in chunks (the nominal output, :func:`nominal_blocks`) adds the sums of the
    plausibility check block by block. Held: a chunk or a spill block, whatever the record's
    length (issue 22 item 3). The sums are added per block, so they may differ from one sum
    over the position in the last bits (they decide refusals and diagnoses, not the estimate).
    """
    cmd = scheme.angles_deg
    max_gap = float(study.config["record"]["max_gap_s"])
    want = expected_g(study, scheme)
    params = study.centrifuge.scheme_params(scheme)
    positions, counts, last, jit, rates = [], [], [], 0.0, []
    instants = ColumnSpill(2)
    moments = Moments.zero(3)
    truth = None

    def finish(k: int, row0: int, t: ColumnSpill, a: ColumnSpill) -> None:
        nonlocal jit
        med, origin = check_position_spilled(k, t, a, scheme, study.sample_s, max_gap, float(want[k - 1]))
        jit = max(jit, spilled_jitter(t, study.sample_s))
        rates.append(spilled_segment_rate(t, study.sample_s, med))
        n, t_last = 0, np.nan
        with ColumnSpill(2) as mine:  # this position's (sample, instant): its sums' pass reads them back
            for keep, tk in instants_spilled_blocks(k, t, med, origin, study.filter.period_s,
                                                    study.filter.update_at_reset):
                if keep.size:
                    mine.write(np.column_stack([keep.astype(float), tk]))  # indices as float64: exact below 2**53
                    n, t_last = n + keep.size, float(tk[-1])
            z, nominal = RowsAt(a.blocks()), RowsAt(nominal_blocks(study, scheme, params, k))
            for _, v in mine.blocks():
                keep, tk = v[:, 0].astype(np.int64), v[:, 1]
                moments.add(z.take(keep), nominal.take(nominal_index(study, scheme, tk)))
                instants.write(np.column_stack([row0 + v[:, 0], tk]))
        positions.append(k)
        counts.append(n)
        last.append(t_last)

    def check(df) -> None:
        nonlocal truth
        if truth is None:
            truth = has_truth_columns(df.columns)
        pos = df["position"].to_numpy(float)
        check_position_numbers(pos, scheme)
        check_commanded(pos, df[["alpha_cmd", "beta_cmd", "gamma_cmd"]].to_numpy(float), scheme)

    try:
        for position in spilled_positions(chunks, check):
            finish(*position)
        check_every_position(positions, scheme)
    except BaseException:
        instants.close()
        raise
    return StreamScan(positions, counts, last, instants, bool(truth), jit, moments, cmd[np.array(positions) - 1],
                      ClockRate.combine(rates))


def nominal_index(study: Study, scheme: Scheme, tk: np.ndarray) -> np.ndarray:
    """The sample of the nominal output (:func:`nominal_output`) at each instant ``tk`` (s since
    its position's start): the nearest, within the dwell."""
    n = whole_periods(scheme.dwell_s, study.sample_s, f"schemes.{scheme.name}.dwell_s")
    return np.clip(np.rint(tk / study.sample_s).astype(int), 0, n - 1)


def nominal_blocks(study: Study, scheme: Scheme, params: np.ndarray, k: int, chunk_samples: int | None = None):
    """``(j0, A (n, 3) g)``: the noise-free output of the nominal instrument over position ``k``
    (1-based) from its sample ``j0``, a chunk at a time (``chunk_samples``, default
    :data:`platcal.records.SPILL_BLOCK`, the blocks of the spilled outputs it is read beside;
    docs/centrifuge-model.md §2). The chunks carry the attitude, so their size changes no bit;
    the simulation holds 340-460 bytes a sample of its chunk (tracemalloc: 25.6 MB at 100 000 samples,
    22.3 MB at 65 536, 4.1 MB at 10 000)."""
    for ch in simulate_chunks(np.zeros_like(study.truth), scheme, params, study.noise, None, sample_s=study.sample_s,
                              chunk_samples=chunk_samples or records.SPILL_BLOCK, positions=[k - 1]):
        yield ch.j0, ch.A[0]


def identify_streamed(study: Study, scheme: Scheme,
                      read_chunks) -> tuple[Estimate, StreamScan, FitCheck | None, ColumnSpill]:
    """Identify a record read in chunks, twice or more (``read_chunks()`` yields the record's
    checked tables in file order, afresh at each call): a first read checks it
    (:func:`scan_record`, then the plausibility of Ax, Ay, Az as :func:`record_input`), each
    filter pass reads it again and filters it block by block (:func:`~.ekf.run_ekf`
    ``z_source``) and the last pass's innovations feed the fit check's running sums
    (:class:`~platcal.estimation.fit.FitSums`). Estimates, covariance, history and mean NIS are
    bit-identical to the whole record's; the fit's figures agree to rounding. The fit's
    diagnosis of a record that does not fit names units, signs, swaps (from the sums) and the
    clock jitter of :func:`clock_finding`, not the clock offset that :func:`record_fit` finds in
    the innovations' time derivative. ``filter.estimator`` one of :data:`STREAMED_KINDS`,
    without warm-up.

    Nothing held grows with the record (issue 22 item 3): each pass reads the instants and their
    rows back from the scan's file chunk by chunk (:class:`InstantCursor`), and the history goes
    to a temporary file as each block is filtered, returned as the fourth item (columns ``t``,
    the states, their sigmas: :func:`history_columns`' order; the Estimate's history is then
    empty) for :func:`write_identification` ``history``; the caller closes it."""
    scan = scan_record(read_chunks(), study, scheme)
    history = ColumnSpill(1 + 2 * len(study.filter.state_names))
    try:
        est, fit = filter_streamed(study, scheme, read_chunks, scan, history)
    except BaseException:
        history.close()
        raise
    finally:
        scan.close()
    return est, scan, fit, history


def filter_streamed(study: Study, scheme: Scheme, read_chunks, scan: StreamScan,
                    history: ColumnSpill) -> tuple[Estimate, FitCheck]:
    """The filter passes and the fit check of :func:`identify_streamed` over a scanned record
    (its instants read back from ``scan.instants``), the history's rows written to ``history``."""
    refuse_recognised_moments(scan.moments, FIT_CHANNELS, "g",
                              "the record's Ax, Ay, Az must be the platform's x, y, z accelerometers in g")
    settings = replace(study.filter, innovations=True)
    params = study.centrifuge.scheme_params(scheme)[np.array(scan.positions) - 1]
    offs = np.r_[0, np.cumsum(scan.counts)]
    state = {}

    def z_source():
        cursor = InstantCursor(scan.instants)
        i0 = r0 = 0
        for df in read_chunks():
            r1 = r0 + len(df)
            rows, tb = cursor.below(r1)
            yield i0, i0 + rows.size, df[["Ax", "Ay", "Az"]].to_numpy(float)[rows - r0][None], tb
            i0 += rows.size
            r0 = r1

    def on_history(ht, hx, hs):
        history.write(np.column_stack([ht, hx, hs]))

    def on_innovations(i0, i1, zb, rb):
        if i0 == 0:  # a new pass: the fit judges the last one
            state["sums"] = FitSums(3)
        segment = np.searchsorted(offs, np.arange(i0, i1), side="right")
        state["sums"].add(rb[0, :, :3], rb[0, :, 3:], segment)

    kind = check_kind(settings.estimator)
    instants = StreamedInstants(tuple(scan.counts), tuple(scan.last))
    est = kind.run(EstimatorInput(None, instants, scan.cmd_deg, params), settings, z_source=z_source,
                   on_innovations=on_innovations, on_history=on_history, **dict(settings.estimator_options))
    diagnosis = [text for _, text in gross_errors_moments(scan.moments, FIT_CHANNELS)]
    clock = clock_text(study, scheme, scan.jitter_s)
    if not diagnosis and clock is not None:
        diagnosis.append(clock)
    return est, state["sums"].check(FIT_CHANNELS, diagnosis=tuple(diagnosis))


def streamable(settings: FilterSettings) -> bool:
    """Whether the estimator of ``settings`` filters a record in chunks (:data:`STREAMED_KINDS`,
    no warm-up pass)."""
    return settings.estimator in STREAMED_KINDS and dict(settings.estimator_options).get("warmup_s") is None


def identify_record(study: Study, scheme: Scheme, df: pd.DataFrame) -> Estimate:
    """Run the study's EKF over a validated test record (one run: a batch of one)."""
    return identify_input(study, scheme, record_input(study, scheme, df))


def run_problems(est: Estimate, replicate: int = 0) -> list[str]:
    """Why a filter run cannot be trusted (empty if it can): updates skipped because S was not
    positive definite, non-finite estimates or covariance, a final covariance that is not
    positive definite. Messages use plain numbers."""
    out = []
    bad = int(est.failed_updates[replicate])
    if bad:
        out.append(f"{bad} measurement update(s) failed (innovation covariance S not positive definite)")
    out += estimate_problems(est.x[replicate], est.P[replicate], est.names)
    return out


NEES_LEVEL = 0.999
"""A NEES above this quantile of chi-square(dof) is reported as an inconsistent filter."""


def consistency_warning(summary: dict) -> str | None:
    """A warning when the run's NEES (truth known) is beyond the :data:`NEES_LEVEL` quantile of
    chi-square with ``nees_dof`` degrees of freedom, i.e. the covariance is far too optimistic
    for its errors (the one-pass EKF at low noise, docs/centrifuge-model.md §11); None otherwise."""
    if summary.get("nees") is None:
        return None
    dof = int(summary["nees_dof"])
    bound = chi2_quantile(NEES_LEVEL, dof)
    if summary["nees"] <= bound:
        return None
    return (f"NEES {summary['nees']:.4g} for {dof} dof is above its {NEES_LEVEL:.1%} bound {bound:.4g}: the "
            "filter's sigmas are too optimistic for its errors (filter.passes: 2 restores consistency, "
            "and so does a 1 s warm-up pass, filter.warmup_s: 1, at about 1.1 x the cost of one pass)")


def write_identification(out_dir: str | os.PathLike, est: Estimate, study: Study, truth_known: bool,
                         seconds: float | None = None, samples_used: dict[int, int] | None = None,
                         calibration: Calibration | None = None, fit: FitCheck | None = None,
                         segmentation: tuple | None = None, clock: dict | None = None,
                         history: ColumnSpill | None = None) -> dict:
    """Write ``estimates.csv``, ``covariance.csv``, ``history.csv``, ``table2.md`` and ``summary.json``.

    ``history.csv`` is the decimated history of every pass: ``t`` (s from the start of the
    first pass), each state's estimate and its 1-sigma (``<name>_sigma``), angles in rad.
    The five files land together or not at all (:func:`platcal.io.atomic_files`), ``summary.json``
    last; it is strict JSON (``null`` for a number that is not finite). ``samples_used`` (position
    -> number of samples the filter used) goes into the summary as ``samples_used_per_position``;
    ``fit`` (:func:`record_fit`) as its ``fit`` block (``verdict: not available`` when None).
    With ``calibration``, ``calibration.yaml`` lands with them (:mod:`platcal.logs.calibration`);
    with ``segmentation`` (a continuous log's ``(t, |A|, dwells)``, :func:`continuous_input`) the
    summary's ``dwells_found`` and ``dwells.png``, the log's ``|A|`` with the dwells shaded; with
    ``clock`` (:func:`check_clock_rate`) the summary's ``clock`` block; with ``history`` (a
    streamed identify's spilled history, :func:`identify_streamed`) ``history.csv`` from it,
    block by block, instead of from ``est``.
    """
    nc = est.n_coef
    truth = study.truth if truth_known else None
    table = estimates_columns(est.names[:nc], est.coef[0], est.coef_sigma[0], truth)
    summary = {"n_states": len(est.names), "estimator": study.filter.estimator,
               "estimator_options": dict(study.filter.estimator_options), "passes": study.filter.passes,
               "mean_nis": float(est.mean_nis[0]), "failed_updates": int(est.failed_updates[0])}
    if samples_used is not None:
        summary["samples_used_per_position"] = {str(k): int(v) for k, v in samples_used.items()}
    if seconds is not None:
        summary["seconds"] = seconds
    if segmentation is not None:
        summary["dwells_found"] = dwells_found(segmentation[0], segmentation[2])
    if clock is not None:
        summary["clock"] = clock
    summary["fit"] = fit.as_dict() if fit is not None else {
        "verdict": "not available", "reason": f"estimator {study.filter.estimator!r} keeps no innovations"}
    if truth is not None:
        idx = study.filter.coef_index
        summary["nees"] = float(nees(est.coef, est.P[:, :nc, :nc], truth[idx][None])[0])
        summary["nees_dof"] = nc
        rel = np.abs(table["rel_err_pct"])
        gyro = np.array([n.startswith("D") for n in table["name"]])
        # NaN-skipping maxima (a zero truth), as the pandas table's max() was
        summary["max_abs_rel_err_pct_gyro"] = float(np.nanmax(rel[gyro]))
        summary["max_abs_rel_err_pct_accel"] = float(np.nanmax(rel[~gyro]))
    with atomic_files(out_dir) as tmp:
        write_csv(tmp("estimates.csv"), table)
        write_covariance(tmp("covariance.csv"), est.names, est.P[0])
        if history is None:
            write_csv(tmp("history.csv"), history_columns(est))
        else:
            # a spill block of rows (not values) of 97 columns was 33 MB at 6 h
            rows = max(1, records.SPILL_BLOCK // history.width)
            write_csv_blocks(tmp("history.csv"), history_names(est), ([v[:, j] for j in range(v.shape[1])]
                                                                      for _, v in history.blocks(per_block=rows)))
        tmp("table2.md").write_text(table2_markdown(table))
        if calibration is not None:
            write_calibration_files(tmp, calibration, covariance=False)  # covariance.csv above has every state
        if segmentation is not None:
            resolve(DWELL_FIGURE)(*segmentation, tmp("dwells.png"), names=("|A|",), ylabel="specific force |A|, g")
        tmp("summary.json").write_text(json_text(summary))
    return summary


def history_columns(est: Estimate, replicate: int = 0) -> dict:
    """The decimated estimate and 1-sigma history of one run as a wide table's columns: ``t``
    (s), each state's estimate and ``<name>_sigma`` (the state's unit; angles in rad)."""
    values = [est.history_t] + [est.history_x[replicate, :, i] for i in range(len(est.names))] + \
        [est.history_sigma[replicate, :, i] for i in range(len(est.names))]
    return dict(zip(history_names(est), values))


def history_names(est: Estimate) -> list[str]:
    """The columns of :func:`history_columns`, in order."""
    return ["t", *est.names, *(f"{name}_sigma" for name in est.names)]


def truth_known(df: pd.DataFrame) -> bool:
    """A record carries its truth when it has the simulated true-angle columns."""
    return has_truth_columns(df.columns)


def timed(fn, *args, **kw):
    """``(result, seconds)`` of a call."""
    t0 = time.perf_counter()
    res = fn(*args, **kw)
    return res, time.perf_counter() - t0



def calibration(est: Estimate, study: Study, log_path) -> Calibration:
    """The calibration of one identified record: the identified coefficients (Table 2 names and
    units), their covariance, the log's hash and the config (docs/centrifuge-model.md §13)."""
    nc = est.n_coef
    names = list(est.names[:nc])
    cat = load_catalogue()
    unit = dict(zip(cat.names, cat.units))
    units = [unit.get(n, "deg/h/g^2") for n in names]  # the DOO terms are not in Table 2
    return calibration_of("centrifuge", "centrifuge-model.md", names, units, est.coef[0], est.P[0, :nc, :nc],
                          log_path, study.config)
