"""The multi-position rig's ``identify`` kernels compiled ahead of time (:mod:`platcal.aot`; issue 22 item 3).

An identify of one record runs two numba kernels, each at a batch of one: the EKF's pass
(:func:`.filter._ekf_pass_one`, the reference kernel :func:`.filter._ekf_one` with its sums; also
the IEKF's, with its iteration count; docs/multiposition-1g.md §9) and the simulator
(:func:`.filter._simulate_range`: the noise-free output of the nominal instrument the record's
plausibility and fit checks compare with, §7, §12). A batch's EKF runs the replicates in SIMD
lanes (:mod:`.filter_lanes`: a ``noalias`` compiler pipeline and SLP vectorisation, which pycc's
``export`` does not take); each lane's numbers are the reference kernel's bit for bit
(``tests/multiposition/test_multiposition_lanes.py``), so the reference is the one compiled here.
The signatures are the types the glue passes (:func:`.filter._ekf_pass`,
:func:`.filter.simulate_blocks`: every array C-contiguous float64 or int64); a call with other
types is refused by :func:`platcal.aot.kernel`'s check rather than converted.

    platcal kernels --config config/multiposition.yaml     # build into the per-user cache
"""

from __future__ import annotations

import argparse

from ...aot import AotKernel, KernelSet, build, pick

_F1, _F2, _F3, _F4 = "f8[::1]", "f8[:, ::1]", "f8[:, :, ::1]", "f8[:, :, :, ::1]"
_I1 = "i8[::1]"

EKF_PASS = ", ".join([
    _F1, _F2, _F2, _F2, _F3, _I1,     # x (n,), P (n, n), phi0s (K, 3) rad, tk (K, m) s, zk (K, m, 6), nk (K,)
    _I1, "f8", "f8", _F1, "f8", "f8",  # lay, wn, wu rad/s, r_var (6,), arw2 rad^2/s, set_var rad^2
    _I1, "b1", "i8", "f8", "i8",      # cols, update_x, iters, tol, s0
    _F1, _F3])                        # sums (4,), rec (K, m, 12)
"""The arguments of :func:`.filter._ekf_pass_one` (docs/multiposition-1g.md §9), in order."""

SIMULATE = ", ".join([
    "i8", "i8", _F2, _F1, _I1, "f8", "f8",  # lo, hi, phi0s (K, 3) rad, coef, lay, wn, wu rad/s
    "f8", "i8", _F3, _F4, _F4, _F4])        # ts s, n_sub, init (R, K, 3), w (R, K, n-1, 3), phi, z
"""The arguments of :func:`.filter._simulate_range` (docs/multiposition-1g.md §12), in order."""

KERNELS = KernelSet("multiposition", (
    AotKernel("ekf_pass_one", f"{__package__}.filter:_ekf_pass_one", f"none({EKF_PASS})"),
    AotKernel("simulate_range", f"{__package__}.filter:_simulate_range", f"none({SIMULATE})"),
))
"""The kernels of the multi-position rig's identify at a batch of one."""


def one_replicate(name: str, serial):
    """The kernel one replicate runs: the ahead-of-time kernel ``name`` of :data:`KERNELS` when
    this process enabled them and they are built from these sources, else ``serial`` (its numba
    kernel on the JIT) (:func:`platcal.aot.pick` at a batch of one)."""
    return pick(KERNELS, name, serial, serial, 1)


def kernels_command(cfg, args: argparse.Namespace) -> int:
    """``platcal kernels``: build :data:`KERNELS` into the per-user cache (:func:`platcal.aot.cache_dir`)."""
    path, seconds = build(KERNELS)
    print(f"platcal kernels: {len(KERNELS.kernels)} multiposition identify kernels compiled ahead of time in "
          f"{seconds:.1f} s -> {path}")
    return 0
