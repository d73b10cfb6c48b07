"""A Monte Carlo cell's estimators on one simulation per chunk (the rigs' ``simulate_cell`` and
``identify_cell`` hooks, issue 22 item 4): each estimator's tables are those of its cell run alone,
bit for bit, whatever the batch or backend, and the simulation runs once per chunk."""

import json

import pandas as pd
import pytest

from platcal.io import read_yaml
from platcal.rig import get_rig
from platcal.rigs.centrifuge import study as cf
from platcal.study import montecarlo as smc

CENTRIFUGE = {
    "seed": 7,
    "schemes": {"table1": {"dwell_s": 2, "positions": [[45, 0, 167], [350, 0, 325], [209, 0, 182],
                                                         [134, 0, 141], [106, 0, 338], [142, 0, 269]]}},
    "study": {"schemes": ["table1"], "sigma_a_ug": [20], "replicates": 5, "batch": 2,
              "paper": {"scheme": "table1", "estimator": "ekf1", "sigma_a_ug": 20},
              # a warm-up pass, and a filter period of its own: it reads every 2nd kept output
              "estimators": {"ekf1": {"passes": 1}, "ekfw": {"estimator": "ekf", "warmup_s": 0.2},
                             "slow": {"passes": 1, "period_ms": 40},
                             # ekf1 is tabled from ekf2's run after its first pass (pass_prefixes)
                             "ekf2": {"passes": 2}}},
}

MULTIPOSITION = """rig: multiposition
seed: 7
schemes:
  TET4: {dwell_s: 4, positions: [[0, 0, 0], [109.47, 0, 0], [109.47, 0, 120], [109.47, 0, 240]]}
study: {seeds: 5, batch: 2, schemes: [TET4], sigma_a_ug: [20]}
"""


def _cell(name):
    rig = get_rig(name)
    raw = json.loads(json.dumps(CENTRIFUGE)) if name == "centrifuge" else read_yaml(MULTIPOSITION)
    cfg = cf.check_study(raw) if name == "centrifuge" else rig.montecarlo.check(raw)
    h = rig.montecarlo
    case = h.case(cfg, h.cases(cfg)[0])
    return rig, cfg, case, h.noise_levels(cfg)[0], h.estimators(cfg)


class Counting:
    """The rig's hooks, counting the shared simulations and each estimator's identifications."""

    def __init__(self, hooks):
        self.hooks, self.calls, self.identified = hooks, 0, []

    def __getattr__(self, name):
        return getattr(self.hooks, name)

    def simulate_cell(self, *a):
        self.calls += 1
        return self.hooks.simulate_cell(*a)

    def identify_cell(self, cfg, case, noise, estimator, data, **kw):
        self.identified.append(estimator)
        return self.hooks.identify_cell(cfg, case, noise, estimator, data, **kw)


@pytest.mark.parametrize("name", ["centrifuge", "multiposition"])
@pytest.mark.parametrize("kw", [{}, {"batch": 3, "threads": 2, "backend": "joblib"}])
def test_a_cells_estimators_on_one_simulation_give_their_cells_run_alone(name, kw):
    rig, cfg, case, level, estimators = _cell(name)
    assert len(estimators) >= 3
    together = smc.cells_tables(rig, {e: (cfg, case) for e in estimators}, level, **kw)
    assert list(together) == estimators
    for e in estimators:
        coef, runs, timing = together[e]
        alone_coef, alone_runs, _ = smc.run_cell(rig, cfg, case, level, e)
        pd.testing.assert_frame_equal(coef.to_pandas(), alone_coef, check_exact=True)
        pd.testing.assert_frame_equal(runs.to_pandas(), alone_runs, check_exact=True)
        assert len(alone_runs) == 5 and timing["compute_s"] > 0 and timing["estimator"] == e


@pytest.mark.parametrize("name", ["centrifuge", "multiposition"])
def test_a_cell_job_simulates_each_chunk_once_for_all_its_estimators(name, tmp_path, monkeypatch):
    rig, cfg, case, level, estimators = _cell(name)
    counting = Counting(rig.montecarlo)
    monkeypatch.setattr(smc, "get_rig", lambda _: type(rig)(**{**rig.__dict__, "montecarlo": counting}))
    smc.cell_job(name, cfg, case.name, level, estimators, tmp_path / "cell")
    assert counting.calls == len(smc.chunks(5, 2))  # 3 chunks, not 3 per estimator
    # ekf1 comes from ekf2's run on the way: never identified by itself
    assert "ekf1" in estimators and "ekf2" in estimators
    assert sorted(counting.identified) == sorted([e for e in estimators if e != "ekf1"] * 3)
    for e in estimators:
        alone_coef, alone_runs, _ = smc.run_cell(rig, cfg, case, level, e)
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "cell" / e / "coef.parquet"), alone_coef,
                                      check_exact=True)
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "cell" / e / "runs.parquet"), alone_runs,
                                      check_exact=True)
