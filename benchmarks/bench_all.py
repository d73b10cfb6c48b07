"""One benchmark table for every rig: platcal against FilterPy stepping the same model (issue 22 item 2).

Per rig, on its default test (the scenario of its own ``benchmarks/bench_<rig>.py``), this script
times platcal's identification per replicate (a batch of ``--batch`` replicates, numba threads
as set) and the same filter written with FilterPy (``KalmanFilter`` / ``ExtendedKalmanFilter``),
driven step by step in Python on replicate 0 with the same model and the same inputs, then
compares the two estimates of replicate 0 (largest difference in platcal's 1-sigma). What each
side does:

* centrifuge: ``run_ekf`` (Table 1 scheme, 6 x 60 s, 20 ms) against
  :func:`bench_filter.filterpy_run` (``ExtendedKalmanFilter`` with the RK4 map and its exact
  Jacobian, the model of :mod:`platcal.rigs.centrifuge.attitude`);
* multiposition: ``run_ekf`` (scheme S8, 8 x 60 s, one pass, 27 states) against an
  ``ExtendedKalmanFilter`` with the rig's own compiled rate, RK4 and measurement functions
  (Phi = I + F dt + F^2 dt^2 / 2, Q = T T^T ARW^2 dt, the 6-D update with the angles wrapped);
* sled: ``identify`` (mechanisation, run and stop filters, compensation) with its linear filter
  ``platcal.rigs.sled.filters.kalman`` replaced by FilterPy's ``KalmanFilter`` (same Phi, Q, H, R;
  F from the filter's :class:`~platcal.rigs.sled.filters.Dynamics` as one numpy array);
* lowprec_centrifuge: ``identify_proposed`` (window means, then the 14-state filter) with its
  filter ``proposed.run_filter`` replaced by FilterPy's ``KalmanFilter`` (Joseph update, same
  Phi, H, Q, R per window).

For the last two, everything but the filter is platcal's on both sides, so the ratio is of the
whole identification; the filter calls are also timed alone on both sides (``filter_*``
columns: platcal's filter against FilterPy's on the same inputs). On every rig the model itself
(RK4 map and Jacobians, measurement, mechanisation, window means) is platcal's compiled code on
both sides: FilterPy drives the filter step by step in Python (predict, update, its matrix
algebra in numpy), as ``bench_filter`` does for the centrifuge. Each side's time is the best of
``--repeat`` runs, on both sides alike (the whole run's wall and CPU, and the filter calls' wall,
each its smallest): a busy instant of this machine costs a run of a few tens of milliseconds a
third of its time, and one run per side had let it land on either. The table (Markdown and CSV)
is written to ``benchmarks/bench_all.md`` and ``benchmarks/bench_all.csv`` with the machine's
matrix-multiply peak and the load average.

    python benchmarks/bench_all.py [--batch 20] [--repeat 3] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np
import pandas as pd

from platcal.study.tables import frame_markdown, write_table
from platcal.parallel import set_threads

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_filter  # noqa: E402  (the centrifuge's FilterPy baseline and the matmul peak)

TARGET = 50.0
FORMATS = {"platcal_s": ".4f", "filterpy_s": ".3f", "ratio": ".1f", "ratio_cpu": ".1f", "platcal_cpu_s": ".4f",
           "filterpy_cpu_s": ".3f", "filter_platcal_s": ".4f", "filter_filterpy_s": ".3f",
           "filter_ratio": ".1f", "normalised": ".2f", "max_diff_sigma": ".1e",
           "matmul_peak_gflops": ".1f", "load_start": ".2f", "load_end": ".2f"}


def best_time(fn, repeat: int) -> tuple[tuple[float, float], object]:
    """Smallest wall and process CPU time of ``repeat`` calls (s) and the last result: on a busy
    machine the CPU time shows the work, the wall time also the waiting."""
    wall, cpu, out = bench_filter.best_times(fn, repeat)
    return (wall, cpu), out


class Timed:
    """A stand-in for a module function that runs it and sums its wall time over calls (s):
    the filter's share of an identification whose other parts both sides share."""

    def __init__(self, fn):
        self.fn, self.wall = fn, 0.0

    def __call__(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.wall += time.perf_counter() - t0


def best_patched(module, name: str, fn, call, repeat: int) -> tuple[tuple[float, float], float, object]:
    """Best of ``repeat`` runs of ``call()`` with ``module.name`` replaced by ``fn`` under a
    :class:`Timed`: the smallest wall and CPU of the whole run (s), the smallest wall of the
    filter calls in a run (s), and the last run's result."""
    wall, cpu, filt, out = np.inf, np.inf, np.inf, None
    for _ in range(repeat):
        timed = Timed(fn)
        with Clock() as clock, mock.patch.object(module, name, timed):
            out = call()
        wall, cpu, filt = min(wall, clock.times[0]), min(cpu, clock.times[1]), min(filt, timed.wall)
    return (wall, cpu), filt, out


class Clock:
    """Wall and process CPU time of a ``with`` block (s): ``.times`` = (wall, cpu)."""

    def __enter__(self):
        self.t0, self.c0 = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.times = (time.perf_counter() - self.t0, time.process_time() - self.c0)


def centrifuge(B: int, repeat: int) -> dict:
    """The centrifuge's EKF, Table 1 scheme 6 x 60 s (bench_filter's case)."""
    from platcal.model.frames import DEG
    from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf

    scheme, params, settings, z, t = bench_filter.table1_case(B)
    run_ekf(EstimatorInput([zk[:, :20] for zk in z], [tk[:20] for tk in t], scheme.angles_deg, params), settings)
    tp, est = best_time(lambda: run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), settings), repeat)
    # FilterPy's side calls platcal's compiled model: loaded (or compiled) before its clock, as platcal's is
    bench_filter.filterpy_run([zk[0][:20] for zk in z], [tk[:20] for tk in t], scheme.angles_deg * DEG, params, settings)
    tf, (x_fp, _) = best_time(lambda: bench_filter.filterpy_run([zk[0] for zk in z], t, scheme.angles_deg * DEG,
                                                                params, settings), repeat)
    nc = est.n_coef
    d = np.max(np.abs(est.x[0, :nc] - x_fp[:nc]) / est.coef_sigma[0])
    return dict(rig="centrifuge", test=f"Table 1, 6 x 60 s, {nc + 3}-state EKF at 50 Hz", platcal_s=tp[0] / B,
                filterpy_s=tf[0], platcal_cpu_s=tp[1] / B, filterpy_cpu_s=tf[1], max_diff_sigma=d, note="")


