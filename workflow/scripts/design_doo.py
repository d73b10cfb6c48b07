"""Snakemake wrapper: D_OO aliasing (eq. 22) and the two-g-level 51-state filter."""
from pathlib import Path

from platcal.design_study import doo_job

sm = snakemake  # noqa: F821
doo_job(sm.config, sm.input.scheme, Path(sm.output.covariance).parent, log_path=sm.log[0])
