"""Cold-start cost of every rig: numba compile time on an empty cache, and load time once cached
(issue 22 item 4).

Per rig, a fresh process runs the rig's smallest simulate + identify (every kernel its default
test calls, on a few samples; the centrifuge's every estimator of its study with the study's
options, for a batch of two and a batch of one: :func:`warm_centrifuge`) with ``NUMBA_CACHE_DIR``
set to an empty directory (cold: every kernel compiled), then a second fresh process repeats it on the cache the first one wrote (warm:
kernels loaded from disk). Prints the wall and CPU seconds of both, the number of compiled
specialisations the cold run wrote (``*.nbi`` index files and ``*.nbc`` entries) and the load
average.

    NUMBA_NUM_THREADS=1 python benchmarks/bench_compile.py [--rigs centrifuge sled ...]

``NUMBA_NUM_THREADS=1`` compiles what the study's jobs compile (one thread each: the serial
kernels); without it a batch above one also compiles the parallel ones.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def study_config(dwell: float) -> dict:
    """The centrifuge's default-study config (``config/centrifuge.yaml``) with every dwell ``dwell`` s,
    10 comparison replicates (batches of 8 and 2) and a 2-generation GA of 6: numba's types do not
    depend on the record's length or the batch size, so the study's specialisations compile."""
    from platcal.rig import rig_config

    cfg = copy.deepcopy(rig_config({"rigs": {"centrifuge": str(ROOT / "config" / "centrifuge.yaml")}},
                                   "centrifuge"))
    for s in cfg["schemes"].values():
        s["dwell_s"] = dwell
    cfg["study"]["dwell_s"] = dwell
    cfg["study"]["compare"]["replicates"] = 10
    cfg["design"].update(dwell_s=dwell, population=6, generations=2)
    return cfg


def warm_centrifuge() -> None:
    """Every estimator of the study's comparison (ekf1, ekf2, ekfw, iekf, ukf, ml with the study's
    options) through the rig's ``run_batch`` as the study's cells run them, for a batch of two (the
    Monte Carlo cells) and a batch of one (the comparison cells' warm-up run, the single run,
    ``platcal identify``), then a covariance-only run (the GA design)."""
    from platcal.rig import get_rig
    from platcal.rigs.centrifuge.base import Centrifuge
    from platcal.rigs.centrifuge.catalogue import full_truth
    from platcal.rigs.centrifuge.compare_cells import with_compare_estimators
    from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf
    from platcal.rigs.centrifuge.study import builtin_scheme, check_study

    cfg = with_compare_estimators(check_study(study_config(0.2)))
    rig = get_rig("centrifuge")
    sch = builtin_scheme(cfg, "table1")
    # a kernel compiled once per argument type shows here as it does in the study
    for B in (2, 1):
        for est in cfg["study"]["compare"]["estimators"]:
            rig.montecarlo.run_batch(cfg, sch, 10.0, est, [np.random.SeedSequence([1, i]) for i in range(B)])
    params = Centrifuge().scheme_params(sch)
    t = [np.arange(1, 11) * 0.02] * len(sch.angles_deg)
    run_ekf(EstimatorInput([None] * 2, t, sch.angles_deg, params), FilterSettings(),
            linearise_about=np.repeat(full_truth()[None], 2, axis=0))


def warm_multiposition() -> None:
    from platcal.rigs.multiposition.config import load_config
    from platcal.rigs.multiposition.filter import run_ekf, simulate

    cfg = load_config({"rig": "multiposition"})
    sch = cfg.scheme("TET4")
    t, _, z = simulate(cfg, sch, [0])
    run_ekf(cfg, sch.angles_deg, t[:5], z[:, :, :5])


def warm_sled() -> None:
    from platcal.rigs.sled.config import load_config
    from platcal.rigs.sled.identify import identify
    from platcal.rigs.sled.simulate import simulate

    cfg = load_config({"rig": "sled"})
    sb = simulate(cfg, range(1))
    identify(cfg, sb.traj, sb.f, sb.w)


def warm_lowprec_centrifuge() -> None:
    from platcal.rigs.lowprec_centrifuge import RIG
    from platcal.study.montecarlo import run_cell

    small = {"rig": "lowprec_centrifuge", "runs": {"P1": {"r": [1, 1]}, "P2": {"r": [1, 1]}},
             "profile": {"rest_first_s": 1, "rest_between_s": 1}, "study": {"seeds": 1}}
    h = RIG.montecarlo
    cfg = h.check(small)
    for est in h.estimators(cfg):
        run_cell(RIG, cfg, h.case(cfg, "default"), h.noise_levels(cfg)[0], est)


WARM = {"centrifuge": warm_centrifuge, "multiposition": warm_multiposition, "sled": warm_sled,
        "lowprec_centrifuge": warm_lowprec_centrifuge}


def run_child(rig: str, cache: str) -> dict:
    """One fresh process warming ``rig`` up on the numba cache ``cache``: its wall and CPU s."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    out = subprocess.run([sys.executable, __file__, "--child", rig], env=env, check=True, capture_output=True,
                         text=True).stdout.strip().splitlines()[-1]
    return json.loads(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", nargs="+", default=list(WARM), choices=list(WARM))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        t0, c0 = time.perf_counter(), time.process_time()
        WARM[a.child]()
        print(json.dumps({"wall": time.perf_counter() - t0, "cpu": time.process_time() - c0}))
        return
    load0 = os.getloadavg()[0]
    rows = []
    for rig in a.rigs:
        with tempfile.TemporaryDirectory() as cache:
            cold = run_child(rig, cache)
            files = list(Path(cache).rglob("*"))
            nbi = sum(f.suffix == ".nbi" for f in files)
            nbc = sum(f.suffix == ".nbc" for f in files)
            warm = run_child(rig, cache)
        rows.append((rig, cold, warm, nbi, nbc))
        print(f"{rig}: cold {cold['wall']:.1f} s wall / {cold['cpu']:.1f} s CPU, warm {warm['wall']:.1f} s / "
              f"{warm['cpu']:.1f} s CPU, {nbi} cached functions, {nbc} specialisations", flush=True)
    print()
    print(f"numba cold start (empty NUMBA_CACHE_DIR) and warm start (its cache), one fresh process each; "
          f"load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end, {os.cpu_count()} cores")
    print("| rig | cold wall s | cold CPU s | warm wall s | warm CPU s | cached functions | specialisations |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for rig, cold, warm, nbi, nbc in rows:
        print(f"| {rig} | {cold['wall']:.1f} | {cold['cpu']:.1f} | {warm['wall']:.1f} | {warm['cpu']:.1f} | {nbi} "
              f"| {nbc} |")


if __name__ == "__main__":
    main()
