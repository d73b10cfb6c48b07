"""Peak memory of ``platcal simulate`` and ``platcal identify`` against record length, per rig
(issue 22 item 3: long logs in constant memory).

Each command runs as a child process; its peak resident set is the kernel's ``ru_maxrss`` of
that child (``os.wait4``), with its CPU time. Every rig at 1 min, 10 min, 1 h and 6 h of record
where its config can make one that long, at its default config's length otherwise (``natural``):
the centrifuge (Table 1's 6 positions) and the multi-position rig (S8's 8 positions) with the
dwell scaled; the sled with its rest after the run (``trajectory.static_after_s``) lengthened, the
low-precision centrifuge with its rests between spin-ups (``profile.rest_between_s``; run1 of P1
has two), each from its natural length up (a sled record lasts 86 s, its stop at 26 s; a
low-precision run 17 min). The centrifuge and the multi-position rig are measured streamed
(``--chunk-rows``, default) and, up to 1 h, read whole (``--chunk-rows 0``) for comparison (the
multi-position rig's simulate has no ``--chunk-rows``: it holds a block of at most
``filter.SIM_BLOCK`` samples of a position at a time in both rows); so are the sled beyond its natural length (a natural record fits one chunk) and the
low-precision centrifuge. The ``import`` rows
are ``platcal identify --config <rig> --help``: the command's imports and nothing else, the floor
under every other row.

    python benchmarks/bench_memory.py                    # every case, 6 h included (minutes)
    python benchmarks/bench_memory.py --max-minutes 60   # skip the 6-hour cases
    python benchmarks/bench_memory.py --rigs multiposition --out /tmp/mp   # some rigs only
    python benchmarks/bench_memory.py --imports-only --src /path/to/other/tree/src --out /tmp/imports
                                                         # the floor of another tree (default out:
                                                         # benchmarks/bench_memory_imports)

Writes ``benchmarks/bench_memory.{csv,md}`` (every run) and ``bench_memory_by_length.{csv,md}``
(peak RSS by rig and length: the README's table) through platcal.study.tables (the .html is not
kept in git). With ``--rigs``, the other rigs' rows of the files already there are kept (the note
says so), so one rig is measured again without the others. Run it niced on a shared
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


GNU_TIME = "/usr/bin/time"
"""GNU time: the measured command runs as its child. ``ru_maxrss`` survives ``execve``, so a command
forked from this process (pandas loaded, a record's column read) reported this process's size
whenever that was larger: every AOT identify after the centrifuge's 6 h record read 196 MB."""


def run(cmd: list[str], env: dict) -> dict:
    """Run ``cmd``; its peak RSS (MB), CPU and wall seconds and exit status (through
    :data:`GNU_TIME` where it exists, so that the peak is the command's own)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "time.txt"
        timed = os.path.exists(GNU_TIME)
        full = [GNU_TIME, "-f", "%M %U %S", "-o", str(report), *cmd] if timed else cmd
        proc = subprocess.Popen(full, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        err = proc.stderr.read().decode()
        proc.stderr.close()
        code = os.waitstatus_to_exitcode(status)
        if code not in (0, 3):
            raise SystemExit(f"{' '.join(cmd)} failed ({code}):\n{err}")
        if timed:  # "Command exited with non-zero status 3" comes before the format's line
            kb, user, sys_s = report.read_text().split("\n")[-2].split()
            return {"peak_rss_mb": float(kb) / 1024.0, "cpu_s": float(user) + float(sys_s), "wall_s": wall,
                    "exit": code}
    return {"peak_rss_mb": usage.ru_maxrss / 1024.0, "cpu_s": usage.ru_utime + usage.ru_stime, "wall_s": wall,
            "exit": code}


def scaled_config(rig_yaml: str, keys: tuple[str, ...], value: float, folder: Path) -> Path:
    """The rig's default config with the entry at ``keys`` (a path of mapping keys) set to ``value``."""
    raw = read_yaml((ROOT / "config" / rig_yaml).read_text())
    node = raw
    for k in keys[:-1]:
        node = node.setdefault(k, {})
    node[keys[-1]] = value
    out = folder / f"{Path(rig_yaml).stem}_{'_'.join(keys)}_{value:g}.yaml"
    out.write_text(yaml.safe_dump(raw, sort_keys=False))
    return out


SLED_RUN_S = 26.0
"""The default sled record up to the sled's stop, s (5 s still, 14 s of thrust and coast, braking:
the stop at 25.9 s, `platcal simulate` of config/sled.yaml); its 60 s rest after makes 86 s."""
LOWPREC_NATURAL_S, LOWPREC_REST_S = 1044.0, 300.0
"""The default low-precision run P1/run1 (1044 s, `platcal simulate`) and its two rests between
spin-ups (``profile.rest_between_s``), s."""


RIGS = ("centrifuge", "multiposition", "sled", "lowprec_centrifuge")


def cases(max_minutes: float, folder: Path, rigs: tuple[str, ...] = RIGS):
    """(rig, minutes or None for the natural length, mode, config, simulate options, identify options)
    of the rigs ``rigs``."""
    for case in all_cases(max_minutes, folder):
        if case[0] in rigs:
            yield case


LOWPREC_RUN = ["--platform", "P1", "--run", "run1"]
"""The low-precision run every case simulates and identifies (P1/run1)."""


def scaled_case(rig: str, minutes: float, folder: Path):
    """(config, simulate options, identify options) of a ``minutes``-long streamed record of
    ``rig``, or None where the rig's config cannot make one that short (the sled under its run and
    a minute of rest, the low-precision centrifuge under its natural run)."""
    if rig == "centrifuge":
        cfg = scaled_config("centrifuge.yaml", ("schemes", "table1", "dwell_s"), minutes * 60 / 6, folder)
        return cfg, ["--scheme", "table1"], ["--scheme", "table1"]
    if rig == "multiposition":
        cfg = scaled_config("multiposition.yaml", ("schemes", "S8", "dwell_s"), minutes * 60 / 8, folder)
        return cfg, ["--scheme", "S8"], ["--scheme", "S8"]
    if rig == "sled" and minutes * 60 > SLED_RUN_S + 60:
        return scaled_config("sled.yaml", ("trajectory", "static_after_s"), minutes * 60 - SLED_RUN_S, folder), [], []
    if rig == "lowprec_centrifuge" and minutes * 60 > LOWPREC_NATURAL_S:
        cfg = scaled_config("lowprec_centrifuge.yaml", ("profile", "rest_between_s"),
                            LOWPREC_REST_S + (minutes * 60 - LOWPREC_NATURAL_S) / 2, folder)
        return cfg, LOWPREC_RUN, []
    return None


def all_cases(max_minutes: float, folder: Path):
    """:func:`cases` of every rig."""
    for rig in RIGS:
        cfg = ROOT / "config" / f"{rig}.yaml"
        yield rig, None, "import", cfg, None, ["--help"]
    yield "sled", None, "whole", ROOT / "config" / "sled.yaml", [], []
    yield "lowprec_centrifuge", None, "streamed", ROOT / "config" / "lowprec_centrifuge.yaml", LOWPREC_RUN, []
    yield ("lowprec_centrifuge", None, "whole", ROOT / "config" / "lowprec_centrifuge.yaml",
           LOWPREC_RUN + ["--chunk-rows", "0"], ["--chunk-rows", "0"])
    whole = ["--chunk-rows", "0"]
    for minutes in MINUTES:
        if minutes > max_minutes:
            continue
        for rig in RIGS:
            case = scaled_case(rig, minutes, folder)
            if case is None:
                continue
            cfg, sim_opts, id_opts = case
            yield rig, minutes, "streamed", cfg, sim_opts, id_opts
            if minutes <= 60:
                # the multi-position rig's simulate has no --chunk-rows (a block of a position at a time in both)
                yield rig, minutes, "whole", cfg, sim_opts + ([] if rig == "multiposition" else whole), id_opts + whole


def warm_up(base: list[str], todo, folder: Path, env: dict) -> None:
    """Run each rig's first simulate and identify once, unmeasured, so that numba's on-disk caches
    hold the kernels: a row then measures the command, not the compiler (compiling a rig's kernels
    takes seconds of CPU and some 100 MB more; a fresh tree's first run pays it once)."""
    seen = set()
    for rig, _, mode, cfg, sim_opts, id_opts in todo:
        if mode == "import" or (rig, mode) in seen:
            continue
        seen.add((rig, mode))
        data = folder / f"warm_{rig}.csv"
        run(base + ["simulate", "--config", str(cfg), *sim_opts, "--out", str(data)], env)
        # a streamed rig's first (shortest) record fits one chunk: small chunks compile the streamed kernels
        chunks = ["--chunk-rows", "2000"] if mode == "streamed" else []
        run(base + ["identify", "--config", str(cfg), *id_opts, *chunks, "--data", str(data), "--out",
                    str(folder / f"warm_{rig}_{mode}")], env)
        data.unlink()


def by_length(df: pd.DataFrame) -> pd.DataFrame:
    """The README's table: peak RSS, MB, one row per (rig, mode, command), one column per record
    length (``import``: the command's imports alone; ``natural``: the default config's record,
    its length in ``natural_min``)."""
    runs = df[df["mode"] != "import"]
    natural = runs["record_min"].where(~runs["record_min"].isin(MINUTES))
    key = runs["record_min"].where(natural.isna(), -1.0)
    wide = (runs.assign(length=key).pivot_table(index=["rig", "mode", "command"], columns="length",
                                                values="peak_rss_mb", sort=False))
    wide.columns = ["natural" if c < 0 else f"{c:g} min" for c in wide.columns]
    out = wide.reset_index()
    nat = runs.assign(natural_min=natural).dropna(subset=["natural_min"]).groupby("rig")["natural_min"].first()
    out.insert(3, "natural_min", out["rig"].map(nat))
    imports = df[df["mode"] == "import"].set_index("rig")["peak_rss_mb"]
    out.insert(3, "import", out["rig"].map(imports))
    cols = ["rig", "mode", "command", "import", "natural_min", "natural"] + [f"{m:g} min" for m in MINUTES]
    order = {r: i for i, r in enumerate(dict.fromkeys(df["rig"]))}  # the rigs as run (import rows first)
    out = out.sort_values(["rig", "mode", "command"], key=lambda c: c.map(order) if c.name == "rig" else
                          c.map({"streamed": 0, "whole": 1, "simulate": 0, "identify": 1}), kind="stable")
    return out[[c for c in cols if c in out.columns]]


def write_tables(df: pd.DataFrame, out: str, note: str) -> None:
    """``<out>.{csv,md}`` (every run) and ``<out>_by_length.{csv,md}`` (:func:`by_length`)."""
    write_table(df, out, "Peak memory against record length", note,
                {"record_min": ".3g", "file_mb": ".1f", "peak_rss_mb": ".0f", "cpu_s": ".1f", "wall_s": ".1f"})
    if (df["mode"] == "import").all():
        return
    wide = by_length(df)
    write_table(wide, f"{out}_by_length", "Peak RSS (MB) against record length", note,
                {c: (".3g" if c == "natural_min" else ".0f") for c in wide.columns[3:]})


def kept_rows(df: pd.DataFrame, note: str, out: str, rigs: tuple[str, ...]) -> tuple[pd.DataFrame, str]:
    """``df`` with the rows of the rigs not measured (not in ``rigs``) from ``<out>.csv`` when it
    exists, in :data:`RIGS` order (the import rows first, as a full run writes them), and the note
    saying which rows were kept."""
    old = Path(f"{out}.csv")
    others = [r for r in RIGS if r not in rigs]
    if not others or not old.is_file():
        return df, note
    prev = pd.read_csv(old)
    prev = prev[prev["rig"].isin(others)]
    if prev.empty:
        return df, note
    both = pd.concat([prev, df], ignore_index=True)
    order = both["rig"].map({r: i for i, r in enumerate(RIGS)}) + 100 * (both["mode"] != "import")
    both = both.iloc[order.argsort(kind="stable")].reset_index(drop=True)
    return both, note + f" The rows of {', '.join(sorted(prev['rig'].unique()))} are an earlier run's (kept: --rigs)."


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--max-minutes", type=float, default=360.0, help="longest record, min (default 360 = 6 h)")
    ap.add_argument("--format", default="csv", choices=("csv", "parquet"), help="record file format")
    ap.add_argument("--out", default=None, help="output stem (default benchmarks/bench_memory, "
                                                "benchmarks/bench_memory_imports with --imports-only)")
    ap.add_argument("--rigs", nargs="+", default=list(RIGS), choices=RIGS, help="the rigs to measure (default all)")
    ap.add_argument("--imports-only", action="store_true", help="only the import rows (seconds)")
    ap.add_argument("--from-csv", default=None, help="rewrite the tables from this earlier output's .csv "
                                                     "(no run; the note is kept from its .md)")
    ap.add_argument("--src", default=None, help="run the children on the platcal of this source folder "
                                                "(PYTHONPATH), e.g. another worktree's src, to compare")
    a = ap.parse_args(argv)
    if a.out is None:
        a.out = str(ROOT / "benchmarks" / ("bench_memory_imports" if a.imports_only else "bench_memory"))
    if a.from_csv:
        md = Path(a.from_csv).with_suffix(".md").read_text().splitlines()
        note = next((line for line in md if line.startswith("Peak RSS (ru_maxrss")), "")
        write_tables(pd.read_csv(a.from_csv), a.out, note)
        print(f"-> {a.out}.csv, .md, {a.out}_by_length.csv, .md", file=sys.stderr)
        return 0
    env = dict(os.environ, NUMBA_NUM_THREADS=os.environ.get("NUMBA_NUM_THREADS", "1"))
    if a.src:
        env["PYTHONPATH"] = str(Path(a.src).resolve())
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as tmp:
        folder = Path(tmp)
        base = [sys.executable, "-m", "platcal.cli"]
        if not a.imports_only:
            warm_up(base, cases(a.max_minutes, folder, tuple(a.rigs)), folder, env)
        for rig, minutes, mode, cfg, sim_opts, id_opts in cases(a.max_minutes, folder, tuple(a.rigs)):
            if mode == "import":
                res = run(base + ["identify", "--config", str(cfg), *id_opts], env)
                rows.append({"rig": rig, "record_min": float("nan"), "mode": mode, "command": "identify --help",
                             "rows": 0, "file_mb": 0.0, **res})
                print(rows[-1], file=sys.stderr, flush=True)
                continue
            if a.imports_only:
                continue
            data = folder / f"{rig}_{minutes}_{mode}.{a.format}"
            big = ["--max-memory-gb", "64"]  # measured, not refused by the size check
            sim = run(base + ["simulate", "--config", str(cfg), *sim_opts, *big, "--out", str(data)], env)
            size_mb = data.stat().st_size / 1e6
            t = (pd.read_csv(data, usecols=[0]).iloc[:, 0] if a.format == "csv"
                 else pd.read_parquet(data, columns=["t"])["t"])  # every rig's records start with t, s
            # a natural-length record's span (the sled's and the low-precision run's t is one clock;
            # the centrifuge's restarts at each position, so a scaled case gives its length)
            n_rows = len(t)
            length_min = float(minutes) if minutes is not None else float(t.iloc[-1] - t.iloc[0]) / 60.0
            del t
            ident = run(base + ["identify", "--config", str(cfg), *id_opts, *big, "--data", str(data),
                                "--out", str(folder / f"id_{rig}_{minutes}_{mode}")], env)
            for command, res in (("simulate", sim), ("identify", ident)):
                rows.append({"rig": rig, "record_min": length_min,
                             "mode": mode, "command": command, "rows": n_rows, "file_mb": size_mb, **res})
                print(rows[-1], file=sys.stderr, flush=True)
            data.unlink()
    df = pd.DataFrame(rows)
    load = os.getloadavg()
    note = (f"Peak RSS (ru_maxrss of the child process) of `platcal simulate` and `platcal identify` against record "
            f"length; CPU and wall s. Load average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on "
            f"{os.cpu_count()} cores, NUMBA_NUM_THREADS={env['NUMBA_NUM_THREADS']}, {a.format} records. "
            "`python benchmarks/bench_memory.py`.")
    df, note = kept_rows(df, note, a.out, tuple(a.rigs))
    write_tables(df, a.out, note)
    print(f"-> {a.out}.csv, .md, {a.out}_by_length.csv, .md", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
