"""Snakemake wrapper: one centrifuge scenario of the lowprec_centrifuge study (all platforms, runs, seeds)."""
from pathlib import Path

import numpy as np

from platcal.io import atomic_path, atomic_to_csv, read_yaml
from platcal.log import job_logger
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.study import run_scenario, scenarios, study_seeds

sm = snakemake  # noqa: F821
study = load_config(read_yaml(Path(sm.params.config).read_text()))
cen = scenarios(study)[sm.wildcards.scen]["centrifuge"]
res = run_scenario(study.with_centrifuge(cen), study_seeds(study), job_logger(sm.log[0]), trace=True)
atomic_to_csv(res["cross"], sm.output.cross)
atomic_to_csv(res["coeffs"], sm.output.coeffs)
with atomic_path(sm.output.trace) as tmp, open(tmp, "wb") as fh:
    np.savez(fh, **res["trace"])
