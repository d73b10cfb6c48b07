"""Long logs in constant memory (issue 22 item 3): a record read and filtered in chunks gives the
numbers of the record read whole.

A short centrifuge test (3 positions x 4 s, 800 samples a position) is simulated and identified
with a tiny chunk (333 rows: boundaries inside every dwell and across position changes) and
whole (``--chunk-rows 0``); estimates, sigmas and covariance must be bit-identical, the fit
block equal to 1e-9 relative with the same verdict.
"""

import json

import numpy as np
import pandas as pd
import pytest

from clean_records import spilled
from platcal.cli import main
from platcal.errors import InputError
from platcal.mapping import RecordMapping
from platcal import records
from platcal.records import PassMedian, TimeCheck, iter_table, read_table

CONFIG = """
rig: centrifuge
site: {latitude_deg: 28.2}
centrifuge: {rate_deg_s: 180, g_level: 10}
noise: {sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}
filter: {period_ms: 20, passes: PASSES}
sampling: {sample_ms: 5}
schemes:
  short: {dwell_s: 4, positions: [[45, 0, 167], [350, 0, 325], [209, 0, 182]]}
"""
CHUNK = "333"


def _config(tmp_path, passes=1):
    cfg = tmp_path / f"c{passes}.yaml"
    cfg.write_text(CONFIG.replace("PASSES", str(passes)))
    return cfg


def _simulate(tmp_path, cfg, name="run.csv", chunk=CHUNK):
    out = tmp_path / name
    assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "1", "--out", str(out),
                 "--chunk-rows", chunk]) == 0
    return out


def _identify(cfg, data, out, chunk, *extra):
    code = main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(data), "--out", str(out),
                 "--chunk-rows", chunk, *extra])
    return code, json.loads((out / "summary.json").read_text())


def test_simulate_in_chunks_writes_the_whole_record(tmp_path):
    cfg = _config(tmp_path)
    chunked = _simulate(tmp_path, cfg, "a.csv", CHUNK)
    whole = _simulate(tmp_path, cfg, "b.csv", "0")
    assert chunked.read_bytes() == whole.read_bytes()
    pq_chunked = _simulate(tmp_path, cfg, "c.parquet", CHUNK)
    pd.testing.assert_frame_equal(pd.read_parquet(pq_chunked), pd.read_csv(whole))


def _fit_numbers(fit):
    return [fit["nis_per_dof"]] + [c[k] for c in fit["channels"] for k in ("mean", "rms", "nis_per_dof", "lag1")]


@pytest.mark.parametrize("passes,estimator,suffix", [(1, "ekf", ".csv"), (2, "iekf", ".parquet")])
def test_identify_in_chunks_equals_whole(tmp_path, passes, estimator, suffix):
    cfg = _config(tmp_path, passes)
    data = _simulate(tmp_path, cfg, "run" + suffix)
    code_c, s_c = _identify(cfg, data, tmp_path / "chunked", CHUNK, "--estimator", estimator)
    code_w, s_w = _identify(cfg, data, tmp_path / "whole", "0", "--estimator", estimator)
    assert code_c == code_w == 0
    for f in ("estimates.csv", "covariance.csv", "history.csv"):
        assert (tmp_path / "chunked" / f).read_bytes() == (tmp_path / "whole" / f).read_bytes(), f
    assert s_c["mean_nis"] == s_w["mean_nis"] and s_c["nees"] == s_w["nees"]
    assert s_c["samples_used_per_position"] == s_w["samples_used_per_position"] == {"1": 199, "2": 199, "3": 199}
    assert s_c["fit"]["verdict"] == s_w["fit"]["verdict"] == "passed"
    assert s_c["fit"]["n_updates"] == s_w["fit"]["n_updates"]
    np.testing.assert_allclose(_fit_numbers(s_c["fit"]), _fit_numbers(s_w["fit"]), rtol=1e-9, atol=1e-12)


