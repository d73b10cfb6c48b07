"""The precision centrifuge's claims (Xu & Zhang 2017, Su et al.; docs/centrifuge-model.md §10-12,
§14) as measures on the study's results; the claims themselves are data (``data/claims.yaml``),
evaluated by :mod:`platcal.study.claims`.

The measures read, under the rig's results folder ``results/centrifuge``:

- ``montecarlo/coef.parquet``, ``runs.parquet`` (the sweep) and ``compare/coef.parquet``: the cell
  compared with the paper, ``study.paper`` at ``noise.sigma_a_ug`` unless ``study.paper.sigma_a_ug``
  is set, from whichever of the two ran it with more replicates;
- ``compare/coef.parquet``, ``compare/runs.parquet`` (the estimator comparison, issue 9);
- ``design/<ga>.json`` (the GA's optimum, when the sweep has that GA scheme).

The covariance-only quantities (J of Table 1, the sigmas' shrink from P0) are computed here from
the config, at the study's own settings (docs/centrifuge-model.md §10-11: "evaluate J at the
study's own settings and say which").
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims
from ...study.stats import select_cell
from .compare_cells import kind_of, passes_of, with_compare_estimators
from .config import check_filter, study_from_config
from .design import SchemeEvaluator
from .report import resolve_cell


def _same_estimator(cfg: dict, name: str) -> bool:
    """Whether the comparison's estimator ``name`` is the sweep's ``name`` (the comparison's own
    definitions override the sweep's on a shared name, :func:`.compare_cells.with_compare_estimators`)."""
    own = cfg["study"]["compare"]["estimators"]
    return not isinstance(own, dict) or name not in own or own[name] == cfg["study"]["estimators"].get(name)


def _paper_cell(results: Path, cfg: dict, table: str) -> tuple[pd.DataFrame, str] | None:
    """Rows of ``<table>.parquet`` in the cell compared with the paper (``study.paper``: scheme,
    noise level, estimator) and its settings text; None when the study wrote no such cell.

    The sweep (``montecarlo/``) and the estimator comparison (``compare/``) may both run that cell
    with the same estimator; the Table 2 claims are judged on the one with more replicates (the
    narrower interval), and the settings say which (docs/centrifuge-model.md §12)."""
    c = resolve_cell(cfg, "paper")
    found = []
    for source, label in (("montecarlo", ""), ("compare", "comparison, ")):
        path = Path(results) / source / f"{table}.parquet"
        if not path.exists() or (source == "compare" and not _same_estimator(cfg, c["estimator"])):
            continue
        cell = select_cell(pd.read_parquet(path), c["scheme"], c["sigma_a_ug"], c["estimator"])
        if len(cell):
            found.append((cell["replicate"].nunique(), label, cell))
    if not found:
        return None
    n, label, cell = max(found, key=lambda f: f[0])
    return cell, (f"{label}scheme {c['scheme']}, sigma_a {c['sigma_a_ug']:g} ug, estimator {c['estimator']}, "
                  f"{n} replicates")


def max_rel_err(results: Path, cfg: dict, group: str) -> Evidence | None:
    """Per replicate, the largest |relative error| (%, eq. 28) of the ``group`` coefficients (gyro
    or accel) in the paper's cell (docs/centrifuge-model.md §12)."""
    found = _paper_cell(results, cfg, "coef")
    if found is None:
        return None
    cell, settings = found
    g = cell[cell["group"] == group]
    per = g.assign(a=g["rel_err_pct"].abs()).groupby("replicate")["a"].max()
    return Evidence(per.to_numpy(float), settings)


def max_abs_err(results: Path, cfg: dict, terms: list, exclude: list = ()) -> Evidence | None:
    """Per replicate, the largest |estimate - truth| (the coefficient's unit: ug, ug/g, ug/g^2,
    ug/g^3) over the coefficients of ``terms`` (e.g. k0) but ``exclude`` (e.g. k1_z), in the
    paper's cell (docs/centrifuge-model.md §12: the paper's absolute accelerometer bounds)."""
    found = _paper_cell(results, cfg, "coef")
    if found is None:
        return None
    cell, settings = found
    term = cell["name"].str.rsplit("_", n=1).str[0]
    g = cell[term.isin(list(terms)) & ~cell["name"].isin(list(exclude))]
    per = g.assign(a=(g["estimate"] - g["truth"]).abs()).groupby("replicate")["a"].max()
    return Evidence(per.to_numpy(float), settings)


def _compare(results: Path, name: str) -> pd.DataFrame | None:
    path = Path(results) / "compare" / f"{name}.parquet"
    return pd.read_parquet(path) if path.exists() else None


def _estimator(cfg: dict, names, kind: str, passes: int | None = None) -> str | None:
    """The first compared estimator of ``kind`` (and ``passes``; a warm-up variant is not a plain
    pass), or None."""
    est = with_compare_estimators(cfg)["study"]["estimators"]
    for n in names:
        if kind_of(cfg, n) == kind and (passes is None or (passes_of(cfg, n) == passes
                                                            and not (est.get(n) or {}).get("warmup_s"))):
            return n
    return None


def ekf_nees(results: Path, cfg: dict, passes: int) -> Evidence | None:
    """Per replicate, the NEES of the 45 coefficient errors of the comparison's EKF with
    ``passes`` passes at the paper's noise level (docs/centrifuge-model.md §11, §14)."""
    runs = _compare(results, "runs")
    if runs is None:
        return None
    level = resolve_cell(cfg, "paper")["sigma_a_ug"]
    at = runs[np.isclose(runs["noise"], level)]
    name = _estimator(cfg, list(dict.fromkeys(at["estimator"])), "ekf", passes)
    if name is None:
        return Evidence(np.array([]), f"comparison at sigma_a {level:g} ug: no {passes}-pass EKF in study.compare")
    r = at[at["estimator"] == name]
    return Evidence(r["nees"].to_numpy(float), f"comparison, scheme {r['scheme'].iloc[0]}, sigma_a {level:g} ug, "
                                                f"estimator {name}, {len(r)} replicates")


def gain_over_ekf(results: Path, cfg: dict, kind: str) -> Evidence | None:
    """Per replicate (the same record for every estimator), the one-pass EKF's largest gyro
    |relative error| minus that of the estimator of ``kind`` (percentage points; > 0: ``kind`` is
    better), in the comparison at the paper's noise level (Su et al.; docs/centrifuge-model.md §14)."""
    coef = _compare(results, "coef")
    if coef is None:
        return None
    level = resolve_cell(cfg, "paper")["sigma_a_ug"]
    at = coef[np.isclose(coef["noise"], level) & (coef["group"] == "gyro")]
    names = list(dict.fromkeys(at["estimator"]))
    ekf, other = _estimator(cfg, names, "ekf", 1), _estimator(cfg, names, kind)
    if ekf is None or other is None:
        return Evidence(np.array([]), f"comparison at sigma_a {level:g} ug: no one-pass EKF and {kind} pair "
                                      "in study.compare")
    worst = at.assign(a=at["rel_err_pct"].abs()).groupby(["estimator", "replicate"])["a"].max()
    diff = (worst.loc[ekf] - worst.loc[other]).dropna()
    return Evidence(diff.to_numpy(float), f"comparison, sigma_a {level:g} ug, {ekf} - {other}, {len(diff)} replicates")


def _table1_covariance(cfg: dict, dwell_s: float | None = None):
    """Covariance-only evaluator of the config's ``table1`` scheme at ``dwell_s`` (default its own)."""
    study = study_from_config({k: v for k, v in cfg.items() if k != "study"})
    check_filter(study.filter)
    s = study.schemes.get("table1")
    if s is None:
        return None
    dwell = float(s.dwell_s if dwell_s is None else dwell_s)
    ev = SchemeEvaluator(study, dwell, estimate_doo=False)
    g = None if s.g_levels is None else np.asarray(s.g_levels)[None]
    n = study.noise
    settings = (f"covariance-only, scheme table1, {dwell:g} s per position, sigma_a {n.sigma_a_ug:g} ug, "
                f"ARW {n.arw_deg_rth:g} deg/sqrt(h), sigma_set {n.sigma_set_arcsec:g} arcsec")
    return ev, s.angles_deg[None], g, dwell, settings


def _not_at(cfg: dict, at: dict | None) -> Evidence | None:
    """Why a covariance-only claim stated at settings ``at`` (``dwell_s`` s of Table 1,
    ``sigma_a_ug`` ug, ``arw_deg_rth`` deg/sqrt(h), ``sigma_set_arcsec`` arcsec) was not run by a
    study at other settings (the numbers depend on them, §11); None when the study is at ``at``."""
    scheme = cfg.get("schemes", {}).get("table1") or {}
    own = {"dwell_s": float(scheme.get("dwell_s", 60)),
           **{k: float(cfg["noise"][k]) for k in ("sigma_a_ug", "arw_deg_rth", "sigma_set_arcsec")}}
    off = [k for k, v in (at or {}).items() if not np.isclose(own[k], float(v))]
    if not off:
        return None
    return Evidence(np.array([]), "not run: the study has " + ", ".join(f"{k} {own[k]:g}" for k in off)
                    + ", the claim holds at " + ", ".join(f"{k} {float(at[k]):g}" for k in off))


def table1_criterion(results: Path, cfg: dict, criterion: str = "J", at: dict | None = None) -> Evidence | None:
    """J (eq. 27, the sum of |correlation| over the 45 coefficient pairs) or another design
    criterion of Table 1's scheme, covariance-only at the study's settings (one value); not run
    when the study is not at the claim's settings ``at`` (:func:`_not_at`)."""
    found = _not_at(cfg, at) or _table1_covariance(cfg)
    if not isinstance(found, tuple):
        return found
    ev, ang, g, dwell, settings = found
    return Evidence(np.array([float(ev.evaluate(ang, g)[criterion][0])]), settings)


def table1_shrink(results: Path, cfg: dict, at: dict | None = None) -> Evidence | None:
    """The smallest P0 sigma / final sigma over the 45 coefficients of Table 1's scheme,
    covariance-only at the study's settings (docs/centrifuge-model.md §11: at least 280-fold at
    the defaults); not run when the study is not at the claim's settings ``at``."""
    found = _not_at(cfg, at) or _table1_covariance(cfg)
    if not isinstance(found, tuple):
        return found
    ev, ang, g, dwell, settings = found
    sig = np.sqrt(np.diag(ev.covariance(ang, g)[0]))
    return Evidence(np.array([float(np.min(ev.setup.p0 / sig))]), settings)


def ga_over_table1(results: Path, cfg: dict, design: str = "ga_J", criterion: str = "J") -> Evidence | None:
    """The GA scheme's criterion over Table 1's at the GA's dwell and settings (< 1: the GA beats
    Table 1; docs/centrifuge-model.md §11), from ``design/<design>.json``; not run when the
    study's sweep has no ``design`` scheme."""
    path = Path(results) / "design" / f"{design}.json"
    if not path.exists():
        return Evidence(np.array([]), f"{design} not designed in this study (study.schemes)")
    summ = json.loads(path.read_text())
    found = _table1_covariance(cfg, summ["settings"]["dwell_s"])
    if found is None:
        return None
    ev, ang, g, dwell, settings = found
    t1 = float(ev.evaluate(ang, g)[criterion][0])
    ga = float(summ["criteria"][criterion])
    return Evidence(np.array([ga / t1]), f"{design} {criterion} {ga:.4g} / table1 {t1:.4g}, {settings}")


MEASURES = {"max_rel_err": max_rel_err, "max_abs_err": max_abs_err, "ekf_nees": ekf_nees,
            "gain_over_ekf": gain_over_ekf, "table1_criterion": table1_criterion, "table1_shrink": table1_shrink,
            "ga_over_table1": ga_over_table1}


def claims():
    return load_claims("centrifuge", resources.files(__package__).joinpath("data/claims.yaml").read_text())
