"""The lattice's compiled operator set covers the legacy lattice loops' problems, and the
diagnostics over any operator set (:mod:`cartan.compiled.diagnostics`) agree with the
reference path.

Steps: the generated loops are run directly (``Integrator.run_compiled_loop``; ``simulate``
takes the hand-written lattice loops first) on the gravity cantilever of ``make demo`` and on
clamped rods with dead and follower end loads, against ``Integrator.step`` on the numpy path.
Diagnostics: ``op_potential``, ``op_nodal_strains``, ``op_kinetic`` through
``guard_energies`` and the stiffness probe against ``Lattice.potential_energy``,
``Lattice.nodal_strains``, ``Scheme.kinetic_energy`` and the numpy probe, on an SE(3) rod
(d = 1, gravity, clamped, dead end load), the axis-coupled quartic toy on SE(3) (d = 2, corner
energies, a reference configuration), the sigma model on S³ (SO(4), d = 2) and a rod with an
indefinite, non-diagonal kinetic metric (SO(1,3)).

Tolerances
    ``TOL = 1e-12``: the operators evaluate the reference formulas in another order (and
    ``log(G)·(1/h)`` for ``log(G)/h``), a few ulps per value; over ≤ 30 steps the observed
    relative differences are about 1e-14, and 1e-12 is the project's compiled-vs-reference bound.
    The probe: both paths evaluate the same central difference at the same ε, so its
    truncation error cancels and they differ by the round-off of the two forces, about
    ``u·T`` with T the largest stress term a node sums (``cell/h · |Q| / w``) and u the unit
    round-off, divided by 2ε.  :func:`_probe_bound` states it with a factor 64 for the
    few dozen operations per term (observed factors up to 6).

Compile budget: four generated modules in ``make test`` (SE(3) × cosserat-rod d = 1, SE(3) ×
coupled quartic d = 2, SO(4) × sigma model d = 2, SO(1,3) × indefinite toy d = 1), each with
the diagnostics and, for the rod, the ``lie-verlet`` and ``rkmk4`` loops; the other
integrators and groups are marked ``slow``.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import CoupledQuartic, IndefiniteMetric, arc_problem, moving_rod, rel_error

import cartan
import cartan.compiled.diagnostics as diagnostics
from cartan.grid import Grid
from cartan.integrators import RKMK4, ForwardEuler, LieEuler, LieVerlet, Overdamped
from cartan.problem import Clamped, ConstantFieldPotential, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes.base import Scheme
from cartan.schemes.lattice import Lattice

TOL = 1e-12
U = np.finfo(float).eps


# ---------------------------------------------------------------------------- problems
def cantilever() -> Problem:
    """The ``make demo`` scene: a soft cantilever under gravity with damping."""
    return cartan.scene("rod-cantilever-gravity").problem


def rod(kind: str, gravity: bool = True, planar: bool = False, n: int = 11) -> Problem:
    """A Cosserat rod bent into an arc and moving, clamped at the start, with damping: a dead end
    load (``"dead"``), a follower end load and a body-frame force (``"follower"``), optionally
    under gravity."""
    medium = moving_rod(planar)
    r = medium.group.dim
    grid = Grid(n, length=1.0)
    init = medium.initial_state(grid, "arc", curvature=2.0, velocity=np.linspace(0.1, 0.3, r))
    loads = [Damping(np.linspace(0.1, 0.2, r))]
    if gravity:
        loads.append(medium.make_load("gravity", g=[0.0, -9.81, 0.0][: 2 if planar else 3]))
    follower = kind == "follower"
    if follower:
        loads.append(UniformForce(np.linspace(-0.2, 0.3, r)))
    boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=follower)}
    return Problem(medium, grid, init, boundaries, loads)


def coupled_sheet() -> Problem:
    """The axis-coupled quartic toy on SE(3), d = 2 (corner energies), open × periodic, with a
    curved reference configuration, a clamped face, a follower face load and damping."""
    med = CoupledQuartic("SE3", d=2)
    G = med.group
    grid = Grid((6, 5), (1.0, 0.8), periodic=(False, True))
    U_, V_ = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    Phi_ref = G.compose(G.exp(U_[..., None] * np.array([1.0, 0, 0, 0, 0.3, 0])),
                        G.exp(V_[..., None] * np.array([0, 1.0, 0, 0.5, 0, 0])))
    Phi0 = G.compose(Phi_ref, G.exp(0.02 * np.sin(3 * U_)[..., None] * np.linspace(1.0, -0.5, 6)))
    return Problem(med, grid, InitialState(Phi=Phi0), reference=Phi_ref, loads=[Damping(0.1)],
                   boundaries={"u-start": Clamped(), "u-end": Free(load=[0, 0, 0.1, 0, 0, 0.05], follower=True)})


def sigma_s3() -> Problem:
    """The sigma model on S³ (SO(4)), d = 2, on a torus."""
    medium = cartan.medium("sigma-model", n=3, d=2)
    grid = Grid((7, 6), 1.0, periodic=True)
    return Problem(medium, grid, medium.initial_state(grid, "random-smooth"))


def indefinite() -> Problem:
    """A closed rod on SO(1,3) with an indefinite, non-diagonal kinetic metric."""
    medium = IndefiniteMetric("SO13")
    G = medium.group
    grid = Grid(11, 1.0, periodic=True)
    u = grid.coordinates(0)
    wave = np.sin(2 * np.pi * u)[:, None] * np.linspace(0.05, 0.02, G.dim)
    return Problem(medium, grid, InitialState(Phi=G.exp(wave), N=np.cos(2 * np.pi * u)[:, None] * 0.1 * np.ones(6)))


CASES = {
    "rod-SE3-d1": lambda: rod("dead"),
}
#: in ``make test-slow``: each further group or medium compiles its own generated module (30-50 s on a
#: fresh cache); the coupled SE(3) energies run compiled in the fast suite through the shell and the
#: solid (tests/test_cosserat_surface.py, tests/test_cosserat_solid.py), SO(4) through
#: tests/test_generated_implicit.py and the indefinite Poincaré metric through the relativistic string
#: (tests/test_relativistic_rod.py)
SLOW_CASES = {
    "coupled-SE3-d2": coupled_sheet,
    "sigma-SO4-d2": sigma_s3,
    "indefinite-SO13-d1": indefinite,
    "rod-SE2-d1": lambda: rod("dead", planar=True),
    "quadratic-SO3-d1": lambda: arc_problem(n=9, group="SO3", curvature=1.0, velocity=np.linspace(0.1, 0.3, 3)),
}


def _cases():
    return ([pytest.param(name, id=name) for name in CASES]
            + [pytest.param(name, id=name, marks=pytest.mark.slow) for name in SLOW_CASES])


def _moved(scheme: Lattice, seed: int = 1):
    """A state off the initial one: every node drifted by a random motion, a random momentum."""
    state = scheme.initial_state()
    rng = np.random.default_rng(seed)
    scheme.drift(state, 0.05, rng.standard_normal(state.S.shape))
    state.S = state.S + 0.2 * rng.standard_normal(state.S.shape)
    scheme.constrain(state)
    state.t = 0.3
    return state


# ---------------------------------------------------------------------------- steps
def _run_both(problem, make, dt, nsteps, blocks):
    """The same steps by ``Integrator.step`` (numpy) and by ``run_compiled_loop`` in ``blocks``."""
    scheme = Lattice(problem)
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, fast = start.copy(), start.copy()
    ri, fi = make(), make()
    for _ in range(nsteps):
        ri.step(scheme, ref, dt)
    for size in blocks:
        assert fi.run_compiled_loop(scheme, fast, dt, size)
    assert sum(blocks) == nsteps
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"] == nsteps
    assert set(fast.arrays) == set(ref.arrays)
    errors = {"S": rel_error(fast.S, ref.S)}
    errors.update({k: rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays})
    for key in ("dissipated_energy", "external_work"):
        errors[key] = rel_error(fast.scalars[key], ref.scalars[key])
    assert max(errors.values()) <= TOL, errors
    assert fi.nstep == ri.nstep
    if ri.uses_momentum:  # the overdamped loop counts its stage forces its own way
        assert fi.nforce == ri.nforce
    # the run moved: the comparison is not between two unchanged states
    assert rel_error(fast.S, start.S) > 1e-6
    return scheme, ref, fast


def test_gravity_cantilever_scene_runs_generated_and_agrees():
    """The ``make demo`` scene (gravity, damping, clamped start) in the generated ``lie-verlet``
    loop, 30 steps of its Δt, against the numpy path; the potential includes gravity's."""
    problem = cantilever()
    assert any(isinstance(ld, ConstantFieldPotential) for ld in problem.loads)
    scheme, ref, fast = _run_both(problem, LieVerlet, 2e-3, 30, (1, 29))
    assert scheme.compiled_operators().ok
    ops = scheme.compiled_operators()
    module = ops.generated()
    V = module.op_potential(ops.data, ops.pack(fast), module.op_work(ops.data))
    assert rel_error(V, scheme.potential_energy(fast)) <= TOL
    # released from rest, the rod falls: gravity did work (the potential decreased)
    assert scheme.potential_energy(ref) < scheme.potential_energy(scheme.initial_state())


