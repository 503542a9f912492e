"""The generated compiled loops as ``cartan.simulate`` takes them, against the Python reference path.

Every integrator has one compiled loop (:mod:`cartan.integrators.loops`), run by
``Integrator.run_compiled_loop`` over the scheme's operator set (``scheme.compiled_operators()``)
inside a module generated per (scheme, group, medium kernels, d).  The schemes' hand-written
``compiled_advance`` is switched off here (an autouse fixture), so ``simulate`` takes the
generated loops whenever the operator set covers the problem.

What is guarded, on the lattice and on collocation: agreement with the Python path to 1e-12 —
the loops evaluate the reference formulas in another order, so the two differ by round-off
only, a few ulps per step over at most 50 steps, and 1e-12 is the project's
compiled-vs-reference bound —, the same step and force counts (first-same-as-last force of
``lie-verlet``), the root frame only when no load needs the frames, a gauge component, fast
spin, the kinetic-energy limit, the blow-up step, bit-for-bit restarts, declining with a
reason (and ``simulate`` then giving the Python results), malformed kernel declarations,
constant fields (gravity), the numba cache in a new process and the CFL estimate.

Compile budget: each (scheme, group, medium kernels, d) is one generated module, each loop of
it compiles on first use; the un-marked tests share the SE(3) rod on both schemes and the SO(3)
sigma model on a d = 2 lattice with the ``lie-verlet`` and ``rkmk4`` loops (``overdamped`` runs
the RKMK loop); broader matrices are marked ``slow``.
"""

from __future__ import annotations

import importlib
import json
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from toys import QuadraticMedium, arc_problem, moving_rod, params_of, rel_error

import cartan
from cartan.api import InstabilityError, StabilityWarning, simulate
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from cartan.medium import MediumKernels
from cartan.problem import Clamped, ConstantFieldPotential, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes import Collocation, Lattice

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: compiled against Python over whole runs: round-off (see the module docstring)
TOL = 1e-12
#: one force or potential evaluation: a few hundred operations in another order, round-off of
#: order 1e-15 of the value's size; 1e-13 leaves about two digits of margin
FORCE_TOL = 1e-13
SCHEMES = {"lattice": Lattice, "collocation": Collocation}


def slow_when(item) -> bool:
    """``make test`` runs the generated ``lie-verlet`` loops of the SE(3) rod on both schemes; the
    RKMK loop (rkmk4, overdamped, lie-euler, forward-euler) and the d = 2 sigma model's loops run in
    ``make test-slow`` (tests/conftest.py)."""
    p = params_of(item)
    integrator = p.get("name", p.get("integrator", "lie-verlet"))
    return integrator != "lie-verlet" or "order" in p or "sigma_model_d2" in item.originalname
#: the configuration arrays of each scheme beside the frames
CONFIG = {"lattice": {"G_u"}, "collocation": {"X"}}
#: (integrator factory, Δt, steps) inside each method's stable range for the 11-node rods
#: (the overdamped flow of the stiff rod needs Δt·λ_max ≤ 2, λ_max ≈ 4e5 with damping 0.1)
INTEGRATORS = {
    "lie-verlet": (LieVerlet, 1e-3, 30),
    "rkmk4": (RKMK4, 1e-3, 12),
    "overdamped-1": (lambda: Overdamped(order=1), 2e-6, 20),
}
SLOW_INTEGRATORS = {
    "lie-euler": (LieEuler, 2e-4, 30),
    "forward-euler": (ForwardEuler, 1e-5, 8),
    "overdamped-2": (lambda: Overdamped(order=2), 2e-6, 15),
}


@pytest.fixture(autouse=True)
def generated_path_only(monkeypatch):
    """The schemes' hand-written loops decline everything: ``simulate`` takes the generated loop."""
    for cls in SCHEMES.values():
        monkeypatch.setattr(cls, "compiled_advance", lambda self, *args, **kwargs: False, raising=False)


