"""The sled's linear filters run on the shared Kalman update (platcal.estimation.kalman, Joseph
form): the same numbers as §6's textbook filter (docs/rocket-sled.md §6), the form the sled's own
kernel used before, to rounding."""

import numpy as np
import pytest

from platcal.rigs.sled.config import G, load_config
from platcal.rigs.sled.errmodel import run_F
from platcal.rigs.sled.filters import kalman, run_tuning

J = 300


def textbook(Phis, z, x0, P0, Qd, R):
    """Predict ``P = Φ P Φᵀ + Q``, update ``K = P Hᵀ S⁻¹``, ``P = P − K H P``, symmetrised (§6)."""
    S, steps, n = Phis.shape[0], Phis.shape[1], Phis.shape[-1]
    m = z.shape[-1]
    H = np.eye(m, n)
    xs, sig = np.empty((S, steps + 1, n)), np.empty((S, steps + 1, n))
    Ps = np.empty((S, n, n))
    for s in range(S):
        x, P = x0[s].copy(), P0[s].copy()
        xs[s, 0], sig[s, 0] = x, np.sqrt(np.diag(P))
        for j in range(steps):
            Phi = Phis[s, j]
            x = Phi @ x
            P = Phi @ P @ Phi.T + Qd[j]
            K = np.linalg.solve(H @ P @ H.T + R, H @ P).T
            x = x + K @ (z[s, j] - H @ x)
            P = P - K @ H @ P
            P = 0.5 * (P + P.T)
            xs[s, j + 1], sig[s, j + 1] = x, np.sqrt(np.maximum(np.diag(P), 0.0))
        Ps[s] = P
    return xs, sig, Ps


def profile(S: int) -> np.ndarray:
    """Mean specific force per filter step (S,J,3): rest, 5 g boost, coast, 4 g brake, rest."""
    ax = np.r_[np.zeros(50), np.full(60, 5.0), np.full(80, -0.3), np.full(60, -4.0), np.zeros(J - 250)] * G
    f = np.stack([ax, np.zeros(J), np.full(J, G)], axis=-1)
    return np.broadcast_to(f, (S, J, 3)).copy()


@pytest.mark.parametrize("states", [6, 7])
@pytest.mark.parametrize("tuning", ["default", "paper"])
def test_shared_update_equals_the_textbook_filter(states, tuning):
    cfg = load_config({"rig": "sled", "filter": {"states": states, "tuning": tuning}})
    rng = np.random.default_rng(1)
    S = 3
    Fs = run_F(profile(S), cfg.omega_ie, states=states)
    z = np.cumsum(rng.standard_normal((S, J, 4)) * 0.01, axis=1)     # drifting Y/Z navigation errors, m
    x0 = rng.standard_normal((S, states)) * 1e-3
    tun = run_tuning(cfg, states)
    T = cfg.period_ms / 1000.0
    out = kalman(Fs, z, x0, tun, T, T)
    Phis = np.eye(states) + Fs * T + (Fs * T) @ (Fs * T) / 2
    P0 = np.broadcast_to(tun.P0, (S, states, states))
    ref = textbook(Phis, z, x0, P0, np.broadcast_to(tun.Qd, (J, states, states)), tun.R)
    for got, want in zip((out.x, out.sigma, out.P), ref):
        scale = np.abs(want).max(axis=tuple(range(1, want.ndim)), keepdims=True)
        assert np.max(np.abs(got - want) / scale) < 1e-12
    assert not np.array_equal(out.x[:, -1], x0)        # the filter moved


def test_failed_update_is_skipped_and_counted():
    cfg = load_config({"rig": "sled"})
    tun = run_tuning(cfg, 6)
    bad = type(tun)(P0=tun.P0, Qd=tun.Qd, R=-1e3 * np.eye(4))   # S = P + R not positive definite
    S = 2
    Fs = run_F(profile(S)[:, :5], cfg.omega_ie, states=6)
    out = kalman(Fs, np.zeros((S, 5, 4)), np.zeros((S, 6)), bad, 0.02, 0.02)
    assert list(out.failed_updates) == [5, 5] and np.all(np.isnan(out.mean_nis))
    assert np.all(np.isfinite(out.x))
