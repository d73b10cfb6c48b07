"""Snakemake wrapper: tables, figures and report.md of the lowprec_centrifuge study."""
from pathlib import Path

from platcal.log import job_logger
from platcal.rig import get_rig
from platcal.study.claims import evaluate_rig
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.report import write_study
from platcal.rigs.lowprec_centrifuge.study import scenarios

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
study = load_config(dict(sm.params.config))
dirs = {n: Path(p).parent for n, p in zip(sm.params.names, sm.input.cross)}
out = Path(sm.output.report).parent
claims = evaluate_rig(get_rig("lowprec_centrifuge"), out, study.raw)  # the ledger's rows open the report
write_study(dirs, scenarios(study), Path(sm.input.trace), out, study.study["seeds"], claims)
log.info(f"report of {len(dirs)} scenarios -> {sm.output.report}")
