"""Driven ends (:class:`cartan.Driven`) on the lattice's generated loops: the operator set's
driven nodes (their ξ and ∂K/∂N(ξ) in ``LatticeData``, :func:`cartan.schemes._lattice_ops.driven_fragment`)
against ``Integrator.step`` on the numpy path.

A Cosserat rod clamped at u = 0 and driven at u = L, stepped 50 times by the Python step and by
the generated loop in three blocks (1, 2, 47 steps): the generated loop really takes the steps
(the hand-written rod loops decline driven ends; the set serves the loops of lie-verlet,
lie-euler, rkmk4 and overdamped and no other), the momenta, edges, dissipated energy and the
supports' work (``external_work``, the power ``−w W·ξ`` at the driven nodes) agree to round-off,
and the end frame is Φ(0)exp(tξ) to round-off.

The lie-verlet runs use the generated module of the rod of tests/test_driven_end.py (the same
medium kernels: one module, compiled once per cache).  Slow: the other integrators' loops and a
plate's driven edge (coupled corners), each compiled on first use.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import run_both

import cartan
from cartan.integrators import RKMK4, ImplicitMidpoint, LieVerlet, Overdamped, Rattle
from cartan.integrators.explicit import LieEuler
from cartan.schemes.lattice import Lattice

#: compiled against Python, relative to the largest value: a force sums a few terms per node in
#: another order (round-off ≈ 1e-16 per evaluation), 50 steps (measured: below 4e-15)
TOL = 1e-12
NSTEPS = 50
BLOCKS = (1, 2, NSTEPS - 3)

#: a twist about the rod's axis, and a screw along it (translation and rotation about e₁: parts
#: in commuting blocks of lie-verlet's free flow, so its split flow moves the end by exp(Δtξ))
TWIST = np.array([0.0, 0.0, 0.0, 0.7, 0.0, 0.0])
AXIAL_SCREW = np.array([0.3, 0.0, 0.0, 0.7, 0.0, 0.0])
#: a general velocity (every component): lie-euler, rkmk4 and overdamped move it by exp(Δtξ)
SCREW = np.array([0.1, -0.2, 0.05, 0.3, -0.4, 0.5])


def _rod():
    # the rod of tests/test_driven_end.py (the same generated module)
    return cartan.medium("cosserat-rod", stretch_shear=[4.0, 4.0, 4.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                         rotational_inertia=[1.0, 0.5, 0.5])


def _problem(xi, n: int = 21, loads=()) -> cartan.Problem:
    rod = _rod()
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Driven(velocity=xi)}, loads=list(loads))


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b), initial=0.0)) / max(float(np.max(np.abs(b), initial=0.0)), 1e-300)


def _assert_compiled_agrees(problem, make, dt: float):
    """The Python and the generated runs agree to round-off; returns the scheme and the compiled state."""
    scheme, (ref, _), (fast, integ) = run_both(Lattice, problem, make, dt, NSTEPS, BLOCKS)
    ops = scheme.compiled_operators()
    assert ops.data.any_driven and not ops.ok  # a set for some loops only
    assert ops.serves("lie_verlet_loop") and ops.serves("rkmk_loop") and not ops.serves("implicit_loop")
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    assert not scheme.compiled_advance(make(), start, dt, 1)  # so the generated loop took the steps
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == integ.nstep == NSTEPS
    assert fast.t == ref.t
    assert _rel(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert _rel(fast.arrays[key], ref.arrays[key]) <= TOL, key
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= TOL * max(abs(ref.scalars[key]), 1e-300), key
    assert ref.scalars["external_work"] != 0.0  # the supports work
    return scheme, fast


def _assert_end_moves_by_exp(scheme, state, xi):
    """The driven end's frame is Φ(0)exp(tξ): round-off of the 20 edge products that rebuild it
    and of 50 exact steps (≲ 1e-13)."""
    g = scheme.group
    exact = scheme.problem.initial.Phi[-1] @ g.exp(state.t * np.asarray(xi, dtype=float))
    assert np.max(np.abs(scheme.frames(state)[-1] - exact)) < 1e-12
    mask, Nd, Sd = scheme._driven
    assert np.array_equal(state.S[mask], Sd[mask])  # its momentum is ∂K/∂N(ξ), set after every step
    assert np.array_equal(scheme.velocity(state)[mask], Nd[mask])


@pytest.mark.slow  # (the driven rod's loop compiles on first use: ≈ 45–65 s on a fresh cache)
@pytest.mark.parametrize("xi", [TWIST, AXIAL_SCREW], ids=["twist", "axial-screw"])
def test_lie_verlet_moves_a_driven_end_compiled(xi):
    scheme, fast = _assert_compiled_agrees(_problem(xi), LieVerlet, 2e-3)
    _assert_end_moves_by_exp(scheme, fast, xi)


@pytest.mark.slow  # (the driven rod's loop compiles on first use: ≈ 45–65 s on a fresh cache)
def test_lie_verlet_with_damping_books_the_same_work():
    """Damping: the closing kick is implicit in it, W carried between steps is −Γξ at the driven
    node (as on the numpy path), and the dissipated energy agrees too."""
    xi = np.array([0.2, 0.1, -0.3, 0.0, 0.0, 0.0])
    scheme, fast = _assert_compiled_agrees(_problem(xi, loads=[cartan.Damping([0.1] * 6)]), LieVerlet, 2e-3)
    assert fast.scalars["dissipated_energy"] > 0.0
    _assert_end_moves_by_exp(scheme, fast, xi)


@pytest.mark.slow  # (the driven rod's loop compiles on first use: ≈ 45–65 s on a fresh cache)
def test_rattle_without_rows_runs_lie_verlets_loop():
    """A medium without constrained strains: rattle's step is lie-verlet's, and so is its loop."""
    scheme, fast = _assert_compiled_agrees(_problem(TWIST), Rattle, 2e-3)
    _assert_end_moves_by_exp(scheme, fast, TWIST)


def test_the_other_compiled_paths_decline():
    """implicit-midpoint (its Newton loop) and the compiled diagnostics leave driven ends to the
    numpy path: the set is not ``ok``, and says why."""
    scheme = Lattice(_problem(TWIST))
    ops = scheme.compiled_operators()
    assert not ops.ok and "Driven" in ops.reason and "implicit-midpoint" in ops.reason
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    assert not ImplicitMidpoint().compiled_advance(scheme, state, 1e-3, 1)
    assert state.scalars["nstep"] == 0


@pytest.mark.slow  # (each loop compiles on first use: ≈ 25–50 s on a fresh cache)
@pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")
@pytest.mark.parametrize(("make", "loads", "dt"), [
    (LieEuler, (), 2e-3), (RKMK4, (), 2e-3),
    (lambda: Overdamped(1), (cartan.Damping([10.0] * 6),), 1e-3),
    (lambda: Overdamped(2), (cartan.Damping([10.0] * 6),), 1e-3),
], ids=["lie-euler", "rkmk4", "overdamped-1", "overdamped-2"])
def test_the_other_explicit_loops_move_a_driven_end_compiled(make, loads, dt):
    scheme, fast = _assert_compiled_agrees(_problem(SCREW, n=11, loads=loads), make, dt)
    g = scheme.group
    exact = scheme.problem.initial.Phi[-1] @ g.exp(fast.t * SCREW)
    assert np.max(np.abs(scheme.frames(fast)[-1] - exact)) < 1e-12


@pytest.mark.slow  # (the plate's module compiles on first use)
def test_a_plate_edge_driven_compiled():
    """A plate's edge u = L turned about its own line (coupled corners: the supports' power sums
    the corner stresses of the edges at the driven nodes)."""
    shell = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.1, density=1.0)
    grid = cartan.Grid((9, 5), length=(1.0, 0.5))
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
    problem = cartan.Problem(shell, grid, shell.initial_state(grid, "flat"),
                             {"u-start": cartan.Clamped(), "u-end": cartan.Driven(velocity=xi)})
    scheme, fast = _assert_compiled_agrees(problem, LieVerlet, 2e-3)
    exact = np.einsum("vij,jk->vik", problem.initial.Phi[-1], shell.group.exp(fast.t * xi))
    assert np.max(np.abs(scheme.frames(fast)[-1] - exact)) < 1e-12
