"""The blocked loops of platcal.estimation.kalman (issue 22: several terms or rows per pass) give
exactly the numbers of the term-by-term loops they replace: every entry the same operations in
the same order, for any count of terms (the remainders included)."""

import numpy as np
import pytest

from platcal.estimation.kalman import add_row_combinations, innovation_covariance, mirror_lower


@pytest.mark.parametrize("n", list(range(0, 14)) + [48, 51])
def test_mirror_lower_copies_the_lower_triangle(n):
    A = np.tril(np.random.default_rng(n).standard_normal((n, n)))
    P = A.copy()
    mirror_lower(P)
    assert np.array_equal(P, A + np.tril(A, -1).T)


def _symmetric(n, seed):
    a = np.random.default_rng(seed).standard_normal((n, n))
    return a @ a.T


@pytest.mark.parametrize("nnz", [(0, 1, 2), (3, 4, 5), (8, 9, 10), (7, 0, 6)])
def test_innovation_covariance_sums_terms_in_order(nnz):
    n = 13
    rng = np.random.default_rng(sum(nnz))
    P = _symmetric(n, 1)
    hnnz = np.array(nnz, dtype=np.int64)
    width = max(max(nnz), 1)
    hcols = np.stack([rng.permutation(n)[:width] for _ in range(3)]).astype(np.int64)
    hval = rng.standard_normal((3, width))
    r_var = np.array([1e-3, 2e-3, 3e-3])
    U = np.full((3, n), np.nan)
    S = np.empty((3, 3))
    innovation_covariance(P, hcols, hnnz, hval, r_var, U, S)
    ref = np.zeros((3, n))
    for r in range(3):
        for t in range(nnz[r]):  # the reference: one term at a time, in t order
            ref[r] = ref[r] + hval[r, t] * P[hcols[r, t]]
    assert np.array_equal(U, ref)
    assert np.array_equal(S, S.T)


@pytest.mark.parametrize("count", [0, 1, 2, 5, 30])
def test_row_combinations_add_rows_in_order(count):
    n = 17
    rng = np.random.default_rng(count)
    P = _symmetric(n, 2)
    rows = rng.integers(0, n, max(count, 1)).astype(np.int64)
    coef = rng.standard_normal((3, max(count, 1)))
    start = rng.standard_normal((3, n))
    out = start.copy()
    add_row_combinations(coef, P, rows, count, out)
    ref = start.copy()
    for k in range(count):
        ref = ref + coef[:, k : k + 1] * P[rows[k]][None, :]
    assert np.array_equal(out, ref)
