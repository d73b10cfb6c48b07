"""The 1 g multi-position model: layout, error-angle dynamics and 6-D measurement.

docs/multiposition-1g.md §2-7 (and §13 for the extended layout). The base is fixed to the
Earth: ``f^n = [0, 0, g]`` (ENU, up), ``w_ie^n = [0, Omega cos L, Omega sin L]``;
``C_n^p = Mz(gamma) My(beta) Mx(alpha)`` and ``T = E^-1`` come from :mod:`platcal.frames`
(the centrifuge's rotations, docs/centrifuge-model.md §3), the gyro I/O/S axes from
:mod:`platcal.instruments` (CM §4).

State ``x = [phi (3, rad); c (nc)]``: the platform error angles (gimbal angles minus the
command ``phi0``), then the coefficients in engineering units, in the order of
:func:`coef_names` (§15): ``DF, DI, DS, DO, k0, k1, theta_p, theta_o`` each x, y, z (24); the
§13 extension appends ``DII, DSS, DIO, DIS, DOS, [DOO], k2, k3, kIP`` (51 or 54 states).

Units: drift deg/h (deg/h/g, deg/h/g^2); accelerometer outputs in ug in the model (the record
stores g); k0 ug, k1 ug/g, k2 ug/g^2, k3 ug/g^3, kIP ug/g^2, theta arcsec; angle-sensor outputs
in arcsec; phi in rad, phi' in rad/s.

Kernels are numba-compiled scalar code on one replicate (the batched simulator and EKF call
them in loops over replicates); every kernel also returns its analytic Jacobian.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...jit import njit
from ...model.frames import ARCSEC, DEG_PER_HOUR, c_rp_into, c_rp_sc_into, euler_t_sc_into
from ...model.instruments import GYRO_AXES, gyro_axis_components, gyro_regressors_into
from ...model.platform import default_platform

AXES = ("x", "y", "z")
BASE_GYRO = ("DF", "DI", "DS", "DO")
BASE_ACCEL = ("k0", "k1", "theta_p", "theta_o")
EXT_GYRO = ("DII", "DSS", "DIO", "DIS", "DOS")
EXT_ACCEL = ("k2", "k3", "kIP")
ANGLE_NAMES = ("phi_x", "phi_y", "phi_z")
UG_PER_G = 1e6

UNITS = {"DF": "deg/h", "DI": "deg/h/g", "DS": "deg/h/g", "DO": "deg/h/g", "DII": "deg/h/g^2",
         "DSS": "deg/h/g^2", "DIO": "deg/h/g^2", "DIS": "deg/h/g^2", "DOS": "deg/h/g^2",
         "DOO": "deg/h/g^2", "k0": "ug", "k1": "ug/g", "k2": "ug/g^2", "k3": "ug/g^3",
         "kIP": "ug/g^2", "theta_p": "arcsec", "theta_o": "arcsec"}

# Nominal accelerometer axes in p, rows I0, P0, O0 (docs/multiposition-1g.md §6).
ACCEL_AXES = np.array([
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]],
    [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
])

# Truth (§10), deg/h, deg/h/g, ug, ug/g, arcsec; extension from CM Table 2 (DOO = 0).
BASE_TRUTH = {
    "DF": (7.370, 7.821, 1.654), "DI": (1.083, 1.023, 0.933), "DS": (1.083, 1.023, 0.933),
    "DO": (1.083, 1.023, 0.933), "k0": (3500.0, 4250.0, 6310.0), "k1": (160.0, 100.0, 1100.0),
    "theta_p": (120.0, 305.0, 305.0), "theta_o": (-180.0, 210.0, 260.0),
}
P0_BASE = {"DF": 10.0, "DI": 2.0, "DS": 2.0, "DO": 2.0, "k0": 1e4, "k1": 2e3, "theta_p": 600.0,
           "theta_o": 600.0}
P0_EXT = {"DII": 0.2, "DSS": 0.2, "DIO": 0.2, "DIS": 0.2, "DOS": 0.2, "DOO": 0.2, "k2": 50.0,
          "k3": 10.0, "kIP": 20.0}
"""Prior sigmas (§9 and CM §11); the config may override them."""


def ext_terms(ext: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Gyro and accelerometer terms of layout ``ext`` (0: §9's 24, 1: §13 without DOO, 2: with)."""
    if ext == 0:
        return BASE_GYRO, BASE_ACCEL
    gyro = BASE_GYRO + EXT_GYRO + (("DOO",) if ext == 2 else ())
    return gyro, BASE_ACCEL + EXT_ACCEL


