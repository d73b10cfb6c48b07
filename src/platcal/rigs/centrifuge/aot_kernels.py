"""The centrifuge's ``identify`` kernels compiled ahead of time (:mod:`platcal.aot`; issue 22 item 3).

An identify of one record runs two numba kernels: the EKF's pass at a batch of one
(:func:`.ekf._run_pass_serial`, also the IEKF's: the same kernel with its iteration control) and
the simulator's position at a batch of one (:func:`.simulate._simulate_position_serial`: the
nominal output the record is checked against, docs/centrifuge-model.md §13). Their signatures are
the types :func:`.ekf.run_ekf` and :func:`.simulate.simulate_chunks` pass (every array
C-contiguous, float64 or int64; ``seg`` the tuple of :func:`.ekf.chunk_segments`); a call with
other types is refused by :func:`platcal.aot.kernel`'s check rather than converted.

    platcal kernels --config config/centrifuge.yaml     # build into the per-user cache
"""

from __future__ import annotations

import argparse

from ...aot import AotKernel, KernelSet, build

_F1, _F2, _F3, _F4 = "f8[::1]", "f8[:, ::1]", "f8[:, :, ::1]", "f8[:, :, :, ::1]"
_I1, _I2 = "i8[::1]", "i8[:, ::1]"
_SEG = f"Tuple(({_I1}, {_F1}, b1[::1], {_F1}))"

EKF_PASS = ", ".join([
    _F2, _F3, _F3, _F1, _I1,          # x, P, z, t, offs
    _F3, "f8", _I1, _F2, _F3,         # cmd, reset_var, est_idx, coef_fixed, params
    _F1, "f8", "b1", _I1,             # r_var, q_rate, update_x, hist_idx
    _F3, _F3, _F1, _I1,               # hist_x, hist_s, nis_sum, n_bad
    _I1, _I1, _I2, _I2, _I1,          # pcols, pg, hcols, hsrc, hnnz
    _F1, _F3, _SEG])                  # it_ctl, rec, seg
"""The arguments of :func:`.ekf._run_pass_serial` (docs/centrifuge-model.md §9), in order."""

SIMULATE_POSITION = ", ".join([
    _F2, _F2, "i8", "f8", _F2,        # theta0, truth, m, sample_s, params
    _F4, _I1, _F3, "f8", _F3,         # force table, its index, acc noise, sigma_a, arw noise
    "f8", "i8", _F3, _F3, "i8", "i8"])  # arw step, keep_every, A, angles, i0, n
"""The arguments of :func:`.simulate._simulate_position_serial` (docs/centrifuge-model.md §8), in order."""

KERNELS = KernelSet("centrifuge", (
    AotKernel("run_pass_serial", f"{__package__}.ekf:_run_pass_serial", f"none({EKF_PASS})"),
    AotKernel("simulate_position_serial", f"{__package__}.simulate:_simulate_position_serial",
              f"none({SIMULATE_POSITION})"),
))
"""The kernels of the centrifuge's identify at a batch of one."""


def kernels_command(study, args: argparse.Namespace) -> int:
    """``platcal kernels``: build :data:`KERNELS` into the per-user cache (:func:`platcal.aot.cache_dir`)."""
    path, seconds = build(KERNELS)
    print(f"platcal kernels: {len(KERNELS.kernels)} centrifuge identify kernels compiled ahead of time in "
          f"{seconds:.1f} s -> {path}")
    return 0
