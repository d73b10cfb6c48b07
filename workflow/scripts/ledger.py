"""Snakemake wrapper: results/claims.{csv,md,html}, the ledger of every rig's claims."""
from pathlib import Path

import pandas as pd

from platcal.log import job_logger
from platcal.study.claims import ledger_for_people, ledger_note
from platcal.study.tables import write_table

sm = snakemake  # noqa: F821
rows = pd.concat([pd.read_csv(f) for f in sm.input], ignore_index=True)
write_table(rows, Path(sm.output[0]).with_suffix(""), "The claims ledger: every paper claim, computed from this study",
            ledger_note(rows), shown=ledger_for_people(rows))
job_logger(sm.log[0]).info(ledger_note(rows))
