"""Scheme check of every rank scheme in one job: `platcal observability` for each (one import, not ten)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from types import SimpleNamespace

from platcal.log import job_logger
from platcal.rigs.multiposition.study_commands import cmd_observability
from platcal.rigs.multiposition.study import load

log = job_logger(snakemake.log[0])  # noqa: F821
cfg = load(snakemake.params.config)  # noqa: F821
for scheme, out in zip(snakemake.params.schemes, snakemake.params.outdirs):  # noqa: F821
    args = SimpleNamespace(config=None, out=out, scheme=scheme, arw=None, rate=None,  # noqa: F821
                           doo=False, replicates=None)
    cmd_observability(cfg, args)
    log.info(f"{scheme} -> {out}")
