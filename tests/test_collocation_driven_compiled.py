"""Driven ends (:class:`cartan.Driven`) on the collocation scheme's compiled operators
(:mod:`cartan.schemes._collocation_ops`, "driven ends"): the generated loops against the numpy
path.

An SE(3) rod bent into an arc (curvature 2), clamped at u = 0 and driven at u = L, stepped 30
times by the Python step on the numpy path and by the generated loop in three blocks (1, 2, 27
steps): the generated loop really takes the steps, the momenta, strains and frames, the
dissipated energy and the supports' work (``external_work``: the power ``R·ξ`` with the weak-form
raw force of ``Collocation._clamped_traction``) agree to round-off, the driven end's frame is
Φ(0)exp(tξ) and its momentum ∂K/∂N(ξ).  ``lie-verlet`` (a twist, and a screw along the axis under
damping: the closing kick), ``lie-euler``, ``rkmk4``, ``overdamped`` and ``implicit-midpoint`` (a
general screw), and a plate's edge (``cosserat-surface``, d = 2) turned about its own line, its
corners on the free edges (their penalty terms in the raw force); the scene ``rod-twist-buckling``
(a dead ``NodeForce``, the node forces being data of the set too) with its end driven or free.

Slow: each loop of the driven rod's and the plate's modules compiles on first use (30–90 s on a
fresh cache).
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import rel_error

import cartan
from cartan.integrators import RKMK4, ImplicitMidpoint, LieVerlet, Overdamped
from cartan.integrators.explicit import LieEuler
from cartan.problem import InitialState
from cartan.schemes.collocation import Collocation

#: compiled against numpy, relative to the largest value: a force sums a few stencil terms per node
#: in another order (round-off ≈ 1e-16 per evaluation), 30 steps
TOL = 1e-12
NSTEPS = 30
BLOCKS = (1, 2, NSTEPS - 3)

#: a twist about the rod's axis, and a screw along it (parts in commuting pieces of lie-verlet's
#: free flow, which then moves the end by exp(Δtξ))
TWIST = np.array([0.0, 0.0, 0.0, 0.7, 0.0, 0.0])
AXIAL_SCREW = np.array([0.3, 0.0, 0.0, 0.7, 0.0, 0.0])
#: a general velocity: lie-euler, rkmk4, overdamped and implicit-midpoint move it by exp(Δtξ)
SCREW = np.array([0.1, -0.2, 0.05, 0.3, -0.4, 0.5])


def _arc(xi, n: int = 11, loads=()) -> cartan.Problem:
    """The rod of tests/test_collocation_driven.py bent into an arc of curvature 2 (an equilibrium
    between clamps), clamped at s = 0 and driven at s = 1 with ξ, starting with N(s) = ξ s."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[4.0, 4.0, 4.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                        rotational_inertia=[1.0, 0.5, 0.5])
    grid = cartan.Grid(n, length=1.0)
    u = grid.coordinates(0)
    Phi = rod.group.exp(u[:, None] * np.array([1.0, 0.0, 0.0, 0.0, 0.0, 2.0]))
    return cartan.Problem(rod, grid, InitialState(Phi=Phi, N=u[:, None] * np.asarray(xi)),
                          {"start": cartan.Clamped(), "end": cartan.Driven(velocity=xi)}, loads=list(loads))


def _plate() -> cartan.Problem:
    """A plate's edge u = L turned about its own line (tests/test_collocation_driven.py), its
    other edges along v free (the corners of the driven edge on them), the edge u = 0 clamped."""
    shell = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.1, density=1.0)
    grid = cartan.Grid((9, 5), length=(1.0, 0.5))
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
    return cartan.Problem(shell, grid, shell.initial_state(grid, "flat"),
                          {"u-start": cartan.Clamped(), "u-end": cartan.Driven(velocity=xi)},
                          [shell.make_load("gravity", g=[0.0, 0.0, -1e-2])])


def _start(scheme):
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    return state


def _run_both(problem, make, dt):
    """The numpy path (``Integrator.step`` under the numpy backend) and the generated loop in
    ``BLOCKS``: (scheme, reference state, compiled state)."""
    from cartan._backend import use_backend

    scheme = Collocation(problem)
    ref, fast = _start(scheme), _start(scheme)
    ri, fi = make(), make()
    with use_backend("numpy"):
        for _ in range(NSTEPS):
            ri.step(scheme, ref, dt)
    for size in BLOCKS:  # the generated loop takes the steps (implicit-midpoint's Newton blocks: compiled_advance)
        if isinstance(fi, ImplicitMidpoint):
            assert fi.compiled_advance(scheme, fast, dt, size)
        else:
            assert fi.run_compiled_loop(scheme, fast, dt, size)
    return scheme, ref, fast


