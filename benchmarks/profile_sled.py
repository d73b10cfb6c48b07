"""Where the sled's identification spends its time (issue 22 item 2): bench_all's sled case
(the default config, 85.9 s at 200 Hz, a batch of replicates), each stage of
:func:`platcal.rigs.sled.identify.identify` timed alone with its own inputs, CPU and wall.

    python benchmarks/profile_sled.py [--batch 20] [--repeat 5] [--threads 1]

Stages: the run filter's kernel alone, with the seeds in lanes (F formed from the mean force)
and one seed at a time (the reference kernel, main's before issue 22, on the dense F: the
before/after of the filter in one run); the mechanisation (§4), the epoch means of the computed
force, the run and stop filters (§6), metric B's model (§8) and the X compensation of both modes
(§7: identify's one pass of both modes, :func:`compensate_modes`, with their
holds); the mechanisation's kernel with its outputs allocated once (the state carried on from call
to call: the same work), and the allocation and first touch of its outputs (72 bytes a sample),
which ``mechanise`` pays per call; ``identify`` is the whole, the rest of it (Python glue, array slicing) being the difference. Per replicate, best of ``--repeat``; the load average is printed with them.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from platcal.parallel import set_threads
from platcal.rigs.sled import filters
from platcal.rigs.sled.config import load_config
from platcal.rigs.sled.errmodel import propagate_run_model
from platcal.rigs.sled.identify import compensate_modes, identify, phi_hold
from platcal.rigs.sled.aot_kernels import run_seeds
from platcal.rigs.sled.config import G
from platcal.rigs.sled.ins import _initial_attitude, _mechanise, mechanise
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.simulate import simulate


def best(fn, repeat: int) -> tuple[float, float]:
    """Smallest wall and process CPU time of ``repeat`` calls (s)."""
    wall, cpu = np.inf, np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return wall, cpu


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--batch", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--threads", type=int, default=1, help="numba threads (1)")
    a = ap.parse_args(argv)
    threads = set_threads(a.threads)
    cfg = load_config({"rig": "sled"})
    sb = simulate(cfg, replicate_seeds(cfg.raw, "default", range(a.batch)))
    idn = identify(cfg, sb.traj, sb.f, sb.w)   # compiles (or loads) every kernel
    ep, fl, v, r, js, je, N = idn.epochs, idn.fl, idn.v, idn.r, idn.j_stop, idn.j_end, sb.f.shape[1]
    iy = 4 if cfg.states == 6 else 5
    run = idn.run

    def filt():
        out = filters.run_filter(cfg, fl, v, r, js, ep)
        filters.stop_filter(cfg, fl, v, r, js, je, out.x[:, -1, iy], out.P[:, iy, iy], ep)

    k = ep.k[1:js + 1]
    z = np.ascontiguousarray(np.stack([v[:, k, 1], r[:, k, 1], v[:, k, 2], r[:, k, 2]], axis=-1))
    dyn = filters.Dynamics.run(filters.epoch_mean(fl, ep, 0, js), cfg.omega_ie, cfg.states)
    dense = dyn.dense()
    tun, x0 = filters.run_tuning(cfg, cfg.states), np.zeros((a.batch, cfg.states))

    def kernel(Fs):
        return lambda: filters.KalmanRun(x0, tun, cfg.period_ms / 1000.0).step(Fs, z, ep.T[:js])

    kernel(dense)()
    S = a.batch
    f = np.ascontiguousarray(sb.f, dtype=np.float64)
    w = np.ascontiguousarray(np.broadcast_to(sb.w, f.shape), dtype=np.float64)
    C, vr = np.empty((S, 3, 3)), np.zeros((S, 6))
    _initial_attitude(np.zeros((S, 3)), C)
    wie = np.asarray(cfg.omega_ie, dtype=np.float64)
    dts = np.ascontiguousarray(np.broadcast_to(ep.dts, (N,)), dtype=np.float64)
    outs = np.empty((S, N + 1, 3)), np.empty((S, N + 1, 3)), np.empty((S, N, 3))

    def touched_outputs():
        for o in (np.empty((S, N + 1, 3)), np.empty((S, N + 1, 3)), np.empty((S, N, 3))):
            o.fill(0.0)

    r_nav = mechanise(sb.f, sb.w, np.zeros((a.batch, 3)), cfg.omega_ie, ep.dts)[1]   # (S,N+1,3), as identify's
    held = [phi_hold(run, cfg.states, ep.k, js, N, m) for m in ("realtime", "post")]

    stages = {
        "run filter kernel alone, lanes": kernel(dyn),
        "run filter kernel alone, one seed at a time": kernel(dense),
        "mechanisation": lambda: mechanise(sb.f, sb.w, np.zeros((a.batch, 3)), cfg.omega_ie, ep.dts),
        "mechanisation kernel, outputs allocated once": lambda: run_seeds("mechanise", _mechanise, S, f, w, C, vr,
                                                                          wie, G, dts, *outs),
        "mechanisation's outputs: allocate, first touch": touched_outputs,
        "epoch means": lambda: (filters.epoch_mean(fl, ep, 0, js), filters.epoch_mean(fl, ep, js, je)),
        "run + stop filters (incl. epoch means)": filt,
        "metric B model": lambda: propagate_run_model(fl[:, :idn.n_stop], cfg.omega_ie, np.nan_to_num(idn.phi_run),
                                                      cfg.states, ep.dts[:idn.n_stop]),
        "X compensation (both modes)": lambda: compensate_modes(fl, r_nav, held[0][0],
                                                                np.stack([h for _, h in held]), ep.dts),
        "identify (whole)": lambda: identify(cfg, sb.traj, sb.f, sb.w),
    }
    J = run.x.shape[1] + idn.stop.x.shape[1] - 2
    load0 = os.getloadavg()
    print(f"sled identify, batch {a.batch}, {threads} numba threads, {J} filter epochs, {N} samples per replicate")
    for name, fn in stages.items():
        wall, cpu = best(fn, a.repeat)
        print(f"  {name:42s} wall {wall / a.batch * 1e3:7.3f} ms  CPU {cpu / a.batch * 1e3:7.3f} ms per replicate"
              + (f"  ({cpu / (a.batch * J) * 1e6:.3f} us CPU per epoch)" if "filters" in name else "")
              + (f"  ({cpu / (a.batch * js) * 1e6:.3f} us CPU per epoch)" if "kernel" in name else ""))
    print(f"  load average {load0[0]:.2f} at start, {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