def coef_terms(ext: int = 0) -> tuple[str, ...]:
    """Coefficient terms in state order (§15): base 24 first, then the §13 terms."""
    if ext == 0:
        return BASE_GYRO + BASE_ACCEL
    return BASE_GYRO + BASE_ACCEL + EXT_GYRO + (("DOO",) if ext == 2 else ()) + EXT_ACCEL


def name_of(term: str, axis: str) -> str:
    """``theta_p`` + ``x`` -> ``theta_px``; ``DI`` + ``y`` -> ``DI_y`` (§15 names)."""
    return f"{term}{axis}" if term.startswith("theta") else f"{term}_{axis}"


def coef_names(ext: int = 0) -> tuple[str, ...]:
    """The coefficient names in state order (24, 48 or 51)."""
    return tuple(name_of(t, a) for t in coef_terms(ext) for a in AXES)


def state_names(ext: int = 0) -> tuple[str, ...]:
    return ANGLE_NAMES + coef_names(ext)


def term_of(name: str) -> str:
    return name[:-1] if name.startswith("theta") else name.rsplit("_", 1)[0]


def unit_of(name: str) -> str:
    return UNITS[term_of(name)]


def group_of(name: str) -> str:
    return "gyro" if name.startswith("D") else "accel"


def layout_index(ext: int) -> np.ndarray:
    """(16,) int column of each term slot in the coefficient vector (-1: absent), axis x.

    Slots: 0-9 gyro [DF, DI, DS, DO, DII, DSS, DIO, DIS, DOS, DOO]; 10-16 accel
    [k0, k1, theta_p, theta_o, k2, k3, kIP]. Axis j adds j.
    """
    slots = ("DF", "DI", "DS", "DO", "DII", "DSS", "DIO", "DIS", "DOS", "DOO",
             "k0", "k1", "theta_p", "theta_o", "k2", "k3", "kIP")
    terms = coef_terms(ext)
    return np.array([3 * terms.index(s) if s in terms else -1 for s in slots], dtype=np.int64)


def truth_vector(ext: int = 0, overrides: dict | None = None) -> np.ndarray:
    """True coefficients (§10; §13 extension from CM Table 2, DOO = 0), then ``overrides``."""
    platform = default_platform()
    vals = {}
    for t, v in BASE_TRUTH.items():
        for a, x in zip(AXES, v):
            vals[name_of(t, a)] = x
    for t in EXT_GYRO + EXT_ACCEL:
        for a in AXES:
            vals[name_of(t, a)] = float(platform.truth[platform.index(f"{t}_{a}")])
    for a in AXES:
        vals[f"DOO_{a}"] = 0.0
    names = coef_names(ext)
    for k, v in (overrides or {}).items():
        vals[k] = float(v)
    return np.array([vals[n] for n in names])


def p0_vector(ext: int = 0, overrides: dict | None = None) -> np.ndarray:
    """Prior sigma of each coefficient (§9), by term; ``overrides`` by term name."""
    p0 = {**P0_BASE, **P0_EXT, **(overrides or {})}
    return np.array([p0[term_of(n)] for n in coef_names(ext)])


@dataclass(frozen=True)
class Site:
    """Constants of §2: latitude (deg), g (m/s^2, only a unit here) and Earth rate (rad/s)."""

    latitude_deg: float = 28.2
    earth_rate: float = 7.2921151467e-5

    def params(self, omega_on: bool = True) -> np.ndarray:
        """Packed ``[Omega_N, Omega_U]`` (rad/s); zeros for the static (Omega = 0) variant."""
        lat = np.radians(self.latitude_deg)
        w = self.earth_rate if omega_on else 0.0
        return np.array([w * np.cos(lat), w * np.sin(lat)])


