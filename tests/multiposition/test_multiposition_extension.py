"""§13 (§15 item 6): higher-order terms at 1 g: ranks with and without DOO, sigma ranges."""

import numpy as np
import pandas as pd
import pytest

from platcal.rigs.multiposition import extension as ex
from platcal.rigs.multiposition.filter import covariance_only
from platcal.rigs.multiposition.model import coef_names, term_of


@pytest.fixture(scope="module")
def ranks(cfg):
    return pd.DataFrame(ex.rank_table(cfg))


@pytest.mark.slow
def test_ranks_with_and_without_doo(ranks):
    r = ranks.set_index(["set", "model"])
    assert r.loc[("random24", "without DOO"), "static_rank"] == 51
    assert r.loc[("S8", "without DOO"), "static_rank"] == 48
    for s in ("S8", "random24"):
        # DOO adds three columns and no rank: one null vector DII = DOO = DSS per gyro (CM eq. 22)
        assert r.loc[(s, "with DOO"), "static_rank"] == r.loc[(s, "without DOO"), "static_rank"]
        assert r.loc[(s, "with DOO"), "static_deficit"] - r.loc[(s, "without DOO"), "static_deficit"] == 3
    assert (ranks["static_rank"] == ranks["exact_rank"]).all()
    vecs = ranks.set_index(["set", "model"]).loc[("random24", "with DOO"), "static_null_vectors"]
    assert len(vecs) == 3
    for v in vecs:
        assert {k.split("_")[0] for k in v} == {"DF", "DII", "DSS", "DOO"}
        for a in "xyz":  # any basis of the span of the three per-gyro vectors DII = DOO = DSS
            assert v.get(f"DII_{a}", 0) == pytest.approx(v.get(f"DOO_{a}", 0), abs=1e-4)
            assert v.get(f"DSS_{a}", 0) == pytest.approx(v.get(f"DOO_{a}", 0), abs=1e-4)


SPEC = {"gyro": (10, 26), "k3": (11, 16), "k2": (1.1, 1.5), "kIP": (4.4, 4.9)}
"""§15: covariance-only sigma/|truth| (%) with 24 random positions x 60 s (one draw)."""


def _ranges(cfg, pos):
    P = covariance_only(cfg, pos, 60.0, ext=1)
    rel = np.sqrt(np.diag(P)) / np.abs(cfg.truth(1)) * 100
    terms = np.array([term_of(n) for n in coef_names(1)])
    gyro = np.isin(terms, ["DII", "DSS", "DIO", "DIS", "DOS"])
    out = {"gyro": rel[gyro]}
    for t in ("k3", "k2", "kIP"):
        out[t] = rel[terms == t]
    return {k: (v.min(), v.max()) for k, v in out.items()}


@pytest.mark.slow
def test_sigma_ranges_within_spread_of_random_draws(cfg):
    """The spec's ranges come from one unknown draw of 24 positions, and the ranges move a lot
    from draw to draw (gyro maximum 20-47 %). Claim checked: each spec endpoint lies inside the
    envelope of 8 seeded draws widened by 20 %; and the centrifuge gap holds for every draw
    (gyro g^2 terms >= 5 %, k3 >= 5 %)."""
    draws = [_ranges(cfg, ex.random_positions(24, s)) for s in range(8)]
    for k, (lo, hi) in SPEC.items():
        los = [d[k][0] for d in draws]
        his = [d[k][1] for d in draws]
        assert min(los) / 1.2 <= lo <= max(los) * 1.2, (k, lo, los)
        assert min(his) / 1.2 <= hi <= max(his) * 1.2, (k, hi, his)
    for d in draws:
        assert d["gyro"][0] >= 5 and d["k3"][0] >= 5


def test_spread_summary_counts_draws_within_20_percent():
    rows = []
    for d, scale in ((1, 1.0), (2, 1.1), (3, 1.5)):  # draws 1 and 2 within 20 % of every spec endpoint
        for g, (lo, hi) in ex.SPEC_RANGES.items():
            rows.append({"draw": d, "seed": 13 + d, "group": g, "min_pct": lo * scale, "max_pct": hi * scale})
    sm = ex.spread_summary(rows)
    assert sm["draws"] == 3 and sm["share_all_within_20pct"] == pytest.approx(2 / 3)
    assert sm["groups"]["kIP"]["min"]["median"] == pytest.approx(4.4 * 1.1)
    assert sm["groups"]["k3"]["max"]["within_20pct"] == pytest.approx(2 / 3)
    assert ex.spread_summary([])["draws"] == 0


def test_group_ranges_of_the_extended_layout():
    rel = np.arange(len(coef_names(1)), dtype=float)
    r = ex.group_ranges(rel)
    terms = [term_of(n) for n in coef_names(1)]
    assert r["k3"] == (terms.index("k3"), terms.index("k3") + 2)
    assert r["gyro g^2"] == (terms.index("DII"), terms.index("DOS") + 2)
