"""Issue 25 item 4 in the workflow: a job that meets a full disk, no permission or bad input ends
as the command line does -- one line naming the path or field, exit status 2, no traceback, nothing
half-written -- through the one job entry point every workflow script starts
(:func:`platcal.log.job_logger`, translating with :func:`platcal.errors.error_line`).

The job is a real workflow script (``workflow/scripts/sled_observability.py``, the cheapest rule)
run as Snakemake runs a ``script:`` -- its own Python process with a ``snakemake`` object in its
globals -- with the table writer failing as a full disk makes it fail (``OSError(ENOSPC)``; root
ignores a read-only mode, so the fault is injected, as in tests/test_bad_input_sweep.py).
"""

import os
import subprocess
import sys
from pathlib import Path

from file_snapshot import snapshot

SCRIPT = Path(__file__).resolve().parents[1] / "workflow" / "scripts" / "sled_observability.py"
# Snakemake's preamble, reduced to what the script reads, then the script, as its own process
RUN = """
import errno, os, runpy, sys
from types import SimpleNamespace
import pandas as pd
script, out, log, fault = sys.argv[1:]
if fault == "enospc":
    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), a[1] if len(a) > 1 else k.get("path_or_buf"))
    pd.DataFrame.to_csv = full
cfg = {"rig": "sled"} if fault != "bad" else {"rig": "sled", "imu": {"rate_hz": -5}}
sm = SimpleNamespace(output=[out], log=[log], params=SimpleNamespace(cfg=cfg))
runpy.run_path(script, init_globals={"snakemake": sm}, run_name="__main__")
"""


def _job(tmp_path, fault: str):
    out = tmp_path / "results" / "rank_table.csv"
    out.parent.mkdir()
    log = tmp_path / "logs" / "observability.log"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "NUMBA_NUM_THREADS": "1"}
    before = snapshot(out.parent)
    p = subprocess.run([sys.executable, "-c", RUN, str(SCRIPT), str(out), str(log), fault], capture_output=True,
                       text=True, env=env, timeout=120)
    return p, out, log, before


def test_full_disk_ends_the_job_with_one_line(tmp_path):
    p, out, log, before = _job(tmp_path, "enospc")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr, p.stderr
    lines = [ln for ln in p.stderr.splitlines() if "error:" in ln]
    assert len(lines) == 1 and "No space left on device" in lines[0] and "rank_table" in lines[0], p.stderr
    assert "No space left on device" in log.read_text()   # the job's log says it too
    assert snapshot(out.parent) == before                   # nothing half-written, no temporary


def test_bad_input_ends_the_job_with_the_field(tmp_path):
    p, out, log, before = _job(tmp_path, "bad")
    assert p.returncode == 2, p.stderr
    assert "Traceback" not in p.stderr and "error: imu.rate_hz" in p.stderr, p.stderr


def test_clean_job_still_writes(tmp_path):
    p, out, log, before = _job(tmp_path, "none")
    assert p.returncode == 0, p.stderr
    assert out.exists() and out.with_suffix(".md").exists()


def test_the_exit_hook_is_a_workflow_jobs_only():
    """Called outside a Snakemake job (a test, a notebook), the job logger leaves the interpreter's
    exception hook alone: an InputError there must not end the process with os._exit."""
    from platcal.log import job_logger

    before = sys.excepthook
    job_logger(None, "platcal.test")
    assert sys.excepthook is before
