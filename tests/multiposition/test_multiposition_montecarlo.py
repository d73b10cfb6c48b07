"""The multiposition rig on the generic Monte Carlo runner: hooks, seeds, bit-identity, the CLI's
``--seed`` as a replicate of the study's cell (docs/multiposition-1g.md §14, §16)."""

import json

import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from platcal.errors import InputError
from platcal.rig import get_rig
from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.filter import simulate
from platcal.rigs.multiposition.record import to_frame
from platcal.study.montecarlo import replicate_seed, run_cell

SHORT = """rig: multiposition
seed: 7
noise: {sigma_a_ug: 20}
schemes:
  TET4: {dwell_s: 4, positions: [[0, 0, 0], [109.47, 0, 0], [109.47, 0, 120], [109.47, 0, 240]]}
study: {seeds: 8, schemes: [TET4, GA], sigma_a_ug: [5, 20]}
"""


@pytest.fixture(scope="module")
def mc():
    from platcal.io import read_yaml

    rig = get_rig("multiposition")
    return rig, rig.montecarlo.check(read_yaml(SHORT))


def test_hooks_axes_and_settings(mc):
    rig, cfg = mc
    h = rig.montecarlo
    assert h.cases(cfg) == ["TET4", "GA"] and h.noise_levels(cfg) == [5.0, 20.0]
    assert h.estimators(cfg) == ["ekf1", "ekf2", "iekf"]
    st = h.settings(cfg)
    assert (st.seed, st.replicates, st.backend, st.threads) == (7, 8, "numba", 1)
    assert h.case_file(cfg, "GA") == "design/GA.yaml" and h.case_file(cfg, "TET4") is None
    with pytest.raises(InputError) as exc:
        h.case(cfg, "GA")  # a GA design needs the design rule's file
    assert exc.value.field == "study.schemes"
    p5, p20 = h.cell_params(cfg, "TET4", 5.0, "ekf2"), h.cell_params(cfg, "TET4", 20.0, "ekf2")
    assert p5["noise"]["sigma_a_ug"] == 5.0 and p20["noise"]["sigma_a_ug"] == 20.0
    assert p5["filter"]["passes"] == 2 and p5["scheme"]["dwell_s"] == 4 and p5["seed"] == 7
    assert "scheme" not in h.cell_params(cfg, "GA", 5.0, "ekf1")  # the design file is the cell's input
    # speed-only settings are not params of a cell: changing them reruns nothing
    fast = h.check({**cfg, "study": {**cfg["study"], "batch": 3, "threads": 2, "backend": "joblib"}})
    assert h.cell_params(fast, "TET4", 5.0, "ekf2") == p5


@pytest.mark.parametrize("study, field", [
    ({"sigma_a_ug": [5, 5.0004]}, "study.sigma_a_ug"),
    ({"schemes": ["TET4", "TET4"]}, "study.schemes[1]"),
    ({"schemes": ["nope"]}, "study.schemes[0]"),
    ({"estimators": {"bad name": {"passes": 1}}}, "study.estimators.bad name"),
    ({"estimators": {"x": {"estimator": "ukf"}}}, "study.estimators.x.estimator"),
    ({"backend": "mpi"}, "study.backend"),
    ({"batch": 0}, "study.batch"),
])
def test_bad_study_is_refused_naming_the_field(study, field):
    with pytest.raises(InputError) as exc:
        get_rig("multiposition").montecarlo.check({"rig": "multiposition", "study": study})
    assert exc.value.field == field


