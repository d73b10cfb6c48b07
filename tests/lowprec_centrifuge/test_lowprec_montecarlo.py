"""The rig's Monte Carlo hooks on the generic runner: a batch equals runs of one, common random
numbers across scenarios and methods, and ``platcal simulate --seed N`` writes replicate N."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.config import COEFFS, load_config
from platcal.rigs.lowprec_centrifuge.metrics import ERRORS, compensate, effect
from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY, metric_column, study_frames
from platcal.rigs.lowprec_centrifuge.truth import coeff_vector, simulate_batch
from platcal.study.montecarlo import replicate_seed, run_cell

TINY = {"rig": "lowprec_centrifuge", "seed": 3,
        "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6], "run2": [4, 7]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20},
        "traditional": {"levels_g": [4, 6], "hold_s": 30, "rest_last_s": 10},
        "study": {"seeds": 3, "rate_errors": [], "arm_errors_mm": [], "gross": {}}}


@pytest.fixture(scope="module")
def hooks():
    rig = get_rig("lowprec_centrifuge")
    return rig, rig.montecarlo, rig.montecarlo.check(TINY)


@pytest.mark.parametrize("estimator", ["proposed", "traditional"])
def test_a_batch_equals_runs_of_one(hooks, estimator):
    rig, h, cfg = hooks
    case, level = h.case(cfg, "default"), h.noise_levels(cfg)[0]
    c3, r3, _ = run_cell(rig, cfg, case, level, estimator)
    c1, r1, _ = run_cell(rig, cfg, case, level, estimator, batch=1)
    pd.testing.assert_frame_equal(c3, c1, check_exact=True)
    pd.testing.assert_frame_equal(r3, r1, check_exact=True)
    assert len(r3) == 3 and not r3["failed"].any()
    assert (c3.groupby("name")["estimate"].nunique() == 3).all()   # replicates differ


def test_common_random_numbers_across_scenarios_and_methods(hooks):
    """The traditional calibrations are evaluated on exactly the proposed cell's records: the same
    numbers as simulating the proposed run again (same seeds, floor and sensitivities) and
    compensating it with the traditional cell's estimates."""
    rig, h, cfg = hooks
    level = h.noise_levels(cfg)[0]
    cells = [run_cell(rig, cfg, h.case(cfg, "default"), level, e, replicates=2) for e in h.estimators(cfg)]
    assert not any("|truth|" in c for c in cells[1][1].columns)     # the traditional cell simulates no proposed run
    st = load_config(cfg)
    cross, _ = study_frames(st, ["default"], pd.concat([c[0] for c in cells]), pd.concat([c[1] for c in cells]))
    seeds = [replicate_seed(3, SEED_KEY, level, r) for r in range(2)]
    rb = simulate_batch(st, "P1", "run2", seeds, floor=True)
    trad = cells[1][0].set_index("name")["estimate"]
    c_hat = np.stack([trad.loc[f"P1.traditional.{k}"].to_numpy() for k in COEFFS], axis=1)
    truth = coeff_vector(st, "P1")
    after = compensate(rb.final_floor, rb.sens_final, c_hat - truth)
    rows = cross[(cross["method"] == "traditional") & (cross["eval_run"] == "run2")].sort_values(["seed", "error"])
    for j, e in enumerate(ERRORS):
        r = rows[rows["error"] == e]
        assert np.array_equal(r["before"].to_numpy(), rb.final[:, j])
        assert np.array_equal(r["after"].to_numpy(), after[:, j])
        assert np.array_equal(r["effect_pct"].to_numpy(), effect(rb.final, after)[:, j])
        t = cross[(cross["method"] == "truth") & (cross["eval_run"] == "run2") & (cross["error"] == e)]
        assert np.array_equal(t.sort_values("seed")["before"].to_numpy(), rb.final[:, j])
    a = simulate_batch(st.with_centrifuge(h.case(cfg, "perfect").centrifuge), "P1", "run1", seeds)
    b = simulate_batch(st.with_centrifuge(h.case(cfg, "worst").centrifuge), "P1", "run1", seeds)
    assert np.array_equal(a.draws.k0_ug, b.draws.k0_ug) and np.array_equal(a.draws.phi0_rad, b.draws.phi0_rad)
    assert not np.array_equal(a.err, b.err)        # the centrifuge matters, the draws are shared


def test_simulate_seed_n_writes_replicate_n(hooks, tmp_path):
    rig, h, cfg = hooks
    path = tmp_path / "lp.yaml"
    path.write_text(yaml.safe_dump(TINY))
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(path), "--platform", "P1", "--run", "run2", "--seed", "2",
                 "--out", str(out)]) == 0
    truth = json.loads(out.with_name("rec.csv.truth.json").read_text())
    _, runs, _ = run_cell(rig, cfg, h.case(cfg, "default"), h.noise_levels(cfg)[0], "proposed")
    row = runs.set_index("replicate").loc[2]
    for e, k in (("VE", "dVE"), ("VN", "dVN"), ("pE", "dpE"), ("pN", "dpN")):
        assert truth["final_errors"][k] == row[metric_column("P1", "truth", "run2", e, "before")]
    assert truth["seed"] == 2
