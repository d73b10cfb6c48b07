"""Snakemake wrapper: the same positions with the centrifuge off (static 1 g) and on."""
from pathlib import Path

from platcal.design_study import static_job

sm = snakemake  # noqa: F821
static_job(sm.config, list(sm.input.schemes), Path(sm.output.table).parent, log_path=sm.log[0])
