"""Model checks: frames, specific force, instrument models and their Jacobians (spec sections 1-6)."""

import numpy as np
import pytest

from platcal.model import frames
from platcal.rigs.centrifuge.base import Centrifuge, specific_force
from platcal.model.instruments import FULL_NAMES, INDEX, NAMES, accel_output, gyro_drift, unit_of
from platcal.rigs.centrifuge.catalogue import full_truth, load_catalogue
from platcal.rigs.centrifuge.attitude import attitude_rate, measure, rk4

rng = np.random.default_rng(12345)
PARAMS = Centrifuge().params()


def _fr3(t, h, params):
    """The base specific force at an RK4 step's start, middle and end (m/s^2)."""
    return np.stack([specific_force(t + c * h, params) for c in (0.0, 0.5, 1.0)])


def random_angles(n=20):
    a = rng.uniform(-np.pi, np.pi, (n, 3))
    a[:, 1] = rng.uniform(-1.3, 1.3, n)  # keep away from beta = +-90 deg
    return a


def test_rotations_orthonormal_and_product_order():
    for a, b, g in random_angles():
        C = frames.c_rp(a, b, g)
        np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(C, frames.rot_z(g) @ frames.rot_y(b) @ frames.rot_x(a), atol=1e-15)
        for M in (frames.rot_x(a), frames.rot_y(b), frames.rot_z(g)):
            np.testing.assert_allclose(M @ M.T, np.eye(3), atol=1e-15)


def test_passive_rotation_convention():
    # a passive rotation by +90 deg about z maps the old x axis to -y in the new frame
    np.testing.assert_allclose(frames.rot_z(np.pi / 2) @ [1.0, 0, 0], [0, -1, 0], atol=1e-15)


def test_euler_e_times_t_is_identity():
    for _, b, g in random_angles():
        np.testing.assert_allclose(frames.euler_e(b, g) @ frames.euler_t(b, g), np.eye(3), atol=1e-13)


def test_rotation_and_t_partials_match_finite_differences():
    h = 1e-6
    for ang in random_angles(5):
        C = np.empty((3, 3)); dC = np.empty((3, 3, 3))
        frames.c_rp_into(*ang, C, dC)
        T = np.empty((3, 3)); dT = np.empty((3, 3, 3))
        frames.euler_t_into(ang[1], ang[2], T, dT)
        for i in range(3):
            e = np.zeros(3); e[i] = h
            fd = (frames.c_rp(*(ang + e)) - frames.c_rp(*(ang - e))) / (2 * h)
            np.testing.assert_allclose(dC[i], fd, atol=1e-9)
            fdT = (frames.euler_t(*(ang + e)[1:]) - frames.euler_t(*(ang - e)[1:])) / (2 * h)
            np.testing.assert_allclose(dT[i], fdT, atol=1e-8)


def test_specific_force_magnitude_eq19():
    """|f_r|^2 / g^2 averaged over a revolution is 101.0044 at 10 g (eqs. 19-20)."""
    c = Centrifuge()
    t = np.linspace(0, 2.0, 4001)[:-1]  # one revolution at 180 deg/s
    f = np.array([specific_force(ti, PARAMS) for ti in t])
    ratio = (f**2).sum(axis=1) / c.g**2
    assert ratio.mean() == pytest.approx(101.0044, abs=5e-5)
    assert ratio.min() > 101.0 and ratio.max() < 101.01
    # centripetal part is exactly g_level g, and the vertical +g (spec decision)
    assert c.arm_radius * c.rate**2 == pytest.approx(10 * c.g)
    assert specific_force(0.5, Centrifuge(rate_deg_s=0).params()) == pytest.approx([0, 0, c.g])


def test_outputs_with_zero_coefficients_equal_fp_over_g():
    zero = np.zeros(48)
    for ang in random_angles(5):
        t = rng.uniform(0, 60)
        fp = frames.c_rp(*ang) @ specific_force(t, PARAMS) / PARAMS[2]
        A, _, _ = measure(ang, zero, specific_force(t, PARAMS), PARAMS)
        np.testing.assert_allclose(A, fp, rtol=0, atol=1e-15)
        assert np.all(gyro_drift(zero, fp) == 0)


def test_gyro_drift_eq11_by_hand():
    coef = np.zeros(48)
    f = np.array([0.3, -2.0, 9.5])
    # x gyro: I = x_p, O = -z_p, S = y_p (spec section 4)
    coef[INDEX["DF_x"]] = 1.0
    coef[INDEX["DO_x"]] = 2.0
    coef[INDEX["DIS_x"]] = 3.0
    coef[INDEX["DOO_x"]] = 0.5
    eps = gyro_drift(coef, f)
    aI, aO, aS = f[0], -f[2], f[1]
    assert eps[0] == pytest.approx(1.0 + 2.0 * aO + 3.0 * aI * aS + 0.5 * aO**2)
    assert eps[1] == 0 and eps[2] == 0
    # z gyro: I = z_p, O = x_p, S = y_p
    coef[:] = 0
    coef[INDEX["DSS_z"]] = 1.0
    coef[INDEX["DIO_z"]] = 1.0
    assert gyro_drift(coef, f)[2] == pytest.approx(f[1] ** 2 + f[2] * f[0])


