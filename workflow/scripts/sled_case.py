"""Snakemake wrapper: one sled study case over the seeds (platcal.rigs.sled.study.run_case)."""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.rigs.sled.study import run_case  # noqa: E402

sm = snakemake  # noqa: F821
run_case(dict(sm.params.raw), sm.wildcards.case, int(sm.params.seeds), sm.output.metrics, sm.output.series,
         log_path=sm.log[0])
