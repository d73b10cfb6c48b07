"""Snakemake wrapper: results/claims.{csv,md,html}, the ledger of every rig's claims, and
results/claims_front.html, its short form on the HTML report's front page."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

import pandas as pd

from platcal.io import atomic_write_text
from platcal.log import job_logger
from platcal.study.claims import ledger_for_people, ledger_note
from platcal.study.tables import frame_html, write_table

sm = snakemake  # noqa: F821
rows = pd.concat([pd.read_csv(f) for f in sm.input], ignore_index=True)
people, note = ledger_for_people(rows), ledger_note(rows)
write_table(rows, Path(sm.output[0]).with_suffix(""), "The claims ledger: every paper claim, computed from this study",
            note, shown=people)
front = people[["rig", "claim", "verdict", "measured", "95 % interval", "paper"]]
atomic_write_text(sm.output[3], frame_html(front, "The claims ledger", note))
job_logger(sm.log[0]).info(note)
