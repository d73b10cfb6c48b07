"""Benchmark of the batched simulator and EKF against FilterPy's ExtendedKalmanFilter (issue 5).

In one run, on the same simulated data (the paper's Table 1 scheme, 6 positions x dwell s,
default noise and filter settings), this script times:

* platcal ``simulate`` and ``run_ekf`` for batches of B = 1, 8, 64 replicates (per replicate,
  amortised over the batch; numba threads as set by ``--threads``);
* a baseline: FilterPy's ``ExtendedKalmanFilter`` driven step by step in Python with the same
  model functions (``platcal.rigs.centrifuge.attitude.rk4`` and ``platcal.rigs.centrifuge.attitude.measure``), on replicate 0;
* the covariance-only run (observability / GA objective) over a population of random schemes;
* every estimator kind of the registry (:data:`platcal.rigs.centrifuge.estimators.KINDS`, default
  options) at the largest batch, so that a newly registered kind appears here;

checks that platcal's estimate of replicate 0 agrees with FilterPy's, and reports the achieved
GFLOP/s of the filter's covariance algebra against this machine's measured matrix-multiply peak.
Issue 22's normalised cost (wall s per replicate x peak GFLOP/s, run_ekf at the largest batch) is
printed twice: with the peak measured once at the start, and as the median of ``--pairs``
adjacent pairs (the peak, a pause of :data:`BLAS_SETTLE_S`, then one run_ekf), each pair's figure printed too.
The last line is ``speedup_vs_filterpy=<ratio>`` (FilterPy s per replicate / platcal s per
replicate at the largest batch).

Usage::

    pip install -e '.[bench]'
    python benchmarks/bench_filter.py                # about a minute on 2 cores
    python benchmarks/bench_filter.py --dwell 10     # quicker, shorter dwell
    python benchmarks/bench_filter.py --lanes        # every filter row on the state-major kernel
    python benchmarks/bench_filter.py --default-kernel   # every filter row on the default kernel

Without either, ``run_ekf`` chooses (``FilterSettings.lanes`` None): the state-major kernel from
B = 8 (:data:`platcal.rigs.centrifuge.ekf.LANES_FROM_BATCH`), the default kernel below.

Wall-clock times; the load average at start and end is printed because other processes on the
machine slow every figure down.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from platcal.rigs.centrifuge import attitude as platform
from platcal.model.frames import ARCSEC, DEG
from platcal.model.instruments import N_FULL, N_IDENTIFIED
from platcal.parallel import get_threads, set_threads
from platcal.rigs.centrifuge.base import Centrifuge, specific_force
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge import ekf as centrifuge_ekf
from platcal.rigs.centrifuge.ekf import LANES_FROM_BATCH, FilterSettings, _structure, first_instant, run_ekf
from platcal.rigs.centrifuge.estimators import KINDS
from platcal.scheme import check_scheme
from platcal.scheme import TABLE1_POSITIONS
from platcal.rigs.centrifuge.simulate import Noise, simulate


def best_time(fn, repeat: int) -> tuple[float, object]:
    """Smallest wall time of ``repeat`` calls (s) and the last result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def best_times(fn, repeat: int) -> tuple[float, float, object]:
    """Smallest wall time and smallest process CPU time (all threads) of ``repeat`` calls (s),
    and the last result. CPU time shows the work done even when other processes hold cores."""
    wall, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu, out


def matmul_peak(n: int = 1500, repeat: int = 3) -> float:
    """Measured float64 matrix-multiply rate of numpy's BLAS on this machine, GFLOP/s."""
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    a @ b
    t, _ = best_time(lambda: a @ b, repeat)
    return 2.0 * n**3 / t / 1e9


BLAS_SETTLE_S = 0.3
"""Seconds between a pair's peak and its filter call: OpenBLAS's threads spin on after a call (0.10 s
of CPU in the 0.5 s after a 1500^3 product on this machine, stop 50), taking a core from the
filter's first tenth of a second: without the pause, the filter's median wall over 5 calls right
after a product was 0.0240 s per replicate against 0.0185 s away from one, alternating in one run."""


