"""Observability: rho and J (eqs. 26-27), the exact position decomposition, rank test and CLI."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from platcal.rigs.centrifuge import observability as ob
from platcal.cli import main
from platcal.rigs.centrifuge.config import load_config, study_from_config

CONFIG = Path(__file__).resolve().parents[1] / "config" / "centrifuge.yaml"
SHORT = [[45, 0, 167], [350, 0, 325], [209, 0, 182]]


@pytest.fixture(scope="module")
def study():
    return load_config(CONFIG)


def test_rho_and_j_on_a_known_covariance():
    P = np.array([[4.0, 2.0, 0.0], [2.0, 9.0, -3.0], [0.0, -3.0, 1.0]])
    rho = ob.correlation(P)
    assert rho[0, 1] == pytest.approx(1 / 3)
    assert rho[1, 2] == pytest.approx(-1.0)
    assert rho[0, 2] == 0.0
    np.testing.assert_allclose(np.diag(rho), 1.0)
    assert ob.j_objective(P) == pytest.approx(4 / 3)
    # batched, and J of a diagonal covariance is 0
    assert ob.j_objective(np.stack([P, np.diag([1.0, 2.0, 3.0])])) == pytest.approx([4 / 3, 0.0])


def test_criteria_on_a_known_covariance():
    P = np.diag([0.01, 0.04])
    c = ob.criteria(P, np.array([1.0, 2.0]))
    assert c["A"] == pytest.approx(0.01 + 0.01)
    assert c["D"] == pytest.approx(np.log(0.01 * 0.01))
    assert c["maxrel"] == pytest.approx(10.0)
    assert c["rms_rel"] == pytest.approx(10.0)
    assert c["J"] == 0.0


def test_position_decomposition_equals_the_direct_run(study):
    """P_end^-1 = P0^-1 + sum_k I_k exactly; the order of the positions does not matter."""
    setup = ob.setup_from_study(study, 2.0)
    direct = ob.direct_covariance(setup, np.array(SHORT))[0]
    dec = ob.scheme_covariance(setup, np.array(SHORT))[0]
    rev = ob.scheme_covariance(setup, np.array(SHORT[::-1]))[0]
    np.testing.assert_allclose(np.sqrt(np.diag(dec)), np.sqrt(np.diag(direct)), rtol=1e-6)
    assert ob.j_objective(dec) == pytest.approx(ob.j_objective(direct), rel=1e-6)
    np.testing.assert_allclose(rev, dec, rtol=1e-8, atol=1e-12 * np.abs(dec).max())


def test_gram_information_equals_the_filter_without_gyro_noise(study):
    """The observability Gram (angles marginalised) and the covariance-only EKF agree at ARW 0."""
    setup = ob.setup_from_study(study, 2.0, arw_deg_rth=0.0)
    a = ob.position_information(setup, np.array(SHORT[:2]))
    b = ob.gram_information(setup, np.array(SHORT[:2]))
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6 * np.abs(a).max())


def test_table1_j_matches_the_independent_implementation(study):
    """Spec section 11: J(Table 1) = 94.5 at the defaults and 133.2 with ARW 0 (within 5 %)."""
    sch = study.schemes["table1"]
    j = ob.j_objective(ob.scheme_covariance(ob.setup_from_study(study, sch.dwell_s), sch.angles_deg))[0]
    j0 = ob.j_objective(ob.scheme_covariance(ob.setup_from_study(study, sch.dwell_s, arw_deg_rth=0.0),
                                             sch.angles_deg))[0]
    assert j == pytest.approx(94.5, rel=0.05)
    assert j0 == pytest.approx(133.2, rel=0.05)


def test_rank_test_full_at_10g_deficient_at_1g(study):
    sch = study.schemes["table1"]
    setup = ob.setup_from_study(study, 5.0)
    om = ob.observability_matrix(setup, sch.angles_deg)
    assert om.n_cols == 45 + 18 and om.rank == om.n_cols and om.coef_rank == 45
    static = replace(setup, centrifuge=replace(setup.centrifuge, rate_deg_s=0.0))
    om1 = ob.observability_matrix(static, sch.angles_deg)
    assert om1.coef_rank < 45


def _short_config(tmp_path):
    raw = yaml.safe_load(CONFIG.read_text())
    raw["schemes"] = {"short": {"dwell_s": 2, "positions": SHORT + [[106, 0, 338], [142, 0, 269], [134, 0, 141]]}}
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def test_cli_writes_json_and_correlation(tmp_path):
    cfg = _short_config(tmp_path)
    out = tmp_path / "obs"
    assert main(["observability", "--config", str(cfg), "--scheme", "short", "--out", str(out)]) == 0
    res = json.loads((out / "observability.json").read_text())
    assert res["n_pairs"] == 990 and res["J"] > 0
    assert res["settings"]["dwell_s"] == 2 and res["settings"]["arw_deg_rth"] == 0.001
    assert len(res["coefficients"]) == 45
    c0 = res["coefficients"][0]
    assert c0["posterior_over_prior"] == pytest.approx(c0["posterior_sigma"] / c0["prior_sigma"])
    assert res["observability_matrix"]["n_cols"] == 63
    rho = np.loadtxt(out / "correlation.csv", delimiter=",", skiprows=1, usecols=range(1, 46))
    np.testing.assert_allclose(np.diag(rho), 1.0)
    assert ob.j_objective(rho) == pytest.approx(res["J"], rel=1e-9)


def test_cli_bad_input_exits_2(tmp_path, capsys):
    cfg = _short_config(tmp_path)
    assert main(["observability", "--config", str(cfg), "--scheme", "nope", "--out", str(tmp_path / "o")]) == 2
    assert "--scheme" in capsys.readouterr().err
    assert main(["observability", "--config", str(cfg), "--scheme", "short", "--out", str(tmp_path / "o"),
                 "--arw", "-1"]) == 2
    assert not (tmp_path / "o").exists()
