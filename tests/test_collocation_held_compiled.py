"""Held components (``cartan.Held`` ends, ``cartan.Symmetry`` faces) on the collocation scheme's
compiled operators (:mod:`cartan.schemes._collocation_ops`, the ``held`` ``[n, r]`` mask): the
generated loop against ``Integrator.step`` on the numpy path.

d = 1: a Cosserat rod pinned at u = 0 (``Held((0, 1, 2))``: the position held, the frame free)
under a follower moment at its free end (out of the arc's plane, so the problem stays on SE(3)),
and a rod clamped at u = 0 with a symmetry end under a body-frame transverse force; Lie–Verlet
(the free flow moves a partly held node along its free components only), ``rkmk4`` and
``overdamped`` (N = Γ⁻¹W, zero on the held components with W), stepped by the Python step and by
the generated loop in blocks, and ``simulate`` with and without ``compiled``.  The generated loop
really takes the steps, the states agree to round-off, and the held components stay exactly
fixed (zero momentum and velocity there; the pin's position and the symmetry end's normal
coordinate bit for bit on the stepped frames).  These use the generated modules of the quadratic
SE(3) kernels on collocation that tests/test_generated_collocation.py and
tests/test_collocation_compiled.py compile too.

Slow (a module each, 20–95 s to compile once): ``implicit-midpoint``'s Newton blocks on both rods,
the Nambu–Goto string with fixed ends (an indefinite non-diagonal metric), a Cosserat surface
(d = 2) with a symmetry edge and the octant of a Cosserat block (d = 3, three symmetry faces).
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
)

import cartan
from cartan import Clamped, Damping, Free, Held, Symmetry, UniformForce
from cartan.integrators import RKMK4, LieVerlet, Overdamped
from cartan.schemes.collocation import Collocation

#: compiled against Python: one force evaluation sums a few tens of stencil terms in another
#: order, round-off of order 1e-15 of the largest nodal force (tests/test_compiled_paths.py); the
#: momenta take NSTEPS kicks of Δt·W, so they agree to NSTEPS·Δt·max|W|·FORCE_TOL
FORCE_TOL = 1e-13
#: the strains and frames: relative round-off over the run
TOL = 1e-12
NSTEPS = 30
DT = 1e-4


_rod = held_rod


def _pinned() -> cartan.Problem:
    return pinned_rod((0.0, 0.0, 0.0, 0.0, 4.0, 10.0))


_mirrored = mirrored_rod


def _both_held() -> cartan.Problem:
    rod = held_rod()
    grid = cartan.Grid(9, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0),
                          {"start": Held(components=(0, 1, 2)), "end": Symmetry()},
                          [Damping([1e5] * 6), UniformForce([0.0, 0.0, -5e3, 0.0, 0.0, 0.0])])


def _run_both(problem, make=LieVerlet, dt=DT, nsteps=NSTEPS):
    """:func:`toys.run_both_held` on the collocation scheme."""
    return run_both_held(Collocation, problem, make, dt, nsteps)


def _assert_agree_and_held(scheme, start, ref, fast, dt=DT, nsteps=NSTEPS, momentum=True):
    """Compiled against Python (the force a density per unit volume here), held components zero."""
    force = float(np.max(np.abs(scheme.internal_force(start))))
    assert_agree_and_held(scheme, start, ref, fast, nsteps * dt * force * FORCE_TOL, TOL, 1e-7, momentum)


_assert_kinetic = assert_kinetic_of_held


def _assert_simulate_agrees(problem, dt, nsteps, generated_runs):
    """``simulate`` on the generated loop against ``compiled=False``: positions, frames, velocities
    and kinetic energy to 1e-11 relative (round-off of the momenta's bound, over the run)."""
    kw = dict(scheme="collocation", integrator="lie-verlet", dt=dt, t_end=nsteps * dt, save_every=4,
              progress=False)
    out = cartan.simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    slow = cartan.simulate(problem, **kw, compiled=False)
    for name in ("position", "frame", "N", "kinetic_energy"):
        assert rel_error(out[name].values, slow[name].values) <= 1e-11, name


def test_operator_data_hold_the_components():
    """The set is no longer declined: ``held`` is the scheme's mask per component, ``clamped`` its
    wholly held rows, the held end's and the symmetry face's free components unloaded (P = 0)."""
    pinned = Collocation(_pinned()).compiled_operators()
    assert pinned.ok, pinned.reason
    data = pinned.data
    assert data.held[0].tolist() == [True] * 3 + [False] * 3 and not data.held[1:].any()
    assert not data.clamped.any() and data.any_held
    # the ends: the pin (no load) and the loaded free end
    assert data.end_idx.tolist() == [0, 8] and data.end_loaded.tolist() == [False, True]
    assert np.all(data.end_load[0] == 0.0) and data.end_follow.tolist() == [False, True]
    mirrored = Collocation(_mirrored())
    data = mirrored.compiled_operators().data
    assert data.clamped.tolist() == [True] + [False] * 8
    assert np.array_equal(data.held, mirrored._clamped)
    assert data.end_idx.tolist() == [8] and data.end_loaded.tolist() == [False]
    # a Held end holding every component is a clamp in the data
    rod = _rod()
    grid = cartan.Grid(9, length=1.0)
    whole = Collocation(cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                                       {"start": Held(components=tuple(range(6)))})).compiled_operators()
    assert whole.ok and whole.data.clamped[0] and not whole.data.any_held


