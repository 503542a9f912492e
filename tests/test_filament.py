"""The Kirchhoff filament and the constrained strain components of the statics (paper §III.E,
§IV.E, §VII.A): multipliers, constraint residuals, the elastica, Euler buckling, the Kirchhoff
analogy and the cross-medium limit of the Cosserat rod."""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np
import pytest

import cartan
from cartan.statics import _Equilibrium

try:
    import cartan_filament.plugin as filament_plugin
except ModuleNotFoundError:  # not installed yet: the package beside the others
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "plugins"))
    import cartan_filament.plugin as filament_plugin

from cartan_verification.case import observed_orders, run_case  # noqa: E402
from cartan_verification.references import ELASTICA_TABLE, cantilever_elastica  # noqa: E402


@pytest.fixture(scope="module", autouse=True)
def registered():
    """The filament registered (through its entry point when installed, else in-process)."""
    from cartan.plugins import reset_registry

    if "filament" not in cartan.registry("media"):
        reset_registry([("filament", filament_plugin)])
    yield


@pytest.fixture(scope="module")
def cases():
    from cartan_filament import cases as module

    return module


def _cantilever(n: int, alpha: float, **params):
    rod = cartan.medium("filament", **params)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -alpha, 0.0, 0.0, 0.0, 0.0])})


# ---------------------------------------------------------------------------- the medium
@pytest.mark.parametrize("params, word", [
    ({"bending": -1.0}, "bending"), ({"bending": [1.0, 2.0, 3.0]}, "bending"), ({"twist": 0.0}, "twist"),
    ({"rest_curvature": [1.0]}, "rest_curvature"), ({"rest_twist": math.nan}, "rest_twist"),
    ({"mass": 0.0}, "mass"), ({"rotational_inertia": [1.0, -1.0, 1.0]}, "rotational_inertia"),
])
def test_bad_parameters(params, word):
    with pytest.raises(ValueError, match=word):
        cartan.medium("filament", **params)


def test_energy_ignores_the_constrained_strains():
    rod = cartan.medium("filament", bending=[1.0, 2.0], twist=0.5, rest_curvature=[0.3, -0.2], rest_twist=0.1)
    comp, val = rod.constrained_strains()
    assert list(comp) == [0, 1, 2] and list(val) == [1.0, 0.0, 0.0]
    rng = np.random.default_rng(1)
    X = rng.normal(size=(5, 1, 6))
    Y = X.copy()
    Y[..., :3] += rng.normal(size=(5, 1, 3))
    np.testing.assert_array_equal(rod.potential(X), rod.potential(Y))
    np.testing.assert_array_equal(rod.stress(X), rod.stress(Y))
    assert not np.any(rod.stress(X)[..., :3])
    # U = ½C(π₁ − π₁⁰)² + ½B₂(π₂ − π₂⁰)² + ½B₃(π₃ − π₃⁰)²
    d = X[..., 0, 3:] - np.array([0.1, 0.3, -0.2])
    np.testing.assert_allclose(rod.potential(X), 0.5 * (0.5 * d[:, 0]**2 + d[:, 1]**2 + 2.0 * d[:, 2]**2))
    assert cartan.medium("filament", **rod.parameters()).parameters() == rod.parameters()


