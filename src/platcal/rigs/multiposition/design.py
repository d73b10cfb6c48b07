"""A-optimal genetic-algorithm design of a multi-position scheme (docs/multiposition-1g.md §8, §11).

As the centrifuge's :mod:`platcal.design` (pymoo's single-objective GA with integer sampling,
SBX and polynomial mutation rounded to integers, duplicates eliminated), but over positions of
this rig: each of K positions is an (alpha, beta, gamma) on a ``design.grid_deg`` grid with
|beta| <= beta_max (the gimbal range, §3). Fitness is A-optimal, ``sum_i (sigma_i/|truth_i|)^2``
over the 24 coefficients, from the exact position decomposition of the covariance-only run
(:func:`.filter.position_information`): the information of every grid position is computed
once (step ``design.info_step_s``, noise scaled to the same density), then a scheme's covariance
is one 24 x 24 inverse. The optimum is re-evaluated at the §14 0.1 s step for the comparison.

This module should become the generic, rig-agnostic GA of the study layer (a rig supplies its
position grid and its per-position information); it lives here until that layer exists.
Reproducible: pymoo's seed is drawn from ``SeedSequence(design.seed or the config's seed)``.
"""

from __future__ import annotations

import numpy as np
from pymoo.algorithms.soo.nonconvex.ga import GA
from pymoo.core.problem import Problem
from pymoo.operators.crossover.sbx import SBX
from pymoo.operators.mutation.pm import PM
from pymoo.operators.repair.rounding import RoundingRepair
from pymoo.operators.sampling.rnd import IntegerRandomSampling
from pymoo.optimize import minimize

from ...scheme import Scheme
from .filter import position_information, scheme_covariance_from_info


def grid(cfg) -> np.ndarray:
    """(G, 3) candidate positions (deg) on the design grid inside the gimbal range."""
    step = int(cfg.raw["design"]["grid_deg"])
    ang = np.arange(0, 360, step, dtype=float)
    bmax = cfg.beta_max_deg
    betas = np.arange(-np.floor(bmax / step) * step, bmax + 1e-9, step) if step <= bmax else np.array([0.0])
    A, B, G = np.meshgrid(ang, betas, ang, indexing="ij")
    return np.column_stack([A.ravel(), B.ravel(), G.ravel()])


def a_criterion(cfg, info_sum: np.ndarray) -> np.ndarray:
    """A-optimal criterion of summed normalised information (..., 24, 24)."""
    p0, tr = cfg.p0(), np.abs(cfg.truth())
    Pn = np.linalg.inv(np.eye(p0.size) + info_sum)
    rel2 = np.diagonal(Pn, axis1=-2, axis2=-1) * (p0 / tr) ** 2
    return rel2.sum(axis=-1)


def run_design(cfg, n_positions: int, log=None) -> dict:
    """GA over ``n_positions`` grid positions; returns the best scheme and its history."""
    d = cfg.raw["design"]
    cand = grid(cfg)
    info = position_information(cfg, cand, d["dwell_s"], step_s=d["info_step_s"])
    K = int(n_positions)

    class P(Problem):
        def __init__(self):
            super().__init__(n_var=K, n_obj=1, xl=np.zeros(K), xu=np.full(K, len(cand) - 1), vtype=int)

        def _evaluate(self, X, out, *args, **kwargs):
            idx = np.asarray(np.round(X), dtype=np.int64)
            out["F"] = a_criterion(cfg, info[idx].sum(axis=1))[:, None]

    seed = cfg.seed if d["seed"] is None else int(d["seed"])
    pseed = int(np.random.SeedSequence([seed, K]).generate_state(1, dtype=np.uint32)[0])
    alg = GA(pop_size=int(d["population"]), sampling=IntegerRandomSampling(),
             crossover=SBX(prob=0.9, eta=15, vtype=float, repair=RoundingRepair()),
             mutation=PM(eta=20, vtype=float, repair=RoundingRepair()), eliminate_duplicates=True)
    res = minimize(P(), alg, ("n_gen", int(d["generations"])), seed=pseed, verbose=False)
    best = np.asarray(np.round(res.X), dtype=np.int64).ravel()
    pos = cand[np.sort(best)]
    name = f"GA{K}"
    scheme = Scheme(name=name, positions=tuple(tuple(float(a) for a in p) for p in pos), dwell_s=float(d["dwell_s"]))
    if log:
        log(f"{name}: A = {float(res.F[0]):.4g} over {len(cand)} grid positions, {res.algorithm.evaluator.n_eval} evaluations")
    return {"scheme": scheme, "A_fitness": float(res.F[0]), "grid_positions": int(len(cand)),
            "evaluations": int(res.algorithm.evaluator.n_eval), "pymoo_seed": pseed}


def compare(cfg, schemes: list[Scheme]) -> list[dict]:
    """A criterion and max sigma/|truth| of schemes at the §14 step (0.1 s)."""
    rows = []
    tr = np.abs(cfg.truth())
    for s in schemes:
        I = position_information(cfg, s.angles_deg, s.dwell_s).sum(axis=0)
        P = scheme_covariance_from_info(cfg, I)
        rel = np.sqrt(np.diag(P)) / tr * 100.0
        rows.append({"scheme": s.name, "positions": s.n_positions, "A": float(a_criterion(cfg, I)),
                     "rms_rel_sigma_pct": float(np.sqrt(np.mean(rel**2))), "max_rel_sigma_pct": float(rel.max()),
                     "angles_deg": "; ".join(f"({a:g},{b:g},{g:g})" for a, b, g in s.positions)})
    return rows
