"""Result tables: per-coefficient estimates, the covariance, and the paper's Table 2 layout.

Relative error is eq. 28: ``e = (estimate - truth) / truth * 100 %``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ...model.instruments import FULL_NAMES, unit_of
from ...study.stats import rel_err_pct
from .catalogue import load_catalogue


def estimates_frame(names, estimate, sigma, truth_full=None) -> pd.DataFrame:
    """One row per coefficient: name, unit, estimate, sigma (and truth, error, rel_err_pct)."""
    df = pd.DataFrame({"name": list(names), "unit": [unit_of(n) for n in names],
                       "estimate": np.asarray(estimate, float), "sigma": np.asarray(sigma, float)})
    if truth_full is not None:
        idx = [FULL_NAMES.index(n) for n in names]
        truth = np.asarray(truth_full, float)[idx]
        df["truth"] = truth
        df["error"] = df["estimate"] - truth
        df["rel_err_pct"] = rel_err_pct(df["estimate"], truth)
    return df


def covariance_frame(names, P) -> pd.DataFrame:
    """The covariance with the state names as row and column labels."""
    return pd.DataFrame(np.asarray(P), index=list(names), columns=list(names)).rename_axis("state")


def table2_frame(est: pd.DataFrame) -> pd.DataFrame:
    """Table 2 with the paper's estimate and relative error beside ours (45 identified rows)."""
    cat = load_catalogue().frame().set_index("name")
    rows = []
    for _, r in est.iterrows():
        if r["name"] not in cat.index:
            continue
        c = cat.loc[r["name"]]
        rows.append({
            "coefficient": r["name"], "unit": r["unit"], "truth": c["truth"],
            "paper_estimate": c["paper_estimate"], "paper_rel_err_pct": c["paper_rel_err_pct"],
            "estimate": r["estimate"], "sigma": r["sigma"],
            "error": r.get("error", np.nan), "rel_err_pct": r.get("rel_err_pct", np.nan),
        })
    return pd.DataFrame(rows)


def table2_markdown(est: pd.DataFrame, title: str = "Table 2: identification results") -> str:
    """The paper's Table 2 in Markdown, our estimate and relative error beside the paper's."""
    t2 = table2_frame(est)
    lines = [f"# {title}", "",
             "Relative error is eq. 28, (estimate - truth) / truth x 100 %. "
             "Paper: Xu & Zhang (2017), Table 2.", "",
             "| coefficient | unit | truth | paper estimate | paper rel. err. % | our estimate "
             "| 1-sigma | our error | our rel. err. % |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for _, r in t2.iterrows():
        lines.append(
            f"| {r['coefficient']} | {r['unit']} | {r['truth']:g} | {r['paper_estimate']:g} | "
            f"{r['paper_rel_err_pct']:.2f} | {r['estimate']:.6g} | {r['sigma']:.3g} | "
            f"{r['error']:.4g} | {r['rel_err_pct']:.2f} |")
    gyro = t2[t2["coefficient"].str.startswith("D")]
    acc = t2[~t2["coefficient"].str.startswith("D")]
    if t2["rel_err_pct"].notna().any():
        lines += ["", f"Largest |relative error|: gyro {gyro['rel_err_pct'].abs().max():.2f} % "
                      f"(paper {gyro['paper_rel_err_pct'].abs().max():.2f} %), accelerometer "
                      f"{acc['rel_err_pct'].abs().max():.2f} % (paper {acc['paper_rel_err_pct'].abs().max():.2f} %)."]
    return "\n".join(lines) + "\n"
