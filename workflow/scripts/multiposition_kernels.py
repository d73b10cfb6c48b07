"""Compile (or load from numba's cache) the rig's kernels once, before the Monte Carlo cells and the covariance jobs."""
import json, time  # noqa: E401

from platcal.io import atomic_write_text
from platcal.log import job_logger
from platcal.rigs.multiposition.study import load, warm_kernels

log = job_logger(snakemake.log[0])  # noqa: F821
cfg, t0 = load(snakemake.params.config), time.perf_counter()  # noqa: F821
warm_kernels(cfg)
log.info(f"numba kernels ready, {time.perf_counter() - t0:.1f} s")
atomic_write_text(snakemake.output[0], json.dumps({"code": snakemake.params.code}) + "\n")  # noqa: F821
