"""The low-precision centrifuge's §11 checks (docs/lowprec-centrifuge.md §11, §12) over several root
seeds: is a failed check on the study's root seed sampling noise or a real shortfall?

For each root seed (the config's ``seed``), the default scenario and the perfect and worst
centrifuges are run with the study's replicates per cell on the generic runner (the pipeline's
cells), and :func:`platcal.rigs.lowprec_centrifuge.study.acceptance` is evaluated as the pipeline
does. Per root, one row per check (appended to ``--out`` as each root finishes, so an interrupted
run keeps what it has); ``--summary`` prints per check the share of roots that pass and the spread
of the measured value (its first number).

    python benchmarks/lowprec_seed_roots.py --roots 0 1 2 3 4 5 6 7 --out seed_roots.csv
    python benchmarks/lowprec_seed_roots.py --summary seed_roots.csv
"""

from __future__ import annotations

import argparse
import re
import time
from pathlib import Path

import pandas as pd

from platcal.io import read_config
from platcal.rig import get_rig
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.montecarlo import study_frames
from platcal.rigs.lowprec_centrifuge.study import acceptance
from platcal.study.montecarlo import run_cell

NUMBER = re.compile(r"[-+]?\d+\.?\d*(?:e[-+]?\d+)?")


def scenario_tables(cfg: dict, name: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Cross-validation and coefficient tables of one scenario's cells (both methods)."""
    rig = get_rig("lowprec_centrifuge")
    h = rig.montecarlo
    cells = [run_cell(rig, cfg, h.case(cfg, name), h.noise_levels(cfg)[0], e) for e in h.estimators(cfg)]
    cross, coeffs = study_frames(load_config(cfg), [name], pd.concat([c[0] for c in cells]),
                                 pd.concat([c[1] for c in cells]))
    return cross.drop(columns="scenario"), coeffs.drop(columns="scenario")


def measured_value(text: str) -> float:
    """The number a check is judged on from its ``measured`` text: the difference in points when
    one is given in parentheses (``a -> b (+d pp)``), else the first number."""
    m = re.search(r"\(([-+]?[\d.]+) pp\)", text)
    return float(m.group(1)) if m else float(NUMBER.search(text).group())


def checks_of_root(raw: dict, root: int) -> pd.DataFrame:
    """The §11 checks of the pipeline's acceptance table with root seed ``root``."""
    cfg = get_rig("lowprec_centrifuge").montecarlo.check({**raw, "seed": int(root)})
    d, p, w = (scenario_tables(cfg, n) for n in ("default", "perfect", "worst"))
    t = acceptance(d[0], d[1], p[0], p[1], w[0], w[1])
    t.insert(0, "root", int(root))
    t["value"] = [measured_value(m) for m in t["measured"]]
    return t


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per check: roots run, share passing (%), and the measured value's min, median, max."""
    g = table.groupby(["item", "check"], sort=False)
    return pd.DataFrame({"roots": g["root"].nunique(), "pass_pct": 100 * g["pass"].mean(),
                         "min": g["value"].min(), "median": g["value"].median(),
                         "max": g["value"].max()}).reset_index()


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="config/lowprec_centrifuge.yaml")
    ap.add_argument("--roots", type=int, nargs="*", default=list(range(8)))
    ap.add_argument("--out", default="lowprec_seed_roots.csv")
    ap.add_argument("--summary", metavar="CSV", help="summarise a finished --out file and exit")
    args = ap.parse_args(argv)
    if args.summary:
        s = summary(pd.read_csv(args.summary))
        with pd.option_context("display.width", 200, "display.max_colwidth", 90, "display.max_rows", 200):
            print(s.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        return
    raw = read_config(args.config, "--config")
    out = Path(args.out)
    for root in args.roots:
        t0 = time.perf_counter()
        t = checks_of_root(raw, root)
        t.to_csv(out, mode="a", header=not out.exists(), index=False)
        print(f"root {root}: {int(t['pass'].sum())}/{len(t)} pass, {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