def multiposition(B: int, repeat: int) -> dict:
    """The multiposition rig's 27-state EKF, scheme S8 (8 x 60 s), one pass (bench_multiposition's case)."""
    from filterpy.kalman import ExtendedKalmanFilter

    from platcal.model.frames import ARCSEC, DEG
    from platcal.rigs.multiposition.config import load_config
    from platcal.rigs.multiposition.filter import run_ekf, simulate
    from platcal.rigs.multiposition.model import layout_index, make_scratch, meas_k, rate_k, rk4_k

    cfg = load_config({"rig": "multiposition"})
    s8 = cfg.scheme("S8")
    t, _, Z = simulate(cfg, s8, list(range(B)))
    run_ekf(cfg, s8.angles_deg, t[:5], Z[:, :, :5], passes=1)
    tp, (coef, cov, _) = best_time(lambda: run_ekf(cfg, s8.angles_deg, t, Z, passes=1), repeat)

    p0 = cfg.p0(0)
    n = p0.size + 3
    lay = layout_index(0)
    wn, wu = cfg.site.params()
    C, dC, T, dT, f, eps, deps, greg = make_scratch(n)
    F = np.zeros((3, n))
    nxt = np.empty(3)
    zp = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.empty((3, 10), dtype=np.int64)
    nn = np.empty(3, dtype=np.int64)
    zero3 = np.zeros(3)
    arw2, set_var = cfg.arw_rad**2, cfg.sigma_set_rad**2
    phi0s = np.asarray(s8.angles_deg, float) * DEG

    # FilterPy's side calls platcal's compiled model: loaded (or compiled) before its clock, as platcal's is
    rate_k(phi0s[0], np.zeros(n), lay, wn, wu, zero3, nxt, F, True, C, dC, T, dT, f, eps, deps, greg)
    rk4_k(phi0s[0], np.zeros(n), lay, wn, wu, zero3, 0.02, nxt)
    meas_k(phi0s[0], np.zeros(n), lay, zp, Hs, hc, nn, C, dC)

    def wrap(a, b):
        d = (a - b).copy()
        d[3:] = (d[3:] + 648000.0) % 1296000.0 - 648000.0
        return d

    def fp_run():
        ekf = ExtendedKalmanFilter(dim_x=n, dim_z=6)
        ekf.x = np.zeros((n, 1))
        ekf.P = np.zeros((n, n))
        ekf.P[3:, 3:] = np.diag(p0**2)
        ekf.R = np.diag([cfg.sigma_a_ug**2] * 3 + [cfg.sigma_an_arcsec**2] * 3)
        for k in range(phi0s.shape[0]):
            fp_position(ekf, k)
        return ekf.x[3:, 0]

    def fp_position(ekf, k):
        x = ekf.x
        x[:3, 0] = 0.0
        ekf.P[:3, :] = 0.0
        ekf.P[:, :3] = 0.0
        ekf.P[:3, :3] = np.eye(3) * set_var
        for s in range(t.size):
            if s > 0:
                dt = t[s] - t[s - 1]
                xv = np.ascontiguousarray(ekf.x[:, 0])
                rate_k(phi0s[k], xv, lay, wn, wu, zero3, nxt, F, True, C, dC, T, dT, f, eps, deps, greg)
                Phi = np.eye(n)
                Phi[:3] += F * dt + 0.5 * dt * dt * (F[:, :3] @ F)
                ekf.F = Phi
                Q = np.zeros((n, n))
                Q[:3, :3] = arw2 * dt * (T @ T.T)
                ekf.Q = Q
                rk4_k(phi0s[k], xv, lay, wn, wu, zero3, dt, nxt)
                ekf.x_next = xv.copy()
                ekf.x_next[:3] = nxt
                ekf.P = Phi @ ekf.P @ Phi.T + Q
                ekf.x = ekf.x_next.reshape(n, 1)

            def hjac(xc):
                meas_k(phi0s[k], np.ascontiguousarray(xc[:, 0]), lay, zp, Hs, hc, nn, C, dC)
                H = np.zeros((6, n))
                for j in range(3):
                    H[j, hc[j, :nn[j]]] = Hs[j, :nn[j]]
                    H[3 + j, j] = 1.0 / ARCSEC
                return H

            def hx(xc):
                return zp.reshape(6, 1).copy()

            ekf.update(Z[0, k, s].reshape(6, 1), hjac, hx, residual=wrap)
    tf, x_fp = best_time(fp_run, repeat)
    d = np.max(np.abs(coef[0] - x_fp) / np.sqrt(np.diag(cov[0])))
    return dict(rig="multiposition", test=f"S8, 8 x 60 s, {n}-state EKF at {1 / (t[1] - t[0]):g} Hz, one pass",
                platcal_s=tp[0] / B, filterpy_s=tf[0], platcal_cpu_s=tp[1] / B, filterpy_cpu_s=tf[1],
                max_diff_sigma=d, note="the covariance algebra runs 4 replicates per vector (SIMD lanes, no fused "
                                       "multiply-adds: the numbers stay bit-identical); the scalar model chain per "
                                       "replicate (4 rates and the measurement, 15 sin/cos pairs; RK4's stages on "
                                       "scalars) is then about a third of a step; "
                                       "benchmarks/profile_multiposition.py")


