"""The proposed method's batch over the job's threads (issue 22 item 2): the window means and the
window filter of a batch of replicates run in contiguous replicate ranges, one per numba thread
(platcal.parallel.run_threaded); every replicate's numbers are those of one thread and of the
replicate alone, bit for bit; the windows' plan made once per batch gives each replicate's windows;
the window means' compiled pass over the samples keeps the values
of the whole arrays it no longer writes (docs/lowprec-centrifuge.md §7)."""

import numpy as np
import pytest

from platcal.parallel import threads
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.proposed import (_boundary_samples, arm_offset, boundary_index, boundary_integrals,
                                                      boundary_value, cumtrap, find_windows, force_integrand,
                                                      identify_proposed, unwrap_heading, window_plan)
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed

TINY = {"rig": "lowprec_centrifuge", "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20}}
FIELDS = ("x", "P", "n_windows", "mean_nis", "failed_updates", "innovations")


@pytest.fixture(scope="module")
def batch():
    st = load_config(TINY)
    return st, simulate_batch(st, "P1", "run1", [replicate_seed(0, "lp-threads", 10, r) for r in range(5)])


def ident(st, rb, sl, n_threads, common_force=False):
    f = rb.f_meas[0] if common_force else rb.f_meas[sl]
    with threads(n_threads):
        return identify_proposed(rb.prof.t, rb.v_ind[sl], rb.p_ind[sl], rb.psi[sl], f, rb.prof.schedule,
                                 st.centrifuge.arm_m, st.latitude_deg, keep_innovations=True)


def same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("common_force", [False, True])
def test_two_threads_give_one_threads_numbers(batch, common_force):
    st, rb = batch
    one, two = (ident(st, rb, slice(None), n, common_force) for n in (1, 2))
    assert one.x.shape[0] == 5
    for name in FIELDS:
        assert same(getattr(one, name), getattr(two, name)), name


@pytest.mark.parametrize("n_threads", [1, 2])
def test_each_replicate_alone_gives_its_batch_numbers(batch, n_threads):
    """Replicates 0, 3 and 4 of the batch (the first and the second thread's ranges at 2 threads)
    identified alone (a batch of one: no thread asked) and in a batch of two."""
    st, rb = batch
    whole = ident(st, rb, slice(None), n_threads)
    for sl in (slice(0, 1), slice(3, 5), slice(4, 5)):
        part = ident(st, rb, sl, n_threads)
        nw = part.innovations.shape[1]
        for name in FIELDS:
            want = getattr(whole, name)[sl]
            if name == "innovations":
                assert np.isnan(want[:, nw:]).all()   # the batch's padding windows
                want = want[:, :nw]
            assert same(getattr(part, name), np.ascontiguousarray(want)), (sl, name)


@pytest.mark.parametrize("with_force", [True, False])
def test_boundary_samples_are_the_whole_arrays_values(with_force):
    """The compiled pass that keeps only the samples around the windows' ends (the window means'
    kernel) gives the rows of the whole (N, 4) arrays of y, yf and their cumulative trapezoids at
    any non-decreasing indices, repeated ones and the first and last allowed (0, N - 2) included,
    bit for bit (signed zeros too)."""
    rng = np.random.default_rng(np.random.SeedSequence(2203))
    n = 500
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    v = rng.standard_normal((n, 2))
    v[:2, 0] = -0.0
    p = rng.standard_normal((n, 2)) * 100.0
    psi = np.cumsum(rng.uniform(0.0, 0.3, n))
    f = rng.standard_normal((n, 2)) * 30.0
    u0 = np.array([np.cos(psi[0]), np.sin(psi[0])])
    y = np.concatenate([v, arm_offset(p, psi, u0, 0.7)], axis=1)
    yf = force_integrand(f)
    c, cf = cumtrap(t, y), cumtrap(t, yf)
    kb = np.sort(np.concatenate([[0, 0, 1, n - 2, n - 2], rng.integers(0, n - 1, 40)]))
    out = [np.full((kb.size, 4), np.nan) for _ in range(6)]
    _boundary_samples(t, v, p, np.cos(psi), np.sin(psi), u0, 0.7, f if with_force else np.empty((0, 2)), kb, *out)
    want = [y[kb], y[kb + 1], c[kb], yf[kb], yf[kb + 1], cf[kb]]
    for got, w in zip(out[:6 if with_force else 3], want):
        assert same(got, w)
        assert np.array_equal(np.signbit(got), np.signbit(w))
    if not with_force:
        assert all(np.isnan(o).all() for o in out[3:])      # untouched without force rows
    tb = np.concatenate([t[kb] + 0.3 * (t[kb + 1] - t[kb]), [t[0], t[-1]]])
    k = boundary_index(t, tb)
    assert same(boundary_value(tb, t[k], t[k + 1], y[k], y[k + 1], c[k]), boundary_integrals(t, y, c, tb))


def test_one_window_plan_gives_every_replicates_windows(batch):
    """The batch's window plan (spins, tolerances, static edges: from t and the schedule alone),
    made once and shared, gives each replicate the windows it finds alone; the plan's arrays are
    not written."""
    st, rb = batch
    t, schedule = rb.prof.t, rb.prof.schedule
    plan = window_plan(t, schedule)
    before = [e.copy() for e in plan.static_edges]
    for psi_u in unwrap_heading(rb.psi):
        got, want = find_windows(t, psi_u, schedule, plan), find_windows(t, psi_u, schedule)
        for name in ("ts", "te", "spinning"):
            assert same(getattr(got, name), getattr(want, name)), name
    assert len(plan.spins) == 2 and all(same(a, b) for a, b in zip(plan.static_edges, before))
