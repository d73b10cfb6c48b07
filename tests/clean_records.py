"""One clean simulated record per rig, for the tests that spoil records case by case."""

import pandas as pd

from platcal import records
from platcal.cli import main


def simulated_records(folder, configs: dict, simulate_args: dict, seed: int) -> dict:
    """``{rig: (config path, record frame)}``: each rig's config text written to
    ``folder/<rig>.yaml`` and the record ``platcal simulate`` writes from it (with
    ``simulate_args[rig]`` and ``--seed seed``) read back."""
    out = {}
    for rig, text in configs.items():
        cfg = folder / f"{rig}.yaml"
        cfg.write_text(text)
        rec = folder / f"{rig}.csv"
        assert main(["simulate", "--config", str(cfg), *simulate_args[rig], "--seed", str(seed), "--out", str(rec)]) == 0
        out[rig] = (cfg, pd.read_csv(rec))
    return out


def spilled(t, block: int) -> records.ColumnSpill:
    """``t`` written to a :class:`platcal.records.ColumnSpill` ``block`` values at a time, as a
    streamed read spills a column chunk by chunk."""
    spill = records.ColumnSpill()
    for i in range(0, t.size, block):
        spill.write(t[i:i + block])
    return spill
