"""Write vendor_log.csv: a simulated run of config.yaml's scheme 'short' as a vendor's logger
would record it (a metadata header, one clock in us, accelerations in mg, encoder angles in rad,
10-30 s slews at a constant rate between the dwells, two extra columns). Run from this folder."""

import numpy as np
import pandas as pd
import yaml

from platcal.cli import main

SLEWS_S = (10.0, 30.0, 17.5, 22.0, 12.0, 25.0, 14.0)
STEP_S = 0.02
COLUMNS = ("t", "Ax", "Ay", "Az", "alpha_m", "beta_m", "gamma_m")


def continuous(df: pd.DataFrame, clock: float = 0.0, missing: tuple[int, ...] = ()) -> pd.DataFrame:
    """The labelled record on one clock from ``clock`` s with the slews in, without position and
    commanded angles; the slews after the positions in ``missing`` are left out of the log (gaps)."""
    parts = []
    ks = sorted(df["position"].unique())
    for i, k in enumerate(ks):
        dwell = df.loc[df["position"] == k, list(COLUMNS)].copy()
        dwell["t"] += clock
        parts.append(dwell)
        clock = float(dwell["t"].iloc[-1]) + STEP_S
        if i + 1 < len(ks):
            n = int(round(SLEWS_S[i] / STEP_S))
            a = dwell.iloc[-1][list(COLUMNS[1:])].to_numpy(float)
            b = df.loc[df["position"] == ks[i + 1], list(COLUMNS[1:])].iloc[0].to_numpy(float)
            s = np.arange(1, n + 1)[:, None] / (n + 1)
            slew = pd.DataFrame(a + s * (b - a), columns=list(COLUMNS[1:]))
            slew.insert(0, "t", clock + STEP_S * np.arange(n))
            if k not in missing:
                parts.append(slew)
            clock += n * STEP_S
    return pd.concat(parts, ignore_index=True)


def vendor(log: pd.DataFrame) -> pd.DataFrame:
    """The log in the vendor's columns and units (config.yaml's record: mapping undoes this)."""
    out = pd.DataFrame({"TimeStamp_us": np.round(log["t"] * 1e6)})
    for a in "XYZ":
        out[f"Acc{a}_mg"] = log[f"A{a.lower()}"] * 1e3
    for i, c in enumerate(("alpha_m", "beta_m", "gamma_m")):
        out[f"Enc{i + 1}_rad"] = np.deg2rad(log[c])
    out["BoardTemp_C"] = 31.5
    out["Status"] = 0
    return out


if __name__ == "__main__":
    plain = yaml.safe_load(open("config.yaml"))
    plain.pop("record")
    open("simulated.yaml", "w").write(yaml.safe_dump(plain))
    assert main(["simulate", "--config", "simulated.yaml", "--scheme", "short", "--seed", "1",
                 "--out", "simulated.csv"]) == 0
    # the logger's header: three lines of metadata above the columns (record.header_lines)
    meta = ("# MPT-3 multi-position table logger, firmware 1.4\n# test: scheme short, seed 1, one clock\n"
            "# units: us, mg, rad\n")
    open("vendor_log.csv", "w").write(meta + vendor(continuous(pd.read_csv("simulated.csv"))).to_csv(index=False))
