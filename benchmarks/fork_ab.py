"""A Monte Carlo cell job in a fresh interpreter against the same job forked from a process that
has done the fork server's imports (issue 22 item 4; :mod:`platcal.study.forkserver`).

For each cell (the first noise level of ``rig:case``, every estimator of the default config, as
:mod:`job_ab`'s child runs it) and each round: the job once in a fresh interpreter (process CPU
from ``RUSAGE_CHILDREN``) and once in a child forked from this process (CPU from ``wait4``),
after this process imported platcal's study modules, checked every rig's config and loaded numba
and its CPU target (``--init target``; ``--init imports``: without the target). One numba and one
BLAS thread; numba's cache warmed by one fresh run of each cell first. Prints CPU / wall seconds
per run.

    cd benchmarks && python fork_ab.py --rounds 3 --init target
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

from platcal.rig import get_rig, rig_config  # noqa: E402
from platcal.study.montecarlo import cell_job  # noqa: E402

ROOT = str(Path(__file__).resolve().parents[1])
CELLS = ("centrifuge:table1", "multiposition:S8", "lowprec_centrifuge:default", "sled:default")


def checked(rig: str):
    hooks = get_rig(rig).montecarlo
    return hooks, hooks.check(rig_config({"rigs": {rig: f"{ROOT}/config/{rig}.yaml"}}, rig))


def fresh(cell: str, out: str) -> tuple[float, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", CHILD, f"cell:{cell}", ROOT, out, "0"], cwd=ROOT, check=True,
                   capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, time.perf_counter() - t


def forked(cell: str, out: str) -> tuple[float, float]:
    t = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        try:
            rig, case = cell.split(":")
            hooks, raw = checked(rig)
            cell_job(rig, raw, case, hooks.noise_levels(raw)[0], hooks.estimators(raw), out + "/warm")
        finally:
            os._exit(0)
    _, _, ru = os.wait4(pid, 0)
    return ru.ru_utime + ru.ru_stime, time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--init", choices=("imports", "target"), default="target")
    a = ap.parse_args(argv)
    t0 = time.process_time()
    for c in CELLS:
        checked(c.split(":")[0])
    # numba after platcal's modules, as in a job and in the fork server: their kernels are declared first
    import numba.core.registry
    if a.init == "target":
        numba.core.registry.cpu_target.target_context
    print(f"parent's imports and checks: {time.process_time() - t0:.2f} s CPU; load {os.getloadavg()[0]:.2f}")
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
