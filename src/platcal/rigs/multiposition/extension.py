"""The centrifuge's motivation, measured at 1 g (docs/multiposition-1g.md §13).

The §9 model extended with the centrifuge's higher-order terms (CM §4/§5): gyro DII, DSS, DIO,
DIS, DOS (and optionally DOO), accelerometer k2, k3, kIP; 51 states (54 with DOO). The order-1
Lie rank (static, Omega = 0, and exact, at x = 0) with and without DOO over S8 and over
``extension.random_positions`` random beta = 0 positions (``default_rng(extension.seed)``,
alpha and gamma uniform in [0, 360) deg), and the covariance-only sigma/|truth| of every
higher-order term with the random positions x ``extension.dwell_s``.
"""

from __future__ import annotations

import numpy as np

from .filter import covariance_only
from .lie import rank_analysis
from .model import EXT_ACCEL, EXT_GYRO, coef_names, term_of


def random_positions(n: int, seed: int) -> np.ndarray:
    """``n`` positions (deg), beta = 0, alpha and gamma uniform in [0, 360)."""
    rng = np.random.default_rng(seed)
    ag = rng.uniform(0.0, 360.0, size=(n, 2))
    return np.column_stack([ag[:, 0], np.zeros(n), ag[:, 1]])


def position_sets(cfg) -> dict[str, np.ndarray]:
    e = cfg.raw["extension"]
    return {"S8": cfg.scheme("S8").angles_deg,
            f"random{e['random_positions']}": random_positions(e["random_positions"], e["seed"])}


def rank_table(cfg) -> list[dict]:
    """Order-1 ranks (static and exact, x = 0) with and without DOO for every position set."""
    rows = []
    dwell = float(cfg.raw["extension"]["dwell_s"])
    for name, pos in position_sets(cfg).items():
        for ext, label in ((1, "without DOO"), (2, "with DOO")):
            st = rank_analysis(cfg, pos, dwell, ext=ext, order=1, omega_on=False)
            ex = rank_analysis(cfg, pos, dwell, ext=ext, order=1)
            rows.append({"set": name, "positions": int(len(pos)), "model": label, "n_states": st["n_states"],
                         "static_rank": st["rank"], "exact_rank": ex["rank"],
                         "static_deficit": st["n_states"] - st["rank"], "exact_deficit": ex["n_states"] - ex["rank"],
                         "static_null_space": ", ".join(st["null_space"]),
                         "static_null_vectors": st["null_vectors"]})
    return rows


def sigma_table(cfg) -> list[dict]:
    """Covariance-only sigma/|truth| (%) of the higher-order terms, random positions, 51 states."""
    dwell = float(cfg.raw["extension"]["dwell_s"])
    name, pos = list(position_sets(cfg).items())[1]
    P = covariance_only(cfg, pos, dwell, ext=1)
    truth = cfg.truth(1)
    sig = np.sqrt(np.diag(P))
    rows = []
    for n, t, s in zip(coef_names(1), truth, sig):
        if term_of(n) in EXT_GYRO + EXT_ACCEL:
            rows.append({"name": n, "term": term_of(n), "truth": float(t), "sigma": float(s),
                         "rel_sigma_pct": float(s / abs(t) * 100.0) if t else float("nan"), "set": name})
    return rows
