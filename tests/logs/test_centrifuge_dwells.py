"""The centrifuge's position changes found in a continuous log (issue 21, item 3): a simulated
record joined on one clock, with the table spun down for 10-30 s slews between the positions (or
the slew missing from the log), identifies as the labelled record."""

import json

import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from platcal.model.frames import c_rp

from .test_record_mapping import CENTRIFUGE, simulated, write_cfg

SLEWS_S = (10.0, 30.0, 17.5, 22.0, 12.0)
STEP_S = 0.005
COMMANDED = ["alpha_cmd", "beta_cmd", "gamma_cmd"]
TRUE = ["alpha", "beta", "gamma"]


def continuous(df: pd.DataFrame, clock: float, missing: tuple[int, ...] = (), commanded: bool = False) -> pd.DataFrame:
    """The labelled record on one clock from ``clock`` s, without ``position`` (and without the
    commanded angles unless ``commanded``), with a slew after each position: the table at rest
    (1 g of gravity, seen at gimbal angles turning at a constant rate from one position to the
    next; commanded angles ramped alike). Slews after the positions in ``missing`` are not logged."""
    keep = ["t", "Ax", "Ay", "Az"] + (COMMANDED if commanded else []) + TRUE
    parts = []
    ks = sorted(df["position"].unique())
    for i, k in enumerate(ks):
        dwell = df.loc[df["position"] == k, keep].copy()
        dwell["t"] += clock
        parts.append(dwell)
        clock = float(dwell["t"].iloc[-1]) + STEP_S
        if i + 1 < len(ks):
            n = int(round(SLEWS_S[i] / STEP_S))
            a = df.loc[df["position"] == k, COMMANDED].iloc[0].to_numpy(float)
            b = df.loc[df["position"] == ks[i + 1], COMMANDED].iloc[0].to_numpy(float)
            ang = a + np.arange(1, n + 1)[:, None] / (n + 1) * (b - a)
            acc = np.array([c_rp(*np.radians(x)) @ np.array([0.0, 0.0, 1.0]) for x in ang])
            slew = pd.DataFrame({"t": clock + STEP_S * np.arange(n), "Ax": acc[:, 0], "Ay": acc[:, 1],
                                 "Az": acc[:, 2]})
            for j, c in enumerate(COMMANDED if commanded else []):
                slew[c] = ang[:, j]
            for j, c in enumerate(TRUE):
                slew[c] = ang[:, j]
            if k not in missing:
                parts.append(slew[keep])
            clock += n * STEP_S
    return pd.concat(parts, ignore_index=True)


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    """A simulated record of scheme 'short' and its identification: ``(config, record, out)``."""
    tmp = tmp_path_factory.mktemp("labelled")
    cfg, rec = simulated(tmp, CENTRIFUGE, "--scheme", "short", "--seed", "4")
    assert main(["identify", "--config", cfg, "--data", str(rec), "--scheme", "short", "--out", str(tmp / "a")]) == 0
    return cfg, rec, tmp / "a"


@pytest.mark.parametrize("commanded", [False, True])
def test_continuous_log_identifies_as_the_labelled_one(tmp_path, labelled, commanded, capsys):
    cfg, rec, a_dir = labelled
    df = pd.read_csv(rec)
    log = continuous(df, clock=5000.25, missing=(2,), commanded=commanded)  # the slew after position 2 not logged
    assert "position" not in log.columns and (("alpha_cmd" in log.columns) == commanded)
    log.to_csv(tmp_path / "log.csv", index=False)
    assert main(["inspect", "--config", cfg, "--data", str(tmp_path / "log.csv")]) == 0   # inspect reads it too
    assert "gaps (> 1.5 steps): 1" in capsys.readouterr().out                             # the slew not logged
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "log.csv"), "--scheme", "short", "--out",
                 str(tmp_path / "b")]) == 0
    a = pd.read_csv(a_dir / "estimates.csv")
    b = pd.read_csv(tmp_path / "b" / "estimates.csv")
    assert np.all(np.abs(a["estimate"] - b["estimate"]) <= 0.1 * a["sigma"])
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert [d["position"] for d in summary["dwells_found"]] == list(range(1, 7))
    per_position = int((df["position"] == 1).sum())
    assert all(d["samples"] == per_position for d in summary["dwells_found"])
    assert (tmp_path / "b" / "dwells.png").stat().st_size > 0


def test_continuous_log_of_another_scheme_refused(tmp_path, labelled, capsys):
    """Dwells that do not match the scheme: exit 2 naming --data, nothing written."""
    cfg, rec, _ = labelled
    df = pd.read_csv(rec)
    log = continuous(df[df["position"] != 4], clock=0.0)  # position 4 never held
    log.to_csv(tmp_path / "log.csv", index=False)
    out = tmp_path / "b"
    assert main(["identify", "--config", cfg, "--data", str(tmp_path / "log.csv"), "--scheme", "short", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert "--data" in err and "position 4" in err
    assert not out.exists()
    # a scheme whose positions the log's dwells do not hold
    other = write_cfg(tmp_path / "o.yaml", {**CENTRIFUGE, "schemes": {"short": {
        "dwell_s": 3, "positions": [[0, 0, 0], [90, 0, 0], [180, 0, 0], [270, 0, 0], [0, 45, 0], [0, 0, 90]]}}})
    continuous(df, clock=0.0).to_csv(tmp_path / "all.csv", index=False)
    assert main(["identify", "--config", other, "--data", str(tmp_path / "all.csv"), "--scheme", "short", "--out",
                 str(out)]) == 2
    assert "from the nearest position of the scheme" in capsys.readouterr().err
    assert not out.exists()
