"""The residual's round-off floor in ``solve_static`` (docs/statics.md, "Method", the
"Convergence" item): a Newton iteration that ends on its increment test or stagnates is accepted
only with the residual within ``FLOOR_RATIO`` of the floor on every row, a floor built from each
term's own scale (``FLOOR_FACTOR·ε_mach·Σ|terms|``: the stresses' sensitivity to the strains'
round-off, the loads and the supports' ``k·|x|``).

Cases: the stiff propped cantilever of tests/test_statics_stiff.py (accepted: its residual,
far above ``tol·f``, sits at its floor ``EA·ε_mach``); the same rod with a Jacobian made wrong on
purpose (refused with the row, the residual and the floor named — a test on the step alone,
"a stagnation with ``max|δ| ≤ 1e4·xtol`` counts as converged", accepts the unloaded start); the
Scordelis–Lo quarter roof, whose floor at the diaphragm comes from its penalty support.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import cartan
import cartan.statics as statics
from cartan.problem import NodeForce, Problem
from cartan.statics import FLOOR_FACTOR, FLOOR_RATIO, ConvergenceError

EPS = float(np.finfo(float).eps)
EI, M, GA = 1.0, 1e-3, 1e9


def _propped(n: int = 9) -> Problem:
    """Clamped at u = 0, position held at u = L = 1, end moment M; stretch and shear stiffness GA."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[GA] * 3, bend_twist=[EI] * 3, mass=1.0,
                        rotational_inertia=[1.0, 1.0, 1.0])
    grid = cartan.Grid(n, length=1.0)
    ends = {"start": cartan.Clamped(), "end": cartan.Held(components=(0, 1, 2))}
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries=ends,
                          loads=[NodeForce(grid, [0.0, 0.0, 0.0, 0.0, 0.0, M], node=-1)])


def test_stiff_rod_converged_at_its_floor_is_accepted():
    """GA = 1e9: ‖r‖_∞ = 1.7e-7 ≫ tol·f = 1e-15 at the end, 0.098 of the floor (measured; 0.14–0.15
    at 17 and 33 nodes).  The largest floor is the axial row's two edges, ``4·ε·2·EA·|X|`` with
    |X| = 1 + O(1e-9), plus the shear stresses' round-off through the edges' dexp⁻¹, O(h·κ) =
    O(1e-4) relative (measured 4.7e-5)."""
    ds = cartan.solve_static(_propped(), tol=1e-12)
    assert ds.attrs["newton_converged_by"] == "increment"
    assert ds.attrs["newton_residual_max"] > 1e6 * ds.attrs["newton_residual_tol"]  # far above tol·f ...
    assert ds.attrs["newton_residual_floor_ratio"] <= 1.0  # ... and at its floor
    assert ds.attrs["newton_residual_floor"] == pytest.approx(FLOOR_FACTOR * EPS * 2.0 * GA, rel=1e-3)


@pytest.mark.parametrize(("stiffer", "path"), [(1e6, "stagnates above its round-off floor"),
                                               (1e12, "fell below xtol")])
def test_a_wrong_jacobian_is_refused_with_the_row_and_the_floor(monkeypatch, stiffer, path):
    """Newton steps solved with a Jacobian ``stiffer`` times too stiff: at 1e6 no damped step passes
    the monotonicity test (the iterate never moves, max|δ| = 2.5e-10 ≤ 1e4·xtol, which a test on
    the step alone accepts as an equilibrium); at 1e12 the steps fall below xtol and the
    residual stays at M.  Either is refused, naming the end node's moment row, where
    |r| = M = 1e-3 is 1.8e4 times its floor (``4·ε·½h·GA`` there: the axial stresses' round-off
    through the edge's dexp⁻¹)."""
    factorise = statics._factorise

    def wrong(*args, **kwargs):
        solve = factorise(*args, **kwargs)
        return lambda b: solve(b) / stiffer

    monkeypatch.setattr(statics, "_factorise", wrong)
    with pytest.raises(ConvergenceError, match=path) as err:
        cartan.solve_static(_propped(), tol=1e-12, adaptive_load=False)
    msg = str(err.value)
    assert "node 8, component 5" in msg and "round-off floor" in msg
    ratio = float(re.search(r"is (\S+) times its round-off floor", msg).group(1))
    assert ratio > FLOOR_RATIO
    if stiffer == 1e6:  # a test on the step alone would accept it
        assert float(re.search(r"max\|δ\| = (\S+),", msg).group(1)) <= 1e4 * 1e-12


def test_shell_with_a_stiff_penalty_support_is_accepted_by_its_floor(monkeypatch):
    """The Scordelis–Lo quarter roof on 9 × 9 nodes (diaphragm: a penalty support of stiffness
    ``PENALTY·Et/h²``): Newton ends on its increment test with ‖r‖_∞ = 0.14 (tol·f = 6e-12), 0.10
    of its floor (measured).  The floor of the worst rows is the support's ``k·ε·|x|``: the floor
    without the supports' terms would put the residual 4.6e5 times above it (measured)."""
    from cartan_cosserat_surface.cases_shells import scordelis_lo_problem

    prob, _ = scordelis_lo_problem(9)
    seen = []
    floor = statics._residual_floor

    def spy(eq, state, mu, lam):
        seen.append((eq, state, mu, lam))
        return floor(eq, state, mu, lam)

    monkeypatch.setattr(statics, "_residual_floor", spy)
    ds = cartan.solve_static(prob, tol=1e-10)
    assert ds.attrs["newton_converged_by"] == "increment"
    assert ds.attrs["newton_residual_max"] > 1e6 * ds.attrs["newton_residual_tol"]
    assert ds.attrs["newton_residual_floor_ratio"] <= 1.0
    eq, state, mu, lam = seen[-1]  # the final state's floor (the Dataset's)
    r = np.abs(eq.residual(state, mu, lam))
    bare = Problem(prob.medium, prob.grid, prob.initial, prob.boundaries,
                   [load for load in prob.loads if load.scaled])  # the supports left out
    no_support = floor(statics._Equilibrium(bare), state, mu, lam)
    assert np.max(r / floor(eq, state, mu, lam)) <= 1.0
    assert np.max(r / no_support) > FLOOR_RATIO