def test_identify_in_chunks_jittered_clock_from_another_origin(tmp_path):
    """Each position stamped from a logger's own origin with +-0.2 ms of jitter: read in chunks
    (its checks, medians and instants by passes over the spilled position) and whole, the
    estimates, covariance and history are bit-identical, the samples used, exit status and
    fit verdict the same, and the clock block's figures equal to 1e-9 relative (its sums are
    taken in another order)."""
    cfg = _config(tmp_path)
    df = pd.read_csv(_simulate(tmp_path, cfg))
    df["t"] += 1000.0 * df["position"] + np.random.default_rng(11).uniform(-2e-4, 2e-4, len(df))
    rec = tmp_path / "jittered.csv"
    df.to_csv(rec, index=False)
    code_c, s_c = _identify(cfg, rec, tmp_path / "chunked", CHUNK)
    code_w, s_w = _identify(cfg, rec, tmp_path / "whole", "0")
    assert code_c == code_w
    for f in ("estimates.csv", "covariance.csv", "history.csv"):
        assert (tmp_path / "chunked" / f).read_bytes() == (tmp_path / "whole" / f).read_bytes(), f
    assert s_c["samples_used_per_position"] == s_w["samples_used_per_position"]
    assert s_c["fit"]["verdict"] == s_w["fit"]["verdict"]
    clock_c, clock_w = s_c["clock"], s_w["clock"]
    assert clock_c["samples"] == clock_w["samples"] and clock_c["most_sensitive"] == clock_w["most_sensitive"]
    assert clock_w["rate_error"] is not None
    for key in ("rate_error", "rate_error_se", "tolerance"):
        np.testing.assert_allclose(clock_c[key], clock_w[key], rtol=1e-9, atol=0, err_msg=key)


BAD_POSITIONS = {
    "gap": lambda df: df.drop(index=range(500, 560)),
    "t in ms": lambda df: df.assign(t=np.where(df.position == 2, df.t * 1000.0, df.t)),
    "A in m/s^2": lambda df: df.assign(Ax=np.where(df.position == 3, df.Ax * 9.80665, df.Ax),
                                      Ay=np.where(df.position == 3, df.Ay * 9.80665, df.Ay),
                                      Az=np.where(df.position == 3, df.Az * 9.80665, df.Az)),
    "step back": lambda df: df.assign(t=np.where(df.index == 1000, df.t.shift(2), df.t)),
    "short dwell": lambda df: df[~((df.position == 2) & (df.t > 3.0))],
}


@pytest.mark.parametrize("bad", list(BAD_POSITIONS))
def test_chunked_position_checks_refuse_as_whole(tmp_path, capsys, bad):
    """A position's checks on the spilled position (a gap, t in ms, |A| in m/s^2, a step back, a
    dwell too short) refuse with exit 2 and the whole read's message, before any output."""
    cfg = _config(tmp_path)
    rec = tmp_path / "bad.csv"
    BAD_POSITIONS[bad](pd.read_csv(_simulate(tmp_path, cfg))).to_csv(rec, index=False)
    errs = []
    for chunk in (CHUNK, "0"):
        capsys.readouterr()
        out = tmp_path / f"o{chunk}"
        assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec), "--out", str(out),
                     "--chunk-rows", chunk]) == 2
        errs.append(capsys.readouterr().err.strip().splitlines()[-1])
        assert not out.exists()
    assert errs[0] == errs[1] and "error: --data column" in errs[0]


def test_chunked_plausibility_refuses_a_swap_as_whole(tmp_path, capsys):
    """Ax and Ay swapped: refused before the filter (exit 2) with the same finding either way."""
    cfg = _config(tmp_path)
    df = pd.read_csv(_simulate(tmp_path, cfg))
    df[["Ax", "Ay"]] = df[["Ay", "Ax"]].to_numpy()
    bad = tmp_path / "bad.csv"
    df.to_csv(bad, index=False)
    msgs = []
    for chunk in (CHUNK, "0"):
        capsys.readouterr()
        assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(bad), "--out",
                     str(tmp_path / f"o{chunk}"), "--chunk-rows", chunk]) == 2
        msgs.append(capsys.readouterr().err)
        assert not (tmp_path / f"o{chunk}" / "summary.json").exists()
    assert "swap" in msgs[0]
    assert msgs[0].split(";")[1:] == msgs[1].split(";")[1:]  # the same finding (RMS may differ in rounding)


