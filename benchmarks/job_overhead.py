"""Per-job start-up overhead of the workflow's cell jobs, by phase (issue 22 item 4).

Runs a job script that Snakemake generated (its preamble holds the pickled ``snakemake``
object: keep it with ``--skip-script-cleanup``) the way Snakemake runs it, in this process,
and prints the process CPU seconds of each phase as one JSON line: the preamble (unpickling),
the wrapper's imports, the rig's package import (``get_rig``), the config check (the rig's
``montecarlo.check`` hook, or ``check_study`` in the centrifuge's comparison cells), the cell's
compute (``run_cell``: simulation, filter and the numba cache load), the writing
(``write_cell``), the rest, and ``overhead`` = the job's CPU minus ``run_cell``'s. CPU, not
wall, so that a loaded machine changes the figures little. The job rewrites its outputs.

    snakemake --cores 2 --skip-script-cleanup results/centrifuge/runs/random_3/noise5/ekfw/coef.parquet
    NUMBA_NUM_THREADS=1 python benchmarks/job_overhead.py .snakemake/scripts/tmp*.montecarlo_cell.py
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time


def cpu() -> float:
    """The process's CPU seconds so far (user + system)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed(f, acc: dict, key: str):
    """``f`` adding its CPU seconds to ``acc[key]``."""
    def w(*a, **k):
        c0 = cpu()
        try:
            return f(*a, **k)
        finally:
            acc[key] = acc.get(key, 0.0) + cpu() - c0
    return w


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("script", help="a job script kept by snakemake --skip-script-cleanup")
    args = ap.parse_args(argv)
    startup = cpu()  # the interpreter's own start, before this script's first line
    src = open(args.script, encoding="utf-8").read()
    head, sep, body = src.partition("\nsm = snakemake")
    if not sep:
        print(f"{args.script}: not a platcal wrapper script (no 'sm = snakemake' line)", file=sys.stderr)
        return 2
    pre, _, imports = head.partition("######## snakemake preamble end #########")
    T: dict[str, float] = {"startup": startup}
    g = {"__name__": "__main__", "__file__": args.script}
    c = cpu()
    exec(compile(pre, "preamble", "exec"), g)
    T["preamble_unpickle"] = cpu() - c
    c = cpu()
    exec(compile(imports, "imports", "exec"), g)
    T["imports"] = cpu() - c
    # platcal is imported here, not at the top: its import is a phase of the job being measured
    c = cpu()
    from platcal.rig import get_rig
    import platcal.study.montecarlo as mc
    hooks = get_rig(getattr(g["snakemake"].wildcards, "rig", "centrifuge")).montecarlo
    T["get_rig(rig import)"] = cpu() - c
    acc: dict[str, float] = {}
    # the compute: cell_tables where the runner has it (run_cell, the DataFrame form, calls it),
    # run_cell on a tree before it; counted as "run_cell" either way, so trees compare
    compute = "cell_tables" if hasattr(mc, "cell_tables") else "run_cell"
    for name, key in ((compute, "run_cell"), ("write_cell", "write_cell")):
        original = getattr(mc, name)
        wrapped = timed(original, acc, key)
        for n, mod in list(sys.modules.items()):  # the runner and every module that imported it by name
            if n.startswith("platcal") and mod is not None and vars(mod).get(name) is original:
                setattr(mod, name, wrapped)
    hooks.check = timed(hooks.check, acc, "check")
    for n, mod in list(sys.modules.items()):
        # a module that calls the centrifuge's check_study itself (the comparison's cells); not
        # the study module, whose hook is wrapped above (counted once)
        if n.startswith("platcal") and mod is not None and "check_study" in vars(mod) and not n.endswith(".study"):
            mod.check_study = timed(mod.check_study, acc, "check")
    c, t = cpu(), time.perf_counter()
    exec(compile("sm = snakemake" + body, "body", "exec"), g)
    T["body"] = cpu() - c
    T["body_wall"] = time.perf_counter() - t
    T.update(acc)
    T["body_other"] = T["body"] - sum(acc.values())
    T["job_total"] = startup + T["preamble_unpickle"] + T["imports"] + T["get_rig(rig import)"] + T["body"]
    T["overhead"] = T["job_total"] - acc.get("run_cell", 0.0)
    print(json.dumps({k: round(v, 3) for k, v in T.items()}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
