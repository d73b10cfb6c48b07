"""Where the multi-position rig's EKF cycles go (issue 22 item 2): each part of one filter step
timed alone, in a compiled loop on one thread, on a realistic state and covariance (the end of
one pass of scheme S8, 27 states; docs/multiposition-1g.md §9).

Parts, in the order the step runs them (the one-replicate reference kernel
:func:`platcal.rigs.multiposition.filter._ekf_one`):
the rate of §4 with its analytic Jacobian F, Phi's 3 rows (I + F dt + F^2 dt^2 / 2 on the
dynamic columns) and Q, the sparse propagation of P, RK4's three further rate evaluations, the
measurement of §7 with its Jacobian, the accelerometer update (3 rows, sparse H) and the angle
update (3 rows of 1/arcsec on phi) in Joseph form. Prints ns per call (CPU time of the thread)
and the share of the reference kernel's whole step (one replicate, one thread), then the whole
step of the kernel the filter runs (``run_filter``: replicates in SIMD lanes, the same numbers)
per replicate at B = 1 (one live lane) and at ``--batch`` replicates.

    python benchmarks/profile_multiposition.py [--steps 20000] [--batch 64]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from platcal.estimation.lanes import LANES
from platcal.model.frames import ARCSEC, DEG
from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.filter import _ekf_range, dynamic_cols, run_filter, simulate, transition_rows
from platcal.rigs.multiposition.model import (gyro_coefs, layout_index, make_scratch, meas_k, rate, rate_k, rk4_s,
                                              rot_t_into)

sys.path.insert(0, str(Path(__file__).resolve().parent))

from profile_ekf import _loop_copy, _loop_propagate, _loop_update, per_call  # noqa: E402  (the centrifuge's loops)


@njit(cache=True)
def _loop_rate_jac(steps, phi0, x, lay, wn, wu):
    n = x.shape[0]
    C, dC, T, dT, f, eps, deps, greg = make_scratch(n)
    F = np.zeros((3, n))
    nxt = np.empty(3)
    zero3 = np.zeros(3)
    acc = 0.0
    x0 = x[:3].copy()
    for s in range(steps):
        for i in range(3):  # new angles each call: the compiler cannot hoist the sines
            x[i] = x0[i] + 1e-12 * (s % 7)
        rate_k(phi0, x, lay, wn, wu, zero3, nxt, F, True, C, dC, T, dT, f, eps, deps, greg)
        acc += nxt[0] + F[0, 0]
    return acc


@njit(cache=True)
def _loop_phi_q(steps, F, T, cols, dt, arw2):
    phi = np.empty((3, cols.shape[0]))
    q = np.empty((3, 3))
    acc = 0.0
    for _ in range(steps):
        transition_rows(F, T, cols, dt, arw2, phi, q)
        acc += phi[0, 0] + q[0, 0]
    return acc


@njit(cache=True)
def _loop_rk4(steps, phi0, x, lay, wn, wu, dt):
    acc = 0.0
    x0 = x[:3].copy()
    for s in range(steps):
        for i in range(3):
            x[i] = x0[i] + 1e-12 * (s % 7)
        g0, g1, g2, on = gyro_coefs(x, lay)
        p0, p1, p2 = rk4_s(phi0[0], phi0[1], phi0[2], x[0], x[1], x[2], g0, g1, g2, on, wn, wu, 0.0, 0.0, 0.0, dt,
                           1e-6, 2e-6, 3e-6)
        acc += p0 + p1 + p2
    return acc


@njit(cache=True)
def _loop_meas(steps, phi0, x, lay):
    zp = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.empty((3, 10), dtype=np.int64)
    nn = np.empty(3, dtype=np.int64)
    C, dC = np.empty((3, 3)), np.empty((3, 3, 3))
    acc = 0.0
    x0 = x[:3].copy()
    for s in range(steps):
        for i in range(3):
            x[i] = x0[i] + 1e-12 * (s % 7)
        meas_k(phi0, x, lay, zp, Hs, hc, nn, C, dC)
        acc += zp[0] + Hs[0, 0]
    return acc


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--batch", type=int, default=64, help="replicates of the lane kernel's batch run (64)")
    args = ap.parse_args(argv)
    cfg = load_config({"rig": "multiposition"})
    s8 = cfg.scheme("S8")
    t, _, Zb = simulate(cfg, s8, list(range(args.batch)))
    Z = np.ascontiguousarray(Zb[:1])
    # the whole step per replicate, one thread (per_call's best of 5 CPU times of one call,
    # divided by the steps): the reference kernel on one replicate (the parts below are its),
    # and run_filter (replicates in lanes) on one replicate and on the batch
    steps = s8.n_positions * t.size
    lay, wn, wu, cols = layout_index(0), *cfg.site.params(), dynamic_cols(0)
    r_var = np.array([cfg.sigma_a_ug**2] * 3 + [cfg.sigma_an_arcsec**2] * 3)
    phi0s = np.asarray(s8.angles_deg, float) * DEG
    nc = cfg.p0(0).size
    n = nc + 3

    def reference(k):
        X, Ps = np.zeros((1, n)), np.zeros((1, n, n))
        Ps[0, 3:, 3:] = np.diag(cfg.p0(0) ** 2)
        tk = np.broadcast_to(t[:k], (phi0s.shape[0], k)).copy()
        _ekf_range(0, 1, X, Ps, phi0s, tk, np.ascontiguousarray(Z[:, :, :k]), np.full(phi0s.shape[0], k), lay, wn,
                   wu, r_var, cfg.arw_rad**2, cfg.sigma_set_rad**2, cols, True, 0, 0.0, np.empty(1), np.zeros(1),
                   np.zeros(1, dtype=np.int64), np.zeros((1, 0, 0, 12)))

    whole = per_call(reference, t.size) * t.size / steps
    lanes1 = per_call(lambda k: run_filter(cfg, s8.angles_deg, t[:k], Z[:, :, :k], passes=1, threads=1),
                      t.size) * t.size / steps
    lanes = per_call(lambda k: run_filter(cfg, s8.angles_deg, t[:k], Zb[:, :, :k], passes=1, threads=1),
                     t.size, repeat=3) * t.size / steps / args.batch
    # a realistic point: the coefficients and covariance at the end of a short run, phi and its
    # covariance as after the last position's dwell
    tc, Zc = t[:500], Z[:, :, :500]
    X = np.zeros((1, n))
    Ps = np.zeros((1, n, n))
    Ps[0, 3:, 3:] = np.diag(cfg.p0(0) ** 2)
    tk = np.broadcast_to(tc, (phi0s.shape[0], tc.size)).copy()
    nk = np.full(phi0s.shape[0], tc.size, dtype=np.int64)
    _ekf_range(0, 1, X, Ps, phi0s, tk, np.ascontiguousarray(Zc), nk, lay, wn, wu, r_var, cfg.arw_rad**2,
               cfg.sigma_set_rad**2, cols, True, 0, 0.0, np.empty(1), np.zeros(1), np.zeros(1, dtype=np.int64),
               np.zeros((1, 0, 0, 12)))
    x, P = X[0].copy(), np.ascontiguousarray(Ps[0])
    phi0 = phi0s[-1].copy()
    dt = float(t[1] - t[0])
    _, F = rate(phi0, x, cfg.site)
    C, dC, T, dT, *_ = make_scratch(n)
    rot_t_into(phi0[0] + x[0], phi0[1] + x[1], phi0[2] + x[2], C, dC, T, dT, False)
    phi, q = np.empty((3, cols.size)), np.empty((3, 3))
    transition_rows(F, T, cols, dt, cfg.arw_rad**2, phi, q)
    zp = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.empty((3, 10), dtype=np.int64)
    nn = np.empty(3, dtype=np.int64)
    meas_k(phi0, x, lay, zp, Hs, hc, nn, np.empty((3, 3)), np.empty((3, 3, 3)))
    innov_a = Z[0, -1, tc.size, :3] - zp[:3]
    ha = np.full((3, 1), 1.0 / ARCSEC)
    hca = np.arange(3, dtype=np.int64).reshape(3, 1)
    nna = np.ones(3, dtype=np.int64)
    innov_n = np.array([1.0, -2.0, 0.5])
    s = args.steps
    copy = per_call(lambda k: _loop_copy(k, P.copy()), s)
    parts = {
        "rate of §4 + analytic Jacobian F (3 sin/cos pairs)": (per_call(
            lambda k: _loop_rate_jac(k, phi0, x.copy(), lay, wn, wu), s), False),
        "Phi's 3 rows and Q": (per_call(lambda k: _loop_phi_q(k, F, T, cols, dt, cfg.arw_rad**2), s), False),
        "propagate_sparse (3 rows x 15 columns)": (per_call(
            lambda k: _loop_propagate(k, P.copy(), np.arange(3), cols, phi, q), s), True),
        "RK4's 3 further rates (no Jacobian; 9 sin/cos pairs)": (per_call(
            lambda k: _loop_rk4(k, phi0, x.copy(), lay, wn, wu, dt), s), False),
        "measurement of §7 + Jacobian (3 sin/cos pairs)": (per_call(
            lambda k: _loop_meas(k, phi0, x.copy(), lay), s), False),
        "accelerometer update (Joseph, 3 rows)": (per_call(lambda k: _loop_update(
            k, x.copy(), P.copy(), hc, nn, Hs, innov_a, r_var[:3]), s), True),
        "angle update (Joseph, 3 rows)": (per_call(lambda k: _loop_update(
            k, x.copy(), P.copy(), hca, nna, ha, innov_n, r_var[3:]), s), True),
    }
    print(f"one filter step, n = {n}, one thread, CPU time of the thread, load average {os.getloadavg()[0]:.2f}")
    print("| part | ns per step | % of the whole step |")
    print("|---|---:|---:|")
    total = 0.0
    for name, (ns, restores) in parts.items():
        net = ns - copy if restores else ns
        total += net
        print(f"| {name} | {ns:.0f}" + (f" (net {net:.0f})" if restores else "") + f" | {100 * net / whole:.0f} |")
    print(f"| sum of the parts | {total:.0f} | {100 * total / whole:.0f} |")
    print(f"| whole step (reference kernel _ekf_one, one replicate) | {whole:.0f} | 100 |")
    print(f"| whole step, lanes (run_filter, B = 1: one live lane, {LANES - 1} filler lanes) | {lanes1:.0f} | "
          f"{100 * lanes1 / whole:.0f} |")
    print(f"| whole step, lanes (run_filter, B = {args.batch}), per replicate | {lanes:.0f} | "
          f"{100 * lanes / whole:.0f} |")


if __name__ == "__main__":
    main()
