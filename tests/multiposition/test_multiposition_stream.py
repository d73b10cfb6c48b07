"""Long logs in bounded memory (issue 22 item 3), multi-position rig: a record read in chunks and
filtered one position at a time gives the whole read's numbers.

A short test (3 positions x 2 s at 20 ms, 101 samples a position) is identified with a tiny chunk
(37 rows: boundaries inside every position and across position changes) and whole
(``--chunk-rows 0``): estimates.csv bit-identical, mean NIS and the fit block's figures equal to
1e-9 relative with the same verdict.
"""

import json

import numpy as np
import pandas as pd
import pytest

from platcal.cli import main
from platcal import records
from platcal.io import read_yaml
from platcal.rigs.multiposition import commands
from platcal.rigs.multiposition.commands import NominalPosition
from platcal.rigs.multiposition.config import load_config
from platcal.rigs.multiposition.filter import simulate, simulate_positions
from platcal.rigs.multiposition.record import to_frame

CONFIG = """rig: multiposition
filter: {passes: PASSES}
schemes:
  odd: {dwell_s: 2, positions: [[17, 12.5, 203], [250, -29, 41], [333, 0, 290]]}
"""
CHUNK = "37"


def _config(tmp_path, passes):
    p = tmp_path / f"c{passes}.yaml"
    p.write_text(CONFIG.replace("PASSES", str(passes)))
    return str(p)


def _identify(cfg, data, out, chunk, *extra):
    code = main(["identify", "--config", cfg, "--data", str(data), "--out", str(out), "--chunk-rows", chunk, *extra])
    return code, json.loads((out / "summary.json").read_text())


def _fit_numbers(fit):
    return [fit["nis_per_dof"]] + [c[k] for c in fit["channels"] for k in ("mean", "rms", "nis_per_dof", "lag1")]


@pytest.mark.parametrize("passes,estimator,suffix,scheme,spill_block",
                         [(1, "ekf", ".csv", True, None), (2, "iekf", ".parquet", False, None), (2, "ekf", ".csv", True, 23)])
def test_identify_in_chunks_equals_whole(tmp_path, monkeypatch, passes, estimator, suffix, scheme, spill_block):
    """``spill_block``: the spilled columns and instants read back 23 rows at a time, so the
    filter is fed each position in blocks (a later block going on from the previous one's last
    instant) and the fit's and plausibility sums add block by block."""
    if spill_block:
        monkeypatch.setattr(records, "SPILL_BLOCK", spill_block)
    cfg = _config(tmp_path, passes)
    data = tmp_path / ("rec" + suffix)
    assert main(["simulate", "--config", cfg, "--scheme", "odd", "--seed", "3", "--out", str(data)]) == 0
    extra = ["--estimator", estimator] + (["--scheme", "odd"] if scheme else [])
    code_c, s_c = _identify(cfg, data, tmp_path / "chunked", CHUNK, *extra)
    code_w, s_w = _identify(cfg, data, tmp_path / "whole", "0", *extra)
    assert code_c == code_w == 0
    assert (tmp_path / "chunked" / "estimates.csv").read_bytes() == (tmp_path / "whole" / "estimates.csv").read_bytes()
    assert s_c["scheme"] == s_w["scheme"]
    assert s_c["samples_used_per_position"] == s_w["samples_used_per_position"] == {"1": 101, "2": 101, "3": 101}
    np.testing.assert_allclose(s_c["mean_nis"], s_w["mean_nis"], rtol=1e-9)
    assert s_c["fit"]["verdict"] == s_w["fit"]["verdict"] == "passed"
    assert s_c["fit"]["n_updates"] == s_w["fit"]["n_updates"]
    np.testing.assert_allclose(_fit_numbers(s_c["fit"]), _fit_numbers(s_w["fit"]), rtol=1e-9, atol=1e-12)


