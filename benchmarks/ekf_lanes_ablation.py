"""Issue 22 item 1: where the state-major EKF kernel's cycles go, by ablation.

Variants of :mod:`platcal.rigs.centrifuge.ekf_lanes` are written to a temporary directory, each
with one part of the filter step done on a segment's first step only (its numbers are then
wrong; only its time counts): the model (the base specific force, once per block when its lanes
share a centrifuge; the RK4 map and its exact Jacobian for the block's lanes at once), the outputs
and H, W = Phi P, U = H P with S, and K, D, x with the Joseph update of the packed P (the last three are calls of the shared lane pieces,
:mod:`platcal.estimation.lanes`, which the variant skips after a segment's first step). Every variant and the kernel itself run the Table 1 case (6 x 60 s) at ``--batch``
replicates on one numba thread, alternating over ``--rounds`` rounds in one process (so that the
machine's load falls on all alike); prints the best CPU s per replicate of each, the share of
the step the part takes (1 - variant / kernel) and the load average.

    python benchmarks/ekf_lanes_ablation.py [--batch 64] [--rounds 3]
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import os
import re
import sys
import tempfile
import time

import platcal.rigs.centrifuge.ekf_lanes as ekf_lanes
from bench_filter import table1_case
from platcal.parallel import set_threads
from platcal.rigs.centrifuge.ekf import EstimatorInput, run_ekf

# part -> (the kernel's code, the same code run on a segment's first step only), or a tuple of such pairs
PARTS = {
    "model (the base specific force; the RK4 map and its Jacobian, all lanes at once)": (
        ("                for l in range(nact):\n                    for r in range(3):\n"
         "                        fr3[l, 0, r] = fr_now[l, r]",
         "                for l in range(nact if m == 0 else 0):\n                    for r in range(3):\n"
         "                        fr3[l, 0, r] = fr_now[l, r]"),
        ("                rk4_jac_lanes(m_ang,", "                if m == 0:\n                    rk4_jac_lanes(m_ang,")),
    "outputs and H (scalar, per lane)": (
        "            for l in range(nact):\n                b = b0 + l\n                g = pb_l[l, P_G]",
        "            for l in range(nact if m == 0 else 0):\n                b = b0 + l\n                g = pb_l[l, P_G]"),
    # the covariance algebra is in the shared lane pieces (platcal.estimation.lanes), inlined: the
    # kernel's call is skipped after a segment's first step
    "W = Phi P (3 attitude rows)": (
        "                propagate_rows_lanes(Pl, pidx, pcols, phi, W, acc, nc)",
        "                if m == 0:\n                    propagate_rows_lanes(Pl, pidx, pcols, phi, W, acc, nc)"),
    "U = H P and S": (
        "            innovation_covariance_lanes(Pl, pidx, hcols, hnnz, hval, r_var, U, S, acc[0])\n"
        "            _cholesky_inverse_lanes(",
        "            if m == 0:\n"
        "                innovation_covariance_lanes(Pl, pidx, hcols, hnnz, hval, r_var, U, S, acc[0])\n"
        "            _cholesky_inverse_lanes("),
    "K, D, x and the Joseph update of the packed P": (
        "            joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, update_x)",
        "            if m == 0:\n                joseph_correct_lanes(xl, Pl, U, K, D, S, Sinv, innov, update_x)"),
}


def variant(src: str, name: str, folder: str):
    """The kernel module from ``src`` (relative imports made absolute) as module ``name``."""
    src = src.replace("from ...", "from platcal.")
    src = re.sub(r"from \.(\w+) import", r"from platcal.rigs.centrifuge.\1 import", src)
    path = os.path.join(folder, f"{name}.py")
    with open(path, "w") as f:
        f.write(src)
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    set_threads(1)
    src = inspect.getsource(ekf_lanes)
    scheme, params, settings, z, t = table1_case(a.batch)
    data = EstimatorInput(z, t, scheme.angles_deg, params)
    small = EstimatorInput([zk[:1] for zk in z], t, scheme.angles_deg, params)
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        runs = {"whole kernel": ekf_lanes.run_pass_lanes}
        for i, (part, pairs) in enumerate(PARTS.items()):
            text = src
            for old, new in (pairs if isinstance(pairs[0], tuple) else (pairs,)):
                if text.count(old) != 1:
                    raise SystemExit(f"ekf_lanes_ablation: the code of {part!r} is not found once in ekf_lanes.py; "
                                     "update PARTS to the kernel's code")
                text = text.replace(old, new)
            runs[part] = variant(text, f"ekf_lanes_ablate{i}", folder).run_pass_lanes
        best = dict.fromkeys(runs, float("inf"))
        # run_ekf imports run_pass_lanes from ekf_lanes at each call: the module's name is swapped
        try:
            for kernel in runs.values():  # compile
                ekf_lanes.run_pass_lanes = kernel
                run_ekf(small, settings, lanes=True)
            for _ in range(a.rounds):
                for name, kernel in runs.items():
                    ekf_lanes.run_pass_lanes = kernel
                    c0 = time.process_time()
                    run_ekf(data, settings, lanes=True)
                    best[name] = min(best[name], (time.process_time() - c0) / a.batch)
        finally:
            ekf_lanes.run_pass_lanes = runs["whole kernel"]
    whole = best["whole kernel"]
    steps = sum(len(tk) for tk in t)
    print(f"state-major EKF kernel, B = {a.batch}, one numba thread, Table 1 case 6 x 60 s ({steps} steps), "
          f"best of {a.rounds} alternating rounds; load average {load0:.2f} at start, {os.getloadavg()[0]:.2f} at end")
    print("| part (done on a segment's first step only) | CPU s / replicate | share of the step | ns / replicate step |")
    print("|---|---:|---:|---:|")
    print(f"| whole kernel | {whole:.4f} | 100 % | {whole / steps * 1e9:.0f} |")
    for part in PARTS:
        saved = whole - best[part]
        print(f"| {part} | {best[part]:.4f} | {100 * saved / whole:.0f} % | {saved / steps * 1e9:.0f} |")
    rest = whole - sum(whole - best[p] for p in PARTS)
    print(f"| rest (reset, Cholesky, NIS, history, coefficient scatter, block layout) | | {100 * rest / whole:.0f} % | "
          f"{rest / steps * 1e9:.0f} |")


if __name__ == "__main__":
    main()