def sled(B: int, repeat: int) -> dict:
    """The sled's run and stop filters inside ``identify`` (bench_sled's case, 85.9 s at 200 Hz)."""
    from filterpy.kalman import KalmanFilter

    from platcal.rigs.sled import filters
    from platcal.rigs.sled.config import load_config
    from platcal.rigs.sled.identify import identify
    from platcal.rigs.sled.montecarlo import replicate_seeds
    from platcal.rigs.sled.simulate import simulate

    cfg = load_config({"rig": "sled"})
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", range(B)))
    identify(cfg, sb.traj, sb.f[:1], sb.w[:1])

    def kalman_fp(Fs, z, x0, tun, T, T_nominal=None):
        Fs = Fs.dense() if isinstance(Fs, filters.Dynamics) else Fs   # the system matrices as numpy arrays
        S, J, n = Fs.shape[0], Fs.shape[1], Fs.shape[-1]
        T = np.broadcast_to(np.asarray(T, dtype=float), (J,))
        scale = np.ones(J) if tun.per_step or T_nominal is None else T / T_nominal
        Phis = filters.discretise(Fs, T)
        xs, sig, Pout = np.empty((S, J + 1, n)), np.empty((S, J + 1, n)), np.empty((S, n, n))
        nis = np.zeros(S)
        for s in range(S):
            kf = KalmanFilter(dim_x=n, dim_z=4)
            kf.x = x0[s].reshape(n, 1).copy()
            kf.P = np.array(np.broadcast_to(tun.P0, (S, n, n))[s])
            kf.R = np.asarray(tun.R, float)
            kf.H = np.eye(4, n)
            xs[s, 0], sig[s, 0] = kf.x[:, 0], np.sqrt(np.diag(kf.P))
            for j in range(J):
                kf.predict(F=Phis[s, j], Q=np.asarray(tun.Qd, float) * scale[j])
                kf.update(z[s, j].reshape(4, 1))
                nis[s] += float(kf.y[:, 0] @ kf.SI @ kf.y[:, 0]) / J
                kf.P = 0.5 * (kf.P + kf.P.T)
                xs[s, j + 1], sig[s, j + 1] = kf.x[:, 0], np.sqrt(np.maximum(np.diag(kf.P), 0.0))
            Pout[s] = kf.P
        return filters.FilterOut(xs, sig, Pout, nis, np.zeros(S, dtype=np.int64))

    tp, filt_pc, idn = best_patched(filters, "kalman", filters.kalman, lambda: identify(cfg, sb.traj, sb.f, sb.w),
                                    repeat)
    with mock.patch.object(filters, "kalman", kalman_fp):   # warm: F's and Phi's compiled builders loaded, as platcal's
        identify(cfg, sb.traj, sb.f[:1], sb.w[:1])
    tf, filt_fp, fp = best_patched(filters, "kalman", kalman_fp, lambda: identify(cfg, sb.traj, sb.f[:1], sb.w[:1]),
                                   repeat)
    d = max(np.max(np.abs(idn.run.x[0, -1] - fp.run.x[0, -1]) / idn.run.sigma[0, -1]),
            np.max(np.abs(idn.stop.x[0, -1] - fp.stop.x[0, -1]) / idn.stop.sigma[0, -1]))
    J = idn.run.x.shape[1] + idn.stop.x.shape[1] - 2
    return dict(rig="sled", test=f"85.9 s at 200 Hz, run + stop filters ({J} epochs), mechanisation, compensation",
                platcal_s=tp[0] / B, filterpy_s=tf[0], platcal_cpu_s=tp[1] / B, filterpy_cpu_s=tf[1],
                filter_platcal_s=filt_pc / B, filter_filterpy_s=filt_fp,
                max_diff_sigma=d, note="the run and stop filters (6 states by default, 7 and 6) run 4 replicates per vector "
                                        "(SIMD lanes; F and Phi = I + FT + (FT)^2/2 formed in the kernel from the "
                                        "mean force, Phi's zero products left out; FilterPy's side forms F and Phi "
                                        "with numpy): filter_ratio; the 200 Hz mechanisation, epoch means and X "
                                        "compensation, shared by both sides, are compiled loops over the replicates "
                                        "and add to platcal's time: benchmarks/profile_sled.py")


