"""Snakemake wrapper: the centrifuge's single run of Table 2 (platcal.rigs.centrifuge.study.single_job)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from pathlib import Path  # noqa: E402

from platcal.rig import rig_config  # noqa: E402
from platcal.rigs.centrifuge.study import single_job  # noqa: E402

sm = snakemake  # noqa: F821
single_job(rig_config(sm.config, "centrifuge"), Path(sm.output.estimates).parent, threads=sm.threads,
           log_path=sm.log[0])
