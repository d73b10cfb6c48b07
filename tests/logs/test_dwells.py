"""Dwells found, not cut (issue 21, item 3): a continuous multiposition log with slews."""

import json

import numpy as np
import pandas as pd

from platcal.cli import main

from .test_record_mapping import MULTIPOSITION, simulated

SLEWS_S = (10.0, 30.0, 17.5, 22.0, 12.0, 25.0, 14.0)
"""Slew between position k and k + 1, s (the third is missing from the log: a gap)."""


def continuous_log(df: pd.DataFrame, step: float = 0.02) -> pd.DataFrame:
    """The labelled record on one clock, slews (constant rate) between the dwells, no position
    or commanded columns; the slew after position 3 is not in the log."""
    keep = ["t", "Ax", "Ay", "Az", "alpha_m", "beta_m", "gamma_m"]
    parts, clock = [], 1234.5
    ks = sorted(df["position"].unique())
    for i, k in enumerate(ks):
        dwell = df.loc[df["position"] == k, keep].copy()
        dwell["t"] = dwell["t"] + clock
        parts.append(dwell)
        clock = float(dwell["t"].iloc[-1]) + step
        if i + 1 == len(ks):
            break
        n = int(round(SLEWS_S[i] / step))
        nxt = df.loc[df["position"] == ks[i + 1], keep].iloc[0]
        s = np.arange(1, n + 1)[:, None] / (n + 1)
        a, b = dwell.iloc[-1][keep[1:]].to_numpy(float), nxt[keep[1:]].to_numpy(float)
        slew = pd.DataFrame(a + s * (b - a), columns=keep[1:])
        slew.insert(0, "t", clock + step * np.arange(n))
        if i != 2:
            parts.append(slew)
        clock += n * step
    return pd.concat(parts, ignore_index=True)


def test_continuous_log_identifies_as_the_labelled_one(tmp_path):
    cfg, rec = simulated(tmp_path, MULTIPOSITION, "--scheme", "short", "--seed", "6")
    assert main(["identify", "--config", cfg, "--data", str(rec), "--scheme", "short", "--out",
                 str(tmp_path / "a")]) == 0
    log = continuous_log(pd.read_csv(rec))
    log.to_csv(tmp_path / "log.csv", index=False)
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "log.csv"), "--scheme", "short", "--out",
                 str(tmp_path / "b")]) == 0
    a = pd.read_csv(tmp_path / "a" / "estimates.csv")
    b = pd.read_csv(tmp_path / "b" / "estimates.csv")
    assert np.all(np.abs(a["estimate"] - b["estimate"]) <= 0.1 * a["sigma"])
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert [d["position"] for d in summary["dwells_found"]] == list(range(1, 9))
    assert all(d["samples"] == 201 for d in summary["dwells_found"])
    assert (tmp_path / "b" / "dwells.png").stat().st_size > 0