# ---------------------------------------------------------------------------- problems
def rod(kind: str, gravity: bool = False, n: int = 11, planar: bool = False, moving: bool = True) -> Problem:
    """The Cosserat rod of ``toys.moving_rod`` with damping: bent into an arc and clamped with a
    dead end load (``"dead"``: the frames are stepped) or with a follower end load and a
    body-frame force (``"follower"``), or a closed, wavy ring of length 2π; optionally under gravity."""
    medium = moving_rod(planar)
    r = medium.group.dim
    velocity = np.linspace(0.1, 0.3, r) if moving else None
    if kind == "ring":  # closed: exp(2πξ) = I (collocation takes closed periodic axes only)
        grid = Grid(n, 2 * np.pi, periodic=True)
        xi = np.array([1.0, 0.0, 1.0] if planar else [1.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        u = grid.coordinates(0)
        wave = 0.05 * np.sin(u)[:, None] * np.linspace(1.0, 0.5, r)  # off the uniform ring's equilibrium
        init = InitialState(Phi=medium.group.compose(medium.group.exp(u[:, None] * xi), medium.group.exp(wave)),
                            N=None if velocity is None else np.broadcast_to(velocity, (n, r)).copy())
    else:
        grid = Grid(n, length=1.0)
        init = medium.initial_state(grid, "arc", curvature=2.0, velocity=velocity)
    loads = [Damping(np.linspace(0.1, 0.2, r))]
    if gravity:
        loads.append(medium.make_load("gravity", g=[0.0, -9.81, 0.0][: 2 if planar else 3]))
    boundaries = {}
    if kind == "dead":
        boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=False)}
    elif kind == "follower":
        boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=True)}
        loads.append(UniformForce(np.linspace(-0.2, 0.3, r)))
    return Problem(medium, grid, init, boundaries, loads)


