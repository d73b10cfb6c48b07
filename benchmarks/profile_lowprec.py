"""Where the low-precision centrifuge's identification spends its time (issue 22 item 2): bench_all's
low-precision case (platform P1's first proposed run of the default config, a batch of replicates),
each stage of :func:`platcal.rigs.lowprec_centrifuge.proposed.identify_proposed` timed alone with
its own inputs (docs/lowprec-centrifuge.md §7), and the floor of its data-rate work.

    python benchmarks/profile_lowprec.py [--batch 20] [--repeat 7] [--threads 2]

Stages, per replicate: the heading's unwrap and the windows' plan (once per batch), and per
replicate the heading's cos and sin (numpy, as ``window_data`` takes them), the one compiled pass
that keeps the windows' end samples (``_boundary_samples``), the windows (``find_windows``), the
whole ``window_data`` (one thread), the window filter over the padded windows (``run_filter``, on
``--threads``) and ``identify_proposed`` whole (on ``--threads``). Besides them, the same cos and
sin in a compiled loop (the C library's ``sin`` and ``cos``, as numba calls them; the script says
whether its bits equal numpy's on this record): the cheapest way to the heading's cos and sin that
keeps the numbers. ``floor`` is the data-rate work that a free filter would leave, with that loop:
compiled cos and sin + the boundary pass + the windows, CPU s per replicate; divided by the
threads it bounds platcal's wall time a replicate from below, and bench_all's FilterPy time over it
bounds the ratio of the whole from above. Best of ``--repeat``; the load average printed with them.
"""

from __future__ import annotations

import argparse
import math
import os
from unittest import mock

import numpy as np
from numba import njit

from bench_all import best_time, lowprec_case
from platcal.parallel import set_threads
from platcal.rigs.lowprec_centrifuge import proposed


@njit(cache=True, nogil=True)
def cos_sin(psi, c, s):
    """c, s = cos, sin of psi (N,) rad, one sample at a time (the C library's functions)."""
    for i in range(psi.size):
        c[i] = math.cos(psi[i])
        s[i] = math.sin(psi[i])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--threads", type=int, default=2, help="numba threads of the filter and the whole (2)")
    a = ap.parse_args(argv)
    threads = set_threads(a.threads)
    study, p, r, rb = lowprec_case(a.batch)
    t, sched, arm = rb.prof.t, rb.prof.schedule, study.centrifuge.arm_m
    v, p_rel, f = rb.v_ind, rb.p_ind, rb.f_meas
    S, N = v.shape[0], t.size

    def ident():
        return proposed.identify_proposed(t, v, p_rel, rb.psi, f, sched, arm, study.latitude_deg)

    with mock.patch.object(proposed, "run_filter", wraps=proposed.run_filter) as spy:
        res = ident()     # compiles (or loads) every kernel
    fargs = spy.call_args.args[:5]
    psi_u = proposed.unwrap_heading(rb.psi)
    plan = proposed.window_plan(t, sched)
    fs = [f if f.ndim == 2 else f[s] for s in range(S)]
    c, sn = np.empty(N), np.empty(N)
    differ = 0
    for s in range(S):
        cos_sin(psi_u[s], c, sn)
        differ += int(np.count_nonzero(np.cos(psi_u[s]) != c) + np.count_nonzero(np.sin(psi_u[s]) != sn))
    wins = [proposed.find_windows(t, psi_u[s], sched, plan) for s in range(S)]
    bounds = []
    for w in wins:
        tb = np.concatenate([w.ts, w.te])
        k = proposed.boundary_index(t, tb)
        bounds.append((np.sort(k, kind="stable"), tb.size))
    cos_all = [(np.cos(psi_u[s]), np.sin(psi_u[s])) for s in range(S)]

    def boundary_pass():
        for s in range(S):
            ks, nb = bounds[s]
            out = [np.empty((nb, 4)) for _ in range(6)]
            proposed._boundary_samples(t, v[s], p_rel[s], cos_all[s][0], cos_all[s][1],
                                       np.array([cos_all[s][0][0], cos_all[s][1][0]]), float(arm), fs[s], ks, *out)

    stages = {
        "heading unwrap (batch)": lambda: proposed.unwrap_heading(rb.psi),
        "window plan (batch)": lambda: proposed.window_plan(t, sched),
        "heading cos + sin, numpy": lambda: [(np.cos(psi_u[s]), np.sin(psi_u[s])) for s in range(S)],
        "heading cos + sin, compiled loop": lambda: [cos_sin(psi_u[s], c, sn) for s in range(S)],
        "boundary pass (_boundary_samples)": boundary_pass,
        "windows (find_windows)": lambda: [proposed.find_windows(t, psi_u[s], sched, plan) for s in range(S)],
        "window_data (whole, one thread)": lambda: [proposed.window_data(t, v[s], p_rel[s], psi_u[s], fs[s], sched, arm,
                                                                         None, plan) for s in range(S)],
        "window filter (run_filter)": lambda: proposed.run_filter(*fargs),
        "identify_proposed (whole)": ident,
    }
    n_win = int(np.asarray(res.n_windows).sum())
    load0 = os.getloadavg()
    print(f"low-precision identify_proposed, platform {p} run {r}, batch {S}, {threads} numba threads, {N} samples "
          f"and {n_win / S:.0f} windows per replicate")
    cpu_of = {}
    for name, fn in stages.items():
        (wall, cpu), _ = best_time(fn, a.repeat)
        cpu_of[name] = cpu / S
        extra = f"  ({cpu / n_win * 1e6:.2f} us CPU per window)" if "filter" in name else ""
        print(f"  {name:36s} wall {wall / S * 1e3:7.3f} ms  CPU {cpu / S * 1e3:7.3f} ms per replicate{extra}")
    floor = (cpu_of["heading cos + sin, compiled loop"] + cpu_of["boundary pass (_boundary_samples)"]
             + cpu_of["windows (find_windows)"])
    print(f"  the compiled loop's cos and sin against numpy's: {differ} of {2 * S * N} values differ")
    print(f"  floor (compiled cos + sin, boundary pass, windows): {floor * 1e3:.3f} ms CPU per replicate, "
          f"{floor / threads * 1e3:.3f} ms wall on {threads} threads: with a free filter the whole is no faster")
    print(f"  load average {load0[0]:.2f} at start, {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
