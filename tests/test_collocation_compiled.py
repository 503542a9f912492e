"""The collocation scheme on the compiled path against the Python reference path.

Collocation runs the integrators' generated loops (``Integrator.run_compiled_loop``) over its
compiled operator set (``Collocation.compiled_operators()``, :mod:`cartan.schemes._collocation_ops`),
and the stiffness products of the CFL estimate on the same operators
(:mod:`cartan.compiled.diagnostics`).  The reference is ``Integrator.step`` with the scheme's
numpy methods.  The compiled steps must agree with it to 1e-12, relative to each array's
magnitude, on every state array and energy accumulator (the differences are round-off: the
same formulas in another order, the Fourier derivative as a dense circulant matrix instead of
an FFT), count steps and force evaluations identically, give the same bits in one call as in
blocks, and hand their caches over to the Python loop.

What this file adds to ``tests/test_compiled_paths.py`` (the rods of both schemes: blocks,
counters, fast spin, gauge components, stopping, declining, restarts, the numba cache) and
``tests/test_generated_collocation.py`` (the operator set on other media and metrics): every
integrator × difference rule × boundary kind on toy rods of every group, Cosserat rods with
``fd4`` under gravity, the integrators those files leave out of the fast-spin and gauge
cases, single force and drift evaluations, d = 2 and 3 grids, and the CFL estimate on every
case.

Compile budget: each (group, medium, d) is one generated module.  The un-marked tests use the
modules the other files build — the toy quadratic rod on SO(2) (d = 1), the Cosserat rod on
SE(3) (d = 1) and the sigma model on S² (d = 2); the other groups, toy surfaces and d = 3 are
marked ``slow``.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import toys
from toys import QuadraticMedium, params_of

import cartan
from cartan.api import simulate
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from cartan.problem import Clamped, ConstantFieldPotential, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes.collocation import Collocation

#: compiled against Python over whole runs: round-off
TOL = 1e-12
#: one force evaluation or one drift: a few hundred operations in another order
OP_TOL = 1e-13
SLOW = pytest.mark.slow
#: integrators the fast suite runs per module (each loop of each module compiles for 10-45 s on a
#: fresh cache): the toy rod on SO(2) the Euler family only, the Cosserat rod on SE(3) and the
#: sigma model on S² the leapfrog and the RKMK loops; every other pair is in ``make test-slow``
FAST_TOY = {"lie-euler"}
FAST_ROD = {"lie-verlet", "overdamped-1", "overdamped-2", "rkmk4"}


def _fast_only(names, fast):
    """``names`` as parameters, those outside ``fast`` marked slow."""
    return [n if n in fast else pytest.param(n, marks=SLOW) for n in names]

#: (integrator factory, Δt, steps): Δt inside each method's stable range for the toy rods
#: (forward-euler is unstable at every Δt: a few small steps only)
INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 30),
    "lie-euler": (LieEuler, 2e-4, 30),
    "forward-euler": (ForwardEuler, 1e-5, 8),
    "rkmk4": (RKMK4, 1e-3, 12),
    "overdamped-1": (lambda: Overdamped(order=1), 2e-6, 30),
    "overdamped-2": (lambda: Overdamped(order=2), 2e-6, 15),
}
#: the same for the d = 2, 3 grids below (h ≥ 0.1, wave speeds ≤ 7, drag ≥ 0.5: the overdamped
#: flows are stable below Δt ≈ 1e-4 with fd4 and fourier)
GRID_INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 16),
    "lie-euler": (LieEuler, 2e-4, 16),
    "forward-euler": (ForwardEuler, 1e-5, 5),
    "rkmk4": (RKMK4, 1e-3, 6),
    "overdamped-1": (lambda: Overdamped(order=1), 1e-5, 16),
    "overdamped-2": (lambda: Overdamped(order=2), 1e-5, 8),
}
#: closed generators: exp(2π ξ) = I, so Φ(u) = exp(u ξ) is a closed rod of length 2π
RING = {"SO2": [1.0], "SE2": [1.0, 0.0, 1.0], "SO3": [0.0, 0.0, 1.0], "SE3": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0]}
#: (boundary kind, derivative): rings with every operator, open rods with fd2 and fd4
CASES = [("ring", "fd2"), ("ring", "fd4"), ("ring", "fourier"), ("clamped", "fd2"), ("clamped", "fd4"),
         ("free", "fd2"), ("free", "fd4")]
CASE_IDS = [f"{k}-{d}" for k, d in CASES]
#: SO(2) shares its module with tests/test_generated_collocation.py; the others compile their own
GROUPS = ["SO2", pytest.param("SE2", marks=SLOW), pytest.param("SO3", marks=SLOW), pytest.param("SE3", marks=SLOW)]

def slow_when(item) -> bool:
    """``make test`` runs the generated ``lie-verlet`` loop of the toy rods; the other integrators'
    loops and the d = 2 sigma models' in ``make test-slow`` (tests/conftest.py)."""
    return params_of(item).get("name", "lie-verlet") != "lie-verlet" or item.originalname in {
        "test_grids_agree_with_python", "test_grid_blocks_and_caches_match_the_step_loop",
        "test_simulate_sigma_model_d2_runs_compiled",
        "test_cfl_products_and_estimates_match_numpy",  # the compiled probes: used from 60,000 unknowns
        "test_cfl_rod_with_and_without_frames"}


