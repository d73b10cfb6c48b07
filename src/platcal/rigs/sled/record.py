"""The sled test record (docs/rocket-sled.md §10): one row per IMU sample.

Columns ``t`` (s), ``fx, fy, fz`` (m/s^2), ``wx, wy, wz`` (rad/s) in the record's body axes
(the navigation's initial axes, see :mod:`.simulate`); a simulated record adds the
simulation-only truth columns ``x_true``, ``vx_true`` (error-free run) and ``x_inst``
(instrument-only run), m and m/s at the row's time. The drawn error parameters go to a side
file ``<record>.truth.json`` (``rec.csv.truth.json``, :func:`platcal.records.truth_path`; JSON: seed, the
replicate's SeedSequence as entropy and spawn key;
phi0, accelerometer and gyro errors in engineering units). CSV (``.csv``) or Parquet (``.parquet``) by suffix; both files written as a pair
(:func:`platcal.records.write_record`), so a record never appears without its truth.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...lighttable import Table
from ...estimation.consistency import normal_quantile
from ...logs.increments import increment_units, rates_from_increments, sample_intervals
from ...mapping import RecordMapping
from ...plausibility import refuse_recognised
from ... import records
from ...records import check_times, grid_origin, iter_table, num
from .config import ARCSEC, DEG_H, G, OMEGA_E, SledConfig
from .sensors import ErrorParams
from .simulate import SimBatch, Truth
from .trajectory import Trajectory, build_trajectory

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd

IMU_COLUMNS = ("t", "fx", "fy", "fz", "wx", "wy", "wz")
TRUTH_COLUMNS = ("x_true", "vx_true", "x_inst")
UNITS = {"t": "s", "fx": "m/s^2", "fy": "m/s^2", "fz": "m/s^2", "wx": "rad/s", "wy": "rad/s", "wz": "rad/s",
         "x_true": "m", "vx_true": "m/s", "x_inst": "m"}
"""The record's columns and their units (§10), for a config's ``record:`` mapping; g converts by
:data:`.config.G` (9.80665 m/s^2)."""


def check_out_path(path: str | Path, option: str = "--out") -> Path:
    path = Path(path)
    if path.suffix not in (".csv", ".parquet"):
        raise InputError(option, f"a sled record is written as .csv or .parquet, got {path.name!r}")
    return path


def sim_frame(sb: SimBatch, s: int = 0) -> pd.DataFrame:
    """Seed slot ``s`` of a simulated batch as a record frame."""
    return record_frame(sb.traj.t, sb.f[s], sb.w[s], sb.truth.x_true[s], sb.truth.vx_true[s], sb.truth.x_inst[s])


def record_frame(t, f, w, x_true, vx_true, x_inst) -> pd.DataFrame:
    """A record frame (§10) of samples at ``t`` (N,) s: f (N,3) m/s^2, w (N,3) rad/s and the
    truth columns (N,) m, m/s; a pandas DataFrame for the record writer
    (:meth:`platcal.lighttable.Table.to_pandas`)."""
    df = Table({"t": t})
    for i, ax in enumerate("xyz"):
        df[f"f{ax}"] = f[:, i]
    for i, ax in enumerate("xyz"):
        df[f"w{ax}"] = w[:, i]
    df["x_true"] = x_true
    df["vx_true"] = vx_true
    df["x_inst"] = x_inst
    return df.to_pandas()


def truth_side(ss: np.random.SeedSequence, params: ErrorParams, nabla_static: np.ndarray, s: int = 0) -> dict:
    """The truth side file of seed slot ``s``: its SeedSequence, the accelerometer error at rest
    ``nabla_static`` (S,3) m/s^2 (in µg) and the drawn errors (:meth:`ErrorParams.to_json`)."""
    return {"seed": {"entropy": int(ss.entropy), "spawn_key": [int(k) for k in ss.spawn_key]},
            "nabla_static_ug": (nabla_static[s] / G * 1e6).tolist(), **params.to_json(s)}


RECORD_FLOATS = "%.17g"
"""A simulated record's floats in CSV: every digit (the record reads back bit for bit)."""


def write_record(sb: SimBatch, path: str | Path, s: int = 0) -> None:
    """Write seed slot ``s`` as a record plus its truth side file, as a pair
    (:func:`platcal.records.write_record`)."""
    path = check_out_path(path)
    side = truth_side(sb.seeds[s], sb.truth.params, sb.truth.nabla_static, s)
    records.write_record(sim_frame(sb, s), path, truth=side, float_format=RECORD_FLOATS)


