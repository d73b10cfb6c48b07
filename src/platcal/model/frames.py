"""Frames, elementary rotations and Euler kinematics (docs/centrifuge-model.md §3; paper eqs. 7, 14, 15).

All angles are in radians. Rotations are *passive* (frame) rotations: ``v_new = M v_old``.
The platform attitude is ``C_r^p = Mz(gamma) My(beta) Mx(alpha)`` (the z-y-x order the spec
chooses over the misprinted eq. 7). Every function is compiled with numba so the simulator
and the filter kernels can call it; each is also callable from Python on scalars.
"""

from __future__ import annotations

import numpy as np
from ..jit import njit

ARCSEC = np.pi / (180.0 * 3600.0)
"""One arc second in radians."""
DEG = np.pi / 180.0
"""One degree in radians."""
DEG_PER_HOUR = np.pi / (180.0 * 3600.0)
"""One deg/h in rad/s."""


@njit(cache=True)
def rot_x(a):
    """Elementary passive rotation about x, ``Mx(a)`` (a in rad)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


@njit(cache=True)
def rot_y(b):
    """Elementary passive rotation about y, ``My(b)`` (b in rad)."""
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


@njit(cache=True)
def rot_z(g):
    """Elementary passive rotation about z, ``Mz(g)`` (g in rad)."""
    c, s = np.cos(g), np.sin(g)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


@njit(cache=True)
def c_rp_sc_into(sa, ca, sb, cb, sg, cg, C, dC, want_d):
    """:func:`c_rp_into` from the angles' sines and cosines (``sa = sin(alpha)``, ...), for a
    kernel that shares them with :func:`euler_t_sc_into`; ``dC`` only with ``want_d``."""
    C[0, 0] = cg * cb
    C[0, 1] = cg * sb * sa + sg * ca
    C[0, 2] = -cg * sb * ca + sg * sa
    C[1, 0] = -sg * cb
    C[1, 1] = -sg * sb * sa + cg * ca
    C[1, 2] = sg * sb * ca + cg * sa
    C[2, 0] = sb
    C[2, 1] = -cb * sa
    C[2, 2] = cb * ca
    if not want_d:
        return
    # d/d alpha
    dC[0, 0, 0] = 0.0
    dC[0, 0, 1] = cg * sb * ca - sg * sa
    dC[0, 0, 2] = cg * sb * sa + sg * ca
    dC[0, 1, 0] = 0.0
    dC[0, 1, 1] = -sg * sb * ca - cg * sa
    dC[0, 1, 2] = -sg * sb * sa + cg * ca
    dC[0, 2, 0] = 0.0
    dC[0, 2, 1] = -cb * ca
    dC[0, 2, 2] = -cb * sa
    # d/d beta
    dC[1, 0, 0] = -cg * sb
    dC[1, 0, 1] = cg * cb * sa
    dC[1, 0, 2] = -cg * cb * ca
    dC[1, 1, 0] = sg * sb
    dC[1, 1, 1] = -sg * cb * sa
    dC[1, 1, 2] = sg * cb * ca
    dC[1, 2, 0] = cb
    dC[1, 2, 1] = sb * sa
    dC[1, 2, 2] = -sb * ca
    # d/d gamma
    dC[2, 0, 0] = -sg * cb
    dC[2, 0, 1] = -sg * sb * sa + cg * ca
    dC[2, 0, 2] = sg * sb * ca + cg * sa
    dC[2, 1, 0] = -cg * cb
    dC[2, 1, 1] = -cg * sb * sa - sg * ca
    dC[2, 1, 2] = cg * sb * ca - sg * sa
    dC[2, 2, 0] = 0.0
    dC[2, 2, 1] = 0.0
    dC[2, 2, 2] = 0.0


@njit(cache=True)
def c_rp_into(alpha, beta, gamma, C, dC):
    """Fill ``C = C_r^p(alpha, beta, gamma)`` and its partials ``dC[i] = dC/d(angle_i)``.

    Closed form of ``Mz(gamma) My(beta) Mx(alpha)`` (docs/centrifuge-model.md §3). ``C`` is (3, 3),
    ``dC`` is (3, 3, 3) with the angle index first (alpha, beta, gamma). Angles in rad.
    """
    c_rp_sc_into(np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta), np.sin(gamma), np.cos(gamma), C, dC,
                 True)


@njit(cache=True)
def c_rp(alpha, beta, gamma):
    """``C_r^p = Mz(gamma) My(beta) Mx(alpha)`` (3, 3); angles in rad (docs/centrifuge-model.md §3)."""
    C = np.empty((3, 3))
    dC = np.empty((3, 3, 3))
    c_rp_into(alpha, beta, gamma, C, dC)
    return C


@njit(cache=True)
def euler_e(beta, gamma):
    """``E(beta, gamma)`` of eq. 14: ``w_rp^p = E [alpha', beta', gamma']`` (rad, rad/s)."""
    sb, cb = np.sin(beta), np.cos(beta)
    sg, cg = np.sin(gamma), np.cos(gamma)
    return np.array([[cb * cg, sg, 0.0], [-cb * sg, cg, 0.0], [sb, 0.0, 1.0]])


@njit(cache=True)
def euler_t_sc_into(sb, cb, sg, cg, T, dT, want_d):
    """:func:`euler_t_into` from the sines and cosines of beta and gamma; ``dT`` only with ``want_d``."""
    ib = 1.0 / cb
    tb = sb * ib
    T[0, 0] = cg * ib
    T[0, 1] = -sg * ib
    T[0, 2] = 0.0
    T[1, 0] = sg
    T[1, 1] = cg
    T[1, 2] = 0.0
    T[2, 0] = -tb * cg
    T[2, 1] = tb * sg
    T[2, 2] = 1.0
    if not want_d:
        return
    for r in range(3):
        for c in range(3):
            dT[0, r, c] = 0.0
    # d/d beta: d(1/cb) = tb/cb, d(tb) = 1/cb^2
    dT[1, 0, 0] = cg * tb * ib
    dT[1, 0, 1] = -sg * tb * ib
    dT[1, 0, 2] = 0.0
    dT[1, 1, 0] = 0.0
    dT[1, 1, 1] = 0.0
    dT[1, 1, 2] = 0.0
    dT[1, 2, 0] = -cg * ib * ib
    dT[1, 2, 1] = sg * ib * ib
    dT[1, 2, 2] = 0.0
    # d/d gamma
    dT[2, 0, 0] = -sg * ib
    dT[2, 0, 1] = -cg * ib
    dT[2, 0, 2] = 0.0
    dT[2, 1, 0] = cg
    dT[2, 1, 1] = -sg
    dT[2, 1, 2] = 0.0
    dT[2, 2, 0] = tb * sg
    dT[2, 2, 1] = tb * cg
    dT[2, 2, 2] = 0.0


@njit(cache=True)
def euler_t_into(beta, gamma, T, dT):
    """Fill ``T = E^-1`` (eq. 15, exact inverse) and ``dT[i] = dT/d(angle_i)``.

    ``dT[0]`` (alpha) is zero. Singular at beta = +-90 deg; callers reject such schemes.
    """
    euler_t_sc_into(np.sin(beta), np.cos(beta), np.sin(gamma), np.cos(gamma), T, dT, True)


@njit(cache=True)
def euler_t(beta, gamma):
    """``T(beta, gamma) = E^-1`` (3, 3) of eq. 15: Euler-angle rates from ``w_rp^p``."""
    T = np.empty((3, 3))
    dT = np.empty((3, 3, 3))
    euler_t_into(beta, gamma, T, dT)
    return T
