"""Snakemake wrapper: the design report (results/design/report.md)."""
from pathlib import Path

from platcal.design_study import report_job

sm = snakemake  # noqa: F821
report_job(sm.config, Path(sm.output[0]).parent, sm.output[0], log_path=sm.log[0])
