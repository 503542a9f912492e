"""``implicit-midpoint`` with its compiled stage residual against the numpy reference.

``ImplicitMidpoint._residual`` (``Scheme.drift``, ``Scheme.force`` and batched group
operations) is the reference; the stage of ``cartan.integrators.newton`` evaluates the same
residual in one numba call over the scheme's compiled operator set.  The
pieces of the residual must agree to 1e-12 relative (round-off of the compiled kernels, which
differ from the numpy ones in summation order and closed forms); whole steps agree to the
Newton tolerance (both paths stop within it of the same stage solution); the reference path
is taken whenever the compiled one does not apply.
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_verification.stiff import stiff_rod
from toys import QuadraticMedium, rel_error, rod_problem

import cartan
from cartan import _backend
from cartan.grid import Grid
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.integrators.implicit import _stage as stage_residual
from cartan.problem import Clamped, Damping, InitialState, Problem, UniformForce
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

#: agreement of one residual evaluation: round-off of the compiled kernels (measured ≤ 3e-15)
TOL = 1e-12


class _Toy2(QuadraticMedium):
    """A coupled quadratic medium on a d = 2 grid (another rest strain per axis)."""

    name = "toy-quadratic-2d"
    material_dim = 2
    separable_axes = True

    def __init__(self, group: str):
        r = cartan.group(group).dim
        super().__init__(group, mass=np.linspace(1.0, 0.3, r))
        B = np.random.default_rng(3).standard_normal((r, r))
        self.C = B @ B.T + r * np.eye(r)
        self._set_energy(np.stack([np.eye(r)[0], np.linspace(-0.3, 0.2, r)]), self.C)


def _toy2_problem(group: str) -> Problem:
    medium = _Toy2(group)
    g = medium.group
    grid = Grid((7, 6), (1.0, 0.8), periodic=(False, True))
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    a, b = np.random.default_rng(5).standard_normal((2, g.dim))
    Phi = g.exp(u[..., None] * np.eye(g.dim)[0] + 0.3 * np.sin(2 * np.pi * u)[..., None] * a
                + 0.2 * np.cos(2 * np.pi * v)[..., None] * b)
    N = 0.3 * np.sin(2 * np.pi * (u + v))[..., None] * np.linspace(0.5, 1.0, g.dim)
    return Problem(medium, grid, InitialState(Phi=Phi, N=N), {"u-start": Clamped()}, [Damping(0.2)])


def _so2_problem() -> Problem:
    med = QuadraticMedium("SO2", mass=[1.0], stiffness=[1e2], rest=[0.5])
    grid = Grid(21, length=1.0)
    u = grid.coordinates(0)
    Phi = med.group.exp((0.5 * u + 0.05 * np.sin(2 * np.pi * u))[:, None])
    N = np.exp(-(((u - 0.5) / 0.1) ** 2))[:, None]
    return Problem(med, grid, InitialState(Phi=Phi, N=N), {"start": Clamped()}, [Damping([0.3])])


def _sphere_problem() -> Problem:
    med = cartan.medium("sphere-rod")
    grid = Grid(16, length=2 * np.pi, periodic=True)
    return Problem(med, grid, med.initial_state(grid, "perturbed", amplitude=0.2))


def _sigma_problem() -> Problem:
    """SO(3) on a d = 2 grid with a gauge component (zero inertia) and drag."""
    med = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((6, 5), 1.0, periodic=(True, False))
    init = med.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4, seed=1)
    return Problem(med, grid, init, {}, [med.make_load("drag", gamma=0.7)])


#: scheme factories and a Δt (a few times the explicit limit of each problem)
CASES = {
    "lattice-SE3-dead": (lambda: Lattice(rod_problem("dead")), 2e-2),
    "lattice-SE3-follower": (lambda: Lattice(rod_problem("follower")), 2e-2),
    "lattice-SE2-ring": (lambda: Lattice(rod_problem("ring", planar=True)), 2e-2),
    "lattice-SO3-sphere-rod": (lambda: Lattice(_sphere_problem()), 0.5),
    "lattice-SO2": (lambda: Lattice(_so2_problem()), 1.5e-2),
    "lattice-d2-SO3-sigma": (lambda: Lattice(_sigma_problem()), 2e-2),
    "lattice-d2-SE2": (lambda: Lattice(_toy2_problem("SE2")), 5e-2),
    "collocation-SE3-dead": (lambda: Collocation(rod_problem("dead")), 2.5e-2),
    "collocation-SE2-follower": (lambda: Collocation(rod_problem("follower", planar=True)), 2.5e-2),
}
#: ``make test`` compiles one implicit loop, the SE(3) rod's on the lattice (the stiff rods' of
#: tests/test_implicit_loop.py): every other problem's implicit blocks (30-60 s each on a fresh
#: cache) run in ``make test-slow``
SLOW_CASES = {name for name in CASES if not name.startswith("lattice-SE3-")}


def case_params(names):
    """``names`` as parameters, those of :data:`SLOW_CASES` (and the d = 2 SE(2) face loads,
    the same module) marked slow."""
    return [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_CASES or n.startswith("lattice-d2-SE2") else n
            for n in names]




def _moved_state(scheme):
    """The initial state after two reference steps (a state away from the initial data)."""
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    scheme.compiled_diagnostics = False
    integ = ImplicitMidpoint()
    for _ in range(2):
        integ.step(scheme, state, 1e-3)
    scheme.compiled_diagnostics = True
    return state


# ---------------------------------------------------------------------------- one residual
@pytest.mark.parametrize("name", case_params(sorted(CASES)))
def test_residual_matches_the_reference(name):
    make, _ = CASES[name]
    scheme = make()
    state = _moved_state(scheme)
    kernel = stage_residual(scheme)
    assert kernel is not None and kernel.accepts(state)
    kernel.bind(state)
    before = state.copy()
    rng = np.random.default_rng(7)
    for amplitude, dt in ((1e-3, 1e-3), (0.3, 2e-2)):  # the series and the closed-form branches
        xi = amplitude * rng.standard_normal(state.S.shape)
        ref = ImplicitMidpoint()._residual(scheme, state, xi, dt)
        fast = kernel(xi, dt)
        for key in ("W", "mu", "BW", "Dmu"):
            assert rel_error(fast[key], ref[key]) <= TOL, (key, rel_error(fast[key], ref[key]))
        # R is a difference of its terms: round-off relative to their size
        scale = np.abs(ref["Dmu"]).max() + dt * np.abs(ref["BW"]).max() + np.abs(state.S).max()
        assert np.abs(fast["R"] - ref["R"]).max() <= TOL * scale
        assert set(fast) == {"R", "W", "mu", "BW", "Dmu"} and fast["R"].shape == state.S.shape
    # the step's state is read, never written
    assert np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


@pytest.mark.parametrize("name", case_params(["lattice-SE3-dead", "lattice-SO2", "collocation-SE2-follower"]))
def test_outside_the_domain_of_exp_both_paths_decline(name):
    make, _ = CASES[name]
    scheme = make()
    state = _moved_state(scheme)
    kernel = stage_residual(scheme)
    kernel.bind(state)
    xi = np.zeros_like(state.S)
    g = scheme.group
    # a rotation by 3.2 rad > π (the injectivity radius) about one axis at one node
    xi.reshape(-1, g.dim)[3, g.dim - 1] = 3.2
    assert ImplicitMidpoint()._residual(scheme, state, xi, 1e-2) is None
    assert kernel(xi, 1e-2) is None
    xi.reshape(-1, g.dim)[3, g.dim - 1] = 3.1
    assert kernel(xi, 1e-2) is not None


# ---------------------------------------------------------------------------- whole steps
def _run(make, dt: float, compiled: bool, steps: int, tol: float):
    scheme = make()
    scheme.compiled_diagnostics = compiled
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    integ = ImplicitMidpoint(tol=tol)
    for _ in range(steps):
        integ.step(scheme, state, dt)
    return state, integ


@pytest.mark.parametrize("name", case_params(sorted(CASES)))
def test_steps_match_the_reference(name):
    """Both paths solve the same stage equation to the Newton tolerance, from iterates that
    differ by round-off: each step's state agrees to about tol (relative), and K steps of a
    stable method to about K·tol — far above round-off, far below any error in a formula."""
    make, dt = CASES[name]
    steps, tol = 10, 1e-10
    fast, fi = _run(make, dt, True, steps, tol)
    ref, ri = _run(make, dt, False, steps, tol)
    bound = 2 * steps * tol
    errors = {"S": rel_error(fast.S, ref.S)}
    errors.update({k: rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays})
    for key in ("dissipated_energy", "external_work"):
        errors[key] = abs(fast.scalars[key] - ref.scalars[key]) / max(abs(ref.scalars[key]), 1e-300)
    assert max(errors.values()) <= bound, errors
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"] == steps
    # the same Newton iterations, and every compiled residual counted as a force evaluation
    assert (fi.nstep, fi.nforce, fi.newton_iterations, fi.jacobians) == (ri.nstep, ri.nforce, ri.newton_iterations,
                                                                         ri.jacobians)


def test_simulate_compiled_false_is_the_reference(tmp_path):
    problem = stiff_rod(21, tip_speed=0.01)
    dt, steps = 5e-4, 40  # about 9 × the explicit limit of this rod
    runs = {c: cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=steps * dt, save_every=10,
                               compiled=c, progress=False) for c in (True, False)}
    for key in ("S", "position", "kinetic_energy", "potential_energy"):
        assert rel_error(runs[True][key].values, runs[False][key].values) <= 2 * steps * 1e-10, key
    assert np.array_equal(runs[True]["time"].values, runs[False]["time"].values)


@pytest.mark.slow  # the implicit loop of the SE(3) rod on collocation: ≈ 20 s to compile
def test_restart_is_bit_for_bit_on_the_compiled_path(tmp_path):
    make, dt = CASES["collocation-SE3-dead"]
    problem = make().problem
    kw = {"integrator": "implicit-midpoint", "dt": dt, "save_every": 4, "progress": False,
          "scheme": "collocation"}
    full = cartan.simulate(problem, t_end=16 * dt, output=tmp_path / "full.nc", **kw)
    cartan.simulate(problem, t_end=8 * dt, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(problem, restart=tmp_path / "part.nc", t_end=16 * dt, progress=False)
    for name in ("S", "X", "position", "kinetic_energy", "time"):
        assert np.array_equal(full[name].values, cont[name].values), name


# ---------------------------------------------------------------------------- which path
def test_the_compiled_path_does_not_call_the_reference(monkeypatch):
    make, dt = CASES["lattice-SE3-follower"]
    calls = []
    reference = ImplicitMidpoint._residual

    def counted(self, *args):
        calls.append(1)
        return reference(self, *args)

    monkeypatch.setattr(ImplicitMidpoint, "_residual", counted)
    _run(make, dt, True, 3, 1e-10)
    assert calls == []
    _, integ = _run(make, dt, False, 3, 1e-10)
    assert len(calls) == integ.nforce > 0


def test_without_a_compiled_plan_the_reference_runs():
    """A spatial (dead) uniform force is not among the loads of the compiled operator sets."""
    base = rod_problem("dead")
    problem = Problem(base.medium, base.grid, base.initial, {"start": Clamped()},
                      [UniformForce([0.0, -1.0, 0.0, 0.0, 0.0, 0.0], frame="spatial")])
    scheme = Lattice(problem)
    assert stage_residual(scheme) is None
    state = scheme.initial_state()
    ImplicitMidpoint().step(scheme, state, 1e-2)
    assert state.is_finite()


def test_numpy_backend_and_overridden_methods_use_the_reference():
    make, _ = CASES["lattice-SE3-dead"]
    scheme = make()
    state = scheme.initial_state()
    integ = ImplicitMidpoint()
    plan = integ._layout(scheme)
    assert integ._compiled(scheme, state, plan) is not None
    _backend.set_backend("numpy")
    try:
        assert integ._compiled(scheme, state, plan) is None
    finally:
        _backend.set_backend(None)

    class Custom(ImplicitMidpoint):
        def _residual(self, scheme, state, xi, dt):
            return super()._residual(scheme, state, xi, dt)

    custom = Custom()
    assert custom._compiled(scheme, state, custom._layout(scheme)) is None
    # a state with another layout (here an extra array) is left to the reference
    other = state.copy()
    other.arrays["extra"] = np.zeros(3)
    assert integ._compiled(scheme, other, plan) is None


def test_lu_solve_matches_superlu():
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from cartan.integrators.newton import LUSolve

    rng = np.random.default_rng(2)
    n = 300
    A = sp.random(n, n, density=0.02, random_state=rng) + sp.diags(5.0 + rng.random(n))
    A = A.tocsc()
    lu = spla.splu(A)
    b = rng.standard_normal(n)
    kernel = stage_residual(CASES["lattice-SO2"][0]())
    x = LUSolve(lu, kernel.module.im_lu_solve).solve(b)
    # the same factors, substituted in another order: round-off of a well-conditioned system
    assert rel_error(x, lu.solve(b)) <= 1e-13
    assert np.abs(A @ x - b).max() <= 1e-12 * np.abs(b).max()
