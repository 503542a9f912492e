"""Compiled collocation loops on d = 2 and 3 grids (``Collocation.compiled_advance``) against the
Python reference path.

The reference is ``Integrator.step`` with the collocation scheme's numpy methods.  For every
integrator the compiled steps must agree with it to 1e-12, relative to each array's magnitude,
on every state array and energy accumulator (the differences are round-off: SE(3) scalar
formulas instead of 6 × 6 matrices, per-node sums instead of ``einsum``/``np.sum``, a circulant
sum instead of the FFT for ``fourier``), on the sigma model (SO(3) with a gauge component) and
toy quadratic surfaces on SO(2), SE(2), SE(3), with periodic and open axes, clamped faces,
follower and dead face loads, damping, body forces and a constant field; count steps and force
evaluations identically; hand their caches over to the Python loop; and decline what they do
not support.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import toys
from toys import QuadraticMedium

import cartan
from cartan.api import simulate
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from cartan.problem import Clamped, ConstantFieldPotential, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes import _collocation_compiled as cc
from cartan.schemes import _collocation_compiled_nd as ccn
from cartan.schemes.collocation import Collocation

#: the agreement required of the compiled loops (round-off; measured: ≤ 1e-15 on these runs)
TOL = 1e-12

#: (integrator factory, Δt, steps).  Δt inside each method's stable range on the grids below
#: (h ≥ 0.1, wave speeds ≤ 7, drag ≥ 0.5: the overdamped flows are stable below Δt ≈ 1e-4 with
#: fd4 and fourier); forward-euler is unstable at every Δt: a few small steps only
INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 16),
    "lie-euler": (LieEuler, 2e-4, 16),
    "forward-euler": (ForwardEuler, 1e-5, 5),
    "rkmk4": (RKMK4, 1e-3, 6),
    "overdamped-1": (lambda: Overdamped(order=1), 1e-5, 16),
    "overdamped-2": (lambda: Overdamped(order=2), 1e-5, 8),
}

run_both = functools.partial(toys.run_both, Collocation)
_rel = toys.rel_error


def assert_close_states(a, b, tol=TOL):
    toys.assert_close_states(a, b, tol)


# ---------------------------------------------------------------------------- problems
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


def sigma_problem(shape: tuple, periodic, boundaries=None) -> Problem:
    """The sigma model on S² (SO(3), a gauge component without inertia) with its harmonic-map
    drag: a smooth random field with a gauge twist and a velocity."""
    medium = cartan.medium("sigma-model", n=2, d=len(shape))
    grid = Grid(shape, 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    return Problem(medium, grid, init, boundaries or {}, [medium.make_load("drag", gamma=0.7)])


#: name → (problem, derivative): every group, periodic and open axes, clamped faces, follower
#: and dead face loads (a dead load and the constant field need every frame), and d = 3
CASES = {
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


# ---------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_compiled_agrees_with_python(name, case):
    make, dt, nsteps = INTEGRATORS[name]
    build, derivative = CASES[case]
    problem = build()
    scheme, (ref, ri), (fast, fi) = run_both(problem, make, dt, nsteps, derivative=derivative)
    assert scheme.grid.d >= 2 and cc.build_plan(scheme) is not None
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    # the run moved the configuration and booked energy (not a comparison of two copies of the start)
    start = scheme.initial_state()
    assert _rel(ref.arrays["X"], start.arrays["X"]) > 1e-9
    assert ref.scalars["dissipated_energy"] != 0.0
    if problem.boundaries or any(isinstance(ld, UniformForce) for ld in problem.loads):
        assert ref.scalars["external_work"] != 0.0


@pytest.mark.parametrize("name", ["lie-verlet", "overdamped-1", "overdamped-2"])
def test_blocks_and_caches_match_the_step_loop(name):
    """Split into blocks, the compiled path counts like the Python path (first-same-as-last
    force, cached overdamped velocity, both in the state's shape) and hands its caches over to
    a following Python step; one call gives the same bits as the blocks."""
    make, dt, _ = INTEGRATORS[name]
    build, derivative = CASES["sigma-cylinder-fd4"]
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
@pytest.mark.parametrize(("shape", "periodic", "derivative"), [
    ((9, 7), (False, True), "fd2"), ((9, 8), (True, False), "fd4"), ((6, 5), (True, True), "fourier"),
    ((8, 5, 8), (False, True, False), "fd4")])
def test_axis_derivatives_match_the_operators(shape, periodic, derivative):
    scheme = Collocation(sigma_problem(shape, periodic), derivative=derivative)
    _, Dc = cc.build_plan(scheme)
    A = np.random.default_rng(1).standard_normal((*shape, 3))
    out = np.empty((A.size // 3, 3))
    for axis in range(len(shape)):
        ccn.axis_derivative_once(Dc, axis, A.reshape(-1, 3), out)
        assert _rel(out.reshape(A.shape), scheme.D[axis](A, axis=axis)) <= 1e-14


@pytest.mark.parametrize("case", ["se2-open-dead-load", "se3-solid-d3", "sigma-cylinder-fd4"])
def test_force_and_drift_match_the_scheme(case):
    """One force evaluation and one drift (exact and naive) at a perturbed state, with frames."""
    build, derivative = CASES[case]
    scheme = Collocation(build(), derivative=derivative, track_frames=True)
    state = scheme.initial_state()
    rng = np.random.default_rng(0)
    n, d, r = scheme.grid.size, scheme.grid.d, scheme.group.dim
    state.arrays["X"] = state.arrays["X"] + 0.05 * rng.standard_normal(state.arrays["X"].shape)
    N = rng.standard_normal(state.S.shape)
    P, Dc = cc.build_plan(scheme)
    Phi0 = state.arrays["Phi"].reshape(n, *state.arrays["Phi"].shape[-2:])
    W = np.empty((n, r))
    ccn.force_once(P, Dc, state.arrays["X"].reshape(n, d * r).copy(), Phi0, N.reshape(n, r), W)
    assert _rel(W.reshape(N.shape), scheme.force(state, N, 0.0)) <= 1e-13
    for exact in (True, False):
        moved = state.copy()
        scheme.drift(moved, 0.05, N, exact=exact)
        X, Phi = state.arrays["X"].reshape(n, d * r).copy(), Phi0.copy()
        ccn.drift_once(P, Dc, X, Phi, N.reshape(n, r), 0.05, exact)
        assert _rel(X.reshape(moved.arrays["X"].shape), moved.arrays["X"]) <= 1e-13
        assert _rel(Phi.reshape(moved.arrays["Phi"].shape), moved.arrays["Phi"]) <= 1e-13


# ---------------------------------------------------------------------------- what qualifies
def test_sigma_model_and_quadratic_surfaces_qualify():
    """The quadratic media that run collocation on d ≥ 2 qualify: the sigma model on S² (d = 2, 3;
    SO(3)) and quadratic SE(3)/SE(2) surfaces, open or periodic — with one numba type for the
    plans of d = 2 and 3 (one compiled loop serves both).  Not: the sigma model on S³ (SO(4)), a
    surface whose energy methods are overridden (not known to be quadratic)."""
    types = set()
    for problem in (sigma_problem((16, 16), (True, True)), sigma_problem((6, 5, 4), (True, False, True)),
                    surface_problem("SE3", (9, 7), (False, False), gravity=True),
                    surface_problem("SE2", (6, 6), (True, True))):
        plan = cc.build_plan(Collocation(problem))
        assert plan is not None
        types.add(numba_type(plan))
    assert len(types) == 1
    s3 = cartan.medium("sigma-model", n=3, d=2)
    grid = Grid((6, 6), 1.0, periodic=True)
    assert cc.build_plan(Collocation(Problem(s3, grid, s3.initial_state(grid, "random-smooth")))) is None

    class Undeclared(Surface):
        def potential(self, X):  # an overridden energy is not known to be quadratic
            return super().potential(X)

    base = surface_problem("SE3", (6, 5), (True, True))
    undeclared = Undeclared("SE3")
    assert cc.build_plan(Collocation(Problem(undeclared, base.grid, base.initial))) is None


def numba_type(plan):
    from numba import typeof

    return typeof(plan)


def test_simulate_sigma_model_d2_runs_compiled(monkeypatch):
    """``cartan.simulate`` on a d = 2 sigma model (the lump) takes the compiled path and agrees
    with ``compiled=False``."""
    medium = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((16, 16), 1.0, periodic=True)
    problem = Problem(medium, grid, medium.initial_state(grid, "lump", charge=1, size=0.15))
    calls = []
    real = cc.advance_nd
    monkeypatch.setattr(cc, "advance_nd", lambda *a: calls.append(1) or real(*a))
    kw = dict(dt=4e-3, t_end=0.04, save_every=5, scheme="collocation", progress=False)
    fast = simulate(problem, **kw)
    assert calls
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "kinetic_energy", "potential_energy"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)


# ---------------------------------------------------------------------------- fallback
def _declines(problem, integ, **scheme_options):
    scheme = Collocation(problem, **scheme_options)
    state = scheme.initial_state()
    before = state.copy()
    assert not scheme.compiled_advance(integ, state, 1e-4, 3)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
    assert integ.nstep == 0


def test_unsupported_combinations_decline():
    base = sigma_problem((6, 5), (True, True))
    _declines(base, Kinematic(velocity=lambda t, u, X: np.zeros((6, 5, 3))))
    spatial = Problem(base.medium, base.grid, base.initial, loads=[UniformForce(np.ones(3), frame="spatial")])
    _declines(spatial, LieVerlet())
    _declines(Problem(base.medium, base.grid, base.initial), Overdamped())  # no drag: Python raises
    dead = surface_problem("SE3", (6, 5), (False, True), {"u-end": Free(load=np.ones(6), follower=False)})
    _declines(dead, LieVerlet(), track_frames=False)  # the dead load needs the frames
    wide = sigma_problem((cc.FOURIER_MAX_NODES + 2, 3), (True, True))
    _declines(wide, LieVerlet(), derivative="fourier")
    with cartan.use_backend("numpy"):
        _declines(base, LieVerlet())


def test_kinetic_limit_stops_after_the_failing_step():
    for make in (LieVerlet, LieEuler, RKMK4):
        scheme = Collocation(surface_problem("SE3", (6, 5), (True, False)))
        state = scheme.initial_state()
        state.scalars["nstep"] = 0
        integ = make()
        assert scheme.compiled_advance(integ, state, 1e-4, 20, kinetic_limit=1e-12)
        assert state.scalars["nstep"] == 1 and integ.nstep == 1
