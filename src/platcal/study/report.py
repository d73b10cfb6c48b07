"""The study's index report: one section per rig, linking the rig's own report.

Each rig writes ``results/<rig>/report.md`` (its tables inline, figures linked); the index
``results/report.md`` lists the rigs with their titles and the sections of their reports, so a
reader starts there whatever rigs the study holds. The report of a rig without rules of its own,
which draws a figure, is :mod:`platcal.study.generic_report`: this module imports no figure
library (the index job's start, issue 22 item 4).
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from ..io import atomic_write_text
from ..rig import get_rig
from .claims import ledger_markdown, ledger_note
from .tables import frame_markdown
from .timing import TIMING_FORMATS, TIMING_NOTE


def _sections(md: Path) -> tuple[str, list[str]]:
    """The title (first ``# `` line) and the ``## `` section titles of a Markdown report."""
    title, sections = "", []
    for line in md.read_text().splitlines():
        if line.startswith("# ") and not title:
            title = line[2:].strip()
        elif line.startswith("## "):
            sections.append(line[3:].strip())
    return title, sections


def _anchor(heading: str) -> str:
    """The GitHub-style anchor of a Markdown heading."""
    keep = "".join(c for c in heading.lower() if c.isalnum() or c in " -_")
    return keep.replace(" ", "-")


def _links(md, out: Path) -> list[str]:
    """A Markdown list linking each ``## `` section of report ``md`` from the folder of ``out``."""
    rel = os.path.relpath(md, out.parent)
    return [f"- [{s}]({rel}#{_anchor(s)})" for s in _sections(Path(md))[1]] + [""]


def write_index(rigs: list[str], reports: list, out_path, ledger=None, campaign=None, timing=None) -> None:
    """``results/report.md``: the claims ledger (``ledger``, the CSV of every rig's claims) first,
    then for each rig its title, spec and a link to each section of its report, then the
    calibration campaign's report (``campaign``, ``results/campaign/report.md``) when one is given,
    then "Where the time goes" (``timing``, :func:`platcal.study.timing.where_the_time_goes`)."""
    out = Path(out_path)
    lines = ["# platcal: identification studies, one section per test rig", "",
             "Written by the Snakemake workflow (`snakemake --cores 2`). Each rig's report holds its "
             "tables inline and links its figures; every number comes from this run's result files.", ""]
    if ledger is not None:
        rows = pd.read_csv(ledger)
        lines += ["## The claims ledger", "", ledger_note(rows), ""]
        for name in rigs:
            part = rows[rows["rig"] == name]
            if len(part):
                lines += [f"### {name}", "", ledger_markdown(part)]
    for name, md in zip(rigs, reports):
        rig = get_rig(name)
        rel = os.path.relpath(md, out.parent)
        title = _sections(Path(md))[0]
        lines += [f"## {name}: {rig.title}", "", f"Spec: `docs/{rig.spec}`. Report: [{title or rel}]({rel})", ""]
        lines += _links(md, out)
    if campaign is not None:
        rel = os.path.relpath(campaign, out.parent)
        title = _sections(Path(campaign))[0]
        lines += ["## The calibration campaign", "", f"Planned across the rigs above (`platcal plan`): "
                  f"[{title or rel}]({rel})", ""] + _links(campaign, out)
    if timing is not None:
        lines += ["## Where the time goes", "", TIMING_NOTE, "", frame_markdown(timing, TIMING_FORMATS)]
    atomic_write_text(out, "\n".join(lines))
