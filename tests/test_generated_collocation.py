"""The collocation scheme's compiled operator set (:mod:`cartan.schemes._collocation_ops`) in
the integrators' generated loops, against the numpy reference path (``integrator.step``).

Tolerances: the operators evaluate the reference path's formulas in another order (and the
Fourier derivative as a dense circulant matrix instead of an FFT), so the two agree to
round-off; over the ≤ 12 steps here the observed relative differences are ≤ 1e-14, and
1e-12 (the project's compiled-vs-reference bound) leaves two digits of margin.

The difference rule and the boundary topology are data of the operator set: one generated
module per (group, medium kernels, d) serves fd2, fd4 and fourier.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import (
    CoupledQuartic,
    IndefiniteMetric,
    arc_problem,
    assert_close_states,
    chain_problem,
    rel_error,
    rod_problem,
)

import cartan
from cartan.grid import Grid
from cartan.problem import Clamped, Damping, Free, InitialState, Problem, UniformForce
from cartan.schemes.collocation import Collocation

TOL = 1e-12
SLOW = pytest.mark.slow


def _integrator(name: str):
    if name.startswith("overdamped"):
        return cartan.registry("integrators")["overdamped"](order=int(name[-1]))
    return cartan.registry("integrators")[name]()


def _compare(problem, name: str, nsteps: int = 10, dt: float = 1e-3, blocks=(6, 4), **scheme_options):
    """``nsteps`` steps of integrator ``name`` by ``integrator.step`` and, in ``blocks`` calls, by
    ``run_compiled_loop``: the states agree to ``TOL``; returns the scheme and both states."""
    scheme = Collocation(problem, **scheme_options)
    ops = scheme.compiled_operators()
    assert ops.ok, ops.reason
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, fast = start.copy(), start.copy()
    ref_integ, fast_integ = _integrator(name), _integrator(name)
    for _ in range(nsteps):
        ref_integ.step(scheme, ref, dt)
    for size in blocks:
        assert fast_integ.run_compiled_loop(scheme, fast, dt, size)
    assert sum(blocks) == nsteps
    assert_close_states(fast, ref, TOL)
    if not name.startswith("overdamped"):  # (the overdamped loop books its stage forces its own way)
        assert fast_integ.nforce == ref_integ.nforce
    return scheme, ref, fast


def _operators_agree(scheme, state) -> None:
    """``op_potential``, ``op_nodal_strains`` and ``op_kinetic`` against the reference."""
    ops = scheme.compiled_operators()
    module = ops.generated()
    C = ops.pack(state)
    K = module.op_work(ops.data)
    V = module.op_potential(ops.data, C, K)
    assert rel_error(V, scheme.potential_energy(state)) <= TOL
    X = np.empty((ops.nodes, scheme.grid.d, scheme.group.dim))
    module.op_nodal_strains(ops.data, C, X)
    assert np.array_equal(X, scheme.nodal_strains(state).reshape(X.shape))
    S = np.ascontiguousarray(state.S).reshape(ops.nodes, -1)
    assert rel_error(module.op_kinetic(ops.data, S), scheme.kinetic_energy(state)) <= TOL


def _sheet(derivative_shape=(9, 6), velocity=True):
    """The coupled quartic medium on SE(3), d = 2, a curved sheet (open × periodic) whose rest
    strain varies over the body (``reference``), clamped and follower-loaded faces, damping."""
    med = CoupledQuartic("SE3", d=2)
    G = med.group
    grid = Grid(derivative_shape, (1.0, 0.8), periodic=(False, True))
    U, V = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    Phi_ref = G.compose(G.exp(U[..., None] * np.array([1.0, 0, 0, 0, 0.3, 0])),
                        G.exp(np.sin(2 * np.pi * V / 0.8)[..., None] * np.array([0, 0.1, 0, 0.2, 0, 0])))
    rng = np.random.default_rng(1)
    Phi0 = G.compose(Phi_ref, G.exp(0.02 * np.sin(3 * U)[..., None] * rng.standard_normal(6)))
    N0 = 0.1 * np.cos(2 * np.pi * V / 0.8)[..., None] * np.linspace(1, 0.5, 6) if velocity else None
    return Problem(med, grid, InitialState(Phi=Phi0, N=N0), reference=Phi_ref,
                   boundaries={"u-start": Clamped(), "u-end": Free(load=[0, 0, 0.1, 0, 0, 0.05], follower=True)},
                   loads=[Damping(np.linspace(0.5, 1.0, 6))])


def _sigma(n: int, shape, periodic, boundaries=None):
    """The sigma model on Sⁿ (SO(n+1), gauge components without inertia) with its drag."""
    medium = cartan.medium("sigma-model", n=n, d=len(shape))
    grid = Grid(shape, 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    return Problem(medium, grid, init, boundaries or {}, [medium.make_load("drag", gamma=0.7)])


def _ring(group: str, n: int = 12):
    """A closed toy rod (periodic axis, no holonomy) with a smooth wave and a velocity."""
    base = arc_problem(n=n, group=group)
    G = base.medium.group
    grid = Grid(n, 1.0, periodic=True)
    u = grid.coordinates(0)
    xi = np.sin(2 * np.pi * u)[:, None] * np.linspace(0.3, 0.1, G.dim)
    N = np.cos(2 * np.pi * u)[:, None] * np.linspace(0.2, 0.1, G.dim)
    return Problem(base.medium, grid, InitialState(Phi=G.exp(xi), N=N), loads=[Damping(0.2)])


def _indefinite(n: int = 13):
    medium = IndefiniteMetric("SO13")
    G = medium.group
    grid = Grid(n, 1.0, periodic=True)
    u = grid.coordinates(0)
    wave = np.sin(2 * np.pi * u)[:, None] * np.linspace(0.05, 0.02, G.dim)
    return Problem(medium, grid, InitialState(Phi=G.exp(wave), N=np.cos(2 * np.pi * u)[:, None] * 0.1 * np.ones(6)))


# ---------------------------------------------------------------------------- fast set: one module each
@pytest.mark.parametrize("integrator", ["lie-verlet", pytest.param("rkmk4", marks=SLOW)])
@pytest.mark.parametrize("derivative", ["fd2", "fd4"])
def test_se3_rod_with_every_load_agrees(derivative, integrator):
    """SE(3) Cosserat rod, d = 1: clamped start, dead end load, damping, gravity (the frames are
    stepped); the loop and the operators outside it (potential with gravity, strains, K).
    ``make test`` runs lie-verlet, whose loop the collocation output tests compile too."""
    scheme, ref, fast = _compare(rod_problem("dead", n=11), integrator, derivative=derivative)
    assert scheme.track and scheme.compiled_operators().data.has_field
    _operators_agree(scheme, ref)


@pytest.mark.slow  # the Euler loop: ≈ 20 s to compile on a fresh cache
def test_se3_follower_rod_lie_euler_agrees():
    _compare(rod_problem("follower", n=11), "lie-euler", derivative="fd4")


@pytest.mark.slow  # the SO(2) rod's own loop (make test compiles the SE(3) rod's)
def test_abelian_rod_lie_verlet_agrees():
    """SO(2): one free-flow piece, so the loop's single move per step is the reference's drift."""
    problem = arc_problem(n=13, group="SO2", curvature=1.0, velocity=0.3)
    problem = Problem(problem.medium, problem.grid, problem.initial, loads=[Damping(0.1)],
                      boundaries={"start": Clamped(), "end": Free(load=[0.2], follower=True)})
    for derivative in ("fd2", "fd4"):
        _compare(problem, "lie-verlet", derivative=derivative)


@pytest.mark.slow  # a d = 2 collocation loop of its own: ≈ 10 s to compile on a fresh cache
def test_sigma_model_s2_d2_fourier_agrees():
    scheme, ref, _ = _compare(_sigma(2, (8, 6), (True, True)), "rkmk4", derivative="fourier")
    _operators_agree(scheme, ref)


@pytest.mark.slow
def test_coupled_quartic_sheet_with_reference_agrees():
    """Non-quadratic, axis-coupled energy on SE(3), d = 2, with a rest strain that varies over
    the body: fd2 and fd4 on an open × periodic sheet."""
    for derivative in ("fd2", "fd4"):
        scheme, ref, _ = _compare(_sheet(), "lie-euler", derivative=derivative)
        assert scheme.compiled_operators().data.x0step == 1
        _operators_agree(scheme, ref)


@pytest.mark.slow
def test_indefinite_nondiagonal_metric_agrees():
    problem = _indefinite()
    for derivative in ("fd2", "fourier"):
        scheme, ref, _ = _compare(problem, "rkmk4", dt=1e-3, derivative=derivative)
        assert not scheme.diagonal_metric
        _operators_agree(scheme, ref)


def test_free_flow_operator_is_the_reference_free_flow():
    """``op_free_flow``: lie-verlet's free flow piece by piece (every piece a momentum update and
    an exact drift), as ``LieVerlet._step`` takes it, on SE(3) (seven pieces)."""
    from cartan.integrators.explicit import _coAd_exp

    problem = rod_problem("dead", n=11)
    scheme = Collocation(problem)
    ops = scheme.compiled_operators()
    module = ops.generated()
    integ = _integrator("lie-verlet")
    seq = integ._sequence(scheme)
    state = scheme.initial_state()
    state.S = state.S + 0.1 * np.random.default_rng(0).standard_normal(state.S.shape)
    scheme.constrain(state)
    C = ops.pack(state)
    S = np.ascontiguousarray(state.S).reshape(ops.nodes, -1).copy()
    dt = 0.01
    pieces = np.ascontiguousarray([P for P, _ in seq])
    fracs = np.array([f for _, f in seq])
    Dn = np.empty((ops.nodes, 4, 4))
    assert module.op_free_flow(ops.data, C, S, pieces, fracs, dt, Dn, module.op_work(ops.data))
    for P, frac in seq:
        N = scheme.velocity(state)
        Np = np.zeros_like(N)
        Np[..., np.flatnonzero(np.diag(P))] = N[..., np.flatnonzero(np.diag(P))]
        state.S = _coAd_exp(scheme.group, frac * dt, Np, state.S)
        scheme.drift(state, frac * dt, Np)
    assert rel_error(S, state.S) <= TOL
    assert rel_error(C[0], state.arrays["X"].reshape(C[0].shape)) <= TOL
    assert rel_error(C[1], state.arrays["Phi"]) <= TOL


def test_data_layout():
    problem = _sheet()
    ops = Collocation(problem).compiled_operators()
    grid = problem.grid
    coords = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(2)], indexing="ij"), -1).reshape(-1, 2)
    assert ops.data.shape == (9, 6) and np.array_equal(ops.data.coords, coords)
    assert ops.nodes == 54 and tuple(ops.data.stride) == (6, 1)


def test_declined_problems_say_why():
    rod = arc_problem(n=9, group="SE3")
    spatial = Problem(rod.medium, rod.grid, rod.initial, loads=[UniformForce(np.ones(6), "spatial")])
    ops = Collocation(spatial).compiled_operators()
    assert not ops.ok and "UniformForce" in ops.reason
    assert "point kernels" in Collocation(chain_problem(n=9)).compiled_operators().reason
    untracked = Collocation(rod_problem("dead", n=11), track_frames=False).compiled_operators()
    assert not untracked.ok and "frames" in untracked.reason
    # the Fourier derivative as a dense circulant is O(n²): beyond 512 nodes the FFT of the
    # reference path is faster, so the set declines (and the same rod at 512 nodes qualifies)
    from cartan.schemes._collocation_ops import FOURIER_MAX_NODES

    for n, ok in ((FOURIER_MAX_NODES, True), (FOURIER_MAX_NODES + 1, False)):
        medium = cartan.medium("sphere-rod")
        grid = Grid(n, length=2 * np.pi, periodic=True)
        ring = Problem(medium, grid, medium.initial_state(grid, "perturbed", amplitude=0.2))
        ops = Collocation(ring, derivative="fourier").compiled_operators()
        assert ops.ok is ok, ops.reason
        assert ok or "Fourier" in ops.reason

    class Other(Collocation):
        def force(self, state, N, t):
            return super().force(state, N, t)

    assert "overrides force" in Other(rod).compiled_operators().reason
    scheme = Collocation(rod)
    assert scheme.compiled_operators() is scheme.compiled_operators()  # built once per scheme


# ---------------------------------------------------------------------------- slow: every integrator, more groups
ALL = ["rkmk4", "lie-euler", "forward-euler"]


@SLOW
@pytest.mark.parametrize("name", [*ALL, "overdamped1", "overdamped2"])
def test_se3_rod_every_integrator(name):
    # the stiff rod's gradient flow needs Δt·λ_max ≤ 2: λ_max ≈ 4e5 at n = 11, damping 0.1
    _compare(rod_problem("dead", n=11), name, dt=1e-6 if name.startswith("overdamped") else 1e-3)


@SLOW
@pytest.mark.parametrize("name", [*ALL, "overdamped1", "overdamped2"])
def test_se2_rod_every_integrator(name):
    _compare(rod_problem("follower", planar=True, n=11), name, derivative="fd4",
             dt=1e-6 if name.startswith("overdamped") else 1e-3)


@SLOW
@pytest.mark.parametrize("name", [*ALL, "overdamped2"])
def test_sigma_s2_every_integrator(name):
    _compare(_sigma(2, (9, 8), (False, True), {"u-start": Clamped(),
                                              "u-end": Free(load=[0.2, -0.1, 0.0], follower=True)}), name,
             derivative="fd4")


@SLOW
@pytest.mark.parametrize("name", ["rkmk4", "lie-euler", "overdamped1"])
def test_sigma_s3_d2_so4(name):
    _compare(_sigma(3, (8, 6), (True, False)), name)


@SLOW
@pytest.mark.parametrize("name", ["rkmk4", "forward-euler", "overdamped2"])
def test_coupled_quartic_sheet_every_integrator(name):
    _compare(_sheet(), name, derivative="fd4")


@SLOW
@pytest.mark.parametrize("derivative", ["fd2", "fourier"])
def test_sigma_d3(derivative):
    periodic = (True, True, True) if derivative == "fourier" else (False, True, False)
    _compare(_sigma(2, (5, 4, 4), periodic, None if derivative == "fourier" else {
        "w-end": Free(load=[0.1, 0.2, 0.0], follower=True)}), "rkmk4", derivative=derivative)


@SLOW
@pytest.mark.parametrize("group", ["SE2", "SE3", "SO3"])
def test_closed_rods_fourier(group):
    _compare(_ring(group), "rkmk4", derivative="fourier")


@SLOW
def test_se3_rod_lie_verlet_in_the_generated_loop():
    _compare(rod_problem("dead", n=11), "lie-verlet")
