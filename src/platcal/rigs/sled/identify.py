"""Identification of a sled test: INS, run and stop filters, X compensation, metrics.

docs/rocket-sled.md §4-8. Everything is batched over a leading seed axis (S); one record is
S = 1. Times: navigation states at t_k (k = 0 … N−1, the record's rows; the state after the
last sample is dropped so that "end" is the last row), filter epochs at k = m·j.

Recorded times (docs/rocket-sled.md §12): with the record's ``t`` the navigation integrates each
sample over its actual interval, the epochs are the samples nearest the multiples of the filter
period (:func:`record_epochs`), the stop is the first sample at or after the trajectory's stop
time, and the X compensation and metric B use the same intervals; a clean record gives the grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...estimation.fit import FitCheck, fit_check
from ...jit import kernel_input, njit
from ...lighttable import Table
from ...logs.calibration import Calibration, calibration_of
from ...logs.increments import sample_intervals
from .aot_kernels import run_seeds
from .config import ARCSEC, DEG_H, G, SledConfig
from .errmodel import propagate_run_model
from ...records import nearest_samples
from .filters import Epochs, FilterOut, run_filter, stop_filter
from .ins import mechanise
from .simulate import Truth
from .trajectory import Trajectory

if TYPE_CHECKING:  # annotations only: an identify that imports this module does not load pandas
    import pandas as pd


@dataclass(frozen=True)
class Identification:
    """Results of :func:`identify` (SI units; arrays over seeds first)."""

    cfg: SledConfig
    traj: Trajectory
    v: np.ndarray            # (S,N,3) navigation velocity at t_k
    r: np.ndarray            # (S,N,3) navigation position at t_k
    fl: np.ndarray           # (S,N,3) computed specific force
    run: FilterOut
    stop: FilterOut
    j_stop: int
    j_end: int
    phi_run: np.ndarray      # (S,3) final run estimate [φ_x, φ_y, φ_z] (φ_x = NaN for 6 states), rad
    sig_run: np.ndarray      # (S,3) its 1 sigma, rad
    r_model: np.ndarray      # (S,n_stop+1,2) metric B model [δr_y, δr_z], m
    x_con: np.ndarray        # (S,N) compensated X position (config's compensation), m
    x_con_other: np.ndarray  # (S,N) the other compensation mode, m
    nabla_x_hat: np.ndarray  # (S,) stop filter by-product ∇̂_x = g (φ̂_y^run − φ̂_y^stop), m/s^2
    t: np.ndarray            # (N,) sample times from the record's start, s
    epochs: Epochs           # filter epochs (sample indices) and intervals
    n_stop: int              # sample index of the stop in the record
    tail_finite: np.ndarray | None = None   # (S,) a streamed record's navigation finite beyond its held run part

    @property
    def t_epochs(self) -> np.ndarray:
        return self.t[self.epochs.k]


def record_epochs(t: np.ndarray, period_s: float) -> Epochs:
    """Epochs of a record with times ``t`` (s from its start, increasing): the samples nearest
    the multiples of ``period_s`` within half the median step (decimation by time; an instant in
    a gap is skipped and the next prediction spans both periods), the first sample always being
    epoch 0 (the run filter's prior); sample intervals
    ``dts = diff(t)``, the last sample covering the median step."""
    k, T = epoch_samples(t, period_s)
    return Epochs(k=k, T=T, dts=sample_intervals(t))


def epoch_samples(t: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`record_epochs`' sample indices (J+1,) and intervals between them (J,) s."""
    step = float(np.median(np.diff(t)))
    k = np.union1d(0, nearest_samples(t, period_s, 0.5 * step))   # epoch 0 (the prior) is the first sample
    return k, np.diff(t[k])


def stop_index(t: np.ndarray, stop_time_s: float) -> int:
    """The record's sample of the stop: the first at or after the trajectory's stop time (half a
    median step of tolerance, so the grid's own sample is found despite jitter)."""
    tol = 0.5 * float(np.median(np.diff(t)))
    return int(min(np.searchsorted(t, stop_time_s - tol), t.size - 1))


def phi_columns(states: int) -> dict[str, int]:
    """Index of φ_x, φ_y, φ_z in the run state (§6.1)."""
    return {"phi_x": 4, "phi_y": 5, "phi_z": 6} if states == 7 else {"phi_y": 4, "phi_z": 5}


def compensate_x(fl: np.ndarray, r_x: np.ndarray, est: np.ndarray, hold: np.ndarray, dt) -> np.ndarray:
    """Open-loop X compensation (§7, eqs. 20-21) with sample k holding the attitude errors
    ``est[:, hold[k]]`` [φ_x, φ_y, φ_z] rad (:func:`phi_hold`).

    ``Δa_x = f_y φ̂_z − f_z φ̂_y``; ``v^c = v − Σ Δa dt`` (Euler), ``r^c = r − trapezoid`` (the
    INS's rules). ``r_x`` (S,N) at t_k, m, with ``fl`` (S,N,3) m/s^2; ``dt`` the IMU period or (N,)
    the record's sample intervals, s; returns r_x^c (S,N), m (one hold of :func:`compensate_modes`).
    """
    return compensate_modes(fl, np.asarray(r_x, dtype=np.float64)[..., None], est, np.asarray(hold)[None], dt)[0]


def x_corrections(fl: np.ndarray, phi_hat: np.ndarray, dt, start: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The along-track velocity and position errors (S,N+1) at t_0 … t_N, m/s and m, that the
    attitude errors ``phi_hat`` (S,N,3) rad cause through the computed specific force ``fl``
    (S,N,3) (§7, eqs. 20-21: ``Δa_x = f_y φ̂_z − f_z φ̂_y`` summed by the INS's rules), from
    ``start`` (dv, dr) (S,) each at t_0 (default 0: a streamed record's next block continues from
    the last values of the one before, the same sums as one block)."""
    phi_hat = np.asarray(phi_hat, dtype=float)
    N = fl.shape[1]
    if phi_hat.shape[1] > 0 and phi_hat.strides[1] == 0:   # one attitude held over the samples
        return x_corrections_held(fl, phi_hat[:, :1], np.zeros(N, dtype=np.int64), dt, start)
    return x_corrections_held(fl, phi_hat, np.arange(N), dt, start)


@njit(cache=True, nogil=True)
def _x_corrections(lo, hi, fl, est, hold, dts, dv0, dr0, dv, dr):
    """:func:`x_corrections_held` for seeds ``lo .. hi - 1``: the cumulative sums of numpy's
    ``cumsum`` (sequential), each term formed as there, so the same numbers."""
    for s in range(lo, hi):
        v = dv0[s]
        x = dr0[s]
        dv[s, 0] = v
        dr[s, 0] = x
        for k in range(fl.shape[1]):
            p = hold[k]
            da = fl[s, k, 1] * est[s, p, 2] - fl[s, k, 2] * est[s, p, 1]
            nv = v + da * dts[k]
            x = x + (v + nv) * 0.5 * dts[k]
            v = nv
            dv[s, k + 1] = v
            dr[s, k + 1] = x


def x_corrections_held(fl: np.ndarray, est: np.ndarray, hold: np.ndarray, dt,
                       start: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`x_corrections` with sample k's attitude errors ``est[:, hold[k]]`` (``est`` (S,M,3)
    rad, ``hold`` (N,) int: the estimate each sample holds, :func:`phi_hold`), without forming
    the (S,N,3) array; one compiled loop per seed, the seeds over the numba threads set."""
    fl = np.ascontiguousarray(fl, dtype=np.float64)
    S, N = fl.shape[:2]
    dts = kernel_input(np.broadcast_to(np.asarray(dt, dtype=np.float64), (N,)))
    dv0, dr0 = (np.zeros(S), np.zeros(S)) if start is None else (
        kernel_input(np.broadcast_to(np.asarray(v, dtype=np.float64), (S,))) for v in start)
    dv, dr = np.empty((S, N + 1)), np.empty((S, N + 1))
    run_seeds("x_corrections", _x_corrections, S, fl, np.ascontiguousarray(est, dtype=np.float64),
              np.ascontiguousarray(hold, dtype=np.int64), dts, dv0, dr0, dv, dr)
    return dv, dr


@njit(cache=True, nogil=True)
def _x_compensated(lo, hi, fl, r, est, holds, dts, out):
    """:func:`compensate_modes` for seeds ``lo .. hi - 1``: per hold row m, :func:`_x_corrections`'
    position sum from 0 (each term formed as there) subtracted from the navigation's X at each
    sample, ``out[m, s, k] = r[s, k, 0] − Σ_{i<k}`` (:func:`compensate_x`'s numbers, without the
    (S,N+1) sums in memory). Two hold rows per pass over the samples: their sums are independent
    chains the processor overlaps (an odd last row is paired with itself, written twice alike)."""
    M = holds.shape[0]
    for s in range(lo, hi):
        for m0 in range(0, M, 2):
            m1 = min(m0 + 1, M - 1)
            va, xa, vb, xb = 0.0, 0.0, 0.0, 0.0
            for k in range(fl.shape[1]):
                f1, f2, rx, dt = fl[s, k, 1], fl[s, k, 2], r[s, k, 0], dts[k]
                out[m0, s, k] = rx - xa
                out[m1, s, k] = rx - xb
                pa, pb = holds[m0, k], holds[m1, k]
                da = f1 * est[s, pa, 2] - f2 * est[s, pa, 1]
                db = f1 * est[s, pb, 2] - f2 * est[s, pb, 1]
                na = va + da * dt
                nb = vb + db * dt
                xa = xa + (va + na) * 0.5 * dt
                xb = xb + (vb + nb) * 0.5 * dt
                va, vb = na, nb


def compensate_modes(fl: np.ndarray, r: np.ndarray, est: np.ndarray, holds: np.ndarray, dt) -> np.ndarray:
    """:func:`compensate_x` for several holds at once (§7, eqs. 20-21; identify's realtime and post
    modes): ``holds`` (M,N) int, row m the estimate of ``est`` (S,J,3) rad each sample holds
    (:func:`phi_hold`); ``r`` (S,≥N,3) the navigation position, m (its X column is read; the
    mechanisation's own (S,N+1,3) array needs no copy); ``fl`` (S,N,3) m/s^2; ``dt`` s, the IMU
    period or (N,) the sample intervals. Returns r_x^c (M,S,N), m: per row the numbers of
    :func:`compensate_x`, bit for bit (one compiled pass per seed, the seeds over the numba
    threads set, no (S,N+1) sums formed)."""
    fl = kernel_input(fl)   # writable inputs: one compiled signature whatever the caller hands over
    S, N = fl.shape[:2]
    holds = np.require(holds, np.int64, ["C", "W"])
    dts = kernel_input(np.broadcast_to(np.asarray(dt, dtype=np.float64), (N,)))
    out = np.empty((holds.shape[0], S, N))
    run_seeds("x_compensated", _x_compensated, S, fl, kernel_input(r), kernel_input(est), holds, dts, out)
    return out


def compensated_track(cfg: SledConfig, f: np.ndarray, w: np.ndarray, t: np.ndarray, phi: np.ndarray) -> pd.DataFrame:
    """The along-track position X(t) (m) and velocity V(t) (m/s) of one record, navigated (§4)
    and compensated open loop with the constant attitude errors ``phi`` (3,) rad [φ_x, φ_y, φ_z]
    (§7, the ``post`` mode): columns ``t, x_nav_m, v_nav_m_s, x_m, v_m_s``. ``f``, ``w`` (N,3)
    m/s^2, rad/s; ``t`` (N,) s from the record's start, its samples' own intervals. A pandas
    DataFrame for the record writer (:meth:`platcal.lighttable.Table.to_pandas`)."""
    dts = sample_intervals(t)
    v, r, fl = mechanise(f[None], w[None], np.zeros((1, 3)), cfg.omega_ie, dts)
    n = t.size
    dv, dr = x_corrections(fl, np.broadcast_to(np.asarray(phi, float), (1, n, 3)), dts)
    return Table({"t": t, "x_nav_m": r[0, :n, 0], "v_nav_m_s": v[0, :n, 0],
                  "x_m": r[0, :n, 0] - dr[0, :n], "v_m_s": v[0, :n, 0] - dv[0, :n]}).to_pandas()


def phi_hold(run: FilterOut, states: int, epochs: np.ndarray, j_stop: int, n: int,
             mode: str) -> tuple[np.ndarray, np.ndarray]:
    """The run filter's φ̂ [φ_x, φ_y, φ_z] at its epochs (S,j_stop+1,3) rad and, for each of
    ``n`` samples, the epoch whose estimate the X compensation holds there (n,) (§7, D6):
    realtime = the latest (zero-order hold; the final one after the stop), post = the final one
    from t = 0. ``epochs``: the epochs' sample indices."""
    S = run.x.shape[0]
    est = np.zeros((S, j_stop + 1, 3))
    for name, i in phi_columns(states).items():
        est[..., "xyz".index(name[-1])] = run.x[:, :, i]
    if mode == "post":
        return est, np.full(n, j_stop, dtype=np.int64)
    return est, np.minimum(np.searchsorted(epochs, np.arange(n), side="right") - 1, j_stop)


def phi_per_sample(run: FilterOut, states: int, epochs: np.ndarray, j_stop: int, n: int, mode: str) -> np.ndarray:
    """φ̂(t_k) (S,n,3) for the X compensation, :func:`phi_hold`'s estimates per sample."""
    est, hold = phi_hold(run, states, epochs, j_stop, n, mode)
    if mode == "post":
        return np.broadcast_to(est[:, -1:, :], (est.shape[0], n, 3))
    return est[:, hold, :]


def run_attitude(run: FilterOut, states: int) -> tuple[np.ndarray, np.ndarray]:
    """The run filter's final [φ_x, φ_y, φ_z] and their sigmas (S,3) each, rad (φ_x NaN with 6 states)."""
    S = run.x.shape[0]
    phi_run = np.full((S, 3), np.nan)
    sig_run = np.full((S, 3), np.nan)
    for name, i in phi_columns(states).items():
        phi_run[:, "xyz".index(name[-1])] = run.x[:, -1, i]
        sig_run[:, "xyz".index(name[-1])] = run.sigma[:, -1, i]
    return phi_run, sig_run


def identify(cfg: SledConfig, traj: Trajectory, f: np.ndarray, w: np.ndarray,
             t: np.ndarray | None = None) -> Identification:
    """Run §4-7 on recorded samples f, ω (S,N,3) in the record's body axes (Ĉ_0 = I).

    ``t`` (N,): the samples' times from the record's start (s), as recorded; default the
    config's grid k·dt (then N must be the trajectory's length).
    """
    N = f.shape[1]
    if t is None:
        t = np.arange(N) * cfg.dt
        ep = Epochs.grid(N, cfg.kf_every, cfg.dt)
        n_stop = traj.n_stop
    else:
        t = np.asarray(t, dtype=float)
        ep = record_epochs(t, cfg.period_ms / 1000.0)
        n_stop = stop_index(t, traj.stop_time_s)
    dts = ep.dts
    v, r_nav, fl = mechanise(f, w, np.zeros((f.shape[0], 3)), cfg.omega_ie, dts)
    v, r = v[:, :N], r_nav[:, :N]
    j_stop = int(min(np.searchsorted(ep.k, n_stop), ep.k.size - 1))
    j_end = ep.k.size - 1
    run = run_filter(cfg, fl, v, r, j_stop, ep)
    phi_run, sig_run = run_attitude(run, cfg.states)
    iy = phi_columns(cfg.states)["phi_y"]
    stop = stop_filter(cfg, fl, v, r, j_stop, j_end, run.x[:, -1, iy], run.P[:, iy, iy], ep)
    phi_b = np.nan_to_num(phi_run)
    r_model = propagate_run_model(fl[:, :n_stop], cfg.omega_ie, phi_b, cfg.states, dts[:n_stop])
    modes = ("realtime", "post")
    held = [phi_hold(run, cfg.states, ep.k, j_stop, N, mode) for mode in modes]   # the same est, two holds
    xc = dict(zip(modes, compensate_modes(fl, r_nav, held[0][0], np.stack([h for _, h in held]), dts)))
    other = "post" if cfg.compensation == "realtime" else "realtime"
    nabla = G * (run.x[:, -1, iy] - stop.x[:, -1, 5])
    return Identification(cfg=cfg, traj=traj, v=v, r=r, fl=fl, run=run, stop=stop, j_stop=j_stop, j_end=j_end,
                          phi_run=phi_run, sig_run=sig_run, r_model=r_model, x_con=xc[cfg.compensation],
                          x_con_other=xc[other], nabla_x_hat=nabla, t=t, epochs=ep, n_stop=n_stop)


def run_problems(idn: Identification, s: int = 0) -> list[str]:
    """Why seed slot ``s``'s filter run cannot be trusted (empty if it can): non-finite navigation,
    estimates or sigmas of the run or stop filter, updates skipped because the innovation
    covariance was not positive definite, or a final covariance that is not positive definite."""
    out = []
    if not (np.all(np.isfinite(idn.v[s])) and np.all(np.isfinite(idn.r[s]))
            and (idn.tail_finite is None or idn.tail_finite[s])):
        out.append("the navigation is not finite (a non-physical sample?)")
    for name, fo in (("run", idn.run), ("stop", idn.stop)):
        if fo.failed_updates[s]:
            out.append(f"the {name} filter skipped {int(fo.failed_updates[s])} update(s): innovation covariance "
                       "not positive definite")
        if not (np.all(np.isfinite(fo.x[s])) and np.all(np.isfinite(fo.sigma[s]))):
            out.append(f"the {name} filter's estimates or sigmas are not finite")
        elif not np.all(np.isfinite(fo.P[s])):
            out.append(f"the {name} filter's covariance has non-finite entries")
        else:
            try:
                np.linalg.cholesky(0.5 * (fo.P[s] + fo.P[s].T))
            except np.linalg.LinAlgError:
                out.append(f"the {name} filter's final covariance is not positive definite")
    return out


def failed_runs(idn: Identification) -> np.ndarray:
    """(S,) True where a seed's run fails :func:`run_problems`."""
    return np.array([bool(run_problems(idn, s)) for s in range(idn.r.shape[0])])


def effective_phi(truth: Truth) -> np.ndarray:
    """Effective (apparent) attitude the filters estimate (§5, §8), rad (S,3):
    [φ_x + ∇_y/g (at rest), φ_y + M_zx, φ_z − M_yx]."""
    p = truth.params
    return np.stack([p.phi0[:, 0] + truth.nabla_static[:, 1] / G, p.phi0[:, 1] + p.M[:, 2, 0],
                     p.phi0[:, 2] - p.M[:, 1, 0]], axis=1)


def after_a(idn: Identification, static: bool = True) -> dict[str, np.ndarray]:
    """Metric A (§8): nav minus the filter's position-error estimate at the epochs (S,J); the
    stop filter's (``y_static``) only with ``static`` (a streamed record keeps its maximum,
    :class:`Tail`)."""
    kr = idn.epochs.k[:idn.j_stop + 1]
    out = {"y_run": idn.r[:, kr, 1] - idn.run.x[:, :, 1], "z_run": idn.r[:, kr, 2] - idn.run.x[:, :, 3]}
    if static:
        ks = idn.epochs.k[idn.j_stop:idn.j_end + 1]
        out["y_static"] = idn.r[:, ks, 1] - idn.stop.x[:, :, 1]
    return out


@dataclass(frozen=True)
class Tail:
    """What :func:`metrics` takes from the record beyond the stop (§8): per seed the largest
    lateral or vertical navigation error over every sample ``yz_max`` (m), metric A's largest
    stop-filter residual ``y_static_max`` (m) and, with the truth, the along-track errors at the
    last sample ``end`` (m: naive, compensated, the other compensation, instrument-only). A
    streamed record (:mod:`.stream`) keeps them as running values; :meth:`of` takes them from a
    whole one."""

    yz_max: np.ndarray
    y_static_max: np.ndarray
    end: dict[str, np.ndarray] | None = None

    @staticmethod
    def of(idn: Identification, truth: Truth | None) -> "Tail":
        end = None
        if truth is not None:
            end = end_errors(idn.r[:, -1, 0], idn.x_con[:, -1], idn.x_con_other[:, -1], truth.x_inst[:, -1],
                             truth.x_true[:, -1])
        return Tail(np.abs(idn.r[..., 1:]).max(axis=(1, 2)), np.abs(after_a(idn)["y_static"]).max(axis=1), end)


def end_errors(x_nav, x_con, x_other, x_inst, x_true) -> dict[str, np.ndarray]:
    """The along-track errors of :class:`Tail` ``end`` at one sample (S,) m from the navigated,
    compensated (the config's and the other mode) and the truths' positions there."""
    return {"naive": x_nav - x_inst, "con": x_con - x_inst, "other": x_other - x_inst, "inst": x_inst - x_true}


def after_b(idn: Identification) -> np.ndarray:
    """Metric B (§8): nav minus the model driven by the final run estimate, run phase (S,n_stop+1,2)."""
    n = idn.n_stop + 1
    rr = np.concatenate([idn.r, idn.r[:, -1:]], axis=1)[:, :n, 1:]
    return rr - idn.r_model


def metric_columns(idn: Identification, truth: Truth | None, tail: Tail | None = None) -> dict:
    """Per-seed metrics of §8 with the keys of §10 (cm, arcsec, µg; absolute values), one array
    of seeds per key. ``tail``: the values beyond the stop of a streamed record, whose ``idn`` and
    ``truth`` hold the run up to the stop only (default: from ``idn``'s whole record)."""
    tr, ns = idn.traj, idn.n_stop
    S = idn.r.shape[0]
    tail = Tail.of(idn, truth) if tail is None else tail
    a = after_a(idn, static=False)
    b = after_b(idn)
    yz = np.abs(idn.r[..., 1:])
    out = {
        "stop_time_s": np.full(S, tr.stop_time_s), "run_length_m": np.full(S, tr.run_length_m),
        "v_max_m_s": np.full(S, tr.v_max_m_s),
        "yz_before_max_run_cm": 100 * yz[:, :ns + 1].max(axis=(1, 2)),
        "yz_before_max_all_cm": 100 * tail.yz_max,
        "yz_before_stop_cm": 100 * yz[:, ns].max(axis=1),
        "y_after_a_max_run_cm": 100 * np.abs(a["y_run"]).max(axis=1),
        "z_after_a_max_run_cm": 100 * np.abs(a["z_run"]).max(axis=1),
        "y_after_a_max_static_cm": 100 * tail.y_static_max,
        "y_after_b_max_run_cm": 100 * np.abs(b[..., 0]).max(axis=1),
        "z_after_b_max_run_cm": 100 * np.abs(b[..., 1]).max(axis=1),
        "nabla_x_hat_ug": idn.nabla_x_hat / G * 1e6,
    }
    if truth is not None:
        e_naive = idn.r[..., 0] - truth.x_inst
        e_con = idn.x_con - truth.x_inst
        e_oth = idn.x_con_other - truth.x_inst
        e_inst = truth.x_inst - truth.x_true
        end = tail.end
        other = "post" if idn.cfg.compensation == "realtime" else "realtime"
        out.update({
            "x_naive_stop_cm": 100 * np.abs(e_naive[:, ns]), "x_constrained_stop_cm": 100 * np.abs(e_con[:, ns]),
            "x_naive_end_cm": 100 * np.abs(end["naive"]), "x_constrained_end_cm": 100 * np.abs(end["con"]),
            "x_naive_max_run_cm": 100 * np.abs(e_naive[:, :ns + 1]).max(axis=1),
            "x_constrained_max_run_cm": 100 * np.abs(e_con[:, :ns + 1]).max(axis=1),
            f"x_{other}_stop_cm": 100 * np.abs(e_oth[:, ns]), f"x_{other}_end_cm": 100 * np.abs(end["other"]),
            "x_inst_stop_cm": 100 * np.abs(e_inst[:, ns]), "x_inst_end_cm": 100 * np.abs(end["inst"]),
        })
        eff = effective_phi(truth)
        for i, ax in enumerate("xyz"):
            out[f"phi_{ax}_eff_err_arcsec"] = np.abs(idn.phi_run[:, i] - eff[:, i]) / ARCSEC
            out[f"phi_{ax}_true_err_arcsec"] = np.abs(idn.phi_run[:, i] - truth.params.phi0[:, i]) / ARCSEC
            out[f"phi_{ax}_sigma_arcsec"] = idn.sig_run[:, i] / ARCSEC
            out[f"phi0_{ax}_arcsec"] = truth.params.phi0[:, i] / ARCSEC          # signed: the drawn value
        out["nabla_x_err_ug"] = np.abs(idn.nabla_x_hat - truth.nabla_static[:, 0]) / G * 1e6
    return out


def metrics(idn: Identification, truth: Truth | None, tail: Tail | None = None) -> pd.DataFrame:
    """:func:`metric_columns` as a pandas DataFrame, one row per seed (the Monte Carlo's tables;
    :meth:`platcal.lighttable.Table.to_pandas`)."""
    return Table(metric_columns(idn, truth, tail)).to_pandas()


def estimate_columns(idn: Identification, truth: Truth | None, s: int = 0) -> dict:
    """estimates.csv of one seed slot, as columns: run-filter attitude (arcsec) with sigma, truth,
    effective; the stop filter's φ_x, φ_y and the by-product ∇̂_x (µg)."""
    eff = effective_phi(truth)[s] if truth is not None else np.full(3, np.nan)
    tru = truth.params.phi0[s] if truth is not None else np.full(3, np.nan)
    rows = []
    for i, ax in enumerate("xyz"):
        rows.append({"name": f"phi_{ax}", "filter": "run", "unit": "arcsec", "estimate": idn.phi_run[s, i] / ARCSEC,
                     "sigma": idn.sig_run[s, i] / ARCSEC, "truth": tru[i] / ARCSEC, "effective": eff[i] / ARCSEC})
    for i, ax in ((4, "x"), (5, "y")):
        rows.append({"name": f"phi_{ax}", "filter": "stop", "unit": "arcsec", "estimate": idn.stop.x[s, -1, i] / ARCSEC,
                     "sigma": idn.stop.sigma[s, -1, i] / ARCSEC, "truth": tru["xyz".index(ax)] / ARCSEC,
                     "effective": np.nan})
    nab = truth.nabla_static[s, 0] / G * 1e6 if truth is not None else np.nan
    rows.append({"name": "nabla_x", "filter": "stop", "unit": "ug", "estimate": idn.nabla_x_hat[s] / G * 1e6,
                 "sigma": np.nan, "truth": nab, "effective": np.nan})
    return {k: [r[k] for r in rows] for k in rows[0]}


def estimates(idn: Identification, truth: Truth | None, s: int = 0) -> pd.DataFrame:
    """:func:`estimate_columns` as a pandas DataFrame (:meth:`platcal.lighttable.Table.to_pandas`)."""
    return Table(estimate_columns(idn, truth, s)).to_pandas()


def calibration(idn: Identification, log_path, config: dict, s: int = 0) -> Calibration:
    """The calibration of one identified run (docs/rocket-sled.md §7): the run filter's attitude
    errors it estimates (arcsec; φ_x only with 7 states) with their covariance block, and the
    by-product ∇̂_x (µg), whose variance is not given by the filters (NaN)."""
    cols = phi_columns(idn.cfg.states)
    names = list(cols) + ["nabla_x"]
    idx = list(cols.values())
    n = len(names)
    cov = np.full((n, n), np.nan)
    cov[:-1, :-1] = idn.run.P[s][np.ix_(idx, idx)] / ARCSEC ** 2
    values = [idn.run.x[s, -1, i] / ARCSEC for i in idx] + [idn.nabla_x_hat[s] / G * 1e6]
    return calibration_of("sled", "rocket-sled.md", names, ["arcsec"] * (n - 1) + ["ug"], values, cov, log_path,
                          config)


def phi_from_calibration(cal: Calibration) -> np.ndarray:
    """(3,) rad: the attitude errors [φ_x, φ_y, φ_z] of a sled calibration (:func:`calibration`;
    φ_x 0 when the 6-state filter did not estimate it). InputError naming ``--calibration key
    names`` for one without φ_y, φ_z."""
    missing = [n for n in ("phi_y", "phi_z") if n not in cal.names]
    if missing:
        raise InputError("--calibration key names", f"lacks {missing[0]!r}; a sled calibration holds phi_y, phi_z "
                         "(and phi_x with 7 states), arcsec")
    return np.array([cal.value(n) if n in cal.names else 0.0 for n in ("phi_x", "phi_y", "phi_z")]) * ARCSEC


RUN_CHANNELS = ("run v_y", "run r_y", "run v_z", "run r_z")
"""The run filter's measured channels (docs/rocket-sled.md §6.1): the navigation's lateral
velocity (m/s) and position (m), y and z, whose true values are 0 on the track."""


def record_fit(idn: Identification, s: int = 0) -> FitCheck:
    """The fit check (:func:`platcal.estimation.fit.fit_check`) of seed slot ``s``'s run filter
    (docs/rocket-sled.md §6.1): its innovations of v_y, r_y, v_z, r_z and their predicted variances
    at the epochs up to the stop. The stop filter is left out: its measurements restart at the
    stop and its few epochs add little. No diagnosis: the filter predicts the navigation's error,
    not the IMU's output, so a unit, sign or swap is recognised before the filters
    (:func:`.record.check_plausible`), and a clock cannot be told from a drift here."""
    return fit_check(idn.run.innov[s], idn.run.s_var[s], RUN_CHANNELS)


def gyro_rate_error(cfg: SledConfig, traj: Trajectory, f: np.ndarray, w: np.ndarray, t: np.ndarray,
                    est: dict, tolerance: np.ndarray) -> dict:
    """What a constant gyro rate error the record cannot see does to the estimates (the
    ``gyro_rate_error`` block of metrics.json; docs/rocket-sled.md §3, §6, §10).

    The filters have no gyro-bias state, so their sigmas leave out the gyros' constant error
    (``imu.gyro.bias_deg_h`` and the g-sensitivity at 1 g, ``g_sens_deg_h_g``: ``sigma_deg_h``),
    and because the sled's true rate is the earth rate throughout, a gyro scale error 1 + e is the
    same as a rate error e omega_i in every sample: the record tells them apart only at rest,
    beyond ``tolerance`` (3,) rad/s (:func:`.record.static_rate_tolerance`). Each gyro of the
    record ``f``, ``w`` (N,3), ``t`` (N,) is offset by ``sigma_deg_h`` in turn and identified
    again (one batch of three), ``est`` the record's own :func:`estimate_columns`; per estimate the
    shift per sigma of each gyro (arcsec), the sigma with the three added in quadrature
    (``sigma_with_gyro_arcsec``: the honest 1 sigma with the config's gyros) and the shift, in
    the filter's sigma, of the largest rate error the check at rest lets pass
    (``shift_at_tolerance_sigmas``); per gyro the largest scale error that passes
    (``scale_tolerance``, ``tolerance / omega_i``)."""
    sig = gyro_rate_sigma(cfg)
    idn = identify(cfg, traj, np.repeat(f[None], 3, axis=0), gyro_offsets(cfg, w[None]), t=t) if sig > 0 else None
    return gyro_rate_block(cfg, est, tolerance, idn)


def gyro_rate_sigma(cfg: SledConfig) -> float:
    """The gyros' constant rate error the filters leave out, 1 sigma (rad/s): the bias
    ``imu.gyro.bias_deg_h`` and the g-sensitivity at 1 g ``g_sens_deg_h_g`` in quadrature."""
    return float(np.hypot(cfg.gyro["bias_deg_h"], cfg.gyro["g_sens_deg_h_g"])) * DEG_H


def gyro_offsets(cfg: SledConfig, w: np.ndarray) -> np.ndarray:
    """(3,N,3) rad/s: the rates ``w`` (1,N,3) with each gyro offset by :func:`gyro_rate_sigma` in turn."""
    return np.repeat(w, 3, axis=0) + gyro_rate_sigma(cfg) * np.eye(3)[:, None, :]


def gyro_rate_block(cfg: SledConfig, est: dict, tolerance: np.ndarray,
                    shifted: Identification | None, first: int = 0) -> dict:
    """:func:`gyro_rate_error`'s block from the identification ``shifted`` whose seed slots
    ``first`` … ``first + 2`` hold the record with each gyro offset (None: the config's gyros
    have no constant error)."""
    sig = gyro_rate_sigma(cfg)
    out = {"sigma_deg_h": sig / DEG_H, "rest_tolerance_deg_h": (np.asarray(tolerance) / DEG_H).tolist(),
           "scale_tolerance": (np.abs(np.asarray(tolerance) / cfg.omega_ie)).tolist(), "estimates": {}}
    if shifted is None:
        return out
    shifts = np.stack([np.array(estimate_columns(shifted, None, first + s)["estimate"]) for s in range(3)], axis=1) \
        - np.array(est["estimate"])[:, None]                     # (rows, 3 gyros), per sigma_deg_h
    rows = [dict(zip(est, values)) for values in zip(*est.values())]
    for i, row in enumerate(rows):
        if row["unit"] != "arcsec" or not np.isfinite(row["estimate"]):
            continue
        sh = shifts[i]
        at_tol = np.abs(sh) / sig * np.asarray(tolerance) / row["sigma"]
        out["estimates"][f"{row['name']} {row['filter']}"] = {
            "sigma_arcsec": float(row["sigma"]), "shift_per_gyro_sigma_arcsec": sh.tolist(),
            "sigma_with_gyro_arcsec": float(np.hypot(row["sigma"], np.linalg.norm(sh))),
            "shift_at_tolerance_sigmas": at_tol.tolist()}
    return out
