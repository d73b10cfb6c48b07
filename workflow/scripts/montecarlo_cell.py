"""Snakemake wrapper: one Monte Carlo cell (platcal.montecarlo.cell_job)."""
import os

# one BLAS thread per process: the parallelism is numba's prange or joblib's workers
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from pathlib import Path  # noqa: E402

from platcal.montecarlo import cell_job  # noqa: E402

sm = snakemake  # noqa: F821
cell_job(sm.config, sm.wildcards.scheme, sm.params.cell["sigma_a_ug"], sm.wildcards.estimator,
         Path(sm.output.coef).parent, threads=sm.threads, log_path=sm.log[0],
         scheme_file=sm.input.scheme or None)
