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
from cartan.integrators import RKMK4, LieVerlet, Overdamped, Rattle
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
    assert ops.serves("lie_verlet_loop") and ops.serves("rkmk_loop") and ops.serves("implicit_loop")
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


def test_the_set_serves_the_driven_loops():
    """The set with driven ends is not ``ok`` (the hand-written loops decline it), says why, and
    serves the generated loops that move driven ends and the compiled diagnostics
    (tests/test_driven_diagnostics.py; implicit-midpoint's Newton loop:
    tests/test_driven_compiled_implicit.py)."""
    from cartan.compiled.diagnostics import SERVED

    scheme = Lattice(_problem(TWIST))
    ops = scheme.compiled_operators()
    assert not ops.ok and "Driven" in ops.reason and "diagnostics" in ops.reason
    assert ops.serves("implicit_loop") and ops.serves("rattle_loop") and ops.serves(SERVED)


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


# ---------------------------------------------------------------------------- rattle
# The inextensible filament of tests/test_driven_rattle.py, clamped at s = 0 (or free) and driven
# at s = L, in rattle's generated loop (cartan.integrators.rattle_loop): the driven velocity
# enters the rows (B_c N = B_u N_u + B_d ξ, N = ξ at the driven node), the free flow moves the
# driven node by exp(Δtξ), and the support's work books the power −λᵀB_dξ of the rows' force on
# the driven node (λ the force-level multipliers with the rows' rate to round-off, a central
# difference: ≈ 1e-10 relative, Rattle._rows_rate_exact) and the first step's impulse (the
# velocity projection from rest).

#: the support's work against the Python path: its power −λᵀB_dξ takes λ with the rows' rate by
#: a central difference (round-off ≈ 1e-16/ε₀ ≈ 1e-10 relative per step, ε₀ = 1e-5/max|N|)
RATTLE_WORK_TOL = 1e-10


def _driven_filament(xi, start=None, loads=None, n: int = 11, straight: bool = False, J: float = 0.05):
    fil = cartan.medium("filament", bending=1.0, twist=1.0, mass=1.0, rotational_inertia=[J, 0.05, 0.05])
    grid = cartan.Grid(n, length=1.0)
    initial = (fil.initial_state(grid, "straight") if straight
               else fil.initial_state(grid, "arc", curvature=1.5, centered=True))
    if loads is None:
        loads = [fil.make_load("gravity", g=[0.0, 0.0, -2.0])]
    return cartan.Problem(fil, grid, initial, {"start": start or cartan.Clamped(), "end": cartan.Driven(velocity=xi)},
                          loads=list(loads))


def test_rattle_takes_a_driven_end_in_its_loop():
    """The driven filament's operator set serves rattle's loop; rattle's loop arguments are built
    (no compilation here: the set's reason and loops only)."""
    scheme = Lattice(_driven_filament(np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0])))
    ops = scheme.compiled_operators()
    assert ops.data.any_driven and ops.serves("rattle_loop")
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    integ = Rattle()
    assert integ.compiled_loop(scheme, state, 4e-3)[0] == "rattle_loop" and integ.compiled_declined is None


RATTLE_CASES = {
    # the arc turned about d₂ under gravity (the rows' force on the end does work)
    "arc-turned": (lambda: _driven_filament(np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0])), 4e-3),
    # the arc twisted about d₁
    "arc-twisted": (lambda: _driven_filament(np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0])), 4e-3),
    # a straight filament, free at s = 0, twisted against a twist drag (the closing matrix is not
    # s·I: the closing projection's own factors)
    "straight-damped-twist": (lambda: _driven_filament(
        np.array([0.0, 0.0, 0.0, 0.2, 0.0, 0.0]), start=cartan.Free(), n=21, straight=True, J=0.1,
        loads=[cartan.Damping([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])]), 5e-3),
    # the arc turned about d₂, pinned at s = 0 (held components and a driven end)
    "arc-pinned-turned": (lambda: _driven_filament(np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
                                                   start=cartan.Held((0, 1, 2))), 4e-3),
}


@pytest.mark.slow  # (the driven filament's rattle loop compiles on first use: 45–90 s on a fresh cache)
@pytest.mark.parametrize("case", list(RATTLE_CASES))
def test_rattle_moves_a_driven_end_compiled(case):
    make, dt = RATTLE_CASES[case]
    problem = make()
    scheme, (ref, ref_integ), (fast, integ) = run_both(Lattice, problem, Rattle, dt, NSTEPS, BLOCKS)
    assert integ.compiled_declined is None
    if case != "straight-damped-twist":  # (a twisted straight line keeps its rows at round-off: whether a
        assert integ.niter == ref_integ.niter  # step iterates once more is round-off's choice there)
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    assert not scheme.compiled_advance(Rattle(), start, dt, 1)  # so the generated loop took the steps
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == integ.nstep == NSTEPS and fast.t == ref.t
    assert _rel(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert _rel(fast.arrays[key], ref.arrays[key]) <= TOL, key
    assert ref.scalars["external_work"] != 0.0  # the support works
    assert abs(fast.scalars["external_work"] - ref.scalars["external_work"]) <= RATTLE_WORK_TOL * abs(
        ref.scalars["external_work"])
    assert abs(fast.scalars["dissipated_energy"] - ref.scalars["dissipated_energy"]) <= TOL * max(
        abs(ref.scalars["dissipated_energy"]), 1e-300)
    assert integ.constraint_residual(scheme, fast) <= 1e-13
    xi = scheme._driven[1][-1]
    _assert_end_moves_by_exp(scheme, fast, xi)
    R_ref, R_fast = Rattle().support_reaction(scheme, ref), Rattle().support_reaction(scheme, fast)
    assert _rel(R_fast, R_ref) <= RATTLE_WORK_TOL


@pytest.mark.slow  # (the driven filament's rattle loop compiles on first use)
def test_rattle_compiled_refuses_a_filament_without_slack():
    """Clamped at s = 0 and driven at s = L = the ends' distance: the rows are dependent and the
    compiled loop, as the Python step, says so (a ValueError, not a convergence failure)."""
    problem = _driven_filament(np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0]), straight=True, loads=())
    scheme = Lattice(problem)
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    with pytest.raises(ValueError, match="rattle: the constraint rows are dependent"):
        Rattle().run_compiled_loop(scheme, state, 1e-3, 2)
