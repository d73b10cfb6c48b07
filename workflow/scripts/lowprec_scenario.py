"""Snakemake wrapper: one centrifuge scenario of the lowprec_centrifuge study (all platforms, runs, seeds)."""
import numpy as np

from platcal.io import atomic_path, atomic_to_csv
from platcal.log import job_logger
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.study import run_scenario, study_seeds

sm = snakemake  # noqa: F821
study = load_config(dict(sm.params.config))  # the scenario's own config (study.scenario_config)
res = run_scenario(study, study_seeds(study), job_logger(sm.log[0]), trace=True)
atomic_to_csv(res["cross"], sm.output.cross)
atomic_to_csv(res["coeffs"], sm.output.coeffs)
with atomic_path(sm.output.trace) as tmp, open(tmp, "wb") as fh:
    np.savez(fh, **res["trace"])
