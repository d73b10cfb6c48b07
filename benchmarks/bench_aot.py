"""Peak memory of ``platcal identify`` on kernels compiled ahead of time against the JIT's, per
rig and record length, and the time of the ahead-of-time build (issue 22 item 3; platcal.aot).

For each rig: the build runs twice as ``platcal kernels --config config/<rig>.yaml`` into a fresh
``PLATCAL_AOT_DIR``: first with an empty numba cache (a fresh ``NUMBA_CACHE_DIR``: a fresh
machine, the kernels the built ones call are compiled too), then again with that cache filled by
the first. A rig whose command registry has no ``kernels`` command gets a row saying so and its
JIT rows only. Each record (:func:`bench_memory.scaled_case`: the centrifuge's Table 1 and the
multi-position rig's S8 with the dwell scaled, the sled's rest after the run, the low-precision
run's rests; a length the rig cannot make is skipped) is simulated once, then identified streamed
(the default ``--chunk-rows``) with the built kernels and with ``PLATCAL_AOT=0`` (the JIT, its
kernels loaded from numba's cache by an unmeasured identify of the shortest record first); peak
RSS is the child's ``ru_maxrss`` (:func:`bench_memory.run`), with its CPU and wall time. ``same``
compares the two identifies' output files: byte for byte, the JSON files but for their timing
and kernel entries (:data:`VOLATILE`).

    python benchmarks/bench_aot.py                                  # every rig, 1 min, 1 h, 6 h
    python benchmarks/bench_aot.py --rigs sled --minutes 10 360 --out /tmp/aot

Writes ``benchmarks/bench_aot.{csv,md}`` through platcal.study.tables (the .html is not kept in
git); with ``--rigs``, the other rigs' rows of the files already there are kept (the note says so).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pandas as pd

from bench_memory import RIGS, ROOT, run, scaled_case
from platcal.study.tables import write_table

VOLATILE = ("seconds", "cpu_s", "wall_s", "kernels", "aot")
"""Keys of an identify's JSON outputs that may differ between two runs of the same numbers (times,
which kernels ran); any key containing one of these is left out of ``same``."""


def _stable(obj):
    """``obj`` (parsed JSON) without its :data:`VOLATILE` keys, recursively."""
    if isinstance(obj, dict):
        return {k: _stable(v) for k, v in obj.items() if not any(w in k for w in VOLATILE)}
    if isinstance(obj, list):
        return [_stable(v) for v in obj]
    return obj


def same_outputs(a: Path, b: Path) -> str:
    """``all N`` when the two output folders hold the same files with the same content (JSON
    compared by :func:`_stable`), else the files that differ."""
    names = sorted({p.relative_to(a) for p in a.rglob("*") if p.is_file()}
                   | {p.relative_to(b) for p in b.rglob("*") if p.is_file()})
    differ = []
    for name in names:
        fa, fb = a / name, b / name
        if not (fa.is_file() and fb.is_file()):
            differ.append(str(name))
        elif name.suffix == ".json":
            if _stable(json.loads(fa.read_text())) != _stable(json.loads(fb.read_text())):
                differ.append(str(name))
        elif fa.read_bytes() != fb.read_bytes():
            differ.append(str(name))
    return f"all {len(names)}" if not differ else "differ: " + " ".join(differ)


def has_kernels_command(rig: str, env: dict) -> bool:
    """Whether ``rig``'s command registry offers ``platcal kernels`` (the ahead-of-time build)."""
    probe = f"from platcal.rig import get_rig; import sys; sys.exit(0 if 'kernels' in get_rig({rig!r}).commands else 1)"
    return subprocess.run([sys.executable, "-c", probe], env=env).returncode == 0


