"""Snakemake wrapper: GA schemes for N positions, criterion and Monte Carlo error against N."""
from pathlib import Path

from platcal.design_study import npos_job

sm = snakemake  # noqa: F821
npos_job(sm.config, list(sm.input.schemes), Path(sm.output.table).parent, log_path=sm.log[0])
