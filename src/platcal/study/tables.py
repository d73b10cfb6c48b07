"""The one table writer: CSV for machines, Markdown and HTML for people (atomic writes)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import atomic_to_csv, atomic_write_text


def _fmt(v, spec):
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return format(v, spec)


def frame_markdown(df: pd.DataFrame, formats: dict[str, str] | None = None) -> str:
    """A DataFrame as a Markdown table (no tabulate dependency); ``formats`` by column."""
    formats = formats or {}
    cols = list(df.columns)
    lines = ["| " + " | ".join(str(c) for c in cols) + " |",
             "|" + "|".join("---:" if pd.api.types.is_numeric_dtype(df[c]) else "---" for c in cols) + "|"]
    specs = [formats.get(c, "g") for c in cols]
    # the rows of df.values are the values iterrows gives (one common dtype: ints read as
    # floats beside float columns), without building a Series per row (14 000 rows a second
    # or more in the low-precision report's cross-validation table; issue 22 item 4)
    for row in df.values:
        lines.append("| " + " | ".join(_fmt(v, f) for v, f in zip(row, specs)) + " |")
    return "\n".join(lines) + "\n"


def frame_html(df: pd.DataFrame, title: str, note: str = "", formats: dict[str, str] | None = None) -> str:
    """A self-contained HTML page with one table (for people and ``snakemake --report``)."""
    formats = formats or {}
    shown = df.copy()
    for c in shown.columns:
        if c in formats:
            shown[c] = [_fmt(v, formats[c]) for v in shown[c]]
    body = shown.to_html(index=False, border=0, classes="t", na_rep="-")
    # text columns read left-aligned, numbers right-aligned (the columns' dtypes before formatting)
    left = "".join(f"table.t td:nth-child({i + 1}),table.t th:nth-child({i + 1}){{text-align:left}}"
                   for i, c in enumerate(df.columns) if not pd.api.types.is_numeric_dtype(df[c]))
    return ("<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>" + title + "</title>\n"
            "<style>body{font-family:sans-serif;margin:1em}table.t{border-collapse:collapse;font-size:13px}"
            "table.t td,table.t th{border-bottom:1px solid #ddd;padding:2px 8px;text-align:right}"
            "table.t th{background:#f0f0f0}" + left + "</style></head><body>\n"
            f"<h2>{title}</h2>\n<p>{note}</p>\n{body}\n</body></html>\n")


def write_table(df: pd.DataFrame, stem: str | os.PathLike, title: str, note: str = "",
                formats: dict[str, str] | None = None, md_extra: str = "", shown: pd.DataFrame | None = None) -> None:
    """Write ``stem.csv`` (``df``, full precision), ``stem.md`` and ``stem.html`` (formatted; of
    ``shown`` when given: the same rows as people read them), atomically."""
    stem = Path(stem)
    people = df if shown is None else shown
    atomic_to_csv(df, stem.with_suffix(".csv"))
    atomic_write_text(stem.with_suffix(".md"), f"# {title}\n\n{note}\n\n" + frame_markdown(people, formats) + md_extra)
    atomic_write_text(stem.with_suffix(".html"), frame_html(people, title, note, formats))
