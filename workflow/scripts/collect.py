"""Snakemake wrapper: concatenate a rig's cells into its study-wide tidy tables."""
from platcal.io import atomic_to_csv, atomic_to_parquet
from platcal.log import job_logger
from platcal.study.collect import collect

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
log.info("collecting %d cells of %s", len(sm.input.coef), sm.wildcards.rig)
coef, runs, timing = collect(sm.input.coef, sm.input.runs, sm.input.timing)
atomic_to_parquet(coef, sm.output.coef)
atomic_to_parquet(runs, sm.output.runs)
atomic_to_csv(timing, sm.output.timing)
log.info("done: %d rows, %d runs", len(coef), len(runs))