def sigma_problem(shape, periodic, boundaries=None) -> Problem:
    """The sigma model on S² (SO(3), the gauge component carries no inertia) on a d = 2 or 3
    grid: a smooth random field with a gauge twist of the frames, a velocity and its drag."""
    medium = cartan.medium("sigma-model", n=2, d=len(shape))
    grid = Grid(shape, 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    return Problem(medium, grid, init, boundaries or {}, [medium.make_load("drag", gamma=0.7)])


# ---------------------------------------------------------------------------- helpers
def assert_close_states(a, b, tol=TOL):
    """Same time and step count; every state array and energy accumulator within ``tol``."""
    assert a.t == b.t
    assert set(a.arrays) == set(b.arrays)
    errors = {"S": rel_error(a.S, b.S)}
    errors.update({k: rel_error(a.arrays[k], b.arrays[k]) for k in b.arrays})
    for key in ("dissipated_energy", "external_work"):
        errors[key] = rel_error(a.scalars[key], b.scalars[key])
    assert max(errors.values()) <= tol, errors
    assert a.scalars["nstep"] == b.scalars["nstep"]


def assert_identical_states(a, b):
    assert a.t == b.t and a.scalars == b.scalars and np.array_equal(a.S, b.S)
    assert set(a.arrays) == set(b.arrays)
    assert all(np.array_equal(a.arrays[k], b.arrays[k]) for k in a.arrays)


def run_both(scheme, make, dt, nsteps, blocks=None):
    """``nsteps`` steps by ``Integrator.step`` and, in ``blocks`` calls, by the generated loop."""
    ops = scheme.compiled_operators()
    assert ops.ok, ops.reason
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, fast = start.copy(), start.copy()
    ri, fi = make(), make()
    for _ in range(nsteps):
        ri.step(scheme, ref, dt)
    blocks = blocks or (nsteps,)
    assert sum(blocks) == nsteps
    for size in blocks:
        assert fi.run_compiled_loop(scheme, fast, dt, size)
    # the run moved the configuration (not a comparison of two copies of the start)
    assert max(rel_error(ref.arrays[k], start.arrays[k]) for k in start.arrays) > 1e-9
    return (ref, ri), (fast, fi)


def _config(ds) -> dict:
    return json.loads(ds.attrs["cartan_config"])


def _identical_runs(a, b):
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        assert np.array_equal(a[name].values, b[name].values), name


def _numbers_masked(error) -> str:
    """The message of an InstabilityError up to its first ';', numbers masked (the magnitudes it
    quotes differ between the paths: round-off grows with the blow-up)."""
    return re.sub(r"\d+(\.\d*)?(e[-+]\d+)?", "#", str(error).split(";")[0])


# ---------------------------------------------------------------------------- agreement
@pytest.mark.parametrize("integrator", ["lie-verlet", "rkmk4"])
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_simulate_compiled_agrees_with_python(scheme, integrator, generated_runs):
    """``simulate`` on the generated loop against ``compiled=False``: frames, energies, steps and
    the step and force counters (collocation under gravity; the lattice without)."""
    problem = rod("dead", gravity=scheme == "collocation", n=15)
    kw = dict(dt=1e-3, t_end=0.05, save_every=7, scheme=scheme, integrator=integrator, progress=False)
    fast = simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("X", "S", "N", "position", "frame", "kinetic_energy", "potential_energy", "dissipated_energy",
                 "external_work"):
        assert rel_error(fast[name].values, ref[name].values) <= TOL, name
    assert np.array_equal(fast.step.values, ref.step.values)
    cf, cr = _config(fast)["counters"], _config(ref)["counters"]
    assert (cf["nstep"], cf["nforce"]) == (cr["nstep"], cr["nforce"])


@pytest.mark.parametrize("kind", ["dead", "follower", "ring"])
@pytest.mark.parametrize("name", sorted(INTEGRATORS))
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_loop_in_blocks_agrees_and_hands_over_its_caches(scheme, name, kind):
    """The generated loop in blocks against the step loop: states, counters (first-same-as-last
    force of lie-verlet across blocks), and a following Python step from the handed-over caches."""
    make, dt, nsteps = INTEGRATORS[name]
    sch = SCHEMES[scheme](rod(kind, gravity=scheme == "collocation"))
    blocks = (1, 2, nsteps - 3)
    (ref, ri), (fast, fi) = run_both(sch, make, dt, nsteps, blocks)
    assert_close_states(fast, ref)
    assert fi.nstep == ri.nstep and fi.wall_time > 0
    assert fi.nforce == ri.nforce
    ri.step(sch, ref, dt)
    fi.step(sch, fast, dt)
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_overdamped_loop_counts_forces_like_the_python_path(scheme, order):
    """One velocity per stage, the one computed for the powers at the end of a step being the
    first stage's of the next, across blocks: order·n + 1 forces for n steps on both paths."""
    make, dt, nsteps = {**INTEGRATORS, **SLOW_INTEGRATORS}[f"overdamped-{order}"]
    sch = SCHEMES[scheme](rod("dead", gravity=scheme == "collocation"))
    (ref, ri), (fast, fi) = run_both(sch, make, dt, nsteps, (1, 2, nsteps - 3))
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce) == (nsteps, order * nsteps + 1)


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_velocity_free_lie_verlet_uses_one_force_per_step(scheme):
    """No damping, no velocity-dependent load: one force per step, plus the first one, across
    blocks (the last force of a block is the first of the next)."""
    medium = moving_rod(False)
    grid = Grid(9)
    problem = Problem(medium, grid, medium.initial_state(grid, "arc", curvature=1.0,
                                                         velocity=[0, 0.1, 0, 0, 0, 0.3]))
    (ref, ri), (fast, fi) = run_both(SCHEMES[scheme](problem), LieVerlet, 1e-3, 50, blocks=(10, 40))
    assert_close_states(fast, ref)
    assert fi.nforce == ri.nforce == 51


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_root_frame_only(scheme):
    """Follower loads need no frames: only the root frame is stepped, on both paths."""
    medium = moving_rod(False)
    grid = Grid(9)
    init = medium.initial_state(grid, "arc", curvature=1.5, velocity=[0.1, 0.2, 0, 0.3, 0, 0.1])
    problem = Problem(medium, grid, init, {"start": Clamped(), "end": Free(load=[0, 0, 1.0, 0, 0.2, 0], follower=True)})
    sch = SCHEMES[scheme](problem, track_frames=False)
    (ref, _), (fast, _) = run_both(sch, LieVerlet, 1e-3, 40)
    assert set(fast.arrays) == CONFIG[scheme] | {"Phi_root"}
    assert_close_states(fast, ref)


@pytest.mark.parametrize("name", ["lie-verlet", "rkmk4"])
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_se3_with_a_gauge_component(scheme, name):
    """A zero inertia: lie-verlet's free flow has a piece without the zero-mass direction, and
    the gauge component of the momentum stays zero."""
    make, dt, nsteps = INTEGRATORS[name]
    rod_type = type(moving_rod(False))

    class GaugeRod(rod_type):
        """The test rod without inertia along its third translation (the same point kernels)."""

        def inertia(self):
            m = np.array(super().inertia(), dtype=float)
            m[2] = 0.0
            return m

    medium = GaugeRod(stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                      rotational_inertia=[0.02, 0.01, 0.01])
    grid = Grid(9)
    init = medium.initial_state(grid, "arc", curvature=1.0, velocity=[0.1, 0.2, 0.0, 0.3, 0.1, 0.2])
    sch = SCHEMES[scheme](Problem(medium, grid, init, {"start": Clamped()}, [Damping(0.1)]))
    assert not sch.live[2]
    (ref, ri), (fast, fi) = run_both(sch, make, dt, nsteps)
    if name == "lie-verlet":
        assert any(np.count_nonzero(np.diag(P)) == 2 for P, _ in fi._sequence(sch))
    assert_close_states(fast, ref)
    assert np.all(fast.S[..., 2] == 0.0)
    assert fi.nforce == ri.nforce


