"""Snakemake wrapper: tables, figures and report.md of the lowprec_centrifuge study from its tidy tables."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.report import write_study
from platcal.study.claims import evaluate_rig

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
cfg = dict(sm.params.cfg)
out = Path(sm.output.report).parent
claims = evaluate_rig(get_rig("lowprec_centrifuge"), out, cfg)  # the ledger's rows open the report
write_study(cfg, sm.input.coef, sm.input.runs, sm.input.trace, out, claims)
log.info(f"report -> {sm.output.report}")
