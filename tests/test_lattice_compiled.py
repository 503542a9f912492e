"""Compiled lattice paths against the Python reference path.

The compiled path of a problem is the one :func:`cartan.simulate` takes
(``toys.advance_compiled``): the hand-written structure-of-arrays loops of SE(3) rods
(``Lattice.compiled_advance``: ``lie-verlet``, ``overdamped`` of order 1), else the generated
loops over the lattice's operators (``Integrator.run_compiled_loop``: the other groups, d = 2
and 3, the other integrators).  The reference is ``Integrator.step`` with the lattice
scheme's numpy methods; the compiled paths must agree with it to 1e-12 (relative to each
array's magnitude) on every state array and energy accumulator — rods (d = 1) and the sigma
model and toy media on d = 2 and 3 grids —, count steps and force evaluations identically,
decline (and leave the state untouched) whatever they do not support, keep restarts bit for
bit, and load their machine code from numba's cache in a new process.
"""

from __future__ import annotations

import contextlib
import functools
import json
import pathlib
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import toys
from toys import QuadraticMedium, arc_problem, moving_rod, params_of, rod_problem

import cartan
from cartan import _threads
from cartan.api import InstabilityError, StabilityWarning, simulate
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from cartan.medium import Medium
from cartan.problem import Clamped, ConstantFieldPotential, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes import _lattice_compiled as lc
from cartan.schemes.lattice import Lattice

ROOT = pathlib.Path(__file__).resolve().parents[1]
TOL = 1e-12

#: first-order loops beyond the fast suite's (each loop compiles for a minute under load)
SLOW_SE3 = {"forward-euler", "lie-euler", "overdamped-2"}
#: (integrator factory, Δt, steps): Δt within each method's stable range for the test rods
#: (forward-euler is unstable at every Δt, so it runs a few small steps only)
INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 120),
    "lie-euler": (LieEuler, 1e-4, 60),
    "forward-euler": (ForwardEuler, 1e-5, 10),
    "rkmk4": (RKMK4, 1e-3, 30),
    "overdamped-1": (lambda: Overdamped(order=1), 2e-6, 40),
    "overdamped-2": (lambda: Overdamped(order=2), 2e-6, 30),
}


#: tests whose loops ``make test`` does not compile (tests/conftest.py): the d ≥ 2 loops, the
#: vectorised overdamped SE(3) loop and the force kernels alone
SLOW_TESTS = {"test_sigma_model_d2_agrees_with_python", "test_d2_clamped_and_loaded_faces",
              "test_every_group_on_a_d2_grid", "test_force_matches_lattice_force",
              "test_force_matches_lattice_force_d2", "test_simulate_sigma_model_d2_compiled_agrees_with_reference",
              "test_overdamped_se3_runs_the_vectorised_loop",
              "test_overdamped_se3_stops_after_the_first_non_finite_step", "test_overdamped_se3_with_root_frame_only"}


def slow_when(item) -> bool:
    """``make test`` runs the lie-verlet loops of SE(3) and SE(2) rods (d = 1: the SE(3) loop of
    the demo and the generated loop the planar rods share); the other integrators' loops and the
    SO(2), SO(3) toys' generated loops (one module each, ≈ 30–60 s to compile) in ``make test-slow``."""
    params = params_of(item)
    name = params.get("name", "lie-verlet")
    return item.originalname in SLOW_TESTS or name != "lie-verlet" or params.get("group") in ("SO2", "SO3")


def assert_close_states(a, b, tol=TOL):
    toys.assert_close_states(a, b, tol)


run_both = functools.partial(toys.run_both, Lattice)
_rel = toys.rel_error


# ---------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("planar", [False, True], ids=["SE3", "SE2"])
@pytest.mark.parametrize("kind", ["dead", "follower", "ring"])
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_SE3 else n
                                  for n in sorted(INTEGRATORS)])
def test_compiled_agrees_with_python(name, kind, planar):
    make, dt, nsteps = INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(rod_problem(kind, planar), make, dt, nsteps)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    assert fi.wall_time > 0


@pytest.mark.parametrize("name", ["lie-verlet", "overdamped-1"])
def test_blocks_and_caches_match_the_step_loop(name):
    """Split into blocks, the compiled path counts like the Python path (first-same-as-last
    force, cached overdamped velocity) and hands its caches over to a following Python step."""
    make, dt, _ = INTEGRATORS[name]
    problem = rod_problem("dead")
    scheme, (ref, ri), (fast, fi) = run_both(problem, make, dt, 13, blocks=(1, 1, 2, 4, 5))
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    ri.step(scheme, ref, dt)
    fi.step(scheme, fast, dt)
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


def test_velocity_free_lie_verlet_uses_one_force_per_step():
    rod = moving_rod(False)
    grid = Grid(9)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0, velocity=[0, 0.1, 0, 0, 0, 0.3]))
    _, (ref, ri), (fast, fi) = run_both(problem, LieVerlet, 1e-3, 50, blocks=(10, 40))
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce == 51


