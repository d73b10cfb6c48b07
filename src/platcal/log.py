"""The one job logger: timestamped lines to a job's log file and to stderr; every workflow job
(``workflow/scripts/*.py``) starts it, so it is also where a job's bad input or failed write
becomes the command line's one-line message and exit status 2 (:func:`platcal.errors.error_line`)."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

from .errors import EXIT_REFUSED, error_line


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
    if _workflow_job():
        sys.excepthook = _one_line_exit(lg)
    return lg


def _workflow_job() -> bool:
    """Whether this process is a Snakemake ``script:`` job: its ``__main__`` holds the ``snakemake``
    object Snakemake's preamble defines. Only there does the job's exit hook replace the
    interpreter's (a test or a notebook calling a job function keeps its own)."""
    return "snakemake" in getattr(sys.modules.get("__main__"), "__dict__", {})


def _one_line_exit(lg: logging.Logger):
    """A ``sys.excepthook`` for a workflow job: an error the user can fix (bad input, a full disk,
    no permission) ends the job with one line naming the field or path (to stderr and the job's
    log, as the command line says it) and exit status 2; any other error keeps its traceback.
    (Snakemake runs a ``script:`` in its own Python process, whose uncaught exception would be a
    traceback and status 1; the atomic writers have already removed their temporaries.)"""
    def hook(kind, exc, tb):
        line = error_line(exc)
        if line is None:
            sys.__excepthook__(kind, exc, tb)
            return
        lg.error(f"platcal job: error: {line}")
        logging.shutdown()   # flush the log file: os._exit skips the interpreter's clean-up
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(EXIT_REFUSED)   # an excepthook cannot set the status; sys.exit would print a second traceback
    return hook


def eta_line(done: int, total: int, seconds: float) -> str:
    """``12/40 done, 3.1 s elapsed, ETA 7.2 s`` for progress lines of long jobs."""
    eta = seconds / done * (total - done) if done else float("nan")
    return f"{done}/{total} done, {seconds:.1f} s elapsed, ETA {eta:.1f} s"