# ------------------------------------------------------------------ numba kernels
#
# The kernels are inlined into their callers (the filter step, the simulator) and use numpy's
# error model (a division by zero gives inf instead of raising) because a call of a compiled
# function with array arguments pays an atomic reference-count increment and decrement per array
# (about 15 of each per rate evaluation, four evaluations per filter step), and the raise paths
# keep numba from pruning them; the arithmetic is unchanged, so are the numbers (issue 22 item 2:
# about 10 % of a multiposition filter step, benchmarks/profile_multiposition.py). Inlining alone
# does not remove the counts of an array handed on past a branch, so RK4's stages, which need no
# Jacobian, run on scalars only (rate_s, rk4_s: the same operations in the same order as rate_k,
# 3.2x faster per step's three stages). Those scalar kernels (_drift_s, rate_s, rk4_s) are plain
# calls, not inlined by numba: with no array argument there is no reference count to save, LLVM
# inlines them anyway, and numba's inlining typed and lowered a copy per call site (rk4_s holds
# three rate_s, each three _drift_s): the rig's kernels job compiled 40.7 s CPU with them inlined,
# 30.0 s without, the same numbers (issue 22 item 4; benchmarks/results_issue22_mpinline.txt).

@njit(cache=True, error_model="numpy", inline="always")
def gyro_drift_k(c, lay, f, eps, deps, greg):
    """Drift of gyros x, y, z (deg/h) at ``f`` (g, in p), §5 (+ §13 terms when in ``lay``).

    ``deps[j, k] = d eps_j / d f_k``; ``greg[j, m]`` the regressor of slot m (see
    :func:`layout_index`) so that ``d eps_j / d c[lay[m] + j] = greg[j, m]``.
    """
    for j in range(3):
        aI, aO, aS = gyro_axis_components(j, f[0], f[1], f[2])
        gyro_regressors_into(aI, aO, aS, greg[j])
        # this rig's slot order (layout_index, §5) has the spin term before the output term
        greg[j, 2] = aS
        greg[j, 3] = aO
        e = 0.0
        gI = 0.0
        gO = 0.0
        gS = 0.0
        for m in range(10):
            if lay[m] >= 0:
                k = c[lay[m] + j]
                e += k * greg[j, m]
                if m == 1:
                    gI += k
                elif m == 2:
                    gS += k
                elif m == 3:
                    gO += k
                elif m == 4:
                    gI += 2.0 * k * aI
                elif m == 5:
                    gS += 2.0 * k * aS
                elif m == 6:
                    gI += k * aO
                    gO += k * aI
                elif m == 7:
                    gI += k * aS
                    gS += k * aI
                elif m == 8:
                    gO += k * aS
                    gS += k * aO
                elif m == 9:
                    gO += 2.0 * k * aO
        eps[j] = e
        for k in range(3):
            deps[j, k] = gI * GYRO_AXES[j, 0, k] + gO * GYRO_AXES[j, 1, k] + gS * GYRO_AXES[j, 2, k]


@njit(cache=True, error_model="numpy", inline="always")
def rot_t_into(a0, a1, a2, C, dC, T, dT, want_d):
    """``C_n^p(a0, a1, a2)`` and ``T(a1, a2)`` (and, with ``want_d``, their partials ``dC``,
    ``dT``) from one evaluation of the six sines and cosines.

    The kernels of :func:`platcal.model.frames.c_rp_into` and
    :func:`~platcal.model.frames.euler_t_into` (docs/centrifuge-model.md §3, eq. 15) on one set
    of sines and cosines, because the shared trigonometry is a fifth of the cost of the rate of
    §4 with its Jacobian (once per filter step).
    """
    sa, ca = np.sin(a0), np.cos(a0)
    sb, cb = np.sin(a1), np.cos(a1)
    sg, cg = np.sin(a2), np.cos(a2)
    c_rp_sc_into(sa, ca, sb, cb, sg, cg, C, dC, want_d)
    euler_t_sc_into(sb, cb, sg, cg, T, dT, want_d)


