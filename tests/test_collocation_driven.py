"""A driven end (:class:`cartan.Driven`) on the ``collocation`` scheme (numpy path).

At the driven node N = ξ and S = ∂K/∂N(ξ) at every step and the force is not applied: the
drift moves its frame by exp(Δtξ) (Φ(t) = Φ(0)exp(tξ) to round-off) and its stored strain by the
scheme's Lie group integrator with ξ in ∂N.  The raw force there is the weak form of a clamp's,
so the reaction's power closes the semi-discrete energy balance; runs converge to the lattice's
at second order in h, and the integrability residual at the driven end grows as at a clamp
(first order in h at the ends: the SBP boundary rows of order p/2; second order inside).
The compiled operators take driven ends too: tests/test_collocation_driven_compiled.py.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from test_driven_end import SCREW, TWIST, _exact_end, _problem, assert_twist_impedance
from test_driven_rattle import _arc, assert_rattle_balance_second_order

import cartan
from cartan.integrators.explicit import LieVerlet
from cartan.problem import InitialState
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")

_SIM = dict(scheme="collocation", progress=False, compiled=False)


def _twisted_arc(n: int, om: float = 2.0) -> cartan.Problem:
    """An SE(3) rod (stretch–shear 4, bend–twist 1, ρA = 1, ρJ = (1, ½, ½)) bent into an arc of
    curvature 2 (an equilibrium between its clamps), clamped at s = 0 and twisted at s = L = 1
    about d₁ at rate ω, starting with the smooth body velocity N(s) = ξ s/L (continuous with the
    clamp and the driven end: no kink in the solution)."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[4.0, 4.0, 4.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                        rotational_inertia=[1.0, 0.5, 0.5])
    grid = cartan.Grid(n, length=1.0)
    u = grid.coordinates(0)
    xi = np.array([0.0, 0.0, 0.0, om, 0.0, 0.0])
    Phi = rod.group.exp(u[:, None] * np.array([1.0, 0.0, 0.0, 0.0, 0.0, 2.0]))
    return cartan.Problem(rod, grid, InitialState(Phi=Phi, N=u[:, None] * xi),
                          {"start": cartan.Clamped(), "end": cartan.Driven(velocity=xi)})


@functools.cache
def _run(kind: str, n: int):
    """``_twisted_arc(n)`` stepped by lie-verlet to t = 0.5 (Δt = 1e-3) on ``kind``: (scheme, state)."""
    problem = _twisted_arc(n)
    scheme = Collocation(problem) if kind == "collocation" else Lattice(problem)
    state, integ = scheme.initial_state(), LieVerlet()
    for _ in range(500):
        integ.step(scheme, state, 1e-3)
    return scheme, state


# ---------------------------------------------------------------------------- the end's motion
@pytest.mark.parametrize(("integrator", "xi", "dt"), [
    ("lie-verlet", TWIST, 2e-3), ("lie-euler", SCREW, 2e-3), ("rkmk4", SCREW, 2e-3),
    ("implicit-midpoint", SCREW, 2e-3), ("overdamped", SCREW, 2e-4)])
def test_the_driven_end_moves_by_exp_t_xi(integrator, xi, dt):
    """At every saved time the end's frame and position are Φ(0)exp(tξ) to round-off (each of the
    200 steps moves it by exp(Δtξ): bound 1e-12, measured ≤ 1.3e-14), its velocity is ξ exactly,
    and its neighbour, a free node, lags behind."""
    loads = [cartan.Damping([1.0] * 6)] if integrator == "overdamped" else []
    problem = _problem(xi, loads=loads)
    ds = cartan.simulate(problem, integrator=integrator, dt=dt, t_end=200 * dt, save_every=20, **_SIM)
    exact = _exact_end(problem, xi, ds.time.values)
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - exact[:, 1:, 0])) < 1e-12
    assert np.max(np.abs(ds.N.values[:, -1] - xi)) == 0.0
    assert np.max(np.abs(ds.frame.values[:, -2] - exact[:, 1:, 1:])) > 1e-5


@pytest.mark.parametrize("xi", [[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]])
def test_rattle_moves_the_driven_end_of_a_filament_and_holds_the_rows(xi):
    """The slack filament arc of tests/test_driven_rattle.py on the collocation's nodal rows,
    twisted (d₁) or turned (d₂) at its end: the end frame is Φ(0)exp(tξ) to round-off (bound
    1e-12, measured 5e-15) and the rows hold to round-off (bound 1e-12, measured 6e-14)."""
    xi = np.asarray(xi)
    problem = _arc(xi)
    ds = cartan.simulate(problem, integrator="rattle", dt=4e-3, t_end=0.4, save_every=20, **_SIM)
    exact = _exact_end(problem, xi, ds.time.values)
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - exact[:, 1:, 0])) < 1e-12
    assert np.max(ds.constraint_residual.values) < 1e-12
    assert np.max(np.abs(ds.frame.values[:, -2] - exact[:, 1:, 1:])) > 1e-3


