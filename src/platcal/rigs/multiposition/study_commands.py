"""The multi-position rig's ``platcal observability`` (docs/multiposition-1g.md §8): apart from
:mod:`.commands` so that the commands on a log do not import the exact Lie-derivative rank test
(sympy; issue 22 item 3).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pandas as pd

from ...io import atomic_files, check_writable, json_text
from .observability import evaluate


def cmd_observability(cfg, args) -> int:
    scheme = cfg.scheme(args.scheme)
    check_writable(args.out, "--out", folder=True)
    t0 = time.perf_counter()
    res = evaluate(cfg, scheme)
    res["seconds"] = time.perf_counter() - t0
    out = Path(args.out)
    with atomic_files(out) as tmp:
        pd.DataFrame(res["coefficients"]).to_csv(tmp("coefficients.csv"), index=False)
        tmp("observability.json").write_text(json_text(res))
    v = res["verdict"]
    print(f"platcal observability: multiposition scheme {scheme.name!r}: static rank {res['static_rank']}, "
          f"exact Lie rank {res['exact_rank_nominal']}/{res['exact_rank_truth']} of {res['n_states']}, max "
          f"sigma/|truth| {res['max_rel_sigma_pct']:.3g} % -> {v['decision'].upper()}: {'; '.join(v['reasons'])}"
          f" -> {out} ({res['seconds']:.1f} s)", file=sys.stderr)
    return 0
