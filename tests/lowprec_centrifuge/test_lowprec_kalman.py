"""The proposed filter's measurement update is the shared one (platcal.estimation.kalman): the
same estimates and covariances as the rig's former dense batched Joseph update, to ~1e-12."""

import numpy as np

from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.proposed import (NX, P0_STD, R_DIAG, f_base, f_matrix, filter_windows, predict,
                                                      q_density, run_filter,
                                                      window_data)
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed

TINY = {"rig": "lowprec_centrifuge", "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20}}


def dense_filter(T, z, m, valid, lat_rad):
    """The rig's filter before issue 19: batched numpy predict and dense Joseph update (the oracle)."""
    nb, nw = T.shape
    q = q_density()
    eye = np.eye(NX)
    x = np.zeros((nb, NX))
    P = np.broadcast_to(np.diag(P0_STD**2), (nb, NX, NX)).copy()
    R = np.diag(R_DIAG)
    Fw = f_matrix(lat_rad, m)
    for w in range(nw):
        ok = valid[:, w]
        Tw = np.where(ok, T[:, w], 0.0)
        _, H, xp, Pp = predict(Fw[:, w], Tw, x, P, q)   # the prediction is shared; the update is under test
        PHt = Pp @ np.swapaxes(H, 1, 2)
        S = H @ PHt + R
        K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, 1, 2)), 1, 2)
        innov = z[:, w] - np.einsum("bij,bj->bi", H, xp)
        xn = xp + np.einsum("bij,bj->bi", K, innov)
        ikh = eye - K @ H
        Pn = ikh @ Pp @ np.swapaxes(ikh, 1, 2) + K @ R @ np.swapaxes(K, 1, 2)
        Pn = 0.5 * (Pn + np.swapaxes(Pn, 1, 2))
        x = np.where(ok[:, None], xn, x)
        P = np.where(ok[:, None, None], Pn, P)
    return x, P


def test_shared_update_matches_the_dense_joseph_filter():
    st = load_config(TINY)
    rb = simulate_batch(st, "P1", "run1", [replicate_seed(0, "k", 10, r) for r in range(2)])
    per = [window_data(rb.prof.t, rb.v_ind[s], rb.p_ind[s], np.unwrap(rb.psi[s]), rb.f_meas[s], rb.prof.schedule,
                       st.centrifuge.arm_m)[1:] for s in range(2)]
    nw = max(len(p[0]) for p in per) + 3   # padded windows of the second seed change nothing
    T, z, m, valid = np.zeros((2, nw)), np.zeros((2, nw, 4)), np.zeros((2, nw, 4)), np.zeros((2, nw), bool)
    for s, (tt, zz, mm) in enumerate(per):
        k = len(tt) - 3 * s
        T[s, :k], z[s, :k], m[s, :k], valid[s, :k] = tt[:k], zz[:k], mm[:k], True
    lat = np.radians(st.latitude_deg)
    new = run_filter(T, z, m, valid, lat)
    x0, P0 = dense_filter(T, z, m, valid, lat)
    assert np.max(np.abs(new.x - x0) / np.abs(x0).max(axis=1, keepdims=True)) < 1e-12
    rel_p = np.abs(new.P - P0) / np.sqrt(np.einsum("bii,bjj->bij", P0, P0))   # relative to the correlation scale
    assert rel_p.max() < 1e-12
    assert np.allclose(new.coeffs, x0[:, 7:11], rtol=1e-12, atol=1e-9)
    assert new.failed_updates.tolist() == [0, 0]
    assert np.all(np.isfinite(new.mean_nis)) and np.all(new.mean_nis > 0)


def test_compiled_filter_carries_its_state_across_blocks_of_windows():
    """filter_windows updates x, P, NIS in place: windows fed in two blocks give the one call's numbers."""
    st = load_config(TINY)
    rb = simulate_batch(st, "P1", "run1", [replicate_seed(0, "k", 10, r) for r in range(2)])
    per = [window_data(rb.prof.t, rb.v_ind[s], rb.p_ind[s], np.unwrap(rb.psi[s]), rb.f_meas[s], rb.prof.schedule,
                       st.centrifuge.arm_m)[1:] for s in range(2)]
    nw = min(len(p[0]) for p in per)
    T = np.stack([p[0][:nw] for p in per])
    z, m = np.stack([p[1][:nw] for p in per]), np.stack([p[2][:nw] for p in per])
    valid = np.ones((2, nw), bool)
    lat = np.radians(st.latitude_deg)
    whole = run_filter(T, z, m, valid, lat, keep_innovations=True)
    x = np.zeros((2, NX))
    P = np.broadcast_to(np.diag(P0_STD**2), (2, NX, NX)).copy()
    nis, skipped = np.zeros(2), np.zeros(2, np.int64)
    inn = np.full((2, nw, 8), np.nan)
    cut = nw // 3
    for sl in (slice(0, cut), slice(cut, nw)):
        filter_windows(T[:, sl].copy(), z[:, sl].copy(), m[:, sl].copy(), valid[:, sl].copy(), f_base(lat),
                       q_density(), R_DIAG.copy(), x, P, nis, skipped, inn[:, sl])
    assert np.array_equal(x, whole.x) and np.array_equal(P, whole.P)
    assert np.array_equal(nis / nw, whole.mean_nis) and np.array_equal(inn, whole.innovations)
