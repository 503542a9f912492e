"""``rattle`` with held components: ``cartan.Held`` ends and ``cartan.Symmetry`` faces of the
inextensible filament (the Python step; the compiled loop against it: tests/test_rattle_compiled_held.py).

The held components' velocities and momenta stay zero, the constraint rows take them as fixed
(a partly held node keeps its free components as unknowns, an edge between wholly held nodes
has no row), and ``Rattle.support_reaction`` gives the reaction on them, constraint force
included.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import PLANAR_PIN, frames_of, pinned_arc

import cartan
from cartan.integrators.constrained import Rattle
from cartan.schemes.lattice import Lattice


def filament():
    return cartan.medium("filament", bending=1.0, twist=1.0, mass=1.0, rotational_inertia=0.05)


def test_the_rows_take_held_components_as_fixed():
    """A pinned end node keeps its free rotation as its only unknown; its edge keeps its rows.
    Two wholly held nodes (``Held`` with every component) leave their edge no row."""
    scheme = Lattice(pinned_arc())
    con, unknown, nodes, _ = Rattle()._constraints(scheme, scheme.initial_state())
    assert unknown[0].tolist() == [False] * 5 + [True] and unknown[-1].tolist() == [False] * 5 + [True]
    assert np.all(unknown[1:-1]) and nodes.tolist() == list(range(11))
    assert con.ncon == 10 * 3 and con.nunk == 9 * 6 + 2
    every = cartan.Held(tuple(range(6)))
    fil, grid = filament(), cartan.Grid(2, length=0.1)
    stuck = Lattice(cartan.Problem(fil, grid, fil.initial_state(grid, "straight"), {"start": every, "end": every}))
    assert Rattle()._constraints(stuck, stuck.initial_state())[0].ncon == 0


def test_the_compiled_loop_takes_held_components():
    assert Rattle().compiled_reason(Lattice(pinned_arc())) is None


@pytest.mark.parametrize("scheme, t_end", [("lattice", 0.6), ("collocation", 0.4)])
def test_pinned_arc_conserves_energy_to_second_order(scheme, t_end):
    """The pinned–pinned arc oscillating (the kinetic energy swings by 0.16), on both schemes: the
    energy error quarters with Δt (measured, to t = 0.6 at Δt = 4e-3, 2e-3: 2.1e-3, 5.4e-4 on the
    lattice, ratio 3.97; 1.75e-3, 4.39e-4 on the collocation, ratio 3.99; asserted 4 ± 0.6,
    rattle's order 2), the rows stay at round-off (bound 1e-12 on values of 1, measured 1e-13),
    the pins do not move (exactly: their velocity is zero), the held components' velocity and
    momentum are zero, the pins turn about e₃ and the arc stays in its plane."""
    problem = pinned_arc()
    errors = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(problem, scheme=scheme, integrator="rattle", dt=dt, t_end=t_end,
                             save_every=int(round(0.02 / dt)), progress=False, compiled=False)
        E = ds.kinetic_energy.values + ds.potential_energy.values
        assert float(np.ptp(ds.kinetic_energy.values)) > 0.1
        errors.append(float(np.max(np.abs(E - E[0]))))
        assert float(np.max(ds.constraint_residual.values)) < 1e-12
        ends = ds.position.values[:, [0, -1]]
        assert np.array_equal(ends, np.broadcast_to(ends[0], ends.shape))
        for var in ("N", "S"):
            assert np.all(ds[var].values[:, [0, -1]][..., list(PLANAR_PIN)] == 0.0)
        assert float(np.max(np.abs(ds.N.values[:, 0, 5]))) > 1e-2  # the pins turn about e₃
        assert float(np.max(np.abs(ds.position.values[..., 2]))) == 0.0  # it stays in its plane
    assert errors[0] / errors[1] == pytest.approx(4.0, abs=0.6)


def test_a_symmetry_face_is_half_of_the_symmetric_filament():
    """The half s ≤ L/2 of the pinned arc (ball joints: the positions held, the frames free),
    with a ``Symmetry`` face at s = L/2 (its mirror plane x = 0, the default: the end's tangent;
    the node slides in it and turns about x only), moves as the first half of the whole arc
    (the lattice's nodes coincide): positions and frames agree to round-off (bound 1e-12,
    measured 2e-15 and 5e-15 over 250 steps), the face node stays at x = 0, and the half holds
    half the energy (to 1e-12; measured 2e-14)."""
    full = pinned_arc(pin=(0, 1, 2))
    half = cartan.Problem(full.medium, cartan.Grid(6, length=0.5), cartan.InitialState(Phi=full.initial.Phi[:6].copy()),
                          {"start": cartan.Held((0, 1, 2)), "end": cartan.Symmetry()}, loads=full.loads)
    run = {"integrator": "rattle", "dt": 2e-3, "t_end": 0.5, "save_every": 25, "progress": False, "compiled": False}
    a, b = cartan.simulate(full, **run), cartan.simulate(half, **run)
    assert float(np.ptp(a.position.values[:, 5, 1])) > 1e-2  # the middle moves
    assert np.max(np.abs(a.position.values[:, :6] - b.position.values)) < 1e-12
    assert np.max(np.abs(a.frame.values[:, :6] - b.frame.values)) < 1e-12
    assert np.max(np.abs(b.position.values[:, -1, 0])) < 1e-15
    assert float(np.max(b.constraint_residual.values)) < 1e-12
    Ea = a.kinetic_energy.values + a.potential_energy.values
    Eb = b.kinetic_energy.values + b.potential_energy.values
    assert np.max(np.abs(2.0 * Eb - Ea)) < 1e-12


# ---------------------------------------------------------------------------- statics and reaction
P_TIP = 4.0  # the tip's dead load along +x
G = 8.0  # gravity along −y (mass 1 per length: a weight G)


def hanging(damping=None, initial=None, n: int = 9) -> cartan.Problem:
    """A filament pinned at s = 0 (in-plane rotation free) under gravity −G e_y and a dead load
    P e_x at its free end s = L = 1: its equilibrium hangs down and to the right, bent (the pin
    holds no moment, the load and the weight bend it)."""
    fil = filament()
    grid = cartan.Grid(n, length=1.0)
    loads = [fil.make_load("gravity", g=[0.0, -G, 0.0])] + ([] if damping is None else [cartan.Damping(damping)])
    return cartan.Problem(fil, grid, fil.initial_state(grid, "straight") if initial is None else initial,
                          {"start": cartan.Held(PLANAR_PIN), "end": cartan.Free(load=[P_TIP, 0, 0, 0, 0, 0])},
                          loads=loads)


def spatial_force(scheme, state, R):
    """The spatial force of the body components R[:3] at the pin."""
    return scheme.frames(state)[0, 1:, 1:] @ R[:3]


@pytest.fixture(scope="module")
def static():
    return cartan.solve_static(hanging(), tol=1e-12)


def test_the_static_solution_stays_and_the_pin_holds_the_loads(static):
    """Started at rest on the static solution of ``solve_static`` (the same ends), rattle stays
    there (10 steps: the statics' Newton tolerance, bound 1e-9, measured 1e-14) and the pin's
    reaction (``Rattle.support_reaction``: the held components, the rows' tension on the first
    edge included: the filament's tension is all in the rows) balances the loads, −(P e_x − G e_y),
    to 1e-9 (measured 3e-15)."""
    problem = hanging(initial=cartan.InitialState(Phi=frames_of(static)))
    scheme, integ = Lattice(problem), Rattle()
    state = scheme.initial_state()
    x0 = scheme.frames(state)[:, 1:, 0].copy()
    R = integ.support_reaction(scheme, state)
    assert np.all(R[1:] == 0.0) and np.all(R[0, [5]] == 0.0)
    np.testing.assert_allclose(spatial_force(scheme, state, R[0]), [-P_TIP, G, 0.0], atol=1e-9)
    for _ in range(10):
        integ.step(scheme, state, 5e-3)
    assert np.max(np.abs(scheme.frames(state)[:, 1:, 0] - x0)) < 1e-9


@pytest.mark.slow  # 830 Python steps (5–12 s)
def test_damped_relaxation_reaches_the_static_solution(static):
    """Released straight and horizontal, damped (γ = 8 on the translations, 0.5 on the
    rotations), the pinned filament swings down and settles on the static solution: the
    distance decays by a factor ≥ 10 per unit time (measured 15; 2.6e-5 at t = 4, 1.7e-6 at
    t = 5), so at t = 5 it is the transient's residual, bounded by 1e-5; the pin's reaction
    balances the loads to the same residual (bound 1e-4 on loads of 8)."""
    scheme, integ = Lattice(hanging(damping=[8.0, 8.0, 8.0, 0.5, 0.5, 0.5])), Rattle()
    state = scheme.initial_state()
    x_static = static.position.values[-1]
    dist = []
    for T in (4.0, 5.0):
        while state.t < T - 1e-9:
            integ.step(scheme, state, 6e-3)
        dist.append(float(np.max(np.abs(scheme.frames(state)[:, 1:, 0] - x_static))))
    assert dist[1] < 1e-5 and dist[1] < 0.1 * dist[0]
    assert np.all(scheme.frames(state)[0, 1:, 0] == 0.0)
    assert integ.constraint_residual(scheme, state) < 1e-12
    R = integ.support_reaction(scheme, state)[0]
    np.testing.assert_allclose(spatial_force(scheme, state, R), [-P_TIP, G, 0.0], atol=1e-4)