def test_pinned_end_runs_compiled_and_agrees_with_the_numpy_path():
    scheme, start, ref, fast, _ = _run_both(_pinned())
    _assert_agree_and_held(scheme, start, ref, fast)
    _assert_kinetic(scheme, fast)
    assert_pin_holds(scheme, start, (ref, fast))


def test_symmetry_end_runs_compiled_and_agrees_with_the_numpy_path():
    scheme, start, ref, fast, _ = _run_both(_mirrored())
    _assert_agree_and_held(scheme, start, ref, fast)
    _assert_kinetic(scheme, fast)
    assert_symmetry_end_slides(scheme, start, (ref, fast), 1e-7)


def test_rkmk4_and_overdamped_hold_the_components():
    """``rkmk4`` (N = M⁺S from ``op_velocity``) on the pinned rod and ``overdamped`` (N = Γ⁻¹W)
    on a rod pinned at one end with a symmetry end at the other: the same tolerances."""
    runs = ((_pinned(), RKMK4, DT, 12, True), (_both_held(), lambda: Overdamped(order=1), 1e-5, 20, False))
    for problem, make, dt, nsteps, momentum in runs:
        scheme, start, ref, fast, fi = _run_both(problem, make, dt, nsteps)
        _assert_agree_and_held(scheme, start, ref, fast, dt, nsteps, momentum)
        held = np.broadcast_to(scheme._clamped, fast.S.shape)
        N = fi.velocity(scheme, fast)
        assert np.all(N[held] == 0.0) and np.any(N[~held] != 0.0)


def test_simulate_takes_the_generated_loop(generated_runs):
    """``simulate`` (saved frames, compiled diagnostics) on the generated loop against
    ``compiled=False``: positions, frames, velocities and energies to round-off (the bound as for
    the momenta: 1e-11 relative), and the held components' velocities exactly zero."""
    for make in (_pinned, _mirrored):
        generated_runs.clear()
        kw = dict(scheme="collocation", integrator="lie-verlet", dt=DT, t_end=NSTEPS * DT, save_every=10,
                  progress=False)
        fast = cartan.simulate(make(), **kw)
        assert generated_runs and all(generated_runs)
        ref = cartan.simulate(make(), **kw, compiled=False)
        for name in ("position", "frame", "N", "kinetic_energy", "potential_energy", "external_work"):
            assert rel_error(fast[name].values, ref[name].values) <= 1e-11, name
        assert np.array_equal(fast.step.values, ref.step.values)
        held = np.broadcast_to(Collocation(make())._clamped, fast.N.values.shape[1:])
        assert np.all(fast.N.values[:, held] == 0.0)


@pytest.mark.slow
def test_implicit_midpoint_holds_the_components():
    """``implicit-midpoint``'s compiled Newton blocks (the operators, unknowns from the scheme's
    mask) against the numpy backend on both rods: to round-off (measured ≤ 2.2e-14 relative, the
    velocities of the symmetry case; ≈ 20 s to compile the Newton module once)."""
    from cartan._backend import use_backend
    from cartan.integrators.implicit import _stage

    for make in (_pinned, _mirrored):
        assert _stage(Collocation(make())) is not None  # the compiled stage (not declined)
        kw = dict(scheme="collocation", integrator="implicit-midpoint", dt=DT, t_end=20 * DT, save_every=10,
                  progress=False)
        fast = cartan.simulate(make(), **kw)
        with use_backend("numpy"):
            ref = cartan.simulate(make(), **kw)
        for name in ("position", "frame", "N", "kinetic_energy"):
            assert rel_error(fast[name].values, ref[name].values) <= 1e-11, name
        held = np.broadcast_to(Collocation(make())._clamped, fast.N.values.shape[1:])
        assert np.all(fast.N.values[:, held] == 0.0)


@pytest.mark.slow
def test_nambu_goto_string_with_fixed_ends_runs_compiled(generated_runs):
    """The Nambu–Goto string between two fixed points (``Held((1, …, 9))`` ends on the Poincaré
    group: an indefinite, non-diagonal metric with gauge components, lie-verlet's eigenvector
    pieces; docs/media/relativistic-rod.md §3) on stepped frames: the generated loop against
    ``compiled=False`` over 40 steps (≈ 95 s to compile its module once)."""
    from cartan_relativistic.fixed import fixed_end

    rod = cartan.medium("relativistic-rod")
    grid = cartan.Grid(17, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "standing", angle=0.8),
                             boundaries={"start": fixed_end(), "end": fixed_end()})
    assert Collocation(problem).compiled_operators().data.any_held
    kw = dict(scheme="collocation", integrator="lie-verlet", dt=1.0 / 64, t_end=40 / 64, save_every=10,
              progress=False, scheme_options={"track_frames": True})
    fast = cartan.simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = cartan.simulate(problem, **kw, compiled=False)
    assert rel_error(ref.position.values[-1], ref.position.values[0]) > 0.1
    for name in ("position", "frame", "N", "kinetic_energy"):
        assert rel_error(fast[name].values, ref[name].values) <= 1e-11, name
    held = np.broadcast_to(Collocation(problem)._clamped, fast.N.values.shape[1:])
    assert np.all(fast.N.values[:, held] == 0.0)