def lowprec_case(B: int):
    """The low-precision centrifuge's case: platform P1's first proposed run of the default config,
    B seeds (``[1, i]``) simulated. Returns ``(study, platform, run, run batch)``."""
    from platcal.rigs.lowprec_centrifuge.config import load_config
    from platcal.rigs.lowprec_centrifuge.truth import simulate_batch

    study = load_config({"rig": "lowprec_centrifuge"})
    p = study.platform_names()[0]
    r = [r for r in study.run_names(p) if r != "traditional"][0]
    return study, p, r, simulate_batch(study, p, r, [np.random.SeedSequence([1, i]) for i in range(B)])


def lowprec_centrifuge(B: int, repeat: int) -> dict:
    """The low-precision centrifuge's proposed method on one run of platform P1 (window means, then
    the 14-state filter); bench_lowprec_centrifuge times the whole scenario of which it is a part."""
    from filterpy.kalman import KalmanFilter

    from platcal.rigs.lowprec_centrifuge import proposed

    study, p, r, rb = lowprec_case(B)

    def ident(b0, b1):
        return proposed.identify_proposed(rb.prof.t, rb.v_ind[b0:b1], rb.p_ind[b0:b1], rb.psi[b0:b1],
                                          rb.f_meas[b0:b1],
                                          rb.prof.schedule, study.centrifuge.arm_m, study.latitude_deg)


    def run_filter_fp(T, z, m, valid, lat_rad, keep_innovations=False):
        nb, nw = T.shape
        q = proposed.q_density()
        Fw = proposed.f_matrix(lat_rad, m)
        x, P = np.zeros((nb, proposed.NX)), np.zeros((nb, proposed.NX, proposed.NX))
        for s in range(nb):
            kf = KalmanFilter(dim_x=proposed.NX, dim_z=4)
            kf.P = np.diag(proposed.P0_STD**2)
            kf.R = np.diag(proposed.R_DIAG)
            for w in range(nw):
                if not valid[s, w]:
                    continue
                phi, H = proposed.transition_and_h(Fw[s, w], T[s, w])
                kf.predict(F=phi, Q=np.diag(q * T[s, w]))
                kf.update(z[s, w].reshape(4, 1), H=H)
                kf.P = 0.5 * (kf.P + kf.P.T)
            x[s], P[s] = kf.x[:, 0], kf.P
        return proposed.FilterResult(x=x, P=P, n_windows=valid.sum(axis=1), mean_nis=np.full(nb, np.nan),
                                     failed_updates=np.zeros(nb, np.int64))

    tp, filt_pc, fr = best_patched(proposed, "run_filter", proposed.run_filter, lambda: ident(0, B), repeat)
    tf, filt_fp, fp = best_patched(proposed, "run_filter", run_filter_fp, lambda: ident(0, 1), repeat)
    sig = np.sqrt(np.diag(fr.P[0]))
    d = np.max(np.abs(fr.x[0] - fp.x[0]) / sig)
    return dict(rig="lowprec_centrifuge", test=f"platform {p} run {r}: {int(fr.n_windows[0])} windows, 14 states",
                platcal_s=tp[0] / B, filterpy_s=tf[0], platcal_cpu_s=tp[1] / B, filterpy_cpu_s=tf[1],
                filter_platcal_s=filt_pc / B, filter_filterpy_s=filt_fp, max_diff_sigma=d,
                note="the 14-state window filter is one compiled kernel over the replicates on the job's threads "
                     "(filter_ratio): FilterPy's side steps a window, not a sample, in Python (a few numpy calls on "
                     "14 x 14 matrices, some 40 us a window); the window means at the data rate (the heading's "
                     "cos and sin, cumulative integrals, revolution crossings), shared by both sides, are about "
                     "half of platcal's time and alone bound the ratio of the whole below 50x even with a free "
                     "filter: benchmarks/profile_lowprec.py")