@pytest.mark.parametrize("make", [pytest.param(LieVerlet, id="lie-verlet"), pytest.param(RKMK4, id="rkmk4")])
@pytest.mark.parametrize("kind", ["dead", "follower"])
def test_clamped_rod_with_end_loads_runs_generated_and_agrees(kind, make):
    """Clamped start, dead or follower end load (and a body-frame force), damping, gravity."""
    _run_both(rod(kind), make, 1e-3, 20, (3, 17))


@pytest.mark.slow
@pytest.mark.parametrize("make", [LieEuler, ForwardEuler, lambda: Overdamped(order=1), lambda: Overdamped(order=2)],
                         ids=["lie-euler", "forward-euler", "overdamped-1", "overdamped-2"])
@pytest.mark.parametrize("planar", [False, True], ids=["SE3", "SE2"])
@pytest.mark.parametrize("kind", ["dead", "follower"])
def test_every_integrator_on_loaded_rods(kind, planar, make):
    dt = 2e-6 if make not in (LieEuler, ForwardEuler) else 1e-5
    _run_both(rod(kind, planar=planar), make, dt, 10, (4, 6))


def test_constant_field_force_is_the_pull_back():
    """The field's force is ``Rᵀρf`` on the translations (zero at the clamped node): compiled
    force with and without the field, against each other and the reference."""
    with_field, without = Lattice(rod("dead")), Lattice(rod("dead", gravity=False))
    ops = with_field.compiled_operators()
    assert ops.ok and ops.data.has_field
    module = ops.generated()
    state = _moved(with_field)
    n, r = ops.nodes, 6
    N = np.ascontiguousarray(with_field.velocity(state).reshape(n, r))
    W, W0 = np.empty((n, r)), np.empty((n, r))
    module.op_force(ops.data, ops.pack(state), 0.0, N, W, module.op_work(ops.data))
    ops0 = without.compiled_operators()
    ops0.generated().op_force(ops0.data, ops0.pack(state), 0.0, N, W0, ops0.generated().op_work(ops0.data))
    Phi = state.arrays["Phi"]
    gravity = with_field.problem.loads[1]
    pulled = np.zeros((n, r))
    pulled[:, :3] = np.einsum("nji,j->ni", Phi[:, 1:, 1:], gravity.density * gravity.field)
    pulled[0] = 0.0
    assert np.max(np.abs(pulled)) > 1.0
    # W and W0 carry round-off of their own size: the difference is the pull-back to that
    assert np.max(np.abs(W - W0 - pulled)) <= TOL * np.max(np.abs(W))
    assert rel_error(W, with_field.force(state, N.reshape(state.S.shape), 0.0).reshape(n, r)) <= TOL


