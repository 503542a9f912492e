"""A driven end (:class:`cartan.Driven`): a clamp moving with a prescribed constant body velocity ξ.

The end's frame is Φ(0)·exp(tξ) to round-off; a twist driven at rate ω into a rod of twist
stiffness C and polar inertia J sends a torsional wave whose torque at the end is the impedance
√(CJ)·ω (c = √(C/J)); the reaction's work (``external_work``) closes the energy balance to the
integrator's order; the integrators and schemes that cannot move the end exactly refuse it.
The runs here take the numpy path (``compiled=False``): the compiled driven loops are checked
against it in tests/test_driven_compiled.py (slow: each compiles on first use).
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.integrators.explicit import LieVerlet
from cartan.schemes.lattice import Lattice


def _rod(C: float = 1.0, J: float = 1.0):
    # stretch and shear 4: waves of speed 2, a twist wave of speed √(C/J)
    return cartan.medium("cosserat-rod", stretch_shear=[4.0, 4.0, 4.0], bend_twist=[C, 1.0, 1.0], mass=1.0,
                         rotational_inertia=[J, 0.5, 0.5])


def _problem(xi, n: int = 21, loads=(), C: float = 1.0, J: float = 1.0) -> cartan.Problem:
    rod = _rod(C, J)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Driven(velocity=xi)}, loads=list(loads))


def _exact_end(problem: cartan.Problem, xi: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Φ(0)·exp(tξ) of the end node, ``[time, 4, 4]``."""
    g = problem.medium.group
    return np.einsum("ij,tjk->tik", problem.initial.Phi[-1], g.exp(t[:, None] * xi[None, :]))


TWIST = np.array([0.0, 0.0, 0.0, 0.7, 0.0, 0.0])
SCREW = np.array([0.1, -0.2, 0.05, 0.3, -0.4, 0.5])


def assert_twist_impedance(scheme, integrator, n: int, C: float, J: float, om: float, dt: float = 2e-3,
                           steps: int = 950) -> None:
    """Step ``scheme`` from its initial state; at every step the supports act on their own nodes
    only, and the driven end's torque about d₁ is the torsional impedance's
    (:func:`assert_torsional_impedance`)."""
    state = scheme.initial_state()
    torque, times = [], []
    for _ in range(steps):
        integrator.step(scheme, state, dt)
        R = scheme.support_reaction(state)
        torque.append(R[-1, 3])
        times.append(state.t)
        assert np.all(R[1:-1] == 0.0)  # the supports act on their own nodes only
    assert_torsional_impedance(torque, times, state, n, C, J, om)


def assert_torsional_impedance(torque, times, state, n: int, C: float, J: float, om: float) -> None:
    """Before the reflection returns (t < 2 on a unit rod with c = 1), the end twisted at rate ω
    feels the torque √(CJ)ω of the torsional wave and has done the work √(CJ)ω²t: both to the
    resolution h = 1/(n − 1) (the wave front spreads over a few edges)."""
    torque, times = np.asarray(torque), np.asarray(times)
    impedance = np.sqrt(C * J) * om
    window = (times > 0.5) & (times < 1.9)
    h = 1.0 / (n - 1)
    assert abs(np.mean(torque[window]) / impedance - 1.0) < h
    assert state.scalars["external_work"] == pytest.approx(impedance * om * state.t, rel=h)


@pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")  # lie-euler: no stable Δt for undamped motion
@pytest.mark.parametrize(("integrator", "xi"), [("lie-verlet", TWIST), ("lie-euler", SCREW), ("rkmk4", SCREW),
                                                 ("lie-verlet", np.array([0.2, 0.1, -0.3, 0.0, 0.0, 0.0]))])
def test_the_driven_end_moves_by_exp_t_xi(integrator, xi):
    """At every saved time the end's frame and position are Φ(0)exp(tξ) to round-off: each step
    moves it by exp(Δtξ) (lie-verlet: ξ in one commuting block of its free flow).  200 steps, 20
    edge products to rebuild the end frame: round-off ≲ 200·20·ε·|ξ|t ≈ 1e-12."""
    problem = _problem(xi)
    ds = cartan.simulate(problem, integrator=integrator, dt=2e-3, t_end=0.4, save_every=20, progress=False,
                         compiled=False)
    t = ds.time.values
    exact = _exact_end(problem, xi, t)
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - exact[:, 1:, 0])) < 1e-12
    assert np.max(np.abs(ds.N.values[:, -1] - xi)) == 0.0  # the end's velocity is ξ at every save
    assert np.max(np.abs(ds.frame.values[:, -2] - exact[:, 1:, 1:])) > 1e-4  # its neighbour lags behind


