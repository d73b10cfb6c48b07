"""The low-precision centrifuge's window filter alone (issue 22 items 1-2): CPU per window of
:func:`platcal.rigs.lowprec_centrifuge.proposed.run_filter` on the windows that
``identify_proposed`` forms from platform P1's first proposed run
(``bench_all.lowprec_case``), ``--seeds`` seeds, best of ``--repeat`` calls after the compile. ``--dump F``
writes the result (x, P, mean NIS, innovations) to F (.npz) so that two source trees can be
compared bit for bit (``--compare A B``).

    NUMBA_NUM_THREADS=1 python benchmarks/lowprec_window_filter.py [--seeds 20] [--repeat 7] [--dump F]
    python benchmarks/lowprec_window_filter.py --compare before.npz after.npz
"""

from __future__ import annotations

import argparse
import os
import time
from unittest import mock

import numpy as np

from bench_all import lowprec_case
from platcal.rigs.lowprec_centrifuge import proposed


def window_inputs(seeds: int) -> tuple:
    """The arguments ``identify_proposed`` hands to ``run_filter`` (T, z, m, valid, lat_rad)."""
    study, _, _, rb = lowprec_case(seeds)
    with mock.patch.object(proposed, "run_filter", wraps=proposed.run_filter) as spy:
        proposed.identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, rb.prof.schedule,
                                   study.centrifuge.arm_m, study.latitude_deg)
    return spy.call_args.args[:5]


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--dump", help="write x, P, mean NIS and the innovations here (.npz)")
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"), help="two dumps: are they equal?")
    a = ap.parse_args(argv)
    if a.compare:
        x, y = (np.load(f) for f in a.compare)
        same = {k: np.array_equal(x[k], y[k], equal_nan=True) for k in x.files}
        print(f"equal (np.array_equal): {same}")
        raise SystemExit(0 if all(same.values()) else 1)
    args = window_inputs(a.seeds)
    res = proposed.run_filter(*args, keep_innovations=True)
    best = np.inf
    for _ in range(a.repeat):
        c0 = time.process_time()
        proposed.run_filter(*args)
        best = min(best, time.process_time() - c0)
    n = int(np.asarray(args[3]).sum())
    print(f"window filter: {best * 1e3:.2f} ms CPU for {a.seeds} seeds, {n} windows, {best / n * 1e6:.2f} us per "
          f"window (best of {a.repeat}); load average {os.getloadavg()[0]:.2f}")
    if a.dump:
        np.savez(a.dump, x=res.x, P=res.P, nis=res.mean_nis, inn=res.innovations)


if __name__ == "__main__":
    main()
