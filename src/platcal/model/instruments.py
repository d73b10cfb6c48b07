"""Gyro and accelerometer error models of a three-gyro, three-accelerometer platform
(docs/centrifuge-model.md §4-5).

One source for every rig and every kernel: the scalar helpers (:func:`gyro_axis_components`,
:func:`gyro_drift_scalar`, :func:`gyro_drift_slopes`, :func:`accel_axes`, :func:`accel_one`,
:func:`accel_slopes`) hold the error terms; the array kernels (:func:`gyro_drift_into`,
:func:`accel_output_into`) and the rigs' own fast scalar kernels call them.

The *full coefficient vector* has 48 entries: the 45 identified coefficients in the order of
the paper's results table (``DF_x`` ... ``theta_oz``), then ``DOO_x, DOO_y, DOO_z`` which the
truth may carry but the paper's filter does not identify (eqs. 19-22). Units are those of the
paper's results table: gyro terms in deg/h, deg/h/g, deg/h/g^2; accelerometer terms in ug,
ug/g, ug/g^2, ug/g^3; misalignments in arcsec. Specific force arguments ``f`` are in g.
"""

from __future__ import annotations

import numpy as np
from ..jit import njit

from .frames import ARCSEC

AXES = ("x", "y", "z")
GYRO_TERMS = ("DF", "DI", "DO", "DS", "DII", "DSS", "DIO", "DIS", "DOS")
ACCEL_TERMS = ("k0", "k1", "k2", "k3", "kIP")
MISALIGNMENTS = ("theta_py", "theta_pz", "theta_oz")

N_IDENTIFIED = 45
N_FULL = 48
I_DOO = 45  # DOO_x; DOO_y, DOO_z follow
I_K0 = 27  # first accelerometer coefficient
I_THETA = 42  # theta_py, theta_pz, theta_oz

UG = 1e-6
"""One micro-g in g."""

_UNITS = {
    "DF": "deg/h", "DI": "deg/h/g", "DO": "deg/h/g", "DS": "deg/h/g",
    "DII": "deg/h/g^2", "DSS": "deg/h/g^2", "DIO": "deg/h/g^2", "DIS": "deg/h/g^2",
    "DOS": "deg/h/g^2", "DOO": "deg/h/g^2",
    "k0": "ug", "k1": "ug/g", "k2": "ug/g^2", "k3": "ug/g^3", "kIP": "ug/g^2",
}

