"""Snakemake wrapper: one Monte Carlo cell (case, noise level; every estimator) of any rig
(platcal.study.montecarlo.cell_job)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import os

# one BLAS thread per process: the parallelism is numba's prange or joblib's workers
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.rig import rig_config  # noqa: E402
from platcal.study.montecarlo import cell_job  # noqa: E402

sm = snakemake  # noqa: F821
w = sm.wildcards
cell_job(w.rig, rig_config(sm.config, w.rig), w.scheme, sm.params.level, list(sm.params.cell), sm.output[0],
         threads=sm.threads, log_path=sm.log[0], case_file=sm.input.case or None)