class _Tilted(ConstantFieldPotential):
    """A field load that changes its gradient: not the core's constant field."""

    def potential_gradient(self, q):
        return 2.0 * super().potential_gradient(q)


def test_loads_it_does_not_run_are_declined_with_a_reason():
    base = rod("dead", gravity=False)
    medium = base.medium

    def declined(loads, **options):
        ops = Lattice(Problem(medium, base.grid, base.initial, base.boundaries, loads), **options).compiled_operators()
        assert not ops.ok
        return ops.reason

    assert "UniformForce" in declined([UniformForce(np.ones(6), frame="spatial")])
    assert "ConstantFieldPotential" in declined([_Tilted([0.0, 0.0, -1.0], 2.0)])
    free = {"end": Free()}
    ops = Lattice(Problem(medium, base.grid, base.initial, free, [ConstantFieldPotential([0.0, 0.0, -1.0], 2.0)]),
                  track_frames=False).compiled_operators()
    assert not ops.ok and "frames" in ops.reason


# ---------------------------------------------------------------------------- diagnostics
def _probe_bound(scheme: Lattice, state, eps: float) -> float:
    """The round-off of the probe's central difference (see the module docstring): 64 u T/(2ε)
    with T the largest stress term ``(cell/h_α)|Q|/w`` a node sums, Q at the nodal strains."""
    Q = np.asarray(scheme.medium.stress(scheme.nodal_strains(state)), dtype=float)
    cell = float(np.prod(scheme.h))
    T = float(np.max(np.abs(Q))) * cell / min(scheme.h) / float(np.min(scheme.weights))
    return 64 * U * max(T, 1.0) / (2 * eps)


