"""Snakemake wrapper: table1, classical, random and GA schemes by criterion and Monte Carlo error."""
from pathlib import Path

from platcal.design_study import compare_job

sm = snakemake  # noqa: F821
compare_job(sm.config, list(sm.input.schemes), Path(sm.output.summary).parent, log_path=sm.log[0])
