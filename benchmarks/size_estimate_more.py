"""The size constants of the commands sized last (issue 25 item 3): ``platcal plan``, the sled's
``observability`` and a Parquet record's bytes as CSV (``platcal.sizes``,
``platcal.study.campaign``, ``platcal.rigs.sled.commands``); ``benchmarks/size_estimate.py`` does
the per-sample and per-byte costs of simulate, identify, inspect and compensate.

- plan: the CPU s of the candidates' information per candidate test-second (positions x dwell_s)
  of ``--campaign``; of :func:`planned_sigma` per plan and its peak memory on two archive sizes
  (the slope); of a short search per plan; of the Monte Carlo check per replicate test-second of
  the search's plan (the slope between two replicate counts);
- the sled's observability: CPU s and peak memory per phase (the slope between two phase counts);
- a record's bytes per value as CSV (``platcal.records.write_record``) and as Parquet, seed 0 of
  the centrifuge's and the multiposition rig's default tests.

Peak memory is the growth of this process's ``ru_maxrss``, each step larger than the last. CPU is
process time; report it with the load (``uptime``).

    NUMBA_NUM_THREADS=1 python benchmarks/size_estimate_more.py [--campaign config/campaign.yaml]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from platcal.cli import main as platcal
from platcal.io import read_config
from platcal.records import write_record
from platcal.rig import get_rig
from platcal.rigs.sled.observability import rank_table
from platcal.study import campaign as C


def peak_kb() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def timed(fn, *args):
    """``(result, CPU s, peak growth in bytes)`` of ``fn(*args)``."""
    r0, c0 = peak_kb(), time.process_time()
    out = fn(*args)
    return out, time.process_time() - c0, (peak_kb() - r0) * 1024


def plan_costs(path: str) -> None:
    camp = C.load_campaign(path)
    extra = [(t["rig"], t["scheme"], float(t["dwell_s"])) for tests in camp.references.values() for t in tests]
    cands, cpu, _ = timed(C.candidates, camp, extra)
    test_s = sum(t.positions * t.dwell_s for t in cands.tests)
    print(f"plan: candidates' information {cpu:.1f} CPU s over {len(cands.tests)} tests, {test_s:g} test-seconds: "
          f"{cpu / test_s:.3g} CPU s per candidate test-second")
    rng = np.random.default_rng(0)
    pts = []
    for plans in (500, 4000):
        counts = rng.integers(0, 4, (plans, len(cands.tests)))
        _, cpu, grew = timed(C.planned_sigma, camp, cands, counts)
        pts.append((plans, cpu, grew))
        print(f"plan: planned_sigma of {plans} plans {cpu:.3g} CPU s ({cpu / plans:.3g} a plan), "
              f"peak +{grew / 1e6:.0f} MB")
    (n0, _, g0), (n1, _, g1) = pts
    print(f"plan: {(g1 - g0) / (n1 - n0) / 8:.0f} float64 values held a plan (slope of the peak), "
          f"{cands.n_coef} coefficients")
    small = C.Campaign(**{**camp.__dict__, "optimiser": {**camp.optimiser, "population": 20, "generations": 5}})
    res, cpu, _ = timed(C.search, small, cands)
    print(f"plan: a search of 20 x 5 plans {cpu:.3g} CPU s, {cpu / 100:.3g} a plan")
    k = res.cheapest_meeting()
    seq = C.plan_sequence(camp, cands, res.counts[res.best() if k is None else k])
    plan_s = sum(cands.tests[j].positions * cands.tests[j].dwell_s for j in seq)
    cpus = [timed(C.check_plan, camp, cands, seq, r)[1] for r in (10, 30)]
    print(f"plan: check of a {len(seq)}-test plan ({plan_s:g} test-seconds): {cpus[0]:.3g} and {cpus[1]:.3g} CPU s "
          f"for 10 and 30 replicates: {cpus[0] / (10 * plan_s):.3g} and {cpus[1] / (30 * plan_s):.3g} CPU s per "
          f"replicate test-second, slope {(cpus[1] - cpus[0]) / (20 * plan_s):.3g}")


def sled_costs() -> None:
    rig = get_rig("sled")
    pts = []
    for n in (200, 2000):
        cfg = rig.load_config({"rig": "sled", "trajectory": {"phases": [{"accel_g": 1 + 1e-3 * i, "duration_s": 1}
                                                                        for i in range(n)]}})
        _, cpu, grew = timed(rank_table, cfg)
        pts.append((n + 2, cpu, grew))
        print(f"sled observability: {n + 2} phases {cpu:.3g} CPU s, peak +{grew / 1e6:.1f} MB")
    (n0, c0, g0), (n1, c1, g1) = pts
    print(f"sled observability: {(c1 - c0) / (n1 - n0):.3g} CPU s and {max(g1 - g0, 0) / (n1 - n0) / 8:.0f} values "
          "a phase (slopes)")


def csv_bytes(work: Path) -> None:
    cases = {"centrifuge": ["--scheme", "table1"], "multiposition": []}
    for rig, opts in cases.items():
        rec = work / f"{rig}.parquet"
        assert platcal(["simulate", "--config", f"config/{rig}.yaml", *opts, "--seed", "0", "--out", str(rec)]) == 0
        df = pd.read_parquet(rec)
        csv = work / f"{rig}.csv"
        write_record(df, csv)
        print(f"{rig}: {df.shape[0]} rows x {df.shape[1]} columns: {os.path.getsize(csv) / df.size:.1f} bytes a value "
              f"as CSV, {os.path.getsize(rec) / df.size:.1f} as Parquet")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaign", default="config/campaign.yaml")
    a = ap.parse_args()
    read_config(a.campaign, "--campaign")   # a bad path: one line, before the long work
    sled_costs()
    with tempfile.TemporaryDirectory() as tmp:
        csv_bytes(Path(tmp))
    plan_costs(a.campaign)
    print(f"load: {os.getloadavg()}")


if __name__ == "__main__":
    main()