def test_accelerometer_eq13_by_hand():
    coef = full_truth()
    f = np.array([0.4, -3.0, 9.0])
    ug, arc = 1e-6, np.pi / 180 / 3600
    A = accel_output(coef, f)
    c = {n: coef[INDEX[n]] for n in FULL_NAMES}
    aI = f[2] + c["theta_pz"] * arc * f[0] + c["theta_oz"] * arc * f[1]
    aP = f[1] - c["theta_oz"] * arc * f[2]
    expect = ug * c["k0_z"] + (1 + ug * c["k1_z"]) * aI + ug * c["k2_z"] * aI**2 + ug * c["k3_z"] * aI**3 \
        + ug * c["kIP_z"] * aI * aP
    assert A[2] == pytest.approx(expect, rel=1e-15)
    aI = c["theta_py"] * arc * f[0] + f[1]
    aP = -f[2]
    expect = ug * c["k0_y"] + (1 + ug * c["k1_y"]) * aI + ug * c["k2_y"] * aI**2 + ug * c["k3_y"] * aI**3 \
        + ug * c["kIP_y"] * aI * aP
    assert A[1] == pytest.approx(expect, rel=1e-15)


def _fd(fun, x, h):
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x); e[i] = h[i] if np.ndim(h) else h
        cols.append((fun(x + e) - fun(x - e)) / (2 * e[i]))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_attitude_rate_jacobians_match_finite_differences(seed):
    r = np.random.default_rng(seed)
    coef = full_truth() * r.uniform(0.5, 1.5, 48)
    coef[45:] = r.uniform(-0.1, 0.1, 3)  # DOO too
    ang = random_angles(1)[0]
    t = r.uniform(0, 60)
    _, ja, jc = attitude_rate(ang, coef, specific_force(t, PARAMS), PARAMS)
    fd_a = _fd(lambda a: attitude_rate(a, coef, specific_force(t, PARAMS), PARAMS)[0], ang, 1e-6)
    fd_c = _fd(lambda c: attitude_rate(ang, c, specific_force(t, PARAMS), PARAMS)[0], coef, 1e-3)
    np.testing.assert_allclose(ja, fd_a, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(jc, fd_c, rtol=1e-6, atol=1e-14)


@pytest.mark.parametrize("seed", [0, 1])
def test_rk4_map_jacobian_matches_finite_differences(seed):
    r = np.random.default_rng(seed)
    coef = full_truth() * r.uniform(0.5, 1.5, 48)
    ang = random_angles(1)[0]
    t, h = r.uniform(0, 60), 0.02
    _, pa, pc = rk4(ang, coef, _fr3(t, h, PARAMS), h, PARAMS)
    # difference the increment (out - ang), not out, so the identity does not swamp the FD
    fd_a = _fd(lambda a: rk4(a, coef, _fr3(t, h, PARAMS), h, PARAMS)[0] - a, ang, 1e-4)
    fd_c = _fd(lambda c: rk4(ang, c, _fr3(t, h, PARAMS), h, PARAMS)[0] - ang, coef, 1.0)
    np.testing.assert_allclose(pa - np.eye(3), fd_a, rtol=1e-5, atol=1e-13)
    np.testing.assert_allclose(pc, fd_c, rtol=1e-5, atol=1e-15)
    # the coefficient columns of the accelerometer terms do not enter the dynamics
    assert np.all(pc[:, 27:45] == 0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_measurement_jacobians_match_finite_differences(seed):
    r = np.random.default_rng(seed)
    coef = full_truth() * r.uniform(0.5, 1.5, 48)
    ang = random_angles(1)[0]
    t = r.uniform(0, 60)
    _, hc, ha = measure(ang, coef, specific_force(t, PARAMS), PARAMS)
    fd_a = _fd(lambda a: measure(a, coef, specific_force(t, PARAMS), PARAMS)[0], ang, 1e-7)
    fd_c = _fd(lambda c: measure(ang, c, specific_force(t, PARAMS), PARAMS)[0], coef, 1.0)
    np.testing.assert_allclose(ha, fd_a, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(hc, fd_c, rtol=1e-6, atol=1e-16)
    assert np.all(hc[:, :27] == 0) and np.all(hc[:, 45:] == 0)


def test_catalogue_matches_table2():
    cat = load_catalogue()
    assert cat.names == NAMES and len(NAMES) == 45
    assert NAMES[0] == "DF_x" and NAMES[-1] == "theta_oz"
    assert cat.truth[NAMES.index("k1_z")] == 1100
    assert unit_of("DIS_y") == "deg/h/g^2" and unit_of("k3_x") == "ug/g^3" and unit_of("theta_pz") == "arcsec"
    assert cat.groups.count("gyro") == 27 and cat.groups.count("accel") == 18
    with pytest.raises(KeyError):
        full_truth({"DF_q": 1.0})
