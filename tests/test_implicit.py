"""The ``implicit-midpoint`` integrator: order, geometry, conservation, stiff rods, failures."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from cartan_verification.stiff import stiff_rod
from toys import QuadraticMedium

import cartan
from cartan.integrators import RKMK4, LieVerlet
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.problem import InitialState
from cartan.schemes.lattice import Lattice
from cartan.simulate import InstabilityError, StabilityWarning
from cartan.statics import ConvergenceError
from cartan.study import observed_order

#: the integrator's physics through its Python driver: its compiled loop (≈ 1 min to compile on a
#: fresh cache) is checked against that driver in tests/test_implicit_compiled.py and
#: tests/test_implicit_loop.py
COMPILED = False


def _arc_rod(n: int = 9, free: bool = True) -> cartan.Problem:
    """The smooth rod of docs/integrators.md: a soft bent rod, spinning and translating."""
    rod = cartan.medium("cosserat-rod", E=1e4, G=1e4 / 3, radius=0.05, density=1000.0)
    grid = cartan.Grid(n, length=1.0)
    initial = rod.initial_state(grid, "arc", curvature=1.0, velocity=[0, 0.02, 0, 0.3, 0, 0.1])
    return cartan.Problem(rod, grid, initial, {} if free else {"start": cartan.Clamped()})


def _run(problem, integrator, dt: float, nsteps: int, track_frames: bool = False):
    scheme = Lattice(problem, track_frames=track_frames)
    scheme.compiled_diagnostics = COMPILED  # the residual in numpy (see COMPILED)
    state = scheme.initial_state()
    e0 = scheme.kinetic_energy(state) + scheme.potential_energy(state)
    energy_error = 0.0
    for _ in range(nsteps):
        integrator.step(scheme, state, dt)
        e = scheme.kinetic_energy(state) + scheme.potential_energy(state)
        energy_error = max(energy_error, abs(e - e0) / e0)
    return scheme, state, energy_error


def _energy(ds) -> np.ndarray:
    return ds["kinetic_energy"].values + ds["potential_energy"].values


# ---------------------------------------------------------------------------- accuracy and geometry
def test_second_order_in_time_and_stays_on_the_group():
    problem = _arc_rod()
    t_end = 0.02
    ref_scheme, ref_state, _ = _run(problem, RKMK4(), 2.5e-5, 800)
    reference = ref_scheme.frames(ref_state)
    G = problem.medium.group
    dts, errors = [4e-4, 2e-4, 1e-4], []
    for dt in dts:
        scheme, state, energy_error = _run(problem, ImplicitMidpoint(), dt, round(t_end / dt), track_frames=True)
        Phi = scheme.frames(state)
        errors.append(float(np.abs(G.log(G.compose(G.inverse(reference), Phi))).max()))
        # group membership and temporal integrability (stored edges against the stepped frames):
        # the drift is exact on the group, so both stay at round-off whatever the step
        assert float(np.max(G.defect(Phi))) < 1e-13
        assert scheme.integrability_residual(state) < 1e-12
        # energy: exact for the linearised problem (implicit midpoint conserves quadratic
        # invariants), so the error comes from the geometric nonlinearity, O((Δt·Ω)²) with
        # Ω ≈ 0.32 rad/s the angular speed of the rod (measured: 1.9e-9 at Δt = 4e-4, 0.12 of it)
        omega = float(np.linalg.norm(problem.initial.N[0, 3:]))
        assert energy_error <= (dt * omega) ** 2
    # the RKMK4 reference error (~1e-15) is far below the finest error (1.5e-7)
    p = observed_order(dts, errors)
    assert ImplicitMidpoint.order - 0.2 <= p <= ImplicitMidpoint.order + 0.3, (p, errors)


def test_time_reversible():
    """Symmetric method: Δt steps forward then −Δt steps back return to the start (Newton tolerance)."""
    problem = _arc_rod()
    scheme = Lattice(problem)
    state = scheme.initial_state()
    start = state.copy()
    integ = ImplicitMidpoint(tol=1e-13)
    for dt in [2e-3] * 10 + [-2e-3] * 10:
        integ.step(scheme, state, dt)
    G = problem.medium.group
    assert np.abs(G.log(G.compose(G.inverse(scheme.frames(start)), scheme.frames(state)))).max() < 1e-12
    assert np.abs(state.S - start.S).max() < 1e-10 * np.abs(start.S).max()


def test_momentum_maps_of_a_free_rod_are_conserved():
    """Σ w Ad_{Φ⁻¹}ᵀ S changes by J(Φ_k, R) per step, R the Newton residual: ‖R‖_* ≤ tol‖N‖_M, so
    over K steps the relative drift is bounded by about K·tol (here 50 steps, tol = 1e-12)."""
    problem = _arc_rod(n=11)
    scheme = Lattice(problem)
    state = scheme.initial_state()
    p0 = scheme.total_momentum(state)
    dt = 2 * LieVerlet().dt_max(scheme, state)  # beyond the explicit limit
    integ = ImplicitMidpoint(tol=1e-12)
    for _ in range(50):
        integ.step(scheme, state, dt)
    p1 = scheme.total_momentum(state)
    moved = np.abs(scheme.frames(state)[:, 1:, 0] - problem.initial.Phi[:, 1:, 0]).max()
    assert moved > 1e-3  # the rod moved (translation and spin)
    assert np.abs(p0[:3]).max() > 1e-3 and np.abs(p0[3:]).max() > 1e-3
    drift = np.abs(p1 - p0).max() / np.abs(p0).max()
    assert drift < 50 * 1e-12 * 10, drift
    # a loose tolerance is visible in the momentum: the bound is the solver's, not luck
    scheme2 = Lattice(problem)
    state2 = scheme2.initial_state()
    loose = ImplicitMidpoint(tol=1e-5)
    for _ in range(50):
        loose.step(scheme2, state2, dt)
    assert np.abs(scheme2.total_momentum(state2) - p0).max() / np.abs(p0).max() > drift


def test_energy_of_a_linear_problem_is_exact_at_any_step():
    """On SO(2) the lattice is a linear wave equation and the method is the classical implicit
    midpoint rule: the quadratic energy is conserved up to the Newton tolerance, each step
    changing it by ⟨N, R⟩ ≤ tol‖N‖²_M ≤ 2·tol·E, at 1000× the explicit limit."""
    med = QuadraticMedium("SO2", mass=[1.0], stiffness=[1e4], rest=[0.5])
    grid = cartan.Grid(41, length=1.0)
    u = grid.coordinates(0)
    G = med.group
    Phi = G.exp((0.5 * u + 0.05 * np.sin(2 * np.pi * u))[:, None])
    N = np.exp(-(((u - 0.5) / 0.1) ** 2))[:, None]
    problem = cartan.Problem(med, grid, InitialState(Phi=Phi, N=N))
    scheme = Lattice(problem)
    dt = 1000 * LieVerlet().dt_max(scheme, scheme.initial_state())
    tol, steps = 1e-12, 200
    _, _, energy_error = _run(problem, ImplicitMidpoint(tol=tol), dt, steps)
    assert energy_error <= 2 * steps * tol + 1e-12


def test_energy_balance_of_a_damped_linear_problem_closes():
    """Damping at the midpoint: for the linear (SO(2)) problem E_{k+1} − E_k = −Δt γ|N_{k+½}|²
    exactly, and the integrator books the dissipated power by the same midpoint rule, so
    K + V + D stays at E₀ to the Newton tolerance — with Δt·γ/m = 100 and Δt·ω_max = 1000."""
    from cartan.problem import Damping

    med = QuadraticMedium("SO2", mass=[1.0], stiffness=[1e4], rest=[0.5])
    grid = cartan.Grid(41, length=1.0)
    u = grid.coordinates(0)
    Phi = med.group.exp((0.5 * u + 0.05 * np.sin(2 * np.pi * u))[:, None])
    N = np.exp(-(((u - 0.5) / 0.1) ** 2))[:, None]
    undamped = cartan.Problem(med, grid, InitialState(Phi=Phi, N=N))
    dt = 1000 * LieVerlet().dt_max(Lattice(undamped), Lattice(undamped).initial_state())
    problem = cartan.Problem(med, grid, InitialState(Phi=Phi, N=N), loads=[Damping([100 / dt])])
    ds = cartan.simulate(problem, integrator="implicit-midpoint", integrator_options={"tol": 1e-12}, dt=dt,
                         t_end=100 * dt, save_every=10, progress=False, compiled=COMPILED)
    e = _energy(ds)
    assert ds["dissipated_energy"].values[-1] > 0.3 * e[0]  # a good part of the energy was dissipated
    balance = e + ds["dissipated_energy"].values - ds["external_work"].values
    assert np.abs(balance - e[0]).max() <= 1e-9 * e[0]


# ---------------------------------------------------------------------------- stiff rod
@pytest.fixture(scope="module")
def stiff():
    """A cantilever with radius 1e-3 ≪ dx = 0.05 in a bending motion, and the explicit limit:
    the CFL estimate 2/ω_max of lie-verlet (power iteration on the force Jacobian), set by
    the shear–rotation modes of the thin cross-sections (ω_max ≈ 3.5e4 rad/s)."""
    problem = stiff_rod(21, tip_speed=0.01)
    scheme = Lattice(problem)
    limit = float(LieVerlet().dt_max(scheme, scheme.initial_state()))
    assert 4e-5 < limit < 8e-5
    return problem, limit


def test_the_cfl_estimate_is_the_explicit_limit(stiff):
    problem, limit = stiff
    ds = cartan.simulate(problem, integrator="lie-verlet", dt=0.9 * limit, t_end=1000 * 0.9 * limit, progress=False)
    e = _energy(ds)
    assert np.abs(e - e[0]).max() < 0.01 * e[0]


@pytest.mark.parametrize("factor", [10, 100])
def test_stiff_rod_far_beyond_the_explicit_limit(stiff, factor, tmp_path):
    problem, limit = stiff
    dt = factor * limit
    steps = 200
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no StabilityWarning for an A-stable integrator
        ds = cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=steps * dt, save_every=5,
                             progress=False, compiled=COMPILED)
    assert int(ds["step"].values[-1]) == steps
    assert float(ds["group_defect"].max()) < 1e-12
    assert float(ds["integrability_residual"].max()) < 1e-12
    err = np.abs(_energy(ds) - _energy(ds)[0]) / _energy(ds)[0]
    # symplectic: bounded oscillation O((Δt·Ω)²), Ω = 0.02 rad/s the largest bending rotation
    # rate (measured 0.07 of it at 100×), plus the Newton tolerance; the stiff modes add
    # nothing (their linearised energy is exact) — and no drift from one half to the other
    omega = 2 * 0.01 / 1.0
    assert err.max() <= (dt * omega) ** 2 + 10 * 1e-10
    half = len(err) // 2
    assert err[half:].max() <= 1.5 * err[1: half + 1].max() + 1e-12
    tip = ds["position"].isel(node=-1).values
    assert np.all(np.isfinite(tip)) and np.abs(tip[:, 2]).max() < 1e-9 < np.abs(tip[:, 1]).max() < 0.05
    # lie-verlet at the same step blows up
    with pytest.warns(StabilityWarning), pytest.raises(InstabilityError):
        cartan.simulate(problem, integrator="lie-verlet", dt=dt, t_end=steps * dt, save_every=5, progress=False,
                        output=tmp_path / "explicit.nc")


def test_counters_include_the_jacobian_force_evaluations(stiff):
    problem, limit = stiff
    scheme = Lattice(problem)
    state = scheme.initial_state()
    integ = ImplicitMidpoint()
    for _ in range(5):
        integ.step(scheme, state, 10 * limit)
    assert integ.nstep == 5 and integ.jacobians >= 1 and integ.newton_iterations >= 5 and integ.wall_time > 0
    # one residual per step to start (two on the first: ΔtN_k and 0 are compared), one per
    # Newton iteration, and 2 per colour × component (3 colours × dim se(3) = 6) per
    # Jacobian; every residual is one force evaluation
    assert integ.nforce == integ.nstep + 1 + integ.newton_iterations + 2 * 3 * 6 * integ.jacobians
    integ.reset()
    assert (integ.nstep, integ.nforce, integ.newton_iterations, integ.jacobians) == (0, 0, 0, 0)


def test_restart_is_bit_for_bit(stiff, tmp_path):
    problem, limit = stiff
    dt = 10 * limit
    full = cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=40 * dt, save_every=5,
                           output=tmp_path / "full.nc", progress=False, compiled=COMPILED)
    cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=20 * dt, save_every=5,
                    output=tmp_path / "part.nc", progress=False, compiled=COMPILED)
    cont = cartan.simulate(problem, restart=tmp_path / "part.nc", t_end=40 * dt, progress=False, compiled=COMPILED)
    for name in ("S", "X", "position", "kinetic_energy", "potential_energy", "time"):
        assert np.array_equal(full[name].values, cont[name].values), name


@pytest.mark.slow  # the implicit residual of the planar rod and the sphere rod: ≈ 20 s to compile each
@pytest.mark.parametrize("medium, params, kind, init", [
    ("planar-cosserat-rod", {"E": 1e4, "G": 1e4 / 3, "radius": 0.05, "density": 1000.0}, "arc",
     {"curvature": 1.0, "velocity": [0.0, 0.05, 0.3]}),
    # the sphere rod's implicit blocks compile for ≈ 15 s on a fresh cache: make test-slow
    pytest.param("sphere-rod", {}, "perturbed", {"amplitude": 0.2}, marks=pytest.mark.slow),
])
def test_planar_rod_and_sphere_rod(medium, params, kind, init):
    med = cartan.medium(medium, **params)
    periodic = medium == "sphere-rod"
    grid = cartan.Grid(16 if periodic else 11, length=2 * np.pi if periodic else 1.0, periodic=periodic)
    problem = cartan.Problem(med, grid, med.initial_state(grid, kind, **init))
    scheme = Lattice(problem)
    state = scheme.initial_state()
    dt = 10 * LieVerlet().dt_max(scheme, state)
    p0 = scheme.total_momentum(state)
    integ = ImplicitMidpoint(tol=1e-12)
    for _ in range(30):
        integ.step(scheme, state, dt)
    assert float(np.max(med.group.defect(scheme.frames(state)))) < 1e-12
    assert np.abs(scheme.total_momentum(state) - p0).max() <= 1e-9 * max(np.abs(p0).max(), 1.0)
    assert state.is_finite()


# ---------------------------------------------------------------------------- bad input and failures
@pytest.mark.parametrize("options, name", [
    ({"tol": -1e-8}, "tol"), ({"tol": 0.0}, "tol"), ({"tol": 1.0}, "tol"), ({"tol": float("nan")}, "tol"),
    ({"max_iter": 0}, "max_iter"), ({"max_iter": 2.5}, "max_iter"), ({"max_iter": True}, "max_iter"),
    ({"fd_step": 0.0}, "fd_step"), ({"contraction": 1.0}, "contraction"), ({"reuse_jacobian": "yes"}, "reuse_jacobian"),
])
def test_bad_options_name_the_option(options, name):
    with pytest.raises(ValueError, match=name):
        ImplicitMidpoint(**options)


def test_bad_options_through_simulate(stiff):
    problem, limit = stiff
    with pytest.raises(ValueError, match=r"max_iter must be an integer ≥ 1"):
        cartan.simulate(problem, integrator="implicit-midpoint", integrator_options={"max_iter": 0}, dt=limit,
                        t_end=10 * limit, progress=False)


def test_newton_failure_is_a_clear_error_and_leaves_the_state(stiff):
    problem, limit = stiff
    scheme = Lattice(problem)
    state = scheme.initial_state()
    before = state.copy()
    with pytest.raises(ConvergenceError, match=r"implicit-midpoint: Newton's method did not converge.*max_iter = 1"):
        ImplicitMidpoint(max_iter=1).step(scheme, state, 100 * limit)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


def test_newton_failure_stops_simulate_with_the_last_good_state(stiff, tmp_path):
    problem, limit = stiff
    dt = 100 * limit

    class Failing(ImplicitMidpoint):
        """Newton's method limited to one iteration from the 8th step on (which needs more); a
        function of the step only, since a failed save block is run again from its start."""

        def _step(self, scheme, state, dt):
            self.max_iter = 1 if self.nstep >= 7 else 25
            super()._step(scheme, state, dt)

    path = tmp_path / "run.nc"
    with pytest.raises(InstabilityError, match=r"unstable at step 8 .*Newton's method did not converge") as info:
        cartan.simulate(problem, integrator=Failing(), dt=dt, t_end=50 * dt, save_every=5, output=path,
                        progress=False)
    assert info.value.path == cartan.io.lastgood_path(path) and info.value.step == 8
    saved = cartan.open(info.value.path)
    assert saved["step"].values.tolist() == [0, 5]  # the frames up to the last good state
    cont = cartan.simulate(problem, restart=info.value.path, t_end=10 * dt, progress=False)  # it continues from there
    assert cont["step"].values.tolist() == [0, 5, 10]


def test_large_dense_problems_are_refused_with_what_is_supported():
    rod = cartan.medium("cosserat-rod", E=1e4, G=1e4 / 3, radius=0.05, density=1000.0)
    grid = cartan.Grid(600, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"))
    scheme = cartan.registry("schemes")["collocation"](problem)
    with pytest.raises(ValueError, match=r"supports the 'lattice' scheme at any size.*3000 unknowns"):
        ImplicitMidpoint().step(scheme, scheme.initial_state(), 1e-3)
