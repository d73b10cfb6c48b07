"""The sled's streamed identify holds nothing that grows with the record (issue 22 item 3): its
three passes read the record a block of rows at a time, and what the filters hold is the run up to
the stop, whatever the rest after it."""

from platcal import records
from platcal.cli import main
from platcal.rigs.sled import stream
from traced_peak import traced_peak

CONFIG = "rig: sled\ntrajectory: {static_after_s: AFTER}\n"
BLOCK = 500
"""Rows read and worked at a time, spilled values read back at a time."""


def _peak_identify(tmp_path, after_s: float) -> int:
    """The traced peak (bytes) of a streamed identify of a record with ``after_s`` s of rest
    after the stop (the kernels compiled or loaded by a first, untraced run)."""
    cfg = tmp_path / f"c{after_s}.yaml"
    cfg.write_text(CONFIG.replace("AFTER", str(after_s)))
    rec = tmp_path / f"r{after_s}.csv"
    assert main(["simulate", "--config", str(cfg), "--out", str(rec)]) == 0
    args = ["identify", "--config", str(cfg), "--data", str(rec), "--chunk-rows", "1000",
            "--out", str(tmp_path / f"o{after_s}")]
    return traced_peak(args)


def test_streamed_identify_does_not_grow_with_the_record(tmp_path, monkeypatch):
    """60 s and 180 s of rest after the stop at 200 Hz (24 000 more rows of 10 columns, 80 bytes
    a row in float64): the traced peak (7.6 MB, the run up to the stop held for the run filter)
    grows by less than 8 bytes an added row (measured: the same to 41 kB, smaller)."""
    monkeypatch.setattr(records, "SPILL_BLOCK", BLOCK)
    monkeypatch.setattr(records, "CSV_BLOCK", 1 << 14)  # the text's check: 16 KiB, not 1 MiB, at a time
    monkeypatch.setattr(stream, "BLOCK", BLOCK)
    short = _peak_identify(tmp_path, 60)
    long = _peak_identify(tmp_path, 180)
    added = (180 - 60) * 200
    assert long - short < 8 * added, (short, long, (long - short) / added)
