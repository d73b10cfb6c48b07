"""Result tables: per-coefficient estimates and the paper's Table 2 layout (docs/centrifuge-model.md §7).

Relative error is eq. 28: ``e = (estimate - truth) / truth * 100 %``. The tables are columns by
name (a dict of arrays, or a DataFrame read back by the report): ``identify`` writes them
without pandas (:func:`platcal.io.write_csv`), so it does not load pandas (issue 22 item 3).
"""

from __future__ import annotations

import numpy as np

from ...estimation.relative import rel_err_pct
from ...lighttable import Table
from ...model.instruments import FULL_NAMES, unit_of
from .catalogue import load_catalogue


def estimates_columns(names, estimate, sigma, truth_full=None) -> dict:
    """One row per coefficient: name, unit, estimate, sigma in the coefficient's unit (and
    truth, error, rel_err_pct %), as columns; ``truth_full`` is the 48-vector in FULL_NAMES order."""
    cols = {"name": list(names), "unit": [unit_of(n) for n in names],
            "estimate": np.asarray(estimate, float), "sigma": np.asarray(sigma, float)}
    if truth_full is not None:
        idx = [FULL_NAMES.index(n) for n in names]
        truth = np.asarray(truth_full, float)[idx]
        cols["truth"] = truth
        cols["error"] = cols["estimate"] - truth
        cols["rel_err_pct"] = rel_err_pct(cols["estimate"], truth)
    return cols


def table2_rows(est) -> list[dict]:
    """Table 2 with the paper's estimate and relative error beside ours (the 45 identified rows
    of ``est``, columns by name as :func:`estimates_columns` gives them; error and rel_err_pct
    NaN when ``est`` has no truth)."""
    cat = load_catalogue()
    where = {n: i for i, n in enumerate(cat.names)}
    names = list(est["name"])
    missing = np.full(len(names), np.nan)
    error = est["error"] if "error" in est else missing
    rel = est["rel_err_pct"] if "rel_err_pct" in est else missing
    rows = []
    for name, unit, e, s, err, r in zip(names, est["unit"], est["estimate"], est["sigma"], error, rel):
        if name not in where:
            continue
        i = where[name]
        rows.append({
            "coefficient": name, "unit": unit, "truth": cat.truth[i],
            "paper_estimate": cat.paper_estimate[i], "paper_rel_err_pct": cat.paper_rel_err_pct[i],
            "estimate": e, "sigma": s, "error": err, "rel_err_pct": r,
        })
    return rows


def table2_frame(est):
    """:func:`table2_rows` as a pandas DataFrame, for the report (:meth:`platcal.lighttable.Table.to_pandas`)."""
    rows = table2_rows(est)
    return Table({k: [r[k] for r in rows] for k in rows[0]}).to_pandas()


def table2_markdown(est, title: str = "Table 2: identification results") -> str:
    """The paper's Table 2 in Markdown, our estimate and relative error beside the paper's."""
    t2 = table2_rows(est)
    lines = [f"# {title}", "",
             "Relative error is eq. 28, (estimate - truth) / truth x 100 %. "
             "Paper: Xu & Zhang (2017), Table 2.", "",
             "| coefficient | unit | truth | paper estimate | paper rel. err. % | our estimate "
             "| 1-sigma | our error | our rel. err. % |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in t2:
        lines.append(
            f"| {r['coefficient']} | {r['unit']} | {r['truth']:g} | {r['paper_estimate']:g} | "
            f"{r['paper_rel_err_pct']:.2f} | {r['estimate']:.6g} | {r['sigma']:.3g} | "
            f"{r['error']:.4g} | {r['rel_err_pct']:.2f} |")
    gyro = np.array([r["coefficient"].startswith("D") for r in t2])
    rel = np.abs(np.array([r["rel_err_pct"] for r in t2], float))
    paper = np.abs(np.array([r["paper_rel_err_pct"] for r in t2], float))
    if (~np.isnan(rel)).any():
        # NaN-skipping maxima, as the pandas table's max() was
        lines += ["", f"Largest |relative error|: gyro {np.nanmax(rel[gyro]):.2f} % "
                      f"(paper {np.nanmax(paper[gyro]):.2f} %), accelerometer "
                      f"{np.nanmax(rel[~gyro]):.2f} % (paper {np.nanmax(paper[~gyro]):.2f} %)."]
    return "\n".join(lines) + "\n"
