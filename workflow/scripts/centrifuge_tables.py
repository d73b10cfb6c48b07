"""Snakemake wrapper: the centrifuge's Table 2 (one run and Monte Carlo) and the summary."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.report import tables_job

sm = snakemake  # noqa: F821
tables_job(rig_config(sm.config, "centrifuge"), sm.input.coef, sm.input.runs, sm.input.timing,
           Path(sm.input.single[0]).parent, Path(sm.output.table2_single).parent, log_path=sm.log[0])
