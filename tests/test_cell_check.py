"""Issue 22 item 4: a Monte Carlo cell job checks what its own cell uses, not every cell of the
study (the workflow's master checks the whole config before any job, workflow/rules/common.smk:
``MC_CONFIG``), and still refuses a bad config of its cell before any work: the field named, exit
status 2, nothing written. The jobs are the real workflow scripts (``montecarlo_cell.py``,
``centrifuge_compare_cell.py``) run as Snakemake runs a ``script:``, their own Python process with
a ``snakemake`` object in its globals, as in tests/test_job_faults.py."""

import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from platcal.errors import InputError
from platcal.io import read_config
from platcal.rig import get_rig, rig_config
from platcal.rigs.centrifuge import study as centrifuge_study

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = ROOT / "workflow" / "scripts"


def _default_centrifuge() -> dict:
    return rig_config(read_config(str(ROOT / "config" / "config.yaml"), "config"), "centrifuge")


def _counting(monkeypatch) -> list:
    calls = []
    original = centrifuge_study.study_for_cell

    def counted(cfg, level, name):
        calls.append((float(level), name))
        return original(cfg, level, name)

    monkeypatch.setattr(centrifuge_study, "study_for_cell", counted)
    return calls


def test_a_centrifuge_cell_checks_its_own_filter_only_and_gets_the_same_config(monkeypatch):
    """The whole check runs a filter check for every (level, estimator) of the sweep and the
    comparison (24 in the default study); a cell's check runs its own one, and both return the
    same config with its defaults."""
    hooks = get_rig("centrifuge").montecarlo
    raw = _default_centrifuge()
    calls = _counting(monkeypatch)
    whole = hooks.check(copy.deepcopy(raw))
    n_whole = len(calls)
    st = whole["study"]
    assert n_whole == len(st["sigma_a_ug"]) * len(st["estimators"]) + len(st["compare"]["sigma_a_ug"]) * len(
        st["compare"]["estimators"]) > 1
    del calls[:]
    cell = hooks.check_cell(copy.deepcopy(raw), "classical", 10.0, "ekf1")
    assert calls == [(10.0, "ekf1")]
    assert cell == whole
    del calls[:]
    centrifuge_study.check_study(copy.deepcopy(raw), cells=[(50.0, "ml")])  # a comparison cell
    assert calls == [(50.0, "ml")]


def test_a_cell_check_refuses_an_estimator_the_study_does_not_define():
    with pytest.raises(InputError) as e:
        get_rig("centrifuge").montecarlo.check_cell(_default_centrifuge(), "classical", 10.0, "nope")
    assert e.value.field == "study.estimators"


# Snakemake's preamble, reduced to what the scripts read, then the script, as its own process
RUN = """
import runpy, sys
from types import SimpleNamespace
script, config, out, log, estimators = sys.argv[1:]
estimators = estimators.split(",")
w = SimpleNamespace(rig="centrifuge", scheme="classical", noise="10", estimator=estimators[0])
class Output(list):  # Snakemake's outputs: by position and by name
    coef = out
sm = SimpleNamespace(config={"rigs": {"centrifuge": config}}, wildcards=w, threads=1,
                     params=SimpleNamespace(level=10.0, cell={e: {} for e in estimators}), output=Output([out]), log=[log],
                     input=SimpleNamespace(case=[]))
runpy.run_path(script, init_globals={"snakemake": sm}, run_name="__main__")
"""


@pytest.mark.parametrize("script", ["montecarlo_cell.py", "centrifuge_compare_cell.py"])
def test_a_cell_job_refuses_a_bad_filter_of_its_cell_with_the_field_named(script, tmp_path):
    """A filter its cell cannot run (no attitude variance at the resets: only a cell's filter check
    sees it, not the schema) ends the job before any replicate: exit 2, the field named, no
    traceback, nothing written."""
    raw = _default_centrifuge()
    raw.setdefault("noise", {})["sigma_set_arcsec"] = 0
    config = tmp_path / "centrifuge.yaml"
    config.write_text(json.dumps(raw))  # JSON is YAML
    out = tmp_path / "results" / "cell" / "coef.parquet"
    log = tmp_path / "logs" / "cell.log"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "NUMBA_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-c", RUN, str(SCRIPTS / script), str(config), str(out), str(log), "ekf1"],
                       capture_output=True, text=True, env=env, timeout=120, cwd=ROOT)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and "error: filter.sigma_set_arcsec" in p.stderr, p.stderr
    assert "replicates" not in p.stderr, p.stderr  # refused before the job announced its run
    assert not out.parent.exists()


def test_a_monte_carlo_cell_refuses_before_its_first_estimator_runs(tmp_path):
    """A cell runs every estimator of its (case, level) in one job: an estimator the study does not
    define, named after a good one, refuses the job before the good one runs (exit 2, nothing
    written)."""
    config = tmp_path / "centrifuge.yaml"
    config.write_text(json.dumps(_default_centrifuge()))
    out = tmp_path / "results" / "cell"
    log = tmp_path / "logs" / "cell.log"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "NUMBA_NUM_THREADS": "1"}
    p = subprocess.run([sys.executable, "-c", RUN, str(SCRIPTS / "montecarlo_cell.py"), str(config), str(out),
                        str(log), "ekf1,nope"], capture_output=True, text=True, env=env, timeout=120, cwd=ROOT)
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and "study.estimators" in p.stderr, p.stderr
    assert "replicates" not in p.stderr, p.stderr
    assert not out.parent.exists()