def test_chunked_record_out_of_order_is_refused_naming_the_fix(tmp_path, capsys):
    cfg = _config(tmp_path)
    df = pd.read_csv(_simulate(tmp_path, cfg))
    shuffled = tmp_path / "shuffled.csv"
    pd.concat([df[df.position == 2], df[df.position == 1], df[df.position == 3]]).to_csv(shuffled, index=False)
    capsys.readouterr()
    assert main(["identify", "--config", str(cfg), "--scheme", "short", "--data", str(shuffled), "--out",
                 str(tmp_path / "o"), "--chunk-rows", CHUNK]) == 2
    err = capsys.readouterr().err
    assert "position 1 follows position 2" in err and "--chunk-rows 0" in err
    code, _ = _identify(cfg, shuffled, tmp_path / "w", "0")  # read whole, the order does not matter
    assert code == 0


def test_iter_table_chunks_are_the_whole_table(tmp_path):
    """Every chunk mapped and checked as the whole file: ISO times count from the log's first
    sample, a bad value is named by its line in the file."""
    t0 = pd.Timestamp("2026-01-01T00:00:00Z")
    df = pd.DataFrame({"time": [(t0 + pd.Timedelta(milliseconds=5 * i)).isoformat() for i in range(50)],
                       "a": np.arange(50.0) * 0.5})
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False)
    mapping = RecordMapping(columns={"t": "time"}, units={"t": "iso"})
    units = {"t": "s", "a": "m"}
    whole = read_table(path, ("t", "a"), mapping=mapping, units=units)
    parts = list(iter_table(path, ("t", "a"), mapping=mapping, units=units, chunk_rows=7))
    assert len(parts) == 8
    pd.testing.assert_frame_equal(pd.concat([p.to_pandas() for p in parts], ignore_index=True), whole)
    np.testing.assert_allclose(whole["t"].to_numpy(), np.arange(50) * 0.005, atol=1e-12)
    df.loc[33, "a"] = np.nan
    df.to_csv(path, index=False)
    with pytest.raises(InputError, match="column a, row 35"):
        list(iter_table(path, ("t", "a"), mapping=mapping, units=units, chunk_rows=7))


def test_time_check_across_chunk_boundaries():
    check = TimeCheck("--data column t")
    check(np.array([0.0, 0.1, 0.2]))
    check(np.array([0.3, 0.4]))
    with pytest.raises(InputError, match=r"sample 6 \(t = 0.4 then 0.35 s\)"):
        check(np.array([0.35, 0.5]))


def _pass_median(values, cut):
    """PassMedian fed ``values`` in slices of ``cut`` (shuffled order each pass), pass after pass."""
    m, order = PassMedian(), np.random.default_rng(5).permutation(values.size)
    while True:
        for i in range(0, values.size, cut):
            m.add(values[order[i:i + cut]])
        if m.end_pass():
            return m.value, m.passes


AWKWARD = {
    "clean steps": np.diff(np.arange(20001) * 0.005),
    "jittered steps, odd": 0.005 + 1e-6 * np.random.default_rng(1).standard_normal(20001),
    "jittered steps, even": 0.005 + 1e-6 * np.random.default_rng(2).standard_normal(20000),
    "all equal": np.full(999, 0.02),
    "ties across the middle": np.repeat(np.random.default_rng(3).standard_normal(3000), 4),
    "middle pair differs in the last bit": np.r_[np.full(50, 1.0), np.full(50, np.nextafter(1.0, 2.0))],
    "negative and signed zeros": np.r_[-np.zeros(7), np.zeros(6), -1e-300, -5.0, 3.0],
    "one value": np.array([7.5]),
    "NaN among them": np.r_[1.0, 2.0, np.nan, 4.0],
    "infinities": np.r_[-np.inf, 1.0, np.inf, np.inf],
}


