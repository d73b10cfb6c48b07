"""The campaign planner (issue 23): validation, information across rigs, the search, the
hand-on of a posterior from one test to the next, and sequential = joint identification."""

import copy
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.errors import InputError
from platcal.estimation.information import marginal_information
from platcal.io import read_config
from platcal.rig import get_rig, rig_config
from platcal.rigs.centrifuge.ekf import EstimatorInput, first_instant
from platcal.rigs.centrifuge.estimators import run_estimator
from platcal.rigs.centrifuge.simulate import simulate as simulate_centrifuge
from platcal.rigs.multiposition.config import make_scheme
from platcal.scheme import check_scheme
from platcal.rigs.multiposition.filter import run_filter, simulate
from platcal.study import campaign as cp
from platcal.study import campaign_file as cf
from file_snapshot import snapshot
from workflow_copy import copy_workflow, needs_snakemake
from workflow_copy import snakemake as smk

MP = {"rig": "multiposition", "schemes": {"TET4": {"dwell_s": 10, "positions": [[0, 0, 0], [109.47, 0, 0],
                                                                              [109.47, 0, 120], [109.47, 0, 240]]}}}
CF = {"rig": "centrifuge", "schemes": {"short": {"dwell_s": 3, "positions": [[45, 0, 167], [350, 0, 325],
                                                                            [209, 0, 182], [134, 0, 141],
                                                                            [106, 0, 338], [142, 0, 269]]}}}


def tiny(**over) -> dict:
    """A small campaign: short dwells, loose targets (every coefficient's prior / 20), a small search."""
    raw = {"name": "tiny",
           "targets": {"DF": 0.5, "DI": 0.1, "DO": 0.1, "DS": 0.1, "DII": 0.01, "DSS": 0.01, "DIO": 0.01,
                       "DIS": 0.01, "DOS": 0.01, "k0": 500, "k1": 100, "k2": 2.5, "k3": 0.5, "kIP": 1, "theta": 30},
           "rigs": {"centrifuge": {"config": copy.deepcopy(CF), "cost_per_hour": 1000, "setup_hours": 8,
                                   "schemes": ["short"], "dwell_s": [3], "max_repeats": 2},
                    "multiposition": {"config": copy.deepcopy(MP), "cost_per_hour": 100, "setup_hours": 1,
                                      "schemes": ["TET4"], "dwell_s": [10], "max_repeats": 2}},
           "references": {"centrifuge_short": [{"rig": "centrifuge", "scheme": "short", "dwell_s": 3}]},
           "optimiser": {"population": 8, "generations": 3, "seed": 1},
           "montecarlo": {"replicates": 0}}
    raw.update(over)
    return raw


@pytest.fixture(scope="module")
def planned():
    camp = cp.load_campaign(tiny())
    return camp, cp.candidates(camp)


@pytest.mark.parametrize("edit, field", [
    (lambda r: r["targets"].pop("k2"), "targets"),
    (lambda r: r["targets"].update(DQ=1), "targets.DQ"),
    (lambda r: r["targets"].update(DF=-1), "targets.DF"),
    (lambda r: r["rigs"]["centrifuge"].update(schemes=["nope"]), "rigs.centrifuge.schemes[0]"),
    (lambda r: r["rigs"]["centrifuge"].update(cost=3), "rigs.centrifuge"),
    (lambda r: r["rigs"].update(sled={"config": {"rig": "sled"}, "schemes": ["x"]}), "rigs.sled"),
    (lambda r: r["references"].update(x=[{"rig": "lowprec", "scheme": "a", "dwell_s": 1}]), "references.x[0].rig"),
    (lambda r: r.update(platform={"truth": {"DF_q": 1}}), "platform.truth.DF_q"),
])
def test_bad_campaign_names_the_field(edit, field):
    raw = tiny()
    edit(raw)
    with pytest.raises(InputError) as exc:
        cp.load_campaign(raw)
    assert exc.value.field == field


def test_cli_bad_campaign_exits_2_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    raw = tiny()
    raw["targets"].pop("theta")
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw))
    before = snapshot(tmp_path)
    assert main(["plan", "--campaign", "c.yaml", "--out", "out"]) == 2
    err = capsys.readouterr().err
    assert "error: targets:" in err and "theta_py" in err
    assert snapshot(tmp_path) == before


def test_marginal_information_is_the_block_of_the_posterior():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(9, 6))
    F = A.T @ A
    prior = np.array([1.0, 2.0, 0.5, 1.0, 3.0, 1.0])
    keep = np.array([True, False, True, True, False, True])
    M = marginal_information(F, keep, prior)
    full = np.linalg.inv(F + np.diag(prior))[np.ix_(keep, keep)]
    assert np.allclose(np.linalg.inv(M + np.diag(prior[keep])), full, rtol=1e-10, atol=1e-12)


