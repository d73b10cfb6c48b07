"""The centrifuge: site constants and the specific force on the platform base (docs/centrifuge-model.md §1-2).

The base frame r is kept aligned with the local East-North-Up frame n by the counter-rotating
table, so the Earth rate in r is ``[0, Omega cos L, Omega sin L]`` (rad/s) and the specific
force is eq. 10 with the vertical sign decided by the spec (``+g`` in ENU).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from ...jit import njit

from .attitude import P_G, P_OMEGA_N, P_OMEGA_U

# Indices into the packed parameter vector the kernels take (see Centrifuge.params()): the
# centrifuge's own slots before the site constants of platcal.rigs.centrifuge.attitude.
P_RATE, P_RADIUS = 0, 1


@dataclass(frozen=True)
class Centrifuge:
    """A centrifuge at a test site.

    Attributes
    ----------
    rate_deg_s : centrifuge rate w_c, deg/s (0: the centrifuge is off, a static 1 g test).
    g_level : centripetal level ``w_c^2 r_o / g`` that sets the arm radius r_o (dimensionless).
    latitude_deg : site latitude L, deg.
    g : gravity magnitude, m/s^2; also the unit "g" of every coefficient.
    earth_rate : Earth rate Omega, rad/s.
    """

    rate_deg_s: float = 180.0
    g_level: float = 10.0
    latitude_deg: float = 28.2
    g: float = 9.80665
    earth_rate: float = 7.2921151467e-5

    @property
    def rate(self) -> float:
        """w_c in rad/s."""
        return np.deg2rad(self.rate_deg_s)

    @property
    def arm_radius(self) -> float:
        """r_o in m, chosen so that ``w_c^2 r_o = g_level g`` (0 when the centrifuge is off)."""
        if self.rate == 0.0:
            return 0.0
        return self.g_level * self.g / self.rate**2

    @property
    def earth_rate_n(self) -> np.ndarray:
        """Earth rate in n (and r), ``[0, Omega_N, Omega_U]``, rad/s."""
        lat = np.deg2rad(self.latitude_deg)
        return np.array([0.0, self.earth_rate * np.cos(lat), self.earth_rate * np.sin(lat)])

    def params(self, g_level: float | None = None) -> np.ndarray:
        """Packed ``[w_c (rad/s), r_o (m), g (m/s^2), Omega_N, Omega_U (rad/s)]`` for the kernels.

        ``g_level`` overrides the centripetal level (a position of a multi-g-level scheme).
        """
        c = self if g_level is None else replace(self, g_level=float(g_level))
        w = self.earth_rate_n
        return np.array([c.rate, c.arm_radius, c.g, w[1], w[2]])

    def scheme_params(self, scheme) -> np.ndarray:
        """(K, 5) packed parameters per position of ``scheme`` (its ``g_levels`` if any)."""
        levels = scheme.g_levels or (None,) * scheme.n_positions
        return np.stack([self.params(g) for g in levels])


@njit(cache=True, inline="always")
def specific_force_into(t, params, out):
    """Specific force on the base in r, eq. 10 (m/s^2), at ``t`` s since the position's start."""
    wc = params[P_RATE]
    ro = params[P_RADIUS]
    amp = wc * wc * ro + 2.0 * wc * ro * params[P_OMEGA_U]
    c, s = np.cos(wc * t), np.sin(wc * t)
    out[0] = -amp * c
    out[1] = -amp * s
    out[2] = 2.0 * wc * ro * params[P_OMEGA_N] * s + params[P_G]


@njit(cache=True)
def specific_force(t, params):
    """Specific force on the base in r, eq. 10 (m/s^2); ``params`` from ``Centrifuge.params()``."""
    out = np.empty(3)
    specific_force_into(t, params, out)
    return out


def broadcast_params(params, B: int, K: int) -> np.ndarray:
    """Packed centrifuge parameters as (B, K, 5) from (5,), (K, 5) or (B, K, 5): always a
    writable copy. (``ascontiguousarray`` of the broadcast returned the read-only view itself
    when no copy was needed, a batch of one, and numba compiled every kernel taking it twice,
    once per writeability: about 2x the centrifuge's cold compile in a study.)"""
    p = np.asarray(params, float)
    if p.ndim == 1:
        p = p[None, None, :]
    elif p.ndim == 2:
        p = p[None]
    return np.array(np.broadcast_to(p, (B, K, p.shape[-1])), order="C")
