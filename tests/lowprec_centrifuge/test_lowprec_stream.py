"""Long logs in bounded memory (issue 22 item 3), low-precision centrifuge: the velocity's cubic
spline evaluated window by window (:func:`velocity_derivative` with overlapping windows) gives the
whole spline's values, and the identification of a record without fE, fN (f from that spline) its
estimates, with a small ``--chunk-rows`` and with the whole spline (``--chunk-rows 0``)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal.cli import main
from platcal.rigs.lowprec_centrifuge.record import velocity_derivative

SMALL = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 10, "rest_between_s": 30},
         "runs": {"P1": {"run1": [5, 8]}, "P2": {"run1": [5, 8]}}}


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    cfg = d / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(SMALL))
    assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", "run1", "--seed", "3",
                 "--out", str(d / "rec.csv")]) == 0
    df = pd.read_csv(d / "rec.csv")
    df.drop(columns=["fE", "fN"]).to_csv(d / "nof.csv", index=False)
    (d / "nof.csv.truth.json").write_text((d / "rec.csv.truth.json").read_text())
    return d, str(cfg), df


@pytest.mark.parametrize("window,overlap", [(997, 64), (3001, 32)])
def test_windowed_spline_equals_whole(record, window, overlap):
    _, _, df = record
    t, v = df["t"].to_numpy(float), df[["VE", "VN"]].to_numpy(float)
    assert t.size > 4 * window
    whole = velocity_derivative(t, v, window=t.size)
    part = velocity_derivative(t, v, window=window, overlap=overlap)
    assert np.max(np.abs(part - whole)) <= 1e-12 * np.max(np.abs(whole))
    # too little overlap leaves the end effects: the test can tell (0.268 per knot, 4 knots: 5e-3)
    short = velocity_derivative(t, v, window=window, overlap=4)
    assert np.max(np.abs(short - whole)) > 1e-9 * np.max(np.abs(whole))


def test_identify_with_small_chunks_equals_whole_spline(record):
    d, cfg, _ = record
    out = {}
    for chunk in ("0", "1000"):
        assert main(["identify", "--config", cfg, "--data", str(d / "nof.csv"), "--out", str(d / f"id{chunk}"),
                     "--chunk-rows", chunk]) == 0
        out[chunk] = (pd.read_csv(d / f"id{chunk}" / "estimates.csv"),
                      json.loads((d / f"id{chunk}" / "summary.json").read_text()))
    (e0, s0), (e1, s1) = out["0"], out["1000"]
    np.testing.assert_allclose(e1["estimate"], e0["estimate"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(e1["sigma"], e0["sigma"], rtol=1e-9, atol=0)
    assert s0["windows"] == s1["windows"]
