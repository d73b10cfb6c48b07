"""The low-precision centrifuge's identify on its kernel compiled ahead of time (:mod:`platcal.aot`,
:mod:`platcal.rigs.lowprec_centrifuge.aot_kernels`; issue 22 item 3): built with numba.pycc, it
loads neither numba nor llvmlite and gives the JIT's numbers and files bit for bit, whole and
streamed, CSV and Parquet (docs/lowprec-centrifuge.md §7, §10)."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from aot_helpers import REPORT, built_folder, run_probe
from platcal.cli import main
from platcal.rigs.lowprec_centrifuge.aot_kernels import KERNELS

pytestmark = pytest.mark.slow  # the build compiles the filter's kernel with pycc and a C compiler

SMALL = {"rig": "lowprec_centrifuge", "profile": {"rest_first_s": 10, "rest_between_s": 30},
         "runs": {"P1": {"run1": [5, 8]}, "P2": {"run1": [5, 8]}}}
"""A short P1 run 1 (two spins, 5 and 8 g): a few thousand rows, some hundred windows."""

PROBE = """
import json, sys
import numpy as np
from platcal.cli import main
from platcal.rigs.lowprec_centrifuge import commands

run_filter = commands.run_filter

def keep(*args, **kw):  # the filter's arrays, before the tables round them
    res = run_filter(*args, **kw)
    np.savez(sys.argv[1], x=res.x, P=res.P, nis=res.mean_nis, innovations=res.innovations,
             skipped=res.failed_updates)
    return res

commands.run_filter = keep
code = main(sys.argv[2:])
""" + REPORT


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A folder holding the rig's kernel set built from these sources."""
    return built_folder(tmp_path_factory, KERNELS)


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """The short config and a noisy record of it, as CSV and as Parquet."""
    folder = tmp_path_factory.mktemp("rec")
    cfg = folder / "config.yaml"
    cfg.write_text(yaml.safe_dump(SMALL))
    rec = folder / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--platform", "P1", "--run", "run1", "--seed", "3",
                 "--out", str(rec)]) == 0
    pq = folder / "rec.parquet"
    pd.read_csv(rec).to_parquet(pq, index=False)
    (folder / "rec.parquet.truth.json").write_text((folder / "rec.csv.truth.json").read_text())
    return cfg, {"csv": rec, "parquet": pq}


def identify(cfg, data, folder, out, chunk_rows: str, aot_on: bool) -> tuple[dict, dict]:
    """Run identify in a fresh interpreter with the kernels of ``folder``; its modules and arrays."""
    return run_probe(PROBE, folder, cfg, data, out, chunk_rows, aot_on)


@pytest.mark.parametrize("fmt,chunk_rows", [("csv", "0"), ("csv", "500"), ("parquet", "700")])
def test_aot_identify_loads_no_numba_and_equals_the_jit(built, record, tmp_path, fmt, chunk_rows):
    """Whole (``--chunk-rows 0``) and streamed (chunks that cut windows and spins), the identify on
    the built module imports neither numba nor llvmlite and says so; with ``PLATCAL_AOT=0`` the JIT
    runs (numba loaded); the final state, covariance, NIS and every window's innovation are equal
    bit for bit, and so are the output files (summary.json but for its time)."""
    cfg, data = record
    info_a, a = identify(cfg, data[fmt], built, tmp_path / "aot", chunk_rows, True)
    info_j, j = identify(cfg, data[fmt], built, tmp_path / "jit", chunk_rows, False)
    assert not info_a["numba"] and not info_a["llvmlite"]
    assert "(kernels compiled ahead of time)" in info_a["stderr"]
    assert info_j["numba"] and info_j["llvmlite"]
    assert "ahead of time" not in info_j["stderr"]
    assert a.keys() == j.keys()
    for k in a:
        assert np.array_equal(a[k], j[k], equal_nan=True), k
    assert a["innovations"].shape[1] > 100   # windows: some hundred
    names = sorted(p.name for p in (tmp_path / "aot").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "jit").iterdir()) and "estimates.csv" in names
    for name in names:
        fa, fj = tmp_path / "aot" / name, tmp_path / "jit" / name
        if name == "summary.json":
            sa, sj = json.loads(fa.read_text()), json.loads(fj.read_text())
            sa.pop("seconds"), sj.pop("seconds")
            assert sa == sj
        else:
            assert fa.read_bytes() == fj.read_bytes(), name
