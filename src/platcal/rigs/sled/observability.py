"""Observability rank tables of the sled models (docs/rocket-sled.md §8, §11).

``Q = [C; CA; …; CA^{n−1}]`` of the scaled model (v: 1 m/s, r: 1 m, φ: 1 mrad, i.e.
``A_s = S⁻¹ A S``, ``C_s = C S``) and rank = #(σ_i/σ_1 > rtol), rtol = 1e-9. Per phase the
specific force is ``f = [a_x, 0, g]``. Rates ([D1]): ``ω = 0`` (no Earth rate anywhere),
``Earth rate`` (ω_ie^l in the attitude block and the Coriolis couplings), ``Earth rate + ω_z``
(the azimuth rate of the paper added to the attitude block only: a rotation of the error frame).
The whole run is the stripped (piecewise-constant, PWCS) stack ``[Q_static; Q_boost; …]``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ...io import check_writable
from ...study.tables import write_table
from .config import G, SledConfig
from .errmodel import run_F, stop_F

RTOL = 1e-9


def rank(Q: np.ndarray, rtol: float = RTOL) -> int:
    """Numerical rank: number of singular values with σ_i/σ_1 > rtol (numpy SVD).

    Generic helper (candidate for the shared layer).
    """
    s = np.linalg.svd(np.asarray(Q, dtype=float), compute_uv=False)
    if s.size == 0 or s[0] == 0:
        return 0
    return int(np.sum(s / s[0] > rtol))


def obs_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Q = [C; CA; …; CA^{n−1}]."""
    blocks, M = [], C.copy()
    for _ in range(A.shape[0]):
        blocks.append(M)
        M = M @ A
    return np.vstack(blocks)


def scaling(n_phi: int) -> np.ndarray:
    """State scaling S (1 m/s, 1 m, 1 mrad): diag(1, 1, 1, 1, 1e-3 …)."""
    return np.diag(np.r_[np.ones(4), np.full(n_phi, 1e-3)])


def scaled_q(F: np.ndarray) -> np.ndarray:
    """Observability matrix of the scaled model with H = [I₄ 0]."""
    n = F.shape[0]
    S = scaling(n - 4)
    A = np.linalg.solve(S, F @ S)
    C = np.hstack([np.eye(4), np.zeros((4, n - 4))]) @ S
    return obs_matrix(A, C)


def phases(cfg: SledConfig) -> list[tuple[str, float]]:
    """(label, a_x in m/s^2) of static, each phase of the config and braking."""
    out = [("static", 0.0)]
    for i, ph in enumerate(cfg.phases):
        kind = "boost" if ph.accel_g > 0 else "coast"
        label = f"{kind} {ph.accel_g:g} g"
        if any(label == o[0] for o in out):          # two phases at the same level: keep both columns
            label += f" (phase {i + 1})"
        out.append((label, ph.accel_g * G))
    out.append((f"brake -{cfg.brake_g:g} g", -cfg.brake_g * G))
    return out


def rate_cases(cfg: SledConfig, azimuth_rates=(0.01, 0.1)):
    """(label, ω of the attitude block, ω of the Coriolis terms)."""
    wie = cfg.omega_ie
    out = [("0", np.zeros(3), np.zeros(3)), ("Earth rate", wie, wie)]
    for wz in azimuth_rates:
        out.append((f"Earth rate + {wz:g} rad/s about z", wie + np.array([0, 0, wz]), wie))
    return out


def rank_table(cfg: SledConfig, rtol: float = RTOL) -> pd.DataFrame:
    """The §11 table: rank per model, rate and phase, plus the stacked whole run and the stop model."""
    ph = phases(cfg)
    rows = []
    for states in (7, 6):
        for label, w, wc in rate_cases(cfg):
            Qs = []
            row = {"model": f"run {states}-state", "omega": label}
            for name, ax in ph:
                Q = scaled_q(run_F(np.array([ax, 0.0, G]), w, wc, states=states))
                Qs.append(Q)
                row[name] = f"{rank(Q, rtol)}/{states}"
            row["whole run stacked"] = f"{rank(np.vstack(Qs), rtol)}/{states}"
            rows.append(row)
    for label, w, wc in rate_cases(cfg)[:2]:
        Q = scaled_q(stop_F(np.array([0.0, 0.0, G]), w, wc))
        rows.append({"model": "stop 6-state", "omega": label, "static": f"{rank(Q, rtol)}/6"})
    return pd.DataFrame(rows).fillna("")


def cmd_observability(cfg: SledConfig, args) -> int:
    """The rank table of §8/§11 -> OUT/rank_table.{csv,md,html}."""
    check_writable(args.out, "--out", folder=True)
    tab = rank_table(cfg)
    write_table(tab, Path(args.out) / "rank_table", "Sled observability ranks (docs/rocket-sled.md §8)",
                note="states scaled 1 m/s, 1 m, 1 mrad; rank = #(sigma_i/sigma_1 > 1e-9); f = [a_x, 0, g] per phase")
    print(tab.to_string(index=False), file=sys.stderr)
    return 0
