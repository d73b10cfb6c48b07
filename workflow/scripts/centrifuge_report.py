"""Snakemake wrapper: results/centrifuge/report.md."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

import pandas as pd

from platcal.log import job_logger
from platcal.rig import rig_config
from platcal.rigs.centrifuge.report import write_report
from platcal.rigs.centrifuge.study import check_study
from platcal.study.claims import read_ledger

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
out = Path(sm.output[0])
write_report(check_study(rig_config(sm.config, "centrifuge")), Path(sm.input.tables[0]).parent,
             Path(sm.input.figures[0]).parent, out, pd.read_csv(sm.input.timing), read_ledger(sm.input.claims))
log.info("report -> %s", out)