def test_frames_are_stepped_by_default_with_a_driven_end():
    """The driven end's frame is a stepped frame (exact), not the root's trapezoidal rebuild."""
    assert Collocation(_problem(TWIST)).track
    assert not Collocation(_problem(TWIST), track_frames=False).track
    rod = _problem(TWIST).medium
    grid = cartan.Grid(21, length=1.0)
    clamped = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": cartan.Clamped()})
    assert not Collocation(clamped).track


def test_a_plate_edge_turns_about_its_own_line():
    """A plate's edge u = L (``cosserat-surface``, d = 2) driven by a rotation about the edge line:
    each of its nodes turns by Φᵢ(0)exp(tξ) (bound 1e-12, measured 1.6e-14) and stays in place,
    and E − W closes to second order (1.0e-10, 2.6e-11 of a work 2.2e-5 at Δt = 2, 1e-3: ratio
    4.0; bound 4 ± 0.6)."""
    shell = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.1, density=1.0)
    grid = cartan.Grid((9, 5), length=(1.0, 0.5))
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
    problem = cartan.Problem(shell, grid, shell.initial_state(grid, "flat"),
                             {"u-start": cartan.Clamped(), "u-end": cartan.Driven(velocity=xi)})
    errors = []
    for dt in (2e-3, 1e-3):
        ds = cartan.simulate(problem, integrator="lie-verlet", dt=dt, t_end=0.4, save_every=int(round(0.1 / dt)),
                             **_SIM)
        exact = np.einsum("vij,tjk->tvik", problem.initial.Phi[-1], shell.group.exp(ds.time.values[:, None] * xi))
        assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, :, 1:, 1:])) < 1e-12
        assert np.max(np.abs(ds.position.values[:, -1] - ds.position.values[0, -1])) < 1e-12
        E = ds.kinetic_energy.values + ds.potential_energy.values - ds.external_work.values
        assert ds.external_work.values[-1] > 1e-5
        errors.append(float(np.max(np.abs(E - E[0]))))
    assert errors[0] / errors[1] == pytest.approx(4.0, abs=0.6)