@pytest.mark.parametrize("name", _cases())
def test_energies_and_nodal_strains_match_the_reference(name):
    problem = (CASES | SLOW_CASES)[name]()
    scheme = Lattice(problem)
    ops = scheme.compiled_operators()
    assert ops.ok, ops.reason
    module = ops.generated()
    state = _moved(scheme)
    n, d, r = ops.nodes, scheme.grid.d, scheme.group.dim
    V = module.op_potential(ops.data, ops.pack(state), module.op_work(ops.data))
    assert rel_error(V, scheme.potential_energy(state)) <= TOL
    X = np.empty((n, d, r))
    module.op_nodal_strains(ops.data, ops.pack(state), X)
    assert rel_error(X, scheme.nodal_strains(state).reshape(n, d, r)) <= TOL
    K_ref = scheme.kinetic_energy(state)
    # the indefinite metric's K is a difference of terms of both signs: relative to their size
    scale = float(np.sum(np.abs(scheme.weights * np.einsum("...k,kl,...l->...", state.S, np.abs(
        scheme.inverse_metric), np.abs(state.S)))))
    K = module.op_kinetic(ops.data, np.ascontiguousarray(state.S.reshape(n, r)))
    assert abs(K - K_ref) <= TOL * max(abs(K_ref), 0.5 * scale)
    assert diagnostics.guard_energies(scheme, state) == (K, V)
    # the layout of the problem
    assert ops.data.shape == tuple(scheme.grid.shape)
    coords = np.stack(np.meshgrid(*[scheme.grid.coordinates(a) for a in range(d)], indexing="ij"), -1)
    assert np.array_equal(ops.data.coords, coords.reshape(n, d))


@pytest.mark.slow  # the SO(1,3) operator set's energies: ≈ 12 s to compile on a fresh cache
def test_kinetic_energy_of_a_nondiagonal_metric_is_the_reference():
    """½Σ w S·M⁺S, not the diagonal's ½Σ w S²/|m|: the two differ for the indefinite toy."""
    scheme = Lattice(indefinite())
    state = _moved(scheme)
    K, _ = diagnostics.guard_energies(scheme, state)
    S = state.S
    diagonal = 0.5 * float(np.sum(scheme.weights[:, None] * S * S * np.abs(np.diag(scheme.inverse_metric))))
    assert abs(K - scheme.kinetic_energy(state)) <= TOL * diagonal
    assert abs(K - diagonal) > 1e-3 * diagonal


