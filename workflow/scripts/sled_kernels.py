"""Snakemake wrapper: compile (or load from numba's cache) the sled's kernels once, before its series and Monte Carlo cells (platcal.rigs.sled.montecarlo.warm_kernels)."""
import json
import os
import time

# one BLAS thread, as the cells that wait for it
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.io import atomic_write_text  # noqa: E402
from platcal.log import job_logger  # noqa: E402
from platcal.rig import rig_config  # noqa: E402
from platcal.rigs.sled.montecarlo import check, warm_kernels  # noqa: E402

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
t0 = time.perf_counter()
warm_kernels(check(rig_config(sm.config, "sled")))
log.info(f"numba kernels ready, {time.perf_counter() - t0:.1f} s")
atomic_write_text(sm.output[0], json.dumps({"code": sm.params.code}) + "\n")
