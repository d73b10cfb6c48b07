"""Snakemake wrapper: the sled observability rank table (platcal.rigs.sled.observability)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.log import job_logger
from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.observability import rank_table
from platcal.study.tables import write_table

sm = snakemake  # noqa: F821
log = job_logger(sm.log[0], "platcal.sled")
tab = rank_table(load_config(dict(sm.params.cfg)))
write_table(tab, Path(sm.output[0]).with_suffix(""), "Sled observability ranks (docs/rocket-sled.md §8)",
            note="states scaled 1 m/s, 1 m, 1 mrad; rank = #(sigma_i/sigma_1 > 1e-9); f = [a_x, 0, g] per phase")
log.info(f"sled rank table: {len(tab)} rows -> {sm.output[0]}")
