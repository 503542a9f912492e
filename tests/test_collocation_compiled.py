"""Compiled collocation loops (``Collocation.compiled_advance``) against the Python reference path.

The reference is ``Integrator.step`` with the collocation scheme's numpy methods.  The compiled
loops must agree with it to 1e-12 (relative to each array's magnitude; the differences are
round-off: scalar formulas instead of 6 × 6 matrices, Taylor series selected per loop, a circulant
sum instead of the FFT for ``fourier``) on every state array and energy accumulator, for
every integrator × derivative × boundary × group, count steps and force evaluations
identically, hand their caches over to the Python loop, decline (touching nothing) what they
do not support, and load their machine code from numba's cache in a new process.
"""

from __future__ import annotations

import functools
import pathlib
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import toys
from toys import QuadraticMedium

import cartan
from cartan.api import InstabilityError, StabilityWarning, simulate
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from cartan.problem import Clamped, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes import _collocation_compiled as cc
from cartan.schemes.collocation import Collocation

ROOT = pathlib.Path(__file__).resolve().parents[1]
TOL = 1e-12

#: (integrator factory, Δt, steps): Δt inside each method's stable range for the test rods
#: (forward-euler is unstable at every Δt: a few small steps only)
INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 30),
    "lie-euler": (LieEuler, 2e-4, 30),
    "forward-euler": (ForwardEuler, 1e-5, 8),
    "rkmk4": (RKMK4, 1e-3, 12),
    "overdamped-1": (lambda: Overdamped(order=1), 2e-6, 30),
    "overdamped-2": (lambda: Overdamped(order=2), 2e-6, 15),
}
#: closed generators: exp(2π ξ) = I, so Φ(u) = exp(u ξ) is a closed rod of length 2π
RING = {"SO2": [1.0], "SE2": [1.0, 0.0, 1.0], "SO3": [0.0, 0.0, 1.0], "SE3": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0]}
#: (boundary kind, derivative): rings with every operator, open rods with fd2 and fd4
CASES = [("ring", "fd2"), ("ring", "fd4"), ("ring", "fourier"), ("clamped", "fd2"), ("clamped", "fd4"),
         ("free", "fd2"), ("free", "fd4")]


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