def test_hand_on_equals_the_joint_posterior():
    """Linear Gaussian: a test seeing states a only, its posterior handed on, gives the joint
    posterior (mean and covariance) of all states."""
    rng = np.random.default_rng(5)
    n, a = 5, np.array([0, 2, 3])
    L = rng.normal(size=(n, n))
    P0 = L @ L.T + np.eye(n)
    x0 = rng.normal(size=n)
    H = rng.normal(size=(4, a.size))
    z = rng.normal(size=4)
    Hf = np.zeros((4, n))
    Hf[:, a] = H
    S = Hf @ P0 @ Hf.T + np.eye(4)
    K = P0 @ Hf.T @ np.linalg.inv(S)
    xj, Pj = x0 + K @ (z - Hf @ x0), P0 - K @ S @ K.T
    Paa = P0[np.ix_(a, a)]
    Sa = H @ Paa @ H.T + np.eye(4)
    Ka = Paa @ H.T @ np.linalg.inv(Sa)
    xa, Pa = x0[a] + Ka @ (z - H @ x0[a]), Paa - Ka @ Sa @ Ka.T
    x, P = cp.hand_on(x0[None], P0[None], a, xa[None], Pa[None])
    assert np.allclose(x[0], xj, atol=1e-12) and np.allclose(P[0], Pj, atol=1e-12)


def test_an_unused_rig_is_skipped_without_changing_a_bit(planned):
    """posterior_information skips a rig no plan of the batch uses (a single-rig search): the
    plans' information is bit-identical to the same plans beside one that uses the rig."""
    camp, cands = planned
    m = len(cands.tests)
    mp_only = np.zeros(m, int)
    mp_only[cands.index("multiposition", "TET4", 10)] = 2
    both = mp_only.copy()
    both[cands.rigs[[b.rig for b in cands.rigs].index("centrifuge")].columns[0]] = 1
    alone = cp.posterior_information(cands, mp_only[None])
    beside = cp.posterior_information(cands, np.stack([mp_only, both]))
    assert np.array_equal(alone[0], beside[0])
    assert not np.array_equal(beside[1], beside[0])


def test_search_keeps_the_sigmas_its_evaluations_computed(planned):
    """The search judges each generation once and keeps its sigmas: every archived plan's worst
    and mean sigma/target equal planned_sigma of the deduplicated archive judged at once, bit for
    bit (a plan's row does not depend on the batch it was judged in), for both searches."""
    camp, cands = planned
    for rigs in (None, ("multiposition",)):
        res = cp.search(camp, cands, rigs)
        ratio = cp.planned_sigma(camp, cands, res.counts) / camp.target_sigma
        assert len(np.unique(res.counts, axis=0)) == len(res.counts) > 1
        assert np.array_equal(res.worst, ratio.max(axis=1)) and np.array_equal(res.mean, ratio.mean(axis=1))
        assert np.array_equal(res.cost, cp.plan_cost(cands, res.counts))


def test_check_numbers_do_not_depend_on_the_batch(planned):
    """The Monte Carlo check of 6 replicates in batches of 2, 4 (a short last block of the lanes
    kernels) and the default: the same NEES, RMS and sigmas bit for bit."""
    camp, cands = planned
    m = len(cands.tests)
    counts = np.zeros(m, int)
    counts[cands.index("multiposition", "TET4", 10)] = 1
    counts[cands.index("centrifuge", "short", 3)] = 1
    seq = cp.plan_sequence(camp, cands, counts)
    runs = [cp.check_plan(camp, cands, seq, 6, batch=b) for b in (2, 4, cp.CHECK_BATCH)]
    for c in runs[1:]:
        for f in ("nees", "achieved_rms", "filter_sigma"):
            assert np.array_equal(getattr(c, f), getattr(runs[0], f)), f


def test_information_adds_and_the_plan_meets_its_targets(planned):
    camp, cands = planned
    m = len(cands.tests)
    one, two = np.zeros(m, int), np.zeros(m, int)
    j = cands.index("multiposition", "TET4", 10)
    one[j], two[j] = 1, 2
    I1, I2 = cp.posterior_information(cands, np.stack([one, two]))
    eye = np.eye(cands.n_coef)
    # one rig's nuisance is marginalised once over all its tests, so two tests are not exactly
    # twice one; the platform part of the multiposition's information is close to additive
    assert np.allclose(I2 - eye, 2 * (I1 - eye), rtol=0.05, atol=1e-6 * np.abs(I1).max())
    res = cp.search(camp, cands)
    i = res.cheapest_meeting()
    assert i is not None and res.worst[i] <= 1.0
    assert res.cost[i] <= res.cost[res.worst <= 1.0].min()
    # the 1 g self-test alone cannot see the g-squared terms: it never meets every target
    mp = cp.search(camp, cands, ("multiposition",))
    assert mp.cheapest_meeting() is None
    sig = cp.planned_sigma(camp, cands, two)[0]
    unseen = [i for i, n in enumerate(camp.platform.names) if cf.term_of(n) in ("DII", "DSS", "DIO", "DIS", "DOS",
                                                                                "k2", "k3", "kIP")]
    seen = [i for i in range(len(sig)) if i not in unseen]
    assert np.allclose(sig[unseen], camp.prior_sigma[unseen])
    assert (sig[seen] < 0.5 * camp.prior_sigma[seen]).all()


