"""The Poincaré group's fused products (``g_coad_exp``, ``g_dexp_inv_apply``, ``g_E_apply``,
``g_Ad_inv_apply`` of :data:`cartan.compiled.kernels.FUSED_OPS`) and the pure-translation
branches of ``exp`` and 𝓔.

Each fused kernel is compared with the composition of the point kernels it replaces (the
matrix — ``poincare_exp_point``, ``poincare_Ad_point``, ``poincare_dexp_inv_point``,
``poincare_E_point``, ``poincare_inverse_point`` — times the vector), on random elements:
pure translations (the in-line branch; the string's nodal velocities and motions), a tiny
Lorentz part (the series branch of dexp⁻¹ and 𝓔), and ordinary and large ones (rapidity and
angle up to 2.5). The fused kernels run as Python here (``py_func``; the point kernels they
call compiled), so the test compiles nothing beyond what the other Poincaré tests share; the
generated ``rkmk4`` and ``lie-euler`` loops of the string run them compiled
(``tests/test_relativistic_rod.py`` compares those runs with the numpy path).  The
pure-translation branches of ``poincare_exp_point`` and ``poincare_E_point`` are compared
with the group's numpy ``exp`` and with ``Δt(I + ½Δt ad_ξ)`` (exact for ad_ξ² = 0).

Tolerance: both sides sum the same products of the same matrix entries, in another order for
the in-line branches (zero products dropped), so they agree to a few ulps of the largest term;
1e-14 relative to the largest entry of the result.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan._backend import use_backend
from cartan.groups import poincare as P

TOL = 1e-14
#: scale of the Lorentz part: 0 (pure translation), series branch, ordinary, large
LORENTZ = (0.0, 1e-4, 0.7, 2.5)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def _xi(rng, z: float) -> np.ndarray:
    xi = rng.standard_normal(10)
    xi[4:] *= z / max(float(np.max(np.abs(xi[4:]))), 1e-300)
    return xi


def _mat(kernel, *args, shape=(10, 10)):
    out = np.empty(shape)
    kernel(*args, out)
    return out


@pytest.mark.parametrize("z", LORENTZ)
def test_fused_equal_point_kernels(z):
    rng = np.random.default_rng(7)
    work = (np.empty((1, 1)),)  # unused by the closed forms
    for _ in range(4):
        xi, v = _xi(rng, z), rng.standard_normal(10)
        X = rng.standard_normal((3, 10))
        tau = 0.37
        # coad_exp: E = exp ξ, s ← Ad_Eᵀ s
        E_ref = _mat(P.poincare_exp_point, xi, shape=(5, 5))
        s_ref = _mat(P.poincare_Ad_point, E_ref).T @ v
        s, E = v.copy(), np.empty((5, 5))
        P.poincare_coad_exp_point.py_func(xi, s, E, work)
        assert _rel(E, E_ref) <= TOL and _rel(s, s_ref) <= TOL, z
        # dexp⁻¹(ξ) v
        out = np.empty(10)
        P.poincare_dexp_inv_apply_point.py_func(xi, v, out, work)
        assert _rel(out, _mat(P.poincare_dexp_inv_point, xi) @ v) <= TOL, z
        # 𝓔(τ, ξ) V[a]
        outs = np.empty((3, 10))
        P.poincare_E_apply_point.py_func(tau, xi, X, outs, work)
        assert _rel(outs, X @ _mat(P.poincare_E_point, tau, xi).T) <= TOL, z
        # Ad_{g⁻¹} X[a], g = exp ξ (a pure translation where z = 0)
        gi = _mat(P.poincare_inverse_point, E_ref, shape=(5, 5))
        P.poincare_Ad_inv_apply_point.py_func(E_ref, X, outs, work)
        assert _rel(outs, X @ _mat(P.poincare_Ad_point, gi).T) <= TOL, z


def test_pure_translation_exp_and_E():
    """``exp{y; 0} = (y; I)`` against the spinor formula (numpy path), 𝓔 against ``Δt(I + ½Δt ad_ξ)``."""
    G = cartan.group("Poincare")
    rng = np.random.default_rng(11)
    for _ in range(4):
        xi = _xi(rng, 0.0)
        with use_backend("numpy"):
            ref = G.exp(xi)
        assert _rel(_mat(P.poincare_exp_point, xi, shape=(5, 5)), ref) <= TOL
        dt = 0.3
        ref_E = dt * (np.eye(10) + 0.5 * dt * _mat(P.poincare_ad_point, xi))
        assert _rel(_mat(P.poincare_E_point, dt, xi), ref_E) <= TOL


def test_fused_are_bound():
    """The generated modules bind the Poincaré closed forms, not the defaults of ``FUSED_OPS``."""
    frag = cartan.group("Poincare").point_kernels()
    for op in ("coad_exp", "dexp_inv_apply", "E_apply", "Ad_inv_apply"):
        assert frag.imports[f"g_{op}"] == ("cartan.groups.poincare", f"poincare_{op}_point"), op


@pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")  # lie-euler: no stable Δt for undamped motion
@pytest.mark.slow  # the string's generated lie-euler and rkmk4 loops (≈ 2 min each on a fresh cache)
@pytest.mark.parametrize("integrator", ["lie-euler", "rkmk4"])
def test_nambu_goto_fused_loops_match_numpy(integrator):
    """The Nambu–Goto loop's compiled steps (the fused kernels' pure-translation branches: the
    nodal velocities have no Lorentz part) against the numpy path: one formula in two orders over
    a few steps, so round-off (1e-12 relative, the conformance kit's compiled-vs-reference bound)."""
    import math

    medium = cartan.medium("relativistic-rod")
    grid = cartan.Grid(32, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(medium, grid, medium.initial_state(grid, "loop"))
    scheme = cartan.registry("schemes")["lattice"](problem)
    dt = 0.1 * cartan.registry("integrators")["lie-verlet"]().dt_max(scheme, scheme.initial_state())
    kw = dict(integrator=integrator, dt=dt, t_end=5 * dt, save_every=5, progress=False)
    fast, ref = cartan.simulate(problem, **kw), cartan.simulate(problem, **kw, compiled=False)
    for k in ("S", "X"):
        assert _rel(fast[k].values, ref[k].values) <= 1e-12, k
