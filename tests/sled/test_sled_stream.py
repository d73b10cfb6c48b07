"""A sled record longer than ``--chunk-rows`` is simulated and identified block by block
(issue 22 item 3, ``platcal.rigs.sled.stream``) with the whole read's results."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from platcal import records
from platcal.cli import main
from platcal.rigs.sled import stream
from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.trajectory import Timeline, build_trajectory, true_imu


def _numbers_close(a, b, path=""):
    """Every number of two metrics.json trees within 1e-9 relative (the run's seconds aside)."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            if k != "seconds":
                _numbers_close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _numbers_close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert b == pytest.approx(a, rel=1e-9, abs=1e-300), path
    else:
        assert a == b, path


def _identify(cfg, data, out, *extra):
    code = main(["identify", "--config", str(cfg), "--data", str(data), "--out", str(out), *extra])
    return code, out


def _same_results(cfg, data, tmp_path, chunks, *extra):
    """identify whole (--chunk-rows 0) and in chunks of ``chunks`` rows give the same estimates
    (to 1e-9 relative) and metrics.json."""
    c0, whole = _identify(cfg, data, tmp_path / "whole", "--chunk-rows", "0", *extra)
    c1, part = _identify(cfg, data, tmp_path / f"chunks{chunks}", "--chunk-rows", str(chunks), *extra)
    assert c0 == c1
    a = pd.read_csv(whole / "estimates.csv")
    b = pd.read_csv(part / "estimates.csv")
    pd.testing.assert_frame_equal(a, b, rtol=1e-9, atol=0)
    ma = json.loads((whole / "metrics.json").read_text())
    mb = json.loads((part / "metrics.json").read_text())
    _numbers_close(ma, mb)
    return ma


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sledstream")
    cfg = folder / "sled.yaml"
    cfg.write_text("rig: sled\n")
    rec = folder / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--seed", "3", "--out", str(rec), "--chunk-rows", "0"]) == 0
    return cfg, rec


def test_timeline_is_the_whole_trajectory():
    cfg = load_config({"rig": "sled", "trajectory": {"static_before_s": 30, "static_after_s": 400}})
    tr, tl = build_trajectory(cfg), Timeline.of(cfg)
    k = np.arange(tr.n)
    assert tl.core.n < tr.n // 10                      # the rests are not held
    assert (tl.n, tl.n_stop, tl.run_length_m, tl.v_max_m_s) == (tr.n, tr.n_stop, tr.run_length_m, tr.v_max_m_s)
    f, w = true_imu(tr, cfg.omega_ie)
    f2, w2 = tl.true_imu_at(k, cfg.omega_ie)
    assert np.array_equal(f, f2) and np.array_equal(w, w2)
    assert np.array_equal(tr.phase, tl.phase_at(k)) and np.array_equal(tr.accel, tl.accel_at(k))
    assert all(tr.phase_rows(p) == tl.phase_rows(p) for p in range(len(tr.phase_names)))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_simulate_in_chunks_writes_the_whole_record(tmp_path, record, suffix):
    cfg, rec = record
    whole, part = tmp_path / f"whole{suffix}", tmp_path / f"part{suffix}"
    assert main(["simulate", "--config", str(cfg), "--seed", "3", "--out", str(whole), "--chunk-rows", "0"]) == 0
    assert main(["simulate", "--config", str(cfg), "--seed", "3", "--out", str(part), "--chunk-rows", "997"]) == 0
    if suffix == ".csv":
        assert whole.read_bytes() == part.read_bytes()
    else:
        pd.testing.assert_frame_equal(pd.read_parquet(whole), pd.read_parquet(part), check_exact=True)
    assert json.loads(whole.with_name(whole.name + ".truth.json").read_text()) == \
        json.loads(part.with_name(part.name + ".truth.json").read_text())


@pytest.mark.parametrize("chunks, block", [(1000, None), (4099, 777)])
def test_identify_in_chunks_equals_whole_csv(tmp_path, record, chunks, block, monkeypatch):
    cfg, rec = record
    if block is not None:   # chunks worked through in smaller blocks, cutting filter periods
        monkeypatch.setattr(stream, "BLOCK", block)
    m = _same_results(cfg, rec, tmp_path, chunks)
    assert m["truth_known"] and m["samples"] == 17180 and m["gyro_rate_error"]["estimates"]


def test_identify_in_chunks_equals_whole_parquet(tmp_path, record):
    cfg, rec = record
    pq = tmp_path / "rec.parquet"
    df = pd.read_csv(rec)
    df.to_parquet(pq, index=False)
    pq.with_name(pq.name + ".truth.json").write_text(rec.with_name(rec.name + ".truth.json").read_text())
    _same_results(cfg, pq, tmp_path, 1500)


def test_identify_in_chunks_7_states_post_jittered_clock(tmp_path, record):
    """7 states, post compensation, no truth, a clock from another origin with jitter and a
    record cut into chunks that split filter periods."""
    cfg, rec = record
    cfg7 = tmp_path / "sled7.yaml"
    cfg7.write_text(yaml.safe_dump({"rig": "sled", "filter": {"states": 7, "compensation": "post"}}))
    df = pd.read_csv(rec)
    rng = np.random.default_rng(np.random.SeedSequence(2022))
    df["t"] = df["t"] + 5000.0 + rng.normal(0.0, 2e-5, len(df))
    jit = tmp_path / "jit.csv"
    df.drop(columns=["x_true", "vx_true", "x_inst"]).to_csv(jit, index=False, float_format="%.17g")
    m = _same_results(cfg7, jit, tmp_path, 1234)
    assert not m["truth_known"]


@pytest.mark.parametrize("column, factor, field", [("fz", 1 / 9.80665, "--data column fz"),
                                                    ("fy", 1.5, "--data column fy"),
                                                    ("wz", -1.0, "--data column wz")])
def test_streamed_read_refuses_as_the_whole_one(tmp_path, record, capsys, column, factor, field):
    cfg, rec = record
    df = pd.read_csv(rec)
    df[column] *= factor
    bad = tmp_path / "bad.csv"
    df.to_csv(bad, index=False, float_format="%.17g")
    messages = []
    for rows in ("0", "1000"):
        code, _ = _identify(cfg, bad, tmp_path / f"out{rows}", "--chunk-rows", rows)
        assert code == 2
        assert not (tmp_path / f"out{rows}" / "metrics.json").exists()
        err = capsys.readouterr().err
        assert field in err
        messages.append(err)
    assert messages[0] == messages[1]   # the same verdict and figures (the sums round as the whole arrays do, to the digits shown)


@pytest.mark.parametrize("t0, jitter, block", [(0.0, 0.0, 1000), (5000.003, 4e-4, 997), (0.0, 2e-3, 64)])
def test_epochs_from_the_spill_are_the_whole_records(monkeypatch, t0, jitter, block):
    """:class:`.stream.EpochStream` over a spilled t (blocks that cut filter periods, a clock with
    jitter and a gap) gives, piece by piece as asked, the whole record's epochs: the samples
    nearest the filter period's multiples (:func:`platcal.records.nearest_samples`) with sample 0
    first, their times, and the stop epoch where :func:`.identify.identify` puts it."""
    monkeypatch.setattr(records, "SPILL_BLOCK", block)
    rng = np.random.default_rng(np.random.SeedSequence(7))
    t = t0 + np.arange(9000) * 0.005 + rng.uniform(-jitter, jitter, 9000)
    t = np.delete(t, np.arange(4000, 4011))             # a gap of 11 samples
    origin, tol = t0, 0.5 * float(np.median(np.diff(t - t0)))
    want = records.nearest_samples(t - origin, 0.02, tol)
    if want.size == 0 or want[0] != 0:
        want = np.r_[0, want]
    n_stop = 5123
    with records.ColumnSpill() as spill:
        spill.write(t)
        stream_ = stream.EpochStream(spill, origin, t[0] - origin, t[-1] - origin, 0.02, tol)
        k, at = stream_.below(n_stop, one_more=True)
        assert k.size - 1 == min(np.searchsorted(want, n_stop), want.size - 1) and k[-1] >= n_stop
        parts = [(k, at)]
        for limit in (5200, 5200, 7001, 8990, 10 ** 6):
            parts.append(stream_.below(limit))
            assert parts[-1][0].size == 0 or parts[-1][0][-1] < limit
        assert stream_.count_rest() == 0
        again = stream.EpochStream(spill, origin, t[0] - origin, t[-1] - origin, 0.02, tol)
        again.below(100)
        assert again.count_rest() == want.size - np.searchsorted(want, 100)
    got_k = np.concatenate([p[0] for p in parts])
    got_at = np.concatenate([p[1] for p in parts])
    assert got_k.dtype == np.int64 and np.array_equal(got_k, want)
    assert np.array_equal(got_at, (t - origin)[want])
