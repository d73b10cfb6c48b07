"""The iterated EKF (issue 9 item 3): the batched sparse kernel equals a dense Gauss-Newton
IEKF written from its definition; one linearisation is the EKF; batch and threads change nothing."""

import numpy as np
import pytest

from platcal.rigs.centrifuge import attitude as platform
from platcal.parallel import threads
from platcal.rigs.centrifuge.base import Centrifuge, specific_force
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf, run_iekf
from platcal.scheme import check_scheme
from platcal.rigs.centrifuge.simulate import Noise, simulate

CEN = Centrifuge()
POSITIONS = [(45, 0, 167), (350, 30, 325)]


def _data(B=2, dwell=0.4):
    scheme = check_scheme("t", {"dwell_s": dwell, "positions": [list(p) for p in POSITIONS]})
    seeds = [np.random.SeedSequence([5, i]) for i in range(B)]
    sim = simulate(full_truth(), scheme, CEN.scheme_params(scheme), Noise(), seeds, keep_every=4)
    z = [sim.A[:, k, 1:] for k in range(2)]
    return scheme, z, [sim.t[1:]] * 2


def _dense_iekf(z, t, cmd_rad, params, s: FilterSettings, iterations, tol, until_s=np.inf):
    """Dense Gauss-Newton IEKF from its definition: x_{i+1} = x_p + K_i (z - h(x_i) - H_i (x_p - x_i)),
    Joseph form with the last K_i, H_i; propagation from the reset at t = 0 as the EKF."""
    nc = s.coef_index.size
    n = nc + 3
    x = np.zeros(n)
    P = np.diag(np.r_[np.asarray(s.p0_sigma) ** 2, np.zeros(3)])
    R = np.eye(3) * (s.sigma_a_ug * 1e-6) ** 2
    q = (s.arw_deg_rth * np.pi / 180 / 60.0) ** 2
    coef = np.zeros(48)

    def h_of(xx, tm, pk):
        coef[:nc] = xx[:nc]
        A, hc, ha = platform.measure(xx[nc:], coef, specific_force(tm, pk), pk)
        return A, np.hstack([hc[:, :nc], ha])

    for k in range(len(t)):
        x[nc:] = cmd_rad[k]
        P[nc:, :] = 0.0
        P[:, nc:] = 0.0
        P[nc:, nc:] = np.eye(3) * (s.sigma_set_arcsec * np.pi / 180 / 3600) ** 2
        t_prev = 0.0
        for m, tm in enumerate(t[k]):
            h = tm - t_prev
            coef[:nc] = x[:nc]
            fr3 = np.stack([specific_force(t_prev + c * h, params[k]) for c in (0.0, 0.5, 1.0)])
            ang, pa, pc = platform.rk4(x[nc:], coef, fr3, h, params[k])
            F = np.eye(n)
            F[nc:, :nc] = pc[:, :nc]
            F[nc:, nc:] = pa
            x[nc:] = ang
            P = F @ P @ F.T
            P[nc:, nc:] += np.eye(3) * q * h
            t_prev = tm
            xp = x.copy()
            xi = xp.copy()
            A, H = h_of(xi, tm, params[k])
            r = z[k][m] - A
            for _ in range(iterations - 1 if tm < until_s else 0):
                Kg = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
                xn = xp + Kg @ r
                done = np.max(np.abs(xn - xi) / np.sqrt(np.diag(P))) < tol
                xi = xn
                A, H = h_of(xi, tm, params[k])
                r = z[k][m] - A - H @ (xp - xi)
                if done:
                    break
            Kg = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
            x = xp + Kg @ r
            IKH = np.eye(n) - Kg @ H
            P = IKH @ P @ IKH.T + Kg @ R @ Kg.T
    return x, P


@pytest.mark.parametrize("iterations,tol,until_s", [(3, 0.0, None), (4, 1e-3, None), (3, 0.0, 0.1)])
def test_sparse_iekf_equals_dense_definition(iterations, tol, until_s):
    scheme, z, t = _data()
    s = FilterSettings(history_every_s=None)
    est = run_iekf(EstimatorInput(z, t, scheme.angles_deg, CEN.scheme_params(scheme)), s, iterations=iterations, tol=tol,
                   until_s=until_s)
    for b in range(2):
        x, P = _dense_iekf([zk[b] for zk in z], t, scheme.angles_deg * np.pi / 180, CEN.scheme_params(scheme), s,
                           iterations, tol, np.inf if until_s is None else until_s)
        sig = np.sqrt(np.diag(P))
        assert np.max(np.abs(est.x[b] - x) / sig) < 1e-6
        assert np.max(np.abs(est.P[b] - P) / np.outer(sig, sig)) < 1e-7
    assert np.array_equal(est.P, np.swapaxes(est.P, 1, 2))
    assert np.all(np.linalg.eigvalsh(est.P) > 0)


def test_one_linearisation_is_the_ekf_and_iterating_changes_the_numbers():
    scheme, z, t = _data()
    s = FilterSettings(history_every_s=None)
    params = CEN.scheme_params(scheme)
    ekf = run_ekf(EstimatorInput(z, t, scheme.angles_deg, params), s)
    one = run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), s, iterations=1)
    assert np.array_equal(ekf.x, one.x) and np.array_equal(ekf.P, one.P)
    three = run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), s, iterations=3)
    assert not np.allclose(three.x, ekf.x, rtol=1e-9, atol=0)
    # never iterating (the window closes before the first instant) is the EKF again
    none = run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), s, iterations=3, until_s=0.01)
    assert np.array_equal(none.x, ekf.x)


def test_iekf_batch_and_threads_change_nothing():
    scheme, z, t = _data(B=3)
    s = FilterSettings(passes=2, history_every_s=None)
    params = CEN.scheme_params(scheme)
    kw = dict(iterations=3, tol=1e-3, ratio=1e-4)
    with threads(2):
        full = run_iekf(EstimatorInput(z, t, scheme.angles_deg, params), s, **kw)
    with threads(1):
        for b in range(3):
            one = run_iekf(EstimatorInput([zk[b:b + 1] for zk in z], t, scheme.angles_deg, params), s, **kw)
            assert np.array_equal(one.x[0], full.x[b]) and np.array_equal(one.P[0], full.P[b])
