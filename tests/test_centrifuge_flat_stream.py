"""The centrifuge's streamed identify holds nothing that grows with the record (issue 22 item 3):
the scan finds and spills the filter instants block by block, the EKF reads them back block by
block and the history goes to its file as it is filtered; and the pieces it is built from give
the numbers of the whole-array functions they replace."""

import tracemalloc

import numpy as np
import pytest

from platcal import records
from clean_records import spilled
from platcal.cli import main
from platcal.rigs.centrifuge.record import instants_spilled_blocks, select_instants

CONFIG = """
rig: centrifuge
site: {latitude_deg: 28.2}
centrifuge: {rate_deg_s: 180, g_level: 10}
noise: {sigma_a_ug: 10, arw_deg_rth: 0.001, sigma_set_arcsec: 10}
filter: {period_ms: 20, passes: 2}
sampling: {sample_ms: 5}
schemes:
  short: {dwell_s: DWELL, positions: [[45, 0, 167], [350, 0, 325], [209, 0, 182]]}
"""


@pytest.mark.parametrize("period", [0.02, 0.003])
def test_nearest_samples_found_in_pieces_is_the_result(period, monkeypatch):
    """NearestSamples.found, called after every block, gives result()'s indices and times end to
    end; at a 3 ms period on a 5 ms clock two instants often share a sample, also across blocks."""
    monkeypatch.setattr(records, "SPILL_BLOCK", 1000)
    rng = np.random.default_rng(3)
    t = 0.005 * np.arange(9876) + 4e-4 * rng.standard_normal(9876)
    with spilled(t, 777) as spill:
        whole = records.NearestSamples(spill.first, spill.last, period, 0.0025, first=1)
        parts = records.NearestSamples(spill.first, spill.last, period, 0.0025, first=1)
        got = []
        for g, ahead, _ in spill.steps():
            whole.add(g, ahead)
            parts.add(g, ahead)
            got.append(parts.found())
        got.append(parts.found(final=True))
    idx, at = whole.result()
    assert np.array_equal(np.concatenate([g[0] for g in got]), idx)
    assert np.array_equal(np.concatenate([g[1] for g in got]), at)
    assert np.array_equal(idx, records.nearest_samples(t, period, 0.0025, first=1))
    if period < 0.005:
        assert idx.size < np.floor(t[-1] / period)  # shared samples were dropped


def test_rows_at_takes_increasing_indices_across_blocks():
    """RowsAt over blocks of a column gives values[idx] for indices asked in increasing order over
    several calls, repeats and empty asks included."""
    values = np.arange(5000.0).reshape(2500, 2) * 1.5
    blocks = ((i, values[i:i + 300]) for i in range(0, 2500, 300))
    take = records.RowsAt(blocks)
    idx = np.sort(np.random.default_rng(5).integers(0, 2500, 900))
    asks = np.split(idx, [0, 100, 100, 450, 899])
    got = np.concatenate([take.take(a) for a in asks])
    assert np.array_equal(got, values[idx])


def test_instants_in_blocks_equal_the_whole_selection(monkeypatch):
    """instants_spilled_blocks end to end gives select_instants' indices and times (a jittered
    clock from another origin)."""
    monkeypatch.setattr(records, "SPILL_BLOCK", 1000)
    rng = np.random.default_rng(9)
    t = 512.25 + 0.005 * np.arange(8000) + 2e-4 * rng.uniform(-1, 1, 8000)
    keep, tk = select_instants(1, t, 0.02, 0.05, False)
    step = float(np.median(np.diff(t)))
    origin = records.grid_origin(t, step)
    with spilled(t, 777) as spill:
        parts = list(instants_spilled_blocks(1, spill, step, origin, 0.02, False))
    assert len(parts) > 5
    assert np.array_equal(np.concatenate([p[0] for p in parts]), keep)
    assert np.array_equal(np.concatenate([p[1] for p in parts]), tk[keep])


def _peak_identify(tmp_path, dwell_s: int) -> tuple[int, bytes]:
    """tracemalloc's peak (bytes) of a streamed identify of a ``dwell_s`` record (333-row chunks,
    spill blocks of 1000 values), and its history.csv."""
    cfg = tmp_path / f"c{dwell_s}.yaml"
    cfg.write_text(CONFIG.replace("DWELL", str(dwell_s)))
    rec = tmp_path / f"r{dwell_s}.csv"
    assert main(["simulate", "--config", str(cfg), "--scheme", "short", "--seed", "2", "--out", str(rec)]) == 0
    out = tmp_path / f"o{dwell_s}"
    args = ["identify", "--config", str(cfg), "--scheme", "short", "--data", str(rec), "--chunk-rows", "333"]
    assert main(args + ["--out", str(out)]) == 0  # the kernels compiled or loaded first
    tracemalloc.start()
    try:
        assert main(args + ["--out", str(out)]) == 0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, (out / "history.csv").read_bytes()


def test_streamed_identify_does_not_grow_with_the_record(tmp_path, monkeypatch):
    """Two passes over 3 positions of 4 s and of 60 s (15 x the filter instants, 8400 more): the
    traced peak grows by less than 8 bytes an added instant (the scan's instants and rows, the
    EKF's instants and history slots and the history were some 130 bytes an instant held), and
    the history file has its 2 x 3 x 59 rows. The bounded buffers are scaled down with the record
    (a spill block of 1000 values; exact medians of more than 10 distinct values by radix passes
    gathering at most 64 candidates), so that both records hold them at their full size, as any
    long record does: what is left to grow is what grows with the record."""
    monkeypatch.setattr(records, "SPILL_BLOCK", 1000)
    monkeypatch.setattr(records, "MEDIAN_DISTINCT", 10)
    monkeypatch.setattr(records, "MEDIAN_HOLD", 64)
    short, _ = _peak_identify(tmp_path, 4)
    long, history = _peak_identify(tmp_path, 60)
    added = 2 * 3 * (60 - 4) * 50  # instants of both passes (the history's rows count once)
    assert long - short < 8 * added, (short, long)
    assert history.count(b"\n") == 1 + 2 * 3 * 59