@pytest.mark.parametrize("name", list(AWKWARD))
@pytest.mark.parametrize("hold", [1 << 18, 3])
def test_pass_median_is_numpys_median(name, hold, monkeypatch):
    """The bounded-memory median equals np.median bit for bit, whatever the cut and order of the
    passes, through the distinct-value count, the radix passes down to the last 16 bits (a hold
    of 3 values) and the gathering of a few candidates."""
    monkeypatch.setattr(records, "MEDIAN_HOLD", hold)
    values = AWKWARD[name]
    got, passes = _pass_median(values, cut=97)
    assert np.array_equal(got, np.median(values), equal_nan=True)
    assert passes <= 5


def test_pass_median_radix_when_values_are_many_distinct(monkeypatch):
    """More distinct values than MEDIAN_DISTINCT: the radix passes, not the count, give the
    median (and a hold of 3 forces all four 16-bit levels)."""
    monkeypatch.setattr(records, "MEDIAN_DISTINCT", 10)
    monkeypatch.setattr(records, "MEDIAN_HOLD", 3)
    values = 0.005 + 1e-9 * np.arange(-500, 501) ** 3
    got, passes = _pass_median(values, cut=64)
    assert got == np.median(values)
    assert passes >= 3


@pytest.mark.parametrize("origin", [0.0, 36512.25])
def test_spilled_times_equal_the_whole_checks(origin, monkeypatch):
    """check_times, grid_origin, the median step of the shifted t and nearest_samples over a
    spilled t (blocks of 1000 values) give the whole record's numbers: a jittered 200 Hz clock
    from another origin, decimated to 20 ms."""
    monkeypatch.setattr(records, "SPILL_BLOCK", 1000)
    rng = np.random.default_rng(7)
    t = origin + 0.005 * np.arange(12345) + 2e-4 * rng.standard_normal(12345)
    args = (0.005, 0.05, "--data column t", "a step of 0.005 s")
    with spilled(t, 1001) as spill:
        med = records.spilled_times(spill, *args)
        assert med == records.check_times(t, *args)
        o = records.spilled_grid_origin(spill, med)
        assert o == records.grid_origin(t, med)
        assert records.spilled_median_step(spill, o) == float(np.median(np.diff(t - o)))
        for first in (None, 1):
            near = records.NearestSamples(spill.first - o, spill.last - o, 0.02, 0.5 * med, first)
            for g, ahead, _ in spill.steps(o):
                near.add(g, ahead)
            idx, at = near.result()
            want = records.nearest_samples(t - o, 0.02, 0.5 * med, first)
            assert np.array_equal(idx, want) and np.array_equal(at, (t - o)[want])


@pytest.mark.parametrize("bad, message", [
    (lambda t: np.r_[t[:5000], t[4999], t[5001:]], r"time does not increase at sample 5001 "),
    (lambda t: np.r_[t[:7000], t[7000:] + 1.0], r"gap of 1.005 s between t = 34.995 and 36 s"),
    (lambda t: t * 1000.0, "median time step 5 s"),
    (lambda t: t[:1], "has 1 sample"),
])
def test_spilled_times_refuse_as_the_whole_check(bad, message, monkeypatch):
    """A step back (refused before the median is taken), a gap, t in ms and one sample: the
    spilled check refuses with the whole check's message."""
    monkeypatch.setattr(records, "SPILL_BLOCK", 1000)
    t = bad(0.005 * np.arange(10000))
    args = (0.005, 0.05, "--data column t", "a step of 0.005 s")
    with pytest.raises(InputError, match=message) as whole:
        records.check_times(t, *args)
    with spilled(t, 1001) as spill, pytest.raises(InputError, match=message) as streamed:
        records.spilled_times(spill, *args)
    assert str(streamed.value) == str(whole.value)
