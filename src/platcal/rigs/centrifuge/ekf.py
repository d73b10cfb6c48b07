"""The identifying EKF of the centrifuge test (docs/centrifuge-model.md §9; paper eqs. 23-25), batched.

State (n = 48 by default), in Table 2's order and engineering units::

    DF(x,y,z) DI DO DS DII DSS DIO DIS DOS  k0 k1 k2 k3 kIP  theta_py theta_pz theta_oz
    alpha beta gamma (rad)

With ``estimate_doo`` the three DOO terms join after theta_oz (n = 51): the two-g-level
extension of docs/centrifuge-model.md §4. Every array carries a leading batch axis B (replicates, or
candidate schemes for the covariance-only run); a batch of one is one run. Replicates are
independent, so a batch gives bit-identical numbers to B runs of one.

Speed (issue 5): each step costs O(n^2), not O(n^3). The coefficients are constant, so only the
3 attitude rows of the transition matrix differ from the identity, and they are nonzero only in
the gyro-coefficient and angle columns; each accelerometer row of H has 8-10 nonzeros. The
propagation touches 3 rows and columns of P (:func:`platcal.estimation.kalman.propagate_sparse`); the
update is the Joseph form as a rank-6 correction of the lower triangle, mirrored
(:func:`platcal.estimation.kalman.joseph_update_sparse`). Replicates run in parallel numba threads
(:mod:`platcal.parallel`); the history is decimated (``history_every_s``), so the memory is
O(B n^2) plus O(B n) per kept instant, whatever the dwell.

Timing convention (docs/centrifuge-model.md §9, "the filter propagates over 20 ms and updates
with the sample taken at the update instant"; issue 9 item 1): at time 0 of each position the
attitude is reset to the commanded angles with variance sigma_set^2 and no cross-covariance with
the coefficients (which carry over); the filter then propagates from 0 to the first instant
``t[k][0]``, updates there, propagates to ``t[k][1]``, and so on. The default instants are
``period, 2 period, ... < dwell`` (:func:`filter_times`): the sample at the reset instant is not
used. ``FilterSettings.update_at_reset`` (config ``filter.update_at_reset``) restores the earlier
behaviour, an update with the sample at t = 0 before any propagation (instants ``0, period, ...
< dwell``); the kernel handles both, since it propagates only when an instant lies after the
previous one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ...aot import pick as aot_pick
from ...estimation.kalman import (cholesky_inverse, innovation_covariance, joseph_update_sparse, propagate_sparse,
                                 update_scratch)
from .attitude import GYRO_COLS, MEAS_COLS, P_G, make_step_scratch, measure_jac_sc, rk4_jac_sc
from ...jit import njit, parallel_chunksize, prange
from ...model.frames import ARCSEC, DEG
from ...model.instruments import FULL_NAMES, I_DOO, N_FULL, N_IDENTIFIED, term_of
from .aot_kernels import KERNELS
from .base import broadcast_params, specific_force_into

ANGLE_NAMES = ("alpha", "beta", "gamma")

# P0 defaults (1 sigma), docs/centrifuge-model.md §11, by error term.
P0_DEFAULTS = {
    "DF": 10.0, "DI": 2.0, "DO": 2.0, "DS": 2.0,
    "DII": 0.2, "DSS": 0.2, "DIO": 0.2, "DIS": 0.2, "DOS": 0.2, "DOO": 0.2,
    "k0": 1e4, "k1": 2e3, "k2": 50.0, "k3": 10.0, "kIP": 20.0, "theta": 600.0,
}


@dataclass(frozen=True)
class FilterSettings:
    """Settings of the identifying EKF (docs/centrifuge-model.md §9 and §11).

    Attributes
    ----------
    period_s : filter period, s (20 ms in the paper); a multiple of the sample period.
    passes : 1 = the paper's EKF; each further pass restarts from the previous estimate with
        ``P0 = 100 x`` its coefficient covariance.
    sigma_a_ug : accelerometer noise assumed by the filter, ug per sample (R).
    arw_deg_rth : gyro angle random walk assumed by the filter, deg/sqrt(h) (Q).
    sigma_set_arcsec : attitude variance at each position reset, arcsec (1 sigma).
    p0_sigma : (n_coef,) initial 1-sigma of the coefficient states, engineering units.
    estimate_doo : identify DOO_x/y/z too (51 states).
    history_every_s : decimation of the returned history, s (None: no history).
    update_at_reset : also update with the sample at each position's reset instant t = 0
        (before any propagation); False (the spec) drops that sample (:func:`filter_times`).
    estimator : the estimator kind that runs (:mod:`platcal.rigs.centrifuge.estimators`:
        ``ekf``, ``iekf``, ...); the covariance-only runs are always the EKF's.
    estimator_options : ``(keyword, value)`` pairs passed to that kind's run function.
    innovations : keep the last pass's innovations and their predicted variances
        (``Estimate.innovations``; the fit check, issue 25); the EKF and IEKF only.
    prior_x, prior_P : the start of the coefficient states, (n_coef,) or (B, n_coef) estimate and
        (n_coef, n_coef) or (B, n_coef, n_coef) covariance (engineering units): a previous test's
        posterior handed on (``platcal plan``'s Monte Carlo). None: 0 and ``diag(p0_sigma^2)`` (§9).
    lanes : :func:`run_ekf`'s passes (the EKF, the IEKF, the ML's EKF start and the
        covariance-only runs) on the state-major kernel (:func:`run_ekf` ``lanes``): the same
        numbers bit for bit, so it chooses a cost, not a result. None (the default): the
        state-major kernel for a batch of at least :data:`LANES_FROM_BATCH` replicates
        (:func:`takes_lanes`).
    """

    period_s: float = 0.02
    passes: int = 1
    sigma_a_ug: float = 10.0
    arw_deg_rth: float = 0.001
    sigma_set_arcsec: float = 10.0
    p0_sigma: np.ndarray = field(default_factory=lambda: default_p0_sigma(False))
    estimate_doo: bool = False
    history_every_s: float | None = 1.0
    update_at_reset: bool = False
    estimator: str = "ekf"
    estimator_options: tuple = ()
    innovations: bool = False
    prior_x: np.ndarray | None = None
    prior_P: np.ndarray | None = None
    lanes: bool | None = None

    @property
    def coef_index(self) -> np.ndarray:
        """Indices into the full 48-vector of the estimated coefficients, in state order."""
        return estimated_index(self.estimate_doo)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(FULL_NAMES[i] for i in self.coef_index) + ANGLE_NAMES


def filter_times(dwell_s: float, period_s: float, update_at_reset: bool = False) -> np.ndarray:
    """The filter instants of one position, s since its start (the module's timing convention):
    ``period, 2 period, ... < dwell`` (the spec), or ``0, period, ... < dwell`` with
    ``update_at_reset``. ``dwell_s`` is a whole number of periods."""
    n = int(round(dwell_s / period_s))
    return np.arange(0 if update_at_reset else 1, n) * period_s


def first_instant(update_at_reset: bool) -> int:
    """Index of the first filter instant in the grid ``0, period, ... < dwell``: 1 (the spec:
    the sample at the reset instant is dropped) or 0 (``update_at_reset``)."""
    return 0 if update_at_reset else 1


def estimated_index(estimate_doo: bool) -> np.ndarray:
    """Full-vector indices of the coefficient states (45, or 48 with DOO)."""
    n = N_FULL if estimate_doo else N_IDENTIFIED
    return np.arange(n, dtype=np.int64)


def default_p0_sigma(estimate_doo: bool, overrides: dict[str, float] | None = None) -> np.ndarray:
    """P0 (1 sigma) per coefficient state from the per-term defaults and ``overrides``.

    ``overrides`` maps an error term (``'DF'``, ``'k0'``, ``'theta'`` ...) or a coefficient name
    (``'DF_x'``) to a sigma in the coefficient's unit; names win over terms.
    """
    overrides = overrides or {}
    out = []
    for i in estimated_index(estimate_doo):
        name = FULL_NAMES[i]
        term = term_of(name)
        out.append(float(overrides.get(name, overrides.get(term, P0_DEFAULTS[term]))))
    return np.array(out)


@dataclass
class Estimate:
    """Result of the EKF for a batch of B runs.

    Attributes
    ----------
    names : state names (coefficients, then alpha, beta, gamma).
    x : (B, n) final state: coefficients in engineering units, angles in rad.
    P : (B, n, n) final covariance in the same units.
    history_t : (H,) time of each history sample, s from the start of the first pass.
    history_x, history_sigma : (B, H, n) estimate and 1-sigma at those times.
    pass_x, pass_P : per-pass final coefficient estimate (passes, B, n_coef) and covariance.
    mean_nis : (B,) mean normalised innovation squared of the last pass (3 expected).
    failed_updates : (B,) updates skipped because S was not positive definite.
    innovations : (B, M, 6) when ``FilterSettings.innovations``: at each of the M instants of the
        last pass (positions end to end), the innovation ``z - h(x_pred)`` of Ax, Ay, Az (g) and
        the diagonal of its predicted covariance S (g^2; NaN where the update was skipped).
    """

    names: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray
    history_t: np.ndarray
    history_x: np.ndarray
    history_sigma: np.ndarray
    pass_x: np.ndarray
    pass_P: np.ndarray
    mean_nis: np.ndarray
    failed_updates: np.ndarray
    innovations: np.ndarray | None = None

    @property
    def n_coef(self) -> int:
        return len(self.names) - 3

    @property
    def coef(self) -> np.ndarray:
        """(B, n_coef) coefficient estimates."""
        return self.x[:, : self.n_coef]

    @property
    def coef_sigma(self) -> np.ndarray:
        """(B, n_coef) 1-sigma of the coefficient estimates."""
        d = np.diagonal(self.P, axis1=1, axis2=2)[:, : self.n_coef]
        return np.sqrt(d)


@njit(parallel=True, cache=True)
def _run_pass(x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var, q_rate,
              update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec, seg):
    """Filter every replicate of the batch through every position of one pass.

    Position k's instants are ``t[offs[k]:offs[k + 1]]`` (s since the position's start) with
    outputs ``z[:, offs[k]:offs[k + 1]]`` (B, M, 3) g (``z`` is (B, 0, 3) for a covariance-only
    run); ``cmd`` (B, K, 3) rad; ``params`` (B, K, 5) packed centrifuge parameters;
    ``hist_idx`` the history slot of each instant (-1: none). ``q_rate`` is the attitude
    process-noise density, rad^2/s per axis.

    Sparsity (from :func:`_structure`): the attitude rows of Phi are nonzero only at the states
    ``pcols`` (gyro coefficients, then the angles); for a coefficient column ``pg`` gives its
    column of the RK4 map's compact gyro Jacobian. Row r of H is nonzero only at the states
    ``hcols[r, :hnnz[r]]``; ``hsrc`` says where each value comes from (a column of
    ``MEAS_COLS[r]``, or ``-1 - i`` for angle i). ``rec`` (B, M, 6) receives each instant's
    innovation and the diagonal of S ((B, 0, 6): not kept).

    ``seg`` (:func:`segments`) cuts the instants into segments: segment s runs the instants
    ``offs[s]:offs[s + 1]`` of position ``seg.k[s]``; it starts with the position's reset when
    ``seg.t0[s]`` is NaN, else it continues the position from its instant ``seg.t0[s]`` (a chunk
    of a streamed record, :func:`run_ekf` ``z_source``); ``seg.nis`` (B,) carries a position's
    NIS sum from segment to segment, added to ``nis_sum`` when ``seg.last[s]``.

    Each replicate runs the same sequential kernel (:func:`_filter_one`) in its own iteration, so
    the numbers do not depend on the batch size or on the number of threads. One parallel region
    per pass (not per position) keeps thread start-up and joins rare.
    """
    B = x.shape[0]
    for b in prange(B):
        _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                          q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg,
                          hcols, hsrc, hnnz, it_ctl, rec, seg)


@njit(cache=True)
def _run_pass_serial(x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                     q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols,
                     hsrc, hnnz, it_ctl, rec, seg):
    """:func:`_run_pass` without threads, for a batch of one or a single thread: the same
    per-replicate kernel, minus the parallel region's start-up and join (milliseconds on a
    busy machine)."""
    for b in range(x.shape[0]):
        _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                          q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg,
                          hcols, hsrc, hnnz, it_ctl, rec, seg)


# inlined into the two pass kernels (a few lines of numba IR): otherwise a third compiled
# function whose own LLVM module links, optimises and emits _filter_one's whole code once more
@njit(cache=True, inline="always")
def _filter_replicate(b, x, P, z, t, offs, cmd, reset_var, est_idx, coef_fixed, params, r_var,
                      q_rate, update_x, hist_idx, hist_x, hist_s, nis_sum, n_bad, pcols, pg, hcols,
                      hsrc, hnnz, it_ctl, rec, seg):
    """Replicate b through every segment of one pass (see :func:`_run_pass`)."""
    seg_k, seg_t0, seg_last, seg_nis = seg
    for s in range(offs.shape[0] - 1):
        o0, o1 = offs[s], offs[s + 1]
        k = seg_k[s]
        zb = z[b, o0:o1] if update_x else z[b]
        rb = rec[b, o0:o1] if rec.shape[1] > 0 else rec[b]
        reset = np.isnan(seg_t0[s])
        stats = _filter_one(x[b], P[b], zb, t[o0:o1], cmd[b, k], reset_var, est_idx,
                            coef_fixed[b], params[b, k], r_var, q_rate, update_x,
                            hist_idx[o0:o1], hist_x[b], hist_s[b], pcols, pg, hcols, hsrc, hnnz, it_ctl, rb,
                            reset, 0.0 if reset else seg_t0[s], 0.0 if reset else seg_nis[b])
        if seg_last[s]:
            nis_sum[b] += stats[0]
        else:
            seg_nis[b] = stats[0]
        n_bad[b] += int(stats[1])


@njit(cache=True, inline="always")
def attitude_reset(xb, Pb, cmd, reset_var):
    """A position's start (docs/centrifuge-model.md §9): the attitude states (the last 3) set to
    the commanded angles ``cmd`` (rad) with variance ``reset_var`` (rad^2) and no
    cross-covariance. Shared by the EKF, the IEKF and the UKF."""
    n = xb.shape[0]
    nc = n - 3
    for r in range(3):
        xb[nc + r] = cmd[r]
        for i in range(n):
            Pb[nc + r, i] = 0.0
            Pb[i, nc + r] = 0.0
        Pb[nc + r, nc + r] = reset_var


@njit(cache=True, inline="always")
def propagate_attitude(Pb, ang, coef, fr3, dt, pb, q_rate, dyn, pcols, pg, ang_new, pa, pgyro, phi, q, Wd,
                       blk, scratch):
    """The EKF's propagation over ``dt`` s (docs/centrifuge-model.md §9): the attitude (rad) through
    RK4, P through the RK4 map's exact Jacobian (rows of the 3 attitude states), plus the angle
    random walk ``q_rate * dt``. Shared by the EKF, the IEKF and the UKF's linear step."""
    npc = pcols.shape[0]
    rk4_jac_sc(ang, coef, fr3, dt, pb, ang_new, pa, pgyro, scratch)
    for r in range(3):
        for k in range(npc - 3):
            phi[r, k] = pgyro[r, pg[k]]
        for i in range(3):
            phi[r, npc - 3 + i] = pa[r, i]
        q[r, r] = q_rate * dt
    for r in range(3):
        ang[r] = ang_new[r]
    propagate_sparse(Pb, dyn, pcols, phi, q, Wd, blk)


