"""Every centrifuge estimator's numbers on a study-like input, to an .npz, and a comparison of two
such files with ``np.array_equal`` (issue 22 item 4: a compile-structure change must leave every
estimate bit-identical).

The comparison's estimators (ekf1, ekfw, ekf2, iekf, ukf, ml with the study's options, through the
rig's ``run_batch``, noise 10 ug, seeds ``[7, i]``) at a batch of 3 and of 1 on the Table 1 scheme
with ``--dwell`` s per position (:func:`bench_compile.study_config`); a covariance-only run's P
(the GA design's run); the single run's tables (``single_job``).

    PYTHONPATH=<tree>/src python benchmarks/centrifuge_estimates_snapshot.py out.npz [--dwell 3]
    python benchmarks/centrifuge_estimates_snapshot.py --compare a.npz b.npz
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from bench_compile import study_config


def snapshot(dwell: float) -> dict[str, np.ndarray]:
    """The arrays (see the module docstring), by name."""
    import pandas as pd

    from platcal.rig import get_rig
    from platcal.rigs.centrifuge.base import Centrifuge
    from platcal.rigs.centrifuge.catalogue import full_truth
    from platcal.rigs.centrifuge.compare_cells import with_compare_estimators
    from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings, run_ekf
    from platcal.rigs.centrifuge.study import builtin_scheme, check_study, single_job

    out = {}
    cfg = with_compare_estimators(check_study(study_config(dwell)))
    rig = get_rig("centrifuge")
    sch = builtin_scheme(cfg, "table1")
    for est in cfg["study"]["compare"]["estimators"]:
        for B in (3, 1):
            rb = rig.montecarlo.run_batch(cfg, sch, 10.0, est, [np.random.SeedSequence([7, i]) for i in range(B)])
            for f in ("estimate", "sigma", "nees", "mean_nis", "failed_updates"):
                out[f"{est}/{B}/{f}"] = np.asarray(getattr(rb, f))
    t = [np.arange(1, 101) * 0.02] * len(sch.angles_deg)
    e = run_ekf(EstimatorInput([None] * 2, t, sch.angles_deg, Centrifuge().scheme_params(sch)), FilterSettings(),
                linearise_about=np.repeat(full_truth()[None], 2, axis=0))
    out["covonly/P"] = e.P
    with tempfile.TemporaryDirectory() as d:
        single_job(study_config(dwell), Path(d))
        for p in sorted(Path(d).rglob("*")):
            if p.suffix in (".parquet", ".csv"):
                df = pd.read_parquet(p) if p.suffix == ".parquet" else pd.read_csv(p)
                for c in df.columns:
                    if df[c].dtype.kind in "fiu":
                        out[f"single/{p.name}/{c}"] = df[c].to_numpy()
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("files", nargs="+", help="the .npz to write, or with --compare the two to compare")
    ap.add_argument("--dwell", type=float, default=3.0, help="s per position (default 3)")
    ap.add_argument("--compare", action="store_true")
    a = ap.parse_args(argv)
    if a.compare:
        x, y = np.load(a.files[0]), np.load(a.files[1])
        names = sorted(set(x.files) | set(y.files))
        bad = [k for k in names if k not in x.files or k not in y.files
               or not np.array_equal(x[k], y[k], equal_nan=True)]
        print(f"{len(names)} arrays, {len(bad)} differ" + (f": {', '.join(bad[:10])}" if bad else ""))
        raise SystemExit(1 if bad else 0)
    arrays = snapshot(a.dwell)
    np.savez(a.files[0], **arrays)
    print(f"{len(arrays)} arrays -> {a.files[0]}")


if __name__ == "__main__":
    main()
