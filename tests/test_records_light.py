"""The streamed reader without pandas (issue 22 item 3): ``platcal.records.iter_table`` reads a
record with pyarrow into numpy columns (``platcal.lighttable.Table``), gives the numbers pandas'
``read_csv`` gives and names a bad value by its line as before (that it loads no pandas:
tests/test_import_weight.py)."""

import numpy as np
import pandas as pd
import pytest

from platcal.errors import InputError
from platcal.lighttable import Table
from platcal.records import iter_table, read_table


def _log(tmp_path, n=5000, seed=0):
    """A log of ``n`` rows: full-precision floats, whole numbers, a text column."""
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    df = pd.DataFrame({"t": np.arange(n) * 0.005, "a": rng.normal(size=n) * 1e-3, "k": np.arange(n) // 700 + 1,
                       "s": np.where(np.arange(n) % 3 == 0, "on", "off")})
    path = tmp_path / "log.csv"
    df.to_csv(path, index=False)
    return path


def test_chunks_hold_the_numbers_pandas_reads(tmp_path):
    path = _log(tmp_path)
    want = pd.read_csv(path)
    parts = list(iter_table(path, ("t", "a", "k"), ("s",), text=("s",), chunk_rows=777))
    assert [len(p) for p in parts] == [777] * 6 + [5000 - 6 * 777]
    assert all(isinstance(p, Table) for p in parts)
    for c in ("t", "a", "k"):
        got = np.concatenate([p[c].to_numpy(float) for p in parts])
        assert np.array_equal(got, want[c].to_numpy(float)), c  # bit for bit
    assert np.concatenate([p["s"].to_numpy() for p in parts]).tolist() == want["s"].tolist()
    whole = read_table(path, ("t", "a", "k"), ("s",), text=("s",))
    assert isinstance(whole, pd.DataFrame) and np.array_equal(whole["a"].to_numpy(), want["a"].to_numpy())


def test_a_value_pyarrow_does_not_parse_is_read_as_pandas_reads_it(tmp_path):
    # spaces around numbers: pandas takes them, pyarrow's number parser does not (the text path)
    path = tmp_path / "spaced.csv"
    path.write_text("t,a\n" + "".join(f"{i * 0.5}, {i * 0.25} \n" for i in range(40)))
    got = np.concatenate([p["a"].to_numpy(float) for p in iter_table(path, ("t", "a"), chunk_rows=7)])
    assert np.array_equal(got, np.arange(40) * 0.25)


@pytest.mark.parametrize("value, shown", [("abc", "'abc'"), ("", "nan"), ("inf", "inf")])
def test_a_bad_value_in_a_late_chunk_is_named_by_its_line(tmp_path, value, shown):
    path = _log(tmp_path)
    lines = path.read_text().splitlines()
    t, a, k, s = lines[4321].split(",")
    lines[4321] = ",".join([t, value, k, s])  # data row 4320, line 4322 of the file
    path.write_text("\n".join(lines) + "\n")
    for chunk in (1000, None):
        with pytest.raises(InputError) as e:
            list(iter_table(path, ("t", "a", "k"), ("s",), text=("s",), chunk_rows=chunk))
        assert e.value.field == "--data column a, row 4322"
        assert f"value {shown} is not a finite number" in str(e.value)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_unused_columns_are_allowed_but_neither_read_nor_checked(tmp_path, suffix):
    n = 3000
    df = pd.DataFrame({"t": np.arange(n) * 0.01, "a": np.linspace(0.0, 1.0, n), "truth_a": np.linspace(0.0, 1.0, n)})
    df.loc[1234, "truth_a"] = np.nan  # a command that does not use truth_a does not refuse it
    path = tmp_path / f"log{suffix}"
    df.to_parquet(path) if suffix == ".parquet" else df.to_csv(path, index=False)
    parts = list(iter_table(path, ("t", "a"), ("truth_a",), chunk_rows=1000, unused=("truth_a",)))
    assert [p.columns for p in parts] == [["t", "a"]] * 3
    assert np.array_equal(np.concatenate([p["a"].to_numpy(float) for p in parts]), df["a"].to_numpy())
    with pytest.raises(InputError, match="truth_a, row 1236"):  # a command that uses it still does
        list(iter_table(path, ("t", "a"), ("truth_a",), chunk_rows=1000))
    df["extra"] = 1.0
    df.to_parquet(path) if suffix == ".parquet" else df.to_csv(path, index=False)
    with pytest.raises(InputError, match="column extra"):  # a column outside the record's is still refused
        list(iter_table(path, ("t", "a"), ("truth_a",), chunk_rows=1000, unused=("truth_a",)))
