"""Snakemake wrapper: the estimator comparison's tables and figures."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.compare_figures import compare_job

sm = snakemake  # noqa: F821
compare_job(rig_config(sm.config, "centrifuge"), sm.input.coef, sm.input.runs,
            {"tables": Path(sm.output.tables[0]).parent, "cost": sm.output.cost, "nees": sm.output.nees},
            log_path=sm.log[0])
