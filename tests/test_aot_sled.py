"""The sled's identify on kernels compiled ahead of time (:mod:`platcal.aot`,
:mod:`platcal.rigs.sled.aot_kernels`; issue 22 item 3): built with numba.pycc, it loads neither
numba nor llvmlite and gives the JIT's numbers bit for bit (the JIT runs the filters with the
seeds in SIMD lanes, the ahead-of-time build the one-seed kernel, a seed at a time), on the
default record and on a jittered clock, read whole and streamed."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from aot_helpers import REPORT, run_probe
from platcal import aot
from platcal.cli import main
from platcal.rigs.sled.aot_kernels import SETS

pytestmark = pytest.mark.slow  # the build compiles seven kernels with pycc and a C compiler

PROBE = """
import json, sys
import numpy as np
from platcal.cli import main
from platcal.rigs.sled import commands

fit = commands.record_fit

def keep(idn, *args, **kw):  # the run's arrays, before the files round them
    arr = {"epochs_k": idn.epochs.k, "epochs_T": idn.epochs.T}
    for name in ("v", "r", "fl", "phi_run", "sig_run", "r_model", "x_con", "x_con_other", "nabla_x_hat"):
        arr[name] = getattr(idn, name)
    for part in ("run", "stop"):
        out = getattr(idn, part)
        for k in ("x", "sigma", "P", "mean_nis", "failed_updates", "innov", "s_var"):
            if getattr(out, k) is not None:
                arr[f"{part}_{k}"] = getattr(out, k)
    np.savez(sys.argv[1], **arr)
    return fit(idn, *args, **kw)

commands.record_fit = keep
code = main(sys.argv[2:])
""" + REPORT


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A folder holding the sled's kernel sets built from these sources (in one process)."""
    folder = tmp_path_factory.mktemp("sled_aot")
    # "sled_system" first: building "sled" after it must not take it for an older build of "sled"
    for kset in sorted(SETS, key=lambda k: -len(k.name)):
        path, _ = aot.build(kset, folder)
        assert path == aot.module_path(kset, folder) and path.is_file()
    assert all(aot.module_path(kset, folder).is_file() for kset in SETS)   # no build removed another's
    return folder


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """The default config and a simulated record (seed 3); the 7-state post-compensation config
    and the record without its truth, on a clock from another origin with jitter."""
    folder = tmp_path_factory.mktemp("rec")
    cfg, cfg7 = folder / "sled.yaml", folder / "sled7.yaml"
    cfg.write_text("rig: sled\n")
    cfg7.write_text(yaml.safe_dump({"rig": "sled", "filter": {"states": 7, "compensation": "post"}}))
    rec = folder / "rec.csv"
    assert main(["simulate", "--config", str(cfg), "--seed", "3", "--out", str(rec), "--chunk-rows", "0"]) == 0
    df = pd.read_csv(rec)
    rng = np.random.default_rng(np.random.SeedSequence(2022))
    df["t"] = df["t"] + 5000.0 + rng.normal(0.0, 2e-5, len(df))
    jit = folder / "jit.csv"
    df.drop(columns=["x_true", "vx_true", "x_inst"]).to_csv(jit, index=False, float_format="%.17g")
    return {"default": (cfg, rec), "jittered": (cfg7, jit)}


def identify(case, folder, out, chunk_rows: str, aot_on: bool) -> tuple[dict, dict]:
    """Run identify in a fresh interpreter with the kernels of ``folder``; its modules and arrays."""
    cfg, rec = case
    return run_probe(PROBE, folder, cfg, rec, out, chunk_rows, aot_on)


@pytest.mark.parametrize("which", ["default", "jittered"])
@pytest.mark.parametrize("chunk_rows", ["0", "1234"])
def test_aot_identify_loads_no_numba_and_equals_the_jit(built, records, tmp_path, which, chunk_rows):
    """Whole (``--chunk-rows 0``) and streamed (1234 rows: chunks that cut filter periods), the
    identify on the built modules imports neither numba nor llvmlite and says so; with
    ``PLATCAL_AOT=0`` the JIT runs (numba loaded), and the navigation, both filters' estimates,
    sigmas, covariances, NIS and innovations, metric B's model and the X compensation are equal
    bit for bit, and so are the output files (but for the run's seconds)."""
    info_a, a = identify(records[which], built, tmp_path / "aot", chunk_rows, True)
    info_j, j = identify(records[which], built, tmp_path / "jit", chunk_rows, False)
    assert not info_a["numba"] and not info_a["llvmlite"]
    assert "(kernels compiled ahead of time)" in info_a["stderr"]
    assert info_j["numba"] and info_j["llvmlite"]
    assert "ahead of time" not in info_j["stderr"]
    assert a.keys() == j.keys() and {"run_P", "stop_x", "x_con"} <= a.keys()
    for k in a:
        assert np.array_equal(a[k], j[k], equal_nan=True), k
    assert a["stop_x"].shape[1] > 1 and np.isfinite(a["run_x"]).all()
    files = sorted(p.name for p in (tmp_path / "aot").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "jit").iterdir()) and "estimates.csv" in files
    for name in files:
        if name != "metrics.json":
            assert (tmp_path / "aot" / name).read_bytes() == (tmp_path / "jit" / name).read_bytes(), name
    ma, mj = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in ("aot", "jit"))
    ma.pop("seconds"), mj.pop("seconds")
    assert ma == mj


def test_a_module_built_from_other_sources_is_not_loaded(built, records, tmp_path):
    """Without current modules (a folder of another build's name, as after any edit of the
    package) identify runs on the JIT with the same numbers."""
    stale = tmp_path / "stale"
    stale.mkdir()
    for kset in SETS:
        name, other = aot.module_name(kset), f"_platcal_aot_{kset.name}_{'0' * 20}"
        for f in built.glob(f"{name}*"):
            (stale / f.name.replace(name, other)).write_bytes(f.read_bytes())
    info, s = identify(records["default"], stale, tmp_path / "stale_out", "1234", True)
    assert info["numba"]
    _, a = identify(records["default"], built, tmp_path / "aot", "1234", True)
    for k in a:
        assert np.array_equal(a[k], s[k], equal_nan=True), k
