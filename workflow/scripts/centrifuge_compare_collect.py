"""Snakemake wrapper: the estimator comparison's cells into results/centrifuge/compare/."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from platcal.study.collect import collect_job

sm = snakemake  # noqa: F821
collect_job(sm.input.coef, sm.input.runs, sm.input.timing, dict(sm.output), log_path=sm.log[0])
