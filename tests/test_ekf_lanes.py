"""The state-major EKF kernel (issue 22 item 1, :mod:`platcal.rigs.centrifuge.ekf_lanes`) against
the default kernel (``run_ekf(...)``; the lanes are ``run_ekf(..., lanes=True)``): the same numbers bit for bit, and a
replicate's numbers independent of its lane, the batch size and the thread count."""

import numpy as np
import pytest
from numba import njit

from platcal.estimation.lanes import NoAliasCompiler, slp_vectorize
from platcal.model.instruments import N_IDENTIFIED
from platcal.parallel import threads
from platcal.rigs.centrifuge import ekf_lanes
from platcal.rigs.centrifuge.attitude import N_GYRO, P_G, P_OMEGA_N, P_OMEGA_U, make_sc_rk4_scratch, rk4_jac_sc
from platcal.rigs.centrifuge.base import P_RADIUS, Centrifuge
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import LANES_FROM_BATCH, EstimatorInput, FilterSettings, run_ekf, run_iekf, takes_lanes
from platcal.rigs.centrifuge.ekf_lanes import LANES, packed_index, rk4_jac_lanes
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.scheme import TABLE1_POSITIONS, check_scheme

CEN = Centrifuge()
B = LANES + 1  # a full block and a block of one live lane and LANES - 1 fillers


@pytest.fixture(scope="module")
def case():
    scheme = check_scheme("t", {"dwell_s": 2.0, "positions": [list(p) for p in TABLE1_POSITIONS]})
    params = CEN.scheme_params(scheme)
    seeds = [np.random.SeedSequence([22, i]) for i in range(B)]
    sim = simulate(full_truth(), scheme, params, Noise(), seeds, keep_every=4)
    z = [sim.A[:, k, 1:] for k in range(scheme.n_positions)]
    t = [sim.t[1:]] * scheme.n_positions
    return scheme, params, z, t


def test_packed_index_is_the_lower_triangle_by_rows():
    idx = packed_index(4)
    assert np.array_equal(idx, idx.T)
    assert [idx[i, j] for i in range(4) for j in range(i + 1)] == list(range(10))


FIELDS = ("x", "P", "history_t", "history_x", "history_sigma", "pass_x", "pass_P", "mean_nis",
          "failed_updates", "innovations")


@pytest.mark.parametrize("kind", ["ekf", "iekf", "covariance"])
def test_lanes_equal_the_reference_bit_for_bit(case, kind):
    """Every entry is the same operations in the same order as in the reference kernel (no fused
    multiply-adds), so the lanes give its numbers exactly: x, P, the history, the per-pass
    estimates, NIS, failed updates and innovations, with 2 passes (issue 22)."""
    scheme, params, z, t = case
    s = FilterSettings(passes=2, history_every_s=0.5, innovations=kind != "covariance")
    if kind == "ekf":
        run = lambda **kw: run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s, warmup_s=0.5, **kw)  # noqa: E731
    elif kind == "iekf":
        run = lambda **kw: run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), s, iterations=3, until_s=0.5, **kw)  # noqa: E731
    else:
        lin = np.repeat(full_truth()[None], B, axis=0)
        run = lambda **kw: run_ekf(EstimatorInput([None] * len(t), t, scheme.angles_deg, params), s,  # noqa: E731
                                   linearise_about=lin, **kw)
    ref = run()
    new = run(lanes=True)
    for name in FIELDS:
        a, b = getattr(ref, name), getattr(new, name)
        if a is None:
            assert b is None, name
            continue
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name
    assert np.array_equal(new.P, np.swapaxes(new.P, 1, 2))
    if kind == "ekf":
        # not trivially equal: the estimates moved far from the start
        assert np.max(np.abs(new.x[:, :N_IDENTIFIED])) > 1.0


def test_a_batch_takes_the_lanes_by_itself(case, monkeypatch):
    """``FilterSettings.lanes`` None (the default): a batch of ``LANES_FROM_BATCH`` replicates or
    more runs on the state-major kernel, a smaller one on the default kernel; True or False
    decides whatever the batch (issue 22: the same numbers, a cost)."""
    assert LANES_FROM_BATCH == 2 * LANES
    assert [takes_lanes(None, b) for b in (1, LANES_FROM_BATCH - 1, LANES_FROM_BATCH, 64)] == [False, False, True, True]
    assert takes_lanes(True, 1) and not takes_lanes(False, 64)
    calls = []
    kernel = ekf_lanes.run_pass_lanes

    def counted(x, *args):
        calls.append(x.shape[0])
        return kernel(x, *args)

    monkeypatch.setattr(ekf_lanes, "run_pass_lanes", counted)
    scheme, params, z, t = case
    s = FilterSettings(history_every_s=None)
    assert s.lanes is None
    big = [np.concatenate([zk, zk[: LANES_FROM_BATCH - B]]) for zk in z]
    run_ekf(EstimatorInput(big, t, scheme.angles_deg, params), s)
    assert calls and set(calls) == {LANES_FROM_BATCH}
    calls.clear()
    run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s)
    assert not calls
    run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s, lanes=True)
    assert calls


