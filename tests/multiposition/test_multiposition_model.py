"""Model values (§15 item 1): golden values, analytic Jacobians, the symbolic model."""

import numpy as np
import pytest

from platcal.model.frames import ARCSEC
from platcal.rigs.multiposition import model as m

GOLDEN = [  # (alpha, beta, gamma) deg; A (ug); eps (deg/h); phi' (arcsec/s)  -- §15 item 1
    ((0, 0, 0), (2918.1305, 3231.7895, 1007410.0), (6.287, 6.798, 2.587), (-6.287, -20.053744, -9.694668)),
    ((90, 0, 90), (1003660.0, 5728.8296, 7790.3083), (8.453, 6.798, 2.587), (6.798, -15.560668, 10.668744)),
]


@pytest.mark.parametrize("pos, A, eps, rate", GOLDEN)
def test_golden_values(pos, A, eps, rate):
    x = np.concatenate([np.zeros(3), m.truth_vector()])
    ph = np.radians(pos)
    z, _ = m.measure(ph, x)
    np.testing.assert_allclose(z[:3], A, atol=1e-3, rtol=0)
    np.testing.assert_allclose(m.drift(x, ph), eps, atol=1e-5, rtol=0)
    r, _ = m.rate(ph, x)
    np.testing.assert_allclose(r / ARCSEC, rate, atol=1e-5, rtol=0)
    np.testing.assert_allclose(z[3:], np.degrees(ph) * 3600, atol=1e-9)


def _random_state(rng, ext):
    x = np.concatenate([rng.normal(0, 1e-3, 3), m.truth_vector(ext) * rng.uniform(0.5, 1.5, m.truth_vector(ext).size)])
    if ext:
        x[3:] += rng.normal(0, 0.1, x.size - 3)  # DOO and friends nonzero too
    return x


@pytest.mark.parametrize("ext", [0, 1, 2])
def test_analytic_jacobians_equal_central_differences(ext):
    rng = np.random.default_rng(ext)
    for _ in range(3):
        x = _random_state(rng, ext)
        ph = np.radians([rng.uniform(0, 360), rng.uniform(-30, 30), rng.uniform(0, 360)])
        _, F = m.rate(ph, x, ext=ext)
        _, H = m.measure(ph, x, ext=ext)
        Fn = np.zeros_like(F)
        Hn = np.zeros_like(H)
        for i in range(x.size):
            d = 1e-7 if i < 3 else 1e-3 * max(1.0, abs(x[i]))
            xp, xm = x.copy(), x.copy()
            xp[i] += d
            xm[i] -= d
            Fn[:, i] = (m.rate(ph, xp, ext=ext)[0] - m.rate(ph, xm, ext=ext)[0]) / (2 * d)
            Hn[:, i] = (m.measure(ph, xp, ext=ext)[0] - m.measure(ph, xm, ext=ext)[0]) / (2 * d)
        np.testing.assert_allclose(F, Fn, rtol=1e-5, atol=1e-14)
        # angle columns are ~1e6 ug/rad: a difference quotient of 1e-7 rad resolves them to ~1e-3
        np.testing.assert_allclose(H, Hn, rtol=1e-5, atol=1e-8 * np.abs(H).max())


def test_symbolic_model_equals_kernels():
    """The sympy model of the Lie test (an independent writing of §4-7) equals the kernels."""
    import sympy as sp

    from platcal.rigs.multiposition.lie_symbolic import symbolic_model

    for ext in (0, 2):
        x, p, f, h = symbolic_model(ext)
        fn = sp.lambdify([x, p], [f, h], modules="numpy")
        rng = np.random.default_rng(7)
        site = m.Site()
        xv = _random_state(rng, ext)
        ph = np.radians([123.0, -17.0, 301.0])
        fs, hs = fn(xv, [*ph, *site.params()])
        np.testing.assert_allclose(np.array(fs, float), m.rate(ph, xv, ext=ext)[0], rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(np.array(hs, float), m.measure(ph, xv, ext=ext)[0], rtol=1e-12, atol=1e-9)


def test_names_and_layout():
    names = m.coef_names()
    assert names[:4] == ("DF_x", "DF_y", "DF_z", "DI_x") and names[-1] == "theta_oz" and len(names) == 24
    assert len(m.coef_names(1)) == 48 and len(m.coef_names(2)) == 51
    assert m.unit_of("theta_py") == "arcsec" and m.unit_of("kIP_z") == "ug/g^2"


def test_wrap():
    np.testing.assert_allclose(m.wrap_arcsec([648001.0, -648001.0, 10.0]), [-647999.0, 647999.0, 10.0])


def test_fused_rotation_equals_the_frames_functions():
    """rot_t_into (the filter's fused C and T) gives exactly the numbers of the shared frames."""
    from platcal.model.frames import c_rp_into, euler_t_into
    from platcal.rigs.multiposition.model import rot_t_into

    rng = np.random.default_rng(5)
    for a in rng.uniform(-3, 3, size=(20, 3)) * [1, 0.5, 1]:
        C, dC, T, dT = np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3))
        C2, dC2, T2, dT2 = np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3)), np.empty((3, 3, 3))
        rot_t_into(a[0], a[1], a[2], C, dC, T, dT, True)
        c_rp_into(a[0], a[1], a[2], C2, dC2)
        euler_t_into(a[1], a[2], T2, dT2)
        for u, v in ((C, C2), (dC, dC2), (T, T2), (dT, dT2)):
            assert np.array_equal(u, v)


def _rate_arrays(phi0, x, lay, wn, wu, w):
    """The §4 rate through rate_k, the array kernel that also gives F (the reference)."""
    C, dC, T, dT, f, eps, deps, greg = m.make_scratch(x.size)
    out = np.empty(3)
    m.rate_k(phi0, x, lay, wn, wu, w, out, np.zeros((3, x.size)), False, C, dC, T, dT, f, eps, deps, greg)
    return out


@pytest.mark.parametrize("ext", [0, 1, 2])
def test_rk4_in_registers_equals_the_array_rate_kernel(ext):
    """rk4_k (the register-only rate_s, the coefficients read once by gyro_coefs) gives exactly
    the numbers of RK4 composed of rate_k's rates (issue 22 item 2: the filter's and the
    simulator's numbers unchanged), with white rate noise, at angles across the gimbal range."""
    rng = np.random.default_rng(40 + ext)
    lay = m.layout_index(ext)
    wn, wu = m.Site().params()
    h = 0.02
    for _ in range(25):
        x = _random_state(rng, ext)
        phi0 = np.radians([rng.uniform(0, 360), rng.uniform(-80, 80), rng.uniform(0, 360)])
        w = rng.normal(0, 1e-5, 3)
        k = [_rate_arrays(phi0, x, lay, wn, wu, w)]
        for step in (0.5 * h, 0.5 * h, h):
            xs = x.copy()
            xs[:3] = x[:3] + step * k[-1]
            k.append(_rate_arrays(phi0, xs, lay, wn, wu, w))
        ref = x[:3] + h / 6.0 * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])
        out = np.empty(3)
        m.rk4_k(phi0, x, lay, wn, wu, w, h, out)
        assert np.array_equal(out, ref)
        assert np.all(np.abs(out - x[:3]) > 0)  # not trivially equal: the step moved every angle
