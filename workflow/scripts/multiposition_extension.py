"""Section 13: ranks with and without DOO, covariance-only sigma of the higher-order terms."""
from platcal.study.forkclient import delegate

delegate(snakemake)  # noqa: F821  (run by the study's fork server when one runs: the job ends here)
import json

import pandas as pd

from platcal.io import atomic_to_csv, atomic_write_text
from platcal.log import job_logger
from platcal.rigs.multiposition.extension import draw_spread, rank_table, sigma_table
from platcal.rigs.multiposition.study import load

log = job_logger(snakemake.log[0])  # noqa: F821
cfg = load(snakemake.params.config)  # noqa: F821
ranks = rank_table(cfg)
log.info("ranks: " + "; ".join(f"{r['set']} {r['model']}: {r['static_rank']}/{r['n_states']}" for r in ranks))
atomic_write_text(snakemake.output.ranks, json.dumps(ranks, indent=1) + "\n")  # noqa: F821
atomic_to_csv(pd.DataFrame(sigma_table(cfg)), snakemake.output.sigma)  # noqa: F821
spread = draw_spread(cfg)
log.info(f"sigma ranges over {cfg.raw['extension']['draws']} further draws")
atomic_to_csv(pd.DataFrame(spread, columns=["draw", "seed", "group", "min_pct", "max_pct"]), snakemake.output.spread)  # noqa: F821
