"""Snakemake wrapper: results/report.md, the claims ledger and the index linking each rig's report."""
from platcal.log import job_logger
from platcal.study.report import write_index

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
write_index(sm.params.rigs, list(sm.input.reports), sm.output[0], ledger=sm.input.ledger,
            campaign=(list(sm.input.campaign) or [None])[0])
log.info("index of %d rig report(s) -> %s", len(sm.input.reports), sm.output[0])
