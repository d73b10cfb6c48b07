"""A rig is a plug-in (issue 19 item 5): a minimal rig written into a temporary package, found
through the ``platcal.rigs`` entry points, runs end to end through the generic rules (Monte
Carlo cells, tidy tables, generic report, claims ledger, index) with no edit to the project."""

import os

import pandas as pd
import pytest
import yaml
from workflow_copy import ROOT, copy_workflow, snakemake

TOY = '''
"""A toy rig: one constant measured n times with noise; the estimate is the sample mean."""
from types import SimpleNamespace

import numpy as np
import pandas as pd

from platcal.rig import NoiseAxis, ReplicateBatch, Rig, RunSettings


def catalogue():
    return pd.DataFrame({"name": ["c"], "group": ["constant"], "unit": ["V"], "truth": [np.nan]})


class Hooks:
    noise = NoiseAxis("sigma_v", "V", "sigma (V)")

    def check(self, raw):
        return {"truth": 3.0, "n": 50, "seed": 1, **raw}

    def cases(self, cfg):
        return ["const"]

    def noise_levels(self, cfg):
        return list(cfg["study"]["sigma_v"])

    def estimators(self, cfg):
        return ["mean"]

    def settings(self, cfg):
        return RunSettings(seed=cfg["seed"], replicates=cfg["study"]["replicates"], batch=4, backend="numba",
                           threads=1)

    def case(self, cfg, name, case_file=None):
        return SimpleNamespace(name=name)

    def case_file(self, cfg, name):
        return None

    def cell_params(self, cfg, case, noise, estimator):
        return {"truth": cfg["truth"], "n": cfg["n"], "seed": cfg["seed"]}

    def run_batch(self, cfg, case, noise, estimator, seeds):
        truth = np.array([[cfg["truth"] + np.random.default_rng(s).normal()] for s in seeds])  # per replicate
        z = np.stack([np.random.default_rng(s.spawn(1)[0]).normal(0, noise, cfg["n"]) for s in seeds])
        est = truth + z.mean(axis=1, keepdims=True)
        sig = np.full_like(est, noise / np.sqrt(cfg["n"]))
        nees = (((est - truth) / sig) ** 2).ravel()
        B = len(seeds)
        return ReplicateBatch(quantities=catalogue(), estimate=est, sigma=sig, nees=nees, nees_dof=1,
                              mean_nis=np.ones(B), failed_updates=np.zeros(B, int), passes=1, truth=truth)


RIG = Rig(name="toy", title="one constant from noisy samples", spec="toy.md", load_config=lambda raw: raw,
          commands={}, catalogue=catalogue, montecarlo=Hooks())
'''


@pytest.mark.slow
def test_a_rig_from_another_package_runs_through_the_generic_rules(tmp_path):
    pkg = tmp_path / "site"
    (pkg / "toyrig").mkdir(parents=True)
    (pkg / "toyrig" / "__init__.py").write_text(TOY)
    dist = pkg / "toyrig-0.1.dist-info"  # an installed distribution declaring the entry point
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: toyrig\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[platcal.rigs]\ntoy = toyrig\n")
    wf = copy_workflow(tmp_path / "wf")
    index = {"rigs": {"centrifuge": None, "multiposition": None, "sled": None, "lowprec_centrifuge": None,
                      "toy": {"truth": 3.0, "study": {"sigma_v": [0.1, 1.0], "replicates": 6}}}}
    (wf / "toy.yaml").write_text(yaml.safe_dump(index))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(pkg), os.environ.get("PYTHONPATH", "")]))
    p = snakemake(wf, "--cores", "2", "--configfile", "toy.yaml", env=env, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    res = wf / "results"
    coef = pd.read_parquet(res / "toy" / "montecarlo" / "coef.parquet")
    assert len(coef) == 12 and set(coef["noise"]) == {0.1, 1.0}
    assert coef["truth"].nunique() == 12  # the truth drawn per replicate reaches the tidy table
    assert (coef["error"].abs() < 5 * coef["sigma"]).all()
    assert "# toy: one constant from noisy samples" in (res / "toy" / "report.md").read_text()
    assert (res / "toy" / "figures" / "nees.png").stat().st_size > 5_000
    assert "toy" in (res / "report.md").read_text()
    assert (res / "claims.csv").exists()
    # every job's benchmark file is summed in the index's "Where the time goes" (one job per cell)
    timing = pd.read_csv(res / "timing.csv").set_index(["rig", "rule"])
    cells = len(list((res / "toy" / "runs").glob("*/*/*/coef.parquet")))
    assert cells == 2 and timing.loc[("toy", "montecarlo_cell"), "jobs"] == cells
    assert timing.loc[("toy", "montecarlo_cell"), "wall_s"] > 0
    assert {"collect", "generic_report", "claims"} <= set(timing.loc["toy"].index)
    assert "## Where the time goes" in (res / "report.md").read_text()
    # nothing of the project names the toy rig
    assert "toy" not in (ROOT / "Snakefile").read_text()
    assert not any("toy" in f.read_text() for f in (ROOT / "workflow" / "rules").glob("*.smk"))
