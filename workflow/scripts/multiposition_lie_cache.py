"""Build (or load) the cached symbolic Lie-derivative Jacobians once, before the jobs that use them."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import json, time  # noqa: E401

from platcal.io import atomic_write_text
from platcal.log import job_logger
from platcal.rigs.multiposition.lie import observability_function
from platcal.rigs.multiposition.study import load

log = job_logger(snakemake.log[0])  # noqa: F821
cfg, t0 = load(snakemake.params.config), time.perf_counter()  # noqa: F821
for ext, order in ((0, cfg.lie_order), (1, 1), (2, 1)):
    observability_function(ext, order)
    log.info(f"Lie Jacobian ext {ext} order {order} ready, {time.perf_counter() - t0:.1f} s")
atomic_write_text(snakemake.output[0], json.dumps({"seconds": time.perf_counter() - t0}) + "\n")  # noqa: F821
