"""Truth simulator: drawn residuals, the platform INS error model and the record (docs/lowprec-centrifuge.md §4, §5, §8, §9).

One call simulates one run of one platform for a batch of seeds (leading axis), in lock-step with
the four unit-coefficient variants of §8 (v1..v4: the response to 1 ug/g kA_x, 1 ug/g^2 k2_x,
1 ug/g kA_y, 1 ug/g^2 k2_y alone; no other error, no noise, zero initial state). The INS error
model is linear in the coefficients, so these give the compensated errors exactly.

Seeding (§9, [D] §12): a replicate is one ``numpy.random.SeedSequence``, the generic runner's
(:func:`platcal.study.montecarlo.replicate_seed`); :func:`run_streams` derives from it, per
(platform, run), one stream for the error parameters (in this order: k0 x,y; scale x,y; gyro
drift x,y,z; tilt x,y; azimuth) and one for the noise (accelerometer x,y; gyro x,y,z; velocity
E,N; position E,N; heading, each a full-length block in that order). A replicate's numbers do not
depend on the batch it runs in, and they are common across centrifuge scenarios (the scenarios
share one seed key, :mod:`.montecarlo`). Platform keys are 1-based positions in ``platforms``;
run keys 1, 2, ... for the proposed runs in config order and 0 for the traditional run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from .config import G0, OMEGA_IE, R_EARTH, Study
from .profile import Kinematics, Profile, build_profile, kinematics

ARCSEC = np.pi / 180 / 3600
DEG_H = np.pi / 180 / 3600
"""1 deg/h in rad/s."""
TILT_SIGMA_ARCSEC = 5.0
"""Levelling residual of the alignment (§5), arcsec."""
VARIANTS = 4


@dataclass(frozen=True)
class Draws:
    """Drawn residuals per seed (§4, §5), shape (S, ...)."""

    k0_ug: np.ndarray         # (S, 2) accelerometer bias x, y, ug
    scale_ppm: np.ndarray     # (S, 2) scale-factor residual x, y, ppm
    drift_deg_h: np.ndarray   # (S, 3) gyro drift x, y, z, deg/h
    phi0_rad: np.ndarray      # (S, 3) initial attitude error x, y, z, rad


@dataclass
class RunBatch:
    """One run of one platform simulated for a batch of seeds (+ the 4 variants of §8)."""

    platform: str
    run: str
    seeds: np.ndarray
    coeffs: np.ndarray        # (4,) true kA_x, k2_x, kA_y, k2_y
    prof: Profile
    kin: Kinematics
    draws: Draws
    err: np.ndarray           # (S, N, 4) true dVE, dVN, dpE, dpN
    phi: np.ndarray | None    # (S, N, 3) true attitude errors (when asked for)
    sens: np.ndarray          # (4, N, 4) unit-coefficient responses (v1..v4)
    v_ind: np.ndarray         # (S, N, 2) INS velocity output, m/s
    p_ind: np.ndarray         # (S, N, 2) INS position output relative to the start, m
    psi: np.ndarray           # (S, N) heading output, rad (not wrapped)

    @property
    def final(self) -> np.ndarray:
        """(S, 4) errors at the end of the run (dVE, dVN, pE, pN) before compensation."""
        return self.err[:, -1, :]

    @property
    def sens_final(self) -> np.ndarray:
        """(4 coefficients, 4 errors) end-of-run sensitivities S_jk (§8)."""
        return self.sens[:, -1, :]


@numba.njit(cache=True)
def _integrate(dt, f, coef, eps, x0, acc_w, gyro_w, sin_l, cos_l, tan_l, out, phi_out):
    """Euler integration of the §5 error model for one trajectory.

    coef = (k0x, k0y, dKx, dKy, kAx, k2x, kAy, k2y) dimensionless (g/g); eps rad/s; x0 =
    (dVE, dVN, pE, pN, phix, phiy, phiz); acc_w (M, 2) m/s^2 and gyro_w (M, 3) rad/s are the
    per-sample white noises (M = 0: none). out (N, 4) receives (dVE, dVN, pE, pN) at each sample,
    phi_out (N, 3) the attitude (if its length is N).
    """
    n = f.shape[0]
    noisy = acc_w.shape[0] == n
    keep_phi = phi_out.shape[0] == n
    ve, vn, pe, pn, px, py, pz = x0[0], x0[1], x0[2], x0[3], x0[4], x0[5], x0[6]
    w_s = OMEGA_IE * sin_l
    w_c = OMEGA_IE * cos_l
    for k in range(n):
        out[k, 0] = ve
        out[k, 1] = vn
        out[k, 2] = pe
        out[k, 3] = pn
        if keep_phi:
            phi_out[k, 0] = px
            phi_out[k, 1] = py
            phi_out[k, 2] = pz
        fe = f[k, 0]
        fn = f[k, 1]
        ae = fe / G0
        an = fn / G0
        nab_e = G0 * (coef[0] + coef[2] * ae + coef[4] * abs(ae) + coef[5] * ae * ae)
        nab_n = G0 * (coef[1] + coef[3] * an + coef[6] * abs(an) + coef[7] * an * an)
        wx, wy, wz = eps[0], eps[1], eps[2]
        if noisy:
            nab_e += acc_w[k, 0]
            nab_n += acc_w[k, 1]
            wx += gyro_w[k, 0]
            wy += gyro_w[k, 1]
            wz += gyro_w[k, 2]
        dve = pz * fn - py * G0 + 2 * w_s * vn + nab_e
        dvn = -pz * fe + px * G0 - 2 * w_s * ve + nab_n
        dpx = -vn / R_EARTH + w_s * py - w_c * pz + wx
        dpy = ve / R_EARTH - w_s * pn / R_EARTH - w_s * px + wy
        dpz = ve * tan_l / R_EARTH + w_c * pn / R_EARTH + w_c * px + wz
        pe += dt * (ve + 0.5 * dt * dve)
        pn += dt * (vn + 0.5 * dt * dvn)
        ve += dt * dve
        vn += dt * dvn
        px += dt * dpx
        py += dt * dpy
        pz += dt * dpz


def run_streams(seed: np.random.SeedSequence, platform_key: int, run_key: int) -> tuple:
    """The (parameters, noise) SeedSequences of one (platform, run) of a replicate: children of the
    replicate's ``seed`` keyed by the platform and run keys (§9, [D] §12), built directly rather
    than by ``spawn`` so that they do not depend on what was spawned before."""
    base = tuple(seed.spawn_key) + (int(platform_key), int(run_key))
    return (np.random.SeedSequence(seed.entropy, spawn_key=base + (0,)),
            np.random.SeedSequence(seed.entropy, spawn_key=base + (1,)))


def draw_params(study: Study, rng: np.random.Generator) -> tuple:
    """(k0_ug(2), scale_ppm(2), drift_deg_h(3), phi0_rad(3)) drawn from ``rng``, the parameter
    stream of one (replicate, platform, run) (§4, §5, §9)."""
    res = study.residuals
    k0 = rng.normal(0.0, res["k0_ug"], 2)
    sk = rng.normal(0.0, res["scale_ppm"], 2)
    eps = rng.normal(0.0, res["gyro_bias_deg_h"], 3)
    tilt = rng.normal(0.0, TILT_SIGMA_ARCSEC * ARCSEC, 2)
    az = rng.normal(0.0, res["azimuth_sigma_arcmin"] * 60 * ARCSEC)
    # levelled by the alignment: the tilt balances the bias (phi_y = k0x, phi_x = -k0y)
    phi0 = np.array([-k0[1] * 1e-6 + tilt[0], k0[0] * 1e-6 + tilt[1], az])
    return k0, sk, eps, phi0


def coeff_vector(study: Study, platform: str) -> np.ndarray:
    c = study.platforms[platform]
    return np.array([c["kA_x"], c["k2_x"], c["kA_y"], c["k2_y"]], dtype=float)


def simulate_batch(study: Study, platform: str, run: str, seeds, replicates=None, keep_phi: bool = False,
                   noise_free: bool = False) -> RunBatch:
    """Simulate ``run`` of ``platform`` for every replicate SeedSequence of ``seeds`` (§2-§5, §8, §9);
    ``replicates``: their numbers (``RunBatch.seeds``; 0, 1, ... by default).

    ``noise_free``: no drawn residual and no noise (truth coefficients only).
    """
    streams = [run_streams(s, study.platform_index(platform), study.run_index(platform, run)) for s in seeds]
    seeds = np.arange(len(streams)) if replicates is None else np.asarray(replicates, dtype=np.int64)
    prof = build_profile(study, platform, run)
    kin = kinematics(prof, study.centrifuge)
    n = prof.t.size
    dt = prof.dt
    lat = np.radians(study.latitude_deg)
    sl, cl, tl = np.sin(lat), np.cos(lat), np.tan(lat)
    res = study.residuals
    coeffs = coeff_vector(study, platform)
    s_acc = res["accel_noise_ug_rthz"] * 1e-6 * G0 / np.sqrt(dt)
    s_gyro = res["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(dt)
    nseed = seeds.size
    err = np.empty((nseed, n, 4))
    phi = np.empty((nseed, n, 3)) if keep_phi else None
    v_ind = np.empty((nseed, n, 2))
    p_ind = np.empty((nseed, n, 2))
    psi = np.empty((nseed, n))
    dr = {k: np.zeros((nseed, m)) for k, m in (("k0", 2), ("sk", 2), ("eps", 3), ("phi0", 3))}
    none2 = np.zeros((0, 2))
    none3 = np.zeros((0, 3))
    nophi = np.zeros((0, 3))
    for i, (param_seed, noise_seed) in enumerate(streams):
        if noise_free:
            k0, sk, eps, phi0 = np.zeros(2), np.zeros(2), np.zeros(3), np.zeros(3)
        else:
            k0, sk, eps, phi0 = draw_params(study, np.random.default_rng(param_seed))
        for key, val in (("k0", k0), ("sk", sk), ("eps", eps), ("phi0", phi0)):
            dr[key][i] = val
        coef = np.concatenate([k0, sk, coeffs]) * 1e-6
        x0 = np.concatenate([np.zeros(4), phi0])
        if noise_free:
            acc_w, gyro_w = none2, none3
        else:
            rng = np.random.default_rng(noise_seed)
            acc_w = rng.standard_normal((n, 2)) * s_acc
            gyro_w = rng.standard_normal((n, 3)) * s_gyro
        _integrate(dt, kin.f, coef, eps * DEG_H, x0, acc_w, gyro_w, sl, cl, tl, err[i],
                   phi[i] if keep_phi else nophi)
        v_ind[i] = kin.v + err[i, :, :2]
        p_ind[i] = kin.p - kin.p[0] + err[i, :, 2:]
        psi[i] = kin.theta
        if not noise_free:
            v_ind[i] += rng.standard_normal((n, 2)) * res["velocity_noise_m_s"]
            p_ind[i] += rng.standard_normal((n, 2)) * res["position_noise_m"]
            psi[i] += rng.standard_normal(n) * res["heading_noise_arcsec"] * ARCSEC
    sens = np.empty((VARIANTS, n, 4))
    for j in range(VARIANTS):
        coef = np.zeros(8)
        coef[4 + j] = 1e-6
        _integrate(dt, kin.f, coef, np.zeros(3), np.zeros(7), none2, none3, sl, cl, tl, sens[j], nophi)
    draws = Draws(k0_ug=dr["k0"], scale_ppm=dr["sk"], drift_deg_h=dr["eps"], phi0_rad=dr["phi0"])
    return RunBatch(platform=platform, run=run, seeds=seeds, coeffs=coeffs, prof=prof, kin=kin, draws=draws,
                    err=err, phi=phi, sens=sens, v_ind=v_ind, p_ind=p_ind, psi=psi)
