"""Snakemake wrapper: results/report.md."""
from pathlib import Path

import pandas as pd

from platcal.montecarlo import check_study, job_logger
from platcal.report import write_report

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0])
out = Path(sm.output[0])
write_report(check_study(sm.config), Path(sm.input.tables[0]).parent, Path(sm.input.figures[0]).parent, out,
             pd.read_csv(sm.input.timing))
log.info("report -> %s", out)
