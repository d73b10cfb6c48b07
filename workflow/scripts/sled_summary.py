"""Snakemake wrapper: sled Table-1 analogue, §11 checks, figures and report.md (study.summarise)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.rigs.sled.study import summarise
from platcal.study.claims import read_ledger

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0], "platcal.sled")
cfg = dict(sm.params.cfg)
cases = list(cfg["study"]["cases"])
summarise(sm.input.runs, dict(zip(cases, sm.input.series)), sm.input.ranks, Path(sm.output.report).parent, cfg,
          read_ledger(sm.input.claims))
log.info(f"sled summary of {len(cases)} cases -> {sm.output.report}")
