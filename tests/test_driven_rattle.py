"""A driven end (:class:`cartan.Driven`) of the inextensible filament under ``rattle``.

The driven node moves by exp(Δtξ) in the split free flow; its prescribed velocity enters the
constraint rows (the velocity projection solves ``B_u N_u = −B_d ξ``, the position multipliers
hold the rows after the flow that moved it); the rows stay at round-off, the end frame is
Φ(0)·exp(tξ) to round-off, and the reaction — including the constraint force on the driven
node, ``−B_dᵀλ`` — closes the energy balance to second order.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_driven_end import assert_restart_is_exact, assert_torsional_impedance

import cartan
from cartan.integrators.constrained import Rattle
from cartan.schemes.lattice import Lattice


def _arc(xi, gravity: float = 2.0) -> cartan.Problem:
    """A slack filament (a clamped arc of curvature 1.5, L = 1, 11 nodes) sagging under gravity,
    clamped at s = 0 and driven at s = L."""
    fil = cartan.medium("filament", bending=1.0, twist=1.0, mass=1.0, rotational_inertia=0.05)
    grid = cartan.Grid(11, length=1.0)
    loads = [fil.make_load("gravity", g=[0.0, 0.0, -gravity])]
    return cartan.Problem(fil, grid, fil.initial_state(grid, "arc", curvature=1.5, centered=True),
                          {"start": cartan.Clamped(), "end": cartan.Driven(velocity=xi)}, loads=loads)


def _straight(om: float, C: float, J: float, n: int, loads=()) -> cartan.Problem:
    """A straight filament, free at s = 0, twisted at s = L = 1 about d₁ at rate ω."""
    fil = cartan.medium("filament", bending=1.0, twist=C, mass=1.0, rotational_inertia=[J, 0.5, 0.5])
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(fil, grid, fil.initial_state(grid, "straight"),
                          {"start": cartan.Free(), "end": cartan.Driven(velocity=[0.0, 0.0, 0.0, om, 0.0, 0.0])},
                          loads=list(loads))


@pytest.mark.parametrize("xi", [[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
def test_the_driven_end_moves_exactly_and_the_rows_hold(xi):
    """Twisted (about d₁) or turned (about d₂) at its end: the end's frame and position are
    Φ(0)exp(tξ) to round-off (100 steps: bound 1e-12, measured 3e-14) and the rows
    X_e − (1, 0, 0) stay at round-off (bound 1e-12, measured 1e-13) while the filament moves."""
    xi = np.asarray(xi)
    problem = _arc(xi)
    ds = cartan.simulate(problem, integrator="rattle", dt=4e-3, t_end=0.4, save_every=20, progress=False,
                         compiled=False)
    t = ds.time.values
    exact = np.einsum("ij,tjk->tik", problem.initial.Phi[-1], problem.medium.group.exp(t[:, None] * xi))
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - exact[:, 1:, 0])) < 1e-12
    assert np.max(ds.constraint_residual.values) < 1e-12
    assert np.max(np.abs(ds.frame.values[:, -2] - exact[:, 1:, 1:])) > 1e-3  # its neighbour lags behind


def test_the_reaction_closes_the_energy_balance_to_second_order():
    """The arc turned at its end about d₂ (the constraint force on the driven node does work:
    without its power −λᵀB_dξ the balance misses 0.19 of a work 1.5): K + V − W closes to
    rattle's second order, the error quartering with Δt (measured 1.3e-5, 3.3e-6: ratio 4.0 ±
    0.6).  The first step sets the free nodes in motion with the end (the velocity projection
    from rest): that kinetic energy is the support's impulse's work, booked too."""
    assert_rattle_balance_second_order(_arc(np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0])), progress=False,
                                       compiled=False)


def assert_rattle_balance_second_order(problem: cartan.Problem, **settings) -> None:
    """``rattle`` runs of ``problem`` to t = 0.8 at Δt = 4e-3 and 2e-3: the end does work
    (> 1) and K + V + D − W − E₀ quarters with Δt (ratio 4 ± 0.6: second order)."""
    errors = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(problem, integrator="rattle", dt=dt, t_end=0.8, save_every=int(round(0.1 / dt)),
                             **settings)
        E = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
        W = ds.external_work.values
        assert W[-1] > 1.0
        errors.append(float(np.max(np.abs(E - E[0] - W))))
    assert errors[0] / errors[1] == pytest.approx(4.0, abs=0.6)


def test_the_torque_of_a_driven_twist_is_the_torsional_impedance():
    """A twist at ω = 0.1 into a straight filament at rest (C = ρJ = 1, c = 1): the wave leaves
    the driven end with π₁ = ω/c, the reaction's torque (``Rattle.support_reaction``) is
    √(CJ)ω until the reflection from the free end returns at t = 2L/c; its mean over
    t ∈ [0.5, 1.9] agrees to h/L = 1/40 (measured 1e-3), the external work √(CJ)ω²t likewise
    (measured 7e-3).  The rows hold the straight line to round-off."""
    C, J, om, n, dt = 1.0, 1.0, 0.1, 41, 4e-3
    scheme, integ = Lattice(_straight(om, C, J, n)), Rattle()
    state = scheme.initial_state()
    torque, times = [], []
    for _ in range(475):
        integ.step(scheme, state, dt)
        torque.append(integ.support_reaction(scheme, state)[-1, 3])
        times.append(state.t)
    assert_torsional_impedance(torque, times, state, n, C, J, om)
    assert integ.constraint_residual(scheme, state) < 1e-12


def test_a_slow_damped_twist_settles_to_the_quasi_static_twist():
    """Twisted slowly (ω = 0.2) against a twist drag γ = 1 per length, free at s = 0: the
    quasi-static twist is π₁(s) = γωs/C (the drag of the part beyond s spinning at ω) and the
    end's torque the drag of the whole filament, γωL.  The transient decays as e^{−4.4t}
    (the slowest mode of Jθ̈ + γθ̇ = Cθ'', J = 0.1): at t = 2 both agree to 2e-3 of γω
    (measured 3e-4)."""
    C, J, om, gam, n = 1.0, 0.1, 0.2, 1.0, 21
    problem = _straight(om, C, J, n, loads=[cartan.Damping([0.0, 0.0, 0.0, gam, 0.0, 0.0])])
    scheme, integ = Lattice(problem), Rattle()
    state = scheme.initial_state()
    for _ in range(400):
        integ.step(scheme, state, 5e-3)
    s = (np.arange(n - 1) + 0.5) / (n - 1)  # the edges' midpoints
    twist = scheme.edge_strains(state)[0][:, 3]
    assert np.max(np.abs(twist - gam * om * s / C)) < 2e-3 * gam * om
    assert integ.support_reaction(scheme, state)[-1, 3] == pytest.approx(gam * om * 1.0, rel=2e-3)


def test_a_screw_across_the_split_flow_is_refused():
    """rattle's free flow is lie-verlet's: a screw across its commuting blocks is refused."""
    with pytest.raises(ValueError, match="integrator 'rattle' does not take Driven ends: the driven velocity"):
        cartan.simulate(_arc(np.array([0.1, -0.2, 0.05, 0.3, -0.4, 0.5])), integrator="rattle", dt=1e-3,
                        t_end=2e-3, progress=False)


def test_a_straight_filament_between_held_ends_is_refused_clearly():
    """Clamped at s = 0 and driven at s = L = the ends' distance: no slack, the rows are
    dependent and the multiplier systems singular — a ValueError that says so."""
    fil = cartan.medium("filament", bending=1.0, twist=1.0)
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(fil, grid, fil.initial_state(grid, "straight"),
                             {"start": cartan.Clamped(),
                              "end": cartan.Driven(velocity=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0])})
    with pytest.raises(ValueError, match="rattle: the constraint rows are dependent"):
        cartan.simulate(problem, integrator="rattle", dt=1e-3, t_end=2e-3, progress=False, compiled=False)


def test_the_driven_twist_scene_reads_and_twists_its_end():
    """The registered scene ``filament-driven-twist``: a clamped arc driven at s = L about d₁ at
    ω = 3 under rattle; over its first 50 steps the end's frame is exp(tξ) to round-off and the
    rows hold to round-off."""
    sc = cartan.scene("filament-driven-twist")
    end = sc.problem.boundaries["end"]
    assert isinstance(end, cartan.Driven) and end.velocity.tolist() == [0.0, 0.0, 0.0, 3.0, 0.0, 0.0]
    ds = sc.simulate(t_end=0.1, save_every=25, progress=False, compiled=False)
    t = ds.time.values
    exact = np.einsum("ij,tjk->tik", sc.problem.initial.Phi[-1], sc.problem.medium.group.exp(t[:, None] * end.velocity))
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(ds.constraint_residual.values) < 1e-12


def test_restart_is_bit_for_bit(tmp_path):
    """A driven rattle run continued from its checkpoint is the uninterrupted run, bit for bit
    (the constraint force's power is computed from the state alone)."""
    assert_restart_is_exact(_arc(np.array([0.0, 0.0, 0.0, 2.0, 0.0, 0.0])), tmp_path, "rattle", 4e-3, 0.08)


def test_the_reactions_close_the_momentum_balance():
    """``Rattle.support_reaction`` with the constraint forces: the arc (n = 11) falling under
    gravity between a clamp and an end driven about d₂, the total linear momentum changes by
    the impulse of the weight and of the supports' forces, ∫(ΣR + ρAgL)dt (trapezoidal, to
    second order: 5.1e-5 and 1.3e-5 at Δt = 4, 2e-3, bound 1e-3 of the weight's impulse 0.8;
    without the constraint forces B_cᵀλ on the end nodes — the filament's force n is all
    multiplier — the supports carry only the end nodes' weight and the balance misses 0.72)."""
    problem = _arc(np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0]), gravity=2.0)
    scheme, integ = Lattice(problem), Rattle()
    state = scheme.initial_state()
    weight = np.array([0.0, 0.0, -2.0 * 1.0 * 1.0])  # ρA g L

    def force(st):
        R = integ.support_reaction(scheme, st)
        return np.einsum("nij,nj->i", scheme.frames(st)[:, 1:, 1:], R[:, :3]) + weight

    dt, impulse = 4e-3, np.zeros(3)
    integ.step(scheme, state, dt)  # (the first step sets the free nodes moving: an impulse)
    P0, F0 = scheme.total_momentum(state)[:3], force(state)
    for _ in range(100):
        integ.step(scheme, state, dt)
        F1 = force(state)
        impulse += 0.5 * dt * (F0 + F1)
        F0 = F1
    change = scheme.total_momentum(state)[:3] - P0
    assert np.max(np.abs(change - impulse)) < 1e-3 * np.linalg.norm(weight) * 100 * dt
