"""Snakemake wrapper: table1, classical, random and GA schemes by criterion and Monte Carlo error."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.design_study import compare_job

sm = snakemake  # noqa: F821
compare_job(rig_config(sm.config, "centrifuge"), list(sm.input.schemes), Path(sm.output.summary).parent, log_path=sm.log[0])
