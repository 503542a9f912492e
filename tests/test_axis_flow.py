"""The one-axis free flow ``g_axis_flow(k, t, s, acc, work)`` (lattice ``lie-verlet``).

``E = exp(t b_k)``, ``s ← Ad_Eᵀ s`` and ``acc ← acc E`` in place.  The closed forms of SO(3),
SE(3), SE(2) and the Poincaré group (``so3_axis_flow_point``, ``se3_axis_flow_point``,
``se2_axis_flow_point``, ``poincare_axis_flow_point``: a turn in one plane, a boost in one
plane, a shift) are compared
with the generic composition — the group's ``exp``, ``Ad`` (transposed) and the matrix product,
on the numpy reference path — along every axis, at tiny angles (±1e-9 and 0.05 rad: the
Taylor-series branch of the coefficients), ordinary ones and large ones (up to 3 rad, near the
injectivity radius π; for a boost, rapidity 3, entries up to cosh 3 ≈ 10), of both signs.  The generic default of
:data:`cartan.compiled.kernels.FUSED_OPS` (``g_exp``, ``g_Ad_T``, ``g_compose`` in a generated
module), which groups without a closed form take, is compared the same way for SO(4) (slow:
it compiles a module).  The closed forms run as Python here (their
coefficient functions compiled), which keeps the test from compiling kernels on a fresh cache;
compiled, they run in every generated ``lie-verlet`` loop of SO(3), SE(3), SE(2) and Poincaré, which
``tests/test_lattice_compiled.py`` and the relativistic-rod tests compare with the reference path.

Tolerance: both sides evaluate the same coefficients (sin θ/θ and (1 − cos θ)/θ² by the same
branch; Poincaré: cos, sin, cosh, sinh against the spinor exponential's coefficients) and differ
only in the order of a few dozen floating-point operations on quantities of the size of the
largest entry (for a boost, cosh t times that of ``s`` and ``acc``), so they agree to a few
ulps of it; 1e-12 relative to the largest entry is the project's compiled-vs-reference bound.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan._backend import use_backend
from cartan.compiled.codegen import Fragment, generate
from cartan.groups.poincare import poincare_axis_flow_point
from cartan.groups.se2 import se2_axis_flow_point
from cartan.groups.se3 import se3_axis_flow_point
from cartan.groups.so3 import so3_axis_flow_point

TOL = 1e-12
ANGLES = (1e-9, -1e-9, -0.05, 0.3, -1.0, 2.0, -2.7, 3.0)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def _reference(G, k: int, t: float, s: np.ndarray, acc: np.ndarray):
    """``(Ad_Eᵀ s, acc E)`` with ``E = exp(t b_k)`` from the group's exp and Ad (numpy path)."""
    xi = np.zeros(G.dim)
    xi[k] = t
    with use_backend("numpy"):
        E = G.exp(xi)
        return G.Ad(E).T @ s, acc @ E


def _check(G, flow, seed: int) -> None:
    rng = np.random.default_rng(seed)
    for k in range(G.dim):
        for t in ANGLES:
            s = rng.standard_normal(G.dim)
            with use_backend("numpy"):
                acc = G.exp(rng.standard_normal(G.dim))
            ref_s, ref_acc = _reference(G, k, t, s, acc)
            flow(k, t, s, acc)
            assert _rel(s, ref_s) <= TOL, (k, t)
            assert _rel(acc, ref_acc) <= TOL, (k, t)


@pytest.mark.parametrize("name, kernel", [("SO3", so3_axis_flow_point), ("SE3", se3_axis_flow_point),
                                          ("SE2", se2_axis_flow_point), ("Poincare", poincare_axis_flow_point)])
def test_closed_form_equals_exp_Ad_compose(name, kernel):
    G = cartan.group(name)
    work = (np.empty((1, 1)),)  # unused by the closed forms

    def flow(k, t, s, acc):
        kernel.py_func(k, t, s, acc, work)  # (its coefficients compiled; the loops run it compiled)

    _check(G, flow, seed=3)


def test_closed_forms_are_bound():
    """SO(3), SE(3), SE(2) and Poincaré bind their closed forms; a group without one takes the default."""
    for name in ("SO3", "SE3", "SE2", "Poincare"):
        assert cartan.group(name).point_kernels().imports["g_axis_flow"][1] == f"{name.lower()}_axis_flow_point"
    frag = cartan.group("SO", n=4).point_kernels()
    assert "g_axis_flow" not in frag.imports and "def g_axis_flow(" in frag.source


_CALL = """
def call_axis_flow(k, t, s, acc):
    g_axis_flow(k, t, s, acc, g_work())
"""


@pytest.mark.slow
@pytest.mark.parametrize("name, kw", [("SO", {"n": 4})])
def test_generic_default_equals_exp_Ad_compose(name, kw):
    G = cartan.group(name, **kw)
    consts = Fragment(constants={"R_": G.dim, "M_": G.matrix_size, "D_": 1}, source=_CALL)
    mod = generate(f"test-axis-flow-{G.name}", [G.point_kernels(), consts])
    _check(G, mod.call_axis_flow, seed=4)
