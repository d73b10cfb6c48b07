"""The multi-position rig's identify on kernels compiled ahead of time (:mod:`platcal.aot`, issue 22
item 3; docs/multiposition-1g.md §9, §12): built with numba.pycc, an identify loads neither numba nor
llvmlite and gives the JIT's numbers bit for bit, whole and streamed, EKF and IEKF, on the default
S8 record and on a copy with jittered time stamps."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aot_helpers import built_folder
from platcal import aot
from platcal.cli import main
from platcal.rigs.multiposition.aot_kernels import KERNELS

pytestmark = pytest.mark.slow  # the build compiles two kernels with pycc and a C compiler

CONFIG = Path(__file__).resolve().parents[1] / "config" / "multiposition.yaml"

PROBE = """
import json, sys
import numpy as np
from platcal import aot
from platcal.cli import main
from platcal.rigs.multiposition import commands

problems = commands.run_problems

def keep(est, P, nis, failed=0):  # the run's numbers, before the tables round them
    np.savez(sys.argv[1], est=est, P=P, nis=nis, failed=failed)
    return problems(est, P, nis, failed)

commands.run_problems = keep
code = main(sys.argv[2:])
print(json.dumps({"code": code, "numba": "numba" in sys.modules, "llvmlite": "llvmlite" in sys.modules,
                  "aot": list(aot.in_use())}))
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A folder holding the multi-position rig's kernel set built from these sources."""
    return built_folder(tmp_path_factory, KERNELS)


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """The default config's S8 record (seed 0, 8 positions x 60 s at 20 ms) and a copy whose time
    stamps jitter by up to +-4 ms (uniform, from a SeedSequence): the filter then propagates over
    unequal intervals."""
    folder = tmp_path_factory.mktemp("rec")
    rec = folder / "s8.csv"
    assert main(["simulate", "--config", str(CONFIG), "--scheme", "S8", "--seed", "0", "--out", str(rec)]) == 0
    df = pd.read_csv(rec)
    rng = np.random.default_rng(np.random.SeedSequence(2211))
    df["t"] = df["t"] + rng.uniform(-0.004, 0.004, len(df))
    jittered = folder / "s8_jitter.csv"
    df.to_csv(jittered, index=False)
    return {"s8": rec, "jitter": jittered}


def identify(data: Path, folder: Path, out: Path, chunk_rows: str, aot_on: bool, estimator: str):
    """Run identify in a fresh interpreter with the kernels of ``folder``; its modules and numbers."""
    env = {**os.environ, "PLATCAL_AOT_DIR": str(folder), "PLATCAL_AOT": "1" if aot_on else "0"}
    arrays = out.with_name(out.name + ".npz")
    res = subprocess.run([sys.executable, "-c", PROBE, str(arrays), "identify", "--config", str(CONFIG),
                          "--scheme", "S8", "--data", str(data), "--chunk-rows", chunk_rows, "--estimator", estimator,
                          "--out", str(out)], capture_output=True, text=True, env=env)
    assert res.returncode == 0, res.stderr
    info = json.loads(res.stdout.splitlines()[-1])
    assert info["code"] == 0, res.stderr
    with np.load(arrays) as z:
        return info, {k: z[k] for k in z.files}, res.stderr


@pytest.mark.parametrize("name, chunk_rows, estimator", [("s8", "0", "ekf"), ("s8", "5000", "ekf"),
                                                         ("jitter", "5000", "iekf")])
def test_aot_identify_loads_no_numba_and_equals_the_jit(built, records, tmp_path, name, chunk_rows, estimator):
    """Whole (``--chunk-rows 0``) and streamed (5000 rows), the identify on the built module
    imports neither numba nor llvmlite and says so; with ``PLATCAL_AOT=0`` the JIT runs (numba
    loaded: the EKF pass on the same reference kernel, the nominal output on the same simulator)
    and the estimate, covariance, mean NIS and skipped updates are equal bit for bit, and so are
    the written estimates and summary but its seconds."""
    info_a, a, err_a = identify(records[name], built, tmp_path / "aot", chunk_rows, True, estimator)
    info_j, j, err_j = identify(records[name], built, tmp_path / "jit", chunk_rows, False, estimator)
    assert not info_a["numba"] and not info_a["llvmlite"] and info_a["aot"] == [KERNELS.name]
    assert "(kernels compiled ahead of time)" in err_a and "ahead of time" not in err_j
    assert info_j["numba"] and info_j["llvmlite"] and info_j["aot"] == []
    assert a.keys() == j.keys()
    for k in a:
        assert np.array_equal(a[k], j[k]), k
    assert np.max(np.abs(a["est"])) > 1.0 and np.all(np.isfinite(a["P"]))  # the filter moved from its prior
    assert (tmp_path / "aot" / "estimates.csv").read_bytes() == (tmp_path / "jit" / "estimates.csv").read_bytes()
    s_a, s_j = (json.loads((tmp_path / d / "summary.json").read_text()) for d in ("aot", "jit"))
    s_a.pop("seconds"), s_j.pop("seconds")
    assert s_a == s_j


def test_a_module_built_from_other_sources_is_not_loaded(built, records, tmp_path):
    """A module whose name carries another source key is ignored: identify runs on the JIT."""
    stale = tmp_path / "stale"
    stale.mkdir()
    name = aot.module_name(KERNELS)
    for f in built.iterdir():
        (stale / f.name.replace(name, f"_platcal_aot_{KERNELS.name}_{'0' * 20}")).write_bytes(f.read_bytes())
    info, _, _ = identify(records["s8"], stale, tmp_path / "stale_out", "0", True, "ekf")
    assert info["numba"] and info["aot"] == []
