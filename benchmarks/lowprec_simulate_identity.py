"""The low-precision centrifuge's truth simulator (``truth.simulate_batch``) of two source trees,
array for array (issue 22 item 4): every array of :class:`RunBatch` (errors, force, outputs,
attitude, floors, variants, draws, kinematics) must be bit-identical (``np.array_equal``).

Each tree runs in its own process (``--before``, ``--after``: the ``src`` directories of two
checkouts; numba's cache beside each, ``<checkout>/.numba_cache``) on the same cases: scenarios
of ``config/lowprec_centrifuge.yaml`` (default, worst, gross), both platforms, proposed and
traditional runs, with and without ``floor``, ``sens``, ``keep_phi``, ``noise_free``, and
batches of other sizes (a replicate's numbers do not depend on its batch,
docs/lowprec-centrifuge.md §9, §12).

    python benchmarks/lowprec_simulate_identity.py --before /path/to/main/src --after src
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

CONFIG = Path(__file__).resolve().parent.parent / "config" / "lowprec_centrifuge.yaml"
CASES = [  # (scenario, platform, run, replicates, options)
    ("default", "P1", "run1", range(20), dict(floor=True, sens=True)),
    ("default", "P2", "run2", range(20), dict(floor=True, sens=True)),
    ("default", "P1", "traditional", range(20), dict(floor=False, sens=False)),
    ("worst", "P2", "run1", range(20), dict(floor=True, sens=True, keep_phi=True)),
    ("gross", "P1", "run2", range(20), dict(floor=True, sens=False)),
    ("gross", "P2", "traditional", range(20), dict(floor=False, sens=False, keep_phi=True)),
    ("default", "P1", "run1", (3, 7, 19), dict(floor=True, sens=True, keep_phi=True)),
    ("default", "P2", "run1", range(5), dict(noise_free=True, floor=True, sens=True)),
    ("default", "P1", "run2", range(9), dict(floor=False, sens=True)),
    ("worst", "P1", "traditional", (0,), dict()),
]


def worker(out: str) -> None:
    """Simulate every case with the platcal on PYTHONPATH and save its arrays into ``out`` (npz)."""
    import yaml
    from platcal.rigs.lowprec_centrifuge.config import load_config
    from platcal.rigs.lowprec_centrifuge.montecarlo import SEED_KEY
    from platcal.rigs.lowprec_centrifuge.scenario import scenarios
    from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
    from platcal.study.sweep import replicate_seed

    study = load_config(yaml.safe_load(CONFIG.read_text()))
    cases = scenarios(study)
    arrays = {}
    for c, (scenario, platform, run, reps, opts) in enumerate(CASES):
        st = study.with_centrifuge(cases[scenario]["centrifuge"])
        seeds = [replicate_seed(st.seed, SEED_KEY, st.residuals["accel_noise_ug_rthz"], r) for r in reps]
        rb = simulate_batch(st, platform, run, seeds, list(reps), **opts)
        for name, value in _arrays(rb).items():
            arrays[f"{c}/{name}"] = value
    np.savez(out, **arrays)


def _arrays(obj, prefix: str = "") -> dict:
    """Every array of a dataclass (nested dataclasses flattened, None kept as an empty marker)."""
    out = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out.update(_arrays(v, f"{prefix}{f.name}."))
        elif v is None:
            out[f"{prefix}{f.name}"] = np.array("None")
        elif isinstance(v, np.ndarray):
            out[f"{prefix}{f.name}"] = v
        else:
            out[f"{prefix}{f.name}"] = np.asarray(v)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="the src directory of the reference checkout")
    ap.add_argument("--after", default=str(Path(__file__).resolve().parent.parent / "src"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        saved = []
        for label, src in (("before", args.before), ("after", args.after)):
            src = Path(src).resolve()
            env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(src.parent / ".numba_cache"),
                       NUMBA_NUM_THREADS="1")
            out = os.path.join(tmp, f"{label}.npz")
            subprocess.run([sys.executable, __file__, "--worker", out], check=True, env=env)
            saved.append(np.load(out))
        a, b = saved
        bad = sorted(k for k in set(a.files) | set(b.files)
                     if k not in a.files or k not in b.files or not np.array_equal(a[k], b[k]))
        print(f"{len(CASES)} cases, {len(a.files)} arrays: "
              f"{'all bit-identical' if not bad else 'DIFFERENT: ' + ', '.join(bad)}")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        worker(sys.argv[2])
    else:
        sys.exit(main())