@pytest.mark.parametrize("name", _cases())
def test_stiffness_probe_matches_the_numpy_probe(name, monkeypatch):
    """``Scheme.stiffness_probe`` takes the generated probe (no numpy force or drift call) and
    agrees with the numpy probe to its round-off (:func:`_probe_bound`); the state is untouched."""
    scheme = Lattice((CASES | SLOW_CASES)[name]())
    scheme.compiled_diagnostics_from = 0  # the compiled probe on a small problem too
    state = _moved(scheme)
    before = state.copy()
    v = np.random.default_rng(2).standard_normal(state.S.shape)
    calls = []
    real_force, real_drift = scheme.force, scheme.drift
    monkeypatch.setattr(scheme, "force", lambda *a, **k: calls.append("force") or real_force(*a, **k))
    monkeypatch.setattr(scheme, "drift", lambda *a, **k: calls.append("drift") or real_drift(*a, **k))
    for eps in (1e-7, 1e-4):
        fast = scheme.stiffness_probe(state, eps)(v)
        assert calls == []
        scheme.compiled_diagnostics = False
        ref = scheme.stiffness_probe(state, eps)(v)
        scheme.compiled_diagnostics = True
        assert calls
        calls.clear()
        assert fast.shape == ref.shape and np.max(np.abs(ref)) > 0
        assert np.max(np.abs(fast - ref)) <= _probe_bound(scheme, state, eps), eps
    assert state.t == before.t and np.array_equal(state.S, before.S)
    for key in before.arrays:
        assert np.array_equal(state.arrays[key], before.arrays[key]), key


def test_diagnostics_decline_without_an_operator_set():
    """No operator set (a group without point kernels), the numpy backend, or diagnostics
    switched off: None, and the reference methods are used."""
    so5 = arc_problem(n=7, group=cartan.group("SO", n=5))
    scheme = Lattice(so5)
    state = scheme.initial_state()
    assert not scheme.compiled_operators().ok
    assert diagnostics.guard_energies(scheme, state) is None
    assert diagnostics.compiled_stiffness_probe(scheme, state, 1e-7) is None
    ok = Lattice(rod("dead"))
    state = ok.initial_state()
    with cartan.use_backend("numpy"):
        assert diagnostics.guard_energies(ok, state) is None
    ok.compiled_diagnostics = False
    assert diagnostics.guard_energies(ok, state) is None
    assert diagnostics.compiled_stiffness_probe(ok, state, 1e-7) is None


def test_overridden_energy_methods_are_declined():
    class Mine(Lattice):
        def potential_energy(self, state):
            return 0.0

    scheme = Mine(rod("dead"))
    assert scheme.compiled_operators().ok
    assert diagnostics.guard_energies(scheme, scheme.initial_state()) is None


@pytest.mark.slow
def test_simulate_guard_uses_the_generated_energies(monkeypatch):
    """``cartan.simulate``'s blow-up guard takes its energies from ``guard_energies`` when the
    operator set's loops take the steps (no hand-written plan: an axis-coupled medium)."""
    results = []
    real = diagnostics.guard_energies
    monkeypatch.setattr(diagnostics, "guard_energies", lambda *a: results.append(real(*a)) or results[-1])
    monkeypatch.setattr(Scheme, "compiled_diagnostics_from", 0)  # a small sheet
    problem = coupled_sheet()
    assert not Lattice(problem).has_hand_written_loops()
    cartan.simulate(problem, integrator="lie-verlet", dt=1e-4, t_end=8e-4, save_every=4, progress=False)
    assert results and all(res is not None for res in results)
