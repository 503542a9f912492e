"""The compiled loop of the ``kinematic`` integrator (the generated RKMK loop with a numba velocity).

With a numba-compiled velocity ``f(t, u, X)`` the lattice and collocation schemes run the
prescribed-velocity RKMK steps in one compiled loop; it must agree with the Python reference
(``Kinematic.step``) to 1e-12 relative on every state array and energy accumulator (the
operations are the same; the compiled group logarithm and exponential differ from numpy's
in the last bits), over blocks of calls, for orders 1, 2 and 4, rods, rings, root frames,
d = 2 grids and collocation; decline a Python callable; stop after a step that leaves a
non-finite configuration; and reject a velocity of the wrong shape.
"""

from __future__ import annotations

import functools

import numba
import numpy as np
import pytest
import toys
from toys import arc_problem, rod_problem

import cartan
from cartan.api import simulate
from cartan.grid import Grid
from cartan.integrators import Kinematic
from cartan.problem import Problem
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

TOL = 1e-12


wave = toys.wave


XI = np.array([0.3, -0.2, 0.1, 0.4, 0.2, -0.5])


@numba.njit
def rigid(t, u, X):
    """A spatially constant body velocity (one ``[r]`` vector for every node)."""
    return XI.copy()


@numba.njit
def blows_up(t, u, X):
    """Finite velocities until t = 0.035, then NaN."""
    N = np.zeros((u.shape[0], X.shape[-1]))
    N[:, 0] = 1.0 if t < 0.035 else np.nan
    return N


@numba.njit
def wrong_shape(t, u, X):
    return np.zeros(X.shape[-1] + 1)


def _run(scheme_type, problem, order, velocity=wave, blocks=(10, 20), **opts):
    return toys.run_both(scheme_type, problem, lambda: Kinematic(velocity=velocity, order=order), 0.01, sum(blocks),
                         blocks=blocks, **opts)


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2, 4])
@pytest.mark.parametrize("kind", ["dead", "follower", "ring"])
def test_lattice_rod_agrees_with_python(kind, order):
    _, (ref, ri), (fast, fi) = _run(Lattice, rod_problem(kind), order, track_frames=True)
    toys.assert_close_states(fast, ref, TOL)
    assert fast.scalars["dissipated_energy"] != 0.0
    assert (fast.scalars["external_work"] != 0.0) == (kind != "ring")  # end loads; gravity is a potential
    assert (fi.nstep, fi.nforce) == (ri.nstep, ri.nforce) == (30, 0)


@pytest.mark.slow  # the kinematic loop: ≈ 40 s to compile on a fresh cache
@pytest.mark.parametrize("planar", [False, True], ids=["SE3", "SE2"])
def test_lattice_root_frame_only(planar):
    """Without loads the lattice steps the root frame only; the velocity depends on the strains."""
    rod = toys.moving_rod(planar)
    grid = Grid(12, length=1.0)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=2.0))
    scheme, (ref, _), (fast, _) = _run(Lattice, problem, 4)
    assert "Phi_root" in fast.arrays
    toys.assert_close_states(fast, ref, TOL)


@pytest.mark.slow
def test_lattice_sigma_model_d2_agrees_with_python():
    medium = cartan.medium("sigma-model", n=2, d=2)
    for periodic in [(True, True), (False, True)]:
        grid = Grid((9, 7), 1.0, periodic=periodic)
        init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, seed=1)
        _, (ref, _), (fast, _) = _run(Lattice, Problem(medium, grid, init), 4, blocks=(4, 6))
        assert set(fast.arrays) == {"G_u", "G_v", "Phi_root"}
        toys.assert_close_states(fast, ref, TOL)


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2, 4])
@pytest.mark.parametrize("kind", ["dead", "follower"])
def test_collocation_rod_agrees_with_python(kind, order):
    _, (ref, _), (fast, _) = _run(Collocation, rod_problem(kind, n=16), order, track_frames=True)
    toys.assert_close_states(fast, ref, TOL)


@pytest.mark.slow  # its velocity compiles a kinematic module of its own (30-70 s on a fresh cache); the
# kinematic loop stays in the fast suite through test_lattice_root_frame_only
@pytest.mark.parametrize("scheme_type", [Lattice, Collocation])
def test_rigid_motion_is_exact(scheme_type):
    """A constant body velocity (returned as one ``[r]`` vector) moves the frames by Φ₀ exp(tN)
    and the strains by ``Ad_{exp(−tN)}`` exactly (paper §V, ∂_uN = 0), to round-off."""
    prob = arc_problem(n=9, curvature=1.5)
    scheme = scheme_type(prob, track_frames=True)
    state = scheme.initial_state()
    X0 = np.asarray(scheme.strains(state))[:, 0].copy()
    assert toys.advance_compiled(scheme, Kinematic(velocity=rigid, order=4), state, 0.02, 50)
    G = scheme.group
    assert np.max(np.abs(scheme.frames(state) - G.compose(prob.initial.Phi, G.exp(1.0 * XI)))) < 1e-12
    assert np.max(np.abs(np.asarray(scheme.strains(state))[:, 0] - X0 @ G.Ad(G.exp(-XI)).T)) < 1e-12


def test_python_velocity_declines():
    scheme = Lattice(rod_problem("dead"), track_frames=True)
    state = scheme.initial_state()
    before = state.copy()
    integ = Kinematic(velocity=wave.py_func)
    assert not toys.advance_compiled(scheme, integ, state, 0.01, 3)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
    assert integ.nstep == 0


@pytest.mark.slow
@pytest.mark.parametrize("scheme_type", [Lattice, Collocation])
def test_stops_after_the_first_non_finite_step(scheme_type):
    """The velocity turns NaN at t ≥ 0.035: the first stage of step 4 (t = 0.03) is finite, the
    stage at t + Δt/2 is not, so step 4 is the first that leaves a non-finite configuration."""
    scheme = scheme_type(rod_problem("dead", n=16), track_frames=True)
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    assert toys.advance_compiled(scheme, Kinematic(velocity=blows_up, order=4), state, 0.01, 10)
    assert state.scalars["nstep"] == 4
    frames = scheme.frames(state)
    assert not np.all(np.isfinite(frames))


@pytest.mark.slow
def test_wrong_shape_is_an_error():
    scheme = Lattice(rod_problem("dead"), track_frames=True)
    with pytest.raises(ValueError, match=r"must return N of shape"):
        toys.advance_compiled(scheme, Kinematic(velocity=wrong_shape), scheme.initial_state(), 0.01, 2)


@pytest.mark.slow  # the kinematic loop: ≈ 40 s to compile on a fresh cache
def test_simulate_compiled_agrees_with_reference():
    run = functools.partial(simulate, rod_problem("follower"), scheme="lattice", integrator="kinematic",
                            integrator_options={"velocity": wave, "order": 2}, dt=0.01, t_end=0.5, save_every=10,
                            progress=False)
    fast, ref = run(), run(compiled=False)
    for name in ("Phi", "G_u"):
        if name in ref:
            assert toys.rel_error(fast[name].values, ref[name].values) <= TOL


@pytest.mark.slow
@pytest.mark.parametrize("periodic", [(True, True), (False, True)], ids=["torus", "cylinder"])
def test_collocation_sigma_model_d2_agrees_with_python(periodic):
    medium = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((9, 7), 1.0, periodic=periodic)
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, seed=1)
    _, (ref, _), (fast, _) = _run(Collocation, Problem(medium, grid, init), 4, blocks=(4, 6))
    toys.assert_close_states(fast, ref, TOL)