@njit(cache=True, error_model="numpy", inline="always")
def rate_k(phi0, x, lay, wn, wu, w, rate, F, want_jac, C, dC, T, dT, f, eps, deps, greg):
    """Error-angle rate of §4, rad/s: ``phi' = -T [eps DPH + C_n^p w_ie^n + w]``.

    ``phi0`` (3,) commanded angles (rad); ``x`` state (rad, engineering units); ``w`` (3,) gyro
    white rate noise (rad/s). With ``want_jac``, ``F`` (3, n) receives ``d phi' / d x``
    (analytic; the caller zeroes its columns once: only the angle and gyro ones are written).
    The other arguments are scratch.
    """
    a0 = phi0[0] + x[0]
    a1 = phi0[1] + x[1]
    a2 = phi0[2] + x[2]
    rot_t_into(a0, a1, a2, C, dC, T, dT, want_jac)
    for r in range(3):
        f[r] = C[r, 2]
    gyro_drift_k(x[3:], lay, f, eps, deps, greg)
    u0 = eps[0] * DEG_PER_HOUR + C[0, 1] * wn + C[0, 2] * wu + w[0]
    u1 = eps[1] * DEG_PER_HOUR + C[1, 1] * wn + C[1, 2] * wu + w[1]
    u2 = eps[2] * DEG_PER_HOUR + C[2, 1] * wn + C[2, 2] * wu + w[2]
    for r in range(3):
        rate[r] = -(T[r, 0] * u0 + T[r, 1] * u1 + T[r, 2] * u2)
    if not want_jac:
        return
    for i in range(3):
        # du/d ang_i = DPH deps (dC_i[:, 2]) + dC_i[:, 1] wn + dC_i[:, 2] wu
        d0 = dC[i, 0, 2]
        d1 = dC[i, 1, 2]
        d2 = dC[i, 2, 2]
        du0 = DEG_PER_HOUR * (deps[0, 0] * d0 + deps[0, 1] * d1 + deps[0, 2] * d2) \
            + dC[i, 0, 1] * wn + dC[i, 0, 2] * wu
        du1 = DEG_PER_HOUR * (deps[1, 0] * d0 + deps[1, 1] * d1 + deps[1, 2] * d2) \
            + dC[i, 1, 1] * wn + dC[i, 1, 2] * wu
        du2 = DEG_PER_HOUR * (deps[2, 0] * d0 + deps[2, 1] * d1 + deps[2, 2] * d2) \
            + dC[i, 2, 1] * wn + dC[i, 2, 2] * wu
        for r in range(3):
            F[r, i] = -(dT[i, r, 0] * u0 + dT[i, r, 1] * u1 + dT[i, r, 2] * u2
                        + T[r, 0] * du0 + T[r, 1] * du1 + T[r, 2] * du2)
    for m in range(10):
        if lay[m] < 0:
            continue
        for j in range(3):
            col = 3 + lay[m] + j
            g = DEG_PER_HOUR * greg[j, m]
            for r in range(3):
                F[r, col] = -T[r, j] * g


