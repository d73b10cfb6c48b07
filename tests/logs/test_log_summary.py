"""``platcal inspect`` (issue 21, item 1): the log as the rig reads it, through the mapping."""

import pandas as pd
import yaml

from platcal.cli import main

CFG = {"rig": "multiposition", "schemes": {"short": {"dwell_s": 2, "positions": [[0, 0, 0], [180, 0, 0], [90, 0, 0]]}}}


def test_inspect_vendor_log(tmp_path, capsys):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(CFG))
    rec = tmp_path / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--out", str(rec)]) == 0
    df = pd.read_csv(rec)
    df = df[~((df["position"] == 2) & (df["t"] > 1.0) & (df["t"] < 1.1))]  # 4 samples lost: one gap
    log = df.rename(columns={"t": "ms"})
    log["ms"] *= 1e3
    log["extra"] = 0.0
    log.to_csv(tmp_path / "log.csv", index=False)
    raw = {**CFG, "record": {"columns": {"t": "ms"}, "units": {"t": "ms"}, "ignore_extra": True}}
    cfg.write_text(yaml.safe_dump(raw))
    capsys.readouterr()
    assert main(["inspect", "--config", str(cfg), "--data", str(tmp_path / "log.csv")]) == 0
    out = capsys.readouterr().out
    assert "t [s]" in out and "Ax [g]" in out and "extra" not in out
    assert "rate 50 Hz" in out and "dwells: 3" in out and "gaps (> 1.5 steps): 1" in out
    assert f"samples: {len(df)}" in out
    raw["record"]["units"]["t"] = "m"
    cfg.write_text(yaml.safe_dump(raw))
    assert main(["inspect", "--config", str(cfg), "--data", str(tmp_path / "log.csv")]) == 2
    assert "record.units.t" in capsys.readouterr().err
