"""The proposed method's batch over the job's threads (issue 22 item 2): the window means and the
window filter of a batch of replicates run in contiguous replicate ranges, one per numba thread
(platcal.parallel.run_threaded); every replicate's numbers are those of one thread and of the
replicate alone, bit for bit (docs/lowprec-centrifuge.md §7)."""

import numpy as np
import pytest

from platcal.parallel import threads
from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.proposed import identify_proposed
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed

TINY = {"rig": "lowprec_centrifuge", "platforms": {"P1": {"kA_x": -40, "k2_x": -8, "kA_y": 25, "k2_y": -5}},
        "runs": {"P1": {"run1": [4, 6]}}, "profile": {"rest_first_s": 10, "rest_between_s": 20}}
FIELDS = ("x", "P", "n_windows", "mean_nis", "failed_updates", "innovations")


@pytest.fixture(scope="module")
def batch():
    st = load_config(TINY)
    return st, simulate_batch(st, "P1", "run1", [replicate_seed(0, "lp-threads", 10, r) for r in range(5)])


def ident(st, rb, sl, n_threads, common_force=False):
    f = rb.f_meas[0] if common_force else rb.f_meas[sl]
    with threads(n_threads):
        return identify_proposed(rb.prof.t, rb.v_ind[sl], rb.p_ind[sl], rb.psi[sl], f, rb.prof.schedule,
                                 st.centrifuge.arm_m, st.latitude_deg, keep_innovations=True)


def same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("common_force", [False, True])
def test_two_threads_give_one_threads_numbers(batch, common_force):
    st, rb = batch
    one, two = (ident(st, rb, slice(None), n, common_force) for n in (1, 2))
    assert one.x.shape[0] == 5
    for name in FIELDS:
        assert same(getattr(one, name), getattr(two, name)), name


@pytest.mark.parametrize("n_threads", [1, 2])
def test_each_replicate_alone_gives_its_batch_numbers(batch, n_threads):
    """Replicates 0, 3 and 4 of the batch (the first and the second thread's ranges at 2 threads)
    identified alone (a batch of one: no thread asked) and in a batch of two."""
    st, rb = batch
    whole = ident(st, rb, slice(None), n_threads)
    for sl in (slice(0, 1), slice(3, 5), slice(4, 5)):
        part = ident(st, rb, sl, n_threads)
        nw = part.innovations.shape[1]
        for name in FIELDS:
            want = getattr(whole, name)[sl]
            if name == "innovations":
                assert np.isnan(want[:, nw:]).all()   # the batch's padding windows
                want = want[:, :nw]
            assert same(getattr(part, name), np.ascontiguousarray(want)), (sl, name)
