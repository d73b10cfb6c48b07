"""The traditional two-level method, eq. (2) as it reads (docs/lowprec-centrifuge.md §6).

Per axis and plateau i (nominal level A_i, duration T_i):
``dV_i = g0 T_i [kA (2/pi) A_i + k2 A_i^2 / 2]``, i = 1, 2, a 2x2 linear solve for (kA, k2)
(ug/g, ug/g^2). A_i is the commanded (nominal) level, i.e. w_nom,i^2 r_nom / g0; dV_i is the
increment of the single-sample velocity error V_ind - V_ref between the first and last hold
samples of the plateau, V_ref = w_nom r_nom (-sin psi, cos psi), and T_i the time between those
samples. Schuler/tilt feedback, drift and ramps are ignored: that is the method, and its bias is
a result, not a bug.
"""

from __future__ import annotations

import numpy as np

from ...errors import InputError
from .config import G0
from .profile import HOLD


def hold_segments(schedule: np.ndarray, n_levels: int) -> list[tuple[int, int]]:
    """(first, last) sample of each plateau; InputError (field ``schedule``) unless there are ``n_levels``."""
    hold = (schedule == HOLD).astype(np.int8)
    d = np.diff(np.concatenate([[0], hold, [0]]))
    starts, stops = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    if starts.size != n_levels or np.any(stops - starts < 1):
        raise InputError("schedule", f"the traditional method needs {n_levels} 'hold' plateaus of at least two "
                                     f"samples; the record has {starts.size}")
    return list(zip(starts.tolist(), stops.tolist()))


def design_matrix(levels_g, durations_s) -> np.ndarray:
    """Rows g0 T_i [(2/pi) A_i, A_i^2/2] * 1e-6 of eq. (2), for (kA ug/g, k2 ug/g^2)."""
    a = np.asarray(levels_g, dtype=float)
    tt = np.asarray(durations_s, dtype=float)
    return G0 * 1e-6 * tt[:, None] * np.stack([2 / np.pi * a, a**2 / 2], axis=1)


def identify_traditional(t, v, psi, schedule, levels_g, arm_m: float) -> np.ndarray:
    """(S, 4) estimates kA_x, k2_x, kA_y, k2_y from S records (v (S, N, 2), psi (S, N) rad)."""
    segs = hold_segments(schedule, len(levels_g))
    return plateau_estimates(np.array([[t[k] for k in e] for e in segs]),
                             np.stack([np.stack([v[:, k, :] for k in e], axis=1) for e in segs], axis=1),
                             np.stack([np.stack([psi[:, k] for k in e], axis=1) for e in segs], axis=1),
                             levels_g, arm_m)


def plateau_estimates(t_ends, v_ends, psi_ends, levels_g, arm_m: float) -> np.ndarray:
    """(S, 4) kA ug/g, k2 ug/g^2 per axis by eq. (2) (docs/lowprec-centrifuge.md §6) from each plateau's first and last hold samples only: their times ``t_ends``
    (L, 2) s, velocities ``v_ends`` (S, L, 2, 2) m/s and headings ``psi_ends`` (S, L, 2) rad (a
    streamed record keeps no more, :mod:`.stream`)."""
    dv = np.empty((v_ends.shape[0], len(levels_g), 2))
    durs = []
    for i, a in enumerate(levels_g):
        speed = np.sqrt(a * G0 / arm_m) * arm_m
        err = [v_ends[:, i, e, :] - speed * np.stack([-np.sin(psi_ends[:, i, e]), np.cos(psi_ends[:, i, e])], axis=-1)
               for e in (0, 1)]
        dv[:, i, :] = err[1] - err[0]
        durs.append(t_ends[i][1] - t_ends[i][0])
    M = design_matrix(levels_g, durs)
    # one 2x2 solve per seed (stacked): a multi-right-hand-side solve rounds by the batch size
    Ms = np.broadcast_to(M, (v_ends.shape[0], 2, 2))
    cx = np.linalg.solve(Ms, dv[:, :, 0:1])[:, :, 0]
    cy = np.linalg.solve(Ms, dv[:, :, 1:2])[:, :, 0]
    return np.stack([cx[:, 0], cx[:, 1], cy[:, 0], cy[:, 1]], axis=1)
