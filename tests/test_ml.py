"""Batch maximum likelihood of the centrifuge (rigs/centrifuge/ml.py) and the generic
Gauss-Newton driver (estimation/gauss_newton.py)."""

from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
import pytest
from scipy.optimize import least_squares

from platcal.errors import InputError
from platcal.estimation.gauss_newton import solve_map
from platcal.model.frames import ARCSEC, DEG
from platcal.parallel import threads
from platcal.rigs.centrifuge import ml
from platcal.rigs.centrifuge import observability as ob
from platcal.rigs.centrifuge.config import load_config
from platcal.rigs.centrifuge.ekf import EstimatorInput, default_p0_sigma
from platcal.scheme import Scheme
from platcal.rigs.centrifuge.simulate import simulate

CONFIG = Path(__file__).resolve().parents[1] / "config" / "centrifuge.yaml"
SHORT = ((45, 0, 167), (350, 0, 325), (209, 0, 182))


@pytest.fixture(scope="module")
def study():
    return load_config(CONFIG)


def _record(study, positions, dwell, seeds, sample_s=None, keep_every=None):
    """Simulated outputs at t = period, 2 period, ... (no sample at the reset instant)."""
    sch = Scheme("s", tuple(positions), float(dwell))
    params = study.centrifuge.scheme_params(sch)
    sim = simulate(study.truth, sch, params, study.noise, seeds, sample_s=sample_s or study.sample_s,
                   keep_every=keep_every or study.keep_every)
    K = sch.n_positions
    return sch, params, [np.ascontiguousarray(sim.A[:, k, 1:]) for k in range(K)], [sim.t[1:]] * K, sim


def test_gauss_newton_driver_matches_scipy_least_squares():
    """A small nonlinear fit with a weak prior: GN and LM land on scipy's least-squares optimum."""
    x = np.linspace(0.0, 2.0, 25)
    rng = np.random.default_rng(3)
    y = 2.0 * np.exp(-1.3 * x) + 0.01 * rng.standard_normal(x.size)
    sig_y, prior_sigma = 0.01, np.array([1e3, 1e3])

    def evaluate(theta, rows):
        N, g, c = [], [], []
        for a, b in theta:
            e = np.exp(b * x)
            r = (y - a * e) / sig_y
            J = np.stack([e, a * x * e], axis=1) / sig_y
            N.append(J.T @ J)
            g.append(J.T @ r)
            c.append(r @ r)
        return np.array(N), np.array(g), np.array(c)

    ref = least_squares(lambda p: np.r_[(y - p[0] * np.exp(p[1] * x)) / sig_y, p / prior_sigma],
                        [1.0, -0.5], xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    for damping in (False, True):
        res = solve_map(evaluate, np.array([[1.0, -0.5]]), np.zeros(2), prior_sigma, damping=damping, tol=1e-8)
        assert res.converged[0]
        np.testing.assert_allclose(res.theta[0], ref, rtol=1e-9)
        N, _, _ = evaluate(res.theta, None)
        np.testing.assert_allclose(res.cov[0], np.linalg.inv(N[0] + np.diag(prior_sigma**-2.0)), rtol=1e-9)


def test_residual_jacobian_against_central_differences(study):
    """The kernel's Jacobian of the prediction (the chained RK4 sensitivities and H) agrees with
    central differences of :func:`ml.predict` at a point away from the truth.

    With ARW 0 the kernel's ``g = J' R^-1 (z - h)`` is linear in z, so perturbing one output by d
    gives one row of J exactly: ``J[m, r, :] = r_var (g(z + d e_mr) - g(z)) / d``.
    """
    fs = replace(study.filter, arw_deg_rth=0.0, history_every_s=None)
    K, M = 2, 4
    t = [np.array([0.02, 0.04, 0.06, 0.1]), np.array([0.0, 0.3, 0.32, 0.5])]  # one starts at the reset
    cmd = np.array(SHORT[:K], float)
    params = study.centrifuge.scheme_params(Scheme("s", SHORT[:K], 1.0))
    z0 = [np.zeros((1, M, 3))] * K
    prob0 = ml._Problem(z0, t, cmd, params, fs)
    rng = np.random.default_rng(5)
    theta = prob0.prior_mean[0].copy()
    theta[:45] = study.truth[:45] * (1.0 + 0.3 * rng.standard_normal(45))
    theta[45:] += 200 * ARCSEC * rng.standard_normal(3 * K)
    # one replicate per perturbed output, all in one batch
    d = 1e-3
    n_out = K * M * 3
    zb = [np.zeros((n_out + 1, M, 3)) for _ in range(K)]
    rows = []
    i = 1
    for k in range(K):
        for m in range(M):
            for r in range(3):
                zb[k][i, m, r] = d
                rows.append((k, m, r))
                i += 1
    prob = ml._Problem(zb, t, cmd, params, fs)
    _, g, _ = prob.evaluate(np.tile(theta, (n_out + 1, 1)), np.arange(n_out + 1))
    r_var = (fs.sigma_a_ug * 1e-6) ** 2
    J_kernel = (g[1:] - g[0]) * r_var / d
    # central differences of the prediction, step 3e-2 prior sigma per parameter (the gyro columns'
    # effect over 0.1 s is ~1e-9 g per step: smaller steps drown in the outputs' rounding, 1e-15 g)
    steps = 3e-2 * prob.prior_sigma
    J_fd = np.empty_like(J_kernel)
    for j in range(prob.n):
        tp, tm = theta.copy(), theta.copy()
        tp[j] += steps[j]
        tm[j] -= steps[j]
        hp = ml.predict(tp[None], t, params, fs)
        hm = ml.predict(tm[None], t, params, fs)
        col = np.concatenate([((hp[k] - hm[k])[0] / (2 * steps[j])).reshape(-1) for k in range(K)])
        J_fd[:, j] = col
    scale = np.abs(J_fd).max(axis=0)
    assert np.all(scale > 0)
    np.testing.assert_allclose(J_kernel / scale, J_fd / scale, rtol=0, atol=1e-6)
    # the gyro columns are not trivially zero: the chained RK4 sensitivities matter
    assert np.abs(J_fd[:, :27]).max() > 0


def test_noise_free_record_is_recovered(study):
    """Truth simulated at the filter's own 20 ms RK4 step, no noise: the MAP estimate (prior made
    negligible by a small assumed sigma_a and no assumed ARW, which would otherwise cap the gyro
    information) is the truth to 1e-6 of each coefficient."""
    sch, params, z, t, sim = _record(study, study.schemes["table1"].positions, 6.0, None, sample_s=0.02,
                                     keep_every=1)
    fs = replace(study.filter, sigma_a_ug=1e-3, arw_deg_rth=0.0, history_every_s=None)
    est, info = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, start="zero")
    assert info.converged[0] and info.steps[0] <= 6
    np.testing.assert_allclose(est.coef[0], study.truth[:45], rtol=1e-6)
    np.testing.assert_allclose(est.x[0, 45:], sch.angles_deg[-1] * DEG, atol=1e-9)
    assert est.failed_updates[0] == 0


