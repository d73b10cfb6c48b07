"""The 1 g multi-position self-test's claims (the patent; docs/multiposition-1g.md §8, §13, §15) as
measures on the study's results; the claims are data (``data/claims.yaml``), evaluated by
:mod:`platcal.study.claims`.

The measures read, under ``results/multiposition`` (written before the report, which opens on
their ledger rows):

- ``observability/<scheme>/observability.json`` (ranks, covariance-only sigmas, accept/refuse);
- ``montecarlo/coef.parquet``, ``montecarlo/runs.parquet`` (the sweep; §15 item 4's cell);
- ``extension/ranks.json`` and ``extension/spread.csv`` (§13: ranks, the sigma ranges per draw).

The noise-free run of §15 item 5 is not a cell of the study: its measure runs it here (S8, the
spec's distinct gyro truths, one record, a fraction of a second).
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ...study.claims import Evidence, load_claims
from ...study.stats import select_cell
from . import filter as fl
from .config import load_config
from .extension import SPEC_RANGES
from .study import spec_cell


def _observability(results: Path, scheme: str) -> dict | None:
    path = Path(results) / "observability" / scheme / "observability.json"
    return json.loads(path.read_text()) if path.exists() else None


def scheme_check(results: Path, cfg: dict, scheme: str, quantity: str) -> Evidence | None:
    """One number of a scheme's check (§8, §15 items 2-3): ``static_rank``, ``exact_rank_nominal``,
    ``exact_rank_truth``, ``max_rel_sigma_pct`` (covariance-only, %) or ``accept`` (1 accepted,
    0 refused); not run when ``scheme`` is not in ``study.rank_schemes``."""
    o = _observability(results, scheme)
    if o is None:
        return Evidence(np.array([]), f"scheme {scheme} not checked in this study (study.rank_schemes)")
    s = o["settings"]
    v = float(o["verdict"]["accept"]) if quantity == "accept" else float(o[quantity])
    return Evidence(np.array([v]), f"scheme {scheme}, {len(o['positions'])} positions x {o['dwell_s']:g} s, sigma_a "
                                   f"{s['sigma_a_ug']:g} ug, ARW {s['arw_deg_rth']:g} deg/sqrt(h), threshold "
                                   f"{s['max_rel_sigma_pct']:g} %")


def _item4_cell(results: Path, cfg: dict, table: str):
    """Rows of ``montecarlo/<table>.parquet`` in §15 item 4's cell (:func:`.study.spec_cell`) and
    its settings text; None when the study wrote no such table."""
    scheme, level, est = spec_cell(load_config(cfg))
    path = Path(results) / "montecarlo" / f"{table}.parquet"
    if not path.exists():
        return None
    if est is None:
        return pd.DataFrame(), f"scheme {scheme}, sigma_a {level:g} ug: no one-pass EKF in study.estimators"
    cell = select_cell(pd.read_parquet(path), scheme, level, est)
    settings = f"scheme {scheme}, sigma_a {level:g} ug, estimator {est}"
    if cell.empty:
        return cell, settings + ": not in this study's sweep (study.schemes, study.sigma_a_ug)"
    return cell, f"{settings}, {cell['replicate'].nunique()} seeds"


def max_rel_err(results: Path, cfg: dict, group: str) -> Evidence | None:
    """Per seed, the largest |relative error| (%) of the ``group`` (gyro, accel) in §15 item 4's
    cell: S8 at 5 ug, the study's one-pass EKF."""
    found = _item4_cell(results, cfg, "coef")
    if found is None:
        return None
    cell, settings = found
    if cell.empty:  # the study did not run the cell: no samples, the settings say why
        return Evidence(np.array([]), settings)
    g = cell[cell["group"] == group]
    return Evidence(g.assign(a=g["rel_err_pct"].abs()).groupby("replicate")["a"].max().to_numpy(float), settings)


def nees(results: Path, cfg: dict) -> Evidence | None:
    """Per seed, the NEES of the 24 coefficients in §15 item 4's cell."""
    found = _item4_cell(results, cfg, "runs")
    if found is None:
        return None
    cell, settings = found
    return Evidence(cell["nees"].to_numpy(float) if "nees" in cell else np.array([]), settings)


