"""The estimator comparison (issue 9 item 4) and the estimator plumbing (item 3): cells, tables,
figures, the report's "Which estimator" section, the registry, and the config's checks."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.errors import InputError
from platcal.rigs.centrifuge import RIG, compare, compare_cells, compare_figures
from platcal.rigs.centrifuge import study as mc
from platcal.rigs.centrifuge.config import study_from_config
from platcal.rigs.centrifuge.estimators import KINDS, run_estimator
from platcal.study.collect import collect_job
from platcal.study.montecarlo import run_cell

BASE = {
    "seed": 7,
    "schemes": {"short": {"dwell_s": 0.6, "positions": [[45, 0, 167], [350, 0, 325], [209, 0, 182],
                                                          [134, 0, 141], [106, 0, 338], [142, 0, 269]]}},
    "study": {"schemes": ["short"], "dwell_s": 0.6, "sigma_a_ug": [10], "replicates": 2, "batch": 2,
              "paper": {"scheme": "short"}, "single": {"scheme": "short"},
              "estimators": {"ekf1": {"passes": 1}, "ekf2": {"passes": 2},
                             "ekfw": {"estimator": "ekf", "warmup_s": 0.2},
                             "iekf": {"estimator": "iekf", "iterations": 2}},
              "compare": {"scheme": "short", "sigma_a_ug": [10, 50], "estimators": ["ekf1", "ekf2", "iekf"],
                          "replicates": 3}},
}


def cfg(**compare_over):
    raw = json.loads(json.dumps(BASE))
    raw["study"]["compare"].update(compare_over)
    return mc.check_study(raw)


def test_registry_lists_the_kinds_and_the_rig_names_them():
    assert list(KINDS)[:2] == ["ekf", "iekf"] and RIG.estimators == tuple(KINDS)
    st = study_from_config({**BASE, "filter": {"estimator": "iekf", "iterations": 4, "iterate_s": 2.0}})
    assert st.filter.estimator == "iekf" and dict(st.filter.estimator_options) == {"iterations": 4, "tol": 0.01, "until_s": 2.0}
    # the EKF kind takes only its own keys: iekf options of the filter section do not leak into it
    st = study_from_config({**BASE, "filter": {"iterations": 4}})
    assert st.filter.estimator == "ekf" and st.filter.estimator_options == ()


@pytest.mark.parametrize("raw, field", [
    ({"filter": {"estimator": "kalman"}}, "filter.estimator"),
    ({"study": {**BASE["study"], "estimators": {**BASE["study"]["estimators"], "x": {"estimator": "nope"}}}}, "study.estimators.x.estimator"),
    ({"study": {**BASE["study"], "compare": {"scheme": "short", "estimators": ["nosuch"]}}}, "study.compare.estimators[0]"),
    ({"study": {**BASE["study"], "compare": {"scheme": "nosuch"}}}, "study.compare.scheme"),
    ({"study": {**BASE["study"], "compare": {"scheme": "short", "sigma_a_ug": [10, 10]}}}, "study.compare.sigma_a_ug"),
    ({"study": {**BASE["study"], "compare": {"scheme": "short", "replicates": 0}}}, "study.compare.replicates"),
    ({"study": {**BASE["study"], "estimators": {**BASE["study"]["estimators"],
                                                 "i": {"estimator": "iekf", "iterations": 0}}}},
     "study.estimators.i.iterations"),
])
def test_bad_estimator_config_names_the_field(raw, field):
    with pytest.raises(InputError) as e:
        mc.check_study({**json.loads(json.dumps(BASE)), **raw})
    assert e.value.field == field


def test_cells_follow_the_study_estimators():
    c = mc.study_for_cell(cfg(), 10, "iekf")
    assert c.filter.estimator == "iekf" and dict(c.filter.estimator_options)["iterations"] == 2
    w = mc.study_for_cell(cfg(), 10, "ekfw")
    assert w.filter.estimator == "ekf" and dict(w.filter.estimator_options) == {"warmup_s": 0.2}
    # every kind runs through the registry with the contract's signature
    sch = mc.builtin_scheme(cfg(), "short")
    seeds = [np.random.SeedSequence(3)]
    est = mc.simulate_identify(c, sch, seeds)
    assert est.x.shape == (1, 48) and np.all(np.isfinite(est.P))
    assert run_estimator.__name__ == "run_estimator"


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    c = cfg()
    root = tmp_path_factory.mktemp("compare")
    dirs = []
    for label, level in compare_cells.compare_levels(c).items():  # one job per level, its estimators
        d = root / f"noise{label}"
        compare_cells.compare_level_job(c, level, d)
        dirs.append(d)
    out = {"coef": root / "coef.parquet", "runs": root / "runs.parquet", "timing": root / "timing.csv"}
    collect_job([d / "coef.parquet" for d in dirs], [d / "runs.parquet" for d in dirs],
                [d / "timing.json" for d in dirs], out)
    figs = {"tables": root, "cost": root / "cost.png", "nees": root / "nees.png"}
    compare_figures.compare_job(c, out["coef"], out["runs"], figs)
    return c, root


def test_comparison_cells_tables_and_figures(compared):
    c, root = compared
    assert compare_cells.compare_cells(c) == [("10", "ekf1"), ("10", "ekf2"), ("10", "iekf"),
                                        ("50", "ekf1"), ("50", "ekf2"), ("50", "iekf")]
    runs = pd.read_parquet(root / "runs.parquet")
    assert len(runs) == 6 * 3 and (runs["cpu_s"] > 0).all() and (runs["wall_s"] > 0).all()
    # every estimator of a level sees the same records, those of the sweep's replicates
    coef = pd.read_parquet(root / "coef.parquet")
    sweep = RIG.montecarlo.run_batch(c, mc.builtin_scheme(c, "short"), 10, "ekf2",
                                     [mc.replicate_seed(c["seed"], "short", 10, r) for r in range(3)])
    mine = coef[(coef["estimator"] == "ekf2") & (coef["noise"] == 10)]["estimate"].to_numpy()
    np.testing.assert_array_equal(mine, sweep.estimate.ravel())
    rms = pd.read_csv(root / "compare_rms.csv")
    assert len(rms) == 6 * 45 and set(rms["group"]) == {"gyro", "accel"}
    summ = pd.read_csv(root / "compare_summary.csv")
    assert list(summ["estimator"]) == ["ekf1", "ekf2", "iekf"] * 2
    r = summ.iloc[1]
    g = rms[(rms["estimator"] == "ekf2") & (rms["sigma_a_ug"] == 10)]
    assert r["max_rms_rel_err_pct_gyro"] == pytest.approx(g.loc[g["group"] == "gyro", "rms_rel_err_pct"].max())
    n = runs[(runs["estimator"] == "ekf2") & (runs["noise"] == 10)]["nees"]
    assert r["mean_nees"] == pytest.approx(n.mean()) and r["beyond_999_pct"] == pytest.approx((n > 80.0767).mean() * 100)
    assert summ.loc[summ["estimator"] == "ekf1", "cost_vs_ekf1"].eq(1.0).all()
    for f in ("compare_summary.md", "compare_summary.html", "cost.png", "nees.png"):
        assert (root / f).stat().st_size > 0


def test_a_level_job_gives_each_estimators_cell_run_alone_bit_for_bit(tmp_path):
    """The level job simulates each chunk once and runs every estimator of the level on it
    (issue 22 item 4): its tables are those of each estimator's cell run alone (the runner's
    ``cell_tables``, which simulates for every estimator), bit for bit, for every kind, an
    estimator with a filter period of its own (it reads every 2nd kept output) and a last chunk
    shorter than the batch; only the cost columns differ."""
    own = {"ekf1": {"passes": 1}, "ekf2": {"passes": 2}, "ekfw": {"estimator": "ekf", "warmup_s": 0.2},
           "iekf": {"estimator": "iekf", "iterations": 2}, "ukf": {"estimator": "ukf"}, "ml": {"estimator": "ml"},
           "slow": {"passes": 1, "period_ms": 40}}
    c = cfg(estimators=own, sigma_a_ug=[10, 50], replicates=5, levels_of={"ukf": [50]})
    compare_cells.compare_level_job(c, 50.0, tmp_path)
    coef, runs = pd.read_parquet(tmp_path / "coef.parquet"), pd.read_parquet(tmp_path / "runs.parquet")
    timing = json.loads((tmp_path / "timing.json").read_text())
    assert list(dict.fromkeys(runs["estimator"])) == list(own) == [t["estimator"] for t in timing]
    assert (runs["cpu_s"] > 0).all() and all(t["level_simulation_cpu_s"] > 0 for t in timing)
    full = compare_cells.with_compare_estimators(c)
    scheme = mc.builtin_scheme(c, "short")
    for name in own:
        alone_coef, alone_runs, _ = run_cell(RIG, full, scheme, 50.0, name, replicates=5)
        mine_coef = coef[coef["estimator"] == name].reset_index(drop=True)
        mine_runs = runs[runs["estimator"] == name].drop(columns=["wall_s", "cpu_s"]).reset_index(drop=True)
        pd.testing.assert_frame_equal(mine_coef, alone_coef, check_exact=True)
        pd.testing.assert_frame_equal(mine_runs, alone_runs, check_exact=True)
        assert len(alone_runs) == 5 and np.isfinite(alone_runs["nees"]).all()


def _summ(rows):
    cols = ["estimator", "kind", "passes", "sigma_a_ug", "runs", "max_rms_rel_err_pct_gyro",
            "max_rms_rel_err_pct_accel", "mean_nees", "median_nees", "inside_95_pct", "beyond_999_pct",
            "wall_s_per_run", "cpu_s_per_run", "failed_runs"]
    return compare.meets_bounds(pd.DataFrame([dict(zip(cols, r)) for r in rows]))


def test_bounds_and_the_recommendation_come_from_the_numbers():
    s = _summ([("ekf1", "ekf", 1, 10.0, 200, 2.2, 0.08, 71.0, 51, 75, 18.0, 0.3, 0.14, 0),
               ("ekf2", "ekf", 2, 10.0, 200, 1.45, 0.08, 44.9, 44, 97, 0.0, 0.5, 0.28, 0),
               ("ekfw", "ekf", 1, 10.0, 200, 1.40, 0.08, 46.0, 44, 95, 0.5, 0.3, 0.16, 0),
               ("bad", "iekf", 1, 10.0, 200, 1.30, 0.08, 52.0, 44, 90, 0.5, 0.3, 0.15, 0),
               ("worse", "iekf", 1, 10.0, 200, 1.60, 0.08, 45.0, 44, 95, 0.0, 0.3, 0.15, 0)])
    # bad: mean NEES 52 is > 10 % off 45; worse: gyro 10 % above ekf2's, beyond the 5 % resolution
    assert s["meets"].tolist() == [False, True, True, False, False]
    assert s["gyro_ok"].tolist() == [False, True, True, True, False]
    assert s["cheap"].tolist() == [True, False, True, True, True]
    assert s.loc[2, "cost_vs_ekf1"] == pytest.approx(0.16 / 0.14)
    text = compare.which_estimator(cfg(), s)
    assert "**Use ekfw**" in text and "fails the mean NEES" in text
    assert compare.UKF_SLOT in text and "no UKF ran" in text
    # a UKF row fills the slot with its numbers
    u = _summ([("ekf1", "ekf", 1, 10.0, 200, 2.2, 0.08, 71.0, 51, 75, 18.0, 0.3, 0.14, 0),
               ("ukf", "ukf", 1, 10.0, 200, 1.9, 0.08, 50.0, 48, 90, 2.0, 0.9, 0.50, 0)])
    sentence = compare.ukf_sentence(u)
    assert "1.90 %" in sentence and "2.20 %" in sentence and "holds" in sentence


def test_comparison_may_define_its_own_estimators():
    """study.compare.estimators as a mapping: estimators of the comparison only (the sweep does not
    run them); a name of study.estimators must keep its definition."""
    c = cfg(estimators={"ekf1": {"passes": 1}, "w1": {"estimator": "ekf", "warmup_s": 0.2}})
    assert list(c["study"]["estimators"]) == ["ekf1", "ekf2", "ekfw", "iekf"]  # the sweep's, unchanged
    assert compare_cells.compare_cells(c) == [("10", "ekf1"), ("10", "w1"), ("50", "ekf1"), ("50", "w1")]
    assert compare_cells.kind_of(c, "w1") == "ekf" and compare_cells.passes_of(c, "w1") == 1
    p = compare_cells.cell_params(c, 10.0, "w1")
    assert p["estimator"] == {"estimator": "ekf", "warmup_s": 0.2} and p["replicates"] == 3
    with pytest.raises(InputError) as e:
        cfg(estimators={"ekf1": {"passes": 3}})
    assert e.value.field == "study.compare.estimators.ekf1"
    with pytest.raises(InputError) as e:
        cfg(estimators={"u": {"estimator": "nosuch"}})
    assert e.value.field == "study.compare.estimators.u.estimator"


def test_levels_of_limits_an_estimator_to_some_levels():
    """study.compare.levels_of runs a costly estimator at some levels only; bad names or levels
    are refused naming the field (before any job: the workflow builds its cells from this)."""
    raw = yaml.safe_load(open("config/centrifuge.yaml"))
    cells = compare_cells.compare_cells(mc.check_study(raw))
    assert ("10", "ukf") in cells and ("5", "ukf") not in cells and ("5", "ekf1") in cells
    raw["study"]["compare"]["levels_of"] = {"nope": [10]}
    with pytest.raises(InputError) as exc:
        compare_cells.compare_cells(mc.check_study(raw))
    assert exc.value.field == "study.compare.levels_of.nope"
    raw["study"]["compare"]["levels_of"] = {"ukf": [20]}
    with pytest.raises(InputError) as exc:
        compare_cells.compare_cells(mc.check_study(raw))
    assert exc.value.field == "study.compare.levels_of.ukf[0]"
