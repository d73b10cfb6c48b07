"""The low-precision centrifuge's ``identify`` kernels compiled ahead of time (:mod:`platcal.aot`;
issue 22 item 3).

An identify of one record (docs/lowprec-centrifuge.md §10) runs one numba kernel: the proposed
filter over the record's windows at a batch of one (:func:`.proposed.filter_windows`, §7; its
Joseph update :func:`platcal.estimation.kalman.joseph_update_sparse` and :func:`.proposed._matmul`
are compiled into it). The windows' integrals and means are numpy's (:mod:`.stream`,
:func:`.proposed.window_means`), the traditional method (eq. (2), §6) is numpy's too. The
signature is the types :func:`.proposed.run_filter` passes (every array C-contiguous; ``valid``
bool, ``skipped`` int64, the rest float64); a call with other types is refused by
:func:`platcal.aot.kernel`'s check rather than converted.

    platcal kernels --config config/lowprec_centrifuge.yaml     # build into the per-user cache
"""

from __future__ import annotations

import argparse

from ...aot import AotKernel, KernelSet, build

_F1, _F2, _F3 = "f8[::1]", "f8[:, ::1]", "f8[:, :, ::1]"

FILTER_WINDOWS = ", ".join([
    _F2, _F3, _F3, "b1[:, ::1]",      # T (S, W) s, z (S, W, 4), m (S, W, 4), valid (S, W)
    _F2, _F1, _F1,                    # fb (14, 14), q (14,), r_var (4,)
    _F2, _F3, _F1, "i8[::1]", _F3])   # x (S, 14), P (S, 14, 14), nis, skipped, innovations
"""The arguments of :func:`.proposed.filter_windows` (docs/lowprec-centrifuge.md §7), in order."""

KERNELS = KernelSet("lowprec_centrifuge", (
    AotKernel("filter_windows", f"{__package__}.proposed:filter_windows", f"none({FILTER_WINDOWS})"),
))
"""The kernels of the low-precision centrifuge's identify at a batch of one."""


def kernels_command(study, args: argparse.Namespace) -> int:
    """``platcal kernels``: build :data:`KERNELS` into the per-user cache (:func:`platcal.aot.cache_dir`)."""
    path, seconds = build(KERNELS)
    print(f"platcal kernels: {len(KERNELS.kernels)} lowprec_centrifuge identify kernel compiled ahead of time in "
          f"{seconds:.1f} s -> {path}")
    return 0
