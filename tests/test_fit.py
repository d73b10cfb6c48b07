"""The fit check without the truth (issue 25, platcal.estimation.fit) on synthetic channels: a
clean record passes, a unit, a sign, a swapped pair and a clock are failed and named."""

import numpy as np
import pytest

from platcal.estimation.fit import FitTolerance, fit_check, lag1_autocorrelation, scale_meaning

SIGMA = 1e-3
NAMES = ("Ax", "Ay", "Az")


def synthetic(seed=0, n_seg=6, per_seg=500, dt=0.02):
    """Predictions that move (a rotating vector, different per segment), their instants and labels."""
    rng = np.random.default_rng(seed)
    t = np.tile(np.arange(per_seg) * dt, n_seg)
    seg = np.repeat(np.arange(n_seg), per_seg)
    phase = rng.uniform(0, 2 * np.pi, (n_seg, 3))[seg]
    amp = rng.uniform(0.5, 1.5, (n_seg, 3))[seg]
    pred = amp * np.sin(np.pi * t[:, None] + phase)
    noise = SIGMA * rng.standard_normal(pred.shape)
    return pred, t, seg, noise


def check(z, pred, t, seg):
    return fit_check(z - pred, np.full(z.shape, SIGMA**2), NAMES, predicted=pred, t=t, segment=seg)


def test_clean_channels_pass_at_about_the_stated_rate():
    flagged = 0
    for seed in range(100):
        pred, t, seg, noise = synthetic(seed)
        fc = check(pred + noise, pred, t, seg)
        flagged += not fc.passed
        assert abs(fc.nis_per_dof - 1) < 0.1
    assert flagged <= 2


def test_unit_error_is_named():
    pred, t, seg, noise = synthetic()
    z = pred + noise
    z[:, 0] *= 9.80665
    fc = check(z, pred, t, seg)
    assert not fc.passed and fc.worst[0] == "Ax"
    assert any(d.startswith("Ax: unit") and "9.80665" in d for d in fc.diagnosis)
    assert "Ax" in fc.message() and "9.80665" in fc.message()


@pytest.mark.parametrize("scale", [57.29577951308232, 1 / 1000.0, 3600.0])
def test_other_units(scale):
    pred, t, seg, noise = synthetic(1)
    z = pred + noise
    z[:, 2] *= scale
    fc = check(z, pred, t, seg)
    assert not fc.passed
    assert any(d.startswith("Az: unit") for d in fc.diagnosis)


def test_sign_is_named():
    pred, t, seg, noise = synthetic(2)
    z = pred + noise
    z[:, 1] *= -1
    fc = check(z, pred, t, seg)
    assert not fc.passed and fc.worst == ("Ay",)
    assert any(d.startswith("Ay: sign") for d in fc.diagnosis)


def test_swap_is_named():
    pred, t, seg, noise = synthetic(3)
    z = (pred + noise)[:, [1, 0, 2]]
    fc = check(z, pred, t, seg)
    assert not fc.passed and set(fc.worst) == {"Ax", "Ay"}
    assert any("swap: Ax follows the prediction of Ay" in d for d in fc.diagnosis)


def test_clock_offset_and_jitter_are_named():
    pred, t, seg, noise = synthetic(4)
    rng = np.random.default_rng(5)
    # the record's clock 2 ms late (z(t) = model(t + 2 ms)), then +-5 ms of uniform jitter
    for shift, label in ((np.full(len(t), 2e-3), "time offset of 0.002"), (rng.uniform(-5e-3, 5e-3, len(t)), "jitter")):
        fc = check(shifted(4, shift) + noise, pred, t, seg)
        assert not fc.passed
        assert any(d.startswith("clock") and label in d for d in fc.diagnosis), fc.diagnosis


def shifted(seed, shift, n_seg=6, per_seg=500, dt=0.02):
    """synthetic()'s predictions evaluated at t + shift."""
    rng = np.random.default_rng(seed)
    t = np.tile(np.arange(per_seg) * dt, n_seg) + shift
    seg = np.repeat(np.arange(n_seg), per_seg)
    phase = rng.uniform(0, 2 * np.pi, (n_seg, 3))[seg]
    amp = rng.uniform(0.5, 1.5, (n_seg, 3))[seg]
    return amp * np.sin(np.pi * t[:, None] + phase)


def test_correlated_innovations_fail_on_whiteness():
    pred, t, seg, noise = synthetic(6)
    walk = np.cumsum(noise, axis=0) * 0.3  # a slow error the model does not have
    fc = check(pred + noise + walk, pred, t, seg)
    assert not fc.passed
    assert max(abs(c.lag1) for c in fc.channels) > fc.lag1_bound + FitTolerance().lag1


def test_lag1_pairs_stay_within_segments():
    e = np.array([[1.0], [1.0], [-1.0], [-1.0]])
    assert lag1_autocorrelation(e)[0] != lag1_autocorrelation(e, np.array([0, 0, 1, 1]))[0]


def test_scale_meaning_near_one_is_nothing():
    assert scale_meaning(1.01) is None
    assert "sign" in scale_meaning(-0.98)
    assert "9.80665" in scale_meaning(1 / 9.80665)