def test_a_surface_edge_turns_about_its_own_line():
    """A plate's edge u = L driven by a rotation about the edge line (body e₂ = the v axis): each
    of its nodes turns by Φᵢ(0)exp(tξ), a rigid rotation of the edge about its line (its nodes on
    the axis stay put); the reaction's work closes the balance (lie-verlet, second order: 4e-11 of
    a work 1.5e-5 measured; bound 1e-3 of the work)."""
    shell = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.1, density=1.0)
    grid = cartan.Grid((9, 5), length=(1.0, 0.5))
    xi = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
    problem = cartan.Problem(shell, grid, shell.initial_state(grid, "flat"),
                             {"u-start": cartan.Clamped(), "u-end": cartan.Driven(velocity=xi)})
    ds = cartan.simulate(problem, integrator="lie-verlet", dt=2e-3, t_end=0.4, save_every=50, progress=False,
                         compiled=False)
    t = ds.time.values
    exact = np.einsum("vij,tjk->tvik", problem.initial.Phi[-1], shell.group.exp(t[:, None] * xi))
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, :, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - ds.position.values[0, -1])) < 1e-12
    E = ds.kinetic_energy.values + ds.potential_energy.values - ds.external_work.values
    assert ds.external_work.values[-1] > 0.0
    assert np.max(np.abs(E - E[0])) < 1e-3 * ds.external_work.values[-1]


def test_the_torque_of_a_driven_twist_is_the_torsional_impedance():
    """A twist at rate ω into a straight rod at rest: the wave θ(s, t) = ω(t − (L − s)/c) leaves
    the driven end with π₁ = ω/c, so the reaction's torque is C·ω/c = √(CJ)·ω until the
    reflection from the clamp returns at t = 2L/c (c = 1, L = 1: t = 2).  Its mean over
    t ∈ [0.5, 1.9] agrees to h/L = 1e-2 (the lattice's resolution; measured 2e-5); the external
    work booked from it is √(CJ)ω²t likewise."""
    C, J, om, n = 1.0, 1.0, 0.1, 101
    problem = _problem([0.0, 0.0, 0.0, om, 0.0, 0.0], n=n, C=C, J=J)
    assert_twist_impedance(Lattice(problem), LieVerlet(), n, C, J, om)


def test_the_reaction_closes_the_energy_balance_to_second_order():
    """Twisting a rod that sags under gravity (bending and twist couple, nonlinear): the
    reaction's work booked as ``external_work`` equals the change of K + V to lie-verlet's order,
    the error quartering with Δt (ratio 4 ± 0.6)."""
    errors = []
    for dt in (4e-3, 2e-3):
        gravity = _rod().make_load("gravity", g=[0.0, 0.0, -2.0])
        problem = _problem([0.0, 0.0, 0.0, 2.0, 0.0, 0.0], loads=[gravity])
        ds = cartan.simulate(problem, integrator="lie-verlet", dt=dt, t_end=0.8, save_every=int(round(0.1 / dt)),
                             progress=False, compiled=False)
        E = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
        W = ds.external_work.values
        assert W[-1] > 0.1  # the end does work
        errors.append(float(np.max(np.abs(E - E[0] - W))))
    assert errors[0] / errors[1] == pytest.approx(4.0, abs=0.6)


def test_restart_is_bit_for_bit(tmp_path):
    """A run with a driven end continued from its checkpoint is the uninterrupted run, bit for
    bit (the end's momentum is set from ξ after every kick; the external work carries on)."""
    assert_restart_is_exact(_problem(TWIST), tmp_path, "lie-verlet", 2e-3, 0.04)