PHASE_TOL_G = 0.1
"""A phase whose median along-track specific force ``fx`` is further than this (g, plus 2 % of
the phase's level) from the config's acceleration is refused: the record is another run."""


def read_record(path: str | Path, cfg: SledConfig) -> tuple[Trajectory, Table, np.ndarray]:
    """Read and check a record against the config's trajectory; InputError naming the field.

    Returns the trajectory, the record (a :class:`platcal.lighttable.Table`: the checks of
    ``read_table`` without its DataFrame, so identify loads no pandas) and ``t`` (N,), the samples' times from the record's start
    (s), used as recorded (docs/rocket-sled.md §12, "Recorded times"). Refused, before any work:
    a file that is not UTF-8 CSV or Parquet, a missing or unknown column, non-finite values;
    time that does not increase, a median step more than 10x off the IMU period (``t`` not in
    seconds), a gap above ``record.max_gap_s``; a duration that differs from the trajectory's by
    more than ``record.max_gap_s``; a phase whose median ``fx`` is not the trajectory's
    acceleration (within :data:`PHASE_TOL_G`), or a median ``fz`` that is not about 1 g in m/s^2.
    The clock may count from 0 (a first sample within ``record.max_gap_s`` of it) or from any
    origin (a constant offset, removed by :func:`platcal.records.grid_origin`); jitter is kept.
    A log in other columns or units is read through the config's ``record:`` mapping (:data:`UNITS`);
    with ``record.kind: increments`` the f and w columns are delta-v (m/s) and delta-theta (rad)
    per sample, converted over each sample's interval (:mod:`platcal.logs.increments`).
    """
    df = next(iter_table(path, **table_options(cfg)))
    traj = build_trajectory(cfg)
    t, med, _ = record_times(cfg, traj.n, df["t"].to_numpy(dtype=float))
    if incremental(cfg):  # delta-v, delta-theta over each sample's interval (platcal.logs.increments)
        rates = rates_from_increments(df[list(IMU_COLUMNS[1:])].to_numpy(float), t)
        for i, c in enumerate(IMU_COLUMNS[1:]):
            df[c] = rates[:, i]
    fz = float(np.median(df["fz"].to_numpy(float)))
    if not 0.9 * G <= fz <= 1.1 * G:
        refuse_fz(fz)
    fx = df["fx"].to_numpy(float)
    for p, (name, (a, b), inside, level) in phase_windows(cfg, traj, t, med):
        got = float(np.median(fx[inside]))
        if phase_off(got, level):
            refuse_phase(name, a, b, got, level)
    return traj, df, t


def incremental(cfg: SledConfig) -> bool:
    """Whether the config's ``record.kind`` is ``increments`` (delta-v, delta-theta per sample)."""
    return RecordMapping.from_config(cfg.raw["record"], g=G).kind == "increments"


def table_options(cfg: SledConfig) -> dict:
    """The keyword arguments of :func:`platcal.records.read_table` / ``iter_table`` for a sled
    record read through the config's ``record:`` mapping."""
    mapping = RecordMapping.from_config(cfg.raw["record"], g=G)
    return dict(required=IMU_COLUMNS, optional=TRUTH_COLUMNS, what="a sled record", min_rows=2, mapping=mapping,
                units=increment_units(UNITS, IMU_COLUMNS[1:]) if mapping.kind == "increments" else UNITS,
                increments=IMU_COLUMNS[1:])