@njit(cache=True, inline="always")
def store_history(hi, xb, Pb, hist_x, hist_s):
    """Row ``hi`` of the estimate history (skipped when ``hi < 0``): the state and its 1-sigma
    (-1 where the variance is not positive)."""
    if hi >= 0:
        for i in range(xb.shape[0]):
            hist_x[hi, i] = xb[i]
            hist_s[hi, i] = np.sqrt(Pb[i, i]) if Pb[i, i] > 0.0 else -1.0


@njit(cache=True)
def _filter_one(xb, Pb, zb, t, cmd, reset_var, est_idx, coef_fixed, pb, r_var, q_rate,
                update_x, hist_idx, hist_x, hist_s, pcols, pg, hcols, hsrc, hnnz, it_ctl, rec,
                reset=True, t_start=0.0, nis_start=0.0):
    """One replicate through one position (or a segment of it); returns (sum of NIS, number of
    skipped updates).

    ``reset``: the position starts here (attitude reset, t = 0); False continues it from the
    instant ``t_start`` (s since its start) where the previous segment ended, with the NIS sum
    ``nis_start`` so far: the same operations in the same order as one call over the position.

    ``rec`` (M, 6): each instant's innovation and diagonal of S, when it has M rows (else unused).

    ``it_ctl`` (4 + n_coef,) controls the iterated update (:func:`iteration_control`): max
    linearisations per update (1 = the EKF), tolerance (largest state change, in sigmas),
    iterate while t < this (s since the position's start), iterate while the mean over the
    coefficients of P_ii / P0_ii > this, then the coefficients' P0 variances.
    """
    n = xb.shape[0]
    nc = n - 3
    M = t.shape[0]
    npc = pcols.shape[0]
    mh = hcols.shape[1]
    dyn = np.arange(nc, n)
    scratch, ang_new, pa, pgyro = make_step_scratch()
    hm = np.zeros((3, MEAS_COLS.shape[1]))
    g = pb[P_G]
    coef = coef_fixed.copy()
    phi = np.empty((3, npc))
    q = np.zeros((3, 3))
    blk = np.empty((3, 3))
    Wd = np.empty((3, n))
    U, K, D, S, Sinv, nu = update_scratch(3, n)
    out = np.empty(3)
    ha = np.empty((3, 3))
    hval = np.zeros((3, mh))
    innov = np.zeros(3)
    fr3 = np.empty((3, 3))
    fr_now = np.empty(3)
    fr_mid = np.empty(3)
    ang = xb[nc:]
    nis = nis_start
    bad = 0
    it_max = int(it_ctl[0])
    it_tol = it_ctl[1]
    it_until = it_ctl[2]
    it_ratio = it_ctl[3]
    xi = np.empty(n)
    xnew = np.empty(n)
    coef_i = coef_fixed.copy()
    w3 = np.empty(3)
    if reset:
        attitude_reset(xb, Pb, cmd, reset_var)
    # the position starts at the reset (t = 0): the first instant is reached by propagation,
    # unless it is the reset instant itself (filter.update_at_reset)
    t_prev = t_start
    specific_force_into(t_prev, pb, fr_now)
    for m in range(M):
        for k in range(nc):
            coef[est_idx[k]] = xb[k]
        if t[m] > t_prev:
            h = t[m] - t_prev
            # the end-of-step force is the one measured at t[m]: computed once, used twice
            for r in range(3):
                fr3[0, r] = fr_now[r]
            # the mid-step force through a scratch vector, not a row view of fr3 (a view per
            # step costs two atomic reference-count updates, issue 22)
            specific_force_into(t_prev + 0.5 * h, pb, fr_mid)
            specific_force_into(t[m], pb, fr_now)
            for r in range(3):
                fr3[1, r] = fr_mid[r]
                fr3[2, r] = fr_now[r]
            propagate_attitude(Pb, ang, coef, fr3, h, pb, q_rate, dyn, pcols, pg, ang_new, pa, pgyro, phi, q, Wd,
                               blk, scratch)
            t_prev = t[m]
        measure_jac_sc(ang, coef, fr_now[0], fr_now[1], fr_now[2], g, out, hm, ha)
        for r in range(3):
            for k in range(hnnz[r]):
                src = hsrc[r, k]
                hval[r, k] = hm[r, src] if src >= 0 else ha[r, -1 - src]
            if update_x:
                innov[r] = zb[m, r] - out[r]
        if it_max > 1 and update_x and t[m] < it_until and _coef_ratio(Pb, it_ctl, nc) > it_ratio:
            # iterated EKF, Gauss-Newton form: relinearise h about x_i, then the final update
            # below uses the last linearisation; xb still holds x_pred
            for i in range(n):
                xi[i] = xb[i]
            for it in range(it_max - 1):
                if not _gain_step(Pb, hcols, hnnz, hval, innov, r_var, U, S, Sinv, nu, w3, xb, xnew):
                    break
                dmax = 0.0
                for i in range(n):
                    d = abs(xnew[i] - xi[i]) / np.sqrt(Pb[i, i])
                    if d > dmax:
                        dmax = d
                    xi[i] = xnew[i]
                for k in range(nc):
                    coef_i[est_idx[k]] = xi[k]
                measure_jac_sc(xi[nc:], coef_i, fr_now[0], fr_now[1], fr_now[2], g, out, hm, ha)
                for r in range(3):
                    v = zb[m, r] - out[r]
                    for k in range(hnnz[r]):
                        src = hsrc[r, k]
                        hval[r, k] = hm[r, src] if src >= 0 else ha[r, -1 - src]
                        c = hcols[r, k]
                        v -= hval[r, k] * (xb[c] - xi[c])
                    innov[r] = v
                if dmax < it_tol:
                    break
        if joseph_update_sparse(xb, Pb, hcols, hnnz, hval, innov, r_var, U, K, D, S, Sinv, nu,
                                update_x):
            nis += nu[0] * nu[0] + nu[1] * nu[1] + nu[2] * nu[2]
            if rec.shape[0] > m:
                for r in range(3):
                    rec[m, r] = innov[r]
                    rec[m, 3 + r] = S[r, r]
        else:
            bad += 1
            if rec.shape[0] > m:
                for r in range(3):
                    rec[m, r] = innov[r]
                    rec[m, 3 + r] = np.nan
        store_history(hist_idx[m], xb, Pb, hist_x, hist_s)
    return nis, bad