def test_restart_is_bit_for_bit(tmp_path):
    """A collocation run with a driven end continued from its checkpoint is the uninterrupted run,
    bit for bit (strains, frames, momenta, the external work)."""
    kw = dict(integrator="lie-verlet", dt=2e-3, save_every=5, checkpoint_every=1, **_SIM)
    whole = cartan.simulate(_problem(TWIST), t_end=0.04, output=tmp_path / "whole.nc", **kw)
    cartan.simulate(_problem(TWIST), t_end=0.02, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(_problem(TWIST), restart=tmp_path / "part.nc", t_end=0.04, progress=False, compiled=False)
    for name in ("position", "frame", "S", "X", "kinetic_energy", "external_work"):
        assert np.array_equal(whole[name].values, cont[name].values), name


# ---------------------------------------------------------------------------- convergence
def test_runs_converge_to_the_lattice_at_second_order():
    """The twisted arc (t = 0.5, 500 lie-verlet steps) on collocation (fd2) and on the lattice,
    both second order in h: at n = 21, 41, 81 the largest difference of their positions at the
    shared nodes s = k/10 falls as h² (measured 3.5e-4, 8.5e-5, 2.1e-5: observed orders 2.07,
    2.02; bound 2 ± 0.3 for what is left of the pre-asymptotic range), as does that of the
    reactions' work (1.9 and 2.0).  The time error is common to both (same Δt) and below 1e-6."""
    diffs, works = [], []
    for n in (21, 41, 81):
        (cs, cst), (ls, lst) = _run("collocation", n), _run("lattice", n)
        k = (n - 1) // 10
        diffs.append(np.max(np.abs(cs.frames(cst)[::k, :3, 3] - ls.frames(lst)[::k, :3, 3])))
        works.append(abs(cst.scalars["external_work"] - lst.scalars["external_work"]))
    assert cst.scalars["external_work"] > 0.4
    for a, b in ((diffs[0], diffs[1]), (diffs[1], diffs[2]), (works[0], works[1]), (works[1], works[2])):
        assert np.log2(a / b) == pytest.approx(2.0, abs=0.3)


def test_the_integrability_residual_at_the_driven_end_is_a_clamps():
    """|X(stored) − X(Φ)| after the twisted arc's run (t = 0.5): at the driven end as at the clamp
    (the drift there is the same Lie group integrator, with ξ in ∂N), first order in h at both
    ends — the SBP boundary rows are of order p/2 = 1 (measured orders 0.93, 0.95; bound 1 ±
    0.2) — and second order at the interior nodes (1.82, 1.88; bound ≥ 1.6)."""
    ends, starts, inner = [], [], []
    for n in (21, 41, 81):
        scheme, state = _run("collocation", n)
        res = np.max(np.abs(state.arrays["X"] - scheme.strain_from_frames(state.arrays["Phi"])), axis=(1, 2))
        ends.append(res[-1])
        starts.append(res[0])
        inner.append(res[3:-3].max())
        assert res[-1] <= 1.1 * res[0]
    for seq in (ends, starts):
        for a, b in zip(seq, seq[1:]):
            assert np.log2(a / b) == pytest.approx(1.0, abs=0.2)
    for a, b in zip(inner, inner[1:]):
        assert np.log2(a / b) > 1.6


# ---------------------------------------------------------------------------- energy balance
@pytest.mark.parametrize(("integrator", "order"), [("lie-verlet", 2), ("implicit-midpoint", 2), ("rkmk4", 2),
                                                    ("lie-euler", 1)])
def test_the_reaction_closes_the_energy_balance(integrator, order):
    """K + V − W_ext of the twisted arc (n = 21, t = 0.4): the reaction's work booked by the
    trapezoidal rule closes the balance to the integrator's order, at most 2 (the booking's):
    the error falls by 2^order as Δt halves (measured 4.00 for lie-verlet, implicit-midpoint and
    rkmk4, 2.05 for lie-euler; bound 2^order ± 15 %)."""
    errors = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(_twisted_arc(21), integrator=integrator, dt=dt, t_end=0.4,
                             save_every=int(round(0.1 / dt)), **_SIM)
        E = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
        W = ds.external_work.values
        assert W[-1] > 0.3
        errors.append(float(np.max(np.abs(E - E[0] - W))))
    assert errors[0] / errors[1] == pytest.approx(2.0**order, rel=0.15)


def test_rattle_closes_the_energy_balance_to_second_order():
    """The filament arc turned at its end about d₂ (rows on the driven node: their force's power
    −λᵀB_dξ booked with the reaction's): K + V − W closes to second order (measured 4.9e-6,
    1.2e-6: ratio 4.01; bound 4 ± 0.6)."""
    assert_rattle_balance_second_order(_arc(np.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0])), **_SIM)


def test_the_torque_of_a_driven_twist_is_the_torsional_impedance():
    """A twist at ω = 0.1 into a straight rod at rest (C = ρJ = 1, c = 1, n = 101): the
    reaction's torque is √(CJ)ω until the reflection returns at t = 2, its work √(CJ)ω²t (both to
    h/L = 1e-2, as on the lattice); the supports act on their own nodes only."""
    C, J, om, n = 1.0, 1.0, 0.1, 101
    assert_twist_impedance(Collocation(_problem([0.0, 0.0, 0.0, om, 0.0, 0.0], n=n, C=C, J=J)), LieVerlet(),
                           n, C, J, om)


# ---------------------------------------------------------------------------- refusals
# (the compiled operators take driven ends: tests/test_collocation_driven_compiled.py)


@pytest.mark.parametrize(("integrator", "xi", "match"), [
    ("forward-euler", TWIST, "integrator 'forward-euler' does not take Driven ends"),
    ("lie-verlet", SCREW, "integrator 'lie-verlet' does not take Driven ends: the driven velocity"),
])
def test_integrators_that_refuse_on_the_lattice_refuse_here(integrator, xi, match):
    with pytest.raises(ValueError, match=match):
        cartan.simulate(_problem(xi), integrator=integrator, dt=1e-3, t_end=2e-3, **_SIM)


def test_a_lagrangian_coupling_n_and_x_is_refused():
    """A medium whose Lagrangian couples N and X takes no driven end (as on the lattice)."""
    rod = _problem(TWIST).medium
    coupled = type("CoupledRod", (type(rod),), {"coupled_lagrangian": True})(**rod.parameters())
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(coupled, grid, coupled.initial_state(grid, "straight"),
                             {"start": cartan.Clamped(), "end": cartan.Driven(velocity=TWIST)})
    with pytest.raises(ValueError, match="couples N and X"):
        Collocation(problem)