run_both = functools.partial(toys.run_both, Collocation)
_rel = toys.rel_error


def assert_close_states(a, b, tol=TOL):
    toys.assert_close_states(a, b, tol)


# ---------------------------------------------------------------------------- problems
def _velocity(u: np.ndarray, length: float, r: int, amp: float) -> np.ndarray:
    """A smooth periodic, non-uniform velocity field ``[n, r]`` of non-zero mean (the power of a
    uniform force does not cancel to round-off)."""
    k = 2 * np.pi * u[:, None] / length
    return amp * (0.5 + np.sin(k + np.arange(r)[None, :])) * np.linspace(1.0, 0.5, r)


def toy_problem(group: str, kind: str, n: int = 10) -> Problem:
    """A quadratic rod on ``group``: a closed ring (``"ring"``); clamped at the start with a
    dead end load (frames stepped at every node); or free at both ends with a follower load
    (only the root frame stepped).  Damping and a body-frame force on all of them."""
    G = cartan.group(group)
    r = G.dim
    medium = QuadraticMedium(group, rest=np.eye(r)[0] if r > 1 else [0.5])
    if kind == "ring":
        grid = Grid(n, 2 * np.pi, periodic=True)
        xi = np.array(RING[group])
    else:
        grid = Grid(n, 1.0)
        xi = np.linspace(1.0, 0.4, r)
    u = grid.coordinates(0)
    init = InitialState(Phi=G.exp(u[:, None] * xi), N=_velocity(u, grid.length[0], r, 0.3))
    loads = [Damping(np.linspace(0.1, 0.3, r)), UniformForce(np.linspace(-0.2, 0.3, r))]
    boundaries = {}
    if kind == "clamped":
        boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=False)}
    elif kind == "free":
        boundaries = {"end": Free(load=np.linspace(0.3, -0.2, r), follower=True)}
    return Problem(medium, grid, init, boundaries, loads)


def rod_problem(planar: bool = False, n: int = 11) -> Problem:
    """The Cosserat rod of ``toys.rod_problem`` bent into an arc, clamped with a dead end load,
    under gravity (a constant-field potential) and damping."""
    return toys.rod_problem("dead", planar=planar, n=n)


def ring_rod(n: int = 12) -> Problem:
    """The Cosserat rod (SE(3)) closed into a wavy ring of length 2π (exp(2πξ) = I), moving."""
    medium = toys.moving_rod(False)
    G = medium.group
    grid = Grid(n, 2 * np.pi, periodic=True)
    u = grid.coordinates(0)
    wave = 0.05 * np.sin(u)[:, None] * np.linspace(1.0, 0.5, 6)
    Phi = G.compose(G.exp(u[:, None] * np.array(RING["SE3"])), G.exp(wave))
    return Problem(medium, grid, InitialState(Phi=Phi, N=_velocity(u, 2 * np.pi, 6, 0.2)), loads=[Damping(0.1)])