@njit(cache=True, error_model="numpy", inline="always")
def meas_k(phi0, x, lay, z, H, hcols, hnnz, C, dC):
    """The 6-D measurement of §7 without noise and its Jacobian.

    ``z[0:3]`` accelerometer outputs in ug (§6), ``z[3:6]`` angle sensors ``phi0 + phi`` in
    arcsec. ``H`` (3, 10), ``hcols`` (3, 10), ``hnnz`` (3,): the sparse accelerometer rows
    (state columns and values); the angle-sensor rows are ``1/ARCSEC`` on phi (implicit).
    """
    c = x[3:]
    a0 = phi0[0] + x[0]
    a1 = phi0[1] + x[1]
    a2 = phi0[2] + x[2]
    c_rp_into(a0, a1, a2, C, dC)
    for j in range(3):
        tp = c[lay[12] + j] * ARCSEC
        to = c[lay[13] + j] * ARCSEC
        k1 = c[lay[11] + j]
        fI = 0.0
        fP = 0.0
        fO = 0.0
        for k in range(3):
            fI += ACCEL_AXES[j, 0, k] * C[k, 2]
            fP += ACCEL_AXES[j, 1, k] * C[k, 2]
            fO += ACCEL_AXES[j, 2, k] * C[k, 2]
        aI = fI + to * fP - tp * fO
        gain = UG_PER_G + k1
        A = c[lay[10] + j] + gain * aI
        n = 0
        if lay[14] >= 0:
            k2 = c[lay[14] + j]
            k3 = c[lay[15] + j]
            kip = c[lay[16] + j]
            A += k2 * aI * aI + k3 * aI * aI * aI + kip * aI * fP
            gain += 2.0 * k2 * aI + 3.0 * k3 * aI * aI + kip * fP
            hcols[j, 0] = 3 + lay[14] + j
            H[j, 0] = aI * aI
            hcols[j, 1] = 3 + lay[15] + j
            H[j, 1] = aI * aI * aI
            hcols[j, 2] = 3 + lay[16] + j
            H[j, 2] = aI * fP
            n = 3
        z[j] = A
        # angle columns: d aI / d ang_i through f = C[:, 2], plus kIP aI dfP
        for i in range(3):
            dI = 0.0
            dP = 0.0
            dO = 0.0
            for k in range(3):
                dI += ACCEL_AXES[j, 0, k] * dC[i, k, 2]
                dP += ACCEL_AXES[j, 1, k] * dC[i, k, 2]
                dO += ACCEL_AXES[j, 2, k] * dC[i, k, 2]
            v = gain * (dI + to * dP - tp * dO)
            if lay[14] >= 0:
                v += c[lay[16] + j] * aI * dP
            hcols[j, n] = i
            H[j, n] = v
            n += 1
        hcols[j, n] = 3 + lay[10] + j
        H[j, n] = 1.0
        hcols[j, n + 1] = 3 + lay[11] + j
        H[j, n + 1] = aI
        hcols[j, n + 2] = 3 + lay[12] + j
        H[j, n + 2] = -gain * fO * ARCSEC
        hcols[j, n + 3] = 3 + lay[13] + j
        H[j, n + 3] = gain * fP * ARCSEC
        hnnz[j] = n + 4
    for i in range(3):
        z[3 + i] = (phi0[i] + x[i]) / ARCSEC


@njit(cache=True, error_model="numpy", inline="always")
def gyro_coefs(x, lay):
    """The gyro coefficients of the state ``x`` (deg/h, deg/h/g, deg/h/g^2) as tuples: per gyro j
    its 10 slots (:func:`layout_index`), and which slots the layout has (``on[m]``; an absent
    slot's value is another coefficient's and is never used). Read once per filter or simulator
    step, since RK4's stages change only phi, and handed to :func:`rate_s` in registers: an array
    handed to an inlined kernel past a branch costs atomic reference counts at every call."""
    on = (lay[0] >= 0, lay[1] >= 0, lay[2] >= 0, lay[3] >= 0, lay[4] >= 0, lay[5] >= 0, lay[6] >= 0, lay[7] >= 0,
          lay[8] >= 0, lay[9] >= 0)
    # column of slot m, gyro x (3 + lay[m]); an absent slot (-1) reads column 3 instead (in range, unused)
    i0, i1, i2, i3, i4 = 3 + max(lay[0], 0), 3 + max(lay[1], 0), 3 + max(lay[2], 0), 3 + max(lay[3], 0), \
        3 + max(lay[4], 0)
    i5, i6, i7, i8, i9 = 3 + max(lay[5], 0), 3 + max(lay[6], 0), 3 + max(lay[7], 0), 3 + max(lay[8], 0), \
        3 + max(lay[9], 0)
    g0 = (x[i0], x[i1], x[i2], x[i3], x[i4], x[i5], x[i6], x[i7], x[i8], x[i9])
    g1 = (x[i0 + 1], x[i1 + 1], x[i2 + 1], x[i3 + 1], x[i4 + 1], x[i5 + 1], x[i6 + 1], x[i7 + 1], x[i8 + 1],
          x[i9 + 1])
    g2 = (x[i0 + 2], x[i1 + 2], x[i2 + 2], x[i3 + 2], x[i4 + 2], x[i5 + 2], x[i6 + 2], x[i7 + 2], x[i8 + 2],
          x[i9 + 2])
    return g0, g1, g2, on


