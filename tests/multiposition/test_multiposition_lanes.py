"""The multi-position EKF with replicates in SIMD lanes (issue 22 item 2,
:func:`platcal.rigs.multiposition.filter._ekf_block`) against the one-replicate reference kernel
(``_ekf_one`` through ``_ekf_range``): the same operations in the same order, so x, P, the NIS,
the linearisation count and the innovations record are bit-identical, whatever the replicate's
lane, the batch size or the thread count (docs/multiposition-1g.md §9)."""

import numpy as np
import pytest

from platcal.estimation.lanes import LANES
from platcal.rigs.multiposition import filter as fl

B = LANES + 1  # a full block, then a block of one live lane and LANES - 1 fillers


def _reference(cfg, angles_deg, t, Z, passes, ext, iters=0, tol=0.0):
    """run_filter as it ran before the lanes: every pass through the scalar kernel."""
    R, K, ns, _ = Z.shape
    tk = np.broadcast_to(t, (K, ns)).copy()
    nk = np.full(K, ns, dtype=np.int64)
    st = fl.FilterStart.of(cfg, R, ext)
    phi0s = np.asarray(angles_deg, float) * fl.DEG
    nis, nlin, nbad = np.empty(R), np.zeros(R), np.zeros(R, dtype=np.int64)
    rec = np.zeros((R, K, ns, 12))
    for p in range(passes):
        if p > 0:
            st.next_pass()
        fl._ekf_range(0, R, st.X, st.Ps, phi0s, tk, Z, nk, st.lay, st.wn, st.wu, st.r_var, cfg.arw_rad**2,
                      cfg.sigma_set_rad**2, st.cols, True, iters, tol, nis, nlin, nbad, rec)
    return st.X[:, 3:], st.Ps[:, 3:, 3:], nis, nlin / (passes * nk.sum()), nbad, rec


@pytest.fixture(scope="module")
def case(cfg):
    s = cfg.scheme("S8")
    t, _, Z = fl.simulate(cfg, s, list(range(B)))
    return s, t[:121], np.ascontiguousarray(Z[:, :, :121])


@pytest.mark.parametrize("ext, iters", [(0, 0), (1, 0), (0, 3)])
def test_lanes_bit_identical_to_the_reference_kernel(cfg, case, ext, iters):
    """The EKF (27 and 51 states) and the iterated EKF (3 linearisations, step tolerance 0.01)."""
    s, t, Z = case
    if ext:  # the 51-state layout (§13) on a noise-free record of its own truth
        t, _, Z = fl.simulate(cfg, s, list(range(B)), noise_free=True, ext=ext)
        t, Z = t[:61], np.ascontiguousarray(Z[:, :, :61])
    ref = _reference(cfg, s.angles_deg, t, Z, 2, ext, iters, 0.01)
    rec = np.zeros(Z.shape[:3] + (12,))
    new = fl.run_filter(cfg, s.angles_deg, t, Z, passes=2, ext=ext, threads=1, innovations=rec, iterations=iters,
                        tolerance=0.01)
    for a, b in zip(new, ref[:5]):
        assert np.array_equal(a, b)
    assert np.array_equal(rec, ref[5])
    # not trivially equal: the estimates moved from the prior, every update was made
    assert np.max(np.abs(new[0])) > 1.0 and not np.any(new[4]) and np.all(np.isfinite(rec))
    if iters:  # the relinearisation ran: more than one linearisation per update on average
        assert np.all(new[3] > 1.0)


def test_one_replicate_on_the_lanes_kernel(cfg, case):
    """``lanes=True`` runs one replicate in the batch kernel (the claims' noise-free check, which
    then compiles no second EKF): the reference kernel's numbers bit for bit."""
    s, t, Z = case
    one = fl.run_filter(cfg, s.angles_deg, t, Z[:1], passes=2, threads=1)
    lanes = fl.run_filter(cfg, s.angles_deg, t, Z[:1], passes=2, threads=1, lanes=True)
    for a, b in zip(lanes, one):
        assert np.array_equal(a, b)
    assert np.max(np.abs(one[0])) > 1.0


