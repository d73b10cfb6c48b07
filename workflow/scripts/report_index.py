"""Snakemake wrapper: results/report.md, the claims ledger and the index linking each rig's report,
closed by the "Where the time goes" table of the jobs' benchmark files (results/timing.*)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.study.report import write_index
from platcal.study.timing import write_timing

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
timing = write_timing(sm.params.benchmarks, Path(sm.output.timing[0]).with_suffix(""), rigs=sm.params.rigs)
write_index(sm.params.rigs, list(sm.input.reports), sm.output[0], ledger=sm.input.ledger,
            campaign=(list(sm.input.campaign) or [None])[0], timing=timing)
log.info("index of %d rig report(s), %d timing rows -> %s", len(sm.input.reports), len(timing), sm.output[0])
