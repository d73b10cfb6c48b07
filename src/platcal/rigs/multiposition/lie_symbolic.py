"""The multi-position model of docs/multiposition-1g.md §4-7 written symbolically with sympy, and
the source of the Lie-derivative Jacobian built from it (§8): what :mod:`.lie` caches on disk.

Apart from :mod:`.lie` (the evaluation) so that only a build imports sympy (about 0.5 s of every
job that loads the cached source; issue 22 item 4).
"""

from __future__ import annotations

import inspect

import sympy as sp

from ...model.frames import ARCSEC, DEG_PER_HOUR
from ...model.instruments import GYRO_AXES
from .model import ACCEL_AXES, ext_terms, state_names

_GYRO_REG = {"DF": lambda I, O, S: 1, "DI": lambda I, O, S: I, "DS": lambda I, O, S: S,
             "DO": lambda I, O, S: O, "DII": lambda I, O, S: I * I, "DSS": lambda I, O, S: S * S,
             "DIO": lambda I, O, S: I * O, "DIS": lambda I, O, S: I * S, "DOS": lambda I, O, S: O * S,
             "DOO": lambda I, O, S: O * O}


def symbolic_model(ext: int = 0):
    """``(x, p, f, h)``: state symbols, parameters (alpha0, beta0, gamma0, Omega_N, Omega_U),
    the phi rows of the drift field (3, rad/s) and the output (6: ug, arcsec), §4-7."""
    names = state_names(ext)
    x = sp.symbols(" ".join(n.replace("theta_", "th_") for n in names), real=True)
    a0, b0, g0, wn, wu = sp.symbols("alpha0 beta0 gamma0 Omega_N Omega_U", real=True)
    a, b, g = a0 + x[0], b0 + x[1], g0 + x[2]
    Mx = sp.Matrix([[1, 0, 0], [0, sp.cos(a), sp.sin(a)], [0, -sp.sin(a), sp.cos(a)]])
    My = sp.Matrix([[sp.cos(b), 0, -sp.sin(b)], [0, 1, 0], [sp.sin(b), 0, sp.cos(b)]])
    Mz = sp.Matrix([[sp.cos(g), sp.sin(g), 0], [-sp.sin(g), sp.cos(g), 0], [0, 0, 1]])
    C = Mz * My * Mx
    fp = C[:, 2]
    c = dict(zip(names[3:], x[3:]))
    gyro, accel = ext_terms(ext)

    def coef(term, j):
        return c[f"{term}{'xyz'[j]}" if term.startswith("theta") else f"{term}_{'xyz'[j]}"]

    eps = []
    for j in range(3):
        I, O, S = (sum(GYRO_AXES[j, r, k] * fp[k] for k in range(3)) for r in range(3))
        eps.append(sum(coef(t, j) * _GYRO_REG[t](I, O, S) for t in gyro))
    u = sp.Matrix([eps[j] * DEG_PER_HOUR + C[j, 1] * wn + C[j, 2] * wu for j in range(3)])
    T = sp.Matrix([[sp.cos(g) / sp.cos(b), -sp.sin(g) / sp.cos(b), 0], [sp.sin(g), sp.cos(g), 0],
                   [-sp.tan(b) * sp.cos(g), sp.tan(b) * sp.sin(g), 1]])
    f = -T * u
    h = []
    for j in range(3):
        fI, fP, fO = (sum(ACCEL_AXES[j, r, k] * fp[k] for k in range(3)) for r in range(3))
        aI = fI + coef("theta_o", j) * ARCSEC * fP - coef("theta_p", j) * ARCSEC * fO
        A = coef("k0", j) + (10**6 + coef("k1", j)) * aI
        if "k2" in accel:
            A += coef("k2", j) * aI**2 + coef("k3", j) * aI**3 + coef("kIP", j) * aI * fP
        h.append(A)
    h += [(a0 + x[0]) / ARCSEC, (b0 + x[1]) / ARCSEC, (g0 + x[2]) / ARCSEC]
    return x, (a0, b0, g0, wn, wu), list(f), h


def build_source(ext: int, order: int) -> str:
    """The Python source of ``M(x, params)``, the Jacobian of the stacked Lie derivatives ``[h;
    L_f h; ...]`` up to ``order`` of layout ``ext`` (:func:`symbolic_model`), lambdified with
    common-subexpression elimination; :func:`.lie.observability_function` caches it on disk."""
    x, p, f, h = symbolic_model(ext)
    rows = [sp.Matrix(h)]
    L = sp.Matrix(h)
    fv = sp.Matrix(f)
    for _ in range(order):
        L = L.jacobian(x[:3]) * fv  # f is zero outside the phi rows
        rows.append(L)
    M = sp.Matrix.vstack(*rows).jacobian(x)
    fn = sp.lambdify([x, p], M, modules="numpy", cse=True)
    return inspect.getsource(fn)
