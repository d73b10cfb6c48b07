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


@pytest.fixture(scope="module")
def spread(cfg):
    """The study's further draws (extension.draws = 20, seeds 14-33), covariance-only."""
    return ex.draw_spread(cfg)


@pytest.mark.slow
def test_sigma_ranges_median_over_draws_within_20_percent(spread):
    """§15 item 6 read on the draw's distribution: the spec's ranges are one unstated draw of 24
    positions, and one draw's endpoints move by more than 20 % between draws (gyro maximum
    20-34 %), so the median over the 20 further draws of every endpoint is held to 20 % of the
    spec's. The centrifuge gap holds for every draw (gyro g^2 terms and k3 >= 5 %)."""
    sm = ex.spread_summary(spread)
    assert sm["draws"] == 20
    for g, (lo, hi) in ex.SPEC_RANGES.items():
        for end, spec in (("min", lo), ("max", hi)):
            med = sm["groups"][g][end]["median"]
            assert med == pytest.approx(spec, rel=0.2), (g, end, med, spec)
    assert sm["medians_within_20pct"]
    for r in spread:
        if r["group"] in ("gyro g^2", "k3"):
            assert r["min_pct"] >= 5, r


def test_ranges_of_one_draw_match_draw_spread(cfg, spread):
    """``draw_spread``'s first row is exactly the covariance-only analysis of seed 14's positions."""
    got = _ranges(cfg, ex.random_positions(24, 14))
    first = {r["group"]: (r["min_pct"], r["max_pct"]) for r in spread if r["draw"] == 1}
    assert first["kIP"] == pytest.approx(got["kIP"]) and first["k3"] == pytest.approx(got["k3"])
    assert first["gyro g^2"] == pytest.approx(got["gyro"])


def test_schemes_in_lanes_equal_each_scheme_alone(cfg):
    """``covariance_only`` of D schemes stacked (D, K, 3) runs them as lanes of one call
    (``draw_spread``'s draws): each scheme's P is bit for bit its own run's, whatever its lane
    and block (5 schemes: a full block of 4 and a block with one lane used)."""
    sets = np.stack([ex.random_positions(4, s) for s in range(5)])
    together = covariance_only(cfg, sets, 2.0, ext=1)
    assert together.shape == (5,) + covariance_only(cfg, sets[0], 2.0, ext=1).shape
    for d in range(5):
        assert np.array_equal(together[d], covariance_only(cfg, sets[d], 2.0, ext=1)), d
    assert not np.array_equal(together[0], together[1])
    with pytest.raises(ValueError, match="sequentially"):
        covariance_only(cfg, sets, 2.0, sequential=False)


def test_spread_summary_counts_draws_within_20_percent():
    rows = []
    for d, scale in ((1, 1.0), (2, 1.1), (3, 1.5)):  # draws 1 and 2 within 20 % of every spec endpoint
        for g, (lo, hi) in ex.SPEC_RANGES.items():
            rows.append({"draw": d, "seed": 13 + d, "group": g, "min_pct": lo * scale, "max_pct": hi * scale})
    sm = ex.spread_summary(rows)
    assert sm["draws"] == 3 and sm["share_all_within_20pct"] == pytest.approx(2 / 3)
    assert sm["groups"]["kIP"]["min"]["median"] == pytest.approx(4.4 * 1.1)
    assert sm["groups"]["k3"]["max"]["within_20pct"] == pytest.approx(2 / 3)
    assert sm["groups"]["kIP"]["max"]["median_dev"] == pytest.approx(0.1)
    # draw 3 is 50 % off but the medians (draw 2) are 10 % off: item 6 holds on the medians
    assert sm["medians_within_20pct"] and sm["largest_median_dev"][1] == pytest.approx(0.1)
    far = ex.spread_summary([dict(r, min_pct=r["min_pct"] * 1.3) for r in rows])
    assert not far["medians_within_20pct"] and far["largest_median_dev"][1] == pytest.approx(0.43)
    assert ex.spread_summary([])["draws"] == 0


def test_group_ranges_of_the_extended_layout():
    rel = np.arange(len(coef_names(1)), dtype=float)
    r = ex.group_ranges(rel)
    terms = [term_of(n) for n in coef_names(1)]
    assert r["k3"] == (terms.index("k3"), terms.index("k3") + 2)
    assert r["gyro g^2"] == (terms.index("DII"), terms.index("DOS") + 2)