@pytest.mark.parametrize("name", ["lie-verlet", "rkmk4"])
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_fast_spin_agrees(scheme, name):
    """Rotations of up to 0.4 rad per step (beyond the range of any small-angle series) and
    nodes at rest (the clamp) in the same run."""
    medium = moving_rod(False)
    grid = Grid(9)
    init = medium.initial_state(grid, "arc", curvature=0.5, velocity=[0.0, 0.0, 0.0, 400.0, 30.0, 0.0])
    problem = Problem(medium, grid, init, {"start": Clamped()})
    sch = SCHEMES[scheme](problem)
    dt = 1e-3
    theta = dt * np.linalg.norm(sch.velocity(sch.initial_state())[..., 3:], axis=-1)
    assert theta.max() > 0.35 and theta.min() == 0.0
    (ref, _), (fast, _) = run_both(sch, INTEGRATORS[name][0], dt, 12)
    assert_close_states(fast, ref)


# ---------------------------------------------------------------------------- stopping
@pytest.mark.parametrize("fail_at", [1, 4])
@pytest.mark.parametrize("name", ["lie-verlet", "rkmk4"])
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_kinetic_limit_stops_after_the_failing_step(scheme, name, fail_at):
    """A rod starting at rest under a follower end load gains kinetic energy at every step; a
    limit crossed at step ``fail_at`` stops the loop after that step, with the state of
    ``fail_at`` Python steps."""
    make, dt, _ = INTEGRATORS[name]
    sch = SCHEMES[scheme](rod("follower", moving=False))
    start = sch.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, ri = start.copy(), make()
    energies, states = [], []
    for _ in range(6):
        ri.step(sch, ref, dt)
        energies.append(sch.kinetic_energy(ref))
        states.append(ref.copy())
    assert energies[0] > 0 and np.all(np.diff(energies) > 0)  # the limit is crossed once
    limit = 0.5 * energies[0] if fail_at == 1 else 0.5 * (energies[fail_at - 2] + energies[fail_at - 1])
    fast, fi = start.copy(), make()
    assert fi.run_compiled_loop(sch, fast, dt, 50, kinetic_limit=limit)
    assert fast.scalars["nstep"] == fail_at and fi.nstep == fail_at
    assert_close_states(fast, states[fail_at - 1])


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_blow_up_is_named_at_the_same_step(scheme, tmp_path, generated_runs):
    """Far beyond the stable Δt both paths name the same step and the same failing test, and
    the last good state before it is kept."""
    problem = rod("dead", gravity=scheme == "collocation")
    errors = []
    for compiled in (True, False):
        with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
            simulate(problem, dt=0.02, t_end=50.0, save_every=10, compiled=compiled, scheme=scheme, progress=False,
                     output=tmp_path / f"blow-{compiled}.nc")
        errors.append(info.value)
    assert generated_runs and all(generated_runs)
    assert errors[0].step == errors[1].step
    assert _numbers_masked(errors[0]) == _numbers_masked(errors[1])
    good = cartan.open(cartan.io.lastgood_path(tmp_path / "blow-True.nc"))
    assert float(good.time[-1]) < errors[0].time and np.all(np.isfinite(good.S.values))


# ---------------------------------------------------------------------------- restarts
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_restart_is_bit_for_bit_with_the_compiled_path(scheme, tmp_path, generated_runs):
    problem = rod("follower", gravity=scheme == "collocation", n=13)
    kw = dict(dt=1e-3, save_every=6, scheme=scheme, progress=False)
    full = simulate(problem, t_end=0.06, output=tmp_path / "full.nc", **kw)
    simulate(problem, t_end=0.024, output=tmp_path / "part.nc", **kw)
    cont = simulate(problem, t_end=0.06, restart=tmp_path / "part.nc", progress=False)
    assert generated_runs and all(generated_runs)
    _identical_runs(full, cont)
    assert _config(full)["counters"]["nstep"] == _config(cont)["counters"]["nstep"]


