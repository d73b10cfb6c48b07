"""The sled on the generic Monte Carlo runner (platcal.rigs.sled.montecarlo; docs/rocket-sled.md §12)."""

import numpy as np
import pandas as pd
import pytest

from platcal.errors import InputError
from platcal.rig import get_rig
from platcal.rigs.sled.config import ARCSEC, load_config
from platcal.rigs.sled.identify import effective_phi, identify, metrics
from platcal.rigs.sled.montecarlo import case_raw, replicate_seeds
from platcal.rigs.sled.simulate import simulate
from platcal.study.montecarlo import replicate_seed, run_cell

RAW = {"rig": "sled", "trajectory": {"static_after_s": 2}, "study": {"seeds": 3, "cases": ["default", "run7"]}}


@pytest.fixture(scope="module")
def hooks():
    return get_rig("sled").montecarlo


@pytest.mark.parametrize("case", ["default", "run7"])
def test_a_batch_gives_the_numbers_of_runs_of_one(hooks, case):
    rig = get_rig("sled")
    cfg = hooks.check(RAW)
    c = hooks.case(cfg, case)
    level = hooks.noise_levels(cfg)[0]
    coef3, runs3, _ = run_cell(rig, cfg, c, level, "kf", batch=3)
    coef1, runs1, _ = run_cell(rig, cfg, c, level, "kf", batch=1)
    pd.testing.assert_frame_equal(coef1, coef3, check_exact=True)
    pd.testing.assert_frame_equal(runs1, runs3, check_exact=True)
    assert list(runs3["replicate"]) == [0, 1, 2] and not runs3["failed"].any()
    assert runs3["y_after_b_max_run_cm"].nunique() == 3          # three different draws
    assert set(coef3["name"]) == ({"phi_x", "phi_y", "phi_z"} if case == "run7" else {"phi_y", "phi_z"})


def test_replicate_is_the_cells_seed_sequence_and_its_own_truth(hooks):
    """Replicate r of case C draws from replicate_seed(seed, C, noise, r); the coef table's truth
    is that replicate's effective attitude and the runs table carries its §8 metrics."""
    cfg = hooks.check({**RAW, "seed": 11})
    case = hooks.case(cfg, "default")
    b = hooks.run_batch(cfg, case, 20.0, "kf", [replicate_seed(11, "default", 20.0, 2)])
    c = load_config(case_raw(cfg, "default"))
    sb = simulate(c, replicate_seeds(cfg, "default", [2]))
    idn = identify(c, sb.traj, sb.f, sb.w)
    assert np.array_equal(b.truth[0], effective_phi(sb.truth)[0, 1:] / ARCSEC)
    assert np.array_equal(b.estimate[0], idn.phi_run[0, 1:] / ARCSEC)
    m = metrics(idn, sb.truth)
    assert all(np.array_equal(b.extra[k], m[k].to_numpy(float), equal_nan=True) for k in m.columns)
    other = hooks.run_batch(cfg, hooks.case(cfg, "run7"), 20.0, "kf", [replicate_seed(11, "run7", 20.0, 2)])
    assert not np.array_equal(other.extra["yz_before_max_run_cm"], b.extra["yz_before_max_run_cm"])


def test_cell_params_hold_what_a_case_depends_on(hooks):
    cfg = hooks.check(RAW)
    p = {c: hooks.cell_params(cfg, c, 20.0, "kf") for c in ("default", "run7")}
    assert p["default"]["filter"]["states"] == 6 and p["run7"]["filter"]["states"] == 7
    assert p["default"]["seed"] == 0 and p["default"]["replicates"] == 3 and "study" not in p["default"]
    # the list of cases is the sweep: adding one leaves the other cells' params alone
    more = hooks.check({**RAW, "study": {"seeds": 3, "cases": ["default", "run7", "post"]}})
    assert hooks.cell_params(more, "default", 20.0, "kf") == p["default"]
    # a value of the base config reaches every case; the states only those that do not set them
    moved = hooks.check({**RAW, "alignment": {"sigma_arcsec": [30, 31, 180]}})
    assert all(hooks.cell_params(moved, c, 20.0, "kf") != p[c] for c in p)
    seven = hooks.check({**RAW, "filter": {"states": 7}})
    assert hooks.cell_params(seven, "default", 20.0, "kf") != p["default"]
    assert hooks.cell_params(seven, "run7", 20.0, "kf") == p["run7"]


def test_check_refuses_a_case_listed_twice(hooks):
    with pytest.raises(InputError) as e:
        hooks.check({"rig": "sled", "study": {"cases": ["default", "default"]}})
    assert e.value.field == "study.cases[1]"
