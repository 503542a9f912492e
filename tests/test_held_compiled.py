"""Held components (``cartan.Held`` ends, ``cartan.Symmetry`` faces) on the lattice's compiled
operators (:mod:`cartan.schemes._lattice_ops`, the ``held`` ``[n, r]`` mask): the generated
loop against ``Integrator.step`` on the numpy path.

A Cosserat rod pinned at u = 0 (``Held((0, 1, 2))``: the position held, the frame free) under a
follower moment at its free end, and a rod clamped at u = 0 with a symmetry end (its tangent's
plane) under a body-frame transverse force; Lie–Verlet, stepped by the Python step and by the
generated loop in three blocks.  The generated loop really takes the steps
(``run_compiled_loop`` returns True, the operator set is not declined), the states agree to
round-off, and the held components stay exactly fixed (zero momentum and velocity there; the
pin's position bit for bit).

Both problems, and the ``rkmk4`` and ``overdamped`` runs, use the generated module of the
quadratic SE(3) kernels that tests/test_compiled_paths.py compiles too (≈ 25 s on a fresh cache,
then loaded).  Slow: the Nambu–Goto string with fixed ends (Poincaré), a non-diagonal indefinite
metric with a held end (SO(1,3)) and the threaded build, each its own module.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import (
    assert_agree_and_held,
    assert_kinetic_of_held,
    assert_pin_holds,
    assert_symmetry_end_slides,
    held_rod,
    mirrored_rod,
    pinned_rod,
    rel_error,
    run_both_held,
    wave,
)

import cartan
from cartan import Clamped, Damping, Held, Symmetry
from cartan.integrators import RKMK4, Kinematic, LieVerlet, Overdamped, Rattle
from cartan.schemes.lattice import Lattice

#: compiled against Python: one force evaluation sums a few hundred terms in another order,
#: round-off of order 1e-15 of the largest nodal force (tests/test_compiled_paths.py); the momenta
#: take NSTEPS kicks of Δt·W, so they agree to NSTEPS·Δt·max|W|·FORCE_TOL (measured: 1.8e-12
#: and 1.1e-12 against a bound of 1.5e-11 for the pin and the symmetry end)
FORCE_TOL = 1e-13
#: the edges and frames: relative round-off over the run (measured: below 1e-15)
TOL = 1e-12
NSTEPS = 30
DT = 1e-4


_rod, _pinned, _mirrored = held_rod, pinned_rod, mirrored_rod


def _run_both(problem, make=LieVerlet, dt=DT, nsteps=NSTEPS):
    """:func:`toys.run_both_held` on the lattice, whose generated loop takes the steps (the
    hand-written rod loops decline held components)."""
    scheme, start, ref, fast, fi = run_both_held(Lattice, problem, make, dt, nsteps)
    hand = getattr(scheme, "compiled_advance", None)
    assert hand is None or not hand(make(), start.copy(), dt, 1)  # so the generated loop took the steps
    return scheme, start, ref, fast, fi


def _assert_agree_and_held(scheme, start, ref, fast):
    """Compiled against Python and the held components zero; the kinetic energy of partly held nodes."""
    force = float(np.max(np.abs(scheme.internal_force(start) / scheme.weights[..., None])))
    assert_agree_and_held(scheme, start, ref, fast, NSTEPS * DT * force * FORCE_TOL, TOL, 1e-6)
    assert_kinetic_of_held(scheme, fast)


def test_pinned_end_runs_compiled_and_agrees_with_the_numpy_path():
    scheme, start, ref, fast, _ = _run_both(_pinned())
    _assert_agree_and_held(scheme, start, ref, fast)
    assert_pin_holds(scheme, start, (ref, fast))


def test_symmetry_end_runs_compiled_and_agrees_with_the_numpy_path():
    scheme, start, ref, fast, _ = _run_both(_mirrored())
    _assert_agree_and_held(scheme, start, ref, fast)
    assert_symmetry_end_slides(scheme, start, (ref, fast), 1e-6)  # (it slides by 2.3e-6)


def test_simulate_takes_the_generated_loop(generated_runs):
    """``simulate`` (saved frames, compiled diagnostics) on the generated loop against
    ``compiled=False`` (the hand-written SE(3) rod loops decline held ends and the steps go to
    the generated ones): positions, frames, velocities and energies to round-off (measured
    ≤ 7.5e-13 relative, the velocities of the symmetry case; the bound as for the momenta)."""
    for make in (_pinned, _mirrored):
        generated_runs.clear()
        kw = dict(integrator="lie-verlet", dt=DT, t_end=NSTEPS * DT, save_every=10, progress=False)
        fast = cartan.simulate(make(), **kw)
        assert generated_runs and all(generated_runs)
        ref = cartan.simulate(make(), **kw, compiled=False)
        for name in ("position", "frame", "N", "kinetic_energy", "potential_energy", "external_work"):
            assert rel_error(fast[name].values, ref[name].values) <= 1e-11, name
        assert np.array_equal(fast.step.values, ref.step.values)


@pytest.mark.slow
def test_implicit_midpoint_holds_the_components():
    """``implicit-midpoint``'s compiled Newton blocks (the operators, unknowns from the scheme's
    mask) against the numpy backend on both rods: to round-off (measured ≤ 1.4e-13 relative,
    the velocities of the symmetry case; ≈ 20 s to compile the Newton module once)."""
    from cartan._backend import use_backend
    from cartan.integrators.implicit import _stage

    for make in (_pinned, _mirrored):
        assert _stage(Lattice(make())) is not None  # the compiled stage (not declined)
        kw = dict(integrator="implicit-midpoint", dt=DT, t_end=20 * DT, save_every=10, progress=False)
        fast = cartan.simulate(make(), **kw)
        with use_backend("numpy"):
            ref = cartan.simulate(make(), **kw)
        for name in ("position", "frame", "N", "kinetic_energy"):
            assert rel_error(fast[name].values, ref[name].values) <= 1e-11, name
        held = np.broadcast_to(Lattice(make())._clamped, fast.N.values.shape)
        assert np.all(fast.N.values[held] == 0.0)


def test_rkmk4_and_overdamped_hold_the_components():
    """``rkmk4`` (N = M⁺S from ``op_velocity``) on the pinned rod and ``overdamped`` (N = Γ⁻¹W, zero
    on the held components with W) on a rod pinned at one end with a symmetry end at the other:
    the generated loop against the Python step (the same tolerances), the held velocity zero."""
    rod = _rod()
    grid = cartan.Grid(9, length=1.0)
    both = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0),
                          {"start": Held(components=(0, 1, 2)), "end": Symmetry()}, [Damping([1e5] * 6)])
    for problem, make, dt, nsteps in ((_pinned(), RKMK4, DT, 12), (both, lambda: Overdamped(order=1), 1e-5, 20)):
        scheme, start, ref, fast, fi = _run_both(problem, make, dt, nsteps)
        assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-5
        assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
        force = float(np.max(np.abs(scheme.internal_force(start) / scheme.weights[..., None])))
        assert float(np.max(np.abs(fast.S - ref.S))) <= nsteps * dt * force * FORCE_TOL
        held = np.broadcast_to(scheme._clamped, fast.S.shape)
        assert np.all(fi.velocity(scheme, fast)[held] == 0.0)


def test_partly_held_problem_no_longer_declined_but_kinematic_stays_in_python():
    """The operator set takes held components; the loop that reads whole-node clamps only
    (``kinematic``'s prescribed velocity) leaves them to Python; ``rattle``'s node operators
    take them (tests/test_rattle_compiled_held.py)."""
    scheme = Lattice(_pinned())
    assert scheme.compiled_operators().ok
    assert scheme.compiled_operators().data.held[0].tolist() == [True] * 3 + [False] * 3
    rattle = Rattle()
    assert rattle.compiled_reason(scheme) is None
    state = scheme.initial_state()
    assert Kinematic(velocity=wave, order=2).compiled_loop(scheme, state, DT) is None
    clamped = Lattice(cartan.Problem(_rod(), scheme.grid, _pinned().initial, {"start": Clamped()}))
    assert Kinematic(velocity=wave, order=2).compiled_loop(clamped, state, DT) is not None
    assert rattle.compiled_reason(clamped) is None


@pytest.mark.parametrize("components", [tuple(range(6))])
def test_every_component_held_is_a_clamp_in_the_data(components):
    """Held with every component is a clamp: ``clamped`` set, no partly held node."""
    rod = _rod()
    grid = cartan.Grid(5, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": Held(components=components)})
    data = Lattice(problem).compiled_operators().data
    assert data.clamped.tolist() == [True, False, False, False, False] and not data.any_held


@pytest.mark.slow
def test_nambu_goto_string_with_fixed_ends_runs_compiled():
    """The Nambu–Goto string between two fixed points (``Held((1, …, 9))`` ends on the Poincaré
    group, an indefinite metric with gauge components; docs/media/relativistic-rod.md §3): the
    generated loop against the numpy path over 40 steps (≈ 40 s to compile its module once)."""
    from cartan_relativistic.fixed import fixed_end

    rod = cartan.medium("relativistic-rod")
    grid = cartan.Grid(17, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "standing", angle=0.8),
                             boundaries={"start": fixed_end(), "end": fixed_end()})
    scheme = Lattice(problem, track_frames=True)
    assert scheme.compiled_operators().ok
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, fast = start.copy(), start.copy()
    ri, fi = LieVerlet(), LieVerlet()
    for _ in range(40):
        ri.step(scheme, ref, 1.0 / 64)
    assert fi.run_compiled_loop(scheme, fast, 1.0 / 64, 40)
    assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 0.1
    force = float(np.max(np.abs(scheme.internal_force(start) / scheme.weights[..., None])))
    assert float(np.max(np.abs(fast.S - ref.S))) <= 40 / 64 * force * FORCE_TOL
    assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
    held = np.broadcast_to(scheme._clamped, fast.S.shape)
    assert np.all(fast.S[held] == 0.0)


@pytest.mark.slow
@pytest.mark.skipif(cartan._threads.max_threads() < 2, reason="numba has a single thread here")
def test_threaded_build_holds_the_same_components():
    """The threaded build's passes (``op_*_threaded``, the held mask in each) give the serial
    build's states bit for bit on both problems (≈ 1 min to compile the threaded module once)."""
    from cartan import _threads

    for problem in (_pinned(), _mirrored()):
        runs = []
        for threaded in (False, True):
            scheme = Lattice(problem, track_frames=True)
            state = scheme.initial_state()
            integrator = LieVerlet()
            if threaded:
                with _threads.threaded_everywhere(2):
                    assert integrator.run_compiled_loop(scheme, state, DT, NSTEPS)
                assert scheme.compiled_operators().threaded_module is not None
            else:
                assert integrator.run_compiled_loop(scheme, state, DT, NSTEPS)
            runs.append(state)
        a, b = runs
        assert np.array_equal(a.S, b.S) and all(np.array_equal(a.arrays[k], b.arrays[k]) for k in a.arrays)


@pytest.mark.slow
def test_non_diagonal_indefinite_metric_with_a_held_end():
    """A rod on SO(1,3) with a non-diagonal, indefinite kinetic metric (tests/toys.py
    ``IndefiniteMetric``) and an end holding components 0–2 (the free 3–5 a subalgebra):
    ``rkmk4`` and ``lie-verlet`` (eigenvector pieces: the non-axial free flow) agree with the
    numpy path, and the kinetic energy of the partly held node (½ w N·MN) with
    ``Scheme.kinetic_energy`` (≈ 25 s to compile the module once)."""
    from toys import IndefiniteMetric

    from cartan.grid import Grid
    from cartan.problem import InitialState, Problem

    medium = IndefiniteMetric("SO13")
    grid = Grid(11, 1.0)
    u = grid.coordinates(0)
    Phi = medium.group.exp(np.sin(2 * np.pi * u)[:, None] * np.linspace(0.05, 0.02, 6))
    N = np.cos(2 * np.pi * u)[:, None] * 0.1 * np.ones(6)
    problem = Problem(medium, grid, InitialState(Phi=Phi, N=N), {"start": Held(components=(0, 1, 2))})
    scheme = Lattice(problem, track_frames=True)
    ops = scheme.compiled_operators()
    assert ops.ok and ops.data.any_held and not scheme.diagonal_metric
    for make, dt, nsteps in ((RKMK4, 1e-3, 12), (LieVerlet, 1e-3, 20)):
        scheme, start, ref, fast, fi = _run_both(problem, make, dt, nsteps)
        assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-3
        force = float(np.max(np.abs(scheme.internal_force(start) / scheme.weights[..., None])))
        assert float(np.max(np.abs(fast.S - ref.S))) <= nsteps * dt * force * FORCE_TOL
        assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
        held = np.broadcast_to(scheme._clamped, fast.S.shape)
        assert np.all(fast.S[held] == 0.0)
        K = scheme.kinetic_energy(fast)
        S = np.ascontiguousarray(fast.S.reshape(ops.nodes, -1))
        assert abs(ops.generated().op_kinetic(ops.data, S) - K) <= 1e-14 * abs(K)


@pytest.mark.slow
def test_d2_symmetry_face_on_a_cosserat_surface():
    """d = 2: a flat Cosserat surface (corner energies, the coupled passes) with a symmetry edge
    (u = 0, the plane x = 0) and a clamped edge (v = 0), under gravity and damping with an
    initial velocity: ``lie-verlet`` on the generated loop against the numpy path, the edge's
    nodes in their plane exactly (≈ 20 s to compile the surface's module once).  The plate
    starts unstressed, so the round-off of the force is the stiffness times that of the strains
    (≈ 1e-16 of the unit stretch), not a fraction of |W|: the momenta take the suite's relative
    bound TOL (tests/test_compiled_paths.py; measured 2.7e-13)."""
    from cartan.grid import Grid
    from cartan.problem import InitialState, Problem

    medium = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = Grid((6, 5), length=(1.0, 0.8))
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(2)], indexing="ij"), axis=-1)
    N = np.zeros((*grid.shape, medium.group.dim))
    N[..., 2] = 1e-2 * np.cos(0.5 * np.pi * u[..., 0]) * np.sin(np.pi * u[..., 1] / 0.8)
    N[..., 0] = 1e-2 * np.sin(np.pi * u[..., 0])
    problem = Problem(medium, grid, InitialState(Phi=medium.initial_state(grid, "flat").Phi, N=N),
                      {"u-start": Symmetry(), "v-start": Clamped()},
                      [medium.make_load("gravity", g=[0.0, 0.0, -1e-3]), Damping(0.3)])
    scheme = Lattice(problem, track_frames=True)
    ops = scheme.compiled_operators()
    assert ops.ok and ops.data.any_held and scheme.coupled
    scheme, start, ref, fast, _ = _run_both(problem, LieVerlet, 0.1 * grid.spacing[0], 12)
    assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-4
    assert rel_error(fast.S, ref.S) <= TOL
    assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
    held = np.broadcast_to(scheme._clamped, fast.S.shape)
    assert np.all(fast.S[held] == 0.0)
    for state in (ref, fast):  # the symmetry edge slides in the plane x = 0 (held v_x)
        assert np.array_equal(scheme.frames(state)[0, :, 1, 0], start.arrays["Phi"][0, :, 1, 0])
