"""Covariance-only analysis as functions of a covariance or an information matrix.

Correlations and the paper's correlation sum J (docs/centrifuge-model.md §10, eqs. 26-27), the
A-, D- and maxrel design criteria, the posterior covariance and Cramer-Rao bound from a Fisher
information in normalised units (coefficient / its prior sigma), and the numerical rank of a
Gram matrix. Every function takes arrays only: a rig supplies the covariance or the information
of its own test (e.g. from a covariance-only run of its filter).
"""

from __future__ import annotations

import numpy as np

CRITERIA = ("J", "A", "D", "maxrel")
"""Design criteria (all minimised): the paper's correlation sum J; A-optimal, the trace of the
covariance normalised by the truth magnitudes (= sum of squared predicted relative sigmas);
D-optimal, the log-determinant of the same; maxrel, the largest predicted relative sigma (%)."""

RANK_RTOL = 1e-7
"""Singular values below ``RANK_RTOL * s_max`` count as zero (a Gram matrix resolves ~1e-8)."""


def correlation(P: np.ndarray) -> np.ndarray:
    """Correlation matrix ``rho_ij = P_ij / sqrt(P_ii P_jj)`` of a (..., n, n) covariance."""
    P = np.asarray(P, float)
    d = np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
    return P / (d[..., :, None] * d[..., None, :])


def j_objective(P: np.ndarray) -> np.ndarray:
    """The paper's J = sum over i < j of |rho_ij| of a (..., n, n) covariance (eq. 27)."""
    rho = correlation(P)
    n = rho.shape[-1]
    iu = np.triu_indices(n, 1)
    return np.abs(rho[..., iu[0], iu[1]]).sum(axis=-1)


def relative_scale(truth: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Magnitudes that normalise the coefficients: |truth|, or ``fallback`` where truth is 0."""
    truth = np.abs(np.asarray(truth, float))
    return np.where(truth > 0, truth, np.asarray(fallback, float))


def criteria(P: np.ndarray, scale: np.ndarray) -> dict[str, np.ndarray]:
    """Every design criterion of a (..., n, n) coefficient covariance; ``scale`` (n,) magnitudes.

    Returns ``{'J', 'A', 'D', 'maxrel', 'rms_rel'}`` with the batch shape; ``rms_rel`` is the
    predicted RMS relative sigma in % (``sqrt(A / n) * 100``).
    """
    P = np.asarray(P, float)
    s = np.asarray(scale, float)
    Pn = P / (s[:, None] * s[None, :])
    var = np.diagonal(Pn, axis1=-2, axis2=-1)
    sign, logdet = np.linalg.slogdet(Pn)
    logdet = np.where(sign > 0, logdet, np.inf)
    A = var.sum(axis=-1)
    return {
        "J": j_objective(P),
        "A": A,
        "D": logdet,
        "maxrel": np.sqrt(var.max(axis=-1)) * 100.0,
        "rms_rel": np.sqrt(A / P.shape[-1]) * 100.0,
    }


def posterior_covariance(F: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """``(P0^-1 + F)^-1`` in engineering units from normalised information (B, nc, nc)."""
    nc = F.shape[-1]
    Pn = np.linalg.inv(F + np.eye(nc))
    Pn = 0.5 * (Pn + np.swapaxes(Pn, -1, -2))
    return Pn * (p0[:, None] * p0[None, :])


def crb_sigma(F: np.ndarray, p0: np.ndarray) -> np.ndarray:
    """Cramer-Rao bound (1 sigma, engineering units) without prior, from normalised F (nc, nc).

    NaN where F is singular (a coefficient the data cannot determine).
    """
    w, V = np.linalg.eigh(0.5 * (F + F.T))
    if w.min() <= w.max() * 1e-13:
        return np.full(F.shape[0], np.nan)
    var = (V**2 / w[None, :]).sum(axis=1)
    return np.sqrt(var) * p0


def gram_singular_values(G: np.ndarray) -> np.ndarray:
    """Singular values, descending, of a matrix O from its Gram matrix ``O^T O`` (symmetrised)."""
    return np.sqrt(np.clip(np.linalg.eigvalsh(0.5 * (G + G.T))[::-1], 0, None))


def numerical_rank(sv: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """Number of singular values above ``rtol`` times the largest."""
    return int((sv > rtol * sv[0]).sum())


def marginal_information(F: np.ndarray, keep: np.ndarray, nuisance_prior: np.ndarray) -> np.ndarray:
    """Information about the states ``keep`` with the others marginalised (Schur complement).

    ``F`` (..., n, n) information (any consistent units); ``keep`` (n,) bool; ``nuisance_prior``
    (n,) the prior information (1 / sigma^2) of each state, used for the marginalised ones only:
    ``F_kk - F_kn (F_nn + diag(prior_n))^-1 F_nk``. Returns (..., k, k).
    """
    keep = np.asarray(keep, bool)
    drop = ~keep
    Fkk = F[..., keep][..., keep, :]
    if not drop.any():
        return Fkk
    Fkn = F[..., keep, :][..., :, drop]
    Fnn = F[..., drop, :][..., :, drop] + np.diag(np.asarray(nuisance_prior, float)[drop])
    out = Fkk - Fkn @ np.linalg.solve(Fnn, np.swapaxes(Fkn, -1, -2))
    return 0.5 * (out + np.swapaxes(out, -1, -2))
