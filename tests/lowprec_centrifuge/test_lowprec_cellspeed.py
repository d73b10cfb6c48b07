"""The low-precision cells' speed-ups change no number (issue 22 item 4): the compiled window
integrands, cumulative trapezoid and heading unwrap give numpy's values bit for bit, and a cell's
runs that share a profile share one true motion with the same results as building it per run."""

import numpy as np
import pytest

from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.proposed import (MIN_STATIC_TAIL_S, STATIC_WINDOW_S, arm_offset,
                                                      boundary_integrals, cumtrap, find_windows, force_integrand,
                                                      force_terms, revolution_crossings, segments_of,
                                                      unwrap_heading, window_data, window_means)
from platcal.rigs.lowprec_centrifuge.truth import TruthCache, simulate_batch
from platcal.study.montecarlo import replicate_seed

SHARED = {"rig": "lowprec_centrifuge",
          "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5},
                        "P2": {"kA_x": 30, "k2_x": 6, "kA_y": -20, "k2_y": 4}},
          "runs": {"P1": {"run1": [4, 6]}, "P2": {"run1": [4, 6], "run2": [4, 8]}},
          "profile": {"rest_first_s": 10, "rest_between_s": 20}}


def numpy_cumtrap(t, y):
    """The rig's cumulative trapezoid as numpy wrote it before the compiled pass (the oracle)."""
    c = np.empty_like(y)
    c[0] = 0.0
    np.cumsum(0.5 * np.diff(t)[:, None] * (y[1:] + y[:-1]), axis=0, out=c[1:])
    return c


@pytest.mark.parametrize("n", [1, 2, 3, 1000])
def test_cumtrap_is_numpys_bit_for_bit(n):
    rng = np.random.default_rng(np.random.SeedSequence(2201))
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    y = rng.standard_normal((n, 3)) * 10.0 ** rng.integers(-8, 8, (n, 3))
    y[:2, 0] = -0.0          # the first term's sign of zero is numpy's too
    got, want = cumtrap(t, y), numpy_cumtrap(t, y)
    assert np.array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))


def test_unwrap_heading_is_numpys_bit_for_bit():
    rng = np.random.default_rng(np.random.SeedSequence(2202))
    t = np.arange(5000) * 0.01
    smooth = 0.5 * t**2 + 1e-5 * rng.standard_normal(t.size)    # steps far below pi: the compiled pass
    smooth[:3] = -0.0
    wrapped = np.mod(smooth, 2 * np.pi)                          # jumps of 2 pi: numpy's
    with_nan = smooth.copy()
    with_nan[100] = np.nan
    psi = np.stack([smooth, wrapped, with_nan, -smooth])
    got = unwrap_heading(psi)
    for row, want in zip(got, (np.unwrap(p) for p in psi)):
        assert np.array_equal(row, want, equal_nan=True)
        assert np.array_equal(np.signbit(row), np.signbit(want))
    assert not np.array_equal(got[1], wrapped)    # the wrapped record was unwrapped


def numpy_window_data(t, v, p_rel, psi_u, f, schedule, arm_m):
    """:func:`window_data` as numpy computed it before the compiled pass (the oracle)."""
    win = find_windows(t, psi_u, schedule)
    y = np.concatenate([v, arm_offset(p_rel, psi_u, np.array([np.cos(psi_u[0]), np.sin(psi_u[0])]), arm_m)], axis=1)
    c = numpy_cumtrap(t, y)
    yf = force_integrand(f)
    cf = numpy_cumtrap(t, yf)
    return window_means(win.ts, win.te, boundary_integrals(t, y, c, win.ts), boundary_integrals(t, y, c, win.te),
                        boundary_integrals(t, yf, cf, win.ts), boundary_integrals(t, yf, cf, win.te),
                        np.interp(win.ts, t, psi_u), np.interp(win.te, t, psi_u), arm_m)


