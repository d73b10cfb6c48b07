"""One Monte Carlo cell: a scheme at one noise level, every seed, every estimator variant."""
from platcal.log import job_logger
from platcal.rigs.multiposition.study import load, mc_cell, save_parquet, scheme_of

log = job_logger(snakemake.log[0])  # noqa: F821
cfg = load(snakemake.params.config)  # noqa: F821
st = cfg.raw["study"]
w = snakemake.wildcards  # noqa: F821
design = [p for p in snakemake.input if str(p).endswith(".yaml")]  # noqa: F821  (a GA scheme's file)
scheme = scheme_of(cfg, w.scheme, design[0] if design else None)
df = mc_cell(cfg, scheme, float(w.sigma), int(st["seeds"]), st["estimators"], log=log.info, threads=int(st["threads"]))
save_parquet(df, snakemake.output[0])  # noqa: F821