def rod_problem(planar: bool, n: int = 10) -> Problem:
    """A Cosserat rod (SE(3) or SE(2)) bent into an arc, clamped with a dead end load, under
    gravity (a constant-field potential) and damping."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                        rotational_inertia=[0.02, 0.01, 0.01])
    rod = rod.planar() if planar else rod
    r = rod.group.dim
    grid = Grid(n, length=1.0)
    init = rod.initial_state(grid, "arc", curvature=2.0, velocity=np.linspace(0.1, 0.3, r))
    loads = [Damping(np.linspace(0.1, 0.2, r)), rod.make_load("gravity", g=[0.0, -9.81, 0.0][: 2 if planar else 3])]
    return Problem(rod, grid, init, {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r))}, loads)


def assert_close_states(a, b, tol=TOL):
    toys.assert_close_states(a, b, tol)


run_both = functools.partial(toys.run_both, Collocation)
_rel = toys.rel_error


# ---------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("group", ["SO2", "SE2", "SO3", "SE3"])
@pytest.mark.parametrize(("kind", "derivative"), CASES, ids=[f"{k}-{d}" for k, d in CASES])
@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_compiled_agrees_with_python(name, kind, derivative, group):
    make, dt, nsteps = INTEGRATORS[name]
    scheme, (ref, ri), (fast, fi) = run_both(toy_problem(group, kind), make, dt, nsteps, derivative=derivative)
    assert set(fast.arrays) == {"X", "Phi" if kind == "clamped" else "Phi_root"}
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    assert fi.wall_time > 0
    # the run moved the configuration (the comparison is not between two copies of the start)
    start = scheme.initial_state()
    assert max(_rel(ref.arrays[k], start.arrays[k]) for k in start.arrays) > 1e-9


@pytest.mark.parametrize("planar", [False, True], ids=["SE3", "SE2"])
@pytest.mark.parametrize("derivative", ["fd2", "fd4"])
@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_rods_under_gravity(name, derivative, planar):
    make, dt, nsteps = INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(rod_problem(planar), make, dt, nsteps, derivative=derivative)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@pytest.mark.parametrize("name", ["lie-verlet", "lie-euler", "overdamped-1", "overdamped-2"])
def test_blocks_and_caches_match_the_step_loop(name):
    """Split into blocks, the compiled path counts like the Python path (first-same-as-last
    force, cached overdamped velocity) and hands its caches over to a following Python step."""
    make, dt, _ = INTEGRATORS[name]
    scheme, (ref, ri), (fast, fi) = run_both(rod_problem(False), make, dt, 13, blocks=(1, 1, 2, 4, 5))
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    # each compiled step depends on the state only: one call gives the same bits as the blocks
    _, _, (whole, _) = run_both(rod_problem(False), make, dt, 13)
    assert np.array_equal(whole.S, fast.S)
    assert all(np.array_equal(whole.arrays[k], fast.arrays[k]) for k in fast.arrays)
    ri.step(scheme, ref, dt)
    fi.step(scheme, fast, dt)
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


def test_velocity_free_lie_verlet_uses_one_force_per_step():
    G = cartan.group("SE3")
    grid = Grid(12, 2 * np.pi, periodic=True)
    u = grid.coordinates(0)
    problem = Problem(QuadraticMedium("SE3"), grid,
                      InitialState(Phi=G.exp(u[:, None] * RING["SE3"]), N=_velocity(u, 2 * np.pi, 6, 0.2)))
    _, (ref, ri), (fast, fi) = run_both(problem, LieVerlet, 1e-3, 50, blocks=(10, 40))
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce == 51


@pytest.mark.parametrize("name", ["lie-verlet", "lie-euler", "overdamped-1", "overdamped-2", "rkmk4"])
def test_fast_spin_uses_the_closed_forms(name):
    """Turns of up to 0.3 rad per step: beyond the series of the vectorised SE(3) pass
    (θ < 0.1), those nodes are recomputed with the closed forms (for the RKMK stages also the
    slopes dexp⁻¹_{−σ}N with stage increments σ beyond 0.1 rad)."""
    make, dt, _ = INTEGRATORS[name]
    base = toy_problem("SE3", "clamped", n=12)  # N = 0 at the clamped node: nodes of both kinds
    if name.startswith("overdamped"):
        # the drift velocity is Γ⁻¹W: a uniform body moment turns the nodes by 0.3 rad per step,
        # at half the stable step of the gradient flow (so that round-off is not amplified)
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
    assert theta.max() > 0.25 and theta.min() < 0.1  # nodes of both kinds
    assert_close_states(fast, ref)


def _rkmk_arguments(scheme, name: str, dt: float, nsteps: int) -> tuple:
    """The arguments ``advance`` hands to the RKMK loops (``rkmk4`` or ``overdamped-2``) for the
    initial state of ``scheme``: fresh copies of the state arrays on every call."""
    from cartan.integrators.explicit import _TABLEAUX

    P, Dc = cc.build_plan(scheme)
    state = scheme.initial_state()
    n, r = state.S.shape
    S = state.S.copy()
    X = state.arrays["X"].reshape(n, r).copy()
    Phi = (state.arrays["Phi"] if scheme.track else state.arrays["Phi_root"][None]).copy()
    dynamics = name == "rkmk4"
    gam = np.ones(r) if dynamics else np.asarray(scheme.drag(), dtype=float)
    N = np.zeros((n, r))
    if not dynamics:
        cc.overdamped_velocity(P, Dc, X, Phi, N, gam)
    A, b, _ = _TABLEAUX[4 if dynamics else 2]
    inv = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    check = 1 if dynamics else 2  # CHECK_MOMENTUM, CHECK_CONFIGURATION
    return (P, Dc, S, X, Phi, N, gam, dynamics, np.ascontiguousarray(A), np.ascontiguousarray(b), 0.0, dt, nsteps,
            0.0, 0.0, check, np.inf, inv)


@pytest.mark.parametrize(("kind", "derivative"), [*CASES, ("rod", "fd4")], ids=[f"{k}-{d}" for k, d in CASES] + ["rod"])
@pytest.mark.parametrize("name", ["rkmk4", "overdamped-2"])
def test_vectorised_rkmk_agrees_with_the_scalar_loop(name, kind, derivative):
    """The structure-of-arrays SE(3) RKMK loop against the scalar one on the same data: state
    arrays (and the returned velocity) to 1e-12, the same steps, time and energy books; and
    ``advance`` routes SE(3) to it (the Python reference is compared above)."""
    problem = rod_problem(False) if kind == "rod" else toy_problem("SE3", kind)
    scheme = Collocation(problem, derivative=derivative)
    _, dt, nsteps = INTEGRATORS[name]
    scalar = _rkmk_arguments(scheme, name, dt, nsteps)
    vector = _rkmk_arguments(scheme, name, dt, nsteps)
    done_s, t_s, diss_s, ext_s = cc.rkmk_loop(*scalar)
    done_v, t_v, diss_v, ext_v = cc.rkmk_se3_loop(*vector)
    assert (done_v, t_v) == (done_s, t_s) and done_v == nsteps  # t: the same sum of Δt
    for a, b in zip(vector[2:6], scalar[2:6], strict=True):  # S, X, Phi, N
        assert _rel(a, b) <= TOL
    assert _rel(diss_v, diss_s) <= TOL and _rel(ext_v, ext_s) <= TOL
    assert _rel(vector[3], _rkmk_arguments(scheme, name, dt, nsteps)[3]) > 1e-9  # the strains moved


def test_advance_routes_se3_rkmk_to_the_vectorised_loop(monkeypatch):
    calls = []
    real = cc.rkmk_se3_loop
    monkeypatch.setattr(cc, "rkmk_se3_loop", lambda *a: calls.append(a[7]) or real(*a))
    for make in (RKMK4, lambda: Overdamped(order=2)):
        _, (ref, ri), (fast, fi) = run_both(rod_problem(False), make, 1e-5, 5, blocks=(2, 3))
        assert_close_states(fast, ref)
        assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    assert calls == [True, True, False, False]
    run_both(toy_problem("SO3", "clamped"), RKMK4, 1e-3, 2)  # other groups: the scalar loop
    assert len(calls) == 4


@pytest.mark.parametrize("name", ["lie-verlet", "lie-euler", "overdamped-1", "overdamped-2", "rkmk4"])
def test_se3_with_a_gauge_component(name):
    """A zero inertia: the lie-verlet pieces have no reduced form (general vectorised pass),
    and the gauge component of N and S stays zero."""
    make, dt, nsteps = INTEGRATORS[name]
    base = toy_problem("SE3", "clamped")
    medium = QuadraticMedium("SE3", mass=[1.0, 1.0, 0.0, 0.05, 0.04, 0.03])
    problem = Problem(medium, base.grid, base.initial, base.boundaries, base.loads)
    scheme, (ref, ri), (fast, fi) = run_both(problem, make, dt, nsteps)
    if name == "lie-verlet":
        assert any(np.count_nonzero(np.diag(P)) == 2 for P, _ in fi._sequence(scheme))
    assert_close_states(fast, ref)
    assert np.all(fast.S[:, 2] == 0.0)
    assert fi.nforce == ri.nforce


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


# ---------------------------------------------------------------------------- single operations
@pytest.mark.parametrize(("kind", "derivative"), CASES, ids=[f"{k}-{d}" for k, d in CASES])
def test_derivative_matches_the_operator(kind, derivative):
    scheme = Collocation(toy_problem("SE3", kind, n=12), derivative=derivative)
    _, Dc = cc.build_plan(scheme)
    A = np.random.default_rng(1).standard_normal((12, 6))
    out = np.empty_like(A)
    cc.derivative_once(Dc, A, out)
    assert _rel(out, scheme.D[0](A, axis=0)) <= 1e-14


@pytest.mark.parametrize("group", ["SO3", "SE3"])
@pytest.mark.parametrize("kind", ["clamped", "ring"])
def test_force_and_drift_match_the_scheme(kind, group):
    """One force evaluation and one drift (exact and naive) at a perturbed state."""
    problem = toy_problem(group, kind, n=12)
    scheme = Collocation(problem, derivative="fd4", track_frames=True)
    state = scheme.initial_state()
    rng = np.random.default_rng(0)
    r = scheme.group.dim
    state.arrays["X"] = state.arrays["X"] + 0.05 * rng.standard_normal(state.arrays["X"].shape)
    N = rng.standard_normal((12, r))
    P, Dc = cc.build_plan(scheme)
    X = state.arrays["X"].reshape(12, r).copy()
    W = np.empty((12, r))
    cc.force_once(P, Dc, X, state.arrays["Phi"], N, W)
    assert _rel(W, scheme.force(state, N, 0.0)) <= 1e-13
    for exact in (True, False):
        moved = state.copy()
        scheme.drift(moved, 0.05, N, exact=exact)
        X, Phi = state.arrays["X"].reshape(12, r).copy(), state.arrays["Phi"].copy()
        cc.drift_once(P, Dc, X, Phi, N, 0.05, exact)
        assert _rel(X, moved.arrays["X"].reshape(12, r)) <= 1e-13
        assert _rel(Phi, moved.arrays["Phi"]) <= 1e-13


def test_kinetic_limit_stops_after_the_failing_step():
    for make in (LieVerlet, LieEuler, RKMK4):  # the vectorised SE(3) loops
        scheme = Collocation(rod_problem(False))
        state = scheme.initial_state()
        state.scalars["nstep"] = 0
        integ = make()
        assert scheme.compiled_advance(integ, state, 1e-4, 50, kinetic_limit=1e-12)
        assert state.scalars["nstep"] == 1 and integ.nstep == 1


# ---------------------------------------------------------------------------- fallback
class _NotQuadratic(QuadraticMedium):
    """A quadratic energy that does not declare itself (no compiled loop)."""

    def quadratic_energy(self):
        return None


def _declines(problem, integ, **scheme_options):
    scheme = Collocation(problem, **scheme_options)
    state = scheme.initial_state()
    before = state.copy()
    assert not scheme.compiled_advance(integ, state, 1e-4, 3)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
    assert integ.nstep == 0


def test_unsupported_combinations_decline():
    base = toy_problem("SE3", "free")
    _declines(Problem(_NotQuadratic("SE3"), base.grid, base.initial), LieVerlet())
    _declines(Problem(base.medium, base.grid, base.initial, loads=[UniformForce(np.ones(6), frame="spatial")]),
              LieVerlet())
    rod = rod_problem(False)
    _declines(rod, LieVerlet(), track_frames=False)  # gravity needs the frames
    _declines(base, Kinematic(velocity=lambda t, u, X: np.zeros((10, 6))))
    _declines(Problem(base.medium, base.grid, base.initial), Overdamped())  # no damping: Python raises
    so4 = cartan.group("SO", n=4)
    grid = Grid(10, 1.0)
    _declines(Problem(QuadraticMedium(so4), grid, InitialState(Phi=so4.exp(np.outer(grid.coordinates(0),
                                                                                    np.linspace(0.2, 0.7, 6))))),
              LieVerlet())
    big = toy_problem("SE3", "ring", n=cc.FOURIER_MAX_NODES + 2)
    _declines(big, LieVerlet(), derivative="fourier")
    assert Collocation(big, derivative="fd2").compiled_advance(LieVerlet(), Collocation(big).initial_state(), 1e-4, 1)
    with cartan.use_backend("numpy"):
        _declines(base, LieVerlet())


def test_malformed_quadratic_energy_is_an_error():
    class Wrong(QuadraticMedium):
        def quadratic_energy(self):
            return self.X0, 2.0 * np.diag(self.C)

    base = toy_problem("SE3", "free")
    scheme = Collocation(Problem(Wrong("SE3"), base.grid, base.initial))
    with pytest.raises(ValueError, match="disagrees with stress"):
        scheme.compiled_advance(LieVerlet(), scheme.initial_state(), 1e-3, 1)


# ---------------------------------------------------------------------------- simulate
def test_simulate_uses_the_compiled_loop(monkeypatch):
    problem = rod_problem(False, n=14)
    kw = dict(dt=1e-3, t_end=0.05, save_every=7, scheme="collocation", scheme_options={"derivative": "fd4"})
    calls = []
    real = cc.advance
    monkeypatch.setattr(cc, "advance", lambda *a: calls.append(1) or real(*a))
    fast = simulate(problem, **kw)
    assert calls
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "position", "frame", "kinetic_energy", "potential_energy", "dissipated_energy",
                 "external_work"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)


def test_blow_up_is_named_at_the_same_step(tmp_path):
    errors = []
    for compiled in (True, False):
        with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
            simulate(rod_problem(False), dt=0.02, t_end=50.0, save_every=10, compiled=compiled, scheme="collocation",
                     output=tmp_path / f"blow-{compiled}.nc")
        errors.append(info.value)
    assert errors[0].step == errors[1].step
    masked = [re.sub(r"\d+(\.\d*)?(e[-+]\d+)?", "#", str(e).split(";")[0]) for e in errors]
    assert masked[0] == masked[1]


# ---------------------------------------------------------------------------- numba cache
CACHE_SCRIPT = textwrap.dedent(
    """
    import numpy as np
    import cartan
    from cartan.grid import Grid
    from cartan.problem import Problem, Clamped, Damping
    from cartan.schemes import _collocation_compiled as cc

    rod = cartan.medium("cosserat-rod", E=1e6, poisson=0.5, radius=0.02, density=1000.0)
    grid = Grid(12, length=1.0)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0), {"start": Clamped()},
                      [Damping(0.1), rod.make_load("gravity", g=[0.0, 0.0, -9.81])])
    for integrator in ("lie-euler", "lie-verlet"):
        cartan.simulate(problem, dt=1e-5, t_end=2e-4, save_every=5, scheme="collocation", integrator=integrator)
    kernels = [v for v in vars(cc).values() if hasattr(v, "stats") and hasattr(v, "signatures")]
    hits = sum(sum(d.stats.cache_hits.values()) for d in kernels)
    misses = sum(sum(d.stats.cache_misses.values()) for d in kernels)
    loops = sum(sum(f.stats.cache_hits.values()) for f in (cc.lie_euler_se3_loop, cc.lie_verlet_se3_loop))
    print(loops, hits, misses)
    """
)


def test_second_process_loads_the_compiled_loops_from_the_cache():
    runs = [
        subprocess.run([sys.executable, "-c", CACHE_SCRIPT], capture_output=True, text=True, cwd=ROOT, timeout=900)
        for _ in range(2)
    ]
    for run in runs:
        assert run.returncode == 0, run.stderr
    loops, hits, misses = map(int, runs[1].stdout.split()[-3:])
    assert loops == 2 and hits >= 2 and misses == 0, runs[1].stdout
