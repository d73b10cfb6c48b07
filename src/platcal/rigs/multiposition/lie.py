"""Exact Lie-derivative observability rank (docs/multiposition-1g.md §8, patent step 3).

The model of §4-7 is written once more, symbolically with sympy (:mod:`.lie_symbolic`: commanded
angles, Earth-rate components and every state as symbols); ``h``, ``L_f h``, ``L_f^2 h`` and their
Jacobian ``M = d/dx [h; L_f h; ...]`` (6 (order+1) x n) are built once per (layout, order),
lambdified with common-subexpression elimination and cached: in-process, and as generated source
keyed by the hash of this file, :mod:`.lie_symbolic` and :mod:`.model`. The sources of the default
study's (layout, order) pairs (:data:`SHIPPED`) ship with the package (``data/lie/``, written by
``python -m platcal.rigs.multiposition.lie``; a test fails when they are not those of the current
files), so a fresh machine's first study builds nothing; others are built once per machine into
the user cache dir (``$XDG_CACHE_HOME/platcal`` or ``~/.cache/platcal``). A job that finds the
source does not import sympy (:data:`SYMBOLIC_SOURCE`, by path; the build is tens of seconds: the
default study's three pairs took 22 s; issue 22 item 4). Being an independent writing of the model,
the symbolic ``h`` and ``f`` are also checked against the numba kernels in the tests.

Evaluation is float64 with the §8 scaling: the rows of ``L_f^k h`` of output i times
``dwell^k / sigma_i``, the column of state j times its P0 sigma (sigma_set for phi); rank = the
number of singular values above ``rtol`` times the largest.
"""

from __future__ import annotations

import hashlib
import math
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from ...io import atomic_write_text
from ...model.frames import DEG
from ...rig import resolve
from .model import state_names

SYMBOLIC_SOURCE = f"{__package__}.lie_symbolic:build_source"
"""The sympy build of the Jacobian's source (:func:`.lie_symbolic.build_source`), by path: imported
only when the disk cache does not hold it, so the jobs that evaluate ranks load no sympy."""
SOURCE_FILES = ("lie.py", "lie_symbolic.py", "model.py")
"""The files the cached source is keyed by (their hash): the build, its model and this loader."""
SHIPPED = ((0, 2), (1, 1), (2, 1))
"""The (layout ``ext``, order) pairs whose sources ship with the package: the default study's
(``observability.lie_order`` 2 for the scheme checks, order 1 for the extension models)."""
SHIPPED_DIR = Path(__file__).parent / "data" / "lie"
SHIPPED_SUFFIX = ".txt"
"""The shipped sources are text the loader executes, as the cached ones: generated, not written."""


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "platcal"


def _source_path(ext: int, order: int) -> Path:
    """Where the source of (ext, order) is: shipped with the package if it is there for the current
    files, else the user cache (which may not hold it yet)."""
    key = _code_key(ext, order)
    shipped = SHIPPED_DIR / (key + SHIPPED_SUFFIX)
    return shipped if shipped.exists() else _cache_dir() / (key + ".py")


def _code_key(ext: int, order: int) -> str:
    here = Path(__file__).parent
    h = hashlib.sha256()
    for name in SOURCE_FILES:
        h.update((here / name).read_bytes())
    return f"lie_{h.hexdigest()[:16]}_ext{ext}_order{order}"


@lru_cache(maxsize=None)
def observability_function(ext: int = 0, order: int = 2):
    """``M(x, params) -> (6 (order+1), n)``: the Jacobian of the stacked Lie derivatives."""
    path = _source_path(ext, order)
    if path.exists():
        src = path.read_text()
    else:
        src = resolve(SYMBOLIC_SOURCE)(ext, order)
        try:
            atomic_write_text(path, src)
        except OSError:
            pass  # a read-only cache only costs the next run the build

    ns = {"numpy": np, "math": math, **{k: getattr(np, k) for k in ("sin", "cos", "tan", "sqrt", "array")}}
    ns.update({"ImmutableDenseMatrix": np.array, "MutableDenseMatrix": np.array})
    exec(compile(src, str(path), "exec"), ns)
    fname = src.split("def ", 1)[1].split("(", 1)[0]
    fn = ns[fname]

    def call(xv, params):
        return np.array(fn(np.asarray(xv, float), np.asarray(params, float)), dtype=float)
    return call


def ship() -> list[Path]:
    """Build the sources of :data:`SHIPPED` for the current files into the package's ``data/lie/``
    and remove those of other keys; returns the files written. Run after an edit of
    :data:`SOURCE_FILES` (``python -m platcal.rigs.multiposition.lie``)."""
    keep = {_code_key(ext, order) + SHIPPED_SUFFIX for ext, order in SHIPPED}
    for old in SHIPPED_DIR.glob("lie_*" + SHIPPED_SUFFIX):
        if old.name not in keep:
            old.unlink()
    out = []
    for ext, order in SHIPPED:
        path = SHIPPED_DIR / (_code_key(ext, order) + SHIPPED_SUFFIX)
        atomic_write_text(path, resolve(SYMBOLIC_SOURCE)(ext, order))   # a failure here is an error
        out.append(path)
    return out


def stacked_matrix(cfg, positions_deg, dwell_s: float, x=None, ext: int = 0, order: int | None = None,
                   omega_on: bool = True) -> np.ndarray:
    """The scaled ``P = [M_1; ...; M_K]`` of §8 at state ``x`` (default 0)."""
    order = cfg.lie_order if order is None else order
    fn = observability_function(ext, order)
    n = 3 + cfg.p0(ext).size
    xv = np.zeros(n) if x is None else np.asarray(x, float)
    wn, wu = cfg.site.params(omega_on)
    sig_out = np.array([cfg.sigma_a_ug] * 3 + [cfg.sigma_an_arcsec] * 3)
    sig_out = np.where(sig_out > 0, sig_out, 1.0)
    row_scale = np.concatenate([dwell_s**k / sig_out for k in range(order + 1)])
    col_scale = np.concatenate([[cfg.sigma_set_rad] * 3, cfg.p0(ext)])
    blocks = []
    for pos in np.asarray(positions_deg, float).reshape(-1, 3):
        M = fn(xv, [*(pos * DEG), wn, wu])
        blocks.append(M * row_scale[:, None] * col_scale[None, :])
    return np.vstack(blocks)


def rank_analysis(cfg, positions_deg, dwell_s: float, x=None, ext: int = 0, order: int | None = None,
                  omega_on: bool = True) -> dict:
    """Rank, relative singular values and the null-space directions by state name (§8)."""
    P = stacked_matrix(cfg, positions_deg, dwell_s, x, ext, order, omega_on)
    _, s, Vt = np.linalg.svd(P, full_matrices=True)
    n = P.shape[1]
    sv = np.zeros(n)
    sv[: s.size] = s
    rel = sv / sv.max()
    rank = int(np.sum(rel > cfg.rank_rtol))
    names = state_names(ext)
    null = Vt[rank:]
    weight = np.sum(null**2, axis=0) if rank < n else np.zeros(n)
    vectors = []
    for v in null:
        v = v / v[np.argmax(np.abs(v))]
        vectors.append({names[i]: round(float(v[i]), 6) for i in np.argsort(-np.abs(v)) if abs(v[i]) > 1e-3})
    return {"rank": rank, "n_states": n, "rel_singular_values": rel.tolist(),
            "weakest_rel_singular_value": float(rel[rank - 1]) if rank else 0.0,
            "null_space": [names[i] for i in range(n) if weight[i] > 0.5],
            "null_vectors": vectors}


if __name__ == "__main__":
    for written in ship():
        print(written)
