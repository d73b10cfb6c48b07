"""Write vendor_log.csv: a simulated sled run (config.yaml's trajectory) as a strapdown IMU logs it:
a metadata header, increments per sample (delta-v m/s, delta-theta arcsec), time in ms, a status
column. Run from
this folder."""

import numpy as np
import pandas as pd
import yaml

from platcal.cli import main
from platcal.logs.increments import sample_intervals

if __name__ == "__main__":
    # the same test in platcal's own layout: the config without its record mapping
    config = yaml.safe_load(open("config.yaml"))
    open("simulated.yaml", "w").write(yaml.safe_dump({k: v for k, v in config.items() if k != "record"}))
    assert main(["simulate", "--config", "simulated.yaml", "--seed", "1", "--out", "simulated.csv"]) == 0
    df = pd.read_csv("simulated.csv")
    dts = sample_intervals(df["t"].to_numpy())
    log = pd.DataFrame({"time_ms": df["t"] * 1e3})
    for a in "xyz":
        log[f"dv_{a}"] = df[f"f{a}"] * dts
        log[f"dth_{a}"] = np.rad2deg(df[f"w{a}"] * dts) * 3600.0
    log["status"] = 1
    # the IMU's header: two lines of metadata above the columns (record.header_lines)
    meta = "# strapdown IMU log, unit S/N 1187, firmware 4.0\n# increments per sample: dv m/s, dth arcsec; time ms\n"
    open("vendor_log.csv", "w").write(meta + log.to_csv(index=False))