def test_constitutive_stress_on_a_constrained_component_is_refused():
    from cartan_cosserat.rod import CosseratRod

    class Stretchy(CosseratRod):
        name = "stretchy"

        def constrained_strains(self):
            return np.array([0]), np.array([1.0])

    rod = Stretchy(stretch_shear=[10.0, 10.0, 10.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                   rotational_inertia=[1.0, 1.0, 1.0])
    grid = cartan.Grid(5, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": cartan.Clamped()})
    with pytest.raises(ValueError, match="constrained strain component 0"):
        cartan.solve_static(prob)


# ---------------------------------------------------------------------------- the multiplier block
def test_constraint_jacobian_and_reaction_are_consistent():
    """B_c is the derivative of the constraint values along the drifts (central differences),
    and the residual's reaction of the multipliers ν is B_cᵀν (the Jacobian's columns)."""
    prob = _cantilever(7, 1.0, rest_curvature=[0.5, 1.0], rest_twist=0.3)
    eq = _Equilibrium(prob)
    rng = np.random.default_rng(3)
    state = eq.state0.copy()
    eq.sch.drift(state, 1.0, eq.full(0.2 * rng.normal(size=eq.nunk)))
    Bc = eq._constraint_matrix(state).toarray()
    h = 1e-6
    fd = np.empty_like(Bc)
    for j in range(eq.nunk):
        e = np.zeros(eq.nunk)
        e[j] = h
        plus, minus = state.copy(), state.copy()
        eq.sch.drift(plus, 1.0, eq.full(e))
        eq.sch.drift(minus, -1.0, eq.full(e))
        fd[:, j] = (eq.constraint_values(plus) - eq.constraint_values(minus)) / (2 * h)
    np.testing.assert_allclose(Bc, fd, atol=1e-7 * np.abs(Bc).max())
    nu = rng.normal(size=eq.ncon)
    mu = np.concatenate([np.zeros(eq.npin), nu])
    react = eq.residual(state, mu, 0.0)[: eq.nunk] - eq.residual(state, 0.0 * mu, 0.0)[: eq.nunk]
    np.testing.assert_allclose(react, Bc.T @ nu, atol=1e-12 * np.abs(react).max())


# ---------------------------------------------------------------------------- statics
@pytest.fixture(scope="module")
def elastica_runs():
    out = {}
    for n in (11, 21, 41):
        out[n] = cartan.solve_static(_cantilever(n, 2.0), load_steps=2)
    return out


def test_reference_elastica_table():
    """The tabulated elastica (five digits) from the elliptic-integral solution."""
    for alpha, (v, s) in ELASTICA_TABLE.items():
        v_ref, s_ref = cantilever_elastica(alpha)
        assert abs(v_ref - v) <= 5e-6 and abs(s_ref - s) <= 5e-6


def test_static_elastica_second_order_and_constraints(elastica_runs):
    v_ref, s_ref = cantilever_elastica(2.0)
    errs, tips = [], []
    for n, ds in elastica_runs.items():
        tip = ds["position"].isel(time=0, node=-1).values
        tips.append(tip)
        errs.append(max(abs(-tip[1] - v_ref), abs(1.0 - tip[0] - s_ref)))
        # the constraint θ = (1, 0, 0) on every edge: converged to 1e-3·tol = 1e-13, in practice one
        # quadratic step beyond it, at round-off
        assert ds.attrs["constraint_residual_max"] <= 1e-13
        X = ds["X"].isel(time=0).values.reshape(-1, 6)
        assert np.max(np.abs(X[:, :3] - [1.0, 0.0, 0.0])) <= 1e-13
        # inextensible: each edge is the screw curve exp(s hX_e) of arc length h|θ_e| = h (its chord
        # is shorter), so the length is the reference length
        assert abs(np.sum(np.linalg.norm(X[:, :3], axis=1)) / (n - 1) - 1.0) <= 1e-9
        # the multipliers are the internal force: |n| = P on every edge (spatial force constant)
        n_e = ds["constraint_force"].isel(time=0).values
        assert n_e.shape == (n - 1, 3)
        assert np.max(np.abs(np.linalg.norm(n_e, axis=1) - 2.0)) <= 20.0 / (n - 1) ** 2
    p = observed_orders(errs)
    assert np.all(np.abs(p - 2.0) <= 0.2), (errs, p)
    # Richardson extrapolation reproduces the five tabulated digits (α = 2: 0.49346, 0.16064)
    rich = (4.0 * tips[-1] - tips[-2]) / 3.0
    assert abs(-rich[1] - ELASTICA_TABLE[2.0][0]) <= 1e-5 and abs(1.0 - rich[0] - ELASTICA_TABLE[2.0][1]) <= 1e-5


def test_elastica_case_orders(cases):
    case = cases.FilamentCantileverElastica()
    errors = []
    for level in (0, 1, 2):
        e, ds = run_case(case, level)
        errors.append(e)
        assert float(ds["constraint_residual"].max()) <= 1e-11  # 1e-3·tol of the corrector
        assert ds["constraint_force"].dims == ("path", "constrained_edge", "constrained_component")
    assert np.all(np.abs(observed_orders(errors) - 2.0) <= 0.2), errors
    assert errors[-1] <= 2.0 * case.tolerance


def test_kirchhoff_analogy_orders(cases):
    case = cases.KirchhoffAnalogy()
    drifts = []
    for level in (0, 1, 2):
        problem, settings = case.problem(level)
        ds = case.run(problem, settings)
        parts = case.parts(ds, problem)
        assert parts["constraint residual"] <= 1e-13
        drifts.append([parts[k] for k in ("n_norm", "m_dot_n", "twist_moment", "hamiltonian")])
    drifts = np.array(drifts)
    orders = np.log2(drifts[:-1] / drifts[1:])
    assert np.all(np.abs(orders[-1] - 2.0) <= 0.2), (drifts, orders)
    assert drifts[-1].max() <= case.tolerance


def test_euler_buckling_case(cases):
    """Pinned–pinned, the spin about the axis held by a rotation pin: the bifurcation at the
    lattice's critical load P_cr(1 − π²h²/12 + O(h⁴)) (the leading term within 2 %), then the
    buckled branch."""
    case = cases.FilamentEulerBuckling()
    errors = []
    for level in (0, 1):
        e, ds = run_case(case, level)
        errors.append(e)
        parts = case.parts(ds)
        h = 1.0 / (10 * 2**level)
        lead = math.pi**2 * h * h / 12.0
        assert abs(parts["critical_load"] - lead) <= 0.02 * lead, parts
        assert int(ds["branch"].values[-1]) == 1
        assert parts["constraint residual"] <= 1e-11
        # the spin pin's reaction moment vanishes on the planar path
        assert np.max(np.abs(ds["reaction"].values[:, 3])) <= 1e-8
    assert abs(observed_orders(errors)[-1] - 2.0) <= 0.2, errors


def test_solve_static_without_constraints_unchanged():
    """A medium without constrained strains has no multipliers and no constraint outputs."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[100.0, 100.0, 100.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                        rotational_inertia=[1.0, 1.0, 1.0])
    grid = cartan.Grid(6, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -0.1, 0.0, 0.0, 0.0, 0.0])})
    assert _Equilibrium(prob).ncon == 0
    ds = cartan.solve_static(prob)
    assert "constraint_force" not in ds


def test_scene_runs():
    sc = cartan.scene("filament-elastica")
    ds = sc.run()
    v_ref, s_ref = cantilever_elastica(2.0)
    tip = ds["position"].isel(time=-1, node=-1).values
    # n = 41: the O(h²) error is 5.8e-5 (test_static_elastica_second_order_and_constraints)
    assert abs(-tip[1] - v_ref) <= 1e-4 and abs(1.0 - tip[0] - s_ref) <= 1e-4
    assert ds.attrs["constraint_residual_max"] <= 1e-13


# ---------------------------------------------------------------------------- slow
@pytest.mark.slow
@pytest.mark.parametrize("name", ["filament-cantilever-elastica", "filament-euler-buckling",
                                  "filament-kirchhoff-analogy"])
def test_cases_all_levels(cases, name):
    case = {c.name: c for c in cases.all_cases()}[name]
    errors = [run_case(case, level)[0] for level in case.levels]
    assert errors[-1] <= case.tolerance
    assert np.all(np.abs(observed_orders(errors)[-2:] - 2.0) <= 0.3), errors


@pytest.mark.slow
def test_cosserat_limit_slope(cases):
    out = cases.cosserat_limit()
    assert abs(out["slope"] + 1.0) <= 0.1, out
    assert out["errors"][-1] <= 1e-5


@pytest.mark.slow
def test_conformance():
    from cartan.testing import check_medium

    check_medium("filament", {})


def test_natural_curvature_and_twist_free_filament():
    """A free filament with π⁰ = (τ, κ₂, κ₃) relaxes from straight to its rest helix: every edge
    strain is (1, 0, 0; π⁰) and the multipliers (no load) vanish."""
    pi0 = np.array([0.5, 1.0, 2.0])
    rod = cartan.medium("filament", bending=[1.0, 1.5], twist=0.8, rest_twist=pi0[0], rest_curvature=pi0[1:])
    grid = cartan.Grid(21, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": cartan.Clamped()})
    ds = cartan.solve_static(prob, max_iter=50)
    X = ds["X"].isel(time=0).values.reshape(-1, 6)
    np.testing.assert_allclose(X, np.broadcast_to(np.concatenate([[1.0, 0.0, 0.0], pi0]), X.shape), atol=1e-10)
    assert np.max(np.abs(ds["constraint_force"].isel(time=0).values)) <= 1e-9