def test_restart_after_interruption_with_the_compiled_path(tmp_path, monkeypatch, generated_runs):
    sim = importlib.import_module("cartan.simulate")
    problem = rod("ring", n=12)
    kw = dict(dt=1e-3, t_end=0.05, save_every=4, checkpoint_every=3, progress=False)
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
    _identical_runs(full, simulate(problem, restart=tmp_path / "run.nc", **kw))
    assert generated_runs and all(generated_runs)


# ---------------------------------------------------------------------------- declining
class _SpatialForce(UniformForce):
    """A subclass of a supported load: not known to be data."""


class _NotQuadratic(QuadraticMedium):
    """U = ½Σ C_k (X_k − X0_k)² + ¼ε(X₁ − 1)⁴, overriding the energy: no point kernels."""

    def potential(self, X):
        return super().potential(X) + 0.25 * 0.1 * (X[..., 0, 0] - 1.0) ** 4

    def stress(self, X):
        Q = super().stress(X)
        Q[..., 0, 0] += 0.1 * (X[..., 0, 0] - 1.0) ** 3
        return Q


def _declined_problems() -> list:
    """(id, problem, scheme options, what the reason names)."""
    medium = moving_rod(False)
    grid = Grid(9)
    init = medium.initial_state(grid, "arc", curvature=1.0, velocity=[0, 0.1, 0, 0, 0, 0.2])
    toy = arc_problem(n=9)
    so5 = arc_problem(n=9, group=cartan.group("SO", n=5))
    dead = {"start": Clamped(), "end": Free(load=np.ones(6), follower=False)}
    return [
        ("not-declared", Problem(_NotQuadratic(), toy.grid, toy.initial), {}, "point kernels"),
        ("spatial-force", Problem(medium, grid, init, loads=[UniformForce(np.ones(6), frame="spatial")]), {},
         "UniformForce"),
        ("load-subclass", Problem(medium, grid, init, loads=[_SpatialForce(np.ones(6))]), {}, "load"),
        ("frames-not-stepped", Problem(medium, grid, init, dead), {"track_frames": False}, "frames"),
        ("group-without-kernels", Problem(QuadraticMedium(so5.medium.group), so5.grid, so5.initial), {},
         "point kernels"),
    ]


def _declines(scheme, integ) -> None:
    """``run_compiled_loop`` returns False and touches neither the state nor the counters."""
    state = scheme.initial_state()
    before = state.copy()
    assert not integ.run_compiled_loop(scheme, state, 1e-4, 3)
    assert_identical_states(state, before)
    assert (integ.nstep, integ.nforce) == (0, 0)


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_unsupported_combinations_decline_with_a_reason(scheme):
    for case, problem, options, named in _declined_problems():
        sch = SCHEMES[scheme](problem, **options)
        ops = sch.compiled_operators()
        assert not ops.ok and named in ops.reason, (case, ops.reason)
        _declines(sch, LieVerlet())
    # what the integrator declines: a kinematic velocity that is a Python function, the
    # overdamped flow without damping (the Python step raises the error naming the components)
    base = rod("follower")
    free = Problem(base.medium, base.grid, base.initial)
    sch = SCHEMES[scheme](base)
    assert sch.compiled_operators().ok
    _declines(sch, Kinematic(velocity=lambda t, u, X: np.zeros((11, 6))))
    _declines(SCHEMES[scheme](free), Overdamped())
    # the numpy backend
    with cartan.use_backend("numpy"):
        _declines(sch, LieVerlet())


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_fallback_runs_give_the_python_results(scheme, generated_runs):
    """A declined problem runs on the Python path under ``compiled=True``: bit for bit the
    results of ``compiled=False``."""
    medium = moving_rod(False)
    grid = Grid(9)
    problem = Problem(medium, grid, medium.initial_state(grid, "arc", curvature=1.0,
                                                         velocity=[0, 0.1, 0, 0, 0, 0.2]),
                      loads=[UniformForce([0, 0, 0.5, 0, 0, 0], frame="spatial")])
    kw = dict(dt=1e-3, t_end=0.02, save_every=5, scheme=scheme, progress=False)
    a = simulate(problem, **kw)
    assert generated_runs and not any(generated_runs)
    b = simulate(problem, **kw, compiled=False)
    for name in a.data_vars:
        assert np.array_equal(a[name].values, b[name].values), name


