"""The centrifuge UKF's three sigma-point variants, two source trees against each other, bit for bit
(issue 22 item 4: one kernel per variant must not change a number).

Each tree (``--before``, ``--after``: ``src`` directories) runs in a fresh process on its own empty
``NUMBA_CACHE_DIR``, on the Table 1 scheme at ``--dwell`` s per position (default noise, seeds
``[22, i]``): every variant (``nonlinear``, ``update``, ``all``) at B = 3 with one and with two
threads (the serial and the threaded pass kernel), at B = 1, with two passes and a history every
0.5 s; ``update`` also with the nonlinear-first square root; and every variant from a prior
covariance that is not positive definite (its updates and ``all``'s propagations fail and are
counted). Every array of each Estimate (x, P, history, per-pass estimate and covariance, mean NIS,
failed updates) is compared with ``np.array_equal``; prints one line per case and exits 1 on any
difference. Needs NUMBA_NUM_THREADS >= 2 for the threaded cases.

    python benchmarks/ukf_modes_ab.py --before /path/to/main/src --after src [--dwell 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

FIELDS = ("x", "P", "history_t", "history_x", "history_sigma", "pass_x", "pass_P", "mean_nis", "failed_updates")


def cases():
    """(name, sigma_points, batch, threads, options) of every case."""
    out = []
    for mode in ("nonlinear", "update", "all"):
        out += [(f"{mode} B3 t1", mode, 3, 1, {}), (f"{mode} B3 t2", mode, 3, 2, {}),
                (f"{mode} B1 t1", mode, 1, 1, {}), (f"{mode} bad-prior", mode, 2, 1, {"bad_prior": True})]
    out.append(("update nonlinear-first root", "update", 3, 1, {"nl_first": True}))
    return out


def worker(out_npz: str, dwell: float) -> None:
    """Run every case with the platcal on PYTHONPATH; save the Estimates' arrays."""
    from platcal.parallel import threads
    from platcal.rigs.centrifuge import ukf
    from platcal.rigs.centrifuge.base import Centrifuge
    from platcal.rigs.centrifuge.catalogue import full_truth
    from platcal.rigs.centrifuge.ekf import EstimatorInput, FilterSettings
    from platcal.rigs.centrifuge.simulate import Noise, simulate
    from platcal.scheme import TABLE1_POSITIONS, check_scheme

    scheme = check_scheme("table1", {"dwell_s": dwell, "positions": [list(p) for p in TABLE1_POSITIONS]})
    cen = Centrifuge()
    sim = simulate(full_truth(), scheme, cen.scheme_params(scheme), Noise(),
                   [np.random.SeedSequence([22, i]) for i in range(3)], keep_every=4)
    keep = sim.t > 0
    K = scheme.n_positions
    z_all = [sim.A[:, k][:, keep] for k in range(K)]
    t = [sim.t[keep]] * K
    saved = {}
    for name, mode, B, nthreads, opts in cases():
        base = FilterSettings(passes=2, history_every_s=0.5)
        p0 = base.p0_sigma
        prior_P = np.diag(p0 * p0)
        prior_P[30, 30] = -prior_P[30, 30]  # not positive definite: every sigma-point draw fails
        settings = (FilterSettings(passes=2, history_every_s=0.5, prior_x=np.zeros(p0.size), prior_P=prior_P)
                    if opts.get("bad_prior") else base)
        kw = {"sigma_points": mode}
        if opts.get("nl_first"):
            kw["sqrt_order"] = ukf.nonlinear_first_order(p0.size + 3, base.coef_index)
        data = EstimatorInput([zk[:B] for zk in z_all], t, scheme.angles_deg, cen.scheme_params(scheme))
        c0 = time.process_time()
        with threads(nthreads):
            est = ukf.run_ukf(data, settings, **kw)
        for f in FIELDS:
            saved[f"{name}|{f}"] = np.asarray(getattr(est, f))
        print(f"  {name}: {time.process_time() - c0:.1f} s CPU, failed updates {est.failed_updates.tolist()}",
              file=sys.stderr, flush=True)
    np.savez(out_npz, **saved)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="src directory of the reference tree")
    ap.add_argument("--after", required=True, help="src directory of the tree under test")
    ap.add_argument("--dwell", type=float, default=2.0, help="s per position (default 2)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        worker(a.worker, a.dwell)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        res = {}
        for label, src in (("before", a.before), ("after", a.after)):
            env = dict(os.environ, PYTHONPATH=os.path.abspath(src),
                       NUMBA_CACHE_DIR=os.path.join(tmp, f"numba_{label}"))
            out = os.path.join(tmp, f"{label}.npz")
            print(f"{label}: {src} (load {os.getloadavg()[0]:.1f})", flush=True)
            subprocess.run([sys.executable, __file__, "--worker", out, "--dwell", str(a.dwell),
                            "--before", a.before, "--after", a.after], env=env, check=True)
            res[label] = dict(np.load(out))
        bad = 0
        for name, *_ in cases():
            diff = [f for f in FIELDS if not np.array_equal(res["before"][f"{name}|{f}"], res["after"][f"{name}|{f}"],
                                                          equal_nan=True)]
            bad += bool(diff)
            print(f"{name}: {'bit-identical' if not diff else 'DIFFERENT: ' + ', '.join(diff)}")
    print("all cases bit-identical" if not bad else f"{bad} cases differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
