"""The sled's ``identify`` kernels compiled ahead of time (:mod:`platcal.aot`; issue 22 item 3).

An identify of one record runs the mechanisation (:func:`.ins._initial_attitude`,
:func:`.ins._mechanise`, docs/rocket-sled.md §4), the filters' mean forces and system matrices
(:func:`.filters._epoch_mean`, :func:`.errmodel._fill_all`, §6), the run and stop filters
(:func:`.filters._kalman`, §6.1-6.2), metric B's model (:func:`.errmodel._run_model`, §8) and the
X compensation (:func:`.identify._x_compensated`, both modes in one pass, and
:func:`.identify._x_corrections`, §7). Its seeds (the record, and with a constant
gyro error the record with each gyro offset: four lanes) run one at a time, each a batch of one
(:func:`seed_kernel`, :func:`platcal.aot.pick`). The filters' JIT kernel runs the seeds in SIMD
lanes (:mod:`.filter_lanes`: a ``noalias`` compiler pipeline and SLP vectorisation, which pycc
does not take); each lane's numbers are the one-seed kernel's :func:`.filters._kalman` bit for bit
(``tests/sled/test_sled_lanes.py``), so that kernel is the one compiled here, on the dense system
matrices (:meth:`.filters.Dynamics.dense`). The signatures are the types the glue passes (every
array C-contiguous float64 or int64); a call with other types is refused by
:func:`platcal.aot.kernel`'s check rather than converted.

    platcal kernels --config config/sled.yaml     # build into the per-user cache
"""

from __future__ import annotations

import argparse

from ...aot import AotKernel, KernelSet, build, pick
from ...parallel import run_threaded

_F1, _F2, _F3, _F4 = "f8[::1]", "f8[:, ::1]", "f8[:, :, ::1]", "f8[:, :, :, ::1]"
_I1, _I2 = "i8[::1]", "i8[:, ::1]"

KERNELS = KernelSet("sled", (
    # phi0 (S,3) rad, C (S,3,3)
    AotKernel("initial_attitude", f"{__package__}.ins:_initial_attitude", f"none({_F2}, {_F3})"),
    # lo, hi, f, w (S,N,3), C, vr (S,6), omega_ie (3,), g, dts (N,), v, r (S,N+1,3), fl (S,N,3)
    AotKernel("mechanise", f"{__package__}.ins:_mechanise",
              f"none(i8, i8, {_F3}, {_F3}, {_F3}, {_F2}, {_F1}, f8, {_F1}, {_F3}, {_F3}, {_F3})"),
    # lo, hi, fl (S,N,3), k (J+1,), dts (N,), den (J,), out (S,J,3)
    AotKernel("epoch_mean", f"{__package__}.filters:_epoch_mean", f"none(i8, i8, {_F3}, {_I1}, {_F1}, {_F1}, {_F3})"),
    # Fs (S,J,n,n), Ts (J,), z (S,J,m), X (S,n), PP (S,n,n), Qd (J,n,n), r_var (m,), xs, sig (S,J,n),
    # acc (S,2), failed (S,), innov, s_var (S,J,m)
    AotKernel("kalman", f"{__package__}.filters:_kalman",
              f"none({_F4}, {_F1}, {_F3}, {_F2}, {_F3}, {_F3}, {_F1}, {_F3}, {_F3}, {_F2}, {_I1}, {_F3}, {_F3})"),
    # fl (S,N,3), omega_ie (3,), phi (S,3), has_phix, dts (N,), out (S,N+1,2)
    AotKernel("run_model", f"{__package__}.errmodel:_run_model", f"none({_F3}, {_F1}, {_F2}, b1, {_F1}, {_F3})"),
    # lo, hi, fl (S,N,3), est (S,M,3), hold (N,), dts (N,), dv0, dr0 (S,), dv, dr (S,N+1)
    AotKernel("x_corrections", f"{__package__}.identify:_x_corrections",
              f"none(i8, i8, {_F3}, {_F3}, {_I1}, {_F1}, {_F1}, {_F1}, {_F2}, {_F2})"),
    # lo, hi, fl (S,N,3), r (S,N+1,3), est (S,M,3), holds (H,N), dts (N,), out (H,S,N)
    AotKernel("x_compensated", f"{__package__}.identify:_x_compensated",
              f"none(i8, i8, {_F3}, {_F3}, {_F3}, {_I2}, {_F1}, {_F3})"),
))
"""The kernels of the sled's identify, each run one seed at a time (a batch of one)."""

DYNAMICS = KernelSet("sled_system", (
    # kind, f, w, wc (M,3), F (M,n,n)
    AotKernel("fill_all", f"{__package__}.errmodel:_fill_all", f"none(i8, {_F2}, {_F2}, {_F2}, {_F3})"),
))
"""The filters' dense system matrices (:func:`.errmodel.system_matrices`), a module of their own:
numba 0.6x's pycc does not compile :func:`.errmodel._fill_all` and :func:`.filters._kalman` into
one module (a TypingError in :func:`platcal.estimation.kalman.innovation_covariance`, inlined into
``_kalman``: "Unsupported array index type float64" at ``range(hnnz[c])``), while either alone, or
the two in two modules built in one process, compiles (``tests/test_aot_sled.py``)."""

SETS = (KERNELS, DYNAMICS)
"""Every kernel set of the sled's identify (``platcal kernels`` builds them all)."""


def seed_kernel(name: str, serial):
    """The ahead-of-time kernel ``name`` of :data:`KERNELS` for one seed (:func:`platcal.aot.pick`
    at a batch of one) when this process enabled them and they are built from these sources, else
    None: the caller then runs its seeds on the JIT as before (``serial``, its numba kernel)."""
    kset = next(s for s in SETS if any(k.name == name for k in s.kernels))
    one = pick(kset, name, serial, serial, 1)
    return None if one is serial else one


def run_seeds(name: str, serial, n: int, *args) -> None:
    """``serial(lo, hi, *args)`` (a kernel over seeds ``lo .. hi - 1``) over seeds 0 … n - 1: the
    ahead-of-time kernel ``name`` a seed at a time when there is one (:func:`seed_kernel`), else the
    JIT's over the numba threads set (:func:`platcal.parallel.run_threaded`). The same numbers:
    each seed's loop is the same code."""
    one = seed_kernel(name, serial)
    if one is None:
        run_threaded(serial, n, None, *args)
        return
    for s in range(n):
        one(s, s + 1, *args)


def kernels_command(cfg, args: argparse.Namespace) -> int:
    """``platcal kernels``: build :data:`SETS` into the per-user cache (:func:`platcal.aot.cache_dir`)."""
    for kset in SETS:
        path, seconds = build(kset)
        print(f"platcal kernels: {len(kset.kernels)} sled identify kernels compiled ahead of time in "
              f"{seconds:.1f} s -> {path}")
    return 0
