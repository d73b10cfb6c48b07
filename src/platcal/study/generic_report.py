"""The report of a rig that has no report of its own (workflow rule ``generic_report``): its
Monte Carlo summary table, the NEES histogram and ``report.md``. Apart from
:mod:`platcal.study.report` (the index) because it draws a figure: the index job does not import
matplotlib and scipy.stats (issue 22 item 4).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from ..io import atomic_write_text
from ..rig import get_rig
from .nees_figure import nees_histogram
from .stats import summary
from .tables import frame_markdown, write_table


def write_generic_report(rig_name: str, coef_path, runs_path, out_dir) -> None:
    """The report of a rig that has no report of its own: from its Monte Carlo tidy tables, the
    summary per cell (:func:`platcal.study.stats.summary`: largest and median RMS relative error
    per group, NEES) as CSV/Markdown/HTML, the NEES histogram and ``report.md``."""
    rig = get_rig(rig_name)
    out = Path(out_dir)
    coef, runs = pd.read_parquet(coef_path), pd.read_parquet(runs_path)
    summ = summary(coef, runs)
    write_table(summ, out / "tables" / "summary", f"{rig.name}: Monte Carlo summary",
                "per case x noise level x estimator: RMS relative error (%) per group, NEES", {})
    nees_histogram(runs, out / "figures" / "nees.png")
    lines = [f"# {rig.name}: {rig.title}", "", f"Spec: `docs/{rig.spec}`. {len(runs)} Monte Carlo runs "
             f"({runs['replicate'].nunique()} replicates per cell).", "", "## Monte Carlo summary", "",
             frame_markdown(summ), "", "## Figures", "", "![NEES histogram](figures/nees.png)", ""]
    atomic_write_text(out / "report.md", "\n".join(lines))
