"""The sled's filters with the seeds in SIMD lanes (issue 22 item 2,
:func:`platcal.rigs.sled.filter_lanes._kalman_block`) against the one-seed-at-a-time reference kernel
(:func:`platcal.rigs.sled.filters._kalman`, the dense F of :func:`.errmodel.run_F` /
:func:`.errmodel.stop_F`): the same operations in the same order, so the estimates, sigmas,
covariances, NIS, skipped updates and innovation histories are bit-identical for every seed,
whatever its lane or the thread count (docs/rocket-sled.md §6). The compiled loops that replaced
numpy in the identification (epoch means, X corrections, mechanisation over threads) are checked
against the numpy they replaced, bit for bit."""

import numpy as np
import pytest

from platcal.estimation.lanes import LANES
from platcal.parallel import threads
from platcal.rigs.sled import filters
from platcal.rigs.sled.config import G, load_config
from platcal.rigs.sled.identify import (compensate_modes, compensate_x, identify, phi_hold, x_corrections,
                                        x_corrections_held)
from platcal.rigs.sled.ins import _initial_attitude, _mechanise, mechanise, nav_outputs
from platcal.rigs.sled.montecarlo import replicate_seeds
from platcal.rigs.sled.simulate import simulate

B = LANES + 1   # a full block, then a block of one live lane and LANES - 1 fillers
FIELDS = ("x", "sigma", "P", "mean_nis", "failed_updates", "innov", "s_var")


@pytest.fixture(scope="module")
def small_batch():
    """B replicates of the default case (the Monte Carlo cell's seeds)."""
    cfg = load_config({"rig": "sled"})
    return simulate(cfg, replicate_seeds(cfg.raw, "default", range(B)))


def _inputs(cfg, idn, which):
    """The run or stop filter's dynamics, measurements, prior and tuning of an identification."""
    ep, v, r, js, je = idn.epochs, idn.v, idn.r, idn.j_stop, idn.j_end
    if which == "run":
        k = ep.k[1:js + 1]
        z = np.stack([v[:, k, 1], r[:, k, 1], v[:, k, 2], r[:, k, 2]], axis=-1)
        dyn = filters.Dynamics.run(filters.epoch_mean(idn.fl, ep, 0, js), cfg.omega_ie, cfg.states)
        return dyn, z, np.zeros((B, cfg.states)), filters.run_tuning(cfg, cfg.states), ep.T[:js]
    iy = 4 if cfg.states == 6 else 5
    ks = ep.k[js]
    k = ep.k[js + 1:je + 1]
    z = np.stack([v[:, k, 1], r[:, k, 1], v[:, k, 0], r[:, k, 0] - r[:, ks, None, 0]], axis=-1)
    x0 = np.zeros((B, 6))
    x0[:, 0], x0[:, 1], x0[:, 2], x0[:, 5] = v[:, ks, 1], r[:, ks, 1], v[:, ks, 0], idn.run.x[:, -1, iy]
    dyn = filters.Dynamics.stop(filters.epoch_mean(idn.fl, ep, js, je), cfg.omega_ie)
    return dyn, z, x0, filters.stop_tuning(cfg, idn.run.P[:, iy, iy]), ep.T[js:je]


def _assert_same(new, ref):
    for name in FIELDS:
        assert np.array_equal(getattr(new, name), getattr(ref, name), equal_nan=True), name


@pytest.mark.parametrize("over", [{}, {"states": 7}, {"states": 7, "tuning": "paper"}, {"tuning": "paper"}],
                         ids=["default", "run7", "paper7", "paper6"])
@pytest.mark.parametrize("which", ["run", "stop"])
def test_lanes_bit_identical_to_the_reference_kernel(small_batch, over, which):
    """The default config's cases, both filters, B seeds: every output equal, 1 and 2 threads."""
    sb = small_batch
    cfg = load_config({"rig": "sled", "filter": over})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    dyn, z, x0, tun, T = _inputs(cfg, idn, which)
    T0 = cfg.period_ms / 1000.0
    ref = filters.kalman(dyn.dense(), z, x0, tun, T, T0)
    for n in (1, 2):
        with threads(n):
            _assert_same(filters.kalman(dyn, z, x0, tun, T, T0), ref)
    _assert_same(getattr(idn, which), ref)          # identify's own filter ran in lanes
    # not trivially equal: the filter moved, the seeds differ, every update was made
    assert np.all(np.abs(ref.x[:, -1] - x0).max(axis=1) > 0) and not np.array_equal(ref.x[0], ref.x[1])
    assert not np.any(ref.failed_updates) and np.all(np.isfinite(ref.innov))


