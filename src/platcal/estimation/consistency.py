"""Filter consistency: NEES of a batch of estimates and the chi-square bands it is judged by.

A consistent filter's NEES over n states is chi-square(n) distributed (mean n); its NIS over
an m-dimensional measurement is chi-square(m) per update. Both are the checks every rig's study
reports (docs/centrifuge-model.md §11 for the centrifuge).
"""

from __future__ import annotations

import sys

import numpy as np
from scipy import special


def nees(estimate: np.ndarray, cov: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ``e^T P^-1 e`` for a batch: (B, n), (B, n, n), (B|1, n)."""
    e = estimate - truth
    L = np.linalg.cholesky(cov)
    y = np.linalg.solve(L, e[..., None])[..., 0]
    return np.einsum("bi,bi->b", y, y)


def chi2_quantile(q: float, dof: float) -> float:
    """The ``q`` quantile of chi-square(``dof``): ``scipy.stats.chi2.ppf``'s own formula (its
    ``_ppf``, ``2 gammaincinv(dof / 2, q)``), bit for bit, from ``scipy.special``, so that an
    ``identify`` does not import ``scipy.stats`` (with its optimize and interpolate: about 45 MB
    resident, issue 22 item 3). ``q`` in (0, 1)."""
    return float(2.0 * special.gammaincinv(dof / 2.0, q))


def normal_quantile(q: float) -> float:
    """The ``q`` quantile of the standard normal: ``scipy.stats.norm.ppf``'s ``ndtri``, bit for bit
    (see :func:`chi2_quantile`). ``q`` in (0, 1)."""
    return float(special.ndtri(q))


def nees_band(dof: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` band of a chi-square(dof) NEES (for 45: 28.4 .. 65.4)."""
    a = (1.0 - level) / 2.0
    return chi2_quantile(a, dof), chi2_quantile(1.0 - a, dof)


def estimate_problems(x: np.ndarray, P: np.ndarray | None, names=None) -> list[str]:
    """Why one run's estimate ``x`` (n,) and covariance ``P`` (n, n) (None: no covariance) cannot be
    trusted, empty if they can: non-finite estimates (named from ``names`` when given), a
    covariance with non-finite entries, or one that is not positive definite. Plain numbers and
    names, for people."""
    out = []
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        shown = [str(names[i]) for i in bad[:5]] if names is not None else []
        more = " ..." if bad.size > 5 else ""
        out.append(f"{bad.size} non-finite estimate(s)" + (f" ({', '.join(shown)}{more})" if shown else ""))
    if P is None:
        return out
    if not np.all(np.isfinite(P)):
        out.append("the covariance has non-finite entries")
    else:
        try:
            np.linalg.cholesky(0.5 * (P + P.T))
        except np.linalg.LinAlgError:
            out.append("the final covariance is not positive definite")
    return out


EXIT_RUN_FAILED = 1
"""Exit status of ``platcal identify`` when the estimator's run over the record cannot be trusted
(nothing written); 2 is bad input, 3 a record that does not fit (:mod:`.fit`)."""


def failed_run_status(problems: list[str], what: str, data, out, check: str) -> int:
    """0 when ``problems`` (a run's :func:`estimate_problems` and the like) is empty; else one
    line on stderr naming ``what`` ran over the record ``data``, the problems, the untouched
    output ``out`` and what to ``check``, and :data:`EXIT_RUN_FAILED`."""
    if not problems:
        return 0
    print(f"platcal identify: error: {what} over {data} failed: {'; '.join(problems)}. "
          f"Nothing was written to {out}. Check {check}.", file=sys.stderr)
    return EXIT_RUN_FAILED
