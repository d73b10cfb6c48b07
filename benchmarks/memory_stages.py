"""What a streamed ``platcal identify`` holds, stage by stage (issue 22 item 3: the baseline).

Runs one ``platcal identify`` in this process and reports the resident set (``VmRSS`` of
/proc/self/status, MB) after the interpreter and numpy start, after the CLI and the rig's
command module are imported (``platcal.rig.resolve``: what ``identify --help`` loads), when the
first chunk of the record has been read (the rig's numba kernels not yet run), and the peak
(``VmHWM``) at the end; with ``--trace`` also the peak of the Python-side allocations
(tracemalloc: numpy arrays and pandas frames, not numba's or the C parser's), which is what the
record's length can make grow. At the import stage and at the end it also names the heavy
libraries loaded (pandas, pyarrow, scipy, pint, jsonschema, numba, ...) with the platcal modules
that import each at their top, and counts the numba kernels (dispatchers of the loaded platcal
modules) that hold a compiled or cache-loaded specialisation: those of the command, or all of
the rig's.

    python benchmarks/memory_stages.py --config config/multiposition.yaml -- --scheme S8 --data rec.csv --out /tmp/id
    python benchmarks/memory_stages.py --trace --config ... -- ...

Prints one line per stage.
"""

from __future__ import annotations

import argparse
import re
import resource
import sys
import tracemalloc
from pathlib import Path

import numpy as np  # noqa: F401  (the floor: the interpreter with numpy)

import platcal.records as records


def status_mb(key: str) -> float:
    """``VmRSS`` or ``VmHWM`` of this process, MB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise KeyError(key)


HEAVY = ("pandas", "pyarrow", "scipy", "pint", "jsonschema", "numba", "pymap3d", "matplotlib", "sympy")
"""The libraries whose import is most of a command's floor."""


def heavy_loaded() -> list[str]:
    """Each library of :data:`HEAVY` loaded in this process, with the platcal modules that import
    it at their top (``import x`` / ``from x`` at the start of a line)."""
    out = []
    for lib in HEAVY:
        if lib not in sys.modules:
            continue
        who = []
        for name, mod in sorted(sys.modules.items()):
            path = getattr(mod, "__file__", None) if name.startswith("platcal") else None
            if path and re.search(rf"^(import|from) {lib}\b", Path(path).read_text(), re.M):
                who.append(name.removeprefix("platcal."))
        out.append(f"{lib} ({', '.join(who) or 'through another library'})")
    return out


def kernels() -> tuple[int, int]:
    """``(holding a specialisation, all)``: numba dispatchers defined in the loaded platcal modules."""
    if "numba" not in sys.modules:
        return 0, 0
    from numba.core.dispatcher import Dispatcher  # numba is loaded already: no import cost here

    seen = {}
    for name, mod in list(sys.modules.items()):
        if name.startswith("platcal"):
            for obj in vars(mod).values():
                if isinstance(obj, Dispatcher):
                    seen[id(obj)] = obj
    return sum(bool(d.signatures) for d in seen.values()), len(seen)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", required=True, help="the rig's config")
    ap.add_argument("--trace", action="store_true", help="also the peak of Python-side allocations (slower)")
    ap.add_argument("rest", nargs=argparse.REMAINDER, help="-- then identify's own options")
    a = ap.parse_args(argv)
    rest = a.rest[1:] if a.rest[:1] == ["--"] else a.rest
    stages = [("numpy and platcal.records", status_mb("VmRSS"))]
    from platcal.cli import main as cli_main  # the command's own imports, measured as a stage
    from platcal.io import read_yaml
    from platcal.rig import get_rig

    get_rig(read_yaml(Path(a.config).read_text())["rig"]).command("identify")
    stages.append(("the CLI and the rig's identify module", status_mb("VmRSS")))
    libs_at_import, kernels_at_import = heavy_loaded(), kernels()
    first: dict = {}
    reader = records.iter_frames

    def watched(*args, **kw):
        for i, df in enumerate(reader(*args, **kw)):
            if i == 0 and not first:
                first["rss"] = status_mb("VmRSS")
            yield df

    records.iter_frames = watched  # the first chunk's RSS, whatever reads it
    if a.trace:
        tracemalloc.start()
    code = cli_main(["identify", "--config", a.config, *rest])
    if "rss" in first:
        stages.append(("the first chunk read", first["rss"]))
    stages.append(("peak (VmHWM)", status_mb("VmHWM")))
    for name, mb in stages:
        print(f"{name:45s} {mb:8.1f} MB")
    if a.trace:
        print(f"{'peak of traced Python allocations':45s} {tracemalloc.get_traced_memory()[1] / 2**20:8.1f} MB")
    print("libraries at import: " + "; ".join(libs_at_import))
    print("libraries at the end: " + "; ".join(heavy_loaded()))
    for when, (hot, every) in (("import", kernels_at_import), ("the end", kernels())):
        print(f"numba kernels with a specialisation at {when}: {hot} of the {every} in the loaded platcal modules")
    usage = resource.getrusage(resource.RUSAGE_SELF)
    print(f"exit {code}, CPU {usage.ru_utime + usage.ru_stime:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