@njit(cache=True)
def _coef_ratio(Pb, it_ctl, nc):
    """Mean over the coefficients of P_ii / P0_ii (1 at the start, falls as they are learnt);
    not computed (inf) when the iteration does not depend on it."""
    if it_ctl[3] <= 0.0:
        return np.inf
    s = 0.0
    for k in range(nc):
        s += Pb[k, k] / it_ctl[4 + k]
    return s / nc


@njit(cache=True)
def _gain_step(P, hcols, hnnz, hval, innov, r_var, U, S, Sinv, nu, w, x_pred, x_out):
    """``x_out = x_pred + K innov`` with ``K = P H^T (H P H^T + R)^-1`` for the sparse H of
    :func:`platcal.estimation.kalman.joseph_update_sparse`, P untouched (an inner iteration of
    the iterated EKF). Returns False if S is not positive definite."""
    innovation_covariance(P, hcols, hnnz, hval, r_var, U, S)
    if not cholesky_inverse(S, Sinv, nu, innov):
        return False
    n = P.shape[0]
    for r in range(3):
        w[r] = Sinv[r, 0] * innov[0] + Sinv[r, 1] * innov[1] + Sinv[r, 2] * innov[2]
    for j in range(n):
        x_out[j] = x_pred[j] + U[0, j] * w[0] + U[1, j] * w[1] + U[2, j] * w[2]
    return True