@njit(cache=True, error_model="numpy")
def _drift_s(g, on, j, f0, f1, f2):
    """Drift of gyro ``j`` (deg/h) at ``f`` (g, in p), its slot coefficients ``g`` and the
    layout's slots ``on`` (:func:`gyro_coefs`; §5, §13): :func:`gyro_drift_k`'s ``eps[j]``, the
    same products summed in the same order (the slot order), absent slots skipped as there."""
    aI, aO, aS = gyro_axis_components(j, f0, f1, f2)
    # the regressors in slot order (this rig's order: spin before output, layout_index)
    reg = (1.0, aI, aS, aO, aI * aI, aS * aS, aI * aO, aI * aS, aO * aS, aO * aO)
    e = 0.0
    for m in range(10):
        if on[m]:
            e += g[m] * reg[m]
    return e


@njit(cache=True, error_model="numpy")
def rate_s(a0, a1, a2, g0, g1, g2, on, wn, wu, w0, w1, w2):
    """Error-angle rate of §4 (rad/s) at the gimbal angles ``a0, a1, a2`` (rad: commanded plus
    phi), gyro coefficients ``g0, g1, g2``, ``on`` (:func:`gyro_coefs`), Earth rate ``wn``, ``wu`` (rad/s)
    and white rate ``w0, w1, w2`` (rad/s): ``phi' = -T [eps DPH + C_n^p w_ie^n + w]`` as a tuple,
    without the Jacobian.

    The numbers of :func:`rate_k` bit for bit (the same products and sums in the same order, the
    entries of C and T written as :func:`platcal.model.frames.c_rp_sc_into` and
    :func:`~platcal.model.frames.euler_t_sc_into` write them, T's zeros and ones included) but on
    scalars only: RK4's three further stages (and the simulator's four) need neither F nor the
    scratch arrays, whose stores and reference counts were most of a stage (issue 22 item 2,
    ``benchmarks/profile_multiposition.py``).
    """
    sa, ca = np.sin(a0), np.cos(a0)
    sb, cb = np.sin(a1), np.cos(a1)
    sg, cg = np.sin(a2), np.cos(a2)
    c01 = cg * sb * sa + sg * ca
    c02 = -cg * sb * ca + sg * sa
    c11 = -sg * sb * sa + cg * ca
    c12 = sg * sb * ca + cg * sa
    c21 = -cb * sa
    c22 = cb * ca
    u0 = _drift_s(g0, on, 0, c02, c12, c22) * DEG_PER_HOUR + c01 * wn + c02 * wu + w0
    u1 = _drift_s(g1, on, 1, c02, c12, c22) * DEG_PER_HOUR + c11 * wn + c12 * wu + w1
    u2 = _drift_s(g2, on, 2, c02, c12, c22) * DEG_PER_HOUR + c21 * wn + c22 * wu + w2
    ib = 1.0 / cb
    tb = sb * ib
    # T's constant entries (0 and 1) stay in the products: 0 * u is -0 or NaN for some u
    r0 = -(cg * ib * u0 + -sg * ib * u1 + 0.0 * u2)
    r1 = -(sg * u0 + cg * u1 + 0.0 * u2)
    r2 = -(-tb * cg * u0 + tb * sg * u1 + 1.0 * u2)
    return r0, r1, r2


@njit(cache=True, error_model="numpy")
def rk4_s(p0, p1, p2, x0, x1, x2, g0, g1, g2, on, wn, wu, w0, w1, w2, h, k10, k11, k12):
    """One RK4 step of §4 over ``h`` s from phi ``x0, x1, x2`` (rad) at the commanded angles
    ``p0, p1, p2`` (rad), the gyro coefficients ``g0, g1, g2``, ``on`` (:func:`gyro_coefs`, constant over
    the step) and the white rate ``w`` (rad/s) held constant (§12), given the first stage's rate
    ``k1`` (rad/s). Returns the new phi (tuple, rad)."""
    hh = 0.5 * h
    k20, k21, k22 = rate_s(p0 + (x0 + hh * k10), p1 + (x1 + hh * k11), p2 + (x2 + hh * k12), g0, g1, g2, on, wn, wu,
                           w0, w1, w2)
    k30, k31, k32 = rate_s(p0 + (x0 + hh * k20), p1 + (x1 + hh * k21), p2 + (x2 + hh * k22), g0, g1, g2, on, wn, wu,
                           w0, w1, w2)
    k40, k41, k42 = rate_s(p0 + (x0 + h * k30), p1 + (x1 + h * k31), p2 + (x2 + h * k32), g0, g1, g2, on, wn, wu,
                           w0, w1, w2)
    h6 = h / 6.0
    return (x0 + h6 * (k10 + 2.0 * k20 + 2.0 * k30 + k40), x1 + h6 * (k11 + 2.0 * k21 + 2.0 * k31 + k41),
            x2 + h6 * (k12 + 2.0 * k22 + 2.0 * k32 + k42))