def _assert_agree(scheme, ref, fast, dissipates: bool = False, momentum: bool = True):
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"] == NSTEPS
    assert rel_error(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert rel_error(fast.arrays[key], ref.arrays[key]) <= TOL, key
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= TOL * max(abs(ref.scalars[key]), 1e-300), key
    assert ref.scalars["external_work"] != 0.0  # the supports work
    assert (ref.scalars["dissipated_energy"] > 0.0) == dissipates
    # the driven end: Φ(0)exp(tξ) (round-off of 30 exact steps), its momentum ∂K/∂N(ξ), velocity ξ
    mask, Nd, Sd = scheme._driven
    exact = np.einsum("...ij,...jk->...ik", scheme.problem.initial.Phi[mask], scheme.group.exp(fast.t * Nd[mask]))
    assert np.max(np.abs(fast.arrays["Phi"][mask] - exact)) < 1e-12
    assert np.array_equal(fast.S[mask], Sd[mask]) or not momentum  # (overdamped keeps no momentum)
    assert rel_error(fast.arrays["Phi"], scheme.initial_state().arrays["Phi"]) > 1e-6  # the run moved


def test_the_driven_set_serves_the_loops():
    """The set is no longer declined: the driven nodes with their ξ and ∂K/∂N(ξ), the nodes of
    their stencils, the weak-form term of the driven end through them; not ``ok``, it serves the
    loops of the integrators that move driven ends and the compiled diagnostics
    (tests/test_driven_diagnostics.py), not rattle's (the collocation's nodal rows run the Python
    step)."""
    scheme = Collocation(_arc(TWIST))
    ops = scheme.compiled_operators()
    data = ops.data
    assert data.any_driven and not ops.ok and "Driven" in ops.reason and "diagnostics" in ops.reason
    for loop in ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop"):
        assert ops.serves(loop)
    assert not ops.serves("rattle_loop")
    assert data.dnodes.tolist() == [10] and data.clamped[[0, 10]].all() and data.clamped[1:10].sum() == 0
    assert np.array_equal(data.xi_d[10], TWIST) and np.array_equal(data.S_d[10], scheme._driven[2][-1])
    assert data.pnodes.tolist() == [9, 10]  # the SBP end row of fd2
    assert data.dtr_sign.tolist() == [1.0] and data.dtr_H.tolist() == [0.05]
    assert data.dend_item.size == 0  # no free end through the driven node
    clamped = Collocation(cartan.Problem(scheme.problem.medium, scheme.grid, scheme.problem.initial,
                                         {"start": cartan.Clamped()})).compiled_operators()
    assert clamped.ok and not clamped.data.any_driven


def test_the_plate_lists_its_corners_free_faces():
    """d = 2: a driven edge's corners lie on the free edges along v, whose penalty terms enter
    their raw force (``dend_item``); the stencils read the nodes along both axes."""
    data = Collocation(_plate()).compiled_operators().data
    n = 9 * 5
    assert data.dnodes.tolist() == list(range(n - 5, n))
    corners = {int(data.end_idx[p]) for p in data.dend_item}
    assert corners == {n - 5, n - 1}
    assert set(data.pnodes.tolist()) >= set(range(n - 10, n))


@pytest.mark.slow  # (the driven rod's lie-verlet loop compiles on first use: 30–90 s on a fresh cache)
@pytest.mark.parametrize(("xi", "loads"), [(TWIST, ()), (AXIAL_SCREW, (cartan.Damping([0.3] * 6),))],
                         ids=["twist", "axial-screw-damped"])
def test_lie_verlet_moves_a_driven_end_compiled(xi, loads):
    scheme, ref, fast = _run_both(_arc(xi, loads=loads), LieVerlet, 2e-3)
    _assert_agree(scheme, ref, fast, dissipates=bool(loads))


@pytest.mark.slow  # (each loop compiles on first use: 30–90 s on a fresh cache)
@pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")
@pytest.mark.parametrize(("make", "loads", "dt"), [
    (LieEuler, (), 2e-3), (RKMK4, (), 2e-3), (lambda: Overdamped(1), (cartan.Damping([10.0] * 6),), 1e-3),
], ids=["lie-euler", "rkmk4", "overdamped"])
def test_the_other_explicit_loops_move_a_driven_end_compiled(make, loads, dt):
    fi_uses_momentum = make().uses_momentum  # (overdamped keeps no momentum)
    scheme, ref, fast = _run_both(_arc(SCREW, loads=loads), make, dt)
    _assert_agree(scheme, ref, fast, dissipates=bool(loads), momentum=fi_uses_momentum)


@pytest.mark.slow  # (the Newton loop compiles on first use: 30–90 s on a fresh cache)
def test_implicit_midpoint_moves_a_driven_end_compiled():
    """Newton's blocks (ξ = Δtξ_d at the driven node, no unknown) against the numpy backend, both
    converged to round-off (tol 1e-13: the floor of the convergence test decides)."""
    scheme, ref, fast = _run_both(_arc(SCREW), lambda: ImplicitMidpoint(tol=1e-13), 2e-3)
    _assert_agree(scheme, ref, fast)


@pytest.mark.slow  # (the plate's driven module compiles on first use: 30–90 s on a fresh cache)
def test_a_plate_edge_driven_compiled():
    scheme, ref, fast = _run_both(_plate(), LieVerlet, 2e-3)
    _assert_agree(scheme, ref, fast)


@pytest.mark.slow  # (the driven rod's lie-verlet loop of the tests above: compiles on first use)
def test_simulate_takes_the_generated_loop(generated_runs):
    """``simulate`` on the generated loop against ``compiled=False`` (the rod of
    tests/test_collocation_driven.py twisted at its end): positions, frames, momenta, strains and
    the supports' work to round-off (1e-12 relative)."""
    from test_driven_end import _problem

    kw = dict(scheme="collocation", integrator="lie-verlet", dt=2e-3, t_end=0.04, save_every=5, progress=False)
    fast = cartan.simulate(_problem(TWIST), **kw)
    assert generated_runs and all(generated_runs)
    ref = cartan.simulate(_problem(TWIST), compiled=False, **kw)
    assert ref.external_work.values[-1] != 0.0
    for name in ("position", "frame", "S", "X", "kinetic_energy", "external_work"):
        assert rel_error(fast[name].values, ref[name].values) <= TOL, name


def _scene(end=None) -> cartan.Problem:
    """The scene ``rod-twist-buckling`` (a rod clamped at s = 0, twisted at s = L, under damping and
    a dead ``NodeForce`` at s = ½ that seeds the buckling), its end ``end`` when given."""
    from pathlib import Path

    from cartan.scene import load_scene

    path = Path(__file__).parents[1] / "plugins/cartan_filament/scenes/rod-twist-buckling.toml"
    problem = load_scene(path).problem
    if end is not None:
        problem = cartan.Problem(problem.medium, problem.grid, problem.initial, {"start": cartan.Clamped(), "end": end},
                                 problem.loads)
    return problem


def test_node_forces_are_data():
    """A ``NodeForce`` (dead or follower) is data of the set (``nf_*``): the node, P, its frame and
    the weight it divides P by; the scene's set serves the driven loops."""
    ops = Collocation(_scene()).compiled_operators()
    assert ops.serves("lie_verlet_loop") and ops.data.any_driven
    assert ops.data.nf_idx.tolist() == [15] and ops.data.nf_follow.tolist() == [False]
    assert np.array_equal(ops.data.nf_load[0], [0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    assert ops.data.nf_w.tolist() == [pytest.approx(1.0 / 30)]


@pytest.mark.slow  # (the driven rod's lie-verlet loop; the free rod's: compiles on first use)
@pytest.mark.parametrize("end", ["driven", "free"])
def test_a_dead_node_force_compiled(end):
    """The scene's problem (damping, a dead node force, the driven end; or that end free under a
    follower node force too) on the generated loop against the numpy path: the node forces' power
    in ``external_work``, booked as ``Scheme.powers`` does."""
    if end == "driven":
        problem = _scene()
    else:
        problem = _scene(cartan.Free())
        problem = cartan.Problem(problem.medium, problem.grid, problem.initial, problem.boundaries,
                                 [*problem.loads, cartan.problem.NodeForce(problem.grid, [0.0] * 4 + [0.02, 0.0],
                                                                           node=-1, frame="body")])
    scheme = Collocation(problem)
    ref, fast = _start(scheme), _start(scheme)
    ri, fi = LieVerlet(), LieVerlet()
    from cartan._backend import use_backend

    with use_backend("numpy"):
        for _ in range(NSTEPS):
            ri.step(scheme, ref, 1.5e-3)
    for size in BLOCKS:
        assert fi.run_compiled_loop(scheme, fast, 1.5e-3, size)
    assert rel_error(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert rel_error(fast.arrays[key], ref.arrays[key]) <= TOL, key
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= TOL * abs(ref.scalars[key]), key
