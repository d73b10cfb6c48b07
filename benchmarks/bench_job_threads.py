"""A one-thread job at numba's default threads (every core) against the rule's one thread
(issue 22 item 4): the campaign plan (rule ``campaign_plan``) and the centrifuge's observability
of table1 (rule ``multiposition_centrifuge_table1``), each in a fresh process on an empty numba
cache (cold, as from a fresh clone) or on one the run before filled (warm), alternating the two
settings. Prints wall and CPU seconds (user + system, the child's), the load, and whether the
outputs are byte-identical but for the seconds fields (the check's and the observability's).

    python benchmarks/bench_job_threads.py [--jobs campaign table1] [--rounds 1] [--warm]
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

JOBS = {
    # what the wrappers in workflow/scripts run; at the rule's threads (set_threads here, the job's
    # OMP_NUM_THREADS through platcal/__init__.py in the workflow) when threads is given
    "campaign": ("from platcal.study.campaign import run_campaign\nfrom platcal.study.campaign_file import campaign_content\n"
                 "run_campaign(campaign_content('config/campaign.yaml'), OUT)\n"),
    "table1": ("import yaml\nfrom platcal.cli import main\nfrom platcal.io import read_config\n"
               "cfg = {k: v for k, v in read_config('config/centrifuge.yaml', 'config').items() if k != 'study'}\n"
               "p = OUT / 'config.yaml'\np.write_text(yaml.safe_dump(cfg))\n"
               "main(['observability', '--config', str(p), '--scheme', 'table1', '--out', str(OUT / 'obs')])\n"
               "p.unlink()\n"),
}
TIMING = ("check.csv", "check.md", "check.html", "report.md", "observability.json")
"""Outputs holding a job's seconds (compared without those lines)."""


def run(job: str, threads: int | None, out: Path, cache: Path) -> tuple[float, float]:
    """(wall s, CPU s) of ``job`` in a fresh interpreter with numba's cache at ``cache``."""
    head = "import sys\nfrom pathlib import Path\nOUT = Path(sys.argv[1])\n"
    if threads:
        head += f"from platcal.parallel import set_threads\nset_threads({threads})\n"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    env.pop("NUMBA_NUM_THREADS", None)  # numba's default: every core, as Snakemake leaves it
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", head + JOBS[job], str(out)], cwd=ROOT, env=env, check=True,
                   capture_output=True)
    wall = time.perf_counter() - t0
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (c1.ru_utime - c0.ru_utime) + (c1.ru_stime - c0.ru_stime)


def same_but_seconds(a: Path, b: Path) -> bool:
    """Every file of ``a`` equal in ``b``, but the seconds: the key ``seconds`` of a JSON file,
    the last field of a table row (the check's seconds column) in the TIMING files."""
    for p in sorted(x for x in a.rglob("*") if x.is_file()):
        q = b / p.relative_to(a)
        if p.name not in TIMING:
            if not filecmp.cmp(p, q, shallow=False):
                return False
        elif p.suffix == ".json":
            if json.loads(p.read_text()) | {"seconds": 0} != json.loads(q.read_text()) | {"seconds": 0}:
                return False
        else:
            for x, y in zip(p.read_text().splitlines(), q.read_text().splitlines(), strict=True):
                cut = "|" if x.startswith("|") else ","
                if x != y and x.rstrip(" |").rsplit(cut, 1)[0] != y.rstrip(" |").rsplit(cut, 1)[0]:
                    return False
    return True


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", nargs="+", default=list(JOBS), choices=list(JOBS))
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--warm", action="store_true", help="warm caches (each setting's own, filled first)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for job in a.jobs:
            for r in range(a.rounds):
                for name, threads in (("every core", None), ("one thread", 1)) if r % 2 == 0 else \
                        (("one thread", 1), ("every core", None)):
                    cache = d / f"cache-{job}-{threads}-{r if not a.warm else 0}"
                    out = d / f"out-{job}-{threads}"
                    out.mkdir(exist_ok=True)
                    if a.warm and not cache.exists():
                        run(job, threads, out, cache)
                    load = os.getloadavg()[0]
                    wall, cpu = run(job, threads, out, cache)
                    print(f"{job:9s} {name:10s} {'warm' if a.warm else 'cold'}: {wall:6.1f} s wall, {cpu:6.1f} s CPU, "
                          f"load {load:.1f} -> {os.getloadavg()[0]:.1f}", flush=True)
            print(f"{job}: outputs byte-identical but the seconds: "
                  f"{same_but_seconds(d / f'out-{job}-None', d / f'out-{job}-1')}", flush=True)


if __name__ == "__main__":
    main()