def test_root_frame_only():
    """Follower loads need no frames: only the root frame is stepped, on both paths."""
    rod = moving_rod(False)
    grid = Grid(9)
    init = rod.initial_state(grid, "arc", curvature=1.5, velocity=[0.1, 0.2, 0, 0.3, 0, 0.1])
    problem = Problem(rod, grid, init, {"start": Clamped(), "end": Free(load=[0, 0, 1.0, 0, 0.2, 0], follower=True)})
    _, (ref, _), (fast, _) = run_both(problem, LieVerlet, 1e-3, 100, track_frames=False)
    assert set(fast.arrays) == {"G_u", "Phi_root"}
    assert_close_states(fast, ref)


#: the tests' toy medium declares its (diagonal) quadratic energy through the core base
_QuadraticData = QuadraticMedium


class _FullQuadratic(QuadraticMedium):
    """U = ½(X − X₀)ᵀC(X − X₀) with a full symmetric positive C (coupled strains)."""

    name = "toy-full-quadratic"

    def __init__(self, group="SE3"):
        r = cartan.group(group).dim
        B = np.random.default_rng(3).standard_normal((r, r))
        super().__init__(group, mass=np.linspace(1.0, 0.3, r))
        self.C = B @ B.T + r * np.eye(r)
        self._set_energy(self.X0, self.C)


@pytest.mark.parametrize("group", ["SO2", "SO3", "SE2", "SE3"])
@pytest.mark.parametrize("name", ["lie-verlet", "rkmk4", "lie-euler"])
def test_every_group_with_generic_kernels(group, name):
    make, dt, nsteps = INTEGRATORS[name]
    base = arc_problem(n=9, curvature=1.0, group=group, velocity=np.linspace(0.2, 0.5, cartan.group(group).dim))
    medium = _QuadraticData(group)
    problem = Problem(medium, base.grid, base.initial, {"start": Clamped()}, [Damping(0.1)])
    _, (ref, ri), (fast, fi) = run_both(problem, make, dt, nsteps)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


def test_se3_with_a_gauge_component():
    """A zero inertia splits the SE(3) free flow into pieces without closed form: the
    structure-of-arrays loop declines them, the generated loop runs them."""
    base = arc_problem(n=9, curvature=1.0, velocity=[0.1, 0.2, 0.0, 0.3, 0.1, 0.2])
    medium = _QuadraticData("SE3", mass=[1.0, 1.0, 0.0, 0.05, 0.04, 0.03])
    problem = Problem(medium, base.grid, base.initial, {"start": Clamped()}, [Damping(0.1)])
    _declines(problem, LieVerlet())
    scheme, (ref, ri), (fast, fi) = run_both(problem, LieVerlet, 1e-3, 60)
    assert any(np.count_nonzero(np.diag(P)) == 2 for P, _ in fi._sequence(scheme))
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


def test_fast_spin_uses_the_closed_forms():
    """Rotation angles per free-flow piece beyond the series' range (θ ≥ 0.1)."""
    rod = moving_rod(False)
    grid = Grid(9)
    init = rod.initial_state(grid, "arc", curvature=0.5, velocity=[0.0, 0.0, 0.0, 400.0, 30.0, 0.0])
    _, (ref, _), (fast, _) = run_both(Problem(rod, grid, init), LieVerlet, 1e-3, 40)
    assert_close_states(fast, ref)


# ---------------------------------------------------------------------------- vectorised overdamped loop
def _spy(monkeypatch, name: str) -> list:
    """Record the calls of the structure-of-arrays loop ``name`` (serial or threaded build)
    made by ``compiled_advance``: ``(threaded, blocks)``."""
    calls = []

    def wrap(loop, threaded):
        def spy(*args):
            calls.append((threaded, args[-1]))
            return loop(*args)
        return spy

    monkeypatch.setattr(lc.soa, name, wrap(getattr(lc.soa, name), False))
    monkeypatch.setitem(lc.soa.THREADED, name, wrap(lc.soa.THREADED[name], True))
    return calls


@pytest.mark.parametrize("n", [11, 2100], ids=["one-chunk", "three-chunks"])
@pytest.mark.parametrize("kind", ["dead", "follower", "ring"])
def test_overdamped_se3_runs_the_vectorised_loop(kind, n, monkeypatch):
    """``overdamped`` (order 1) on SE(3) rods — clamped with a dead or a follower end load, or a
    ring; damping and gravity — runs the structure-of-arrays loop, in blocks, and agrees with
    the Python path, counters included; Δt scales with h² (the stable range of the flow)."""
    calls = _spy(monkeypatch, "overdamped_se3_loop")
    make, dt, nsteps = INTEGRATORS["overdamped-1"]
    dt *= (10.0 / n) ** 2
    nsteps = nsteps if n < 100 else 6
    _, (ref, ri), (fast, fi) = run_both(rod_problem(kind, n=n), make, dt, nsteps, blocks=(1, nsteps - 1))
    assert calls == [(False, 1)] * 2
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    assert not np.any(fast.S)
    # the velocity handed over to a following step, N = Γ⁻¹W(N = 0) at the final state: W is a
    # difference quotient of the edge stresses over h, so its round-off grows like 1/h (from
    # 1e-13 on the 11-node rods)
    assert fi._cache[0][1:] == ri._cache[0][1:] and _rel(fi._cache[1], ri._cache[1]) <= TOL * max(1.0, n / 11)


