"""Shared by the workflow tests: a temporary copy of the workflow and Snakemake run in it, so the
repository's results/ is never touched."""

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake"]

needs_snakemake = pytest.mark.skipif(subprocess.run(SNAKEMAKE + ["--version"], capture_output=True).returncode != 0,
                                     reason="snakemake is not installed")


def copy_workflow(d: Path, profiles: bool = False) -> Path:
    """``d`` (created) holding the Snakefile, workflow/ and config/ (and profiles/); symlinks
    (the schema) are copied as files."""
    d.mkdir(parents=True)
    shutil.copy(ROOT / "Snakefile", d)
    for sub in ("workflow", "config") + (("profiles",) if profiles else ()):
        shutil.copytree(ROOT / sub, d / sub, symlinks=False)
    return d


def snakemake(d: Path, *args, timeout=300, env=None) -> subprocess.CompletedProcess:
    """Run snakemake in ``d`` (PYTHONHASHSEED=0); on timeout, end its whole process group (its
    jobs too) and raise. The timeout guards against a hang, not the speed."""
    env = dict(env or os.environ, PYTHONHASHSEED="0")
    p = subprocess.Popen(SNAKEMAKE + list(args), cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=env, start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        raise
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)
