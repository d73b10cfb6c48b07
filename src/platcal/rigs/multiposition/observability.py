"""Scheme check before the test (docs/multiposition-1g.md §8, §15; patent step 3).

Reports, for one scheme: the exact Lie rank (order ``observability.lie_order``, Earth rate on)
at x = 0 and at the truth; the static rank (Omega = 0) at x = 0, the design rule, with its null
space by coefficient name; the covariance-only posterior sigma of every coefficient (§14) and a
verdict. **The verdict never accepts on the exact rank alone** (§15: the Earth-rate sweep makes
it full for ROLL4): a scheme is refused when its static rank is short of n, its exact rank is
short of n, or a coefficient keeps ``sigma/|truth| > observability.max_rel_sigma_pct``.
"""

from __future__ import annotations

import numpy as np

from .filter import covariance_only
from .lie import rank_analysis
from .model import coef_names, group_of, unit_of


def coefficient_table(cfg, positions_deg, dwell_s: float, ext: int = 0) -> list[dict]:
    """Covariance-only prior/posterior sigma per coefficient (§8 'practical observability')."""
    P = covariance_only(cfg, positions_deg, dwell_s, ext)
    truth, p0 = cfg.truth(ext), cfg.p0(ext)
    sig = np.sqrt(np.diag(P))
    return [{"name": n, "unit": unit_of(n), "group": group_of(n), "truth": float(t), "prior_sigma": float(p),
             "posterior_sigma": float(s), "posterior_over_prior": float(s / p),
             "rel_sigma_pct": float(s / abs(t) * 100.0) if t != 0 else None}
            for n, t, p, s in zip(coef_names(ext), truth, p0, sig)]


def evaluate(cfg, scheme) -> dict:
    """The JSON-ready observability report of ``scheme`` (see the module docstring)."""
    pos, dwell = scheme.angles_deg, scheme.dwell_s
    xt = np.concatenate([np.zeros(3), cfg.truth()])
    ex0 = rank_analysis(cfg, pos, dwell)
    ext_ = rank_analysis(cfg, pos, dwell, x=xt)
    st0 = rank_analysis(cfg, pos, dwell, omega_on=False)
    stt = rank_analysis(cfg, pos, dwell, x=xt, omega_on=False)
    coefs = coefficient_table(cfg, pos, dwell)
    rel = [c["rel_sigma_pct"] for c in coefs if c["rel_sigma_pct"] is not None]
    worst = max((c for c in coefs if c["rel_sigma_pct"] is not None), key=lambda c: c["rel_sigma_pct"])
    n = ex0["n_states"]
    reasons, ok = [], True
    if st0["rank"] < n:
        ok = False
        reasons.append(f"static rank {st0['rank']} < {n}: unobservable without Earth rate: "
                       f"{', '.join(st0['null_space'])}")
    if min(ex0["rank"], ext_["rank"]) < n:
        ok = False
        reasons.append(f"exact Lie rank {ex0['rank']} (x = 0) / {ext_['rank']} (truth) < {n}")
    lim = cfg.max_rel_sigma_pct
    if max(rel) > lim:
        ok = False
        reasons.append(f"covariance-only sigma/|truth| of {worst['name']} is {max(rel):.3g} % > {lim:g} % "
                       f"(observability.max_rel_sigma_pct)")
    if ok:
        reasons.append(f"static rank {st0['rank']} = {n} and every sigma/|truth| <= {max(rel):.3g} % "
                       f"<= {lim:g} %")
    return {
        "rig": "multiposition", "scheme": scheme.name, "positions": [list(p) for p in scheme.positions],
        "dwell_s": dwell, "n_states": n,
        "static_rank": st0["rank"], "static_rank_truth": stt["rank"],
        "exact_rank_nominal": ex0["rank"], "exact_rank_truth": ext_["rank"],
        "null_space": st0["null_space"], "null_vectors": st0["null_vectors"],
        "exact_null_space_nominal": ex0["null_space"],
        "weakest_rel_singular_value": {"exact_nominal": ex0["weakest_rel_singular_value"],
                                       "static_nominal": st0["weakest_rel_singular_value"]},
        "max_rel_sigma_pct": float(max(rel)), "max_rel_sigma_coefficient": worst["name"],
        "max_posterior_over_prior": float(max(c["posterior_over_prior"] for c in coefs)),
        "verdict": {"accept": ok, "decision": "accept" if ok else "refuse", "reasons": reasons},
        "coefficients": coefs,
        "settings": {"lie_order": cfg.lie_order, "rank_rtol": cfg.rank_rtol, "cov_step_s": cfg.cov_step_s,
                     "sigma_a_ug": cfg.sigma_a_ug, "sigma_an_arcsec": cfg.sigma_an_arcsec,
                     "arw_deg_rth": cfg.arw_deg_rth, "sigma_set_arcsec": cfg.sigma_set_arcsec,
                     "max_rel_sigma_pct": lim, "latitude_deg": cfg.site.latitude_deg,
                     "scaling": "rows of L_f^k h times dwell^k / sigma_i, columns times P0 sigma (§8)",
                     "static": "Omega = 0 (design rule); exact: Earth rate on"},
    }