def adjacent_pairs(run, B: int, pairs: int) -> list[tuple[float, float]]:
    """``pairs`` times, the matrix-multiply peak (:func:`matmul_peak`), a pause of
    :data:`BLAS_SETTLE_S`, then one call of ``run`` (a batch of ``B``): ``(peak GFLOP/s, wall s per
    replicate)`` each. A pair's
    normalised cost compares the filter with the peak of the same seconds, which a single peak
    at the start of the run does not: on a shared VM both move by up to 1.8x minute to minute."""
    out = []
    for _ in range(pairs):
        peak = matmul_peak()
        time.sleep(BLAS_SETTLE_S)
        wall, _ = best_time(run, 1)
        out.append((peak, wall / B))
    return out


def filter_flops_per_step(n_coef: int = N_IDENTIFIED) -> int:
    """Floating-point operations of the covariance algebra of one platcal filter step (the
    sparse propagation and the Joseph update as implemented; the model and its Jacobians are
    not counted)."""
    pcols, _, hcols, _, hnnz = _structure(np.arange(n_coef))
    n, m = n_coef + 3, pcols.size
    prop = 2 * 3 * m * n + 2 * 6 * m            # W = Phi_d P, then the 3x3 block
    upd = 2 * int(hnnz.sum()) * n               # U = P H^T
    upd += 2 * 6 * int(hnnz.max())              # S
    upd += 18 * n + 21 * n + 18 * n             # K = S^-1 U, D = U - S K, x += K^T nu
    upd += 12 * n * (n + 1) // 2                # P - K U^T - D K^T, lower triangle
    return prop + upd


def table1_case(B: int, dwell: float = 60.0):
    """This benchmark's case for other scripts: the Table 1 scheme, 6 x ``dwell`` s, B replicates
    (seeds ``[2017, i]``) simulated at the default noise. Returns ``(scheme, params, settings, z,
    t)`` with ``z`` K arrays (B, M, 3) g and ``t`` K arrays (M,) s, as ``run_ekf`` takes them."""
    settings = FilterSettings()
    scheme = check_scheme("table1", {"dwell_s": dwell, "positions": [list(p) for p in TABLE1_POSITIONS]})
    params = Centrifuge().scheme_params(scheme)
    seeds = [np.random.SeedSequence([2017, i]) for i in range(B)]
    data = simulate(full_truth(), scheme, params, Noise(), seeds, keep_every=int(round(settings.period_s / 0.005)))
    i0 = first_instant(settings.update_at_reset)
    K = scheme.n_positions
    return scheme, params, settings, [data.A[:, k, i0:] for k in range(K)], [data.t[i0:]] * K