def test_planned_sigma_is_the_centrifuge_covariance_only_run(planned):
    """With the centrifuge's own P0 as the platform prior, one test's planned sigma is its
    covariance-only EKF's sigma (the rig's observability analysis)."""
    camp, cands = planned
    rig = get_rig("centrifuge")
    study = rig.load_config(rig_config({"rigs": {"centrifuge": copy.deepcopy(CF)}}, "centrifuge"))
    from platcal.rigs.centrifuge.observability import direct_covariance, setup_from_study
    setup = setup_from_study(study, 3)
    P = direct_covariance(setup, study.schemes["short"].angles_deg)[0]
    camp2 = cp.Campaign(camp.name, camp.platform, setup.p0[:45].copy(), camp.target_sigma, camp.rigs,
                        camp.references, camp.optimiser, camp.montecarlo, camp.raw)
    cands2 = cp.candidates(camp2)
    counts = np.zeros(len(cands2.tests), int)
    counts[cands2.index("centrifuge", "short", 3)] = 1
    sig = cp.planned_sigma(camp2, cands2, counts)[0]
    assert np.allclose(sig, np.sqrt(np.diag(P))[:45], rtol=1e-4)


def test_sequential_multiposition_equals_one_filter_over_both_records():
    """Two records in sequence, the first's posterior handed on as the second's prior, give the
    estimate and covariance of one filter over both records (to 0.01 sigma)."""
    cfg = get_rig("multiposition").load_config(copy.deepcopy(MP))
    s1 = make_scheme("A", [[0, 0, 0], [109.47, 0, 0]], 10, cfg.beta_max_deg)
    s2 = make_scheme("B", [[109.47, 0, 120], [109.47, 0, 240], [90, 0, 90]], 10, cfg.beta_max_deg)
    seeds = [np.random.SeedSequence(11, spawn_key=(r,)) for r in range(3)]
    t, _, z1 = simulate(cfg, s1, seeds)
    _, _, z2 = simulate(cfg, s2, [np.random.SeedSequence(12, spawn_key=(r,)) for r in range(3)])
    x1, P1 = run_filter(cfg, s1.angles_deg, t, z1, passes=1)[:2]
    xs, Ps = run_filter(cfg, s2.angles_deg, t, z2, passes=1, prior_x=x1, prior_P=P1)[:2]
    both = np.concatenate([s1.angles_deg, s2.angles_deg])
    xj, Pj = run_filter(cfg, both, t, np.concatenate([z1, z2], axis=1), passes=1)[:2]
    sig = np.sqrt(np.diagonal(Pj, axis1=1, axis2=2))
    assert np.all(np.abs(xs - xj) <= 0.01 * sig)
    assert np.all(np.abs(np.sqrt(np.diagonal(Ps, axis1=1, axis2=2)) - sig) <= 0.01 * sig)


