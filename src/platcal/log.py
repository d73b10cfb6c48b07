"""The one job logger: timestamped lines to a job's log file and to stderr."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path


def job_logger(path: str | os.PathLike | None, name: str = "platcal.job") -> logging.Logger:
    """A logger writing timestamped lines to ``path`` (a job's log) and to stderr."""
    lg = logging.getLogger(name)
    lg.setLevel(logging.INFO)
    lg.handlers.clear()
    lg.propagate = False
    fmt = logging.Formatter("%(asctime)s %(message)s", "%H:%M:%S")
    h = logging.StreamHandler(sys.stderr)
    h.setFormatter(fmt)
    lg.addHandler(h)
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fh = logging.FileHandler(path, mode="w")
        fh.setFormatter(fmt)
        lg.addHandler(fh)
    return lg


def eta_line(done: int, total: int, seconds: float) -> str:
    """``12/40 done, 3.1 s elapsed, ETA 7.2 s`` for progress lines of long jobs."""
    eta = seconds / done * (total - done) if done else float("nan")
    return f"{done}/{total} done, {seconds:.1f} s elapsed, ETA {eta:.1f} s"
