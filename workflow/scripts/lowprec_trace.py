"""Snakemake wrapper: the figures' traces of the lowprec_centrifuge study (replicate 0, default scenario)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from platcal.log import job_logger
from platcal.rigs.lowprec_centrifuge.montecarlo import study_trace
from platcal.rigs.lowprec_centrifuge.traces import write_trace

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
write_trace(study_trace(dict(sm.params.cfg)), sm.output[0])
log.info(f"traces -> {sm.output[0]}")
