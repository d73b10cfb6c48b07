"""One EKF run gives the estimates of its first passes on the way (``run_ekf(..., on_pass=...)``,
issue 22 item 4): the Estimate handed over after pass p equals, field by field and bit for bit, a
run of p passes; and the comparison's level job takes the 1-pass EKF from the 2-pass run instead
of filtering again (:func:`platcal.rigs.centrifuge.identify.pass_prefixes`)."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from platcal.rigs.centrifuge import compare_cells
from platcal.rigs.centrifuge.base import Centrifuge
from platcal.rigs.centrifuge.catalogue import full_truth
from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf, run_iekf
from platcal.rigs.centrifuge.estimators import run_estimator
from platcal.rigs.centrifuge.identify import pass_prefixes, same_but_passes
from platcal.rigs.centrifuge.simulate import Noise, simulate
from platcal.scheme import TABLE1_POSITIONS, check_scheme

from test_ekf_compare import cfg

CEN = Centrifuge()
FIELDS = ("x", "P", "history_t", "history_x", "history_sigma", "pass_x", "pass_P", "mean_nis",
          "failed_updates", "innovations")


@pytest.fixture(scope="module")
def data():
    scheme = check_scheme("t", {"dwell_s": 2.0, "positions": [list(p) for p in TABLE1_POSITIONS]})
    params = CEN.scheme_params(scheme)
    seeds = [np.random.SeedSequence([41, i]) for i in range(5)]
    sim = simulate(full_truth(), scheme, params, Noise(), seeds, keep_every=4)
    return EstimatorInput([sim.A[:, k, 1:] for k in range(scheme.n_positions)], [sim.t[1:]] * scheme.n_positions,
                          scheme.angles_deg, params)


@pytest.mark.parametrize("kind", ["ekf", "ekf-warmup", "iekf"])
@pytest.mark.parametrize("lanes", [False, True])
def test_each_pass_on_the_way_is_the_run_of_that_many_passes(data, kind, lanes):
    s = FilterSettings(passes=3, history_every_s=0.5, innovations=True, lanes=lanes)
    if kind == "iekf":
        run = lambda settings, **kw: run_iekf(data, settings, iterations=2, **kw)  # noqa: E731
    else:
        warm = {"warmup_s": 0.5} if kind == "ekf-warmup" else {}
        run = lambda settings, **kw: run_ekf(data, settings, **warm, **kw)  # noqa: E731
    seen = {}
    whole = run(s, on_pass=lambda p, est: seen.setdefault(p, est))
    assert sorted(seen) == [1, 2]   # after each pass but the last
    for p, est in [*seen.items(), (3, whole)]:
        alone = run(replace(s, passes=p))
        for name in FIELDS:
            a, b = getattr(est, name), getattr(alone, name)
            assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True), (p, name)
    # the snapshots are copies: the later passes did not write into them
    assert not np.array_equal(seen[1].x, whole.x)


def test_the_estimator_registry_passes_on_pass_to_kinds_that_take_it(data):
    with pytest.raises(ValueError, match="ukf"):
        run_estimator(data, FilterSettings(passes=2, estimator="ukf"), on_pass=lambda p, est: None)


def test_which_runs_give_which_on_the_way():
    f = FilterSettings(history_every_s=None)
    filters = {"ekf1": f, "ekf2": replace(f, passes=2), "ekf3": replace(f, passes=3), "ekf3b": replace(f, passes=3),
               "slow": replace(f, period_s=0.04), "w": replace(f, estimator_options=(("warmup_s", 1.0),)),
               "iekf": replace(f, estimator="iekf", estimator_options=(("iterations", 2),)),
               "iekf2": replace(f, estimator="iekf", estimator_options=(("iterations", 2),), passes=2),
               "ukf": replace(f, estimator="ukf"), "ukf2": replace(f, estimator="ukf", passes=2),
               "p0": replace(f, p0_sigma=2 * f.p0_sigma)}
    assert pass_prefixes(filters) == {"ekf1": ("ekf3", 1), "ekf2": ("ekf3", 2), "iekf": ("iekf2", 1)}
    assert same_but_passes(f, replace(f, passes=4)) and not same_but_passes(f, filters["p0"])


def test_the_level_job_filters_the_shorter_run_once(tmp_path, monkeypatch):
    """ekf1's rows come from ekf2's run (their equality with ekf1's cell run alone is
    test_ekf_compare's bit-for-bit test): one filter run per chunk fewer, and ekf1's cost is
    the run's up to its pass, below ekf2's."""
    calls = []
    real = compare_cells.identify_shared

    def counted(study, *args, **kw):
        calls.append(study.filter.passes)
        return real(study, *args, **kw)

    monkeypatch.setattr(compare_cells, "identify_shared", counted)
    c = cfg(estimators={"ekf1": {"passes": 1}, "ekf2": {"passes": 2}}, sigma_a_ug=[10], replicates=5)
    compare_cells.compare_level_job(c, 10.0, tmp_path / "cell")
    batch = c["study"]["batch"]
    assert calls == [2] * -(-5 // batch)
    runs = pd.read_parquet(tmp_path / "cell" / "runs.parquet")
    cpu = runs.groupby("estimator")["cpu_s"].first()
    assert 0 < cpu["ekf1"] < cpu["ekf2"]