class Surface(QuadraticMedium):
    """``U = ½Σ_α(X_α − X₀_α)ᵀC(X_α − X₀_α)`` on a d = 2 or 3 grid with a rest strain per axis
    (the form of a linear Cosserat surface or solid), on any group; the frame bundle of E² or
    E³ as its space on SE(2), SE(3) (positions for a constant field)."""

    name = "toy-surface"

    def __init__(self, group: str, d: int = 2, coupled: bool = False):
        super().__init__(group, mass=np.linspace(1.0, 0.4, cartan.group(group).dim))
        self.material_dim = d
        r = self.group.dim
        C = np.diag(self.C)
        if coupled:
            B = np.random.default_rng(3).standard_normal((r, r))
            C = B @ B.T + r * np.eye(r)
        X0 = np.zeros((d, r))
        for a in range(d):
            X0[a, a % r] = 1.0
        X0[-1] += np.linspace(-0.2, 0.3, r)
        self._set_energy(X0, C)
        if group in ("SE2", "SE3"):
            self.space = cartan.space("frame-E2" if group == "SE2" else "frame-E3")


def _fields(grid: Grid, r: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A smooth algebra field (periodic on the periodic axes) ``[*shape, r]`` for the frames and
    a smooth velocity of non-zero mean."""
    rng = np.random.default_rng(seed)
    u = np.meshgrid(*[grid.coordinates(a) / grid.length[a] for a in range(grid.d)], indexing="ij")
    xi = np.zeros((*grid.shape, r))
    N = np.zeros((*grid.shape, r))
    for a in range(grid.d):
        xi += 0.4 * np.sin(2 * np.pi * u[a] + a)[..., None] * rng.standard_normal(r)
        N += 0.3 * (0.5 + np.cos(2 * np.pi * u[a] - a))[..., None] * np.linspace(1.0, 0.5, r)
    return xi, N


def surface_problem(group: str, shape: tuple, periodic, boundaries=None, gravity=False, coupled=False) -> Problem:
    """A toy surface (d = 2) or solid (d = 3) with damping and a body-frame force, optionally a
    constant field (SE groups) and face conditions."""
    medium = Surface(group, d=len(shape), coupled=coupled)
    g = medium.group
    grid = Grid(shape, tuple(1.0 - 0.1 * a for a in range(len(shape))), periodic=periodic)
    xi, N = _fields(grid, g.dim, seed=len(shape))
    loads = [Damping(np.linspace(0.5, 1.0, g.dim)), UniformForce(np.linspace(-0.2, 0.3, g.dim))]
    if gravity:
        loads.append(ConstantFieldPotential(np.linspace(-1.0, 0.5, g.space_dim), density=0.7))
    return Problem(medium, grid, InitialState(Phi=g.exp(xi), N=N), boundaries or {}, loads)


def sigma_problem(shape: tuple, periodic, boundaries=None, n: int = 2) -> Problem:
    """The sigma model on Sⁿ (SO(n+1), gauge components without inertia) with its harmonic-map
    drag: a smooth random field with a gauge twist and a velocity."""
    medium = cartan.medium("sigma-model", n=n, d=len(shape))
    grid = Grid(shape, 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    return Problem(medium, grid, init, boundaries or {}, [medium.make_load("drag", gamma=0.7)])


#: name → (problem, derivative): every group, periodic and open axes, clamped faces, follower
#: and dead face loads (a dead load and the constant field need every frame), and d = 3
GRID_CASES = {
    "sigma-torus": (lambda: sigma_problem((8, 7), (True, True)), "fd2"),
    "sigma-cylinder-fd4": (lambda: sigma_problem((9, 8), (False, True), {
        "u-start": Clamped(), "u-end": Free(load=[0.2, -0.1, 0.0], follower=True)}), "fd4"),
    "se2-open-dead-load": (lambda: surface_problem("SE2", (7, 6), (False, False), {
        "u-start": Clamped(), "v-end": Free(load=[0.3, -0.2, 0.1], follower=False)}, gravity=True), "fd2"),
    "se3-torus-fourier": (lambda: surface_problem("SE3", (8, 6), (True, True), coupled=True), "fourier"),
    "so2-free-faces": (lambda: surface_problem("SO2", (8, 6), (False, True)), "fd4"),
    "se3-solid-d3": (lambda: surface_problem("SE3", (5, 4, 4), (True, False, True), {
        "v-start": Clamped(), "v-end": Free(load=np.linspace(0.1, 0.6, 6), follower=True)}), "fd2"),
    "sigma-d3": (lambda: sigma_problem((5, 4, 4), (False, True, False), {
        "w-end": Free(load=[0.1, 0.2, 0.0], follower=True)}), "fd2"),
}
#: the sigma model on S², d = 2, shares its module with tests/test_generated_collocation.py
FAST_GRID_CASES = ("sigma-cylinder-fd4",)


# ---------------------------------------------------------------------------- d = 1: agreement
@pytest.mark.parametrize("group", GROUPS)
@pytest.mark.parametrize(("kind", "derivative"), CASES, ids=CASE_IDS)
@pytest.mark.parametrize("name", _fast_only(sorted(INTEGRATORS), FAST_TOY))
def test_toy_rods_agree_with_python(name, kind, derivative, group):
    make, dt, nsteps = INTEGRATORS[name]
    scheme, (ref, ri), (fast, fi) = run_both(toy_problem(group, kind), make, dt, nsteps, derivative=derivative)
    assert not scheme.has_hand_written_loops() and scheme.compiled_operators().ok
    assert set(fast.arrays) == {"X", "Phi" if kind == "clamped" else "Phi_root"}
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    assert fi.wall_time > 0
    # the run moved the configuration (the comparison is not between two copies of the start)
    start = scheme.initial_state()
    assert max(_rel(ref.arrays[k], start.arrays[k]) for k in start.arrays) > 1e-9


@pytest.mark.parametrize("planar", [False, pytest.param(True, marks=SLOW)], ids=["SE3", "SE2"])
@pytest.mark.parametrize("name", _fast_only(sorted(INTEGRATORS), FAST_ROD))
def test_rods_under_gravity_with_fd4(name, planar):
    """The Cosserat rod with a dead end load, gravity and damping, ``fd4`` (its ``fd2`` runs are
    in ``tests/test_compiled_paths.py``)."""
    make, dt, nsteps = INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(rod_problem(planar), make, dt, nsteps, derivative="fd4")
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@pytest.mark.parametrize("name", _fast_only(["lie-verlet", "lie-euler", "overdamped-1", "overdamped-2"], FAST_ROD))
def test_blocks_and_caches_match_the_step_loop(name):
    """Split into blocks, the compiled path counts like the Python path (first-same-as-last
    force, cached overdamped velocity), gives the bits of one call, and hands its caches over to
    a following Python step."""
    make, dt, _ = INTEGRATORS[name]
    scheme, (ref, ri), (fast, fi) = run_both(rod_problem(), make, dt, 13, blocks=(1, 1, 2, 4, 5))
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    # each compiled step depends on the state only: one call gives the same bits as the blocks
    _, _, (whole, _) = run_both(rod_problem(), make, dt, 13)
    assert np.array_equal(whole.S, fast.S)
    assert all(np.array_equal(whole.arrays[k], fast.arrays[k]) for k in fast.arrays)
    ri.step(scheme, ref, dt)
    fi.step(scheme, fast, dt)
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


@pytest.mark.parametrize("name", _fast_only(["lie-euler", "overdamped-1", "overdamped-2"], {"overdamped-1"}))
def test_fast_spin_agrees(name):
    """Turns of 0.3 rad per step and nodes at rest (the clamp) in the same run, for the
    integrators ``tests/test_compiled_paths.py`` does not spin (for the overdamped flows, a
    uniform body moment turns the nodes, at half the flow's stable step)."""
    make, dt, _ = INTEGRATORS[name]
    base = rod_problem(n=12)
    if name.startswith("overdamped"):
        probe = Collocation(Problem(base.medium, base.grid, base.initial, base.boundaries, [Damping(1.0)]))
        dt = 0.5 * Overdamped().dt_max(probe, probe.initial_state())
        moment = UniformForce(np.array([0.0, 0.0, 0.0, 1.0, 0.5, 0.2]) * 0.3 / dt)
        problem = Problem(base.medium, base.grid, base.initial, base.boundaries, [Damping(1.0), moment])
    else:
        N = base.initial.N.copy()
        N[:, 3:] *= 0.3 / (dt * np.max(np.linalg.norm(N[1:, 3:], axis=1)))
        problem = Problem(base.medium, base.grid, InitialState(Phi=base.initial.Phi, N=N), base.boundaries,
                          base.loads)
    scheme, (ref, _), (fast, _) = run_both(problem, make, dt, 6)
    start = scheme.initial_state()
    N = Overdamped().drift_velocity(scheme, start, 0.0) if name.startswith("overdamped") else scheme.velocity(start)
    theta = dt * np.linalg.norm(N[:, 3:], axis=1)
    assert theta.max() > 0.25 and theta.min() < 0.1  # turning nodes and nodes at rest
    assert_close_states(fast, ref)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lie-euler", "overdamped-1", "overdamped-2"])
def test_se3_with_a_gauge_component(name):
    """A zero inertia, for the integrators ``tests/test_compiled_paths.py`` leaves out: the gauge
    component of the momentum stays zero."""
    make, dt, nsteps = INTEGRATORS[name]

    class GaugeRod(type(toys.moving_rod(False))):
        """The test rod without inertia along its third translation (the same point kernels)."""

        def inertia(self):
            m = np.array(super().inertia(), dtype=float)
            m[2] = 0.0
            return m

    base = rod_problem()
    medium = GaugeRod(stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                      rotational_inertia=[0.02, 0.01, 0.01])
    scheme, (ref, ri), (fast, fi) = run_both(Problem(medium, base.grid, base.initial, base.boundaries, base.loads),
                                             make, dt, nsteps)
    assert not scheme.live[2]
    assert_close_states(fast, ref)
    assert np.all(fast.S[:, 2] == 0.0)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@SLOW
def test_coupled_stiffness():
    """A full symmetric C (coupled strains) in the force and the stress."""
    r = 6
    B = np.random.default_rng(3).standard_normal((r, r))
    base = toy_problem("SE3", "clamped")
    medium = QuadraticMedium("SE3", stiffness=B @ B.T + r * np.eye(r))
    problem = Problem(medium, base.grid, base.initial, base.boundaries, base.loads)
    for make in (LieVerlet, LieEuler, RKMK4):
        _, (ref, _), (fast, _) = run_both(problem, make, 5e-4, 20, derivative="fd4")
        assert_close_states(fast, ref)


# ---------------------------------------------------------------------------- d = 2, 3: agreement
@pytest.mark.parametrize("case", [c if c in FAST_GRID_CASES else pytest.param(c, marks=SLOW) for c in GRID_CASES])
@pytest.mark.parametrize("name", _fast_only(sorted(GRID_INTEGRATORS), FAST_ROD))
def test_grids_agree_with_python(name, case):
    make, dt, nsteps = GRID_INTEGRATORS[name]
    build, derivative = GRID_CASES[case]
    problem = build()
    scheme, (ref, ri), (fast, fi) = run_both(problem, make, dt, nsteps, derivative=derivative)
    assert scheme.grid.d >= 2 and scheme.compiled_operators().ok
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    # the run moved the configuration and booked energy (not a comparison of two copies of the start)
    start = scheme.initial_state()
    assert _rel(ref.arrays["X"], start.arrays["X"]) > 1e-9
    assert ref.scalars["dissipated_energy"] != 0.0
    if problem.boundaries or any(isinstance(ld, UniformForce) for ld in problem.loads):
        assert ref.scalars["external_work"] != 0.0


@pytest.mark.parametrize("name", ["lie-verlet", "overdamped-1", "overdamped-2"])
def test_grid_blocks_and_caches_match_the_step_loop(name):
    """On a d = 2 grid: counters and caches (first-same-as-last force, overdamped velocity, both
    in the state's shape) across blocks, the bits of one call, and a following Python step."""
    make, dt, _ = GRID_INTEGRATORS[name]
    build, derivative = GRID_CASES["sigma-cylinder-fd4"]
    scheme, (ref, ri), (fast, fi) = run_both(build(), make, dt, 10, blocks=(1, 2, 3, 4), derivative=derivative)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    _, _, (whole, _) = run_both(build(), make, dt, 10, derivative=derivative)
    assert np.array_equal(whole.S, fast.S)
    assert all(np.array_equal(whole.arrays[k], fast.arrays[k]) for k in fast.arrays)
    cached = fi._fsal if name == "lie-verlet" else fi._cache
    assert np.shape(cached[1]) == fast.S.shape
    ri.step(scheme, ref, dt)
    fi.step(scheme, fast, dt)
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


# ---------------------------------------------------------------------------- single operations
#: name → (problem, derivative): open and closed rods with every difference rule, and grids
OPERATION_CASES = {
    "rod-fd4": lambda: (rod_problem(n=12), "fd4"),
    "ring-fd4": lambda: (ring_rod(), "fd4"),
    "ring-fourier": lambda: (ring_rod(), "fourier"),
    "sigma-cylinder-fd4": lambda: (GRID_CASES["sigma-cylinder-fd4"][0](), "fd4"),
    "se2-open-dead-load": lambda: (GRID_CASES["se2-open-dead-load"][0](), "fd2"),
    "se3-solid-d3": lambda: (GRID_CASES["se3-solid-d3"][0](), "fd2"),
}
FAST_OPERATION_CASES = ("rod-fd4", "ring-fd4", "ring-fourier")  # the d = 2 sigma model: slow suite


@pytest.mark.parametrize("case", [c if c in FAST_OPERATION_CASES else pytest.param(c, marks=SLOW)
                                  for c in OPERATION_CASES])
def test_force_and_drift_match_the_scheme(case):
    """One force evaluation (``op_force``) and one drift, exact (``op_drift``) and naive
    (``op_drift_naive``), at a perturbed state with every frame, against ``Collocation.force``
    and ``Collocation.drift``."""
    problem, derivative = OPERATION_CASES[case]()
    scheme = Collocation(problem, derivative=derivative, track_frames=True)
    ops = scheme.compiled_operators()
    assert ops.ok, ops.reason
    module = ops.generated()
    state = scheme.initial_state()
    rng = np.random.default_rng(0)
    n, r = ops.nodes, scheme.group.dim
    state.arrays["X"] = state.arrays["X"] + 0.05 * rng.standard_normal(state.arrays["X"].shape)
    N = rng.standard_normal(state.S.shape)
    W = np.empty((n, r))
    module.op_force(ops.data, ops.pack(state), 0.0, N.reshape(n, r), W, module.op_work(ops.data))
    assert _rel(W.reshape(N.shape), scheme.force(state, N, 0.0)) <= OP_TOL
    for exact, drift in ((True, module.op_drift), (False, module.op_drift_naive)):
        moved = state.copy()
        scheme.drift(moved, 0.05, N, exact=exact)
        C = ops.pack(state)
        drift(ops.data, C, 0.05, N.reshape(n, r), module.op_work(ops.data))
        fast = state.copy()
        ops.unpack(fast, C)
        for key in ("X", "Phi"):
            assert _rel(fast.arrays[key], moved.arrays[key]) <= OP_TOL, (exact, key)
        assert _rel(fast.arrays["X"], state.arrays["X"]) > 1e-6  # the drift moved the strains


# ---------------------------------------------------------------------------- stopping, declining
@pytest.mark.parametrize("make", [LieVerlet, pytest.param(LieEuler, marks=SLOW), pytest.param(RKMK4, marks=SLOW)],
                         ids=["lie-verlet", "lie-euler", "rkmk4"])
@pytest.mark.parametrize("grid", ["rod", pytest.param("sigma-d2", marks=SLOW)])
def test_kinetic_limit_stops_after_the_failing_step(grid, make):
    problem = rod_problem() if grid == "rod" else GRID_CASES["sigma-cylinder-fd4"][0]()
    scheme = Collocation(problem)
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    integ = make()
    assert integ.run_compiled_loop(scheme, state, 1e-4, 20, kinetic_limit=1e-12)
    assert state.scalars["nstep"] == 1 and integ.nstep == 1


def _declines(problem, integ, **scheme_options):
    """The generated loop returns False and touches neither the state nor the counters."""
    scheme = Collocation(problem, **scheme_options)
    state = scheme.initial_state()
    before = state.copy()
    assert not toys.advance_compiled(scheme, integ, state, 1e-4, 3)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
    assert integ.nstep == 0


def test_unsupported_combinations_decline_on_grids():
    """On a d = 2 grid (the rods' cases are in ``tests/test_compiled_paths.py``): a kinematic
    velocity that is a Python function, a spatial force, the overdamped flow without drag, a
    dead face load without the frames, and the numpy backend."""
    base = sigma_problem((6, 5), (True, True))
    _declines(base, Kinematic(velocity=lambda t, u, X: np.zeros((6, 5, 3))))
    spatial = Problem(base.medium, base.grid, base.initial, loads=[UniformForce(np.ones(3), frame="spatial")])
    _declines(spatial, LieVerlet())
    _declines(Problem(base.medium, base.grid, base.initial), Overdamped())  # no drag: Python raises
    dead = surface_problem("SE3", (6, 5), (False, True), {"u-end": Free(load=np.ones(6), follower=False)})
    _declines(dead, LieVerlet(), track_frames=False)  # the dead load needs the frames
    with cartan.use_backend("numpy"):
        _declines(base, LieVerlet())


def test_what_qualifies():
    """Media with point kernels on every grid qualify — the sigma model on S² (d = 2, 3) and on
    S³ (SO(4)), quadratic SE(3)/SE(2) surfaces, open or periodic, with a constant field; a
    surface whose energy methods are overridden without kernels does not, and says so."""
    for problem in (sigma_problem((16, 16), (True, True)), sigma_problem((6, 5, 4), (True, False, True)),
                    sigma_problem((6, 6), (True, True), n=3),
                    surface_problem("SE3", (9, 7), (False, False), gravity=True),
                    surface_problem("SE2", (6, 6), (True, True))):
        ops = Collocation(problem).compiled_operators()
        assert ops.ok, ops.reason

    class Undeclared(Surface):
        def potential(self, X):  # an overridden energy is not known to be described by the kernels
            return super().potential(X)

    base = surface_problem("SE3", (6, 5), (True, True))
    ops = Collocation(Problem(Undeclared("SE3"), base.grid, base.initial)).compiled_operators()
    assert not ops.ok and "point kernels" in ops.reason


# ---------------------------------------------------------------------------- simulate
def test_simulate_uses_the_generated_loop_with_fd4(generated_runs):
    problem = rod_problem(n=14)
    kw = dict(dt=1e-3, t_end=0.05, save_every=7, scheme="collocation", scheme_options={"derivative": "fd4"},
              progress=False)
    fast = simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "position", "frame", "kinetic_energy", "potential_energy", "dissipated_energy",
                 "external_work"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)


def test_simulate_sigma_model_d2_runs_compiled(generated_runs):
    """``cartan.simulate`` on a d = 2 sigma model (the lump) takes the generated loop and agrees
    with ``compiled=False``."""
    medium = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((16, 16), 1.0, periodic=True)
    problem = Problem(medium, grid, medium.initial_state(grid, "lump", charge=1, size=0.15))
    kw = dict(dt=4e-3, t_end=0.04, save_every=5, scheme="collocation", progress=False)
    fast = simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "kinetic_energy", "potential_energy"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)


