"""Where a study's time goes: the Snakemake ``benchmark:`` files of its jobs, summed per rig and
per rule (issue 22 item 4; the "Where the time goes" table of ``results/report.md``).

Every rule of the workflow writes ``results/benchmarks/<rig>/<rule>/<job>.tsv`` (``bench`` in
``workflow/rules/common.smk``; ``<rig>`` is ``study`` or ``campaign`` for the rules of the whole
study). Snakemake's file holds the job's wall time ``s`` (seconds, exact), ``cpu_time`` (CPU
seconds of the job's processes, user + system, *sampled*: every 0.5 s for the first 30 s, then
every 30 s, so a long job's last seconds are missing and the figure is a lower bound) and
``max_rss`` (MB, sampled the same way). A job forked by the study's fork server
(:mod:`platcal.study.forkserver`) ran in a child of the server, which Snakemake does not watch:
its CPU s (exact, from ``wait4``) and peak RSS are in ``<job>.worker.json`` beside the file,
written just before Snakemake writes ``<job>.tsv`` (:data:`WORKER_LAG_S`).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from ..errors import InputError
from .forkclient import worker_file
from .tables import write_table

COLUMNS = ("s", "cpu_time", "max_rss")
"""What the table reads from a benchmark file: wall s, CPU s, peak RSS MB."""
TOTAL = "all rules"
TIMING_FORMATS = {"wall_s": ".1f", "cpu_s": ".1f", "share_pct": ".1f", "max_s": ".1f", "max_rss_mb": ".0f"}
TIMING_NOTE = ("Job-seconds per rig and rule from the Snakemake benchmark files (results/benchmarks/"
               "<rig>/<rule>/<job>.tsv) of the latest run of each job of this study's rigs: wall_s sums the "
               "jobs' wall seconds "
               "(jobs run side by side, so the sum exceeds the study's wall time), cpu_s their CPU seconds "
               "(exact for a job the fork server ran, from its <job>.worker.json; else as Snakemake "
               "samples them, a lower bound for jobs over 30 s), max_s the longest job. "
               "report_index, which writes this table, is not in it.")


WORKER_LAG_S = 60.0
"""A ``<job>.worker.json`` is the run's if Snakemake wrote ``<job>.tsv`` at most this long after it
(a later run of the job in its own interpreter leaves an older one)."""


def worker_cost(tsv: Path) -> dict | None:
    """The fork server's figures of the job run ``tsv`` records (cpu_s, max_rss_mb), or None."""
    side = worker_file(tsv)
    if not side.exists() or not 0.0 <= tsv.stat().st_mtime - side.stat().st_mtime <= WORKER_LAG_S:
        return None
    return json.loads(side.read_text())


STUDY_WIDE = ("study", "campaign")
"""The ``<rig>`` folders of the rules of the whole study."""


def read_benchmarks(root, rigs=None) -> pd.DataFrame:
    """One row per benchmark file under ``root`` (``<rig>/<rule>/<job>.tsv``): rig, rule, job,
    wall_s, cpu_s, max_rss_mb (NaN where Snakemake wrote NA: a job shorter than its first sample).
    ``rigs``: only theirs and the study-wide rules' (a rig left out of this study keeps its files
    from an earlier one). An empty frame when there is none (a study run without benchmarks)."""
    rows = []
    for f in sorted(Path(root).glob("*/*/*.tsv")):
        rig, rule = f.parent.parent.name, f.parent.name
        if rigs is not None and rig not in set(rigs) | set(STUDY_WIDE):
            continue
        bench = pd.read_csv(f, sep="\t", na_values=["NA", "-"])
        missing = [c for c in COLUMNS if c not in bench.columns]
        if missing:
            raise InputError(str(f), f"not a Snakemake benchmark file (no column {', '.join(missing)}); "
                             "delete it and rerun the rule")
        last = bench.iloc[-1]  # a --benchmark-repeats run holds several rows: the last is this run
        cost = worker_cost(f) or {"cpu_s": float(last["cpu_time"]), "max_rss_mb": float(last["max_rss"])}
        rows.append({"rig": rig, "rule": rule, "job": f.stem, "wall_s": float(last["s"]),
                     "cpu_s": float(cost["cpu_s"]), "max_rss_mb": float(cost["max_rss_mb"])})
    return pd.DataFrame(rows, columns=["rig", "rule", "job", "wall_s", "cpu_s", "max_rss_mb"])


def where_the_time_goes(jobs: pd.DataFrame) -> pd.DataFrame:
    """Job-seconds summed per (rig, rule), largest first within each rig, each rig closed by its
    total (rule ``all rules``) and the study by a grand total (rig ``all rigs``): jobs, wall_s (sum
    of the jobs' wall seconds), cpu_s (sum of sampled CPU seconds), share_pct (of the study's
    wall job-seconds), max_s (the longest job) and max_rss_mb (the largest peak)."""
    cols = ["rig", "rule", "jobs", "wall_s", "cpu_s", "share_pct", "max_s", "max_rss_mb"]
    if jobs.empty:
        return pd.DataFrame(columns=cols)
    agg = dict(jobs=("job", "size"), wall_s=("wall_s", "sum"), cpu_s=("cpu_s", "sum"), max_s=("wall_s", "max"),
               max_rss_mb=("max_rss_mb", "max"))
    total = float(jobs["wall_s"].sum())
    parts = []
    by_rig = jobs.groupby("rig").agg(**agg).sort_values("wall_s", ascending=False)
    for rig in by_rig.index:
        rules = jobs[jobs["rig"] == rig].groupby("rule").agg(**agg).sort_values("wall_s", ascending=False)
        rules = rules.reset_index().assign(rig=rig)
        parts += [rules, by_rig.loc[[rig]].reset_index().assign(rule=TOTAL)]
    grand = jobs.assign(rig="all rigs").groupby("rig").agg(**agg).reset_index().assign(rule=TOTAL)
    out = pd.concat(parts + [grand], ignore_index=True)
    out["share_pct"] = 100.0 * out["wall_s"] / total if total > 0 else float("nan")
    return out[cols]


def write_timing(root, stem, rigs=None) -> pd.DataFrame:
    """``stem.{csv,md,html}``: :func:`where_the_time_goes` of the benchmark files under ``root``
    (of ``rigs`` and the study-wide rules; all when None), with the one table writer; returns the
    table."""
    table = where_the_time_goes(read_benchmarks(root, rigs))
    write_table(table, stem, "Where the time goes", TIMING_NOTE, formats=TIMING_FORMATS)
    return table