def test_overdamped_se3_stops_after_the_first_non_finite_step(monkeypatch):
    """Far beyond its stable Δt the flow of the clamped rod overflows; the vectorised loop
    stops after the first step that leaves a non-finite edge or frame (the step at which
    overflow sets in is round-off dependent, so the loop is compared with itself)."""
    calls = _spy(monkeypatch, "overdamped_se3_loop")
    scheme = Lattice(rod_problem("dead", n=11))
    start = scheme.initial_state()
    start.scalars["nstep"] = 0
    dt, limit = 2e-3, 2000

    def run(nsteps):
        state = start.copy()
        with np.errstate(all="ignore"):
            assert scheme.compiled_advance(Overdamped(order=1), state, dt, nsteps)
        return state, all(np.all(np.isfinite(a)) for a in state.arrays.values())

    blown, finite = run(limit)
    k = blown.scalars["nstep"]
    assert 1 < k < limit and not finite
    before, finite = run(k - 1)
    assert before.scalars["nstep"] == k - 1 and finite
    assert len(calls) == 2


def test_overdamped_se3_with_root_frame_only(monkeypatch):
    """Without frames to step beyond the root (follower loads only), on the vectorised loop."""
    calls = _spy(monkeypatch, "overdamped_se3_loop")
    rod = moving_rod(False)
    grid = Grid(9)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.5),
                      {"start": Clamped(), "end": Free(load=[0, 0, 1.0, 0, 0.2, 0], follower=True)},
                      [Damping([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])])
    _, (ref, ri), (fast, fi) = run_both(problem, lambda: Overdamped(order=1), 2e-6, 30, track_frames=False)
    assert calls and set(fast.arrays) == {"G_u", "Phi_root"}
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


def test_vectorised_exp_matches_the_group_exp():
    """``D_i = exp(τN_i)`` of the vectorised loop against the group's exp: a chunk of nodes
    turning by less than 0.1 rad (the series) and one with larger angles (the closed forms);
    the frames, starting from the identity, become ``D``.  Round-off: ≤ 1e-13."""
    rng = np.random.default_rng(5)
    n = lc.soa.CHUNK + 300
    N = rng.standard_normal((n, 6))
    N[: lc.soa.CHUNK, 3:] *= 0.02
    tau = 0.7
    nv = np.ascontiguousarray(N.T)
    D = np.empty((12, n))
    phi = np.zeros((12, n))
    phi[[3, 7, 11]] = 1.0
    lc.soa._soa_exp_nodes(nv, tau, D, phi)
    E = cartan.group("SE3").exp(tau * N)
    expected = np.concatenate([E[:, 1:, 0].T, E[:, 1:, 1:].reshape(n, 9).T])
    assert np.max(np.abs(D - expected)) <= 1e-13
    assert np.array_equal(phi, D)


# ---------------------------------------------------------------------------- pipelined lie-verlet step
@pytest.mark.parametrize(("kind", "n"), [("dead", 2100), ("follower", 3073), ("ring", 2100), ("ring", 3072)],
                         ids=["dead-2100", "follower-3073", "ring-2100", "ring-3072"])
def test_lie_verlet_se3_pipelined_step_agrees(kind, n, monkeypatch):
    """The pipelined step of the vectorised SE(3) loop (drift chunk c, then the edges and the
    closing of chunk c − 1) on rods of several chunks — 3073 nodes have 3 chunks of edges and
    4 of nodes, the case where the last node chunk has no edge chunk of its own — agrees with
    the Python path; Δt scales with h (the explicit limit)."""
    calls = _spy(monkeypatch, "lie_verlet_se3_loop")
    _, (ref, ri), (fast, fi) = run_both(rod_problem(kind, n=n), LieVerlet, 1e-3 * 11.0 / n, 6, blocks=(2, 4))
    assert calls == [(False, 1)] * 2
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@pytest.mark.parametrize("kind", ["follower", "ring"])
def test_lie_verlet_se3_results_do_not_depend_on_the_blocks(kind, monkeypatch):
    """However the chunks are split into blocks (one per thread; here run by the serial build,
    block after block), the pipelined step gives the same state and accumulators bit for bit:
    every chunk does the same arithmetic and the partial sums are added in chunk order."""
    scheme = Lattice(rod_problem(kind, n=5 * lc.soa.CHUNK + 17))
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    monkeypatch.setitem(lc.soa.THREADED, "lie_verlet_se3_loop", lc.soa.lie_verlet_se3_loop)
    monkeypatch.setattr(lc, "numba_threads", lambda k: contextlib.nullcontext())
    states = []
    for blocks in (1, 2, 3, 6):
        monkeypatch.setattr(lc, "loop_threads", lambda nodes, k=blocks: k)
        state = start.copy()
        assert scheme.compiled_advance(LieVerlet(), state, 2e-6, 3)
        states.append(state)
    first = states[0]
    for other in states[1:]:
        assert all(np.array_equal(first.arrays[k], other.arrays[k]) for k in first.arrays)
        assert np.array_equal(first.S, other.S) and first.scalars == other.scalars


def _free_of_velocity(n: int) -> Problem:
    """A clamped rod bent into an arc under gravity, a body-frame force and a dead end load:
    no velocity-dependent force, so the serial loop steps it in blocks of steps."""
    rod = moving_rod(False)
    grid = Grid(n, length=1.0)
    init = rod.initial_state(grid, "arc", curvature=2.0, velocity=np.linspace(0.1, 0.3, 6))
    loads = [rod.make_load("gravity", g=[0.0, -9.81, 0.0]), UniformForce(np.linspace(-0.2, 0.3, 6))]
    return Problem(rod, grid, init, {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, 6), follower=False)},
                   loads)