# ---------------------------------------------------------------------------- CFL estimate
#: the forces carry round-off of about 1e-16 of their size, which the central difference
#: divides by 2ε = 2e-7: products agree to ~1e-9 of their size; margin 10×
PRODUCT_TOL = 1e-8
#: the power iteration stops when two Rayleigh quotients agree to 1e-3; with products equal to
#: 1e-8 it takes the same path and the estimates agree to about that
DT_TOL = 1e-7


def _numpy_probe(scheme, state):
    scheme.compiled_diagnostics = False
    try:
        return scheme.stiffness_probe(state)
    finally:
        scheme.compiled_diagnostics = True


@pytest.fixture
def compiled_products(monkeypatch) -> list:
    """One entry per stiffness product taken on the compiled operators (on the tests' small
    problems too: ``Scheme.compiled_diagnostics_from`` set to 0)."""
    from cartan.compiled import diagnostics
    from cartan.schemes.base import Scheme

    monkeypatch.setattr(Scheme, "compiled_diagnostics_from", 0)
    calls = []
    real = diagnostics.compiled_stiffness_probe

    def counted(*args, **kwargs):
        probe = real(*args, **kwargs)
        if probe is None:
            return None
        return lambda v: calls.append(1) or probe(v)

    monkeypatch.setattr(diagnostics, "compiled_stiffness_probe", counted)
    return calls