def filterpy_run(z, t, cmd_rad, params, settings: FilterSettings):
    """FilterPy's EKF over every position, driven step by step with the platcal model.

    ``z``: K arrays (M, 3) g; ``t``: K arrays (M,) s; ``cmd_rad`` (K, 3). Same filter as
    ``run_ekf`` with one pass: state = 45 coefficients + 3 angles, reset of the attitude at
    each position, RK4 propagation with the exact Jacobian, Joseph update (FilterPy's).
    """
    from filterpy.kalman import ExtendedKalmanFilter

    nc = N_IDENTIFIED
    n = nc + 3

    class PlatformEKF(ExtendedKalmanFilter):
        def predict_x(self, u=0):
            self.x = self.x_next

    ekf = PlatformEKF(dim_x=n, dim_z=3)
    ekf.x = np.zeros((n, 1))
    ekf.P = np.diag(np.r_[np.asarray(settings.p0_sigma) ** 2, np.zeros(3)])
    ekf.R = np.eye(3) * (settings.sigma_a_ug * 1e-6) ** 2
    reset_var = (settings.sigma_set_arcsec * ARCSEC) ** 2
    q_rate = (settings.arw_deg_rth * DEG / 60.0) ** 2
    coef = np.zeros(N_FULL)
    cache = {}

    def h_jac(x, tm, pk):
        coef[:nc] = x[:nc, 0]
        out, hc, ha = platform.measure(x[nc:, 0], coef, specific_force(tm, pk), pk)
        H = np.zeros((3, n))
        H[:, :nc] = hc[:, :nc]
        H[:, nc:] = ha
        cache["hx"] = out.reshape(3, 1)
        return H

    def h_x(x):
        return cache["hx"]

    Q = np.zeros((n, n))
    for k in range(len(t)):
        pk = params[k]
        x = ekf.x
        x[nc:, 0] = cmd_rad[k]
        P = ekf.P
        P[nc:, :] = 0.0
        P[:, nc:] = 0.0
        P[nc:, nc:] = np.eye(3) * reset_var
        t_prev = 0.0  # the reset instant: the filter propagates from it to the first instant
        for m in range(len(t[k])):
            if t[k][m] > t_prev:
                h = t[k][m] - t_prev
                coef[:nc] = ekf.x[:nc, 0]
                fr3 = np.stack([specific_force(t_prev + c * h, pk) for c in (0.0, 0.5, 1.0)])
                ang, pa, pc = platform.rk4(ekf.x[nc:, 0], coef, fr3, h, pk)
                F = np.eye(n)
                F[nc:, :nc] = pc[:, :nc]
                F[nc:, nc:] = pa
                x_next = ekf.x.copy()
                x_next[nc:, 0] = ang
                ekf.x_next = x_next
                ekf.F = F
                Q[nc:, nc:] = np.eye(3) * q_rate * h
                ekf.Q = Q
                ekf.predict()
                t_prev = t[k][m]
            ekf.update(z[k][m].reshape(3, 1), h_jac, h_x, args=(t[k][m], pk))
    return ekf.x[:, 0].copy(), ekf.P.copy()


