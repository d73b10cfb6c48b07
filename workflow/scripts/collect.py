"""Snakemake wrapper: concatenate a rig's cells (one folder per estimator in each) into its
study-wide tidy tables."""
from platcal.study.collect import collect_job

sm = snakemake  # noqa: F821
files = {name: [f"{c}/{e}/{name}" for c in sm.input.cells for e in sm.params.estimators]
         for name in ("coef.parquet", "runs.parquet", "timing.json")}
collect_job(files["coef.parquet"], files["runs.parquet"], files["timing.json"], dict(sm.output), log_path=sm.log[0])