@pytest.mark.parametrize("group", GROUPS)
@pytest.mark.parametrize(("kind", "derivative"), CASES, ids=CASE_IDS)
def test_cfl_products_and_estimates_match_numpy(kind, derivative, group, compiled_products):
    scheme = Collocation(toy_problem(group, kind), derivative=derivative)
    state = scheme.initial_state()
    before = state.copy()
    v = np.random.default_rng(2).standard_normal(state.S.shape)
    K = scheme.stiffness_probe(state)(v)
    assert compiled_products == [1]
    assert _rel(K, _numpy_probe(scheme, state)(v)) <= PRODUCT_TOL
    assert np.abs(K).max() > 0
    for integ in (RKMK4(), Overdamped()):
        fast = integ.dt_max(scheme, state)
        scheme.compiled_diagnostics = False
        ref = integ.dt_max(scheme, state)
        scheme.compiled_diagnostics = True
        assert abs(fast / ref - 1.0) <= DT_TOL
    assert len(compiled_products) > 10  # the power iterations ran on the compiled products
    # the linearisation point is left as it was
    assert np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


@pytest.mark.parametrize("track", [False, True])
def test_cfl_rod_with_and_without_frames(track, compiled_products):
    """The SE(3) rod with a dead end load and gravity (frames needed: stepped at every node),
    and the same rod clamped without loads (only the root frame stepped), ``fd4``."""
    rod = rod_problem(n=14)
    problem = rod if track else Problem(rod.medium, rod.grid, rod.initial, {"start": Clamped()})
    scheme = Collocation(problem, derivative="fd4")
    assert scheme.track == track
    state = scheme.initial_state()
    v = np.random.default_rng(3).standard_normal(state.S.shape)
    assert _rel(scheme.stiffness_probe(state)(v), _numpy_probe(scheme, state)(v)) <= PRODUCT_TOL
    assert compiled_products == [1]