def test_lanes_with_a_centrifuge_per_replicate(case):
    """A block whose lanes have centrifuges of their own (the arm radius of one replicate 1 %
    longer) computes the base specific force lane by lane, not once for the block: the numbers are
    still the default kernel's bit for bit, the odd replicate's among them (issue 22)."""
    scheme, params, z, t = case
    per = np.repeat(np.asarray(params, float)[None], B, axis=0)
    per[2, :, P_RADIUS] *= 1.01
    s = FilterSettings(history_every_s=0.5, innovations=True)
    data = EstimatorInput(z, t, scheme.angles_deg, per)
    ref, new = run_ekf(data, s), run_ekf(data, s, lanes=True)
    for name in ("x", "P", "history_x", "mean_nis", "innovations"):
        assert np.array_equal(getattr(ref, name), getattr(new, name), equal_nan=True), name
    shared = run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s, lanes=True)
    assert not np.array_equal(new.x[2], shared.x[2])  # the odd centrifuge reached its replicate
    assert np.array_equal(new.x[3], shared.x[3])


def test_lane_batch_and_threads_change_nothing(case):
    """Replicate b alone (lane 0 of a block of fillers), in a permuted batch (another lane and
    block) and on 1 or 2 threads: bit-identical x, P, history and NIS."""
    scheme, params, z, t = case
    s = FilterSettings(history_every_s=0.5, innovations=True)
    with threads(2):
        full = run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s, lanes=True)
    with threads(1):
        serial = run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s, lanes=True)
        perm = np.roll(np.arange(B), 2)
        permuted = run_ekf(EstimatorInput([zk[perm] for zk in z], t, scheme.angles_deg, params), s, lanes=True)
        for b in (0, B - 1):
            one = run_ekf(EstimatorInput([zk[b:b + 1] for zk in z], t, scheme.angles_deg, params), s, lanes=True)
            for name in ("x", "P", "history_x", "history_sigma", "mean_nis", "innovations"):
                assert np.array_equal(getattr(one, name)[0], getattr(full, name)[b], equal_nan=True), name
    for name in ("x", "P", "history_x", "mean_nis", "innovations"):
        assert np.array_equal(getattr(serial, name), getattr(full, name), equal_nan=True), name
        assert np.array_equal(getattr(permuted, name), getattr(full, name)[perm], equal_nan=True), name


@njit(pipeline_class=NoAliasCompiler, error_model="numpy")
def _rk4_lanes_once(ang, coef, fr3, h, g, wn, wu, out, pa, pg, k, ka, kg, v, sc0, sc, fr, w):
    rk4_jac_lanes(ang, coef, fr3, h, g, wn, wu, out, pa, pg, k, ka, kg, v, sc0, sc, fr, w)


@pytest.mark.parametrize("h", [0.02, 2000.0])  # the Taylor shift of the angles, and sin/cos for a large step
def test_rk4_map_in_lanes_equals_the_scalar_map_lane_by_lane(h):
    """The lanes' RK4 map and Jacobian (compiled as the block kernel is) are :func:`rk4_jac_sc`'s
    numbers bit for bit in every lane, each lane with its own angles, coefficients and forces."""
    rng = np.random.default_rng(47)
    L, G = LANES, N_GYRO
    coef = np.array([full_truth() * (1.0 + 0.1 * rng.standard_normal(full_truth().size)) for _ in range(L)])
    ang = rng.uniform(-1.2, 1.2, (L, 3))
    fr3 = rng.normal(0.0, 40.0, (L, 3, 3))
    params = np.array([CEN.params()] * L)
    params[:, P_G] *= 1.0 + 0.01 * rng.standard_normal(L)
    want = [np.empty((L, 3)), np.empty((L, 3, 3)), np.empty((L, 3, G))]
    for lane in range(L):
        rk4_jac_sc(ang[lane], coef[lane], fr3[lane], h, params[lane], want[0][lane], want[1][lane], want[2][lane],
                   make_sc_rk4_scratch())
    got = [np.full(3 * L, np.nan), np.full(9 * L, np.nan), np.full(3 * G * L, np.nan)]
    with slp_vectorize(loop_vectorize=False):  # as the block kernel is compiled
        _rk4_lanes_once(ang.T.ravel().copy(), coef.T.ravel().copy(), fr3.transpose(1, 2, 0).ravel().copy(), h,
                        params[:, P_G].copy(), params[:, P_OMEGA_N].copy(), params[:, P_OMEGA_U].copy(), *got,
                        *(np.empty(m * L) for m in (12, 36, 3 * G, 42, 6, 6, 3, 40)))
    assert np.array_equal(got[0].reshape(3, L).T, want[0])
    assert np.array_equal(got[1].reshape(9, L).T.reshape(L, 3, 3), want[1])
    assert np.array_equal(got[2].reshape(3 * G, L).T.reshape(L, 3, G), want[2])