def _serial_blocks(monkeypatch, blocks: int) -> None:
    """Make ``compiled_advance`` run the serial build of the vectorised loop with ``blocks``
    blocks of chunks, stepping in blocks of steps from two chunks per block."""
    monkeypatch.setitem(lc.soa.THREADED, "lie_verlet_se3_loop", lc.soa.lie_verlet_se3_loop)
    monkeypatch.setattr(lc.soa, "THREAD_BLOCK_CHUNKS", 2)
    monkeypatch.setattr(lc, "numba_threads", lambda k: contextlib.nullcontext())
    monkeypatch.setattr(lc, "loop_threads", lambda nodes: blocks)


def test_blocked_steps_agree_with_single_steps(monkeypatch):
    """Steps advanced together chunk by chunk (an open rod of 4 chunks, velocity-free loads:
    8 + 3 steps) in one block of chunks, or in two with the work around their boundary done
    afterwards, give the states of single pipelined steps (three blocks: fewer than two
    chunks each, so one step at a time) bit for bit, and the Python path's to round-off."""
    problem = _free_of_velocity(3073)
    dt = 1e-3 * 11.0 / 3073
    _, (ref, ri), (fast, fi) = run_both(problem, LieVerlet, dt, 11)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)
    states = []
    for blocks in (1, 2, 3):
        _serial_blocks(monkeypatch, blocks)
        scheme = Lattice(problem)
        state = scheme.initial_state()
        state.scalars.setdefault("nstep", 0)
        assert scheme.compiled_advance(LieVerlet(), state, dt, 11)
        states.append(state)
    single = states[-1]
    for other in (fast, *states[:-1]):
        assert all(np.array_equal(other.arrays[k], single.arrays[k]) for k in single.arrays)
        assert np.array_equal(other.S, single.S) and other.scalars == single.scalars


@pytest.mark.parametrize(("n", "blocks", "fail_at"), [(2100, (1, 2), 3), (2100, (1, 2), 8), (5000, (2, 3), 5)])
def test_blocked_steps_stop_at_the_failing_step(n, blocks, fail_at, monkeypatch):
    """A kinetic-energy limit crossed inside a block of steps: the loop returns the state after
    the failing step (the block is replayed from its start), as single steps do (the second
    block count: fewer than two chunks per block)."""
    problem = _free_of_velocity(n)
    dt = 1e-3 * 11.0 / n
    scheme = Lattice(problem)
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    energies = []
    state = start.copy()
    integ = LieVerlet()
    for _ in range(9):
        integ.step(scheme, state, dt)
        energies.append(scheme.kinetic_energy(state))
    assert np.all(np.diff(energies) > 0)  # the rod falls: the limit is crossed once
    limit = 0.5 * (energies[fail_at - 2] + energies[fail_at - 1])
    results = []
    for k in blocks:
        _serial_blocks(monkeypatch, k)
        state = start.copy()
        integ = LieVerlet()
        assert scheme.compiled_advance(integ, state, dt, 12, kinetic_limit=limit)
        results.append((state, integ))
    (a, ai), (b, bi) = results
    assert a.scalars["nstep"] == fail_at == b.scalars["nstep"] and ai.nforce == bi.nforce
    assert all(np.array_equal(a.arrays[k], b.arrays[k]) for k in a.arrays)
    assert np.array_equal(a.S, b.S) and a.scalars == b.scalars


@pytest.mark.slow
@pytest.mark.skipif(_threads.max_threads() < 2, reason="numba has a single thread here (NUMBA_NUM_THREADS = 1)")
def test_overdamped_se3_threaded_build_equals_the_serial_one(monkeypatch):
    """The threaded build of the vectorised overdamped loop (two blocks of edge chunks) gives
    the serial results bit for bit."""
    problem = rod_problem("ring", n=2100)
    scheme = Lattice(problem)
    start = scheme.initial_state()
    states = []
    for threads in (1, 2):
        calls = _spy(monkeypatch, "overdamped_se3_loop")
        monkeypatch.setattr(lc, "loop_threads", lambda nodes, k=threads: k)
        state = start.copy()
        with cartan.use_threads(threads):
            assert scheme.compiled_advance(Overdamped(order=1), state, 2e-6 * (10.0 / 2100) ** 2, 4)
        assert calls == [(threads > 1, threads)]
        states.append(state)
    a, b = states
    assert all(np.array_equal(a.arrays[k], b.arrays[k]) for k in a.arrays)
    assert np.array_equal(a.S, b.S) and a.scalars == b.scalars


@pytest.mark.parametrize("periodic", [False, True])
def test_coupled_stiffness(periodic):
    base = arc_problem(n=9, curvature=1.0, periodic=periodic, velocity=[0.1, 0.2, 0.0, 0.3, 0.1, 0.2])
    problem = Problem(_FullQuadratic(), base.grid, base.initial)
    _, (ref, _), (fast, _) = run_both(problem, LieVerlet, 1e-3, 80)
    assert_close_states(fast, ref)