@pytest.mark.slow
def test_d2_symmetry_edge_on_a_cosserat_surface(generated_runs):
    """d = 2: a flat Cosserat surface with a symmetry edge (u = 0, the plane x = 0) and a clamped
    edge (v = 0), under gravity and damping with an initial velocity: ``lie-verlet`` on the
    generated loop against the numpy path, the edge's nodes in their plane exactly (≈ 30 s to
    compile the surface's collocation module once).  The plate starts unstressed, so the
    round-off of the force is the stiffness times that of the strains, not a fraction of |W|:
    the momenta take the relative bound TOL."""
    medium = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = cartan.Grid((6, 5), length=(1.0, 0.8))
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(2)], indexing="ij"), axis=-1)
    N = np.zeros((*grid.shape, medium.group.dim))
    N[..., 2] = 1e-2 * np.cos(0.5 * np.pi * u[..., 0]) * np.sin(np.pi * u[..., 1] / 0.8)
    N[..., 0] = 1e-2 * np.sin(np.pi * u[..., 0])
    problem = cartan.Problem(medium, grid, cartan.InitialState(Phi=medium.initial_state(grid, "flat").Phi, N=N),
                             {"u-start": Symmetry(), "v-start": Clamped()},
                             [medium.make_load("gravity", g=[0.0, 0.0, -1e-3]), Damping(0.3)])
    dt, nsteps = 0.1 * grid.spacing[0], 12
    scheme, start, ref, fast, _ = _run_both(problem, LieVerlet, dt, nsteps)
    assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-4
    assert rel_error(fast.S, ref.S) <= TOL
    assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
    held = np.broadcast_to(scheme._clamped, fast.S.shape)
    for state in (ref, fast):
        assert np.all(state.S[held] == 0.0)
        # the symmetry edge slides in the plane x = 0 (held v_x)
        assert np.array_equal(scheme.frames(state)[0, :, 1, 0], start.arrays["Phi"][0, :, 1, 0])
    _assert_kinetic(scheme, fast)
    _assert_simulate_agrees(problem, dt, nsteps, generated_runs)


@pytest.mark.slow
def test_d3_symmetry_faces_on_a_cosserat_solid_octant(generated_runs):
    """d = 3: the octant of a Cosserat block (three ``Symmetry`` faces through the origin, its
    far u-face under a compressive traction; tests/test_symmetry_faces.py), ``lie-verlet`` at
    half the scheme's CFL estimate: the generated loop against the numpy path, the faces' nodes
    in their planes exactly, the line where two planes meet sliding along it only (≈ 40 s to
    compile the solid's collocation module once).  The block starts unstressed: the momenta
    take the relative bound TOL, as on the surface."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((4, 4, 4), length=(0.5, 0.5, 0.5))
    boundaries = {"u-start": Symmetry(), "v-start": Symmetry(normal="y"), "w-start": Symmetry(normal="z"),
                  "u-end": Free(load=[-0.05, 0.0, 0.0, 0.0, 0.0, 0.0])}
    problem = cartan.Problem(solid, grid, solid.initial_state(grid, "undeformed"), boundaries)
    probe = Collocation(problem)
    dt, nsteps = 0.5 * LieVerlet().dt_max(probe, probe.initial_state()), 12
    scheme, start, ref, fast, _ = _run_both(problem, LieVerlet, dt, nsteps)
    assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-7
    assert rel_error(fast.S, ref.S) <= TOL
    assert max(rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays) <= TOL
    held = np.broadcast_to(scheme._clamped, fast.S.shape)
    x0 = start.arrays["Phi"][..., 1:, 0]
    for state in (ref, fast):
        assert np.all(state.S[held] == 0.0) and np.any(state.S[~held] != 0.0)
        x = scheme.frames(state)[..., 1:, 0]
        assert np.all(x[0, :, :, 0] == x0[0, :, :, 0])  # the face u = 0 stays in the plane x = 0
        assert np.all(x[:, 0, :, 1] == x0[:, 0, :, 1])  # v = 0 in y = 0
        assert np.all(x[:, :, 0, 2] == x0[:, :, 0, 2])  # w = 0 in z = 0
        assert np.max(np.abs(x - x0)) > 1e-7
    _assert_kinetic(scheme, fast)
    _assert_simulate_agrees(problem, dt, nsteps, generated_runs)