@njit(cache=True, error_model="numpy", inline="always")
def rk4_k(phi0, x, lay, wn, wu, w, h, out):
    """One RK4 step of §4 over ``h`` s with the white rate ``w`` (3,) rad/s held constant (§12);
    angles only (coefficients are constant): ``out`` (3,) the new phi (rad)."""
    g0, g1, g2, on = gyro_coefs(x, lay)
    p0, p1, p2 = phi0[0], phi0[1], phi0[2]
    x0, x1, x2 = x[0], x[1], x[2]
    w0, w1, w2 = w[0], w[1], w[2]
    k10, k11, k12 = rate_s(p0 + x0, p1 + x1, p2 + x2, g0, g1, g2, on, wn, wu, w0, w1, w2)
    out[0], out[1], out[2] = rk4_s(p0, p1, p2, x0, x1, x2, g0, g1, g2, on, wn, wu, w0, w1, w2, h, k10, k11, k12)


@njit(cache=True)
def make_scratch(n):
    """Scratch tuple of :func:`rate_k` for a state of ``n``: (C, dC, T, dT, f, eps, deps, greg)."""
    return (np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3)),
            np.empty(3), np.empty(3), np.empty((3, 3)), np.empty((3, 10)))


# ------------------------------------------------------------------ Python helpers

def rate(phi0_rad, x, site: Site = Site(), ext: int = 0, omega_on: bool = True):
    """``(phi' (3,) rad/s, F (3, n))`` at one point (for tests and small calls)."""
    x = np.asarray(x, float)
    lay = layout_index(ext)
    wn, wu = site.params(omega_on)
    C, dC, T, dT, f, eps, deps, greg = make_scratch(x.size)
    out = np.empty(3)
    F = np.zeros((3, x.size))
    rate_k(np.asarray(phi0_rad, float), x, lay, wn, wu, np.zeros(3), out, F, True,
           C, dC, T, dT, f, eps, deps, greg)
    return out, F


def drift(x, phi0_rad, ext: int = 0) -> np.ndarray:
    """Gyro drift eps (deg/h) at phi0 + phi (§5)."""
    x = np.asarray(x, float)
    C, dC, T, dT, f, eps, deps, greg, *_ = make_scratch(x.size)
    ang = np.asarray(phi0_rad, float) + x[:3]
    c_rp_into(ang[0], ang[1], ang[2], C, dC)
    gyro_drift_k(x[3:], layout_index(ext), C[:, 2].copy(), eps, deps, greg)
    return eps.copy()


def measure(phi0_rad, x, ext: int = 0):
    """``(z (6,), H (6, n))``: the §7 measurement (ug, arcsec) and its dense Jacobian."""
    x = np.asarray(x, float)
    n = x.size
    z = np.empty(6)
    Hs = np.empty((3, 10))
    hc = np.zeros((3, 10), dtype=np.int64)
    nn = np.zeros(3, dtype=np.int64)
    C, dC = np.empty((3, 3)), np.empty((3, 3, 3))
    meas_k(np.asarray(phi0_rad, float), x, layout_index(ext), z, Hs, hc, nn, C, dC)
    H = np.zeros((6, n))
    for j in range(3):
        for t in range(nn[j]):
            H[j, hc[j, t]] += Hs[j, t]
        H[3 + j, j] = 1.0 / ARCSEC
    return z, H


def wrap_arcsec(d):
    """Angle residuals wrapped to +-180 deg (§7), in arcsec."""
    return (np.asarray(d) + 648000.0) % 1296000.0 - 648000.0