class _WrongKernels(QuadraticMedium):
    """Declares point kernels with twice the stiffness of its ``stress``."""

    name = "toy-wrong-kernels"

    def point_kernels(self):
        k = super().point_kernels()
        return MediumKernels(k.energy, k.stress, 2.0 * np.asarray(k.params))


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_malformed_kernel_declaration_is_an_error(scheme):
    base = arc_problem(n=9, velocity=np.linspace(0.1, 0.3, 6))
    problem = Problem(_WrongKernels(), base.grid, base.initial)
    with pytest.raises(ValueError, match="toy-wrong-kernels.*disagree with stress"):
        SCHEMES[scheme](problem).compiled_operators()
    with pytest.raises(ValueError, match="toy-wrong-kernels.*disagree with stress"):
        simulate(problem, dt=1e-3, t_end=0.01, scheme=scheme, progress=False)


# ---------------------------------------------------------------------------- constant fields
def _pull_back_case(scheme):
    medium = moving_rod(False)
    grid = Grid(9)
    init = medium.initial_state(grid, "arc", curvature=1.0)
    field = ConstantFieldPotential([0.0, -2.0, 1.0], density=3.0)
    boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.2, 0.7, 6), follower=False)}
    with_field = SCHEMES[scheme](Problem(medium, grid, init, boundaries, [Damping(0.1), field]))
    without = SCHEMES[scheme](Problem(medium, grid, init, boundaries, [Damping(0.1)]))
    return with_field, without


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_constant_field_potential_pulls_back_to_the_body_force(scheme):
    """A constant field ρf is the body force ``Rᵀρf`` on the translations (zero at the clamped
    node) in the compiled force, and ``−Σ w ρf·x`` in the compiled potential."""
    with_field, without = _pull_back_case(scheme)
    ops = with_field.compiled_operators()
    assert ops.ok, ops.reason
    state = with_field.initial_state()
    rng = np.random.default_rng(4)
    N = 0.3 * rng.standard_normal(state.S.shape)
    module = ops.generated()
    n, r = ops.nodes, with_field.group.dim
    W = np.empty((n, r))
    module.op_force(ops.data, ops.pack(state), 0.0, np.ascontiguousarray(N.reshape(n, r)), W,
                    module.op_work(ops.data))
    Phi = with_field.frames(state).reshape(n, 4, 4)
    pulled = np.zeros((n, r))
    pulled[:, :3] = np.einsum("nji,j->ni", Phi[:, 1:, 1:], 3.0 * np.array([0.0, -2.0, 1.0]))
    pulled[0] = 0.0  # the clamped node
    expected = without.force(without.initial_state(), N, 0.0).reshape(n, r) + pulled
    assert rel_error(W, expected) <= FORCE_TOL
    assert rel_error(W, with_field.force(state, N, 0.0).reshape(n, r)) <= FORCE_TOL
    V = module.op_potential(ops.data, ops.pack(state), module.op_work(ops.data))
    x = Phi[:, 1:, 0]
    weights = np.asarray(with_field.weights, dtype=float).reshape(n)
    V_field = -np.sum(weights * (x @ (3.0 * np.array([0.0, -2.0, 1.0]))))
    assert rel_error(V, without.potential_energy(without.initial_state()) + V_field) <= FORCE_TOL
    assert rel_error(V, with_field.potential_energy(state)) <= FORCE_TOL


@pytest.mark.slow  # the RKMK loops: ≈ 25-35 s each to compile on a fresh cache
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_rod_under_gravity_runs_compiled_and_agrees(scheme, generated_runs):
    problem = rod("dead", gravity=True)
    assert SCHEMES[scheme](problem).compiled_operators().ok
    kw = dict(dt=1e-3, t_end=0.02, save_every=5, scheme=scheme, integrator="rkmk4", progress=False)
    fast = simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("S", "position", "kinetic_energy", "potential_energy", "dissipated_energy", "external_work"):
        assert rel_error(fast[name].values, ref[name].values) <= TOL, name


