"""Write vendor_log.csv: a simulated run of config.yaml's scheme 'short' as a vendor's system would
log it (a metadata header, ms, rad, m/s^2, its own column names, a status column). Run from this
folder."""

import numpy as np
import pandas as pd
import yaml

from platcal.cli import main

G = 9.80665  # the centrifuge's g (centrifuge.g), which converts g to m/s^2

if __name__ == "__main__":
    # the same test in platcal's own layout: the config without its record mapping
    config = yaml.safe_load(open("config.yaml"))
    open("simulated.yaml", "w").write(yaml.safe_dump({k: v for k, v in config.items() if k != "record"}))
    assert main(["simulate", "--config", "simulated.yaml", "--scheme", "short", "--seed", "1",
                 "--out", "simulated.csv"]) == 0
    df = pd.read_csv("simulated.csv")
    log = pd.DataFrame({"POS": df["position"], "time_ms": df["t"] * 1e3})
    for c in ("alpha_cmd", "beta_cmd", "gamma_cmd"):
        log[c.upper()] = np.deg2rad(df[c])
    for a in "xyz":
        log[f"acc_{a}"] = df[f"A{a}"] * G
    log["status"] = 0
    # the acquisition system's header: three lines of metadata above the columns (record.header_lines)
    meta = "# ACQ-9000 centrifuge logger, firmware 2.1\n# test: scheme short, seed 1\n# units: ms, rad, m/s^2\n"
    open("vendor_log.csv", "w").write(meta + log.to_csv(index=False))
