"""Write vendor_log.csv: a simulated run (platform P1, run1 of config.yaml) as the INS computer
logs it: a metadata header, UTC date-times, positions in mm, azimuth in rad, specific force in mg.
Run from this folder."""

import numpy as np
import pandas as pd
import yaml

from platcal.cli import main

G = 9.80665  # the rig's g, which converts mg to m/s^2

if __name__ == "__main__":
    # the same test in platcal's own layout: the config without its record mapping
    config = yaml.safe_load(open("config.yaml"))
    open("simulated.yaml", "w").write(yaml.safe_dump({k: v for k, v in config.items() if k != "record"}))
    assert main(["simulate", "--config", "simulated.yaml", "--platform", "P1", "--run", "run1", "--seed", "1",
                 "--out", "simulated.csv"]) == 0
    df = pd.read_csv("simulated.csv")
    stamps = pd.Timestamp("2026-03-02T08:00:00Z") + pd.to_timedelta(np.round(df["t"] * 1e9).astype("int64"), unit="ns")
    log = pd.DataFrame({"utc": stamps.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ"), "vel_e": df["VE"], "vel_n": df["VN"],
                        "pos_e_mm": df["pE"] * 1e3, "pos_n_mm": df["pN"] * 1e3,
                        "azimuth": np.deg2rad(df["heading_deg"]), "f_e": df["fE"] / G * 1e3, "f_n": df["fN"] / G * 1e3,
                        "mode": df["schedule"]})
    # the INS computer's header: three lines of metadata above the columns (record.header_lines)
    meta = ("# INS computer export, platform P1, run1\n# times UTC; positions local east/north, mm\n"
            "# azimuth rad, f mg\n")
    open("vendor_log.csv", "w").write(meta + log.to_csv(index=False))