def test_covariance_is_the_inverse_information_and_pd(study):
    sch, params, z, t, _ = _record(study, SHORT, 2.0, np.random.SeedSequence(11).spawn(1))
    fs = replace(study.filter, history_every_s=None)
    est, info = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, start="zero")
    prob = ml._Problem(z, t, sch.angles_deg, params, fs)
    N, _, _ = prob.evaluate(info.theta, np.array([0]))
    s = prob.prior_sigma
    full = np.linalg.inv(N[0] + np.diag(s**-2.0))
    np.testing.assert_allclose(info.cov[0], full, rtol=1e-7, atol=1e-12 * np.abs(full).max())
    P = est.P[0]
    np.testing.assert_array_equal(P, P.T)
    assert np.linalg.eigvalsh(P / np.sqrt(np.outer(np.diag(P), np.diag(P)))).min() > 0
    # the Estimate's angles are the last position's initial angles with their covariance block
    keep = np.r_[np.arange(45), prob.n - 3 + np.arange(3)]
    np.testing.assert_array_equal(P, info.cov[0][np.ix_(keep, keep)])
    np.testing.assert_array_equal(est.x[0], info.theta[0, keep])
    assert est.pass_x.shape == (1, 1, 45) and est.history_x.shape == (1, 0, 48)
    assert 2.0 < est.mean_nis[0] < 4.0


def test_batch_and_threads_bit_identical(study):
    sch, params, z, t, _ = _record(study, SHORT, 1.0, np.random.SeedSequence(2).spawn(3))
    fs = replace(study.filter, history_every_s=None)
    with threads(min(2, numba.config.NUMBA_NUM_THREADS)):
        whole = ml.run_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, start="zero")
    for b in range(3):
        with threads(1):
            one = ml.run_ml(EstimatorInput([zk[b:b + 1] for zk in z], t, sch.angles_deg, params), fs, start="zero")
        np.testing.assert_array_equal(one.x[0], whole.x[b])
        np.testing.assert_array_equal(one.P[0], whole.P[b])