def record_times(cfg: SledConfig, n_traj: int, t: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The record's times ``t`` (N,) s checked (increasing, in seconds, no gap above
    ``record.max_gap_s``, lasting the trajectory's ``n_traj`` samples) and counted from its start
    (a clock from any origin: :func:`platcal.records.grid_origin`); with their median step and the
    origin taken off, s."""
    max_gap = float(cfg.raw["record"]["max_gap_s"])
    field = "--data column t"
    med = check_times(t, cfg.dt, max_gap, field, f"imu.rate_hz = {cfg.rate_hz:g} Hz, a step of {cfg.dt:g} s")
    origin = 0.0 if abs(t[0]) <= max_gap else grid_origin(t, med)
    t = t - origin
    check_span(cfg, n_traj, float(t[0]), float(t[-1]), t.size, med)
    return t, med, origin


def check_span(cfg: SledConfig, n_traj: int, t_first: float, t_last: float, rows: int, med: float) -> None:
    """Refuse a record (``rows`` samples from ``t_first`` to ``t_last``, s from its start, median
    step ``med`` s) that does not last the trajectory's ``n_traj`` samples within
    ``record.max_gap_s`` (:func:`record_times`)."""
    max_gap = float(cfg.raw["record"]["max_gap_s"])
    span, want = float(t_last + med), n_traj * cfg.dt
    if abs(span - want) > max_gap:
        raise InputError("--data column t", f"the record lasts {span:g} s ({rows} rows from t = {num(t_first)} s), "
                         f"but the config's trajectory lasts {want:g} s ({n_traj} IMU samples: static_before_s, "
                         f"phases, braking, static_after_s; record.max_gap_s = {max_gap:g} s); check the trajectory "
                         "section or the record")


def refuse_fz(fz: float) -> None:
    raise InputError("--data column fz", f"median fz = {fz:.4g}, expected about g = {G} m/s^2 (the sled is "
                     "level); the specific force must be in m/s^2")


def phase_windows(cfg: SledConfig, traj, t: np.ndarray, med: float):
    """Per phase of ``traj`` (a :class:`.trajectory.Trajectory` or ``Timeline``) with samples of
    the record inside it: ``(p, (name, (a, b), inside, level))``, its span a … b s, the mask of
    the record's instants ``t`` two median steps ``med`` in from its ends, its acceleration m/s^2."""
    for p, name in enumerate(traj.phase_names):
        rows = traj.phase_rows(p)
        if rows is None:
            continue
        a, b = rows[0] * cfg.dt, rows[1] * cfg.dt
        inside = (t >= a + 2 * med) & (t < b - 2 * med)
        if not inside.any():
            continue
        yield p, (name, (a, b), inside, float(traj.accel_at(rows[0])))


def phase_off(got, level: float):
    """Whether a phase's ``fx`` (m/s^2; an array: each value) is further from its acceleration
    ``level`` than :data:`PHASE_TOL_G`."""
    return np.abs(got - level) > PHASE_TOL_G * G + 0.02 * abs(level)


def refuse_phase(name: str, a: float, b: float, got: float, level: float) -> None:
    raise InputError("--data column fx", f"in the {name} phase (t = {a:g} .. {b:g} s) the median fx is "
                     f"{got / G:.3g} g, but the config's trajectory accelerates at {level / G:.3g} g there; "
                     "the record is not a run of this trajectory (check the trajectory section)")


NOMINAL_FIX = {"f": "fx, fy, fz must be the body-axis specific force in m/s^2 (x along the track, z down-up: "
                     "fz about +g at rest)",
               "w": "wx, wy, wz must be the body-axis rates in rad/s (at rest they read the earth rate, "
                    "7.29e-5 rad/s)"}


def nominal_imu(cfg: SledConfig, traj: Trajectory, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,3) m/s^2 and (N,3) rad/s: the error-free IMU output of the config's trajectory
    (docs/rocket-sled.md §2) at the record's instants ``t`` (s from its start; nearest grid sample)."""
    k = np.clip(np.floor(t / cfg.dt + 0.5).astype(np.int64), 0, traj.n - 1)
    return traj.true_imu_at(k, cfg.omega_ie)


def check_plausible(cfg: SledConfig, traj: Trajectory, f: np.ndarray, w: np.ndarray, t: np.ndarray) -> None:
    """Refuse (InputError naming the column, exit 2, before the filters) a record whose specific
    force or rates are a unit, sign or swap of the trajectory's error-free output (docs/rocket-sled.md
    §10): the along-track force and the 1 g at rest for ``fx, fz``, the earth rate for the gyros
    (:func:`platcal.plausibility.refuse_recognised`); then from the rig's physics, each gyro's
    mean at rest against the earth rate (:func:`check_static_rates`) and ``fy`` against the
    Coriolis force of the record's own velocity (:func:`check_lateral_force`). ``f`` (N,3)
    m/s^2, ``w`` (N,3) rad/s as :func:`record_arrays` gives them for one record, ``t`` (N,) s."""
    f_nom, w_nom = nominal_imu(cfg, traj, t)
    refuse_recognised(f, f_nom, ("fx", "fy", "fz"), "m/s^2", NOMINAL_FIX["f"])
    refuse_recognised(w, w_nom, ("wx", "wy", "wz"), "rad/s", NOMINAL_FIX["w"])
    check_static_rates(cfg, traj, w, t)
    check_lateral_force(cfg, traj, f, t)


STATIC_RATE_LEVEL = 1e-3
"""False-alarm probability of :func:`check_static_rates` for a clean record (split over the three
gyros, two-sided): 1e-3 keeps it a tenth of the fit check's 1 % level, so the two together stay
within issue 25's 1 % of clean records flagged."""


def static_rate_sigma(cfg: SledConfig, seconds: float) -> np.ndarray:
    """(3,) rad/s: the standard deviation of a clean record's mean gyro output over ``seconds`` of
    rest about the earth rate's body components (docs/rocket-sled.md §1, §3, §12 "Record axes"),
    from the config: the bias ``imu.gyro.bias_deg_h``, the g-sensitivity at 1 g
    (``g_sens_deg_h_g``; at rest f = [0, 0, g] so one term per axis), the angle random walk
    ``arw_deg_rth`` averaged over ``seconds``, and the record's axes turned by the initial
    attitude error (``alignment.sigma_arcsec``: the record holds R w, R = exp(-[phi0 x]), so
    component i moves by (phi0 x omega_ie)_i)."""
    gy = cfg.gyro
    om = cfg.omega_ie
    sa = np.asarray(cfg.alignment_arcsec, float) * ARCSEC
    # (phi x om)_i = sum_jk eps_ijk phi_j om_k, independent phi_j
    turn = np.array([(sa[1] * om[2]) ** 2 + (sa[2] * om[1]) ** 2, (sa[2] * om[0]) ** 2 + (sa[0] * om[2]) ** 2,
                     (sa[0] * om[1]) ** 2 + (sa[1] * om[0]) ** 2])
    arw = gy["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(max(seconds, cfg.dt))   # rad/s over the mean
    var = (gy["bias_deg_h"] * DEG_H) ** 2 + (gy["g_sens_deg_h_g"] * DEG_H) ** 2 + arw ** 2 + turn
    # a floor far below any gyro's resolution: a config of perfect gyros still compares with a tolerance
    return np.sqrt(var + (1e-9 * OMEGA_E) ** 2)


def rest_samples(cfg: SledConfig, traj: Trajectory, t: np.ndarray, med: float | None = None) -> np.ndarray:
    """(N,) bool: the record's samples at rest, the static periods before launch and after the
    stop (docs/rocket-sled.md §2) by time ``t`` (s from the record's start), two median steps in
    from each end (a jittered stamp near a phase change is not taken for rest); ``med`` the
    record's median step (default: that of ``t``, the whole record)."""
    if med is None:
        med = float(np.median(np.diff(t))) if t.size > 1 else cfg.dt
    rest = np.zeros(t.size, bool)
    for p in (0, len(traj.phase_names) - 1):
        rows = traj.phase_rows(p)
        if rows is not None:
            a, b = rows[0] * cfg.dt, rows[1] * cfg.dt
            rest |= (t >= a + 2 * med) & (t < b - 2 * med)
    return rest


STATIC_RATE_K = -normal_quantile(STATIC_RATE_LEVEL / 6)  # scipy.stats.norm.isf, bit for bit
"""Sigmas of :func:`static_rate_sigma` beyond which a gyro's mean at rest is refused: two-sided
at :data:`STATIC_RATE_LEVEL` over the three gyros (3.59)."""


def rest_seconds(rest: np.ndarray, t: np.ndarray) -> float:
    """Seconds at rest: the samples of ``rest`` x the record's median step."""
    return float(rest.sum()) * float(np.median(np.diff(t))) if t.size > 1 else 0.0


def static_rate_tolerance(cfg: SledConfig, traj: Trajectory, t: np.ndarray) -> np.ndarray:
    """(3,) rad/s: the largest constant rate error of each gyro :func:`check_static_rates` lets
    pass on a record with stamps ``t`` (inf when it has no rest)."""
    return rest_tolerance(cfg, rest_seconds(rest_samples(cfg, traj, t), t))


def rest_tolerance(cfg: SledConfig, seconds: float) -> np.ndarray:
    """(3,) rad/s: :func:`static_rate_tolerance` of a record with ``seconds`` s at rest."""
    return STATIC_RATE_K * static_rate_sigma(cfg, seconds) if seconds > 0 else np.full(3, np.inf)


def check_static_rates(cfg: SledConfig, traj: Trajectory, w: np.ndarray, t: np.ndarray) -> None:
    """Refuse (InputError naming the gyro column, exit 2, before the filters) a record whose mean
    rate at rest differs from the earth rate's body component (docs/rocket-sled.md §1: the sled
    is level, track frame = body frame, so a gyro at rest reads omega_ie^l; issue 25 item 2) by
    more than the config's gyro errors allow (:func:`static_rate_sigma`, two-sided at
    :data:`STATIC_RATE_LEVEL` over the three gyros). The rest is the static periods before
    launch and after the stop, two samples in from each end. Because the true rate is the earth
    rate throughout the test, a gyro scale error 1 + e is, in every sample, a bias of
    e x omega_i: this catches it once e omega_i passes the tolerance (about 0.2 deg/h with the
    default config); below, the record cannot tell it from the gyro's own bias. ``w`` (N,3)
    rad/s, ``t`` (N,) s from the record's start."""
    rest = rest_samples(cfg, traj, t)
    if rest.sum() < 2:
        return
    refuse_static_rates(cfg, w[rest].mean(axis=0), rest_seconds(rest, t))


def refuse_static_rates(cfg: SledConfig, mean: np.ndarray, seconds: float) -> None:
    """:func:`check_static_rates`' verdict on the gyros' ``mean`` (3,) rad/s over ``seconds`` of rest."""
    expected = cfg.omega_ie
    sigma = static_rate_sigma(cfg, seconds)
    k = STATIC_RATE_K
    z = (mean - expected) / sigma
    worst = int(np.argmax(np.abs(z)))
    if abs(z[worst]) <= k:
        return
    col = ("wx", "wy", "wz")[worst]
    ratio = mean[worst] / expected[worst] if expected[worst] else np.nan
    raise InputError(f"--data column {col}",
                     f"mean {mean[worst] / DEG_H:.4g} deg/h over {seconds:g} s at rest, expected the earth rate's "
                     f"component {expected[worst] / DEG_H:.4g} deg/h +- {k * sigma[worst] / DEG_H:.2g} "
                     f"(site.latitude_deg = {cfg.latitude_deg:g}, site.track_azimuth_deg = "
                     f"{cfg.track_azimuth_deg:g}; {k:.2f} sigma of imu.gyro bias, g-sensitivity and ARW and "
                     f"the alignment error; docs/rocket-sled.md §1, §3); it reads {ratio:.4g} x the earth rate "
                     f"there, {z[worst]:+.1f} sigma off: a scale error of {col} (fix the gyro's scale factor), a "
                     "bias beyond imu.gyro.bias_deg_h (declare the gyro's bias), or another site")


def samples_per_phase(traj: Trajectory, t: np.ndarray, dt: float) -> dict[str, int]:
    """Record samples in each phase of the trajectory (by time), for the summary."""
    k = np.clip(np.floor(t / dt + 0.5).astype(np.int64), 0, traj.n - 1)   # nearest grid sample
    counts = np.bincount(traj.phase_at(k), minlength=len(traj.phase_names))
    return {name: int(c) for name, c in zip(traj.phase_names, counts)}


def record_arrays(df: Table) -> tuple[np.ndarray, np.ndarray]:
    """(1,N,3) specific force and rate of a record frame."""
    f = df[["fx", "fy", "fz"]].to_numpy(dtype=float)[None]
    w = df[["wx", "wy", "wz"]].to_numpy(dtype=float)[None]
    return f, w


def truth_params(path: str | Path, columns) -> tuple[ErrorParams, np.ndarray] | None:
    """The drawn errors and the accelerometer error at rest (1,3) m/s^2 of a simulated record
    with ``columns`` (its side file), or None when the truth columns or the side file are absent."""
    if not all(c in columns for c in TRUTH_COLUMNS):
        return None
    d = records.read_truth(path)
    if d is None:
        return None
    try:
        return ErrorParams.from_json([d]), np.asarray(d["nabla_static_ug"], dtype=float)[None] * G * 1e-6
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(str(records.truth_path(path)), f"not a sled truth file ({exc.__class__.__name__}: {exc})") from None


def record_truth(path: str | Path, df: Table) -> Truth | None:
    """The truth of a simulated record (columns + side file), or None when either is absent."""
    drawn = truth_params(path, df.columns)
    if drawn is None:
        return None
    p, nab = drawn
    return Truth(params=p, x_true=df["x_true"].to_numpy(float)[None], vx_true=df["vx_true"].to_numpy(float)[None],
                 x_inst=df["x_inst"].to_numpy(float)[None], nabla_static=nab)


LATERAL_LEVEL = 1e-3
"""False-alarm probability of :func:`check_lateral_force` for a clean record (two-sided), a
tenth of the fit check's 1 % as :data:`STATIC_RATE_LEVEL`."""


def lateral_coriolis_gain(cfg: SledConfig, traj: Trajectory, f: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """The gain of the record's lateral force ``fy`` on the Coriolis force ``2 omega_z v`` and its
    standard error (docs/rocket-sled.md §2: the true specific force is ``[a_x, 2 omega_z v,
    g - 2 omega_y v]``, so an error-free ``fy`` in m/s^2 has gain 1; a ``fy`` scaled by 1 + e has
    1 + e). ``v`` (m/s) is the record's own along-track velocity, ``fx`` integrated over each
    sample's interval after its mean at rest (the accelerometer's bias and the tilt's g) is
    taken off. Least squares of ``fy`` on [1, fx, 2 omega_z v]: the constant takes the lateral
    bias and the roll's g (phi_x, M_yz), the ``fx`` term the azimuth error and the misalignment
    M_yx (phi_z f_x), which are unknown; the Coriolis term is not, up to the y scale factor
    (``imu.accel.scale_ppm``). The standard error is the least-squares one from the residuals'
    scatter (the accelerometer's white noise). ``f`` (N,3) m/s^2, ``t`` (N,) s."""
    rest = rest_samples(cfg, traj, t)
    fx = f[:, 0] - (float(f[rest, 0].mean()) if rest.any() else 0.0)
    v = np.cumsum(fx * sample_intervals(t)) - 0.5 * fx * sample_intervals(t)   # mid-interval, as the Coriolis mean
    cor = 2.0 * cfg.omega_ie[2] * v
    A = np.column_stack([np.ones_like(v), f[:, 0], cor])
    coef, *_ = np.linalg.lstsq(A, f[:, 1], rcond=None)
    r = f[:, 1] - A @ coef
    return gain_and_error(coef, A.T @ A, float(r @ r), t.size)


def gain_and_error(coef: np.ndarray, gram: np.ndarray, rss: float, n: int) -> tuple[float, float]:
    """:func:`lateral_coriolis_gain`'s gain (the Coriolis term's coefficient of ``coef`` (3,)) and
    its least-squares standard error from the regressors' Gram matrix (3,3), the residual sum of
    squares ``rss`` (m/s^2)^2 and the ``n`` samples."""
    cov = np.linalg.pinv(gram) * rss / max(n - gram.shape[0], 1)
    return float(coef[2]), float(np.sqrt(cov[2, 2]))


def check_lateral_force(cfg: SledConfig, traj: Trajectory, f: np.ndarray, t: np.ndarray) -> None:
    """Refuse (InputError naming column ``fy``, exit 2, before the filters) a record whose lateral
    force does not carry the Coriolis force of its own along-track velocity at gain 1
    (:func:`lateral_coriolis_gain`): beyond :data:`LATERAL_LEVEL` two-sided of its standard error
    plus the y scale factor's 4 sigma (``imu.accel.scale_ppm``, a model tolerance). The run
    filter reads the azimuth error from ``fy`` (phi_z f_x), so a ``fy`` scaled by 1 + e gives
    phi_z (1 + e); this is the one term of ``fy`` the record fixes. Skipped (nothing to compare)
    when the run has no speed."""
    refuse_lateral(cfg, *lateral_coriolis_gain(cfg, traj, f, t))


def refuse_lateral(cfg: SledConfig, gain: float, se: float) -> None:
    """:func:`check_lateral_force`'s verdict on the Coriolis ``gain`` and its standard error ``se``."""
    if not (np.isfinite(gain) and np.isfinite(se) and se > 0):
        return
    k = -normal_quantile(LATERAL_LEVEL / 2)
    tol = k * se + 4 * cfg.accel["scale_ppm"] * 1e-6
    if abs(gain - 1.0) <= tol:
        return
    raise InputError("--data column fy",
                     f"carries {gain:.4g} x the Coriolis force 2 omega_z v of the record's along-track velocity "
                     f"(+- {se:.2g}), expected 1 +- {tol:.2g} (docs/rocket-sled.md §2: fy = 2 omega_z v on the "
                     f"rail, omega_z = {cfg.omega_ie[2]:.4g} rad/s at site.latitude_deg = {cfg.latitude_deg:g}; "
                     f"{k:.2f} standard errors and 4 sigma of imu.accel.scale_ppm); fy is scaled by about "
                     f"{gain:.4g}: fix its scale factor (fy must be the lateral specific force in m/s^2), "
                     "or the site's latitude")
