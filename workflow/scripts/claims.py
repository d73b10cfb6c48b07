"""Snakemake wrapper: one rig's claims evaluated on its results (platcal.study.claims)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.rig import get_rig
from platcal.study.claims import evaluate_rig, ledger_for_people, ledger_note
from platcal.study.tables import write_table

sm = snakemake  # noqa: F821
rig = get_rig(sm.wildcards.ledger_rig)
rows = evaluate_rig(rig, Path(sm.output[0]).parent, dict(sm.params.config))
write_table(rows, Path(sm.output[0]).with_suffix(""), f"Claims of the {rig.name} rig's paper", ledger_note(rows),
            shown=ledger_for_people(rows))
job_logger(sm.log[0]).info("%s: %s", rig.name, ledger_note(rows))
