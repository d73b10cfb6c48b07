"""Sensor error model and its random draws (docs/rocket-sled.md §3), batched over seeds.

Accelerometers ``f̃ = (I + M) f + diag(s) f + b_a + k2 ∘ f² + w_a``; gyros
``ω̃ = ω + b_g + G_s f + w_g``; initial attitude error φ0 (rad, rotation vector in l).

Seeding (docs/rocket-sled.md §3, §12): replicate r draws from one ``numpy.random.Generator`` on
the Monte Carlo runner's ``SeedSequence`` (:func:`platcal.study.sweep.replicate_seed`, keyed
by the root seed, the case, the noise level and r), so a replicate's numbers never depend on the
batch it runs in. Draw order: errors b_a(3), s(3), k2(3), M off-diagonal (6: xy, xz, yx, yz, zx,
zy), b_g(3), G_s(3×3 row-major), φ0(3); then noise: accelerometer (N×3), then gyro (N×3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import ARCSEC, DEG_H, G, SledConfig

OFFDIAG = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""(row, column) of the six misalignment terms, in draw order."""


@dataclass(frozen=True)
class ErrorParams:
    """Drawn error parameters, SI units, leading axis = seed (S)."""

    bias_a: np.ndarray     # (S,3) m/s^2
    scale: np.ndarray      # (S,3) dimensionless
    k2: np.ndarray         # (S,3) 1/(m/s^2)
    M: np.ndarray          # (S,3,3) rad, zero diagonal
    bias_g: np.ndarray     # (S,3) rad/s
    g_sens: np.ndarray     # (S,3,3) rad/s per m/s^2
    phi0: np.ndarray       # (S,3) rad

    def to_json(self, s: int) -> dict:
        """Seed slot ``s`` in engineering units (the record's side file)."""
        return {
            "phi0_arcsec": (self.phi0[s] / ARCSEC).tolist(),
            "accel_bias_ug": (self.bias_a[s] / G * 1e6).tolist(),
            "accel_scale_ppm": (self.scale[s] * 1e6).tolist(),
            "accel_k2_ug_g2": (self.k2[s] * G * 1e6).tolist(),
            "accel_misalign_arcsec": (self.M[s] / ARCSEC).tolist(),
            "gyro_bias_deg_h": (self.bias_g[s] / DEG_H).tolist(),
            "gyro_g_sens_deg_h_g": (self.g_sens[s] / DEG_H * G).tolist(),
        }

    @staticmethod
    def from_json(items: list[dict]) -> "ErrorParams":
        """Inverse of :meth:`to_json` for a list of seeds."""
        def arr(key, scale):
            return np.array([np.asarray(d[key], dtype=float) for d in items]) * scale
        return ErrorParams(bias_a=arr("accel_bias_ug", G * 1e-6), scale=arr("accel_scale_ppm", 1e-6),
                           k2=arr("accel_k2_ug_g2", 1e-6 / G), M=arr("accel_misalign_arcsec", ARCSEC),
                           bias_g=arr("gyro_bias_deg_h", DEG_H), g_sens=arr("gyro_g_sens_deg_h_g", DEG_H / G),
                           phi0=arr("phi0_arcsec", ARCSEC))


def draw_errors(cfg: SledConfig, rngs) -> ErrorParams:
    """Error parameters of §3 (1 sigma from the config), one replicate per generator of ``rngs``
    (drawn first from each: :func:`draw_noise` continues the same streams)."""
    a, gy = cfg.accel, cfg.gyro
    out = {k: [] for k in ("bias_a", "scale", "k2", "M", "bias_g", "g_sens", "phi0")}
    for rng in rngs:
        out["bias_a"].append(rng.standard_normal(3) * a["bias_ug"] * 1e-6 * G)
        out["scale"].append(rng.standard_normal(3) * a["scale_ppm"] * 1e-6)
        out["k2"].append(rng.standard_normal(3) * a["k2_ug_g2"] * 1e-6 / G)
        m = np.zeros((3, 3))
        for (i, j), e in zip(OFFDIAG, rng.standard_normal(6)):
            m[i, j] = e * a["misalign_arcsec"] * ARCSEC
        out["M"].append(m)
        out["bias_g"].append(rng.standard_normal(3) * gy["bias_deg_h"] * DEG_H)
        out["g_sens"].append(rng.standard_normal((3, 3)) * gy["g_sens_deg_h_g"] * DEG_H / G)
        out["phi0"].append(rng.standard_normal(3) * np.asarray(cfg.alignment_arcsec) * ARCSEC)
    return ErrorParams(**{k: np.array(v) for k, v in out.items()})


def draw_noise(cfg: SledConfig, rngs, n: int) -> tuple[np.ndarray, np.ndarray]:
    """White noise per IMU sample (S,N,3): accelerometer (m/s^2) and gyro (rad/s), one replicate
    per generator of ``rngs`` (after :func:`draw_errors`).

    Per-sample sigma: ``noise_ug_rthz·1e-6·g·sqrt(1/dt)`` and ``arw (rad/sqrt(s)) / sqrt(dt)``.
    """
    sa, sg = noise_sigmas(cfg)
    wa, wg = [], []
    for rng in rngs:
        wa.append(rng.standard_normal((n, 3)) * sa)
        wg.append(rng.standard_normal((n, 3)) * sg)
    return np.array(wa), np.array(wg)


def noise_sigmas(cfg: SledConfig) -> tuple[float, float]:
    """Per-sample white-noise sigmas of :func:`draw_noise`: accelerometer (m/s^2), gyro (rad/s)."""
    return (cfg.accel["noise_ug_rthz"] * 1e-6 * G * np.sqrt(1.0 / cfg.dt),
            cfg.gyro["arw_deg_rth"] * np.pi / 180 / 60 / np.sqrt(cfg.dt))


def accel_error(p: ErrorParams, f: np.ndarray) -> np.ndarray:
    """Deterministic accelerometer error ``M f + s∘f + b + k2∘f²`` (S,N,3) for true f (N,3)."""
    return (np.einsum("sij,nj->sni", p.M, f) + p.scale[:, None, :] * f + p.bias_a[:, None, :]
            + p.k2[:, None, :] * f ** 2)


def gyro_error(p: ErrorParams, f: np.ndarray) -> np.ndarray:
    """Deterministic gyro error ``b_g + G_s f`` (S,N,3), rad/s."""
    return p.bias_g[:, None, :] + np.einsum("sij,nj->sni", p.g_sens, f)


def measure(p: ErrorParams, f: np.ndarray, w: np.ndarray, wa: np.ndarray, wg: np.ndarray):
    """Erroneous IMU samples ``f̃, ω̃`` (S,N,3) from the truth and the drawn errors (§3)."""
    return f + accel_error(p, f) + wa, w + gyro_error(p, f) + wg
