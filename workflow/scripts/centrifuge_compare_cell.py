"""Snakemake wrapper: one noise level of the centrifuge's estimator comparison, every estimator of the level."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import os

# one BLAS thread per process: the parallelism is numba's or Snakemake's jobs
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from pathlib import Path  # noqa: E402

from platcal.rig import rig_config  # noqa: E402
from platcal.rigs.centrifuge.compare_cells import compare_level_job  # noqa: E402

sm = snakemake  # noqa: F821
compare_level_job(rig_config(sm.config, "centrifuge"), sm.params.level, Path(sm.output.coef).parent,
                  threads=sm.threads, log_path=sm.log[0])