# Gyro input (I), output (O) and spin (S) axes in p, one 3x3 matrix per gyro (docs/centrifuge-model.md §4,
# eqs. 4-6 with the gyro misalignments zero).
GYRO_AXES = np.array(
    [
        [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
        [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]],
        [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    ]
)


def _names() -> tuple[str, ...]:
    gyro = [f"{t}_{a}" for t in GYRO_TERMS for a in AXES]
    accel = [f"{t}_{a}" for t in ACCEL_TERMS for a in AXES]
    return tuple(gyro + accel + list(MISALIGNMENTS) + [f"DOO_{a}" for a in AXES])


FULL_NAMES: tuple[str, ...] = _names()
"""The 48 coefficient names: the 45 identified ones, then DOO_x, DOO_y, DOO_z."""
NAMES: tuple[str, ...] = FULL_NAMES[:N_IDENTIFIED]
"""The 45 identified coefficients (DF_x ... theta_oz), in the paper's order."""
INDEX = {n: i for i, n in enumerate(FULL_NAMES)}


def unit_of(name: str) -> str:
    """Engineering unit of a coefficient name (``'deg/h'``, ``'ug/g'``, ``'arcsec'`` ...)."""
    if name.startswith("theta_"):
        return "arcsec"
    return _UNITS[name.rsplit("_", 1)[0]]


def group_of(name: str) -> str:
    """``'gyro'`` or ``'accel'``: the instrument a coefficient belongs to."""
    return "gyro" if name.startswith("D") else "accel"


def term_of(name: str) -> str:
    """The error term without its axis (``'DIS_x'`` -> ``'DIS'``; ``'theta_py'`` -> ``'theta'``)."""
    return "theta" if name.startswith("theta_") else name.rsplit("_", 1)[0]


@njit(cache=True)
def gyro_axis_components(j, f0, f1, f2):
    """Specific force (g) along gyro j's input, output and spin axes: ``(aI, aO, aS)``."""
    aI = GYRO_AXES[j, 0, 0] * f0 + GYRO_AXES[j, 0, 1] * f1 + GYRO_AXES[j, 0, 2] * f2
    aO = GYRO_AXES[j, 1, 0] * f0 + GYRO_AXES[j, 1, 1] * f1 + GYRO_AXES[j, 1, 2] * f2
    aS = GYRO_AXES[j, 2, 0] * f0 + GYRO_AXES[j, 2, 1] * f1 + GYRO_AXES[j, 2, 2] * f2
    return aI, aO, aS


@njit(cache=True)
def gyro_drift_terms(D, DI, DO, DS, DII, DSS, DIO, DIS, DOS, DOO, aI, aO, aS):
    """Drift of one gyro (deg/h), eqs. 11-12 (docs/centrifuge-model.md §4), from its coefficients
    (deg/h, deg/h/g, deg/h/g^2) and axis components (g): :func:`gyro_drift_scalar` with the
    coefficients as scalars (a caller looping over many gyros' coefficients is vectorised)."""
    e = DOO * (aO * aO)
    e += (D + DI * aI + DO * aO + DS * aS + DII * (aI * aI) + DSS * (aS * aS) + DIO * (aI * aO)
          + DIS * (aI * aS) + DOS * (aO * aS))
    return e


@njit(cache=True)
def gyro_drift_scalar(coef, j, aI, aO, aS):
    """Drift of gyro j (deg/h), eqs. 11-12 (docs/centrifuge-model.md §4), from its axis components (g)."""
    return gyro_drift_terms(coef[j], coef[3 + j], coef[6 + j], coef[9 + j], coef[12 + j], coef[15 + j],
                            coef[18 + j], coef[21 + j], coef[24 + j], coef[I_DOO + j], aI, aO, aS)


@njit(cache=True)
def gyro_drift_slopes(coef, j, aI, aO, aS):
    """``d eps_j / d (aI, aO, aS)`` of gyro j (deg/h/g): ``(gI, gO, gS)``."""
    DI, DO, DS = coef[3 + j], coef[6 + j], coef[9 + j]
    DII, DSS, DIO = coef[12 + j], coef[15 + j], coef[18 + j]
    DIS, DOS, DOO = coef[21 + j], coef[24 + j], coef[I_DOO + j]
    gI = DI + 2.0 * DII * aI + DIO * aO + DIS * aS
    gO = DO + 2.0 * DOO * aO + DIO * aI + DOS * aS
    gS = DS + 2.0 * DSS * aS + DIS * aI + DOS * aO
    return gI, gO, gS


@njit(cache=True)
def accel_axes_sc(j, f0, f1, f2, t_py, t_pz, t_oz):
    """:func:`accel_axes` from the misalignments theta_py, theta_pz, theta_oz (arcsec) as scalars:
    the kernels that vary the coefficients per sigma point pass them so (issue 22)."""
    if j == 0:
        return f0, f1
    if j == 1:
        return t_py * ARCSEC * f0 + f1, -f2
    toz = t_oz * ARCSEC
    return t_pz * ARCSEC * f0 + toz * f1 + f2, f1 - toz * f2


@njit(cache=True)
def accel_axes(coef, j, f0, f1, f2):
    """Input- and pendulous-axis specific force (g) of accelerometer j, with the misalignments
    theta_py, theta_pz, theta_oz (arcsec) of eqs. 1-3 (docs/centrifuge-model.md §5): ``(aI, aP)``."""
    return accel_axes_sc(j, f0, f1, f2, coef[I_THETA], coef[I_THETA + 1], coef[I_THETA + 2])


@njit(cache=True)
def accel_out(k0, k1, k2, k3, kip, aI, aP):
    """Output (g) of an accelerometer with coefficients k0 (ug), k1 (ug/g), k2 (ug/g^2), k3 (ug/g^3),
    kIP (ug/g^2) from its input- and pendulous-axis specific force (g), eq. 13 (docs/centrifuge-model.md §5)."""
    return UG * k0 + (1.0 + UG * k1) * aI + UG * k2 * aI * aI + UG * k3 * aI * aI * aI \
        + UG * kip * aI * aP


@njit(cache=True)
def accel_one(coef, j, aI, aP):
    """Output of accelerometer j (g) from its input- and pendulous-axis specific force (g), eq. 13."""
    return accel_out(coef[I_K0 + j], coef[I_K0 + 3 + j], coef[I_K0 + 6 + j], coef[I_K0 + 9 + j],
                     coef[I_K0 + 12 + j], aI, aP)


@njit(cache=True)
def accel_slopes(coef, j, aI, aP):
    """``d out_j / d (aI, aP)`` of accelerometer j (dimensionless): ``(gI, gP)``."""
    k1 = coef[I_K0 + 3 + j]
    k2 = coef[I_K0 + 6 + j]
    k3 = coef[I_K0 + 9 + j]
    kip = coef[I_K0 + 12 + j]
    gI = 1.0 + UG * (k1 + 2.0 * k2 * aI + 3.0 * k3 * aI * aI + kip * aP)
    gP = UG * kip * aI
    return gI, gP


@njit(cache=True, inline="always")
def gyro_regressors_into(aI, aO, aS, out):
    """The ten regressors of a gyro's drift, eqs. 11-12 (docs/centrifuge-model.md §4), from its
    axis components (g): ``out = [1, aI, aO, aS, aI^2, aS^2, aI aO, aI aS, aO aS, aO^2]``."""
    out[0] = 1.0
    out[1] = aI
    out[2] = aO
    out[3] = aS
    out[4] = aI * aI
    out[5] = aS * aS
    out[6] = aI * aO
    out[7] = aI * aS
    out[8] = aO * aS
    out[9] = aO * aO


@njit(cache=True)
def gyro_drift_into(coef, f, eps, deps_df, reg):
    """Drift of the three gyros, eqs. 11-12 (docs/centrifuge-model.md §4).

    Parameters
    ----------
    coef : (48,) full coefficient vector (deg/h, deg/h/g, deg/h/g^2).
    f : (3,) specific force on the platform in p, in g.
    eps : (3,) out, drift of gyros x, y, z in deg/h.
    deps_df : (3, 3) out, ``d eps_j / d f_k`` in deg/h/g.
    reg : (3, 10) out, the regressors of gyro j: ``[1, aI, aO, aS, aI^2, aS^2, aI aO, aI aS,
        aO aS, aO^2]``; term m < 9 multiplies ``coef[3 m + j]``, term 9 (DOO) ``coef[45 + j]``.
    """
    for j in range(3):
        aI, aO, aS = gyro_axis_components(j, f[0], f[1], f[2])
        gyro_regressors_into(aI, aO, aS, reg[j])
        eps[j] = gyro_drift_scalar(coef, j, aI, aO, aS)
        gI, gO, gS = gyro_drift_slopes(coef, j, aI, aO, aS)
        for k in range(3):
            deps_df[j, k] = gI * GYRO_AXES[j, 0, k] + gO * GYRO_AXES[j, 1, k] + gS * GYRO_AXES[j, 2, k]


@njit(cache=True)
def gyro_drift(coef, f):
    """Drift of gyros x, y, z in deg/h for the platform specific force ``f`` (g), eqs. 11-12."""
    eps = np.empty(3)
    gyro_drift_into(coef, f, eps, np.empty((3, 3)), np.empty((3, 10)))
    return eps


@njit(cache=True)
def accel_output_into(coef, f, out, h_coef, dA_df):
    """Accelerometer outputs, eqs. 1-3 and 13 (docs/centrifuge-model.md §5).

    Parameters
    ----------
    coef : (48,) full coefficient vector (ug, ug/g, ug/g^2, ug/g^3, arcsec).
    f : (3,) specific force on the platform in p, in g.
    out : (3,) out, outputs of accelerometers x, y, z in g (noise-free).
    h_coef : (3, 48) out, ``d out_j / d coef`` in g per coefficient unit.
    dA_df : (3, 3) out, ``d out_j / d f_k`` (dimensionless).
    """
    for j in range(3):
        for i in range(coef.shape[0]):
            h_coef[j, i] = 0.0
    tpy = coef[I_THETA] * ARCSEC
    tpz = coef[I_THETA + 1] * ARCSEC
    toz = coef[I_THETA + 2] * ARCSEC
    for j in range(3):
        aI, aP = accel_axes(coef, j, f[0], f[1], f[2])
        out[j] = accel_one(coef, j, aI, aP)
        h_coef[j, I_K0 + j] = UG
        h_coef[j, I_K0 + 3 + j] = UG * aI
        h_coef[j, I_K0 + 6 + j] = UG * aI * aI
        h_coef[j, I_K0 + 9 + j] = UG * aI * aI * aI
        h_coef[j, I_K0 + 12 + j] = UG * aI * aP
        gI, gP = accel_slopes(coef, j, aI, aP)
        if j == 0:
            dA_df[0, 0] = gI
            dA_df[0, 1] = gP
            dA_df[0, 2] = 0.0
        elif j == 1:
            dA_df[1, 0] = gI * tpy
            dA_df[1, 1] = gI
            dA_df[1, 2] = -gP
            h_coef[1, I_THETA] = gI * f[0] * ARCSEC
        else:
            dA_df[2, 0] = gI * tpz
            dA_df[2, 1] = gI * toz + gP
            dA_df[2, 2] = gI - gP * toz
            h_coef[2, I_THETA + 1] = gI * f[0] * ARCSEC
            h_coef[2, I_THETA + 2] = (gI * f[1] - gP * f[2]) * ARCSEC


@njit(cache=True)
def accel_output(coef, f):
    """Outputs of accelerometers x, y, z in g for the platform specific force ``f`` (g), eq. 13."""
    out = np.empty(3)
    accel_output_into(coef, f, out, np.empty((3, coef.shape[0])), np.empty((3, 3)))
    return out


def accel_outputs(coef: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(N, 3) g: the noise-free outputs of accelerometers x, y, z for the specific forces ``f``
    (N, 3) in p, g, and the full coefficient vector ``coef`` (48,), eqs. 1-3 and 13
    (docs/centrifuge-model.md §5); the scalar helpers applied to whole columns."""
    coef = np.asarray(coef, float)
    f = np.asarray(f, float)
    out = np.empty_like(f)
    for j in range(3):
        aI, aP = accel_axes(coef, j, f[:, 0], f[:, 1], f[:, 2])
        out[:, j] = accel_one(coef, j, aI, aP)
    return out


def gyro_drifts(coef: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(N, 3) deg/h: the drift of gyros x, y, z at the specific forces ``f`` (N, 3) in p, g, with
    the full coefficient vector ``coef`` (48,), eqs. 11-12 (docs/centrifuge-model.md §4); the
    scalar helpers applied to whole columns."""
    coef = np.asarray(coef, float)
    f = np.asarray(f, float)
    out = np.empty_like(f)
    for j in range(3):
        aI, aO, aS = gyro_axis_components(j, f[:, 0], f[:, 1], f[:, 2])
        out[:, j] = gyro_drift_scalar(coef, j, aI, aO, aS)
    return out


def compensate_accelerometers(A: np.ndarray, coef: np.ndarray, iterations: int = 10) -> np.ndarray:
    """(N, 3) g: the specific force in p whose outputs with ``coef`` (48,) are the measured ``A``
    (N, 3) g, i.e. the error-free accelerometer outputs (docs/centrifuge-model.md §5). Solved by
    fixed-point iteration f <- f + (A - outputs(f)): the model departs from the identity by about
    1e-3 (scale, misalignment, nonlinearity at tens of g), so each pass gains about three digits."""
    A = np.asarray(A, float)
    f = A.copy()
    for _ in range(iterations):
        f = f + (A - accel_outputs(coef, f))
    return f