RIGS = {"centrifuge": centrifuge, "multiposition": multiposition, "sled": sled,
        "lowprec_centrifuge": lowprec_centrifuge}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=20, help="replicates per platcal call (20)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each side (its best)")
    ap.add_argument("--threads", type=int, default=None, help="numba threads (default: all)")
    ap.add_argument("--rigs", nargs="+", default=list(RIGS), choices=list(RIGS))
    ap.add_argument("--out", default=str(HERE / "bench_all"), help="table path without suffix")
    a = ap.parse_args(argv)
    threads = set_threads(a.threads)
    load0 = os.getloadavg()[0]
    peak = bench_filter.matmul_peak()
    rows = []
    for name in a.rigs:
        row = RIGS[name](a.batch, a.repeat)
        # where the identification is the filter stepping the model (centrifuge, multiposition),
        # the filter's share is the whole run on both sides
        row.setdefault("filter_platcal_s", row["platcal_s"])
        row.setdefault("filter_filterpy_s", row["filterpy_s"])
        row["filter_ratio"] = row["filter_filterpy_s"] / row["filter_platcal_s"]
        row["ratio"] = row["filterpy_s"] / row["platcal_s"]
        row["ratio_cpu"] = row["filterpy_cpu_s"] / row["platcal_cpu_s"]
        if max(row["ratio"], row["ratio_cpu"]) >= TARGET:
            row["note"] = ""
        rows.append(row)
        print(f"{name}: platcal {row['platcal_s']:.4f} s/replicate, FilterPy {row['filterpy_s']:.3f} s, "
              f"ratio {row['ratio']:.1f} (CPU {row['ratio_cpu']:.1f}), max |dx| {row['max_diff_sigma']:.1e} sigma",
              flush=True)
    peak = max(peak, bench_filter.matmul_peak())
    load1 = os.getloadavg()[0]
    df = pd.DataFrame(rows)[["rig", "test", "platcal_s", "filterpy_s", "ratio", "platcal_cpu_s", "filterpy_cpu_s",
                             "ratio_cpu", "filter_platcal_s", "filter_filterpy_s", "filter_ratio", "max_diff_sigma",
                             "note"]]
    df["normalised"] = df["platcal_s"] * peak
    df["matmul_peak_gflops"] = peak
    df["load_start"], df["load_end"] = load0, load1
    df["batch"], df["threads"], df["cores"] = a.batch, threads, os.cpu_count()
    note = (f"`python benchmarks/bench_all.py`: batch {a.batch}, {threads} numba threads, {os.cpu_count()} cores, "
            f"matrix-multiply peak {peak:.1f} GFLOP/s, load average {load0:.2f} at start and {load1:.2f} at end. "
            f"each side's time the best of {a.repeat} runs; platcal s per replicate (wall; _cpu: process CPU time of "
            f"all threads, which shows the work when other processes hold the cores); FilterPy on replicate 0; normalised = platcal s per "
            f"replicate x peak GFLOP/s; max_diff_sigma = largest difference of the estimates of replicate 0 in "
            f"platcal's 1-sigma; filter_*: the wall time of the filter calls alone (the sled's run and stop "
            f"filters, the low-precision centrifuge's window filter; the whole run for the centrifuge and the "
            f"multi-position rig, whose filter steps the model); target ratio >= {TARGET:g}.")
    shown = df[["rig", "test", "platcal_s", "filterpy_s", "ratio", "ratio_cpu", "filter_ratio", "normalised",
                "max_diff_sigma", "note"]]
    write_table(df, a.out, "platcal against FilterPy, every rig", note, FORMATS)
    print()
    print(note)
    print(frame_markdown(shown, FORMATS))


if __name__ == "__main__":
    main()
