"""The state-major EKF kernel (issue 22 item 1, :mod:`platcal.rigs.centrifuge.ekf_lanes`) against
the default kernel (``run_ekf(...)``; the lanes are ``run_ekf(..., lanes=True)``): the same filter to round-off, and a
replicate's numbers independent of its lane, the batch size and the thread count."""

import numpy as np
import pytest
from dataclasses import replace

from platcal.model.instruments import N_IDENTIFIED
from platcal.parallel import threads
from platcal.rigs.centrifuge.base import Centrifuge
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf, run_iekf
from platcal.rigs.centrifuge.ekf_lanes import LANES, packed_index
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


def _sigma_gap(a, b):
    """Largest |x_a - x_b| / sigma_b and |P_a - P_b| / (sigma_i sigma_j) over the batch."""
    sig = np.sqrt(np.diagonal(b.P, axis1=1, axis2=2))
    return (np.max(np.abs(a.x - b.x) / sig),
            np.max(np.abs(a.P - b.P) / (sig[:, :, None] * sig[:, None, :])))


def test_packed_index_is_the_lower_triangle_by_rows():
    idx = packed_index(4)
    assert np.array_equal(idx, idx.T)
    assert [idx[i, j] for i in range(4) for j in range(i + 1)] == list(range(10))


@pytest.mark.parametrize("kind", ["ekf", "iekf", "covariance"])
def test_lanes_agree_with_reference_to_round_off(case, kind):
    """The bound is the filter's own sensitivity to round-off: the reference kernel moved by a
    one-ulp change of P0 (its result is no more exact than that); the lane kernel must stay
    within 5x of that spread and below 1e-7 sigma (measured: 6.6e-9 against 1.0e-8 here)."""
    scheme, params, z, t = case
    s = FilterSettings(passes=2, history_every_s=0.5)
    ulp = replace(s, p0_sigma=np.nextafter(s.p0_sigma, np.inf))
    if kind == "ekf":
        run = lambda st, **kw: run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), st, **kw)  # noqa: E731
    elif kind == "iekf":
        run = lambda st, **kw: run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), st, iterations=3, until_s=0.5, **kw)  # noqa: E731
    else:
        lin = np.repeat(full_truth()[None], B, axis=0)
        run = lambda st, **kw: run_ekf(EstimatorInput([None] * len(t), t, scheme.angles_deg, params), st,  # noqa: E731
                                       linearise_about=lin, **kw)
    ref = run(s)
    new = run(s, lanes=True)
    floor_x, floor_p = _sigma_gap(run(ulp), ref)
    gap_x, gap_p = _sigma_gap(new, ref)
    assert gap_p <= 5 * max(floor_p, 1e-13) and gap_p < 1e-7
    assert gap_x <= 5 * max(floor_x, 1e-13) and gap_x < 1e-7
    assert np.array_equal(new.P, np.swapaxes(new.P, 1, 2))
    assert np.array_equal(new.failed_updates, ref.failed_updates)
    np.testing.assert_allclose(new.mean_nis, ref.mean_nis, rtol=1e-6)
    np.testing.assert_allclose(new.history_sigma, ref.history_sigma, rtol=1e-6)
    if kind == "ekf":
        # not trivially equal: the estimates moved far from the start
        assert np.max(np.abs(new.x[:, :N_IDENTIFIED])) > 1.0


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
