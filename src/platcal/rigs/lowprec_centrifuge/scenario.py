"""The scenarios of the low-precision centrifuge's study (docs/lowprec-centrifuge.md §2 sweep),
the failed-fit flags of its cells (§11) and the figures' traces: what the Monte Carlo hooks
(:mod:`.montecarlo`) need, without pandas (the rig's identify imports :mod:`.montecarlo`; the
tables built from the tidy Monte Carlo tables are :mod:`.study`'s, issue 22 item 3).
"""

from __future__ import annotations

import numpy as np

from .config import Study
from .proposed import find_windows


def scenarios(study: Study) -> dict[str, dict]:
    """The scenarios of §2: default, the rate and arm sweeps, perfect, worst, gross (+ and -).

    Values: {"centrifuge": Centrifuge, "axis": rate|arm|extreme|default}. Sweep points equal
    to the default are the ``default`` scenario.
    """
    cen = study.centrifuge
    out = {"default": {"centrifuge": cen, "axis": "default"}}

    def add(name, c, axis):
        if c == cen:
            return
        out.setdefault(name, {"centrifuge": c, "axis": axis})

    for v in study.study["rate_errors"]:
        add(f"rate-{v:g}", cen.with_imprecision(rate_error=float(v)), "rate")
    for v in study.study["arm_errors_mm"]:
        add(f"arm-{v:g}mm", cen.with_imprecision(arm_error_mm=float(v)), "arm")
    add("perfect", cen.with_imprecision(0.0, 0.0, 0.0), "extreme")
    w = study.study["worst"]
    add("worst", cen.with_imprecision(w.get("rate_error"), w.get("arm_error_mm"), w.get("stretch_mm_per_g")),
        "extreme")
    g = study.study["gross"]
    if g:   # {} switches the gross extras off
        add("gross", cen.with_imprecision(g.get("rate_error"), g.get("arm_error_mm")), "extreme")
        add("gross-neg", cen.with_imprecision(-g.get("rate_error", 0.0), -g.get("arm_error_mm", 0.0)), "extreme")
    return out


def failed_fits(x: np.ndarray, P: np.ndarray | None = None) -> np.ndarray:
    """(S,) True where a seed's identification failed: a non-finite estimate, or (proposed filter)
    a covariance that is not finite or not positive definite. Such runs are flagged in the tidy
    tables (column ``failed``) and counted in the report, never averaged in (:func:`drop_failed`)."""
    bad = ~np.all(np.isfinite(x), axis=1)
    if P is not None:
        for i in range(P.shape[0]):
            if bad[i] or not np.all(np.isfinite(P[i])):
                bad[i] = True
                continue
            try:
                np.linalg.cholesky(0.5 * (P[i] + P[i].T))
            except np.linalg.LinAlgError:
                bad[i] = True
    return bad


def trace_of(rb, coeffs_proposed, coeffs_traditional, truth) -> dict:
    """Traces of replicate 0 of a run (the figures' data): dVE, pE before compensation and the unit
    responses (10 Hz), the heading around the first spin with its windows, and the proposed,
    traditional and true coefficients (ug/g, ug/g^2)."""
    step = max(1, int(round(0.1 / rb.prof.dt)))
    t = rb.prof.t
    ia = int(np.flatnonzero(rb.prof.schedule != 0)[0]) - 1
    sl = slice(max(ia - int(3 / rb.prof.dt), 0), ia + int(25 / rb.prof.dt))
    psi_u = np.unwrap(rb.psi[0])
    win = find_windows(t, psi_u, rb.prof.schedule)
    return {"platform": rb.platform, "run": rb.run, "seed": int(rb.seeds[0]), "t": t[::step],
            "before": rb.err[0, ::step][:, [0, 2]], "sens": rb.sens[:, ::step][:, :, [0, 2]],
            "proposed_coeffs": coeffs_proposed, "traditional_coeffs": coeffs_traditional, "truth": truth,
            "head_t": t[sl], "head_psi": psi_u[sl] - psi_u[ia],
            "win_ts": win.ts, "win_te": win.te, "win_spin": win.spinning, "spin_start": t[ia]}
