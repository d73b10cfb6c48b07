"""Snakemake wrapper: D_OO aliasing (eq. 22) and the two-g-level 51-state filter."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.design_study import doo_job

sm = snakemake  # noqa: F821
doo_job(rig_config(sm.config, "centrifuge"), sm.input.scheme, Path(sm.output.covariance).parent, log_path=sm.log[0])