def assert_restart_is_exact(problem, tmp_path, integrator: str, dt: float, t_end: float) -> None:
    """The run to ``t_end`` and the run to ``t_end/2`` continued from its checkpoint give the same
    positions, frames, momenta, strains, kinetic energy and external work, bit for bit."""
    kw = dict(integrator=integrator, dt=dt, save_every=5, checkpoint_every=1, progress=False, compiled=False)
    whole = cartan.simulate(problem, t_end=t_end, output=tmp_path / "whole.nc", **kw)
    cartan.simulate(problem, t_end=t_end / 2, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(problem, restart=tmp_path / "part.nc", t_end=t_end, progress=False, compiled=False)
    for name in ("position", "frame", "S", "X", "kinetic_energy", "external_work"):
        assert np.array_equal(whole[name].values, cont[name].values), name


@pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")
@pytest.mark.parametrize(("integrator", "options"), [("forward-euler", {})])
def test_integrators_that_cannot_move_the_end_exactly_refuse_it(integrator, options):
    problem = _problem(TWIST)
    with pytest.raises(ValueError, match=f"integrator '{integrator}' does not take Driven ends"):
        cartan.simulate(problem, integrator=integrator, dt=1e-3, t_end=2e-3, progress=False, **options)


def test_lie_verlet_refuses_a_velocity_across_its_split_free_flow():
    """A screw (translation and rotation about different axes) lies across lie-verlet's commuting
    blocks: the split flow would move the end by a product of exponentials, not exp(Δtξ)."""
    with pytest.raises(ValueError, match="integrator 'lie-verlet' does not take Driven ends: the driven velocity"):
        cartan.simulate(_problem(SCREW), integrator="lie-verlet", dt=1e-3, t_end=2e-3, progress=False, compiled=False)


def test_the_compiled_paths_decline():
    """(collocation moves a driven end on its numpy path: tests/test_collocation_driven.py)"""
    scheme = Lattice(_problem(TWIST))
    ops = scheme.compiled_operators()
    assert not ops.ok and "Driven" in ops.reason


@pytest.mark.parametrize(("velocity", "match"), [
    (None, "velocity must be given"), ("fast", "velocity must be a real number"),
    ([0.0, np.nan, 0.0], "velocity must be finite"), ([[0.0, 1.0]], "velocity must be a vector"),
])
def test_a_malformed_velocity_is_refused(velocity, match):
    with pytest.raises(ValueError, match=match):
        cartan.Driven(velocity=velocity)


def test_a_velocity_of_the_wrong_length_names_the_end():
    with pytest.raises(ValueError, match=r"boundaries\['end'\]\.velocity must have shape \(6,\)"):
        _problem([0.0, 0.0, 0.0, 1.0])


_SCENE = ('medium = "cosserat-rod"\n[parameters]\nstretch_shear = [4.0, 4.0, 4.0]\nbend_twist = [1.0, 1.0, 1.0]\n'
          'mass = 1.0\nrotational_inertia = [1.0, 0.5, 0.5]\n[grid]\nn = 21\nlength = 1.0\n[initial]\n'
          'kind = "straight"\n[boundaries]\nstart = {{ kind = "clamped" }}\nend = {{ kind = "driven"{extra} }}\n'
          '[run]\nintegrator = "lie-verlet"\ndt = 2e-3\nt_end = 0.1\nsave_every = 10\n')


def test_a_scene_drives_an_end(tmp_path):
    """``{ kind = "driven", velocity = [...] }``: the same run as the Python ``Driven`` end, bit
    for bit; a malformed or missing velocity is a scene error naming it."""
    path = tmp_path / "driven.toml"
    path.write_text(_SCENE.format(extra=", velocity = [0.0, 0.0, 0.0, 0.7, 0.0, 0.0]"))
    scene = cartan.load_scene(path)
    assert isinstance(scene.problem.boundaries["end"], cartan.Driven)
    ds = scene.simulate(progress=False, compiled=False)
    ref = cartan.simulate(_problem(TWIST), integrator="lie-verlet", dt=2e-3, t_end=0.1, save_every=10,
                          progress=False, compiled=False)
    assert np.array_equal(ds.frame.values, ref.frame.values)
    assert scene.problem.to_dict()["boundaries"]["end"] == {"kind": "driven", "velocity": TWIST.tolist()}
    for extra, match in [("", r"boundaries\.end\.velocity"), (', velocity = "up"', r"boundaries\.end\.velocity"),
                         (", velocity = [0, 0, 0, 1], load = 1", r"boundaries\.end\.load: unknown key")]:
        path.write_text(_SCENE.format(extra=extra))
        with pytest.raises(cartan.SceneError, match=match):
            cartan.load_scene(path)


def test_the_twist_buckling_scene_reads_and_twists_its_end():
    """The registered scene ``rod-twist-buckling``: clamped at s = 0, driven at s = L about d₁ at
    ω = 2; over its first 100 steps the end's frame is exp(tξ) to round-off and the twist stored
    along the rod is the end's angle, Σ π₁h = ωt — exact for a straight rod (twists about one
    axis add up), here to second order in the seed force's bending (≈ 1e-4: bound 1e-6, measured
    6e-9)."""
    sc = cartan.scene("rod-twist-buckling")
    end = sc.problem.boundaries["end"]
    assert isinstance(end, cartan.Driven) and end.velocity.tolist() == [0.0, 0.0, 0.0, 2.0, 0.0, 0.0]
    assert isinstance(sc.problem.boundaries["start"], cartan.Clamped)
    ds = cartan.simulate(sc.problem, integrator="lie-verlet", dt=1.5e-3, t_end=0.15, save_every=50, progress=False,
                         compiled=False)
    h = 1.0 / (sc.problem.grid.shape[0] - 1)
    twist = h * ds.X.values[:, :, 3].sum(axis=1)
    assert np.max(np.abs(twist - 2.0 * ds.time.values)) < 1e-6
    assert twist[-1] > 0.29
    exact = _exact_end(sc.problem, end.velocity, ds.time.values)
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12


@pytest.mark.parametrize(("integrator", "order"), [("overdamped", 1), ("overdamped", 2), ("implicit-midpoint", None)])
def test_overdamped_and_implicit_midpoint_move_the_end_by_exp_t_xi(integrator, order):
    """overdamped (Lie–Euler and Heun's RKMK2: N = ξ at the driven node in every stage) and
    implicit-midpoint (ξ_step = Δtξ there, no unknown of Newton's method) move the end by
    exp(Δtξ) per step: its frame and position are Φ(0)exp(tξ) to round-off (200 steps: bound
    1e-12, measured 1e-14) while its neighbour lags behind."""
    from cartan.integrators.explicit import Overdamped

    loads = [cartan.Damping([10.0] * 6)] if integrator == "overdamped" else []  # (drag 10: Δt = 2e-3 is stable)
    problem = _problem(SCREW, loads=loads)
    integ = Overdamped(order=order) if integrator == "overdamped" else integrator
    ds = cartan.simulate(problem, integrator=integ, dt=2e-3, t_end=0.4, save_every=20, progress=False, compiled=False)
    exact = _exact_end(problem, SCREW, ds.time.values)
    assert np.max(np.abs(ds.frame.values[:, -1] - exact[:, 1:, 1:])) < 1e-12
    assert np.max(np.abs(ds.position.values[:, -1] - exact[:, 1:, 0])) < 1e-12
    assert np.max(np.abs(ds.frame.values[:, -2] - exact[:, 1:, 1:])) > 1e-3


def test_implicit_midpoint_closes_the_energy_balance_with_the_reaction():
    """The sagging rod twisted at its end (as for lie-verlet above) under implicit-midpoint:
    the reaction's work, booked at the step's midpoint, equals the change of K + V to the
    method's second order (measured 2.0e-7 and 5.0e-8 of a work 3.1 at Δt = 4, 2e-3: ratio
    4.0 ± 0.6)."""
    errors = []
    for dt in (4e-3, 2e-3):
        gravity = _rod().make_load("gravity", g=[0.0, 0.0, -2.0])
        problem = _problem([0.0, 0.0, 0.0, 2.0, 0.0, 0.0], loads=[gravity])
        ds = cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=0.8,
                             save_every=int(round(0.1 / dt)), progress=False, compiled=False)
        E = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values
        W = ds.external_work.values
        assert W[-1] > 0.1
        errors.append(float(np.max(np.abs(E - E[0] - W))))
    assert errors[0] / errors[1] == pytest.approx(4.0, abs=0.6)