def noise_free_error(results: Path, cfg: dict, passes: int, truth: dict) -> Evidence | None:
    """The largest |relative error| (%) over the 24 coefficients of a noise-free S8 record with
    the gyro truths ``truth`` (deg/h per g^2, §15 item 5), identified by the EKF in ``passes`` passes."""
    c = load_config(cfg).with_noise(truth_overrides=dict(truth))
    s8 = c.scheme("S8")
    t, _, z = fl.simulate(c, s8, [0], noise_free=True)
    # the lanes kernel the study's cells compiled: the one-replicate kernel would be compiled in
    # this job alone (about 25 s), for the same numbers bit for bit
    est = fl.run_ekf(c, s8.angles_deg, t, z, passes=int(passes), lanes=True)[0][0]
    tr = c.truth()
    rel = np.abs(est - tr) / np.abs(tr) * 100.0
    return Evidence(np.array([float(rel.max())]), f"noise-free, scheme S8 ({s8.dwell_s:g} s per position), distinct "
                                                    f"gyro truths, {int(passes)} pass(es)")


def _ext_ranks(results: Path) -> list | None:
    path = Path(results) / "extension" / "ranks.json"
    return json.loads(path.read_text()) if path.exists() else None


def extension_rank(results: Path, cfg: dict, set_: str, model: str, quantity: str) -> Evidence | None:
    """A §13 rank (order 1, x = 0) of a position set (``S8`` or ``random``: the random set) and
    model (``without DOO`` / ``with DOO``): ``static_rank``, ``exact_rank``, ``static_deficit``..."""
    ranks = _ext_ranks(results)
    if ranks is None:
        return None
    rows = [r for r in ranks if r["model"] == model
            and (r["set"] == set_ or (set_ == "random" and r["set"].startswith("random")))]
    if not rows:
        return Evidence(np.array([]), f"§13 set {set_}, model {model}: not in this study")
    r = rows[0]
    return Evidence(np.array([float(r[quantity])]), f"§13 model {model}, set {r['set']} ({r['positions']} positions)")


def extension_deficit_all(results: Path, cfg: dict, deficit: int) -> Evidence | None:
    """One sample per §13 position set: 1 when adding DOO raises its static and its exact rank
    deficit by exactly ``deficit`` (the null vector DII = DOO = DSS per gyro, CM eq. 22: DOO adds
    three columns and no rank), else 0. S8's own deficit of 3 without DOO is not DOO's."""
    ranks = _ext_ranks(results)
    if ranks is None:
        return None
    base = {r["set"]: r for r in ranks if r["model"] == "without DOO"}
    doo = [r for r in ranks if r["model"] == "with DOO" and r["set"] in base]
    ok = [float(all(r[k] - base[r["set"]][k] == deficit for k in ("static_deficit", "exact_deficit"))) for r in doo]
    return Evidence(np.array(ok), f"§13 with DOO against without, sets {', '.join(r['set'] for r in doo)}")


def _spread(results: Path) -> pd.DataFrame | None:
    path = Path(results) / "extension" / "spread.csv"
    return pd.read_csv(path) if path.exists() else None


def _draws_settings(df: pd.DataFrame, cfg: dict) -> str:
    e = cfg["extension"]
    if df.empty:
        return "no §13 random draws in this study (extension.draws)"
    return (f"covariance-only, {df['draw'].nunique()} draws of {e['random_positions']} positions x "
            f"{e['dwell_s']:g} s (seeds {df['seed'].min()}-{df['seed'].max()})")


def sigma_endpoint(results: Path, cfg: dict, group: str, end: str) -> Evidence | None:
    """Per draw of the §13 random positions, one endpoint (``min`` or ``max``) of the group's
    covariance-only sigma/|truth| range (%), from ``extension/spread.csv``."""
    df = _spread(results)
    if df is None:
        return None
    d = df[df["group"] == group]
    return Evidence(d[f"{end}_pct"].to_numpy(float), _draws_settings(df, cfg))


def draws_within(results: Path, cfg: dict, tolerance: float) -> Evidence | None:
    """Per draw, 1 when all eight endpoints of §13's sigma ranges lie within ``tolerance``
    (relative, 0.2 = 20 %) of the spec's (:data:`.extension.SPEC_RANGES`), else 0."""
    df = _spread(results)
    if df is None:
        return None
    lo = df["group"].map({g: r[0] for g, r in SPEC_RANGES.items()})
    hi = df["group"].map({g: r[1] for g, r in SPEC_RANGES.items()})
    ok = ((df["min_pct"] / lo - 1).abs() <= tolerance) & ((df["max_pct"] / hi - 1).abs() <= tolerance)
    per_draw = ok.groupby(df["draw"]).all().astype(float)
    return Evidence(per_draw.to_numpy(), _draws_settings(df, cfg))


MEASURES = {f.__name__: f for f in (scheme_check, max_rel_err, nees, noise_free_error, extension_rank,
                                    extension_deficit_all, sigma_endpoint, draws_within)}


def claims():
    return load_claims("multiposition", resources.files(__package__).joinpath("data/claims.yaml").read_text())