def test_sequential_centrifuge_equals_one_filter_over_both_records():
    """The centrifuge's EKF: two records in sequence, the posterior handed on (FilterSettings
    prior_x / prior_P), against one EKF over both records' positions (to 0.01 sigma)."""
    study = get_rig("centrifuge").load_config(rig_config({"rigs": {"centrifuge": copy.deepcopy(CF)}}, "centrifuge"))
    pos = CF["schemes"]["short"]["positions"]
    s1 = check_scheme("A", {"dwell_s": 3, "positions": pos[:3]})
    s2 = check_scheme("B", {"dwell_s": 3, "positions": pos[3:]})
    both = check_scheme("AB", {"dwell_s": 3, "positions": pos})
    fs = replace(study.filter, history_every_s=None)
    i0 = first_instant(fs.update_at_reset)

    def record(scheme, key):
        seeds = [np.random.SeedSequence(21, spawn_key=(key, r)) for r in range(2)]
        sim = simulate_centrifuge(study.truth, scheme, study.centrifuge.scheme_params(scheme), study.noise, seeds,
                                  sample_s=study.sample_s, keep_every=study.keep_every)
        return [sim.A[:, k, i0:] for k in range(scheme.n_positions)], [sim.t[i0:]] * scheme.n_positions

    (z1, t1), (z2, t2) = record(s1, 1), record(s2, 2)
    nc = fs.coef_index.size
    e1 = run_estimator(EstimatorInput(z1, t1, s1.angles_deg, study.centrifuge.scheme_params(s1)), fs)
    fs2 = replace(fs, prior_x=e1.x[:, :nc], prior_P=e1.P[:, :nc, :nc])
    es = run_estimator(EstimatorInput(z2, t2, s2.angles_deg, study.centrifuge.scheme_params(s2)), fs2)
    ej = run_estimator(EstimatorInput(z1 + z2, t1 + t2, both.angles_deg, study.centrifuge.scheme_params(both)), fs)
    sig = np.sqrt(np.diagonal(ej.P[:, :nc, :nc], axis1=1, axis2=2))
    assert np.all(np.abs(es.x[:, :nc] - ej.x[:, :nc]) <= 0.01 * sig)
    assert np.all(np.abs(np.sqrt(np.diagonal(es.P[:, :nc, :nc], axis1=1, axis2=2)) - sig) <= 0.01 * sig)


def test_rms_interval_covers_the_sigma_at_its_level():
    """The chi-square interval of the true sigma from R draws' RMS covers it in about 95 % of trials."""
    rng = np.random.default_rng(7)
    sigma, r = 2.0, 50
    rms = np.sqrt((rng.normal(0.0, sigma, (4000, r)) ** 2).mean(axis=1))
    lo, hi = cp.rms_interval(rms, r)
    assert abs(((lo <= sigma) & (sigma <= hi)).mean() - 0.95) < 0.015
    assert 0.8 < lo[0] / rms[0] < 0.85 and 1.2 < hi[0] / rms[0] < 1.3  # the width quoted in the docstring


def test_default_campaign_is_valid():
    camp = cf.load_campaign(cf.campaign_content("config/campaign.yaml"))
    assert {r.name for r in camp.rigs} == {"centrifuge", "multiposition"}
    assert (camp.target_sigma < camp.prior_sigma).all()
    assert read_config("config/campaign.yaml")["montecarlo"]["replicates"] >= 50


def test_plan_command_writes_every_output(tmp_path, capsys):
    """``platcal plan`` end to end on the tiny campaign, 3 replicates, alternatives simulated too."""
    raw = tiny(montecarlo={"replicates": 3, "alternatives": True})
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw))
    out = tmp_path / "plan"
    assert main(["plan", "--campaign", str(tmp_path / "c.yaml"), "--out", str(out)]) == 0
    plan, coefs = pd.read_csv(out / "plan.csv"), pd.read_csv(out / "coefficients.csv")
    alts, checks = pd.read_csv(out / "alternatives.csv"), pd.read_csv(out / "check.csv")
    assert len(coefs) == 45 and coefs["achieved_rms"].notna().all()
    assert (coefs["meets"] == (coefs["achieved_rms"] <= coefs["target_sigma"])).all()
    lo, hi = coefs["achieved_rms_ci_low"], coefs["achieved_rms_ci_high"]
    assert ((lo < coefs["achieved_rms"]) & (coefs["achieved_rms"] < hi)).all()
    assert (coefs["planned_in_ci"] == ((lo <= coefs["planned_sigma"]) & (coefs["planned_sigma"] <= hi))).all()
    assert (coefs["planned_sigma"] <= coefs["target_sigma"]).all()
    assert plan["cost"].sum() == pytest.approx(alts.loc[alts["name"] == "plan", "cost"].item())
    assert set(checks["name"]) == set(alts["name"])  # every alternative has tests here
    assert checks["replicates"].eq(3).all()
    for f in ("front.png", "progress.png", "report.md", "front.csv", "progress.csv"):
        assert (out / f).stat().st_size > 0
    assert "Monte Carlo of plan" in capsys.readouterr().out


@needs_snakemake
def test_campaign_plan_waits_for_the_rigs_kernels(tmp_path):
    """The default study's campaign_plan waits for what the Monte Carlo cells of its rigs wait
    for (the multi-position kernels job), so that its check loads their numba kernels rather
    than compiling them beside that job."""
    d = copy_workflow(tmp_path / "wf")
    r = smk(d, "-n", "--cores", "1", "results/campaign/plan.csv", timeout=240)
    assert r.returncode == 0, r.stderr[-3000:]
    block = r.stdout.split("rule campaign_plan:")[1].split("\n\n")[0]
    inputs = next(ln for ln in block.splitlines() if ln.strip().startswith("input:"))
    assert "results/multiposition/kernels.json" in inputs