def _generated_force(scheme, state, N) -> np.ndarray:
    """``Lattice.force`` at ``state`` and velocity ``N`` on the generated operators (``op_force``)."""
    ops = scheme.compiled_operators()
    assert ops.ok
    module = ops.generated()
    W = np.empty((ops.nodes, scheme.group.dim))
    module.op_force(ops.data, ops.pack(state), float(state.t),
                    np.ascontiguousarray(N, dtype=float).reshape(ops.nodes, -1), W, module.op_work(ops.data))
    return W.reshape(np.shape(state.S))


@pytest.mark.parametrize("on_group", [True, False])
def test_force_matches_lattice_force(on_group):
    """One force evaluation at a perturbed state: on the group by the structure-of-arrays
    passes of the SE(3) loops (and after a drift ``Φ ← Φ exp(τV)``, as the CFL probe drifts),
    off it (forward-euler) by the generated operators."""
    problem = rod_problem("dead")
    scheme = Lattice(problem)
    state = scheme.initial_state()
    rng = np.random.default_rng(0)
    G = scheme.group.compose(state.arrays["G_u"], scheme.group.exp(0.05 * rng.standard_normal((10, 6))))
    if not on_group:
        G = G + 1e-6 * rng.standard_normal(G.shape) * (np.arange(4) > 0)[:, None]
    state.arrays["G_u"] = G
    N = rng.standard_normal(state.S.shape)
    W = scheme.force(state, N, 0.0)
    if not on_group:
        assert _rel(_generated_force(scheme, state, N), W) <= 1e-13
        return
    Wc = np.empty_like(W)
    lc.force_once(scheme, lc.build_plan(scheme), G, state.arrays["Phi"], N, Wc)
    assert _rel(Wc, W) <= 1e-13
    V, tau = 0.3 * rng.standard_normal(state.S.shape), 0.2
    moved = state.copy()
    scheme.drift(moved, tau, V)
    lc.force_once(scheme, lc.build_plan(scheme), G, state.arrays["Phi"], N, Wc, V, tau)
    assert _rel(Wc, scheme.force(moved, N, 0.0)) <= 1e-13


def test_kinetic_limit_stops_after_the_failing_step():
    problem = rod_problem("dead")
    scheme = Lattice(problem)
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    integ = LieVerlet()
    assert scheme.compiled_advance(integ, state, 1e-3, 50, kinetic_limit=1e-12)
    assert state.scalars["nstep"] == 1 and integ.nstep == 1


# ---------------------------------------------------------------------------- fallback
class _SpatialForce(UniformForce):
    pass


class _NotQuadratic(QuadraticMedium):
    """U = ½Σ C_k (X_k − X0_k)² + ¼ε(X₁ − 1)⁴: not quadratic, so no compiled loop."""

    def potential(self, X):
        return super().potential(X) + 0.25 * 0.1 * (X[..., 0, 0] - 1.0) ** 4

    def stress(self, X):
        Q = super().stress(X)
        Q[..., 0, 0] += 0.1 * (X[..., 0, 0] - 1.0) ** 3
        return Q

    def quadratic_energy(self):
        return None


def _declines(problem, integ, **scheme_options):
    scheme = Lattice(problem, **scheme_options)
    state = scheme.initial_state()
    before = state.copy()
    assert not scheme.compiled_advance(integ, state, 1e-4, 3)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
    assert integ.nstep == 0


def test_unsupported_combinations_decline():
    rod = moving_rod(False)
    grid = Grid(9)
    init = rod.initial_state(grid, "arc", curvature=1.0)
    gravity = rod.make_load("gravity", g=[0, 0, -9.81])
    # a medium whose potential is not quadratic (quadratic_energy() is None)
    toy = arc_problem(n=9)
    _declines(Problem(_NotQuadratic(), toy.grid, toy.initial), LieVerlet())
    # loads that are not data: spatial uniform force, a subclass of a supported load
    _declines(Problem(rod, grid, init, loads=[UniformForce(np.ones(6), frame="spatial")]), LieVerlet())
    _declines(Problem(rod, grid, init, loads=[_SpatialForce(np.ones(6))]), LieVerlet())
    # frames needed but not stepped
    _declines(Problem(rod, grid, init, loads=[gravity]), LieVerlet(), track_frames=False)
    # a kinematic velocity that is a Python function; overdamped without damping (Python raises)
    _declines(Problem(rod, grid, init), Kinematic(velocity=lambda t, u, X: np.zeros((9, 6))))
    _declines(Problem(rod, grid, init), Overdamped())
    # a group without compiled kernels
    base = arc_problem(n=9, group=cartan.group("SO", n=4))
    _declines(Problem(_QuadraticData(base.medium.group), base.grid, base.initial), LieVerlet())
    # the numpy backend
    with cartan.use_backend("numpy"):
        _declines(Problem(rod, grid, init), LieVerlet())


def test_fallback_runs_give_the_python_results():
    rod = moving_rod(False)
    grid = Grid(9)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0, velocity=[0, 0.1, 0, 0, 0, 0.2]),
                      loads=[UniformForce([0, 0, 0.5, 0, 0, 0], frame="spatial")])
    a = simulate(problem, dt=1e-3, t_end=0.02, save_every=5)
    b = simulate(problem, dt=1e-3, t_end=0.02, save_every=5, compiled=False)
    for name in a.data_vars:
        assert np.array_equal(a[name].values, b[name].values), name


