"""Snakemake wrapper: one GA scheme design (results/design/<name>.yaml)."""
from platcal.design_study import design_scheme_job

sm = snakemake  # noqa: F821
design_scheme_job(sm.config, sm.wildcards.design, sm.output.scheme, log_path=sm.log[0])