def source_key(env: dict) -> str:
    """:func:`platcal.aot.source_key` as the children see it (their sources, their environment)."""
    probe = "from platcal import aot; print(aot.source_key())"
    return subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def bench_rig(rig: str, minutes_list: list[float], fmt: str, folder: Path, env: dict) -> list[dict]:
    """The rows of one rig: its two builds, then AOT and JIT identifies per record length."""
    base = [sys.executable, "-m", "platcal.cli"]
    rows = []
    jit = dict(env, PLATCAL_AOT="0")
    default = ROOT / "config" / f"{rig}.yaml"
    aot = has_kernels_command(rig, env)
    key = source_key(env)
    if aot:
        cache = dict(env, NUMBA_CACHE_DIR=str(folder / f"numba_cache_{rig}"))
        for label in ("build, empty numba cache", "build, numba cache filled"):
            res = run(base + ["kernels", "--config", str(default)], cache)
            rows.append({"rig": rig, "command": label, "kernels": "aot", "record_min": float("nan"), "rows": 0, **res})
            print(rows[-1], file=sys.stderr, flush=True)
    else:
        rows.append({"rig": rig, "command": "build: this rig has no kernels command", "kernels": "-",
                     "record_min": float("nan"), "rows": 0})
    warm = True
    for minutes in sorted(minutes_list):
        case = scaled_case(rig, minutes, folder)
        if case is None:
            print(f"{rig}: no {minutes:g}-min record (its config cannot make one that short); skipped",
                  file=sys.stderr)
            continue
        cfg, sim_opts, id_opts = case
        data = folder / f"rec_{rig}_{minutes:g}.{fmt}"
        big = ["--max-memory-gb", "64"]  # measured, not refused by the size check
        run(base + ["simulate", "--config", str(cfg), *sim_opts, *big, "--out", str(data)], env)
        t = (pd.read_csv(data, usecols=[0]).iloc[:, 0] if fmt == "csv"
             else pd.read_parquet(data, columns=["t"])["t"])  # every rig's records start with t, s
        n_rows = len(t)
        del t
        ident = base + ["identify", "--config", str(cfg), *id_opts, *big, "--data", str(data)]
        if warm:  # the JIT's kernels into numba's cache, so that its rows measure identify, not the compiler
            run(ident + ["--out", str(folder / f"warm_{rig}")], jit)
            warm = False
        if aot and source_key(env) != key:
            # an AOT row measured on a stale build would be the JIT's fallback, silently
            raise SystemExit(f"{rig}: the platcal sources changed since the build ({key}); run again on a quiet tree")
        outs = {}
        for kernels, e in (("aot", env), ("jit", jit)) if aot else (("jit", jit),):
            outs[kernels] = folder / f"id_{rig}_{minutes:g}_{kernels}"
            res = run(ident + ["--out", str(outs[kernels])], e)
            rows.append({"rig": rig, "command": "identify", "kernels": kernels, "record_min": float(minutes),
                         "rows": n_rows, **res})
            print(rows[-1], file=sys.stderr, flush=True)
        if aot:
            same = same_outputs(outs["aot"], outs["jit"])
            rows[-1]["same"] = rows[-2]["same"] = same
        data.unlink()
    return rows


def kept_rows(df: pd.DataFrame, out: str, rigs: list[str]) -> tuple[pd.DataFrame, str]:
    """``df`` with the rows of the rigs not measured from ``<out>.csv`` when it has them (in
    :data:`RIGS` order), and a sentence saying which were kept ("" when none)."""
    old = Path(f"{out}.csv")
    if not old.is_file():
        return df, ""
    prev = pd.read_csv(old)
    if "rig" not in prev.columns:  # the centrifuge-only table of before --rigs
        return df, ""
    prev = prev[~prev["rig"].isin(rigs)]
    if prev.empty:
        return df, ""
    both = pd.concat([prev, df], ignore_index=True)
    both = both.iloc[both["rig"].map({r: i for i, r in enumerate(RIGS)}).argsort(kind="stable")]
    return both.reset_index(drop=True), (f" The rows of {', '.join(sorted(prev['rig'].unique()))} are an earlier "
                                         "run's (kept: --rigs).")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", nargs="+", default=list(RIGS), choices=RIGS, help="the rigs to measure (default all)")
    ap.add_argument("--minutes", type=float, nargs="+", default=[1, 60, 360], help="record lengths, min")
    ap.add_argument("--format", default="csv", choices=("csv", "parquet"), help="record file format")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "bench_aot"), help="output stem")
    a = ap.parse_args(argv)
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"))
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_aot_") as tmp:
        folder = Path(tmp)
        env["PLATCAL_AOT_DIR"] = str(folder / "aot")
        for rig in a.rigs:
            rows += bench_rig(rig, a.minutes, a.format, folder, env)
    load = os.getloadavg()
    note = (f"Peak RSS (ru_maxrss of the child process, MB), CPU and wall s of `platcal identify` (streamed, "
            f"{a.format} records) on kernels compiled ahead of time (`aot`) and on numba's JIT (`jit`, PLATCAL_AOT=0), "
            f"and of `platcal kernels` (the build). Load average at the end {load[0]:.1f} / {load[1]:.1f} / "
            f"{load[2]:.1f} on {os.cpu_count()} cores, NUMBA_NUM_THREADS={env['NUMBA_NUM_THREADS']}. `same`: the two "
            "identifies' output files are identical (JSON but for timing and kernel entries). "
            "`python benchmarks/bench_aot.py`.")
    df, kept = kept_rows(pd.DataFrame(rows), a.out, a.rigs)
    write_table(df, a.out, "Identify on ahead-of-time kernels against the JIT", note + kept,
                {"record_min": ".3g", "peak_rss_mb": ".0f", "cpu_s": ".1f", "wall_s": ".1f"})
    print(f"-> {a.out}.csv, .md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