def test_malformed_quadratic_energy_is_an_error():
    class Wrong(_QuadraticData):
        def quadratic_energy(self):
            return self.X0, 2.0 * np.diag(self.C)

    base = arc_problem(n=9)
    problem = Problem(Wrong(), base.grid, base.initial)
    with pytest.raises(ValueError, match="disagrees with stress"):
        Lattice(problem).compiled_advance(LieVerlet(), Lattice(problem).initial_state(), 1e-3, 1)
    assert Medium.quadratic_energy(base.medium) is None


# ---------------------------------------------------------------------------- simulate
def _config(ds):
    return json.loads(ds.attrs["cartan_config"])


def test_simulate_compiled_agrees_with_reference():
    problem = rod_problem("dead", n=15)
    kw = dict(dt=1e-3, t_end=0.05, save_every=7)
    fast = simulate(problem, **kw)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "position", "frame", "kinetic_energy", "potential_energy", "dissipated_energy",
                 "external_work"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)
    cf, cr = _config(fast)["counters"], _config(ref)["counters"]
    assert (cf["nstep"], cf["nforce"]) == (cr["nstep"], cr["nforce"])


def _identical(a, b):
    for name in a.variables:
        assert np.array_equal(a[name].values, b[name].values), name


def test_restart_is_bit_for_bit_with_the_compiled_path(tmp_path):
    problem = rod_problem("follower", n=13)
    kw = dict(dt=1e-3, save_every=6)
    full = simulate(problem, t_end=0.06, output=tmp_path / "full.nc", **kw)
    simulate(problem, t_end=0.024, output=tmp_path / "part.nc", **kw)
    cont = simulate(problem, t_end=0.06, restart=tmp_path / "part.nc", **kw)
    _identical(full, cont)
    assert _config(full)["counters"]["nstep"] == _config(cont)["counters"]["nstep"]


