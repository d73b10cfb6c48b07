"""A-optimal GA designs (one per number of positions), compared with S8 and TET4."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import pandas as pd
import yaml

from platcal.io import atomic_to_csv, atomic_write_text
from platcal.log import job_logger
from platcal.rigs.multiposition.design import compare, run_design
from platcal.rigs.multiposition.study import load

log = job_logger(snakemake.log[0])  # noqa: F821
cfg = load(snakemake.params.config)  # noqa: F821
res = [run_design(cfg, k, log=log.info) for k in cfg.raw["design"]["positions"]]
for r, path in zip(res, snakemake.output[: len(res)]):  # noqa: F821
    atomic_write_text(path, yaml.safe_dump({"dwell_s": r["scheme"].dwell_s, "positions": [list(p) for p in r["scheme"].positions]}))
best = max(res, key=lambda r: r["scheme"].n_positions)
atomic_write_text(snakemake.output.ga, yaml.safe_dump({"dwell_s": best["scheme"].dwell_s, "positions": [list(p) for p in best["scheme"].positions]}))  # noqa: F821
atomic_to_csv(pd.DataFrame(compare(cfg, [r["scheme"] for r in res] + [cfg.scheme("S8"), cfg.scheme("TET4")])), snakemake.output.compare)  # noqa: F821