def test_replicates_bit_identical_whatever_batch_and_threads(mc):
    """A replicate's numbers depend on its SeedSequence only: batch 3 or 8, 1 or 2 threads, numba
    threads or joblib workers give identical arrays (and the estimators share the records)."""
    rig, cfg = mc
    case = rig.montecarlo.case(cfg, "TET4")
    ref_coef, ref_runs, _ = run_cell(rig, cfg, case, 20.0, "ekf1", threads=1, batch=8)
    for kw in ({"threads": 1, "batch": 3}, {"threads": 2, "batch": 8}, {"threads": 2, "batch": 3},
               {"threads": 2, "batch": 3, "backend": "joblib"}):
        coef, runs, timing = run_cell(rig, cfg, case, 20.0, "ekf1", **kw)
        assert timing["batch"] == kw["batch"] and timing["threads"] == kw["threads"]
        for col in ("estimate", "sigma"):
            assert np.array_equal(coef[col].to_numpy(), ref_coef[col].to_numpy()), (kw, col)
        for col in ("nees", "mean_nis", "failed_updates", "linearisations"):
            assert np.array_equal(runs[col].to_numpy(), ref_runs[col].to_numpy()), (kw, col)
    # replicates differ from each other, and the noise level is part of the key
    est = ref_coef.pivot(index="replicate", columns="name", values="estimate")
    assert len(np.unique(est.to_numpy().round(12), axis=0)) == 8
    other, _, _ = run_cell(rig, cfg, case, 5.0, "ekf1", replicates=2)
    assert not np.allclose(other["estimate"].to_numpy(), ref_coef["estimate"].to_numpy()[:48])
    assert list(ref_runs["linearisations"]) == [1.0] * 8 and set(ref_runs["passes"]) == {1}


def test_simulate_seed_is_replicate_of_the_cell(tmp_path, mc):
    """``platcal simulate --seed 3`` writes replicate 3 of the study's cell (TET4, the config's
    sigma_a = 20 ug): the same record as the runner's SeedSequence draws, and identify gives the
    cell's replicate 3."""
    rig, cfg = mc
    conf = tmp_path / "c.yaml"
    conf.write_text(SHORT)
    rec = tmp_path / "rec.parquet"
    assert main(["simulate", "--config", str(conf), "--scheme", "TET4", "--seed", "3", "--out", str(rec)]) == 0
    c = load_config(cfg)
    scheme = c.scheme("TET4")
    t, phi, z = simulate(c, scheme, [replicate_seed(7, "TET4", 20.0, 3)])
    pd.testing.assert_frame_equal(pd.read_parquet(rec), to_frame(scheme, t, phi[0], z[0]), check_exact=True)
    # the default, without --seed, is replicate 0
    rec0 = tmp_path / "rec0.parquet"
    assert main(["simulate", "--config", str(conf), "--scheme", "TET4", "--out", str(rec0)]) == 0
    t0, phi0, z0 = simulate(c, scheme, [replicate_seed(7, "TET4", 20.0, 0)])
    pd.testing.assert_frame_equal(pd.read_parquet(rec0), to_frame(scheme, t0, phi0[0], z0[0]), check_exact=True)
    # identified, the record gives the cell's replicate 3 (records hold g and deg: rounding only)
    assert main(["identify", "--config", str(conf), "--data", str(rec), "--estimator", "ekf1",
                 "--out", str(tmp_path / "id")]) == 0
    got = pd.read_csv(tmp_path / "id" / "estimates.csv")["estimate"].to_numpy()
    coef, _, _ = run_cell(rig, cfg, rig.montecarlo.case(cfg, "TET4"), 20.0, "ekf1", replicates=5)
    per = {r: d["estimate"].to_numpy() for r, d in coef.groupby("replicate")}
    sig = coef[coef.replicate == 3]["sigma"].to_numpy()
    assert np.max(np.abs(got - per[3]) / sig) < 1e-4
    assert min(np.max(np.abs(got - per[r]) / sig) for r in (0, 1, 2, 4)) > 0.1
    summary = json.loads((tmp_path / "id" / "summary.json").read_text())
    assert summary["passes"] == 1


def test_simulate_int_seeds_are_the_cells_replicates(cfg):
    """``simulate(cfg, scheme, [r])`` with replicate numbers draws the SeedSequences of the cell
    (scheme, cfg.sigma_a_ug) under the root seed."""
    s = cfg.scheme("TET4")
    short = type(s)(name=s.name, positions=s.positions, dwell_s=0.4)
    a = simulate(cfg, short, [0, 5])[2]
    b = simulate(cfg, short, [replicate_seed(cfg.seed, "TET4", cfg.sigma_a_ug, r) for r in (0, 5)])[2]
    assert np.array_equal(a, b)
    assert not np.array_equal(a, simulate(cfg.with_noise(seed=cfg.seed + 1), short, [0, 5])[2])
