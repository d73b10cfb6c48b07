"""Observability of a test scheme: covariance-only EKF, correlation objective and design criteria.

docs/centrifuge-model.md §10 (paper eqs. 26-27) judges a scheme by the correlation coefficients of the
filter covariance at the end of a covariance-only run, linearised about the true trajectory::

    rho_ij = P_ij / sqrt(P_ii P_jj),        J = sum_{i<j} |rho_ij|   (45 coefficients)

**Position decomposition.** Linearised about the truth, the covariance-only run is the Kalman
filter of a linear Gaussian model. At the start of each position the attitude states are reset
(commanded angles, variance sigma_set^2, no cross-covariance), so every position's data carry
an independent piece of Fisher information about the coefficients, with that position's
attitude states (and the gyro noise inside it) marginalised out. Hence, exactly,

    P_end^-1 = P0^-1 + sum_k I_k,          I_k = I(alpha_k, beta_k, gamma_k, g_k, dwell)

and ``I_k`` does not depend on the other positions or on the order: it is obtained from a
one-position covariance-only EKF run as ``I_k = P_1^-1 - P0^-1``. A scheme's covariance is
then one small matrix inverse, which is what makes the genetic algorithm cheap
(:func:`scheme_covariance` checks itself against the direct multi-position run in the tests).
All information matrices are kept in *normalised* units (coefficient / its P0 sigma).

**Fisher information and Cramer-Rao bound.** ``F = sum_k I_k`` is the exact Fisher information
of the linearised model (accelerometer noise, gyro angle random walk and setting errors all
included); ``F^-1`` is the Cramer-Rao bound of an unbiased estimator without prior, and
``(P0^-1 + F)^-1`` (the filter's covariance) the Bayesian bound with the prior.

**Observability matrix.** The patent's rank test for 1 g self-calibration, generalised to the
time-varying centrifuge: the state of a K-position scheme is the coefficients plus the three
initial angles of each position; the stacked linearised observability matrix has one 3-row
block ``[H_c + H_a Phi_c(t) | H_a Phi_a(t)]`` per filter instant of every position (no noise).
Its singular values (columns scaled by the prior sigmas, rows by 1/sigma_a) are computed from
the Gram matrix accumulated by a compiled kernel.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numba import njit

from ...errors import InputError
from ...estimation import information
from ...estimation.information import (CRITERIA, correlation, crb_sigma, criteria, gram_singular_values,
                                       j_objective, numerical_rank, posterior_covariance, relative_scale)
from ...io import atomic_files, json_text, write_csv
from .attitude import make_rk4_scratch, make_work, measure_into, rk4_step_jac
from ...model.frames import ARCSEC, DEG
from ...model.instruments import FULL_NAMES, N_FULL, N_IDENTIFIED, group_of, unit_of
from .base import broadcast_params, specific_force_into
from .ekf import EstimatorInput, FilterSettings, default_p0_sigma, filter_times, run_ekf
from .identify import simulate_identify
from ...scheme import whole_periods

CRITERION_HELP = {
    "J": "sum_{i<j} |rho_ij| over the 45 coefficients (paper eq. 27)",
    "A": "sum_i (sigma_i / |truth_i|)^2 (A-optimal, relative units)",
    "D": "log det(N P N), N = diag(1/|truth_i|) (D-optimal, relative units)",
    "maxrel": "max_i sigma_i / |truth_i| * 100 % (largest predicted relative sigma)",
}

# ------------------------------------------------------------------ covariance-only runs

@dataclass(frozen=True)
class Setup:
    """What a covariance-only evaluation needs: model, truth and filter (one study's settings)."""

    centrifuge: object
    truth: np.ndarray          # (48,) full true coefficients
    filter: FilterSettings
    dwell_s: float

    @property
    def p0(self) -> np.ndarray:
        return np.asarray(self.filter.p0_sigma, float)

    @property
    def n_coef(self) -> int:
        return int(self.filter.coef_index.size)

    @property
    def times(self) -> np.ndarray:
        """Filter instants of one position, s."""
        whole_periods(self.dwell_s, self.filter.period_s, "dwell_s", "filter periods")
        return filter_times(self.dwell_s, self.filter.period_s, self.filter.update_at_reset)


def setup_from_study(study, dwell_s: float, **filter_overrides) -> Setup:
    """A :class:`Setup` from a :class:`~platcal.config.Study` (filter fields may be overridden)."""
    # covariance-only batches on the state-major kernel, the one the study's other runs load
    # (:func:`.identify.simulate_identify`; the same numbers bit for bit)
    fs = replace(study.filter, history_every_s=None, lanes=True, **filter_overrides)
    return Setup(centrifuge=study.centrifuge, truth=np.asarray(study.truth, float), filter=fs,
                 dwell_s=float(dwell_s))


def _params_for(setup: Setup, g_levels) -> np.ndarray:
    """(P, 5) packed centrifuge parameters for positions at ``g_levels`` (None: the default)."""
    if g_levels is None:
        return setup.centrifuge.params()[None, :]
    return np.stack([setup.centrifuge.params(float(g)) for g in np.atleast_1d(g_levels)])


def direct_covariance(setup: Setup, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
    """Coefficient covariance at the end of a covariance-only run of whole schemes (batched).

    ``angles_deg`` (B, K, 3) or (K, 3); ``g_levels`` None, (K,) or (B, K). Returns (B, nc, nc).
    This is the plain multi-position EKF run of docs/centrifuge-model.md §10 (reference for the tests).
    """
    ang = np.asarray(angles_deg, float)
    if ang.ndim == 2:
        ang = ang[None]
    B, K, _ = ang.shape
    if g_levels is None:
        params = setup.centrifuge.params()
    else:
        gl = np.broadcast_to(np.asarray(g_levels, float), (B, K))
        params = np.stack([[setup.centrifuge.params(float(g)) for g in row] for row in gl])
    t = [setup.times] * K
    est = run_ekf(EstimatorInput([np.zeros((B, 0, 3))] * K, t, ang, params), setup.filter,
                  linearise_about=np.tile(setup.truth, (B, 1)))
    nc = setup.n_coef
    return est.P[:, :nc, :nc]


def position_information(setup: Setup, angles_deg: np.ndarray, g_levels=None, chunk: int = 256) -> np.ndarray:
    """Normalised Fisher information ``I_k`` (P, nc, nc) of single positions (batched run).

    ``angles_deg`` (P, 3) deg; ``g_levels`` None or (P,). Units: coefficient / P0 sigma.
    """
    ang = np.asarray(angles_deg, float).reshape(-1, 3)
    P = ang.shape[0]
    gl = None if g_levels is None else np.broadcast_to(np.asarray(g_levels, float), (P,))
    nc = setup.n_coef
    p0 = setup.p0
    out = np.empty((P, nc, nc))
    t = [setup.times]
    eye = np.eye(nc)
    for a in range(0, P, chunk):
        b = min(P, a + chunk)
        params = (np.broadcast_to(setup.centrifuge.params(), (b - a, 1, 5)) if gl is None
                  else _params_for(setup, gl[a:b])[:, None, :])
        est = run_ekf(EstimatorInput([np.zeros((b - a, 0, 3))], t, ang[a:b, None, :], params), setup.filter,
                      linearise_about=np.tile(setup.truth, (b - a, 1)))
        Pn = est.P[:, :nc, :nc] / (p0[:, None] * p0[None, :])
        Pn = 0.5 * (Pn + np.swapaxes(Pn, 1, 2))
        info = np.linalg.inv(Pn) - eye
        out[a:b] = 0.5 * (info + np.swapaxes(info, 1, 2))
    return out


class InfoCache:
    """Per-position information, computed once per distinct (alpha, beta, gamma, g-level)."""

    def __init__(self, setup: Setup):
        self.setup = setup
        self._store: dict[tuple, np.ndarray] = {}
        self.runs = 0

    @staticmethod
    def key(pos, g) -> tuple:
        return (round(float(pos[0]), 9), round(float(pos[1]), 9), round(float(pos[2]), 9),
                None if g is None else round(float(g), 9))

    def fill(self, positions: np.ndarray, g_levels=None) -> None:
        """Compute (in one batched run) the information of every position not seen yet."""
        pos = np.asarray(positions, float).reshape(-1, 3)
        gl = [None] * len(pos) if g_levels is None else list(np.asarray(g_levels, float).reshape(-1))
        new, seen = [], set()
        for p, g in zip(pos, gl):
            k = self.key(p, g)
            if k not in self._store and k not in seen:
                seen.add(k)
                new.append((p, g, k))
        if not new:
            return
        angles = np.array([n[0] for n in new])
        gls = None if g_levels is None else np.array([n[1] for n in new])
        info = position_information(self.setup, angles, gls)
        self.runs += len(new)
        for (_, _, k), m in zip(new, info):
            self._store[k] = m

    def get(self, pos, g=None) -> np.ndarray:
        return self._store[self.key(pos, g)]

    def scheme_information(self, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
        """Summed normalised information (B, nc, nc) of schemes (B, K, 3) [g_levels (B, K)]."""
        ang = np.asarray(angles_deg, float)
        if ang.ndim == 2:
            ang = ang[None]
        B, K, _ = ang.shape
        gl = None if g_levels is None else np.broadcast_to(np.asarray(g_levels, float), (B, K))
        self.fill(ang.reshape(-1, 3), None if gl is None else gl.reshape(-1))
        nc = self.setup.n_coef
        out = np.zeros((B, nc, nc))
        for b in range(B):
            for k in range(K):
                out[b] += self.get(ang[b, k], None if gl is None else gl[b, k])
        return out

    def covariance(self, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
        """Coefficient covariance (B, nc, nc), engineering units, of schemes (B, K, 3)."""
        F = self.scheme_information(angles_deg, g_levels)
        return posterior_covariance(F, self.setup.p0)


def scheme_covariance(setup: Setup, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
    """Coefficient covariance of one or more schemes by the position decomposition."""
    return InfoCache(setup).covariance(angles_deg, g_levels)


# ------------------------------------------------------------------ observability matrix

# serial: its jobs run on one thread (the observability of a scheme: a few positions, 0.3 s), and
# numba's parallel lowering cost 1-1.5 s of the 11-13 s cold compile (issue 22 item 4)
@njit(cache=True)
def _position_grams(ang0, coef, t, params, G):
    """Gram matrices ``O_k^T O_k`` (P, 51, 51) of single positions: [48 coef | 3 initial angles].

    ``ang0`` (P, 3) rad, ``coef`` (48,), ``t`` (M,) s, ``params`` (P, 5). Rows of O are the
    noise-free linearised outputs ``dA(t_m) / d[coef, ang0]`` (g per unit).
    """
    Pn = ang0.shape[0]
    M = t.shape[0]
    nf = coef.shape[0]
    for p in range(Pn):
        work = make_work()
        scratch = make_rk4_scratch()
        ang = ang0[p].copy()
        new = np.empty(3)
        pa = np.empty((3, 3))
        pc = np.empty((3, nf))
        phi_a = np.eye(3)
        phi_c = np.zeros((3, nf))
        tmp_a = np.empty((3, 3))
        tmp_c = np.empty((3, nf))
        out = np.empty(3)
        hc = np.empty((3, nf))
        ha = np.empty((3, 3))
        row = np.empty((3, nf + 3))
        fr3 = np.empty((3, 3))
        Gp = G[p]
        # the initial angles are those at the position's start t = 0 (the filter's reset);
        # the first instant may lie after it (ekf.filter_times)
        t_prev = 0.0
        for m in range(M):
            if t[m] > t_prev:
                h = t[m] - t_prev
                specific_force_into(t_prev, params[p], fr3[0])
                specific_force_into(t_prev + 0.5 * h, params[p], fr3[1])
                specific_force_into(t_prev + h, params[p], fr3[2])
                rk4_step_jac(ang, coef, fr3, h, params[p], new, pa, pc, work, scratch)
                for r in range(3):
                    for i in range(3):
                        tmp_a[r, i] = pa[r, 0] * phi_a[0, i] + pa[r, 1] * phi_a[1, i] + pa[r, 2] * phi_a[2, i]
                    for i in range(nf):
                        tmp_c[r, i] = pc[r, i] + pa[r, 0] * phi_c[0, i] + pa[r, 1] * phi_c[1, i] + pa[r, 2] * phi_c[2, i]
                # element copies, not slice assignments: those bring numba's shape-mismatch error
                # (its message formatting) into the kernel, about 4 s of its cold compile (issue 22)
                for r in range(3):
                    ang[r] = new[r]
                    for i in range(3):
                        phi_a[r, i] = tmp_a[r, i]
                    for i in range(nf):
                        phi_c[r, i] = tmp_c[r, i]
                t_prev = t[m]
            specific_force_into(t[m], params[p], fr3[0])
            measure_into(ang, coef, fr3[0], params[p], out, hc, ha, work)
            for r in range(3):
                for i in range(nf):
                    row[r, i] = hc[r, i] + ha[r, 0] * phi_c[0, i] + ha[r, 1] * phi_c[1, i] + ha[r, 2] * phi_c[2, i]
                for i in range(3):
                    row[r, nf + i] = ha[r, 0] * phi_a[0, i] + ha[r, 1] * phi_a[1, i] + ha[r, 2] * phi_a[2, i]
            for i in range(nf + 3):
                for j in range(i, nf + 3):
                    s = row[0, i] * row[0, j] + row[1, i] * row[1, j] + row[2, i] * row[2, j]
                    Gp[i, j] += s
        for i in range(nf + 3):
            for j in range(i):
                Gp[i, j] = Gp[j, i]


def position_grams(setup: Setup, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
    """Gram matrices (P, 51, 51) of the noise-free observability matrix of single positions."""
    ang = np.ascontiguousarray(np.asarray(angles_deg, float).reshape(-1, 3) * DEG)
    P = ang.shape[0]
    params = np.ascontiguousarray(np.broadcast_to(_params_for(setup, g_levels), (P, 5)))
    G = np.zeros((P, N_FULL + 3, N_FULL + 3))
    _position_grams(ang, np.ascontiguousarray(setup.truth), setup.times, params, G)
    return G


@dataclass
class ObservabilityMatrix:
    """Rank test of the stacked linearised observability matrix of a scheme."""

    n_rows: int
    n_cols: int
    singular_values: np.ndarray     # normalised (columns by prior sigma, rows by 1/sigma_a)
    rank: int
    coef_rank: int                  # rank of the coefficient block after the angles are removed
    coef_singular_values: np.ndarray


def observability_matrix(setup: Setup, angles_deg: np.ndarray, g_levels=None) -> ObservabilityMatrix:
    """Singular values and rank of the scheme's stacked observability matrix (noise-free).

    Columns: the filter's coefficients (45, or 48 with DOO) and 3 initial angles per position,
    scaled by their prior sigmas (P0, sigma_set); rows scaled by 1/sigma_a. ``coef_*`` is the
    same test for the coefficients alone, with every position's initial angles projected out.
    """
    ang = np.asarray(angles_deg, float).reshape(-1, 3)
    K = ang.shape[0]
    Gs = _scaled_grams(setup, position_grams(setup, ang, g_levels))
    nc = setup.filter.coef_index.size
    n = nc + 3 * K
    big = np.zeros((n, n))
    schur = np.zeros((nc, nc))
    for k in range(K):
        g = Gs[k]
        a = slice(nc + 3 * k, nc + 3 * k + 3)
        big[:nc, :nc] += g[:nc, :nc]
        big[:nc, a] = g[:nc, nc:]
        big[a, :nc] = g[nc:, :nc]
        big[a, a] = g[nc:, nc:]
        gaa = g[nc:, nc:]
        gca = g[:nc, nc:]
        schur += g[:nc, :nc] - gca @ np.linalg.pinv(gaa, rcond=1e-12, hermitian=True) @ gca.T
    sv = gram_singular_values(big)
    svc = gram_singular_values(schur)
    return ObservabilityMatrix(
        n_rows=3 * K * setup.times.size, n_cols=n, singular_values=sv,
        rank=numerical_rank(sv), coef_rank=numerical_rank(svc), coef_singular_values=svc,
    )


def _scaled_grams(setup: Setup, G: np.ndarray) -> np.ndarray:
    """Per-position Grams (P, nc + 3, nc + 3) over the filter's coefficients and the 3 initial
    angles, columns scaled by their prior sigmas (P0, sigma_set) and rows by 1/sigma_a^2."""
    sel = np.concatenate([setup.filter.coef_index, N_FULL + np.arange(3)])
    s_col = np.concatenate([setup.p0, np.full(3, setup.filter.sigma_set_arcsec * ARCSEC)])
    w = 1.0 / (setup.filter.sigma_a_ug * 1e-6) ** 2
    return G[:, sel][:, :, sel] * (s_col[:, None] * s_col[None, :]) * w


def gram_information(setup: Setup, angles_deg: np.ndarray, g_levels=None) -> np.ndarray:
    """Normalised coefficient information of single positions without gyro noise, (P, nc, nc).

    Built from the observability Gram with each position's initial angles marginalised under
    their sigma_set prior; equals :func:`position_information` when ARW = 0 (a test of both).
    """
    Gs = _scaled_grams(setup, position_grams(setup, angles_deg, g_levels))
    nc = setup.filter.coef_index.size
    out = np.empty((Gs.shape[0], nc, nc))
    for p in range(Gs.shape[0]):
        g = Gs[p]
        gaa = g[nc:, nc:] + np.eye(3)
        out[p] = g[:nc, :nc] - g[:nc, nc:] @ np.linalg.solve(gaa, g[nc:, :nc])
    return out


# ------------------------------------------------------------------ Monte Carlo (small, for comparison)

def monte_carlo_errors(study, scheme, replicates: int, seed: int | None = None, filter_settings=None,
                       batch: int = 8) -> np.ndarray:
    """Estimation errors (R, nc) of the study's EKF on ``replicates`` simulated runs of a scheme.

    Replicate r uses ``SeedSequence(seed).spawn(R)[r]`` (seed: the study's by default), so the
    numbers do not depend on the batch size.
    """
    fs = filter_settings or replace(study.filter, history_every_s=None)
    seeds = np.random.SeedSequence(study.seed if seed is None else seed).spawn(replicates)
    idx = fs.coef_index
    out = [simulate_identify(study, scheme, seeds[a:a + batch], fs).coef - study.truth[idx][None]
           for a in range(0, replicates, batch)]
    return np.concatenate(out)


def rms_relative_error(errors: np.ndarray, truth: np.ndarray) -> float:
    """Pooled RMS relative error, %: sqrt(mean over replicates and coefficients of e_ri^2)."""
    rel = errors / truth[None, :] * 100.0
    return float(np.sqrt(np.mean(rel**2)))


# ------------------------------------------------------------------ the report of one scheme

def evaluate_scheme(study, scheme, *, arw_deg_rth: float | None = None, estimate_doo: bool | None = None,
                    rate_deg_s: float | None = None) -> dict:
    """``(result, P, names)``: the JSON-ready result of :func:`write_observability`, the
    coefficient covariance (engineering units) and the coefficient names.

    ``arw_deg_rth`` overrides the filter's ARW, ``estimate_doo`` selects the 51-state filter,
    ``rate_deg_s`` the centrifuge rate (0: static 1 g).
    """
    over = {}
    if arw_deg_rth is not None:
        over["arw_deg_rth"] = float(arw_deg_rth)
    if estimate_doo is not None and estimate_doo != study.filter.estimate_doo:
        over["estimate_doo"] = bool(estimate_doo)
        over["p0_sigma"] = default_p0_sigma(bool(estimate_doo), study.config["filter"]["p0"])
    setup = setup_from_study(study, scheme.dwell_s, **over)
    if rate_deg_s is not None:
        setup = replace(setup, centrifuge=replace(setup.centrifuge, rate_deg_s=float(rate_deg_s)))
    t0 = time.perf_counter()
    cache = InfoCache(setup)
    F = cache.scheme_information(scheme.angles_deg, scheme.g_levels)[0]
    P = posterior_covariance(F[None], setup.p0)[0]
    seconds = time.perf_counter() - t0
    nc = setup.n_coef
    idx = setup.filter.coef_index
    names = [FULL_NAMES[i] for i in idx]
    truth = setup.truth[idx]
    scale = relative_scale(truth, setup.p0)
    n45 = min(nc, N_IDENTIFIED)
    crit = {k: float(v) for k, v in criteria(P[:n45, :n45], scale[:n45]).items()}
    crit_all = {k: float(v) for k, v in criteria(P, scale).items()} if nc > n45 else None
    sig = np.sqrt(np.diag(P))
    crb = crb_sigma(F, setup.p0)
    rho = correlation(P)
    iu = np.triu_indices(n45, 1)
    r45 = rho[:n45, :n45][iu]
    top = np.argsort(-np.abs(r45))[:10]
    obs = observability_matrix(setup, scheme.angles_deg, scheme.g_levels)
    cen = setup.centrifuge
    result = {
        "scheme": scheme.name,
        "positions": [list(p) for p in scheme.positions],
        "g_levels": None if scheme.g_levels is None else list(scheme.g_levels),
        "J": crit["J"],
        "n_pairs": int(n45 * (n45 - 1) // 2),
        "criteria": crit,
        "criteria_help": CRITERION_HELP,
        "criteria_all_states": crit_all,
        "settings": {
            "dwell_s": scheme.dwell_s, "filter_period_s": setup.filter.period_s,
            "sigma_a_ug": setup.filter.sigma_a_ug, "arw_deg_rth": setup.filter.arw_deg_rth,
            "sigma_set_arcsec": setup.filter.sigma_set_arcsec, "estimate_doo": setup.filter.estimate_doo,
            "n_states": nc + 3, "centrifuge_rate_deg_s": cen.rate_deg_s, "g_level": cen.g_level,
            "latitude_deg": cen.latitude_deg,
            "p0_sigma": {n: float(s) for n, s in zip(names, setup.p0)},
            "linearised_about": "the true coefficients and the noise-free trajectory from the commanded angles",
        },
        "coefficients": [
            {"name": n, "unit": unit_of(n), "group": group_of(n), "truth": float(tr),
             "prior_sigma": float(p0), "posterior_sigma": float(s), "posterior_over_prior": float(s / p0),
             "predicted_rel_sigma_pct": float(s / sc * 100.0),
             "crb_sigma": None if not math.isfinite(c) else float(c)}
            for n, tr, p0, s, sc, c in zip(names, truth, setup.p0, sig, scale, crb)
        ],
        "largest_correlations": [
            {"i": names[iu[0][j]], "j": names[iu[1][j]], "rho": float(r45[j])} for j in top
        ],
        "fisher": {
            "rank": int(np.linalg.matrix_rank(F, tol=np.abs(np.linalg.eigvalsh(F)).max() * 1e-12)),
            "crb_defined": bool(np.all(np.isfinite(crb))),
            "note": "F = sum of per-position information (ARW, sigma_a, sigma_set included); "
                    "CRB = F^-1 without prior; the filter covariance is (P0^-1 + F)^-1",
        },
        "observability_matrix": {
            "n_rows": obs.n_rows, "n_cols": obs.n_cols, "rank": obs.rank,
            "full_rank": obs.rank == obs.n_cols,
            "coef_rank": obs.coef_rank, "n_coef": nc,
            "rank_rtol": information.RANK_RTOL,
            "singular_values": [float(v) for v in obs.singular_values],
            "coef_singular_values": [float(v) for v in obs.coef_singular_values],
            "scaling": "columns by prior sigma (P0, sigma_set), rows by 1/sigma_a; noise-free",
        },
        "seconds": seconds,
    }
    return result, P, names


def write_observability(out_dir, study, scheme, replicates: int = 0, **kw) -> dict:
    """Write ``observability.json`` and ``correlation.csv`` (and ``coefficients.csv``)."""
    result, P, names = evaluate_scheme(study, scheme, **kw)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # coefficients.csv's columns (write_csv: pandas' to_csv text; this module is loaded by identify)
    coef = {k: [c[k] for c in result["coefficients"]] for k in result["coefficients"][0]}
    coef["crb_sigma"] = np.array([np.nan if v is None else v for v in coef["crb_sigma"]], float)
    if replicates > 0:
        fs = replace(study.filter, history_every_s=None)
        if "estimate_doo" in kw and kw["estimate_doo"] is not None and kw["estimate_doo"] != fs.estimate_doo:
                fs = replace(fs, estimate_doo=kw["estimate_doo"],
                         p0_sigma=default_p0_sigma(kw["estimate_doo"], study.config["filter"]["p0"]))
        if kw.get("arw_deg_rth") is not None or kw.get("rate_deg_s") is not None:
            raise InputError("--replicates", "a Monte Carlo comparison runs at the config's own noise "
                             "and centrifuge; drop --arw or --rate, or set them in the config")
        err = monte_carlo_errors(study, scheme, replicates, filter_settings=fs)
        coef["mc_std"] = err.std(axis=0, ddof=1)
        coef["mc_rms"] = np.sqrt((err**2).mean(axis=0))
        coef["mc_std_over_crb"] = coef["mc_std"] / coef["crb_sigma"]
        truth = np.array([c["truth"] for c in result["coefficients"]])
        n45 = min(len(truth), N_IDENTIFIED)
        result["monte_carlo"] = {
            "replicates": replicates, "seed": study.seed, "passes": fs.passes,
            "rms_rel_err_pct_45": rms_relative_error(err[:, :n45], truth[:n45]),
            "median_mc_std_over_crb": float(np.nanmedian(coef["mc_std_over_crb"])),
            "median_mc_std_over_filter_sigma": float(np.median(coef["mc_std"] / np.asarray(coef["posterior_sigma"]))),
        }
        for row, s, r in zip(result["coefficients"], coef["mc_std"], coef["mc_rms"]):
            row["mc_std"] = float(s)
            row["mc_rms"] = float(r)
    rho = correlation(P)
    # the three files land together, observability.json (strict JSON: null for NaN) last
    with atomic_files(out) as tmp:
        write_csv(tmp("correlation.csv"), {n: rho[:, i] for i, n in enumerate(names)}, index=("", list(names)))
        write_csv(tmp("coefficients.csv"), coef)
        tmp("observability.json").write_text(json_text(result))
    return result


# ------------------------------------------------------------------ CLI
