"""Tables, figures and report.md of the multiposition study."""
import json
from pathlib import Path

import pandas as pd

from platcal.log import job_logger
from platcal.rigs.multiposition import study as st

log = job_logger(snakemake.log[0])  # noqa: F821
i, out = snakemake.input, Path(snakemake.output.report).parent  # noqa: F821
rf = st.rank_frame([json.loads(Path(p).read_text()) for p in i.obs])
coef = pd.concat([pd.read_parquet(p) for p in i.cells], ignore_index=True)
st.save_parquet(coef, snakemake.output.coef)  # noqa: F821
summ, design = st.mc_summary(coef), pd.read_csv(i.design)
ext_ranks = pd.DataFrame(json.loads(Path(i.ext_ranks).read_text()))
ef = st.extension_frame(pd.read_csv(i.ext_sigma).to_dict("records"), i.centrifuge[0] if len(i.centrifuge) else None)
st.save_tables(out / "tables", rf, summ, design, ext_ranks, ef)
st.fig_ranks(rf, out / "figures/ranks.png"), st.fig_montecarlo(coef, out / "figures/montecarlo.png"), st.fig_extension(ef, out / "figures/extension.png")
spread = pd.read_csv(i.ext_spread).to_dict("records")
st.write_report(out / "report.md", rf, summ, design, ext_ranks, ef, spread=spread)
log.info(f"report -> {out / 'report.md'}")
