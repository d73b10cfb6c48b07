"""Snakemake wrapper: one sled case's replicate 0 as time series (platcal.rigs.sled.series.write_series)."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

from platcal.rig import rig_config  # noqa: E402
from platcal.rigs.sled.montecarlo import check  # noqa: E402
from platcal.rigs.sled.series import write_series  # noqa: E402

sm = snakemake  # noqa: F821
write_series(check(rig_config(sm.config, "sled")), sm.wildcards.case, sm.output[0], log_path=sm.log[0])
