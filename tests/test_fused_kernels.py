"""The fused group operations of the generated modules (:data:`cartan.compiled.kernels.FUSED_OPS`)
against the groups' matrices.

``g_Ad_inv_apply`` (``Ad_{g⁻¹}`` applied to rows), ``g_E_apply`` (``𝓔(τ, ξ)`` applied to
rows), ``g_dexp_inv_apply`` (``dexp⁻¹(ξ)`` applied to a vector) and ``g_coad_exp`` (exp(ξ) and
``Ad_{exp ξ}ᵀ`` applied to a momentum in place) are compiled in a generated module twice:
with the group's closed forms (SO(3), SE(3), SE(2)) and with the generic defaults built from
the matrix kernels; SO(4) has no closed forms and takes the defaults.  Both are compared
with the numpy reference path of the group (``G.Ad``, ``G.inverse``, ``G.E``)
at small arguments (|ξ| ≈ 1e-9: the Taylor-series branch of every coefficient) and at ordinary
ones (0.3–2 rad).

Tolerance: every form evaluates the same coefficients by the same branch and differs from the
others only in the order of a few dozen floating-point operations on O(1) quantities, so they
agree to a few ulps (observed ≤ 6e-16 relative); 1e-12 relative to the largest entry of the
result is the project's compiled-vs-reference bound.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.compiled.codegen import Fragment, generate
from cartan.compiled.kernels import GROUP_OPS, with_fused

TOL = 1e-12

_CALLS = """
def call_Ad_inv_apply(g, X, out):
    g_Ad_inv_apply(g, X, out, g_work())


def call_E_apply(tau, xi, V, out):
    g_E_apply(tau, xi, V, out, g_work())


def call_dexp_inv_apply(xi, v, out):
    g_dexp_inv_apply(xi, v, out, g_work())


def call_coad_exp(xi, s, E):
    g_coad_exp(xi, s, E, g_work())
"""

GROUPS = {"SO3": {}, "SE3": {}, "SE2": {}, "SO4": {"name": "SO", "n": 4}}


def _group(name: str):
    kw = dict(GROUPS[name])
    return cartan.group(kw.pop("name", name), **kw)


def _module(name: str, closed: bool):
    """The calls compiled against the group's fragment (``closed``) or its matrix kernels only."""
    G = _group(name)
    frag = G.point_kernels()
    if not closed:
        frag = with_fused(Fragment(imports={f"g_{op}": frag.imports[f"g_{op}"] for op in GROUP_OPS
                                            if f"g_{op}" in frag.imports},
                                   constants=dict(frag.constants), source=_matrix_source(frag)))
    consts = Fragment(constants={"R_": G.dim, "M_": G.matrix_size, "D_": 1}, source=_CALLS)
    return G, generate(f"test-fused-{name}-{'closed' if closed else 'default'}", [frag, consts])


def _matrix_source(frag: Fragment) -> str:
    """The fragment's own source functions that define matrix kernels (``g_hat`` …), without
    the defaults of the fused operations (added again by ``with_fused``)."""
    blocks = [b for b in frag.source.split("\n\n\n") if b.strip()]
    keep = [b for b in blocks if any(f"def g_{op}(" in b for op in GROUP_OPS)]
    return "\n\n\n".join(keep)


def _algebra(G, scale: float, rng, shape=()) -> np.ndarray:
    u = rng.standard_normal((*shape, G.dim))
    if scale == 0.0:
        return u
    return scale * u / np.linalg.norm(u, axis=-1, keepdims=True)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


CASES = [(name, closed) for name in ("SO3", "SE3", "SE2") for closed in (True, False)] + [("SO4", True)]
SCALES = [1e-9, 0.3, 1.0, 2.0]


#: ``make test`` checks the closed forms the loops of SO(3), SE(3) and SE(2) use; the matrix-kernel
#: defaults and SO(4) (≈ 10-20 s of compilation each on a fresh cache) run in ``make test-slow``
FAST_CASES = {("SO3", True), ("SE3", True), ("SE2", True)}


@pytest.fixture(scope="module", params=[c if c in FAST_CASES else pytest.param(c, marks=pytest.mark.slow)
                                        for c in CASES],
                ids=[f"{n}-{'closed' if c else 'default'}" for n, c in CASES])
def compiled(request):
    return _module(*request.param)


@pytest.mark.parametrize("scale", SCALES)
def test_Ad_inv_apply(compiled, scale):
    G, mod = compiled
    rng = np.random.default_rng(1)
    for _ in range(5):
        g = G.exp(_algebra(G, scale, rng))
        X = rng.standard_normal((3, G.dim))
        out = np.empty_like(X)
        mod.call_Ad_inv_apply(g, X, out)
        ref = X @ G.Ad(G.inverse(g)).T
        assert _rel(out, ref) <= TOL


@pytest.mark.parametrize("scale", SCALES)
def test_E_apply(compiled, scale):
    G, mod = compiled
    rng = np.random.default_rng(2)
    for tau in (0.7, -1.3, 1.0):
        xi = _algebra(G, scale / abs(tau), rng)
        V = rng.standard_normal((2, G.dim))
        out = np.empty_like(V)
        mod.call_E_apply(tau, xi, V, out)
        ref = V @ G.E(np.array(tau), xi).T
        assert _rel(out, ref) <= TOL


@pytest.mark.parametrize("scale", SCALES)
def test_dexp_inv_apply(compiled, scale):
    G, mod = compiled
    rng = np.random.default_rng(4)
    for _ in range(5):
        xi = _algebra(G, scale, rng)
        v = rng.standard_normal(G.dim)
        out = np.empty(G.dim)
        mod.call_dexp_inv_apply(xi, v, out)
        assert _rel(out, G.dexp_inv(xi) @ v) <= TOL


@pytest.mark.parametrize("scale", SCALES)
def test_coad_exp(compiled, scale):
    G, mod = compiled
    rng = np.random.default_rng(5)
    for _ in range(5):
        xi = _algebra(G, scale, rng)
        s = rng.standard_normal(G.dim)
        ref = G.Ad(G.exp(xi)).T @ s
        E = np.empty((G.matrix_size, G.matrix_size))
        mod.call_coad_exp(xi, s, E)
        assert _rel(s, ref) <= TOL
        assert _rel(E, G.exp(xi)) <= TOL


def test_closed_forms_are_bound():
    """SO(3), SE(3) and SE(2) bind their closed forms; SO(4) takes the defaults from its matrices."""
    for name in ("SO3", "SE3", "SE2"):
        frag = _group(name).point_kernels()
        for op in ("Ad_inv_apply", "E_apply", "dexp_inv_apply"):
            assert frag.imports[f"g_{op}"][1] == f"{name.lower()}_{op}_point"
    frag = _group("SO4").point_kernels()
    assert "g_E_apply" not in frag.imports and "def g_E_apply(" in frag.source