def test_lanes_skipped_updates_as_the_reference(small_batch):
    """S not positive definite on some epochs of one seed only: every lane takes the reference's
    update there (the failing one skips it, the others update), as the reference does."""
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    dyn, z, x0, tun, T = _inputs(cfg, idn, "run")
    J = 40
    dyn = filters.Dynamics(dyn.kind, np.ascontiguousarray(dyn.f[:, :J]), dyn.w, dyn.wc)
    bad = filters.Tuning(P0=tun.P0, Qd=tun.Qd, R=np.diag([-1e-2, 25e-6, 25e-6, 25e-6]))
    x0 = x0.copy()
    x0[1, 0] = 0.0
    P0 = np.broadcast_to(tun.P0, (B,) + tun.P0.shape).copy()
    P0[1, 0, 0] = 1.0   # seed 1's S[0, 0] = P + R > 0 at first: its first updates are made
    bad = filters.Tuning(P0=P0, Qd=tun.Qd, R=bad.R)
    ref = filters.kalman(dyn.dense(), z[:, :J], x0, bad, T[:J], 0.02)
    new = filters.kalman(dyn, z[:, :J], x0, bad, T[:J], 0.02)
    _assert_same(new, ref)
    assert ref.failed_updates[0] == J and 0 < ref.failed_updates[1] < J


def test_non_finite_block_falls_back_to_the_reference(small_batch):
    """A NaN force in one seed: its block runs the reference kernel (the same NaNs), the other
    block the lanes; every seed's numbers as the reference's."""
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    dyn, z, x0, tun, T = _inputs(cfg, idn, "run")
    f = dyn.f.copy()
    f[LANES, 7, 0] = np.nan     # the second block's only seed
    dyn = filters.Dynamics(dyn.kind, f, dyn.w, dyn.wc)
    ref = filters.kalman(dyn.dense(), z, x0, tun, T, 0.02)
    _assert_same(filters.kalman(dyn, z, x0, tun, T, 0.02), ref)
    assert np.isnan(ref.x[LANES, -1]).any() and np.all(np.isfinite(ref.x[:LANES]))


def test_epoch_mean_is_numpys_reduceat():
    """The compiled epoch means against the numpy they replaced (np.add.reduceat's pairwise
    order), on epochs of 1 to 300 samples (a gapped record) with jittered intervals."""
    rng = np.random.default_rng(3)
    lens = np.r_[rng.integers(1, 12, 100), 8, 9, 16, 17, 127, 128, 129, 300]
    k = np.r_[0, np.cumsum(lens)] + 3
    N = k[-1] + 5
    fl = rng.standard_normal((3, N, 3)) * 10
    dts = 0.005 + rng.standard_normal(N) * 1e-5
    ep = filters.Epochs(k=k, T=np.diff(k) * 0.005, dts=dts)
    for j0, j1 in ((0, k.size - 1), (5, 40)):
        kk = k[j0:j1 + 1]
        seg = fl[:, kk[0]:kk[-1]] * dts[None, kk[0]:kk[-1], None]
        want = np.add.reduceat(seg, kk[:-1] - kk[0], axis=1) / np.add.reduceat(dts[kk[0]:kk[-1]],
                                                                                  kk[:-1] - kk[0])[None, :, None]
        assert np.array_equal(filters.epoch_mean(fl, ep, j0, j1), want)


def test_x_corrections_are_numpys_cumsum(small_batch):
    """The compiled X corrections (held φ̂, both modes) against the numpy cumulative sums they
    replaced, from a carried start."""
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    fl, N = idn.fl, idn.fl.shape[1]
    dts = idn.epochs.dts * (1 + 1e-3 * np.sin(np.arange(N)))   # unequal intervals
    start = (np.linspace(-1e-3, 1e-3, B), np.linspace(0.1, 0.2, B))
    for mode in ("realtime", "post"):
        est, hold = phi_hold(idn.run, cfg.states, idn.epochs.k, idn.j_stop, N, mode)
        phi = est[:, hold]
        da = fl[..., 1] * phi[..., 2] - fl[..., 2] * phi[..., 1]
        dv = np.cumsum(np.concatenate([start[0][:, None], da * dts], axis=1), axis=1)
        dr = np.cumsum(np.concatenate([start[1][:, None], (dv[:, :-1] + dv[:, 1:]) * 0.5 * dts], axis=1), axis=1)
        for got in (x_corrections_held(fl, est, hold, dts, start), x_corrections(fl, phi, dts, start)):
            assert np.array_equal(got[0], dv) and np.array_equal(got[1], dr)
        assert np.abs(dr[:, -1] - start[1]).max() > 0


