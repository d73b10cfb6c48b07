"""Snakemake wrapper: concatenate a rig's cells (one folder per estimator in each) into its
study-wide tidy tables."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from platcal.study.collect import collect_job
from platcal.study.montecarlo import cell_files

sm = snakemake  # noqa: F821
cells, estimators = sm.input.cells, sm.params.estimators
collect_job(cell_files(cells, estimators, "coef.parquet"), cell_files(cells, estimators, "runs.parquet"),
            cell_files(cells, estimators, "timing.json"), dict(sm.output), log_path=sm.log[0])
