"""The test record of one run (docs/lowprec-centrifuge.md §10): CSV or Parquet, plus a side JSON.

Columns, one row per sample: ``t`` (s), ``VE, VN`` (m/s), ``pE, pN`` (m, relative to the start),
``heading_deg`` (gimbal azimuth angle, wrapped to [0, 360)), ``fE, fN`` (m/s^2, the INS's own
horizontal specific force, i.e. its accelerometers' outputs; optional on input: without them it
is differentiated from VE, VN),
``schedule`` (``static`` | ``spinning`` | ``hold``). A simulated record adds simulation-only
truth columns ``truth_dVE, truth_dVN`` (m/s), ``truth_dpE, truth_dpN`` (m), ``truth_phi_x/y/z``
(rad) and ``truth_theta_deg``; the identification never reads them. [D] The drawn parameters
and the true coefficients go to a side file ``<record>.truth.json`` next to the record (:func:`platcal.records.truth_path`:
``rec.csv.truth.json``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicSpline

from ...errors import InputError
from ...lighttable import Table
from ...mapping import RecordMapping
from ...plausibility import refuse_recognised_moments
from ... import records
from ...records import CHUNK_ROWS, check_times, iter_table
from .config import COEFFS, G0
from .profile import SCHEDULE_NAMES, STATIC
from .errormodel import integrate_error_model
from .truth import RunBatch

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd

REQUIRED = ("t", "VE", "VN", "pE", "pN", "heading_deg", "schedule")
NUMERIC = ("t", "VE", "VN", "pE", "pN", "heading_deg", "fE", "fN")
TRUTH_COLUMNS = ("truth_dVE", "truth_dVN", "truth_dpE", "truth_dpN", "truth_theta_deg", "truth_phi_x",
                 "truth_phi_y", "truth_phi_z")
"""Simulation-only columns (never read by the identification)."""
UNITS = {"t": "s", "VE": "m/s", "VN": "m/s", "pE": "m", "pN": "m", "heading_deg": "deg", "fE": "m/s^2",
         "fN": "m/s^2", "schedule": None, "truth_dVE": "m/s", "truth_dVN": "m/s", "truth_dpE": "m", "truth_dpN": "m",
         "truth_theta_deg": "deg", "truth_phi_x": "rad", "truth_phi_y": "rad", "truth_phi_z": "rad"}
"""The record's columns and their units (§10; None: text), for a config's ``record:`` mapping; g
converts by :data:`.config.G0` (9.80665 m/s^2)."""
POSITIONS = ("pE", "pN")
"""The east and north positions a ``record.geodetic`` mapping fills from latitude and longitude."""


@dataclass(frozen=True)
class Record:
    """A record read back: arrays for the estimators (psi in rad, not unwrapped)."""

    t: np.ndarray
    v: np.ndarray          # (N, 2)
    p: np.ndarray          # (N, 2)
    psi: np.ndarray        # (N,)
    f: np.ndarray          # (N, 2)
    schedule: np.ndarray   # (N,) int8
    truth: dict | None
    f_recorded: bool = True  # False: f differentiated from v (no fE, fN columns)
    window: int = CHUNK_ROWS  # samples of the velocity's spline evaluated at a time (:func:`velocity_derivative`)


def check_out_path(path, field: str = "--out") -> Path:
    p = Path(path)
    if p.suffix not in (".csv", ".parquet"):
        raise InputError(field, f"a record is .csv or .parquet, got {p.name!r}")
    return p


def record_frame(rb: RunBatch, i: int = 0) -> pd.DataFrame:
    """The record of seed ``rb.seeds[i]`` (§10)."""
    return block_frame(rb.prof.t, rb.prof.schedule, rb.kin.theta, rb.err[i], None if rb.phi is None else rb.phi[i],
                       rb.v_ind[i], rb.f_meas[i], rb.p_ind[i], rb.psi[i])


def block_frame(t, schedule, theta, err, phi, v_ind, f_meas, p_ind, psi) -> pd.DataFrame:
    """Record rows (§10) from one replicate's arrays (:class:`.truth.RunBatch` for one seed, or a
    :class:`.truth.RecordBlock`): t s, schedule codes, true arm angle theta rad, errors err (n, 4),
    attitude phi (n, 3) rad or None, v_ind m/s, f_meas m/s^2, p_ind m, heading psi rad. A pandas
    DataFrame for the record writer (:meth:`platcal.lighttable.Table.to_pandas`: pandas is loaded
    by simulate, not by an identify that imports this module)."""
    cols = {
        "t": t, "VE": v_ind[:, 0], "VN": v_ind[:, 1], "pE": p_ind[:, 0],
        "pN": p_ind[:, 1], "heading_deg": np.mod(np.degrees(psi), 360.0),
        "fE": f_meas[:, 0], "fN": f_meas[:, 1],
        "schedule": np.asarray(SCHEDULE_NAMES)[schedule],
        "truth_dVE": err[:, 0], "truth_dVN": err[:, 1], "truth_dpE": err[:, 2],
        "truth_dpN": err[:, 3], "truth_theta_deg": np.degrees(theta)}
    if phi is not None:
        for j, ax in enumerate("xyz"):
            cols[f"truth_phi_{ax}"] = phi[:, j]
    return Table(cols).to_pandas()


def truth_json(rb: RunBatch, study, i: int = 0) -> dict:
    """The truth side file of seed ``rb.seeds[i]`` (:func:`truth_side`)."""
    return truth_side(study, rb.platform, rb.run, int(rb.seeds[i]), rb.prof.levels, rb.coeffs, rb.draws, i,
                      rb.err[i, -1])


def truth_side(study, platform: str, run: str, seed: int, levels, coeffs, draws, i: int, final) -> dict:
    """The truth side file (§10): the run, the true coefficients, replicate ``i`` of the ``draws``
    (:class:`.truth.Draws`) and its ``final`` errors (dVE, dVN m/s, dpE, dpN m)."""
    cen = study.centrifuge
    return {"rig": "lowprec_centrifuge", "platform": platform, "run": run, "seed": seed,
            "levels_g": list(levels),
            "coefficients": dict(zip(COEFFS, map(float, coeffs))),
            "centrifuge": {"arm_m": cen.arm_m, "rate_error": cen.rate_error, "arm_error_mm": cen.arm_error_mm,
                           "stretch_mm_per_g": cen.stretch_mm_per_g},
            "drawn": {"k0_ug": draws.k0_ug[i].tolist(), "scale_ppm": draws.scale_ppm[i].tolist(),
                      "gyro_drift_deg_h": draws.drift_deg_h[i].tolist(),
                      "phi0_rad": draws.phi0_rad[i].tolist(),
                      "gyro_g_sensitive": draws.gyro_coefficients(i)},
            "final_errors": dict(zip(("dVE", "dVN", "dpE", "dpN"), map(float, final)))}


def write_record(df: pd.DataFrame, meta: dict, path) -> None:
    """Record and its truth side file, as a pair (:func:`platcal.records.write_record`)."""
    path = check_out_path(path)
    records.write_record(df, path, truth=meta)


def read_record(path, use_truth: bool = True, rate_hz: float = 100.0, max_gap_s: float = 0.05,
                mapping: RecordMapping | None = None, window: int = CHUNK_ROWS) -> Record:
    """Read and check a record (UTF-8 CSV or Parquet, :func:`platcal.records.iter_table`);
    InputError naming the column (and row) of the first problem.

    Times as recorded (docs/lowprec-centrifuge.md §12, "Recorded times"): ``t`` must increase,
    its median step be within a factor 10 of ``1 / rate_hz`` (``profile.rate_hz``: t in seconds),
    and no gap exceed ``max_gap_s`` (``record.max_gap_s``); jitter and a constant offset are kept
    (the windows, their integrals and the plateau spans all use the record's own times). A log in
    other columns or units is read through the config's ``record:`` ``mapping`` (:data:`UNITS`).
    ``window`` (``--chunk-rows``): rows read at a time, and samples of the velocity's spline
    evaluated at a time (:func:`velocity_derivative`); 0: all at once.
    """
    # read in chunks of ``window`` rows, each kept as the arrays the identification uses (65 bytes
    # a sample: the table's other columns, the truth's and the schedule's text, are not held)
    cols = {c: [] for c in ("t", "VE", "VN", "pE", "pN", "heading_deg", "fE", "fN")}
    codes, bad, has_f, row = [], None, None, 0
    for df in iter_table(path, REQUIRED, tuple(c for c in NUMERIC if c not in REQUIRED) + TRUTH_COLUMNS,
                         text=("schedule",), what="a lowprec_centrifuge record", min_rows=3, mapping=mapping,
                         units=UNITS, positions=POSITIONS, chunk_rows=window or None):
        if has_f is None:
            has_f = ("fE" in df.columns, "fN" in df.columns)
        for c, parts in cols.items():
            if c in df.columns:
                parts.append(df[c].to_numpy(float))
        sched_s = df["schedule"].astype(str)
        code = sched_s.map(SCHEDULE_CODES)
        if bad is None and code.isna().any():  # the first unknown schedule, refused after the time checks
            i = int(np.flatnonzero(code.isna().to_numpy())[0])
            bad = (row + i, sched_s.iloc[i])
        codes.append(code.fillna(-1).to_numpy(np.int8))
        row += len(df)
    t = np.concatenate(cols["t"])
    check_times(t, 1.0 / rate_hz, max_gap_s, "--data column t", f"profile.rate_hz = {rate_hz:g} Hz, a step of "
                f"{1.0 / rate_hz:g} s")
    if bad is not None:
        raise InputError(f"--data column schedule, row {bad[0] + 2}",
                         f"{bad[1]!r} is not one of {list(SCHEDULE_NAMES)}")
    schedule = np.concatenate(codes)

    def pair(a: str, b: str) -> np.ndarray:
        return np.column_stack([np.concatenate(cols.pop(a)), np.concatenate(cols.pop(b))])

    v = pair("VE", "VN")
    if all(has_f):
        f = pair("fE", "fN")
    elif any(has_f):
        raise InputError(f"--data column {'fN' if has_f[0] else 'fE'}",
                         "the specific force comes as both fE and fN or not at all")
    else:  # [D] no specific-force columns: differentiate the INS velocity (nav frame, Coriolis neglected)
        f = velocity_derivative(t, v, window or t.size)
    truth = None
    if use_truth:
        truth = records.read_truth(Path(path))
    return Record(t=t, v=v, p=pair("pE", "pN"), psi=np.radians(np.concatenate(cols.pop("heading_deg"))), f=f,
                  schedule=schedule, truth=truth, f_recorded=all(has_f), window=window or t.size)


SCHEDULE_CODES = {name: i for i, name in enumerate(SCHEDULE_NAMES)}
"""A schedule's text -> its code (:data:`.profile.SCHEDULE_NAMES`)."""


SPLINE_OVERLAP = 64
"""Samples a window of :func:`velocity_derivative` reaches beyond the samples it returns, each side:
a cubic spline's end effects decay by 2 - sqrt(3) = 0.268 per knot, so after 64 knots they are
0.268^64 = 1e-37 of the signal, far below round-off (measured: 16 knots leave 5e-12 of the
largest derivative, 32 and more none, bit-identical on P1 run 1 and on 2.16 M jittered samples)."""


def velocity_derivative(t: np.ndarray, v: np.ndarray, window: int = CHUNK_ROWS,
                        overlap: int = SPLINE_OVERLAP) -> np.ndarray:
    """(N, 2) m/s^2: the specific force a record without ``fE, fN`` is identified with, the time
    derivative of its velocity (m/s) at the record's own times t (s): the derivative of the cubic
    spline through the samples. A central difference attenuates the spinning velocity by
    (w dt)^2 / 6 (0.2 % at 40 g on the 3 m arm at 100 Hz, 0.4 % on f^2) and shifted k2_x by
    +5.7 sigma (P2 run 1); the spline's error is of order (w dt)^4 (docs/lowprec-centrifuge.md §12).

    The spline through every sample is evaluated ``window`` samples at a time, each from the spline
    through those samples and ``overlap`` more on each side (:data:`SPLINE_OVERLAP`), so its
    memory is one window's, not the record's (a spline over 2.16 M samples, 6 h at 100 Hz, held
    500 MB); the values are the whole spline's to round-off."""
    n = t.size
    if n <= window + 2 * overlap:
        return CubicSpline(t, v, axis=0).derivative()(t)
    out = np.empty(v.shape)
    for a in range(0, n, window):
        b = min(a + window, n)
        lo, hi = max(a - overlap, 0), min(b + overlap, n)
        out[a:b] = CubicSpline(t[lo:hi], v[lo:hi], axis=0).derivative()(t[a:b])
    return out


LEVEL_TOL = 0.05
"""Relative tolerance when the record's spin levels are compared with the config's (5 %: the rate
error of a poor centrifuge, a few 1e-3, and the heading noise are far below it)."""


def level_g(rate_rad_s: float, arm_m: float) -> float:
    """The level (g) of a turn at ``rate_rad_s`` on the nominal arm ``arm_m`` (m): A = w^2 r_nom / g0
    (docs/lowprec-centrifuge.md §2)."""
    return rate_rad_s * rate_rad_s * arm_m / G0


def check_against_config(scan, study, method: str, max_gap_s: float) -> dict:
    """Refuse a record that is not a run of the config (InputError naming the column), before any
    filtering; return what was found (levels, samples per phase) for the summary. ``scan``: the
    record as read (:class:`.stream.Scan`: its spins, plateaus and samples per phase). A level comes
    from the heading rate over about 0.1 s (10 samples, so the heading noise averages out): its
    peak for a spin (schedule not static), its median for a plateau (hold), :func:`level_g`.

    ``proposed``: the record's spins must peak at the two levels of one of the config's proposed
    runs (``runs``, any platform; :data:`LEVEL_TOL`). ``traditional``: it must hold two plateaus at
    ``traditional.levels_g`` for ``traditional.hold_s`` each (within ``max_gap_s`` plus the
    plateau's median step): the method's eq. (2) uses those config values, not the record's.
    """
    arm = study.centrifuge.arm_m
    found = dict(scan.counts)
    if method == "traditional":
        holds = scan.holds
        want = list(study.traditional["levels_g"])
        if len(holds) != len(want):
            raise InputError("--data column schedule", f"the record has {len(holds)} 'hold' plateau(s); the "
                             f"traditional method (traditional.levels_g = {want}) needs {len(want)}")
        for i, ((lvl, a, b, _, step), w) in enumerate(zip(holds, want)):
            if abs(lvl - w) > LEVEL_TOL * w:
                raise InputError("--data column heading_deg", f"plateau {i + 1} (t = {a:g} .. {b:g} s) turns at "
                                 f"{lvl:.4g} g by the heading rate, but traditional.levels_g[{i}] = {w:g} g: the "
                                 "record is not this config's traditional run")
            dur, hold = b - a + step, float(study.traditional["hold_s"])
            if abs(dur - hold) > max_gap_s + step:
                raise InputError("--data column schedule", f"plateau {i + 1} lasts {dur:g} s (t = {a:g} .. {b:g} s), "
                                 f"but traditional.hold_s = {hold:g} s (record.max_gap_s = {max_gap_s:g} s)")
        return {"levels_g": [round(h[0], 4) for h in holds], "samples_per_phase": found,
                "samples_per_plateau": [h[3] for h in holds]}
    spins = scan.spins
    got = [s[0] for s in spins]
    runs = {f"{p}.{r}": lv for p, rr in study.runs.items() for r, lv in rr.items()}
    match = [n for n, lv in runs.items() if len(lv) == len(got)
             and all(abs(g - w) <= LEVEL_TOL * w for g, w in zip(got, lv))]
    if not match:
        raise InputError("--data column heading_deg", f"the record spins {len(got)} time(s) up to "
                         f"{[round(g, 3) for g in got]} g (heading rate, arm_m = {arm:g} m), which matches no "
                         f"proposed run of the config (runs: {runs}); add the run to the config or check arm_m")
    return {"levels_g": [round(g, 4) for g in got], "matches_runs": match, "samples_per_phase": found,
            "samples_per_spin": [s[3] for s in spins]}


def nominal_velocity(t: np.ndarray, psi_u: np.ndarray, arm_m: float) -> np.ndarray:
    """(N, 2) m/s: the error-free velocity (VE, VN) of a platform on an arm of ``arm_m`` turned to
    the unwrapped heading ``psi_u`` (rad) at times t (s) (docs/lowprec-centrifuge.md §7: d/dt arm
    (cos psi, sin psi)); central differences, so a block with one sample of context each side
    gives the whole record's values."""
    return np.gradient(arm_m * np.stack([np.cos(psi_u), np.sin(psi_u)], axis=-1), t, axis=0)


F_SCALE_TOL = 1e-3
"""Largest relative disagreement between the record's fE, fN and the derivative of its own VE, VN
(docs/lowprec-centrifuge.md §10, "Data that do not fit"): the coefficients' responses are
proportional to f and f^2, so a scale error e of f moves k2 by about 2 e k2, unseen by the fit
check; on the default runs 2e-3 in fE (5e-3 in fN) moves an estimate by one sigma
(benchmarks/fit_sensitivity.py), while clean records agree within 5.2e-5 (100 seeds of each
platform's runs)."""


def large_force_ratios(f: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One spin's ratios fE / dE, fN / dN of its recorded specific force f (n, 2) to the derivative
    of its velocity d (n, 2) (:func:`velocity_derivative`), m/s^2, over the samples where that
    component exceeds half the spin's 99th percentile (away from its zero crossings;
    docs/lowprec-centrifuge.md §10, "Data that do not fit")."""
    out = []
    for c in range(2):
        big = np.abs(d[:, c]) > 0.5 * np.quantile(np.abs(d[:, c]), 0.99)
        out.append(f[big, c] / d[big, c])
    return out[0], out[1]


def force_scale(ratios) -> np.ndarray:
    """(2,) the median of each component's spin ratios (:func:`large_force_ratios`, every spin's
    together; 1 where there are none): a median, so a single bad sample is left to the filter's
    own checks."""
    return np.array([float(np.median(r)) if r.size else 1.0 for r in ratios])


def specific_force_scale(rec: Record) -> np.ndarray:
    """(2,) :func:`force_scale` of a record held whole: its spins (schedule not static) one by one."""
    d = velocity_derivative(rec.t, rec.v, rec.window)
    moving = np.diff(np.r_[0, (rec.schedule != STATIC).astype(np.int8), 0])
    parts = [large_force_ratios(rec.f[a:b], d[a:b]) for a, b in zip(np.flatnonzero(moving == 1),
                                                                      np.flatnonzero(moving == -1))]
    return force_scale([np.concatenate([p[c] for p in parts]) if parts else np.zeros(0) for c in range(2)])


def check_plausible(scan, arm_m: float) -> None:
    """Refuse (InputError naming the column, exit 2, before the filter) a record whose velocities
    are a unit, sign or swap of the motion the config's arm and the record's heading imply
    (:func:`nominal_velocity`), or whose positions are one of the integral of its velocities
    (the INS's own position drifts by hundreds of metres on a spinning arm, its integral of
    velocity with it; :func:`platcal.plausibility.refuse_recognised_moments`): e.g. pE, pN in km
    are 1/1000 of the integrated VE, VN. Recorded ``fE``, ``fN`` must agree with the derivative of
    VE, VN (:func:`force_scale` of the spins' ratios) within :data:`F_SCALE_TOL`, a unit or a scale
    error of theirs being invisible to the fit check (the coefficients absorb it). ``scan``: the
    record's sums (:class:`.stream.Scan`: ``velocity``, ``position`` Moments, ``force_ratios``)."""
    refuse_recognised_moments(scan.velocity, ("VE", "VN"), "m/s",
                              f"VE, VN must be the INS's east and north velocities in m/s (on the arm of {arm_m:g} m: "
                              "arm x heading rate)")
    refuse_recognised_moments(scan.position, ("pE", "pN"), "m",
                              "pE, pN must be the INS's east and north positions in m (the integral of VE, VN); map "
                              "lat/lon or other units through the config's record.units",
                              source="the integral of the record's VE, VN")
    if not scan.f_recorded:  # differentiated from VE, VN: nothing to compare
        return
    for name, vel, ratio in zip(("fE", "fN"), ("VE", "VN"), force_scale(scan.force_ratios)):
        if not abs(ratio - 1.0) <= F_SCALE_TOL:
            raise InputError(f"--data column {name} (or {vel})",
                             f"{ratio:.6g} x the time derivative of {vel} while spinning, expected 1 within "
                             f"{F_SCALE_TOL:g} (docs/lowprec-centrifuge.md §10): one of the two is in another unit "
                             "or scale, and a scale error of the specific force scales the identified coefficients "
                             "unseen by the fit check; fE, fN must be the INS's own east and north specific force in "
                             "m/s^2 and VE, VN its velocities in m/s (or leave fE, fN out: they are then "
                             "differentiated from VE, VN)")


def coefficient_responses(rec: Record, lat_deg: float) -> np.ndarray:
    """(4, N, 4): the INS errors (dVE, dVN m/s, pE, pN m) a unit (1 ug/g or ug/g^2) of each
    coefficient kA_x, k2_x, kA_y, k2_y causes along the record, from its own specific force
    (docs/lowprec-centrifuge.md §5, §8: the error model integrated at the record's median step)."""
    lat = np.radians(lat_deg)
    dt = float(np.median(np.diff(rec.t)))
    out = np.empty((len(COEFFS), rec.t.size, 4))
    for j in range(len(COEFFS)):
        coef = np.zeros(8)
        coef[4 + j] = 1e-6
        integrate_error_model(dt, np.ascontiguousarray(rec.f, dtype=float), coef, np.zeros(3), np.zeros(7),
                              np.zeros((0, 2)), np.zeros((0, 3)), np.sin(lat), np.cos(lat), np.tan(lat), out[j],
                              np.zeros((0, 3)))
    return out


def compensated_frame(rec: Record, coeffs: np.ndarray, lat_deg: float) -> pd.DataFrame:
    """The record (``t, VE, VN, pE, pN, heading_deg, fE, fN, schedule``, its units) with the
    velocity and position errors the coefficients ``coeffs`` (kA_x, k2_x, kA_y, k2_y; ug/g,
    ug/g^2) cause taken out (§8: e_after = e - sum_k c_k S_k(t), :func:`coefficient_responses`)."""
    err = np.einsum("k,kni->ni", np.asarray(coeffs, float), coefficient_responses(rec, lat_deg))
    return Table({"t": rec.t, "VE": rec.v[:, 0] - err[:, 0], "VN": rec.v[:, 1] - err[:, 1],
                  "pE": rec.p[:, 0] - err[:, 2], "pN": rec.p[:, 1] - err[:, 3],
                  "heading_deg": np.mod(np.degrees(rec.psi), 360.0), "fE": rec.f[:, 0], "fN": rec.f[:, 1],
                  "schedule": np.asarray(SCHEDULE_NAMES)[rec.schedule]}).to_pandas()


def estimate_columns(names, est, sigma, truth: dict | None) -> dict:
    """``estimates.csv``'s columns (name -> values, for :func:`platcal.io.write_csv`): name,
    estimate, sigma (ug/g, ug/g^2; and truth, error where known), docs/lowprec-centrifuge.md §10."""
    cols = {"name": list(names), "estimate": np.asarray(est, float), "sigma": np.asarray(sigma, float)}
    if truth is not None:
        cols["truth"] = np.array([truth[n] for n in names], float)
        cols["error"] = cols["estimate"] - cols["truth"]
    return cols
