"""Snakemake wrapper: compile a rig's numba kernels once per study, before its cells start
(platcal.study.montecarlo.warm_up; rule montecarlo_warmup)."""
import os

# one BLAS thread per process, as in the cells (the same specialisations are compiled)
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.rig import rig_config  # noqa: E402
from platcal.study.montecarlo import warm_up  # noqa: E402

sm = snakemake  # noqa: F821
warm_up(sm.wildcards.rig, rig_config(sm.config, sm.wildcards.rig), sm.output[0], threads=sm.threads,
        log_path=sm.log[0])