def test_streamed_record_out_of_order_and_bad_units_refused(tmp_path, capsys):
    cfg = _config(tmp_path, 1)
    data = tmp_path / "rec.csv"
    assert main(["simulate", "--config", cfg, "--scheme", "odd", "--seed", "3", "--out", str(data)]) == 0
    df = pd.read_csv(data)
    swapped = pd.concat([df[df.position == 2], df[df.position == 1], df[df.position == 3]])
    swapped.to_csv(tmp_path / "swapped.csv", index=False)
    args = ["identify", "--config", cfg, "--scheme", "odd", "--chunk-rows", CHUNK]
    assert main(args + ["--data", str(tmp_path / "swapped.csv"), "--out", str(tmp_path / "o1")]) == 2
    assert "--chunk-rows 0" in capsys.readouterr().err and not (tmp_path / "o1").exists()
    # read whole, the same record is accepted (positions in any order)
    assert main(args[:-1] + ["0", "--data", str(tmp_path / "swapped.csv"), "--out", str(tmp_path / "o2")]) == 0
    mg = df.assign(Ax=df.Ax * 1000, Ay=df.Ay * 1000, Az=df.Az * 1000)  # mg instead of g
    mg.to_csv(tmp_path / "mg.csv", index=False)
    assert main(args + ["--data", str(tmp_path / "mg.csv"), "--out", str(tmp_path / "o3")]) == 2
    err = capsys.readouterr().err
    assert "--data column Ax" in err and not (tmp_path / "o3").exists()


@pytest.mark.parametrize("noise_free", [False, True])
def test_simulate_position_by_position_writes_the_whole_record(tmp_path, noise_free):
    """``platcal simulate`` draws and writes one position at a time: the CSV text of the batch
    simulator's whole replicate (its draws in §14's order from one stream)."""
    cfg = _config(tmp_path, 1)
    out = tmp_path / "rec.csv"
    assert main(["simulate", "--config", cfg, "--scheme", "odd", "--seed", "5", "--out", str(out)]
                + (["--noise-free"] if noise_free else [])) == 0
    c = load_config(read_yaml(CONFIG.replace("PASSES", "1")))
    scheme = c.scheme("odd")
    t, phi, z = simulate(c, scheme, [5], noise_free=noise_free)
    assert out.read_text() == to_frame(scheme, t, phi[0], z[0]).to_csv(index=False)


@pytest.mark.parametrize("noise_free", [False, True])
def test_simulate_in_blocks_writes_the_same_bytes(tmp_path, monkeypatch, noise_free):
    """``platcal simulate`` holds a block of a position's samples at a time: in blocks of 777
    samples (3 positions x 40 s at 20 ms, 2001 samples a position: blocks of 777, 777, 447, the
    RK4 state and the ARW and noise streams carried across each boundary) it writes the bytes it
    writes in blocks longer than a position, which are the batch simulator's whole replicate
    (docs/multiposition-1g.md §12, §14)."""
    cfg = tmp_path / "c.yaml"
    cfg.write_text(CONFIG.replace("PASSES", "1").replace("dwell_s: 2", "dwell_s: 40"))
    lengths = []

    def written(path, block):
        def in_blocks(*args, **kw):
            for k, t, phi, z in simulate_positions(*args, block=block, **kw):
                lengths.append((k, len(t)))
                yield k, t, phi, z
        monkeypatch.setattr(commands, "simulate_positions", in_blocks)
        assert main(["simulate", "--config", str(cfg), "--scheme", "odd", "--seed", "4", "--out", str(path)]
                    + (["--noise-free"] if noise_free else [])) == 0
        return path.read_bytes()

    small = written(tmp_path / "small.csv", 777)
    assert lengths == [(k, m) for k in range(3) for m in (777, 777, 447)]
    lengths.clear()
    large = written(tmp_path / "large.csv", 10_000)
    assert lengths == [(k, 2001) for k in range(3)]
    assert small == large
    c = load_config(read_yaml(cfg.read_text()))
    scheme = c.scheme("odd")
    t, phi, z = simulate(c, scheme, [4], noise_free=noise_free)
    assert small.decode() == to_frame(scheme, t, phi[0], z[0]).to_csv(index=False)


def test_nominal_position_in_blocks():
    """The nominal output taken at increasing instants in pieces, from a simulation in blocks of 7
    samples, is the one-call output of one block (the simulator restarts from the block's last
    attitude; docs/multiposition-1g.md §7, §12)."""
    cfg = load_config(read_yaml(CONFIG.replace("PASSES", "1")))
    cmd = np.array([250.0, -29.0, 41.0])
    tk = np.arange(101) * cfg.ts + 0.003 * np.sin(np.arange(101))  # jittered instants
    whole = NominalPosition(cfg, cmd, 2.0, block=1000).at(tk)
    pieces = NominalPosition(cfg, cmd, 2.0, block=7)
    got = np.concatenate([pieces.at(tk[i:j]) for i, j in [(0, 5), (5, 5), (5, 40), (40, 101)]])
    assert np.array_equal(got, whole) and np.ptp(whole[:, 0]) > 0
