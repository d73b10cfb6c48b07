"""Snakemake wrapper: concatenate a rig's cells into its study-wide tidy tables."""
from platcal.study.collect import collect_job

sm = snakemake  # noqa: F821
collect_job(sm.input.coef, sm.input.runs, sm.input.timing, dict(sm.output), log_path=sm.log[0])
