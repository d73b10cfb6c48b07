"""Snakemake wrapper: GA schemes for N positions, criterion and Monte Carlo error against N."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.design_study import npos_job

sm = snakemake  # noqa: F821
npos_job(rig_config(sm.config, "centrifuge"), list(sm.input.schemes), Path(sm.output.table).parent, log_path=sm.log[0])
