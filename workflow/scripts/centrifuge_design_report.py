"""Snakemake wrapper: the design report (results/centrifuge/design/report.md)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.design_study import report_job

sm = snakemake  # noqa: F821
report_job(rig_config(sm.config, "centrifuge"), Path(sm.output[0]).parent, sm.output[0], log_path=sm.log[0])
