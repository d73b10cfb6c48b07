"""Snakemake wrapper: one GA scheme design (results/centrifuge/design/<name>.yaml)."""
from platcal.parallel import set_threads
from platcal.rig import rig_config
from platcal.rigs.centrifuge.design_study import design_scheme_job

sm = snakemake  # noqa: F821
set_threads(sm.threads)
design_scheme_job(rig_config(sm.config, "centrifuge"), sm.wildcards.design, sm.output.scheme, log_path=sm.log[0])