def test_covariance_only_lanes_bit_identical(cfg):
    """The covariance-only runs (§8, §14): one run through the positions, and one run per
    position from P0 (each position a batch entry with its own angles), against the scalar
    kernel on the same inputs."""
    s = cfg.scheme("S8")
    step, dwell = cfg.cov_step_s, 3.0
    ns = int(round(dwell / step)) + 1
    phi0s = np.asarray(s.angles_deg, float) * fl.DEG
    K = phi0s.shape[0]
    p0 = cfg.p0(0)
    r_var = np.array([cfg.sigma_a_ug**2 * cfg.ts / step] * 3 + [cfg.sigma_an_arcsec**2 * cfg.ts / step] * 3)
    x0 = np.concatenate([np.zeros(3), cfg.truth(0)])
    P0 = np.zeros((x0.size, x0.size))
    P0[3:, 3:] = np.diag(p0**2)
    wn, wu = cfg.site.params()
    tk = np.tile(np.arange(ns) * step, (K, 1))
    nk = np.full(K, ns, dtype=np.int64)
    args = (fl.layout_index(0), wn, wu, r_var, cfg.arw_rad**2, cfg.sigma_set_rad**2, fl.dynamic_cols(0), False, 0, 0.0)
    out = (np.empty(1), np.zeros(1), np.zeros(1, dtype=np.int64), np.zeros((1, 0, 0, 12)))
    X, P = x0[None].copy(), P0[None].copy()
    fl._ekf_range(0, 1, X, P, phi0s, tk, np.zeros((1, K, ns, 6)), nk, *args, *out)
    assert np.array_equal(fl.covariance_only(cfg, s.angles_deg, dwell), P[0, 3:, 3:])
    per = fl.covariance_only(cfg, s.angles_deg, dwell, sequential=False, threads=2)
    for k in range(K):
        X, P = x0[None].copy(), P0[None].copy()
        fl._ekf_range(0, 1, X, P, phi0s[k:k + 1], tk[:1], np.zeros((1, 1, ns, 6)), nk[:1], *args, *out)
        assert np.array_equal(per[k], P[0, 3:, 3:])
    assert not np.allclose(per[0], per[1])  # the positions' angles reached their own runs


def test_lane_batch_and_threads_change_nothing(cfg, case):
    """Replicate b alone (one replicate: the reference kernel), in a permuted batch (another lane
    and block) and on 2 threads: bit-identical numbers; and the streamed record's run, fed one
    position at a time in uneven blocks (run_filter_positions: a later block goes on from the
    previous one's last instant), is the whole record's run, innovations too."""
    s, t, Z = case
    whole = fl.run_filter(cfg, s.angles_deg, t, Z, passes=2, threads=1)
    perm = np.array([4, 2, 0, 3, 1])
    moved = fl.run_filter(cfg, s.angles_deg, t, Z[perm], passes=2, threads=2)
    for a, b in zip(moved, whole):
        assert np.array_equal(a, b[perm])
    cuts = [0, 50, 51, 51, 120, t.size]  # an empty block and a block of one instant among them
    for b in (0, 3):
        rec = np.zeros((1,) + Z.shape[1:3] + (12,))
        alone = fl.run_filter(cfg, s.angles_deg, t, Z[b:b + 1], passes=2, threads=1, innovations=rec)
        for a, w in zip(alone, whole):
            assert np.array_equal(a[0], w[b])
        seen = {}

        def source():
            return ([(t[i:j], Z[b, k, i:j]) for i, j in zip(cuts[:-1], cuts[1:])] for k in range(s.n_positions))

        streamed = fl.run_filter_positions(cfg, s.angles_deg, source, passes=2,
                                           on_innovations=lambda k, r: seen.setdefault(k, []).append(r.copy()))
        assert np.array_equal(streamed[0][0], whole[0][b]) and np.array_equal(streamed[1][0], whole[1][b])
        assert np.isclose(streamed[2][0], whole[2][b], rtol=1e-12, atol=0) and streamed[4][0] == whole[4][b]
        assert sorted(seen) == list(range(s.n_positions))
        for k, parts in seen.items():
            assert np.array_equal(np.concatenate(parts), rec[0, k])
