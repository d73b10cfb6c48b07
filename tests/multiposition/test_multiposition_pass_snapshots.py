"""The multi-position filter hands the estimates of its first passes on the way
(``run_filter(..., on_pass=...)``, issue 22 item 4): what it hands after pass p equals, array by
array and bit for bit, a run of p passes, for the EKF and the iterated EKF, one replicate or a
batch, innovations kept or not; and the snapshots are copies the later passes do not touch."""

import numpy as np
import pytest

from platcal.rigs.multiposition import filter as fl
from platcal.rigs.multiposition.estimators import FilterChoice, estimate


@pytest.fixture(scope="module")
def records(cfg):
    s = cfg.scheme("TET4")
    t, _, z = fl.simulate(cfg, s, [1, 2, 3])
    return s, t[:401], z[:, :, :401]


@pytest.mark.parametrize("iterations", [0, 2])
@pytest.mark.parametrize("replicates", [1, 3])
@pytest.mark.parametrize("keep", [False, True])
def test_each_pass_on_the_way_is_the_run_of_that_many_passes(cfg, records, iterations, replicates, keep):
    s, t, z = records
    z = z[:replicates]

    def run(passes, **kw):
        inn = np.full(z.shape[:3] + (12,), np.nan) if keep else None
        out = fl.run_filter(cfg, s.angles_deg, t, z, passes=passes, iterations=iterations, tolerance=0.01,
                            innovations=inn, **kw)
        return out, inn

    seen = {}
    whole, whole_inn = run(3, on_pass=lambda p, result, inn: seen.setdefault(p, (result, inn)))
    assert sorted(seen) == [1, 2]
    for p, (result, inn) in [*seen.items(), (3, (whole, whole_inn))]:
        alone, alone_inn = run(p)
        assert len(result) == len(alone) == 5
        for a, b in zip(result, alone):
            assert a.dtype == b.dtype and np.array_equal(a, b), p
        assert (inn is None) == (not keep)
        if keep:
            assert np.array_equal(inn, alone_inn, equal_nan=True), p
    assert not np.array_equal(seen[1][0][0], whole[0])   # copies: later passes did not write into them


def test_the_estimators_hand_estimates_of_fewer_passes(cfg, records):
    s, t, z = records
    seen = {}
    est = estimate(cfg, FilterChoice("iekf", 2, {}), s.angles_deg, t, z, on_pass=lambda p, e: seen.setdefault(p, e))
    one = estimate(cfg, FilterChoice("iekf", 1, {}), s.angles_deg, t, z)
    assert list(seen) == [1] and est is not seen[1]
    for name in ("coef", "cov", "mean_nis", "linearisations", "failed_updates"):
        assert np.array_equal(getattr(seen[1], name), getattr(one, name)), name
