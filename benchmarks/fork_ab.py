"""A Monte Carlo cell job in a fresh interpreter against the same job forked from a process that
has done the fork server's imports (issue 22 item 4; :mod:`platcal.study.forkserver`).

This process first does what the workflow's fork server does before it serves
(:func:`platcal.study.forkserver.preload` of the workflow scripts' imports and every rig's hooks,
numba's CPU target included). Then, for each cell (the first noise level of ``rig:case``, every
estimator of the default config: :mod:`job_ab`'s child) and each round, the job runs once in a
fresh interpreter (process CPU from ``RUSAGE_CHILDREN``) and once in a child forked from this
process running the same child code (CPU from ``wait4``). One numba and one BLAS thread; numba's
cache warmed by one fresh run of each cell first. Prints CPU / wall seconds per run.

    cd benchmarks && python fork_ab.py --rounds 3
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[var] = "1"

from job_ab import CHILD  # noqa: E402

from platcal.rig import rig_names  # noqa: E402
from platcal.study.forkserver import preload, script_imports  # noqa: E402

ROOT = str(Path(__file__).resolve().parents[1])
CELLS = ("centrifuge:table1", "multiposition:S8", "lowprec_centrifuge:default", "sled:default")


def child_args(cell: str, out: str) -> list[str]:
    """``job_ab``'s child's arguments: the cell job once, no timed repeat."""
    return [f"cell:{cell}", ROOT, out, "0"]


def fresh(cell: str, out: str) -> tuple[float, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", CHILD, *child_args(cell, out)], cwd=ROOT, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, time.perf_counter() - t


def forked(cell: str, out: str) -> tuple[float, float]:
    t = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(null, 2)
            os.chdir(ROOT)
            sys.argv = ["-c", *child_args(cell, out)]
            exec(CHILD, {"__name__": "__main__"})
            code = 0
        finally:
            os._exit(code)
    _, status, ru = os.wait4(pid, 0)
    if os.waitstatus_to_exitcode(status):
        raise RuntimeError(f"{cell}: the forked job failed")
    return ru.ru_utime + ru.ru_stime, time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    t0 = time.process_time()
    preload(script_imports(f"{ROOT}/workflow/scripts"), list(rig_names()))
    print(f"the server's preload: {time.process_time() - t0:.2f} s CPU; load {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as d:
        for c in CELLS:
            fresh(c, f"{d}/warm_{c.replace(':', '_')}")
        res = {}
        for r in range(a.rounds):
            for c in CELLS:
                for kind, fn in (("fresh", fresh), ("fork", forked)):
                    res.setdefault((c, kind), []).append(fn(c, f"{d}/{kind}{r}_{c.replace(':', '_')}"))
    for (c, kind), runs in res.items():
        print(f"{c} {kind} (CPU/wall s) " + " ".join(f"{cpu:.2f}/{w:.2f}" for cpu, w in runs))
    print(f"load {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
