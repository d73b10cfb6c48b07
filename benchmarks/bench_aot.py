"""Peak memory of the centrifuge's ``platcal identify`` on kernels compiled ahead of time against
the JIT's, by record length, and the time of the ahead-of-time build (issue 22 item 3; platcal.aot).

The build runs twice as ``platcal kernels`` into a fresh ``PLATCAL_AOT_DIR``: first with an empty
numba cache (a fresh ``NUMBA_CACHE_DIR``: a fresh machine, the kernels the built ones call are
compiled too), then again with that cache filled by the first. Each record (Table 1's 6 positions, the dwell scaled to
the length) is simulated once, then identified streamed (the default ``--chunk-rows``) with the
built kernels and with ``PLATCAL_AOT=0`` (the JIT, its kernels loaded from numba's cache by an
unmeasured identify of the shortest record first); peak RSS is the child's ``ru_maxrss``
(:func:`bench_memory.run`), with its CPU and wall time.

    python benchmarks/bench_aot.py                        # 1 min, 1 h, 6 h (minutes)
    python benchmarks/bench_aot.py --minutes 1 60 --out /tmp/aot

Writes ``benchmarks/bench_aot.{csv,md}`` through platcal.study.tables (the .html is not kept in git).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd

from bench_memory import ROOT, run, scaled_config
from platcal.study.tables import write_table


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[1, 60, 360], help="record lengths, min")
    ap.add_argument("--format", default="csv", choices=("csv", "parquet"), help="record file format")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "bench_aot"), help="output stem")
    a = ap.parse_args(argv)
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"))
    base = [sys.executable, "-m", "platcal.cli"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_aot_") as tmp:
        folder = Path(tmp)
        env["PLATCAL_AOT_DIR"] = str(folder / "aot")
        default = ROOT / "config" / "centrifuge.yaml"
        cache = dict(env, NUMBA_CACHE_DIR=str(folder / "numba_cache"))
        for label in ("build, empty numba cache", "build, numba cache filled"):
            res = run(base + ["kernels", "--config", str(default)], cache)
            rows.append({"command": label, "kernels": "aot", "record_min": float("nan"), "rows": 0, **res})
            print(rows[-1], file=sys.stderr, flush=True)
        jit = dict(env, PLATCAL_AOT="0")
        # the build is current for the sources the identify children load (an edit meanwhile would
        # make them fall back to the JIT silently)
        probe = ("from platcal import aot; from platcal.rigs.centrifuge.aot_kernels import KERNELS; "
                 "assert aot.module_path(KERNELS).is_file(), aot.module_path(KERNELS)")
        subprocess.run([sys.executable, "-c", probe], env=env, check=True)
        for i, minutes in enumerate(sorted(a.minutes)):
            cfg = scaled_config("centrifuge.yaml", ("schemes", "table1", "dwell_s"), minutes * 60 / 6, folder)
            data = folder / f"rec_{minutes:g}.{a.format}"
            big = ["--max-memory-gb", "64"]  # measured, not refused by the size check
            run(base + ["simulate", "--config", str(cfg), "--scheme", "table1", *big, "--out", str(data)], env)
            n_rows = sum(1 for _ in open(data)) - 1 if a.format == "csv" else pd.read_parquet(data, columns=["t"]).shape[0]
            ident = base + ["identify", "--config", str(cfg), "--scheme", "table1", *big, "--data", str(data)]
            if i == 0:  # the JIT's kernels into numba's cache, so that its rows measure identify, not the compiler
                run(ident + ["--out", str(folder / "warm")], jit)
            for kernels, e in (("aot", env), ("jit", jit)):
                res = run(ident + ["--out", str(folder / f"id_{minutes:g}_{kernels}")], e)
                rows.append({"command": "identify", "kernels": kernels, "record_min": float(minutes),
                             "rows": n_rows, **res})
                print(rows[-1], file=sys.stderr, flush=True)
            for f in ("estimates.csv", "covariance.csv", "history.csv"):
                same = (folder / f"id_{minutes:g}_aot" / f).read_bytes() == (folder / f"id_{minutes:g}_jit" / f).read_bytes()
                rows[-1][f"same_{f.split('.')[0]}"] = same
                rows[-2][f"same_{f.split('.')[0]}"] = same
            data.unlink()
    load = os.getloadavg()
    note = (f"Peak RSS (ru_maxrss of the child process, MB), CPU and wall s of the centrifuge's `platcal identify` "
            f"(streamed, {a.format} records of Table 1's scheme) on kernels compiled ahead of time (`aot`) and on "
            f"numba's JIT (`jit`, PLATCAL_AOT=0), and of `platcal kernels` (the build). Load average at the end "
            f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on {os.cpu_count()} cores, "
            f"NUMBA_NUM_THREADS={env['NUMBA_NUM_THREADS']}. `same_*`: the output files of the two are byte-identical. "
            "`python benchmarks/bench_aot.py`.")
    write_table(pd.DataFrame(rows), a.out, "Identify on ahead-of-time kernels against the JIT", note,
                {"record_min": ".3g", "peak_rss_mb": ".0f", "cpu_s": ".1f", "wall_s": ".1f"})
    print(f"-> {a.out}.csv, .md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
