"""The multi-position rig's streamed identify holds nothing that grows with the record (issue 22
item 3): the scan reads the record a block of rows at a time and spills each position's instants,
and the filter's passes read them back block by block."""

from platcal import records
from platcal.cli import main
from platcal.rigs.multiposition import commands, record
from traced_peak import traced_peak

CONFIG = """rig: multiposition
filter: {passes: 2}
schemes:
  odd: {dwell_s: DWELL, positions: [[17, 12.5, 203], [250, -29, 41], [333, 0, 290]]}
"""
BLOCK = 100
"""Rows, spilled values and filter instants taken at a time: the records below are many blocks long."""


def _peak_identify(tmp_path, dwell_s: float) -> int:
    """The traced peak (bytes) of a streamed identify of a record of 3 positions of ``dwell_s``
    s (the kernels compiled or loaded by a first, untraced run)."""
    cfg = tmp_path / f"c{dwell_s}.yaml"
    cfg.write_text(CONFIG.replace("DWELL", str(dwell_s)))
    rec = tmp_path / f"r{dwell_s}.csv"
    assert main(["simulate", "--config", str(cfg), "--scheme", "odd", "--out", str(rec)]) == 0
    args = ["identify", "--config", str(cfg), "--scheme", "odd", "--data", str(rec), "--chunk-rows", "200",
            "--out", str(tmp_path / f"o{dwell_s}")]
    return traced_peak(args)


def test_streamed_identify_does_not_grow_with_the_record(tmp_path, monkeypatch):
    """3 positions of 6 s and of 60 s at 50 Hz (8100 more rows of 15 columns, 120 bytes a row in
    float64): the traced peak grows by less than 150 bytes an added row (measured: 106, 0.9 MB;
    what the scan holds per instant of the longest position while it selects that position's
    instants - their indices and times, and the pieces they are joined from - about 320 bytes an
    instant of that position, a third of the rows here), not by the record's chunks, spills or
    filter blocks, which the monkeypatched sizes keep to 100 rows."""
    monkeypatch.setattr(records, "SPILL_BLOCK", BLOCK)
    monkeypatch.setattr(records, "CSV_BLOCK", 1 << 14)  # the text's check: 16 KiB, not 1 MiB, at a time
    monkeypatch.setattr(record, "FILTER_BLOCK", BLOCK)
    monkeypatch.setattr(commands, "FILTER_BLOCK", BLOCK)
    monkeypatch.setattr(commands.NominalPosition.__init__, "__defaults__", (BLOCK,))
    short = _peak_identify(tmp_path, 6)
    long = _peak_identify(tmp_path, 60)
    added = 3 * (60 - 6) * 50
    assert long - short < 150 * added, (short, long, (long - short) / added)