def iteration_control(p0_sigma: np.ndarray, iterations: int = 1, tol: float = 0.0,
                      until_s: float | None = None, ratio: float | None = None) -> np.ndarray:
    """The kernel's ``it_ctl`` array (see :func:`_filter_one`); ``iterations=1`` is the EKF."""
    head = [float(iterations), float(tol), np.inf if until_s is None else float(until_s),
            0.0 if ratio is None else float(ratio)]
    return np.ascontiguousarray(np.r_[head, np.asarray(p0_sigma, float) ** 2])


def _structure(est_idx: np.ndarray):
    """Sparsity of Phi's attitude rows and of H for the estimated coefficients ``est_idx``.

    Returns ``pcols, pg, hcols, hsrc, hnnz`` as :func:`_filter_one` takes them.
    """
    nc = est_idx.size
    state_of = {int(f): k for k, f in enumerate(est_idx)}
    gyro_pos = {int(f): q for q, f in enumerate(GYRO_COLS)}
    coef_cols = [(state_of[f], gyro_pos[f]) for f in GYRO_COLS if int(f) in state_of]
    pcols = np.array([s for s, _ in coef_cols] + [nc, nc + 1, nc + 2], dtype=np.int64)
    pg = np.array([q for _, q in coef_cols], dtype=np.int64)
    width = MEAS_COLS.shape[1] + 3
    hcols = np.zeros((3, width), dtype=np.int64)
    hsrc = np.zeros((3, width), dtype=np.int64)
    hnnz = np.zeros(3, dtype=np.int64)
    for r in range(3):
        entries = [(state_of[int(f)], m) for m, f in enumerate(MEAS_COLS[r])
                   if f >= 0 and int(f) in state_of]
        entries += [(nc + i, -1 - i) for i in range(3)]
        hnnz[r] = len(entries)
        for k, (s, src) in enumerate(entries):
            hcols[r, k] = s
            hsrc[r, k] = src
    return pcols, pg, hcols, hsrc, hnnz


def _history_index(t: np.ndarray, every_s: float | None, start: int) -> tuple[np.ndarray, int]:
    """History slot of each filter instant (-1: not kept) and the number of slots used."""
    idx = np.full(t.shape[0], -1, dtype=np.int64)
    if every_s is None:
        return idx, 0
    k = np.round(t / every_s)
    keep = np.abs(t - k * every_s) < 1e-9
    idx[keep] = start + np.arange(int(keep.sum()))
    return idx, int(keep.sum())

def history_slots(t: list, every_s: float | None) -> tuple[list[np.ndarray], int]:
    """History slot of each filter instant per position (-1: not kept) and the slots per pass."""
    slots, total = [], 0
    for tk in t:
        idx, used = _history_index(np.asarray(tk, float), every_s, total)
        slots.append(idx)
        total += used
    return slots, total


