"""Snakemake wrapper: one GA scheme design (results/centrifuge/design/<name>.yaml)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from platcal.rig import rig_config
from platcal.rigs.centrifuge.design import design_scheme_job  # not design_study: no matplotlib, scipy.stats

sm = snakemake  # noqa: F821
design_scheme_job(rig_config(sm.config, "centrifuge"), sm.wildcards.design, sm.output.scheme, log_path=sm.log[0])
