"""A record without fE, fN: the identification differentiates the INS velocity (record.py,
docs/lowprec-centrifuge.md §12 "Record"). Is the fallback as good as the recorded specific force?
(issue 20 item 4)."""

import numpy as np
import pytest

from platcal.rigs.lowprec_centrifuge.config import load_config
from platcal.rigs.lowprec_centrifuge.proposed import identify_proposed
from platcal.rigs.lowprec_centrifuge.truth import simulate_batch
from platcal.study.montecarlo import replicate_seed


def fallback_shift(platform: str, replicates: int) -> np.ndarray:
    """(replicates, 4) the coefficients from the differentiated velocity minus those from the
    recorded specific force, in units of the filter's sigma."""
    st = load_config({"rig": "lowprec_centrifuge"})
    rb = simulate_batch(st, platform, "run1", [replicate_seed(0, "fallback", 10, r) for r in range(replicates)])
    args = (rb.prof.schedule, st.centrifuge.arm_m, st.latitude_deg)
    with_f = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, rb.f_meas, *args)
    f_diff = np.gradient(rb.v_ind, rb.prof.t, axis=1)   # what read_record does without fE, fN
    without = identify_proposed(rb.prof.t, rb.v_ind, rb.p_ind, rb.psi, f_diff, *args)
    return (without.coeffs - with_f.coeffs) / with_f.sigmas


@pytest.mark.xfail(strict=True, reason=(
    "measured (12 replicates): P2 run1 k2_x shifted +5.7 sigma (+0.10 ug/g^2), k2_y +2.3, kA_x -1.6; "
    "P1 run1 k2_x -1.4 sigma; the size fits the central difference's attenuation of the spinning "
    "velocity at 100 Hz, (w dt)^2/6 = 0.2 % at 40 g on the 3 m arm, 0.4 % on f^2; not fixed yet"))
def test_fallback_without_specific_force_agrees_within_one_sigma():
    shift = fallback_shift("P2", 4)
    mean = shift.mean(axis=0)
    assert np.all(np.abs(mean) < 1.0), f"kA_x, k2_x, kA_y, k2_y shifted by {np.round(mean, 2)} sigma"