# ---------------------------------------------------------------------------- d = 2
@pytest.mark.parametrize("name", ["lie-verlet", pytest.param("rkmk4", marks=pytest.mark.slow)])
def test_sigma_model_d2_lattice_agrees(name):
    """The sigma model on S² on a 12 × 9 cylinder with a clamped face and a follower face
    load: the root frame only, every edge array agrees (Δt = 1e-3 is a Courant number of 0.01)."""
    boundaries = {"u-start": Clamped(), "u-end": Free(load=[0.1, 0.2, 0.0], follower=True)}
    sch = Lattice(sigma_problem((12, 9), (False, True), boundaries))
    (ref, ri), (fast, fi) = run_both(sch, INTEGRATORS[name][0], 1e-3, 10, blocks=(3, 7))
    assert set(fast.arrays) == {"G_u", "G_v", "Phi_root"}
    assert_close_states(fast, ref)
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce)


def test_simulate_sigma_model_d2_lattice_agrees(generated_runs):
    problem = sigma_problem((16, 12), (True, False))
    kw = dict(dt=2e-3, t_end=0.06, save_every=10, integrator="lie-verlet", progress=False)
    fast = simulate(problem, **kw)
    assert generated_runs and all(generated_runs)
    ref = simulate(problem, **kw, compiled=False)
    for name in ("S", "N", "kinetic_energy", "potential_energy", "dissipated_energy"):
        assert rel_error(fast[name].values, ref[name].values) <= TOL, name
    cf, cr = _config(fast)["counters"], _config(ref)["counters"]
    assert (cf["nstep"], cf["nforce"]) == (cr["nstep"], cr["nforce"])


# ---------------------------------------------------------------------------- CFL estimate
#: the forces carry round-off of about 1e-16 of their size, which the central difference of the
#: probe divides by 2ε = 2e-7: products agree to ~1e-9 of their size; margin 10×
PRODUCT_TOL = 1e-8
#: the power iteration stops when two Rayleigh quotients agree to 1e-3; with products equal to
#: 1e-8 it takes the same path and the estimates agree to about that
DT_TOL = 1e-7


@pytest.mark.slow  # the probes: ≈ 15 s (collocation) and 76 s (the lattice plan's) to compile
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_cfl_estimate_with_compiled_diagnostics_matches_numpy(scheme, monkeypatch):
    """``dt_max`` (a power iteration on the stiffness products) with compiled diagnostics
    against the numpy products: equal to the probe's round-off, without calling the numpy
    force, and the linearisation point left as it was."""
    sch = SCHEMES[scheme](rod("dead", gravity=scheme == "collocation", n=14))
    sch.compiled_diagnostics_from = 0  # a small rod
    state = sch.initial_state()
    before = state.copy()
    numpy_forces = []
    real_force = sch.force
    monkeypatch.setattr(sch, "force", lambda *a, **k: numpy_forces.append(1) or real_force(*a, **k))
    v = np.random.default_rng(2).standard_normal(state.S.shape)
    K = sch.stiffness_probe(state)(v)
    fast = {rate: sch.dt_max(state, rate=rate) for rate in ("inertial", "overdamped")}
    assert numpy_forces == []  # the compiled products ran
    sch.compiled_diagnostics = False
    K_ref = sch.stiffness_probe(state)(v)
    ref = {rate: sch.dt_max(state, rate=rate) for rate in ("inertial", "overdamped")}
    assert numpy_forces  # the numpy products ran
    assert np.abs(K).max() > 0 and rel_error(K, K_ref) <= PRODUCT_TOL
    for rate in fast:
        assert abs(fast[rate] / ref[rate] - 1.0) <= DT_TOL, rate
    assert_identical_states(state, before)


# ---------------------------------------------------------------------------- numba cache
CACHE_SCRIPT = textwrap.dedent(
    """
    import numpy as np
    import cartan
    from cartan.grid import Grid
    from cartan.problem import Clamped, Damping, Free, Problem
    from cartan.schemes import Collocation, Lattice

    for cls in (Lattice, Collocation):
        cls.compiled_advance = lambda self, *args, **kwargs: False
    rod = cartan.medium("cosserat-rod", stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                        rotational_inertia=[0.02, 0.01, 0.01])
    grid = Grid(11, length=1.0)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=2.0, velocity=np.linspace(0.1, 0.3, 6)),
                      {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, 6), follower=True)},
                      [Damping(0.1)])
    hits = misses = 0
    for scheme in (Lattice, Collocation):
        cartan.simulate(problem, scheme=scheme.name, integrator="lie-verlet", dt=1e-3, t_end=1e-2, save_every=5,
                        progress=False)
        loop = scheme(problem).compiled_operators().generated().lie_verlet_loop
        hits += sum(loop.stats.cache_hits.values())
        misses += sum(loop.stats.cache_misses.values())
    print(hits, misses)
    """
)