def end_to_end(z: list | None, t: list, B: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(offs (K+1,), t_all, z_all (B, M, 3))``: every position's instants and outputs end to
    end, so one kernel call runs a whole pass (``z`` None: a covariance-only run, no outputs)."""
    offs = np.zeros(len(t) + 1, dtype=np.int64)
    offs[1:] = np.cumsum([len(tk) for tk in t])
    t_all = np.ascontiguousarray(np.concatenate([np.asarray(tk, float) for tk in t]))
    if z is None:
        return offs, t_all, np.zeros((B, 0, 3))
    return offs, t_all, np.ascontiguousarray(np.concatenate([np.asarray(zk, float) for zk in z], axis=1))


def position_durations(counts, lasts, period_s: float) -> list[float]:
    """Each position's length on the history's clock, s: its last filter instant plus one filter
    period (0 for a position without instants)."""
    return [float(last) + period_s if c else 0.0 for c, last in zip(counts, lasts)]


def pass_history_index(t: list, slots: list, total: int, p: int, period_s: float, keep: bool,
                       hist_t: np.ndarray) -> np.ndarray:
    """The history slot of every instant of pass ``p`` end to end; fills ``hist_t`` (s from the
    start of the first pass; a position lasts to its last instant plus one filter period)."""
    durations = position_durations([len(tk) for tk in t], [tk[-1] if len(tk) else 0.0 for tk in t], period_s)
    out, offset = [], 0.0
    for k, tk in enumerate(t):
        tk = np.asarray(tk, float)
        hidx = slots[k] + (p * total if keep else 0)
        hidx[slots[k] < 0] = -1
        sel = hidx >= 0
        hist_t[hidx[sel]] = p * sum(durations) + offset + tk[sel]
        out.append(hidx)
        offset += durations[k]
    return np.ascontiguousarray(np.concatenate(out), dtype=np.int64)


def whole_segments(offs: np.ndarray, B: int) -> tuple:
    """The kernel's ``seg`` for whole positions end to end (:func:`_run_pass`): position k is
    segment k, starting with its reset and ending the position."""
    K = offs.shape[0] - 1
    return (np.arange(K, dtype=np.int64), np.full(K, np.nan), np.ones(K, dtype=np.bool_), np.zeros(B))


def chunk_segments(offs: np.ndarray, t_all: np.ndarray, i0: int, i1: int, carry: np.ndarray) -> tuple:
    """``(offsets, seg)`` of the instants ``i0 .. i1 - 1`` of a pass (positions end to end at
    ``offs``, instants ``t_all``): one segment per position they touch, which starts with the
    position's reset when it holds the position's first instant and otherwise continues from the
    instant before; ``carry`` (B,) the NIS sums the kernel carries between segments."""
    return block_segments(offs, i0, i1, float(t_all[i0 - 1]) if i0 > 0 else np.nan, carry)


def block_segments(offs: np.ndarray, i0: int, i1: int, t_before: float, carry: np.ndarray) -> tuple:
    """:func:`chunk_segments` given only ``t_before``, the instant ``i0 - 1`` (s since its
    position's start; used when the block continues a position), so that a streamed pass need not
    hold every instant."""
    ks = [k for k in range(offs.shape[0] - 1) if offs[k] < i1 and offs[k + 1] > i0]
    starts = [max(i0, int(offs[k])) for k in ks]
    ends = [min(i1, int(offs[k + 1])) for k in ks]
    local = np.array([a - i0 for a in starts] + [i1 - i0], dtype=np.int64)
    # a segment that does not start its position starts at i0 (only the first can), after t_before
    t0 = np.array([np.nan if a == offs[k] else t_before for k, a in zip(ks, starts)], float)
    last = np.array([b == offs[k + 1] for k, b in zip(ks, ends)], dtype=np.bool_)
    return local, (np.array(ks, dtype=np.int64), t0, last, carry)


def restart_covariance(P: np.ndarray, nc: int) -> np.ndarray:
    """P of a new pass (docs/centrifuge-model.md §11): 100 x the coefficient block, nothing else."""
    out = np.zeros_like(P)
    out[:, :nc, :nc] = P[:, :nc, :nc] * 100.0
    return out


@dataclass
class FilterStart:
    """What every pass of the EKF or UKF starts from (docs/centrifuge-model.md §9, §11): the
    commanded angles (B, K, 3) in rad, the state (B, n) and covariance (B, n, n) at the start,
    the attitude reset variance (rad^2), R's diagonal (g^2), the ARW rate (rad^2/s) and the
    packed centrifuge parameters per replicate and position."""

    cmd_rad: np.ndarray
    x: np.ndarray
    P: np.ndarray
    reset_var: float
    r_var: np.ndarray
    q_rate: float
    params: np.ndarray


def filter_start(cmd_deg: np.ndarray, centrifuge_params: np.ndarray, settings: FilterSettings, B: int,
                 K: int) -> FilterStart:
    """The start of a batch of B runs over K positions: coefficients 0 with P0 = diag(p0^2),
    angles 0 with no covariance until the first reset (docs/centrifuge-model.md §9)."""
    cmd = np.asarray(cmd_deg, float)
    if cmd.ndim == 2:
        cmd = np.broadcast_to(cmd, (B,) + cmd.shape)
    nc = settings.coef_index.size
    p0 = np.asarray(settings.p0_sigma, float)
    if p0.shape != (nc,):
        raise ValueError(f"p0_sigma has {p0.shape} entries, the filter has {nc} coefficients")
    P = np.zeros((B, nc + 3, nc + 3))
    P[:, np.arange(nc), np.arange(nc)] = p0**2
    x = np.zeros((B, nc + 3))
    if settings.prior_x is not None:
        x[:, :nc] = settings.prior_x
    if settings.prior_P is not None:
        P[:, :nc, :nc] = settings.prior_P
    return FilterStart(
        cmd_rad=np.ascontiguousarray(cmd * DEG), x=x, P=P,
        reset_var=(settings.sigma_set_arcsec * ARCSEC) ** 2, r_var=np.full(3, (settings.sigma_a_ug * 1e-6) ** 2),
        q_rate=(settings.arw_deg_rth * DEG / 60.0) ** 2,  # (rad/sqrt(s))^2
        params=broadcast_params(centrifuge_params, B, K))


def drive_passes(run_pass, x: np.ndarray, P: np.ndarray, z: list | None, t: list, settings: FilterSettings,
                 passes: int, nis: np.ndarray | None = None, n_bad: np.ndarray | None = None,
                 on_pass=None) -> Estimate:
    """Run ``passes`` passes over every position end to end (docs/centrifuge-model.md §9, §11):
    pass p > 0 restarts from the previous estimate with P0 = 100 x its coefficient covariance.

    ``run_pass(x, P, z_all, t_all, offs, hidx, hist_x, hist_s, nis, n_bad)`` runs one pass of a
    filter kernel in place (replicates handed out one at a time, so that a thread slowed by other
    processes takes fewer). ``nis`` and ``n_bad`` carry counts from a warm-up pass (None: zeros).
    ``on_pass(p, estimate)``, if given, is called after each pass but the last with ``p`` passes
    done and the Estimate a run of ``p`` passes returns (copies): a pass reads nothing of the
    passes after it, so its numbers are those of that run, bit for bit.
    """
    B = x.shape[0]
    nc = settings.coef_index.size
    n = x.shape[1]
    hist_slots, total = history_slots(t, settings.history_every_s)
    H = total * passes
    hist_x = np.zeros((B, H, n))
    hist_s = np.zeros((B, H, n))
    hist_t = np.zeros(H)
    pass_x = np.zeros((passes, B, nc))
    pass_P = np.zeros((passes, B, nc, nc))
    nis = np.zeros(B) if nis is None else nis
    n_bad = np.zeros(B, dtype=np.int64) if n_bad is None else n_bad
    offs, t_all, z_all = end_to_end(z, t, B)
    for p in range(passes):
        if p > 0:
            P = restart_covariance(P, nc)
            nis[:] = 0.0
        hidx_all = pass_history_index(t, hist_slots, total, p, settings.period_s,
                                      settings.history_every_s is not None, hist_t)
        with parallel_chunksize(1):
            run_pass(x, P, z_all, t_all, offs, hidx_all, hist_x, hist_s, nis, n_bad)
        pass_x[p] = x[:, :nc]
        pass_P[p] = P[:, :nc, :nc]
        if on_pass is not None and p < passes - 1:
            on_pass(p + 1, _estimate_after(p + 1, settings, total, int(offs[-1]), x, P, hist_t, hist_x, hist_s,
                                           pass_x, pass_P, nis, n_bad, copy=True))
    return _estimate_after(passes, settings, total, int(offs[-1]), x, P, hist_t, hist_x, hist_s, pass_x, pass_P,
                           nis, n_bad, copy=False)


def _estimate_after(done: int, settings: FilterSettings, total: int, n_obs: int, x, P, hist_t, hist_x, hist_s,
                    pass_x, pass_P, nis, n_bad, copy: bool) -> Estimate:
    """What a run of ``done`` passes returns (:func:`drive_passes`): its ``total`` history slots
    per pass and its passes' x and P of the running arrays, the NIS over ``n_obs`` instants;
    ``copy``: copies (a snapshot on the way, the later passes keep writing), else the arrays
    themselves (the run's end)."""
    h = total * done
    own = np.copy if copy else (lambda a: a)
    return Estimate(names=settings.state_names, x=own(x), P=own(P), history_t=own(hist_t[:h]),
                    history_x=own(hist_x[:, :h]), history_sigma=own(hist_s[:, :h]), pass_x=own(pass_x[:done]),
                    pass_P=own(pass_P[:done]), mean_nis=nis / max(n_obs, 1), failed_updates=own(n_bad))


@dataclass(frozen=True)
class EstimatorInput:
    """What every centrifuge estimator reads (the run contract of
    :mod:`platcal.rigs.centrifuge.estimators`), for a batch of B runs of one scheme.

    z : K arrays (B, M_k, 3), accelerometer outputs (g) at the instants ``t`` (None where no
        measurement is read: a covariance-only run, a streamed record).
    t : K arrays (M_k,), the instants in s since each position's start (increasing, >= 0).
    cmd_deg : (B, K, 3) or (K, 3) commanded alpha, beta, gamma per position, deg.
    centrifuge_params : (5,), (K, 5) or (B, K, 5) packed centrifuge parameters
        (``Centrifuge.params()``; per position for multi-g-level schemes).
    """

    z: list | None
    t: list
    cmd_deg: np.ndarray
    centrifuge_params: np.ndarray


@dataclass(frozen=True)
class StreamedInstants:
    """The ``t`` of an :class:`EstimatorInput` of a streamed record whose instants are not held
    (:func:`run_ekf` ``z_source`` then yields each block's instants with its outputs): per
    position, in order, the number of filter instants ``counts`` and the last instant ``last``
    (s since the position's start; what the history's clock needs, docs/centrifuge-model.md §9).
    Memory: O(K), whatever the record's length (issue 22 item 3)."""

    counts: tuple
    last: tuple

    def __len__(self) -> int:
        return len(self.counts)

    @classmethod
    def of(cls, t: list) -> StreamedInstants:
        """The counts and last instants of K arrays of instants (s)."""
        return cls(tuple(len(tk) for tk in t), tuple(float(tk[-1]) if len(tk) else 0.0 for tk in t))


LANES_FROM_BATCH = 8
"""The smallest batch that :func:`run_ekf` runs on the state-major kernel by itself: two blocks
of its 4 lanes (``platcal.estimation.lanes.LANES``), one per thread of a 2-core machine. Below it
the default kernel's one replicate per thread is the quicker in wall time (a block costs its 4
lanes whatever number of them are live); from it the lanes take about a third less CPU per
replicate (issue 22: 0.0313 against 0.0482 s at B = 64, ``benchmarks/bench_filter.py``, stop 47)."""


def takes_lanes(lanes: bool | None, batch: int) -> bool:
    """Whether :func:`run_ekf` runs a batch of ``batch`` replicates on the state-major kernel:
    ``lanes`` where given, else (None) from :data:`LANES_FROM_BATCH` replicates on. Either kernel
    gives the same numbers bit for bit (``tests/test_ekf_lanes.py``): this chooses a cost."""
    return batch >= LANES_FROM_BATCH if lanes is None else bool(lanes)


def run_ekf(
    data: EstimatorInput,
    settings: FilterSettings,
    *,
    linearise_about: np.ndarray | None = None,
    iterate: np.ndarray | None = None,
    warmup_s: float | None = None,
    z_source=None,
    on_innovations=None,
    on_history=None,
    lanes: bool | None = None,
    on_pass=None,
) -> Estimate:
    """Run the EKF over every position of a scheme, for a batch of B runs.

    Parameters
    ----------
    data : the record, commands and centrifuge parameters (:class:`EstimatorInput`; ``z`` at
        the filter instants).
    settings : the filter settings.
    linearise_about : (B, 48) full coefficient vectors. If given, the run is covariance-only
        (docs/centrifuge-model.md §10): no measurement is used, the state follows the noise-free trajectory
        of these coefficients, and only P evolves.
    iterate : the iterated update's control array (:func:`iteration_control`; :func:`run_iekf`);
        None: the EKF (one linearisation per update).
    warmup_s : a warm-up pass before the first pass: the filter runs over the instants t <
        warmup_s of every position, and the passes then start from its coefficient estimate with
        ``P0 = 100 x`` its coefficient covariance (as a further pass does), so that the whole
        record is filtered about a better linearisation point for (1 + warmup_s / dwell) times
        the cost of one pass. Not a pass: ``pass_x``, ``pass_P`` and the history hold the full
        passes only. None: no warm-up (the paper's EKF).
    z_source : a streamed record (one run, ``z`` None): called once per pass, it yields
        ``(i0, i1, z_block (1, i1 - i0, 3))``, the outputs of the instants ``i0 .. i1 - 1`` of all
        positions end to end, in order, or, when ``data.t`` is a :class:`StreamedInstants`,
        ``(i0, i1, z_block, t_block (i1 - i0,))`` with those instants (s since their position's
        start); the filter runs block by block with its state carried (:func:`block_segments`,
        :func:`drive_stream`), the same operations as over the whole record, so memory holds
        one block. No warm-up.
    on_innovations : with ``z_source`` and ``settings.innovations``, called with ``(i0, i1,
        z_block, rec_block (1, i1 - i0, 6))`` after each block (every pass; the last pass's are
        the run's), instead of keeping them in ``Estimate.innovations``.
    on_history : with ``z_source``, called with ``(t (h,), x (h, n), sigma (h, n))`` for the
        history rows of each block, in order (every pass), instead of keeping them in the
        Estimate (whose history is then empty): a 6 h history is 17 MB (issue 22 item 3).
    lanes : run the state-major kernel (:mod:`platcal.rigs.centrifuge.ekf_lanes`: replicates in
        SIMD lanes of 4; the same numbers bit for bit, about a third less CPU per replicate at
        B >= 8, 3.8x more at B = 1; issue 22) instead of the default kernel (:func:`_run_pass`:
        one replicate per thread). None: ``settings.lanes``, and where that is None too, the
        lanes for a batch of at least :data:`LANES_FROM_BATCH` (:func:`takes_lanes`). A lone
        record is fast on the default kernel, which is the one compiled ahead of time (an
        identify); the simulated batches (:func:`.identify.simulate_identify`) take the lanes.
    on_pass : called ``on_pass(p, estimate)`` after each pass p < ``settings.passes`` with the
        Estimate (copies, innovations included when kept) that this run with ``passes = p`` returns,
        bit for bit (:func:`drive_passes`), so that one run gives the estimates of fewer passes
        too (:func:`.identify.pass_prefixes`). Not with ``z_source``.

    Returns
    -------
    Estimate
    """
    z, t, cmd_deg, centrifuge_params = data.z, data.t, data.cmd_deg, data.centrifuge_params
    K = len(t)
    cov_only = linearise_about is not None
    if z_source is not None and (cov_only or warmup_s is not None or on_pass is not None):
        raise ValueError("a streamed record (z_source) is filtered without warm-up or on_pass, not covariance-only")
    B = 1 if z_source is not None else z[0].shape[0] if not cov_only else np.asarray(linearise_about).shape[0]
    st = filter_start(cmd_deg, centrifuge_params, settings, B, K)
    est_idx = settings.coef_index
    nc = est_idx.size
    x, P = st.x, st.P
    # coefficients the filter does not estimate keep these values (DOO = 0 in the paper's
    # filter); a covariance-only run follows the true trajectory, true DOO included
    coef_fixed = np.zeros((B, N_FULL))
    if cov_only:
        coef_fixed = np.ascontiguousarray(linearise_about, float)
        x[:, :nc] = coef_fixed[:, est_idx]
    passes = 1 if cov_only else settings.passes
    structure = _structure(est_idx)
    p0 = np.asarray(settings.p0_sigma, float)
    it_ctl = iteration_control(p0) if iterate is None or cov_only else np.ascontiguousarray(iterate, float)
    if takes_lanes(settings.lanes if lanes is None else lanes, B):
        # imported here: its pipeline class subclasses numba's compiler, which an identify whose
        # kernels were compiled ahead of time does not load (platcal.aot)
        from .ekf_lanes import run_pass_lanes
        kernel = run_pass_lanes
    else:
        kernel = aot_pick(KERNELS, "run_pass_serial", _run_pass_serial, _run_pass, B)
    keep = settings.innovations and not cov_only
    # every full pass overwrites it, so it ends holding the last pass's innovations
    if z_source is not None:
        streamed = t if isinstance(t, StreamedInstants) else StreamedInstants.of(t)
        source = z_source if isinstance(t, StreamedInstants) else _with_instants(z_source, t)

        def run_block(x, P, zb, tb, local, hidx, hist_x, hist_s, nis, n_bad, rb, seg):
            kernel(x, P, zb, tb, local, st.cmd_rad, st.reset_var, est_idx, coef_fixed, st.params, st.r_var,
                   st.q_rate, True, hidx, hist_x, hist_s, nis, n_bad, *structure, it_ctl, rb, seg)

        return drive_stream(run_block, x, P, source, streamed, settings, keep, on_innovations, on_history)
    rec = np.zeros((B, sum(len(tk) for tk in t) if keep else 0, 6))

    def run_pass(x, P, z_all, t_all, offs, hidx, hist_x, hist_s, nis, n_bad, update_x=not cov_only, rec=rec):
        kernel(x, P, z_all, t_all, offs, st.cmd_rad, st.reset_var, est_idx, coef_fixed, st.params,
               st.r_var, st.q_rate, update_x, hidx, hist_x, hist_s, nis, n_bad, *structure, it_ctl, rec,
               whole_segments(offs, B))

    nis = np.zeros(B)
    n_bad = np.zeros(B, dtype=np.int64)
    if warmup_s is not None and not cov_only:
        early = [np.asarray(tk, float) < warmup_s for tk in t]
        offs_w, t_w, z_w = end_to_end([np.asarray(zk, float)[:, kp] for zk, kp in zip(z, early)],
                                      [np.asarray(tk, float)[kp] for tk, kp in zip(t, early)], B)
        no_hist = np.full(t_w.size, -1, dtype=np.int64)
        with parallel_chunksize(1):
            run_pass(x, P, z_w, t_w, offs_w, no_hist, np.zeros((B, 0, nc + 3)), np.zeros((B, 0, nc + 3)),
                     nis, n_bad, update_x=True, rec=np.zeros((B, 0, 6)))
        P = restart_covariance(P, nc)
        nis[:] = 0.0
    est = drive_passes(run_pass, x, P, None if cov_only else z, t, settings, passes, nis, n_bad,
                       _with_innovations(on_pass, rec) if on_pass is not None and keep else on_pass)
    return replace(est, innovations=rec) if keep else est


def _with_innovations(on_pass, rec: np.ndarray):
    """``on_pass`` handed each Estimate with the innovations of the pass just done (``rec``, which
    each pass overwrites: a run's innovations are its last pass's), copied."""

    def call(p: int, est: Estimate) -> None:
        on_pass(p, replace(est, innovations=rec.copy()))

    return call


def _with_instants(z_source, t: list):
    """``z_source`` whose blocks also carry their instants (s), cut from the held ``t`` (K arrays)."""
    t_all = np.ascontiguousarray(np.concatenate([np.asarray(tk, float) for tk in t]))

    def source():
        for i0, i1, zb in z_source():
            yield i0, i1, zb, t_all[i0:i1]

    return source


def drive_stream(run_block, x: np.ndarray, P: np.ndarray, z_source, instants: StreamedInstants,
                 settings: FilterSettings, keep: bool, on_innovations=None, on_history=None) -> Estimate:
    """:func:`drive_passes` of a streamed record (one run), block by block (docs/centrifuge-model.md
    §9, §11): ``z_source()`` yields ``(i0, i1, z_block (1, m, 3), t_block (m,))`` once per pass;
    ``run_block(x, P, z, t, offsets, hist_idx, hist_x, hist_s, nis, n_bad, rec, seg)`` runs the
    kernel over one block in place. The history rows (``history_every_s``) and the innovations
    (``keep``) of each block go to ``on_history`` and ``on_innovations`` as they come (the
    history is kept in the Estimate only without ``on_history``), so that nothing held grows
    with the record: the positions' counts and last instants, one block, x and P. The same
    kernel calls on the same blocks as the held record's run: x, P, NIS and history are
    bit-identical to it (slots and clock as :func:`history_slots` and :func:`pass_history_index`)."""
    B, n = x.shape
    nc = settings.coef_index.size
    passes = settings.passes
    every = settings.history_every_s
    counts = [int(c) for c in instants.counts]
    offs = np.zeros(len(counts) + 1, dtype=np.int64)
    offs[1:] = np.cumsum(counts)
    durations = position_durations(counts, instants.last, settings.period_s)
    starts, offset = [], 0.0
    for d in durations:  # each position's start on the history's clock, summed as pass_history_index does
        starts.append(offset)
        offset += d
    pass_x = np.zeros((passes, B, nc))
    pass_P = np.zeros((passes, B, nc, nc))
    nis = np.zeros(B)
    n_bad = np.zeros(B, dtype=np.int64)
    carry = np.zeros(B)
    held = []
    for p in range(passes):
        if p > 0:
            P = restart_covariance(P, nc)
            nis[:] = 0.0
        t_before = np.nan
        for i0, i1, zb, tb in z_source():
            zb = np.ascontiguousarray(zb, float)
            tb = np.ascontiguousarray(tb, float)
            local, seg = block_segments(offs, i0, i1, t_before, carry)
            hidx, _ = _history_index(tb, every, 0)
            ht = np.zeros(0)
            if every is not None:
                sel = hidx >= 0
                # each instant's position's start on the history's clock, as pass_history_index adds it
                base = np.repeat([p * sum(durations) + starts[k] for k in seg[0]], np.diff(local))
                ht = base[sel] + tb[sel]
            hist_x = np.zeros((B, ht.size, n))
            hist_s = np.zeros((B, ht.size, n))
            rb = np.zeros((B, i1 - i0 if keep else 0, 6))
            with parallel_chunksize(1):
                run_block(x, P, zb, tb, local, hidx, hist_x, hist_s, nis, n_bad, rb, seg)
            if ht.size:
                if on_history is not None:
                    on_history(ht, hist_x[0], hist_s[0])
                else:
                    held.append((ht, hist_x, hist_s))
            if keep and on_innovations is not None:
                on_innovations(i0, i1, zb, rb)
            if tb.size:
                t_before = float(tb[-1])
        pass_x[p] = x[:, :nc]
        pass_P[p] = P[:, :nc, :nc]
    hist_t = np.concatenate([h[0] for h in held]) if held else np.zeros(0)
    hist_x = np.concatenate([h[1] for h in held], axis=1) if held else np.zeros((B, 0, n))
    hist_s = np.concatenate([h[2] for h in held], axis=1) if held else np.zeros((B, 0, n))
    return Estimate(names=settings.state_names, x=x, P=P, history_t=hist_t, history_x=hist_x,
                    history_sigma=hist_s, pass_x=pass_x, pass_P=pass_P,
                    mean_nis=nis / max(int(offs[-1]), 1), failed_updates=n_bad)


def run_iekf(
    data: EstimatorInput,
    settings: FilterSettings,
    *,
    iterations: int = 2,
    tol: float = 0.01,
    until_s: float | None = None,
    ratio: float | None = None,
    **stream,
) -> Estimate:
    """The iterated EKF (issue 9 item 3): :func:`run_ekf` whose measurement updates relinearise.

    Gauss-Newton form of the IEKF: from the predicted ``x_p, P`` and ``x_0 = x_p``,
    ``x_{i+1} = x_p + K_i (z - h(x_i) - H_i (x_p - x_i))`` with ``H_i, K_i`` at ``x_i``; the
    update ends after ``iterations`` linearisations, or once no state moves by more than ``tol``
    of its predicted sigma, and P is the Joseph form with the last ``K_i, H_i`` (symmetric,
    positive definite as in the EKF). Propagation, resets and passes are the EKF's.

    Options: ``iterations`` (max linearisations per update; 1 = the EKF), ``tol`` (sigmas),
    ``until_s`` (iterate only at instants t < until_s of each position; None: all) and ``ratio``
    (iterate only while the mean over the coefficients of P_ii / P0_ii exceeds it, i.e. while
    the coefficients are still poorly known; None: always). Same batching and bit-identity
    whatever B and threads as the EKF. ``stream``: :func:`run_ekf`'s ``z_source`` and
    ``on_innovations`` (a streamed record), or ``on_pass``.
    """
    if int(iterations) < 1:
        raise ValueError("iterations must be >= 1")
    ctl = iteration_control(settings.p0_sigma, int(iterations), tol, until_s, ratio)
    return run_ekf(data, settings, iterate=ctl, **stream)