@pytest.mark.parametrize("given_force", [False, True])
def test_window_data_is_numpys_bit_for_bit(given_force):
    st = load_config(SHARED)
    rb = simulate_batch(st, "P1", "run1", [replicate_seed(0, "cellspeed", 10, 0)])
    t, v, p, f, psi_u = rb.prof.t, rb.v_ind[0], rb.p_ind[0], rb.f_meas[0], np.unwrap(rb.psi[0])
    arm = st.centrifuge.arm_m
    force = force_terms(t, f) if given_force else None
    _, *got = window_data(t, v, p, psi_u, f, rb.prof.schedule, arm, force)
    want = numpy_window_data(t, v, p, psi_u, f, rb.prof.schedule, arm)
    assert len(got[0]) > 10
    for a, b in zip(got, want):
        assert np.array_equal(a, b)


def test_shared_truth_gives_the_numbers_of_one_built_per_run():
    st = load_config(SHARED)
    seeds = [replicate_seed(0, "cellspeed", 10, r) for r in range(3)]
    runs = [("P1", "run1"), ("P2", "run1"), ("P2", "run2")]
    cache = TruthCache(st, runs)
    shared = [simulate_batch(st, p, r, seeds, floor=True, truths=cache) for p, r in runs]
    assert cache.built == {}                   # each profile dropped after its last run
    assert shared[0].kin.theta is shared[1].kin.theta    # P1 and P2 run1 have one profile: built once
    for (p, r), a in zip(runs, shared):
        b = simulate_batch(st, p, r, seeds, floor=True)
        for f in ("err", "v_ind", "p_ind", "f_meas", "psi", "sens", "final_floor"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), (p, r, f)


def test_block_buffers_reused_across_blocks_change_no_replicate():
    """9 replicates with their floors and the 4 variants are 22 lanes: two blocks of lanes, the
    second with fewer replicates than the first, through the same reused buffers."""
    st = load_config(SHARED)
    seeds = [replicate_seed(0, "cellspeed", 10, r) for r in range(9)]
    many = simulate_batch(st, "P2", "run2", seeds, floor=True)
    for r in (0, 7, 8):
        one = simulate_batch(st, "P2", "run2", [seeds[r]], floor=True)
        for f in ("err", "v_ind", "p_ind", "f_meas", "psi", "final_floor"):
            assert np.array_equal(getattr(many, f)[r], getattr(one, f)[0]), (r, f)
        assert np.array_equal(many.sens, one.sens)


def loop_find_windows(t, psi_u, schedule):
    """:func:`find_windows` as a Python loop per window, as it was before (the oracle)."""
    def static(a, b):
        if b - a <= 1e-9:
            return []
        edges = list(np.arange(a, b - 1e-9, STATIC_WINDOW_S)) + [b]
        if len(edges) > 2 and edges[-1] - edges[-2] < MIN_STATIC_TAIL_S:
            del edges[-2]
        return [(a, b, False) for a, b in zip(edges[:-1], edges[1:])]
    out, last = [], 0
    for ia, ib in segments_of(schedule):
        out += static(t[last], t[ia])
        edges = [t[ia], *revolution_crossings(t, psi_u, ia, ib).tolist()]
        if t[ib] - edges[-1] < 0.5 * float(np.median(np.diff(t[ia:ib + 1]))):
            edges[-1] = t[ib]
        else:
            edges.append(t[ib])
        out += [(a, b, True) for a, b in zip(edges[:-1], edges[1:])]
        last = ib
    out += static(t[last], t[-1])
    return [np.array(c) for c in zip(*out)]


@pytest.mark.parametrize("run, rest", [("run1", 20), ("run2", 20.05), ("run1", 3.5)])
def test_find_windows_is_the_per_window_loops(run, rest):
    """The windows from one array per stretch equal the per-window loop's, values and dtypes, with a
    tail under MIN_STATIC_TAIL_S merged (rests of 20.05 s) or kept (3.5 s)."""
    cfg = dict(SHARED, profile={"rest_first_s": 10, "rest_between_s": rest})
    rb = simulate_batch(load_config(cfg), "P2", run, [replicate_seed(0, "cellspeed", 10, 1)])
    t, psi_u = rb.prof.t, np.unwrap(rb.psi[0])
    got = find_windows(t, psi_u, rb.prof.schedule)
    want = loop_find_windows(t, psi_u, rb.prof.schedule)
    assert got.spinning.any() and not got.spinning.all()
    for a, b in zip((got.ts, got.te, got.spinning), want):
        assert a.dtype == b.dtype and np.array_equal(a, b)