@pytest.mark.slow  # the SE(3) rod's RKMK loop on collocation: ≈ 10 s to compile on a fresh cache
def test_simulate_uses_the_compiled_estimate(compiled_products):
    """``cartan.simulate`` chooses Δt from ``dt_max`` when none is given: the compiled products
    are taken there, and the run is the same as with the numpy estimate."""
    kw = dict(t_end=2e-3, save_every=10, scheme="collocation", scheme_options={"derivative": "fd4"},
              integrator="rkmk4", progress=False)
    fast = cartan.simulate(rod_problem(), **kw)
    assert compiled_products
    ref = cartan.simulate(rod_problem(), **kw, compiled=False)
    assert fast.step.values[-1] == ref.step.values[-1]
    assert _rel(fast["X"].values, ref["X"].values) <= 1e-10


class _Undeclared(QuadraticMedium):
    """A quadratic energy with an overridden ``potential``: no point kernels, no operator set."""

    def potential(self, X):
        return super().potential(X)


def test_cfl_falls_back_without_operators():
    from cartan.compiled.diagnostics import compiled_stiffness_probe

    base = toy_problem("SO2", "free")
    unplanned = Collocation(Problem(_Undeclared("SO2", rest=[0.5]), base.grid, base.initial))
    assert not unplanned.compiled_operators().ok
    assert compiled_stiffness_probe(unplanned, unplanned.initial_state(), 1e-7) is None
    planned = Collocation(base)
    with cartan.use_backend("numpy"):
        assert compiled_stiffness_probe(planned, planned.initial_state(), 1e-7) is None
    state = planned.initial_state()
    state.arrays["extra"] = state.arrays["X"].copy()  # another state layout
    assert compiled_stiffness_probe(planned, state, 1e-7) is None
    # the numpy probe still answers for both
    for scheme in (unplanned, planned):
        assert np.isfinite(LieVerlet().dt_max(scheme, scheme.initial_state()))