def test_compensation_modes_in_one_pass_are_compensate_x(small_batch):
    """identify's X compensation of both modes in one compiled pass (:func:`compensate_modes`,
    reading X from the mechanisation's (S,N+1,3) positions) against the formula per mode
    (:func:`x_corrections_held`'s sums; :func:`compensate_x`, one hold, too), bit for bit, on
    unequal and equal intervals, a non-contiguous position view and 1 or 2 threads; and identify's
    own x_con, x_con_other are those."""
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    idn = identify(cfg, sb.traj, sb.f, sb.w)
    fl, N = idn.fl, idn.fl.shape[1]
    _, r_nav, _ = mechanise(sb.f, sb.w, np.zeros((B, 3)), cfg.omega_ie, idn.epochs.dts)
    held = [phi_hold(idn.run, cfg.states, idn.epochs.k, idn.j_stop, N, m) for m in ("realtime", "post")]
    holds = np.stack([h for _, h in held])
    for dts in (idn.epochs.dts * (1 + 1e-3 * np.sin(np.arange(N))), cfg.dt):
        # §7's sums as x_corrections_held forms them (numpy's cumsum's numbers: the test above)
        want = [r_nav[:, :N, 0] - x_corrections_held(fl, est, hold, dts)[1][:, :N] for est, hold in held]
        assert all(np.array_equal(compensate_x(fl, r_nav[:, :N, 0], est, hold, dts), w)
                   for (est, hold), w in zip(held, want))
        for n_threads in (1, 2):
            with threads(n_threads):
                for r in (r_nav, r_nav[:, :N]):
                    got = compensate_modes(fl, r, held[0][0], holds, dts)
                    assert got.shape == (2, B, N)
                    for m in range(2):
                        assert np.array_equal(got[m], want[m])
            odd = compensate_modes(fl, r_nav, held[0][0], holds[[1, 0, 1]], dts)   # an odd count of holds
            assert all(np.array_equal(odd[m], want[i]) for m, i in enumerate((1, 0, 1)))
    assert not np.array_equal(want[0], want[1])   # the two holds differ
    xc = compensate_modes(fl, r_nav, held[0][0], holds, idn.epochs.dts)
    assert np.array_equal(idn.x_con, xc[0]) and np.array_equal(idn.x_con_other, xc[1])   # default: realtime


def test_mechanisation_outputs_in_one_block_are_separate_arrays_numbers(small_batch):
    """:func:`nav_outputs` (v, r, f_l as views of one allocation): C-contiguous, disjoint, and
    ``mechanise`` through them gives the kernel's numbers into three arrays allocated apart (and
    pre-filled with NaN, so an unwritten element would show), bit for bit."""
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    S, N = sb.f.shape[:2]
    outs = nav_outputs(S, N)
    assert [o.shape for o in outs] == [(S, N + 1, 3), (S, N + 1, 3), (S, N, 3)]
    assert all(o.flags.c_contiguous and o.flags.writeable for o in outs)
    assert not any(np.shares_memory(a, b) for i, a in enumerate(outs) for b in outs[i + 1:])
    phi0 = np.linspace(-1e-4, 1e-4, 3 * S).reshape(S, 3)
    dts = np.full(N, cfg.dt)
    got = mechanise(sb.f, sb.w, phi0, cfg.omega_ie, dts)
    C = np.empty((S, 3, 3))
    _initial_attitude(phi0, C)
    apart = tuple(np.full(o.shape, np.nan) for o in outs)
    _mechanise(0, S, np.array(sb.f), np.array(np.broadcast_to(sb.w, sb.f.shape)), C,
               np.zeros((S, 6)), np.asarray(cfg.omega_ie, dtype=np.float64), G, dts, *apart)
    for a, b in zip(got, apart):
        assert np.array_equal(a, b)


def test_mechanisation_does_not_depend_on_threads(small_batch):
    sb = small_batch
    cfg = load_config({"rig": "sled"})
    phi0 = np.linspace(-1e-4, 1e-4, 3 * B).reshape(B, 3)
    with threads(1):
        one = mechanise(sb.f, sb.w, phi0, cfg.omega_ie, cfg.dt)
    with threads(2):
        two = mechanise(sb.f, sb.w, phi0, cfg.omega_ie, cfg.dt)
    for a, b in zip(one, two):
        assert np.array_equal(a, b)
