"""Snakemake wrapper: every figure of the centrifuge's study."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
from pathlib import Path

from platcal.rig import rig_config
from platcal.rigs.centrifuge.figures import figures_job
from platcal.rigs.centrifuge.report import FIGURES

sm = snakemake  # noqa: F821
figures_job(rig_config(sm.config, "centrifuge"), sm.input.coef, sm.input.runs, sm.input.t2mc,
            Path(sm.input.single[0]).parent, {k: getattr(sm.output, k) for k in FIGURES}, log_path=sm.log[0])
