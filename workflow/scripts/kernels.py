"""Snakemake wrapper: compile (or load from numba's cache) a rig's kernels once, before the jobs that run its estimators (the rig's Monte Carlo hook ``warm_kernels``)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import json
import os
import time

# one BLAS thread, as the cells that wait for it
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.io import atomic_write_text  # noqa: E402
from platcal.log import job_logger  # noqa: E402
from platcal.rig import get_rig, rig_config  # noqa: E402

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
hooks = get_rig(sm.wildcards.rig).montecarlo
t0 = time.perf_counter()
hooks.warm_kernels(hooks.check(rig_config(sm.config, sm.wildcards.rig)))
log.info(f"{sm.wildcards.rig}: numba kernels ready, {time.perf_counter() - t0:.1f} s")
atomic_write_text(sm.output[0], json.dumps({"code": sm.params.code}) + "\n")
