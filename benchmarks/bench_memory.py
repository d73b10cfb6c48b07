"""Peak memory of ``platcal simulate`` and ``platcal identify`` against record length, per rig
(issue 22 item 3: long logs in constant memory).

Each command runs as a child process; its peak resident set is the kernel's ``ru_maxrss`` of
that child (``os.wait4``), with its CPU time. Lengths: the centrifuge (Table 1's 6 positions) and
the multi-position rig (S8's 8 positions) at 1 min, 10 min, 1 h and 6 h of record (the dwell
scaled; the multi-position rig reads its record whole, so its long cases show the growth); the
sled and the low-precision centrifuge at their natural lengths (a sled run lasts seconds by
physics; a low-precision run is the config's profile). The centrifuge is measured streamed
(``--chunk-rows``, default) and, up to 1 h, read whole (``--chunk-rows 0``) for comparison.

    python benchmarks/bench_memory.py                    # every case, 6 h included (minutes)
    python benchmarks/bench_memory.py --max-minutes 60   # skip the 6-hour cases

Writes ``benchmarks/bench_memory.{csv,md}`` (platcal.study.tables; its .html is not kept in git). Run it niced on a shared
machine; RSS does not depend on the load, wall time does (CPU time is given beside it).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import yaml

from platcal.io import read_yaml
from platcal.study.tables import write_table

ROOT = Path(__file__).resolve().parents[1]
MINUTES = (1, 10, 60, 360)
"""Record lengths of the long-record rigs, min."""


def run(cmd: list[str], env: dict) -> dict:
    """Run ``cmd``; its peak RSS (MB), CPU and wall seconds and exit status."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 3):
        raise SystemExit(f"{' '.join(cmd)} failed ({code}):\n{err}")
    return {"peak_rss_mb": usage.ru_maxrss / 1024.0, "cpu_s": usage.ru_utime + usage.ru_stime, "wall_s": wall,
            "exit": code}


def scaled_config(rig_yaml: str, scheme: str, dwell_s: float, folder: Path) -> Path:
    """The rig's config with ``scheme``'s dwell set to ``dwell_s`` s."""
    raw = read_yaml((ROOT / "config" / rig_yaml).read_text())
    raw["schemes"][scheme]["dwell_s"] = dwell_s
    out = folder / f"{Path(rig_yaml).stem}_{dwell_s:g}.yaml"
    out.write_text(yaml.safe_dump(raw, sort_keys=False))
    return out


def cases(max_minutes: float, folder: Path):
    """(rig, length label, minutes, mode, config, simulate options, identify options)."""
    for minutes in MINUTES:
        if minutes > max_minutes:
            continue
        cfg = scaled_config("centrifuge.yaml", "table1", minutes * 60 / 6, folder)
        yield "centrifuge", minutes, "streamed", cfg, ["--scheme", "table1"], ["--scheme", "table1"]
        if minutes <= 60:
            yield ("centrifuge", minutes, "whole", cfg, ["--scheme", "table1", "--chunk-rows", "0"],
                   ["--scheme", "table1", "--chunk-rows", "0"])
        if minutes <= 60:
            cfg = scaled_config("multiposition.yaml", "S8", minutes * 60 / 8, folder)
            yield "multiposition", minutes, "whole", cfg, ["--scheme", "S8"], ["--scheme", "S8"]
    yield "sled", None, "whole", ROOT / "config" / "sled.yaml", [], []
    yield ("lowprec_centrifuge", None, "whole", ROOT / "config" / "lowprec_centrifuge.yaml",
           ["--platform", "P1", "--run", "run1"], [])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--max-minutes", type=float, default=360.0, help="longest record, min (default 360 = 6 h)")
    ap.add_argument("--format", default="csv", choices=("csv", "parquet"), help="record file format")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "bench_memory"))
    a = ap.parse_args(argv)
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"))
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as tmp:
        folder = Path(tmp)
        for rig, minutes, mode, cfg, sim_opts, id_opts in cases(a.max_minutes, folder):
            data = folder / f"{rig}_{minutes}_{mode}.{a.format}"
            base = [sys.executable, "-m", "platcal.cli"]
            sim = run(base + ["simulate", "--config", str(cfg), *sim_opts, "--out", str(data)], env)
            size_mb = data.stat().st_size / 1e6
            n_rows = sum(1 for _ in open(data, "rb")) - 1 if a.format == "csv" else len(pd.read_parquet(data, columns=["t"]))
            ident = run(base + ["identify", "--config", str(cfg), *id_opts, "--data", str(data),
                                "--out", str(folder / f"id_{rig}_{minutes}_{mode}")], env)
            for command, res in (("simulate", sim), ("identify", ident)):
                rows.append({"rig": rig, "record_min": minutes if minutes is not None else float("nan"),
                             "mode": mode, "command": command, "rows": n_rows, "file_mb": size_mb, **res})
                print(rows[-1], file=sys.stderr, flush=True)
            data.unlink()
    df = pd.DataFrame(rows)
    load = os.getloadavg()
    note = (f"Peak RSS (ru_maxrss of the child process) of `platcal simulate` and `platcal identify` against record "
            f"length; CPU and wall s. Load average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on "
            f"{os.cpu_count()} cores, NUMBA_NUM_THREADS={env['NUMBA_NUM_THREADS']}, {a.format} records. "
            "`python benchmarks/bench_memory.py`.")
    write_table(df, a.out, "Peak memory against record length", note,
                {"record_min": "g", "file_mb": ".1f", "peak_rss_mb": ".0f", "cpu_s": ".1f", "wall_s": ".1f"})
    print(f"-> {a.out}.csv, .md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
