"""Estimator choice of the multiposition rig (issue 9 item 5): ekf and the iterated EKF."""

import json

import numpy as np
import pytest

from platcal.cli import main
from platcal.errors import InputError
from platcal.rigs.multiposition import filter as fl
from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.estimators import ESTIMATORS, FilterChoice, estimate, variant_choice


@pytest.fixture(scope="module")
def short(cfg):
    s = cfg.scheme("TET4")
    t, _, z = fl.simulate(cfg, s, [1, 2])
    return s, t[:151], z[:, :, :151]


def test_iekf_one_linearisation_is_the_ekf(cfg, short):
    """One linearisation per update: the same Jacobian and innovation as the EKF, and the same
    two 3-D Joseph updates, so the same numbers bit for bit."""
    s, t, z = short
    e = estimate(cfg, FilterChoice("ekf", 1, {}), s.angles_deg, t, z)
    i = estimate(cfg, FilterChoice("iekf", 1, {"iterations": 1, "tolerance": 0.0}), s.angles_deg, t, z)
    assert np.array_equal(i.coef, e.coef) and np.array_equal(i.cov, e.cov)
    assert np.array_equal(i.mean_nis, e.mean_nis)
    assert np.all(e.linearisations == 1) and np.all(i.linearisations == 1)


def test_iekf_relinearises_and_keeps_covariance_spd(cfg, short):
    s, t, z = short
    e = estimate(cfg, FilterChoice("ekf", 1, {}), s.angles_deg, t, z)
    i = estimate(cfg, FilterChoice("iekf", 1, {"iterations": 3, "tolerance": 0.0}), s.angles_deg, t, z)
    assert np.all(i.linearisations == 3)
    assert np.array_equal(i.cov, np.swapaxes(i.cov, 1, 2)) and np.all(np.linalg.eigvalsh(i.cov) > 0)
    assert not np.array_equal(i.coef, e.coef)  # the relinearisation changes the estimate
    assert np.all(np.abs(i.mean_nis - 1) < 0.1)  # innovations (at the prior) consistent with R
    t1 = estimate(cfg, FilterChoice("iekf", 1, {"iterations": 3, "tolerance": 1e9}), s.angles_deg, t, z)
    assert np.all(t1.linearisations == 1)  # a tolerance no step exceeds: one linearisation


def test_config_and_variants(cfg):
    assert set(ESTIMATORS) >= {"ekf", "iekf"}
    assert cfg.filter_choice() == FilterChoice("ekf", 1, {})
    c = load_config({"rig": "multiposition", "filter": {"estimator": "iekf", "iekf": {"iterations": 5}}})
    assert c.filter_choice() == FilterChoice("iekf", 1, {"iterations": 5, "tolerance": 0.01})
    assert variant_choice(cfg, "ekf2") == FilterChoice("ekf", 2, {})
    assert variant_choice(cfg, "iekf").estimator == "iekf"
    with pytest.raises(InputError) as e:
        load_config({"rig": "multiposition", "filter": {"estimator": "ukf9"}})
    assert e.value.field == "filter.estimator"
    with pytest.raises(InputError) as e:
        load_config({"rig": "multiposition", "study": {"estimators": {"x": {"estimator": "nope"}}}})
    assert e.value.field == "study.estimators.x.estimator"
    with pytest.raises(InputError) as e:
        variant_choice(cfg, "nope")
    assert e.value.field == "--estimator"


def test_identify_with_estimator_option(tmp_path):
    c = tmp_path / "c.yaml"
    c.write_text("rig: multiposition\nschemes:\n  q: {dwell_s: 2, positions: [[0, 0, 0], [109.47, 0, 0], "
                 "[109.47, 0, 120], [109.47, 0, 240]]}\n")
    rec = tmp_path / "r.csv"
    assert main(["simulate", "--config", str(c), "--scheme", "q", "--seed", "2", "--out", str(rec)]) == 0
    assert main(["identify", "--config", str(c), "--data", str(rec), "--estimator", "iekf",
                 "--out", str(tmp_path / "id")]) == 0
    s = json.loads((tmp_path / "id/summary.json").read_text())
    assert s["estimator"] == "iekf" and s["estimator_options"] == {"iterations": 3, "tolerance": 0.01}
    assert main(["identify", "--config", str(c), "--data", str(rec), "--estimator", "bogus",
                 "--out", str(tmp_path / "id2")]) == 2
    assert not (tmp_path / "id2").exists()