def test_second_process_loads_the_compiled_loops_from_the_cache():
    """Two processes with the same cache: the second compiles nothing (no announcement of a
    generated loop or of a cartan kernel on stderr) and loads both schemes' loops from the cache."""
    env = dict(os.environ, CARTAN_SHOW_COMPILE="1")
    runs = [subprocess.run([sys.executable, "-c", CACHE_SCRIPT], capture_output=True, text=True, cwd=ROOT,
                           timeout=900, env=env) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    assert "cartan: compiling" not in runs[1].stderr, runs[1].stderr
    hits, misses = map(int, runs[1].stdout.split()[-2:])
    assert hits == 2 and misses == 0, runs[1].stdout


# ---------------------------------------------------------------------------- slow: broader matrices
@pytest.mark.slow
@pytest.mark.parametrize("planar", [False, True], ids=["SE3", "SE2"])
@pytest.mark.parametrize("kind", ["dead", "follower", "ring"])
@pytest.mark.parametrize("name", sorted(INTEGRATORS | SLOW_INTEGRATORS))
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_every_integrator_on_rods(scheme, name, kind, planar):
    make, dt, nsteps = (INTEGRATORS | SLOW_INTEGRATORS)[name]
    sch = SCHEMES[scheme](rod(kind, gravity=scheme == "collocation", planar=planar))
    (ref, ri), (fast, fi) = run_both(sch, make, dt, nsteps, blocks=(1, nsteps - 1))
    assert_close_states(fast, ref)
    assert fi.nstep == ri.nstep


@pytest.mark.slow
@pytest.mark.parametrize("derivative", ["fd2", "fd4", "fourier"])
@pytest.mark.parametrize("group", ["SO2", "SE2", "SO3", "SE3"])
def test_collocation_derivatives_and_groups(group, derivative):
    """Every difference rule on closed toy rods of every group (fd2/fd4 also open, clamped)."""
    G = cartan.group(group)
    ring = {"SO2": [1.0], "SE2": [1.0, 0.0, 1.0], "SO3": [0.0, 0.0, 1.0], "SE3": [1.0, 0.0, 0.0, 0.0, 0.0, 1.0]}
    grid = Grid(10, 2 * np.pi, periodic=True)
    u = grid.coordinates(0)
    N = 0.3 * (0.5 + np.sin(u[:, None] + np.arange(G.dim)[None, :]))
    medium = QuadraticMedium(group, rest=np.eye(G.dim)[0] if G.dim > 1 else [0.5])
    problems = [Problem(medium, grid, InitialState(Phi=G.exp(u[:, None] * np.array(ring[group])), N=N),
                        loads=[Damping(0.2), UniformForce(np.linspace(-0.2, 0.3, G.dim))])]
    if derivative != "fourier":
        base = arc_problem(n=10, group=group, curvature=1.0, velocity=np.linspace(0.1, 0.3, G.dim))
        problems.append(Problem(medium, base.grid, base.initial, {"start": Clamped(), "end": Free(
            load=np.linspace(0.5, 1.0, G.dim), follower=False)}, [Damping(0.2)]))
    for problem in problems:
        for make in (LieVerlet, RKMK4):
            (ref, ri), (fast, fi) = run_both(Collocation(problem, derivative=derivative), make, 1e-3, 12, (5, 7))
            assert_close_states(fast, ref)
            assert fi.nforce == ri.nforce


@pytest.mark.slow
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
@pytest.mark.parametrize(("shape", "periodic"), [((8, 7), (True, True)), ((5, 4, 4), (False, True, False))],
                         ids=["d2-torus", "d3-mixed"])
def test_sigma_model_on_grids(scheme, shape, periodic):
    boundaries = {"u-end": Free(load=[0.1, 0.2, 0.0], follower=True)} if not periodic[0] else None
    sch = SCHEMES[scheme](sigma_problem(shape, periodic, boundaries))
    for make, dt, nsteps in (INTEGRATORS["lie-verlet"], INTEGRATORS["rkmk4"], (lambda: Overdamped(order=1), 2e-5, 10)):
        (ref, ri), (fast, fi) = run_both(sch, make, dt, nsteps)
        assert_close_states(fast, ref)
        assert fi.nstep == ri.nstep