def test_restart_after_interruption_with_the_compiled_path(tmp_path, monkeypatch):
    import importlib

    sim = importlib.import_module("cartan.simulate")
    problem = rod_problem("ring", n=12)
    kw = dict(dt=1e-3, t_end=0.05, save_every=4, checkpoint_every=3)
    full = simulate(problem, output=tmp_path / "full.nc", **kw)
    real, calls = sim._advance, {"n": 0}

    def interrupted(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 8:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(sim, "_advance", interrupted)
    with pytest.raises(KeyboardInterrupt):
        simulate(problem, output=tmp_path / "run.nc", **kw)
    monkeypatch.setattr(sim, "_advance", real)
    _identical(full, simulate(problem, restart=tmp_path / "run.nc", **kw))


@pytest.mark.parametrize("save_every", [10, 1000])
def test_blow_up_is_named_at_the_same_step(tmp_path, save_every):
    problem = rod_problem("dead", n=11)
    errors = []
    for compiled in (True, False):
        with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
            simulate(problem, dt=0.02, t_end=50.0, save_every=save_every, compiled=compiled,
                     output=tmp_path / f"blow-{compiled}.nc")
        errors.append(info.value)
    # same step, same test failing (the magnitudes it quotes differ: round-off grows with the blow-up)
    assert errors[0].step == errors[1].step
    masked = [re.sub(r"\d+(\.\d*)?(e[-+]\d+)?", "#", str(e).split(";")[0]) for e in errors]
    assert masked[0] == masked[1]
    good = cartan.open(cartan.io.lastgood_path(tmp_path / "blow-True.nc"))
    assert float(good.time[-1]) < errors[0].time and np.all(np.isfinite(good.S.values))


# ---------------------------------------------------------------------------- field potentials
def test_constant_field_potential_pulls_back_to_body_force():
    rod = moving_rod(False)
    grid = Grid(7)
    init = rod.initial_state(grid, "arc", curvature=1.0)
    field = ConstantFieldPotential([0.0, -2.0, 1.0], density=3.0)
    Problem(rod, grid, init, loads=[field])
    Phi = init.Phi
    T = field.force(Phi, np.zeros((7, 6)), 0.0)
    expected = np.einsum("nji,j->ni", Phi[:, 1:, 1:], 3.0 * np.array([0.0, -2.0, 1.0]))
    np.testing.assert_allclose(T[:, :3], expected, atol=1e-14)
    assert np.all(T[:, 3:] == 0.0)
    np.testing.assert_allclose(field.energy(Phi), -3.0 * Phi[:, 1:, 0] @ [0.0, -2.0, 1.0], atol=1e-14)
    gravity = rod.make_load("gravity", g=[0, 0, -9.81])
    assert isinstance(gravity, ConstantFieldPotential) and gravity.density == rod.linear_density
    with pytest.raises(ValueError, match="shape"):
        Problem(rod, grid, init, loads=[ConstantFieldPotential([1.0, 0.0], 1.0)])
    base = arc_problem(n=5, group="SO3")
    with pytest.raises(ValueError, match="affine"):
        Problem(base.medium, base.grid, base.initial, loads=[ConstantFieldPotential([1.0, 0.0, 0.0], 1.0)])


def test_constant_field_on_a_point_space():
    """E³ points (q_r = 0): position is the point itself."""
    space = cartan.space("E3")
    field = ConstantFieldPotential([0.0, 0.0, -1.0], density=2.0)

    class Particle(_QuadraticData):
        pass

    medium = Particle("SE3")
    medium.space = space
    grid = Grid(5)
    Phi = cartan.group("SE3").exp(np.linspace(0.1, 0.5, 30).reshape(5, 6))
    Problem(medium, grid, InitialState(Phi=Phi), loads=[field])
    T = field.force(Phi, np.zeros((5, 6)), 0.0)
    np.testing.assert_allclose(T[:, :3], np.einsum("nji,j->ni", Phi[:, 1:, 1:], [0.0, 0.0, -2.0]), atol=1e-14)
    np.testing.assert_allclose(field.energy(Phi), 2.0 * Phi[:, 3, 0], atol=1e-14)


# ---------------------------------------------------------------------------- d ≥ 2
def sigma_problem(shape, periodic, damping=False, boundaries=None) -> Problem:
    """The sigma model on S² (SO(3), the gauge component carries no inertia) on a d = 2 or 3
    grid: a smooth random field with a gauge twist of the frames and a velocity."""
    medium = cartan.medium("sigma-model", n=2, d=len(shape))
    grid = Grid(shape, 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    loads = [medium.make_load("drag", gamma=0.7)] if damping else []
    return Problem(medium, grid, init, boundaries or {}, loads)


#: (integrator factory, Δt, steps, damping) on the 12 × 9 grids (h ≈ 0.1, c = 1: Δt = 2e-3 is a
#: Courant number of 0.02; the harmonic-map flow is stable below Δt ≈ h²/8 ≈ 1e-3)
SIGMA_INTEGRATORS = {
    "lie-verlet": (LieVerlet, 2e-3, 40, False),
    "lie-verlet-damped": (LieVerlet, 2e-3, 40, True),
    "lie-euler": (LieEuler, 2e-4, 20, True),
    "forward-euler": (ForwardEuler, 1e-5, 5, True),
    "rkmk4": (RKMK4, 1e-3, 10, True),
    "overdamped-1": (lambda: Overdamped(order=1), 2e-5, 30, True),
    "overdamped-2": (lambda: Overdamped(order=2), 2e-5, 15, True),
}
#: the first-order integrators' loops (each a further compile of a minute under load) in ``make test-slow``
#: the d = 2 sigma model keeps lie-verlet in the fast suite (the other loops of its
#: module compile for 10-25 s each on a fresh cache)
SLOW_SIGMA = {"forward-euler", "overdamped-2", "lie-euler", "overdamped-1", "rkmk4"}


@pytest.mark.parametrize("periodic", [(True, True), (False, False), (True, False)], ids=["torus", "open", "cylinder"])
@pytest.mark.parametrize("name", [pytest.param(name, marks=[pytest.mark.slow] if name in SLOW_SIGMA else [])
                                  for name in sorted(SIGMA_INTEGRATORS)])
def test_sigma_model_d2_agrees_with_python(name, periodic):
    make, dt, nsteps, damping = SIGMA_INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(sigma_problem((12, 9), periodic, damping), make, dt, nsteps)
    assert set(fast.arrays) == {"G_u", "G_v", "Phi_root"}
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@pytest.mark.parametrize("track", [False, True], ids=["root-frame", "all-frames"])
@pytest.mark.parametrize("name", ["lie-verlet-damped", "overdamped-1", "rkmk4"])
def test_d2_clamped_and_loaded_faces(name, track):
    """A clamped face, a follower and a dead load on two others (the corner nodes are loaded
    twice, or loaded and clamped); the dead load needs every frame."""
    make, dt, nsteps, damping = SIGMA_INTEGRATORS[name]
    follower = {"u-start": Clamped(), "u-end": Free(load=[0.1, 0.2, 0.0], follower=True),
                "v-end": Free(load=[0.3, -0.2, 0.1], follower=True)}
    dead = dict(follower, **{"v-end": Free(load=[0.3, -0.2, 0.1], follower=False)})
    problem = sigma_problem((12, 9), (False, False), damping, dead if track else follower)
    _, (ref, ri), (fast, fi) = run_both(problem, make, dt, nsteps)
    assert ("Phi" in fast.arrays) == track
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


@pytest.mark.slow
@pytest.mark.parametrize("periodic", [(True, True, True), (False, True, False)], ids=["periodic", "mixed"])
@pytest.mark.parametrize("name", ["lie-verlet", "overdamped-1"])
def test_sigma_model_d3_agrees_with_python(name, periodic):
    make, dt, nsteps, damping = SIGMA_INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(sigma_problem((6, 5, 4), periodic, damping), make, dt, nsteps // 2)
    assert set(fast.arrays) == {"G_u", "G_v", "G_w", "Phi_root"}
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


class _Toy2(_FullQuadratic):
    """A coupled quadratic medium on a d = 2 grid, with a different rest strain per axis."""

    name = "toy-quadratic-2d"
    material_dim = 2
    separable_axes = True

    def __init__(self, group):
        super().__init__(group)
        r = self.group.dim
        self._set_energy(np.stack([0.5 * np.eye(r)[0], np.linspace(-0.3, 0.2, r)]), self.C)


def _toy2_problem(group: str, periodic) -> Problem:
    medium = _Toy2(group)
    g = medium.group
    grid = Grid((7, 6), (1.0, 0.8), periodic=periodic)
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    rng = np.random.default_rng(5)
    a, b = rng.standard_normal((2, g.dim))
    Phi = g.exp(0.8 * np.sin(2 * np.pi * u)[..., None] * a + 0.6 * np.cos(2 * np.pi * v)[..., None] * b)
    N = 0.3 * np.sin(2 * np.pi * (u + v))[..., None] * np.linspace(0.5, 1.0, g.dim)
    return Problem(medium, grid, InitialState(Phi=Phi, N=N), {}, [Damping(0.2)])


@pytest.mark.parametrize("group", ["SO2", "SE2", "SE3"])
@pytest.mark.parametrize("name", ["lie-verlet", "lie-euler", "rkmk4"])
def test_every_group_on_a_d2_grid(group, name):
    """The generic kernels on d = 2 (and SE(3)'s scalar ones), coupled stiffness, a rest
    strain per axis, damping, a torus."""
    make, dt, nsteps = INTEGRATORS[name]
    _, (ref, ri), (fast, fi) = run_both(_toy2_problem(group, True), make, dt, nsteps // 2)
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


@pytest.mark.parametrize("on_group", [True, False])
def test_force_matches_lattice_force_d2(on_group):
    """One force evaluation on a d = 2 lattice with end loads, at a perturbed state."""
    problem = sigma_problem((8, 7), (False, True), True, {"u-end": Free(load=[0.2, 0.1, 0.0], follower=False)})
    scheme = Lattice(problem)
    state = scheme.initial_state()
    rng = np.random.default_rng(2)
    g = scheme.group
    for key in ("G_u", "G_v"):
        G = state.arrays[key]
        G = g.compose(G, g.exp(0.05 * rng.standard_normal((*G.shape[:-2], 3))))
        if not on_group:
            G = G + 1e-6 * rng.standard_normal(G.shape)
        state.arrays[key] = G
    N = rng.standard_normal(state.S.shape)
    W = scheme.force(state, N, 0.0)
    assert lc.build_plan(scheme) is None  # d = 2: the generated operators
    assert _rel(_generated_force(scheme, state, N), W) <= 1e-13


def test_d2_unsupported_loads_decline():
    problem = sigma_problem((6, 5), (True, True))
    spatial = Problem(problem.medium, problem.grid, problem.initial, loads=[UniformForce(np.ones(3), frame="spatial")])
    _declines(spatial, LieVerlet())


def test_simulate_sigma_model_d2_compiled_agrees_with_reference():
    problem = sigma_problem((16, 12), (True, False), damping=True)
    kw = dict(dt=2e-3, t_end=0.06, save_every=10)
    fast = simulate(problem, **kw)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("S", "N", "kinetic_energy", "potential_energy", "dissipated_energy"):
        assert _rel(fast[name].values, ref[name].values) <= TOL, name
    cf, cr = _config(fast)["counters"], _config(ref)["counters"]
    assert (cf["nstep"], cf["nforce"]) == (cr["nstep"], cr["nforce"])


# ---------------------------------------------------------------------------- numba cache
CACHE_SCRIPT = textwrap.dedent(
    """
    import numpy as np
    import cartan
    from cartan.grid import Grid
    from cartan.problem import Problem, Clamped, Damping
    from cartan.schemes import _lattice_compiled as lc

    rod = cartan.medium("cosserat-rod", E=1e6, poisson=0.5, radius=0.02, density=1000.0)
    grid = Grid(12, length=1.0)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0), {"start": Clamped()},
                      [Damping(0.1), rod.make_load("gravity", g=[0.0, 0.0, -9.81])])
    cartan.simulate(problem, dt=1e-5, t_end=2e-4, save_every=5)
    kernels = [v for v in vars(lc).values() if hasattr(v, "stats") and hasattr(v, "signatures")]
    hits = sum(sum(d.stats.cache_hits.values()) for d in kernels)
    misses = sum(sum(d.stats.cache_misses.values()) for d in kernels)
    print(sum(lc.lie_verlet_se3_loop.stats.cache_hits.values()), hits, misses)
    """
)


def test_second_process_loads_the_compiled_loops_from_the_cache():
    runs = [
        subprocess.run([sys.executable, "-c", CACHE_SCRIPT], capture_output=True, text=True, cwd=ROOT, timeout=600)
        for _ in range(2)
    ]
    for run in runs:
        assert run.returncode == 0, run.stderr
    loop_hits, hits, misses = map(int, runs[1].stdout.split()[-3:])
    assert loop_hits == 1 and hits >= 1 and misses == 0, runs[1].stdout


def test_hand_written_loops_decline_other_integrators_without_a_plan():
    """``may_run`` is the static part of ``compiled_kind``: True for the built-in lie-verlet and
    overdamped, False for the others and for subclasses; a declined integrator builds no plan
    (``compiled_advance`` returns False before it)."""
    from cartan.integrators import Rattle
    from cartan.schemes._lattice_compiled import may_run
    from cartan.schemes.lattice import Lattice

    class MyVerlet(LieVerlet):
        pass

    assert may_run(LieVerlet()) and may_run(Overdamped())
    assert not any(may_run(i) for i in (RKMK4(), LieEuler(), ForwardEuler(), Rattle(), MyVerlet()))
    scheme = Lattice(rod_problem("cantilever"))
    state = scheme.initial_state()
    assert scheme.compiled_advance(RKMK4(), state.copy(), 1e-4, 1) is False
    assert "_compiled_plan" not in scheme.__dict__
