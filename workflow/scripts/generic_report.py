"""Snakemake wrapper: the report of a rig without rules of its own (platcal.study.generic_report)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.study.generic_report import write_generic_report

sm = snakemake  # noqa: F821
write_generic_report(sm.wildcards.generic_rig, sm.input.coef, sm.input.runs, Path(sm.output[0]).parent)
job_logger(sm.log[0]).info("report -> %s", sm.output[0])
