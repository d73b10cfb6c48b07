"""Tables, figures and report.md of the multiposition study (the Monte Carlo from the collected tidy tables)."""
import json
from pathlib import Path

import pandas as pd

from platcal.log import job_logger
from platcal.rigs.multiposition import study as st

log = job_logger(snakemake.log[0])  # noqa: F821
i, out = snakemake.input, Path(snakemake.output.report).parent  # noqa: F821
rf = st.rank_frame([json.loads(Path(p).read_text()) for p in i.obs])
coef, runs, timing = pd.read_parquet(i.coef), pd.read_parquet(i.runs), pd.read_csv(i.timing)
summ, design = st.mc_summary(coef, runs, timing), pd.read_csv(i.design)
ext_ranks = pd.DataFrame(json.loads(Path(i.ext_ranks).read_text()))
ef = st.extension_frame(pd.read_csv(i.ext_sigma).to_dict("records"), i.centrifuge[0] if len(i.centrifuge) else None)
st.save_tables(out / "tables", rf, summ, design, ext_ranks, ef)
st.save_figures(out / "figures", rf, coef, runs, ef)
spread = pd.read_csv(i.ext_spread).to_dict("records")
st.write_report(out / "report.md", rf, summ, design, ext_ranks, ef, spread=spread,
                item4_cell=st.spec_cell(st.load(snakemake.params.config)))  # noqa: F821
log.info(f"report -> {out / 'report.md'}")
