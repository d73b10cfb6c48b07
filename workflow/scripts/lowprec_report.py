"""Snakemake wrapper: tables, figures and report.md of the lowprec_centrifuge study from its tidy tables."""
from pathlib import Path

from platcal.log import job_logger
from platcal.rigs.lowprec_centrifuge.report import write_study

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
write_study(dict(sm.params.cfg), sm.input.coef, sm.input.runs, sm.input.trace, Path(sm.output.report).parent)
log.info(f"report -> {sm.output.report}")