KERNEL_CHOICE = {None: f"run_ekf's choice (the state-major kernel from B = {LANES_FROM_BATCH})",
                 True: "the state-major kernel (lanes=True)", False: "the default kernel (lanes=False)"}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dwell", type=float, default=60.0, help="dwell per position, s (60)")
    ap.add_argument("--batches", type=int, nargs="+", default=[1, 8, 64], help="batch sizes")
    ap.add_argument("--population", type=int, default=64, help="schemes per covariance-only batch")
    ap.add_argument("--threads", type=int, default=None, help="numba threads (default: all)")
    ap.add_argument("--repeat", type=int, default=2, help="timed repeats per platcal figure (best)")
    ap.add_argument("--pairs", type=int, default=5,
                    help="adjacent (peak, run_ekf at the largest batch) pairs for the normalised cost's median (5)")
    kernel = ap.add_mutually_exclusive_group()
    kernel.add_argument("--lanes", action="store_const", const=True, default=None,
                        help="every platcal filter row (and the agreement) on the state-major kernel (lanes=True)")
    kernel.add_argument("--default-kernel", dest="lanes", action="store_const", const=False,
                        help="every platcal filter row on the default kernel (lanes=False)")
    args = ap.parse_args(argv)

    set_threads(args.threads)
    load0 = os.getloadavg()
    scheme = check_scheme("table1", {"dwell_s": args.dwell, "positions": [list(p) for p in TABLE1_POSITIONS]})
    cen = Centrifuge()
    params = cen.scheme_params(scheme)
    # the kernel choice travels in the settings: the run_ekf rows, the registry's estimators and
    # the covariance-only run all follow it
    settings = FilterSettings(lanes=args.lanes)
    K = scheme.n_positions
    truth = full_truth()
    Bmax = max(args.batches)
    seeds = [np.random.SeedSequence([2017, i]) for i in range(Bmax)]
    keep = int(round(settings.period_s / 0.005))

    def sim(B):
        return simulate(truth, scheme, params, Noise(), seeds[:B], keep_every=keep)

    # the filter's default instants: period, 2 period, ... < dwell (docs/centrifuge-model.md §14)
    i0 = first_instant(settings.update_at_reset)

    def record(data, B):
        return centrifuge_ekf.EstimatorInput([data.A[:B, k, i0:] for k in range(K)], [data.t[i0:]] * K,
                                             scheme.angles_deg, params)

    def ekf(data, B):
        return run_ekf(record(data, B), settings)

    def estimator(kind, data, B):
        return KINDS[kind].run(record(data, B), settings)

    # compile (numba caches on disk; the first call of a process still loads and links)
    warm = check_scheme("w", {"dwell_s": 0.2, "positions": [list(p) for p in TABLE1_POSITIONS[:2]]})
    wd = simulate(truth, warm, cen.scheme_params(warm), Noise(), seeds[:2], keep_every=keep)
    wparams = cen.scheme_params(warm)
    for lanes in (True, False) if args.lanes is None else (args.lanes,):
        run_ekf(centrifuge_ekf.EstimatorInput([wd.A[:, k] for k in range(2)], [wd.t] * 2, warm.angles_deg, wparams),
                settings, lanes=lanes)
        run_ekf(centrifuge_ekf.EstimatorInput([None] * 2, [wd.t] * 2, warm.angles_deg, wparams), settings,
                linearise_about=np.repeat(truth[None], 2, axis=0), lanes=lanes)

    peak = matmul_peak()
    n_steps = K * (int(round(args.dwell / settings.period_s)) - i0)
    flops = filter_flops_per_step()
    print(f"platcal filter benchmark: Table 1 scheme, {K} x {args.dwell:g} s, {n_steps} filter steps "
          f"of {settings.period_s * 1e3:g} ms per replicate, numba threads {get_threads()}, "
          f"cores {os.cpu_count()}, load average {load0[0]:.2f}"
          f", filter rows: {KERNEL_CHOICE[args.lanes]}")
    print(f"matrix-multiply peak (numpy BLAS, float64, 1500^3): {peak:.1f} GFLOP/s")

    data = sim(Bmax)
    rows = []
    est1 = None
    for B in sorted(args.batches):
        ts, cs, _ = best_times(lambda: sim(B), args.repeat)
        te, ce, est = best_times(lambda: ekf(data, B), args.repeat)
        if B == 1:
            est1 = est
        rows.append((B, ts / B, te / B, (ts + te) / B, flops * n_steps * B / te / 1e9,
                     cs / B, ce / B))
    if est1 is None:
        est1 = ekf(data, 1)

    # every registered estimator kind with its default options, at the largest batch
    kinds = []
    for kind in KINDS:
        estimator(kind, data, 1)  # compile / load
        tk, ck, _ = best_times(lambda: estimator(kind, data, Bmax), args.repeat)
        kinds.append((kind, tk / Bmax, ck / Bmax))

    # warm: FilterPy's side calls platcal's compiled model, loaded (or compiled, after an edit of
    # src/platcal) here, before its clock, as platcal's side is by its first, untimed calls
    filterpy_run([data.A[0, k, i0:i0 + 3] for k in range(K)], [data.t[i0:i0 + 3]] * K, scheme.angles_deg * DEG,
                 params, settings)
    t0, c0 = time.perf_counter(), time.process_time()
    x_fp, P_fp = filterpy_run([data.A[0, k, i0:] for k in range(K)], [data.t[i0:]] * K, scheme.angles_deg * DEG,
                              params, settings)
    t_fp, c_fp = time.perf_counter() - t0, time.process_time() - c0

    # agreement of replicate 0: estimates relative to the truth's scale and in sigmas
    x_pc, P_pc = est1.x[0], est1.P[0]
    sig = np.sqrt(np.diag(P_pc))
    nc = N_IDENTIFIED
    d_sigma = np.max(np.abs(x_pc[:nc] - x_fp[:nc]) / sig[:nc])
    d_rel = np.max(np.abs(x_pc[:nc] - x_fp[:nc]) / np.abs(truth[:nc]))
    d_sig = np.max(np.abs(np.sqrt(np.diag(P_fp))[:nc] / sig[:nc] - 1.0))
    agree = d_sigma < 1e-4 and d_sig < 1e-4

    P = args.population
    rng = np.random.default_rng(1)
    cmd = np.zeros((P, K, 3))
    cmd[:, :, 0] = rng.integers(0, 360, (P, K))
    cmd[:, :, 2] = rng.integers(0, 360, (P, K))
    lin = np.repeat(truth[None], P, axis=0)
    cov_settings = FilterSettings(history_every_s=None, lanes=args.lanes)
    cov_input = centrifuge_ekf.EstimatorInput([None] * K, [data.t[i0:]] * K, cmd, params)
    tc, cc, _ = best_times(lambda: run_ekf(cov_input, cov_settings, linearise_about=lin), args.repeat)

    print()
    print("| run | B | wall s per replicate | CPU s per replicate | replicates/s (wall) "
          "| covariance GFLOP/s | % of peak |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for B, s_sim, s_ekf, s_tot, gf, c_sim, c_ekf in rows:
        print(f"| platcal simulate | {B} | {s_sim:.4f} | {c_sim:.4f} | {1 / s_sim:.1f} | | |")
        print(f"| platcal run_ekf | {B} | {s_ekf:.4f} | {c_ekf:.4f} | {1 / s_ekf:.1f} | {gf:.2f} "
              f"| {100 * gf / peak:.1f} |")
        print(f"| platcal simulate + run_ekf | {B} | {s_tot:.4f} | {c_sim + c_ekf:.4f} | {1 / s_tot:.1f} | | |")
    for kind, wall_k, cpu_k in kinds:
        print(f"| estimator {kind} (registry, default options: {KINDS[kind].description}) | {Bmax} | {wall_k:.4f} "
              f"| {cpu_k:.4f} | {1 / wall_k:.1f} | | |")
    gf_fp = flops * n_steps / t_fp / 1e9
    print(f"| FilterPy ExtendedKalmanFilter loop | 1 | {t_fp:.4f} | {c_fp:.4f} | {1 / t_fp:.2f} "
          f"| {gf_fp:.3f} (same count) | |")
    print(f"| covariance-only run, random {K}-position schemes | {P} | {tc / P:.4f} | {cc / P:.4f} "
          f"| {P / tc:.1f} | | |")
    print()
    print(f"estimates agree (replicate 0, platcal B=1 vs FilterPy): max |dx|/sigma = {d_sigma:.2e}, "
          f"max |dx|/|truth| = {d_rel:.2e}, max |sigma ratio - 1| = {d_sig:.2e} -> "
          f"{'OK' if agree else 'MISMATCH'}")
    print(f"covariance-only: {P / tc:.1f} scheme evaluations/s, {tc / P:.4f} s per evaluation "
          f"({K} x {args.dwell:g} s, batch of {P})")
    load1 = os.getloadavg()
    print(f"load average at end: {load1[0]:.2f}")
    best = rows[-1]
    # issue 22's machine-normalised cost: wall s per replicate x this run's matrix-multiply peak
    print(f"normalised cost (run_ekf, B={best[0]}, {get_threads()} thread(s)): wall s per replicate x peak "
          f"GFLOP/s = {best[2] * peak:.2f}; CPU s per replicate x peak = {best[6] * peak:.2f}")
    if args.pairs > 0:
        adj = adjacent_pairs(lambda: ekf(data, Bmax), Bmax, args.pairs)
        each = ", ".join(f"{p * w:.2f} ({p:.1f} GFLOP/s, {w:.4f} s)" for p, w in adj)
        print(f"normalised cost, {args.pairs} adjacent pairs (the peak, {BLAS_SETTLE_S:g} s, then run_ekf at B={Bmax}): {each}; "
              f"median {float(np.median([p * w for p, w in adj])):.2f}")
    print(f"speedup on CPU time (FilterPy CPU s / platcal CPU s per replicate, B={best[0]}): "
          f"{c_fp / best[6]:.1f}")
    print(f"speedup_vs_filterpy={t_fp / best[2]:.1f}")


if __name__ == "__main__":
    main()