def test_covariance_agrees_with_observability_crb(study):
    """At the truth, on the observability module's times (t = 0, period, ...), the ML covariance
    is the covariance-only EKF's bound (position decomposition) to rounding: both are the exact
    information of the same linearised model (RK4 Jacobians, R, ARW, sigma_set prior), so 1e-6
    on the sigmas (the decomposition's own test tolerance). At the ML's own estimate from a noisy
    record the linearisation point moves by a few sigma, which changes the sigmas by far less
    than 1 % (measured 4e-4 on Table 1 at 10 ug)."""
    setup = ob.setup_from_study(study, 2.0)
    crb = ob.scheme_covariance(setup, np.array(SHORT))[0]
    K = len(SHORT)
    params = study.centrifuge.scheme_params(Scheme("s", SHORT, 2.0))
    t = [setup.times] * K
    prob = ml._Problem([np.zeros((1, setup.times.size, 3))] * K, t, np.array(SHORT, float), params, setup.filter)
    N, _, _ = prob.evaluate(prob.start(study.truth[None, :45]), np.array([0]))
    s = prob.prior_sigma
    A = N[0] * np.outer(s, s) + np.eye(prob.n)
    cov = (np.linalg.inv(A) * np.outer(s, s))[:45, :45]
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(crb)), rtol=1e-6)
    # from a noisy record, at the estimate
    seeds = np.random.SeedSequence(4).spawn(1)
    sch = Scheme("s", SHORT, 2.0)
    sim = simulate(study.truth, sch, params, study.noise, seeds, sample_s=study.sample_s, keep_every=study.keep_every)
    idx = np.searchsorted(sim.t, setup.times - 1e-9)  # the record's samples at the filter instants
    np.testing.assert_allclose(sim.t[idx], setup.times, atol=1e-9)
    est = ml.run_ml(EstimatorInput([sim.A[:, k][:, idx] for k in range(K)], t, sch.angles_deg, params), setup.filter,
                    start="zero")
    np.testing.assert_allclose(est.coef_sigma[0], np.sqrt(np.diag(crb)), rtol=1e-2)


def test_damped_and_ekf_starts_reach_the_same_estimate(study):
    sch, params, z, t, _ = _record(study, SHORT, 1.0, np.random.SeedSequence(8).spawn(1))
    fs = replace(study.filter, history_every_s=None)
    a, ia = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, start="zero", tol=1e-3)
    b, ib = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, start="ekf", damping=True, tol=1e-3)
    assert ia.converged[0] and ib.converged[0]
    # both stop within 1e-3 posterior sigma of the optimum
    assert np.max(np.abs(a.coef[0] - b.coef[0]) / a.coef_sigma[0]) < 2e-3


def test_coarse_start_and_one_step_agree_with_the_converged_map(study):
    """A preliminary fit on every 4th instant, then (a) converge on the full record: the same MAP;
    (b) one Gauss-Newton step: within 1e-3 sigma of it, same covariance to 1e-3 (measured 5e-5, 2e-5)."""
    sch, params, z, t, _ = _record(study, SHORT, 2.0, np.random.SeedSequence(12).spawn(2))
    fs = replace(study.filter, history_every_s=None)
    ref, iref = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, tol=1e-4)
    c, ic = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, tol=1e-4, coarse=4)
    o, io = ml.solve_ml(EstimatorInput(z, t, sch.angles_deg, params), fs, coarse=4, final="one-step")
    assert np.all(ic.coarse_steps >= 1) and np.all(ic.converged) and np.all(io.evaluations == 1)
    assert np.max(np.abs(c.coef - ref.coef) / ref.coef_sigma) < 1e-3
    assert np.max(np.abs(o.coef - ref.coef) / ref.coef_sigma) < 1e-3
    np.testing.assert_allclose(o.coef_sigma, ref.coef_sigma, rtol=1e-3)


@pytest.mark.parametrize("opts, field", [({"start": "warm"}, "start"), ({"max_iter": -1}, "max_iter"),
                                         ({"tol": 0.0}, "tol"), ({"coarse": 0}, "coarse"),
                                         ({"final": "twice"}, "final")])
def test_bad_options_are_refused(study, opts, field):
    fs = replace(study.filter, history_every_s=None)
    z = [np.zeros((1, 2, 3))]
    with pytest.raises(InputError) as err:
        ml.run_ml(EstimatorInput(z, [np.array([0.02, 0.04])], np.zeros((1, 3)), study.centrifuge.params()), fs, **opts)
    assert field in str(err.value)


def test_estimate_doo_runs_with_48_coefficients(study):
    """With estimate_doo the DOO terms join the gyro sensitivities (51 states in the Estimate)."""
    sch, params, z, t, _ = _record(study, SHORT, 0.5, np.random.SeedSequence(6).spawn(1))
    fs = replace(study.filter, estimate_doo=True, p0_sigma=default_p0_sigma(True), history_every_s=None)
    est = ml.run_ml(EstimatorInput(z, t, sch.angles_deg, params), fs)
    assert est.x.shape == (1, 51) and est.names[45:48] == ("DOO_x", "DOO_y", "DOO_z")
    assert np.linalg.eigvalsh(est.P[0] / np.sqrt(np.outer(np.diag(est.P[0]), np.diag(est.P[0])))).min() > 0
    # DOO is not separable from DF at one g level: its sigma stays near its prior
    assert np.all(est.coef_sigma[0, 45:48] > 0.1 * fs.p0_sigma[45:48])


def test_zero_measurement_noise_is_refused(study):
    fs = replace(study.filter, sigma_a_ug=0.0, history_every_s=None)
    with pytest.raises(InputError, match="filter.sigma_a_ug"):
        ml.run_ml(EstimatorInput([np.zeros((1, 2, 3))], [np.array([0.02, 0.04])], np.zeros((1, 3)),
                                 study.centrifuge.params()), fs)
