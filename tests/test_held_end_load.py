"""A load at a ``cartan.Held`` end: the held components of the force are the support's reaction,
the free ones drive the end (the lattice's numpy path here: a ``NodeForce`` is not a load the
compiled operators take; held ends on the compiled path: tests/test_held_compiled.py).

A Cosserat rod pinned at u = 0 (``Held((0, 1, 2))``: the position held, the frame free) under a
point force-and-moment at the pin (``NodeForce`` on node 0): the force on the held components
changes nothing (bit for bit), the pin stays put exactly, and the moment turns the end; the
angular momentum about the pin grows as M t (the reaction, a force through the pin, has no
moment about it; Lie–Verlet's kicks add exactly Δt·M per step).  In statics the pinned end of
a propped cantilever turns by the closed form under a moment.  In a scene file a held end
takes a ``load`` (and ``follower``) with a free end's meaning: a node force on the end node."""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.problem import NodeForce

MOMENT = 10.0  # about e_z, at the pin


def _run(force, start):
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(5, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries={"start": start},
                             loads=[NodeForce(grid, force, node=0)])
    return cartan.simulate(problem, integrator="lie-verlet", dt=1e-4, t_end=2e-3, save_every=5, progress=False)


def test_force_at_a_pinned_end_is_its_reaction_and_the_moment_turns_it():
    pin = cartan.Held(components=(0, 1, 2))
    moment = _run([0.0, 0.0, 0.0, 0.0, 0.0, MOMENT], pin)
    both = _run([1e3, 2e3, 3e3, 0.0, 0.0, MOMENT], pin)
    # the held components of the force are the reaction's: the runs are identical
    assert np.array_equal(moment.position.values, both.position.values)
    assert np.array_equal(moment.frame.values, both.frame.values)
    # the pin holds its position exactly, its held velocity components are zero, its frame turns
    assert np.array_equal(moment.position.values[:, 0], np.broadcast_to(moment.position.values[0, 0], (5, 3)))
    assert np.all(moment.N.values[:, 0, :3] == 0.0)
    assert np.all(moment.N.values[1:, 0, 5] > 0.0)
    # angular momentum about the pin (the origin): M t, to round-off (a few ulps of M t per step)
    t = moment.time.values
    assert np.allclose(moment.total_momentum.values[:, 5], MOMENT * t, rtol=1e-12, atol=1e-15)


def test_a_load_on_every_held_component_is_the_clamps_reaction():
    """Held with every component is a clamp: the same load does nothing to either (bit for bit)."""
    load = [1e3, 2e3, 3e3, 4.0, 5.0, MOMENT]
    clamped = _run(load, cartan.Clamped())
    held = _run(load, cartan.Held(components=tuple(range(6))))
    assert np.array_equal(clamped.position.values, held.position.values)
    assert np.all(held.N.values == 0.0) and np.all(clamped.N.values == 0.0)


def test_propped_cantilever_end_moment_statics():
    """``solve_static``: a rod clamped at u = 0 and pinned at u = L (``Held((0, 1, 2))``) under a
    moment M at the pin turns it by θ = ML(1 + φ)/(EI(4 + φ)), φ = 12EI/(GA L²) (the Timoshenko
    propped cantilever; 4EI/L the end's rotational stiffness without shear).  Measured errors
    −1.17e-2, −2.93e-3 at 9, 17 nodes (the lattice's O(h²), ratio 4.01); M = 1e-3 keeps the
    geometric nonlinearity small: both ends hold their positions, so the deflection stretches
    the rod and its tension N = GA(ML/EI)²/240 = 4.2e-5 stiffens the end by 1.4e-6 (relative);
    at GA = 1e9 the tension is 3.2 and the angle 9.2 % below the closed form
    (tests/test_statics_stiff.py).  A force on the held components is the pin's reaction and
    changes nothing."""
    EI, GA, M, L = 1.0, 1e4, 1e-3, 1.0
    phi = 12.0 * EI / (GA * L * L)
    exact = M * L * (1.0 + phi) / (EI * (4.0 + phi))
    errors = []
    for n in (9, 17):
        rod = cartan.medium("cosserat-rod", stretch_shear=[GA] * 3, bend_twist=[EI] * 3, mass=1.0,
                            rotational_inertia=[1.0, 1.0, 1.0])
        grid = cartan.Grid(n, length=L)
        ends = {"start": cartan.Clamped(), "end": cartan.Held(components=(0, 1, 2))}
        angles = []
        for force in ([0.0, 0.0, 0.0, 0.0, 0.0, M], [0.3, -0.2, 0.1, 0.0, 0.0, M]):
            problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries=ends,
                                     loads=[NodeForce(grid, force, node=-1)])
            ds = cartan.solve_static(problem, tol=1e-12)
            assert np.array_equal(ds.position.values[-1, -1], [L, 0.0, 0.0])  # the pin holds
            R = ds.frame.values[-1, -1]
            angles.append(np.arctan2(R[1, 0], R[0, 0]))
        # the held components' force is the reaction: the same equilibrium to Newton's tolerance
        assert angles[1] == pytest.approx(angles[0], rel=1e-8)
        errors.append(abs(angles[0] / exact - 1.0))
    assert errors[1] <= 3.5e-3
    assert np.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.1)


_SCENE = ('medium = "cosserat-rod"\n[parameters]\nE = 1e6\nG = 1e4\nradius = 0.25\ndensity = 5000.0\n'
          '[grid]\nn = 5\nlength = 1.0\n[initial]\nkind = "straight"\n'
          '[boundaries]\nstart = {{ kind = "held", components = [0, 1, 2], load = {load}{extra} }}\n'
          '[run]\nintegrator = "lie-verlet"\ndt = 1e-4\nt_end = 2e-3\nsave_every = 5\n')


@pytest.mark.parametrize("follower", [False, True])
def test_a_held_end_load_in_a_scene_is_the_node_force(tmp_path, follower):
    """``{ kind = "held", components = [...], load = [...] }``: the same run as the Python
    ``NodeForce`` on the end node (``frame="body"`` for ``follower = true``), bit for bit."""
    load = [1e3, 2e3, 3e3, 0.0, 0.0, MOMENT]
    path = tmp_path / "held.toml"
    path.write_text(_SCENE.format(load=load, extra=", follower = true" if follower else ""))
    scene = cartan.load_scene(path)
    assert isinstance(scene.problem.boundaries["start"], cartan.Held)
    ds = scene.simulate(progress=False)
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(5, length=1.0)
    force = NodeForce(grid, load, node=0, frame="body" if follower else "spatial")
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                             boundaries={"start": cartan.Held(components=(0, 1, 2))}, loads=[force])
    ref = cartan.simulate(problem, integrator="lie-verlet", dt=1e-4, t_end=2e-3, save_every=5, progress=False)
    assert np.array_equal(ds.position.values, ref.position.values)
    assert np.array_equal(ds.frame.values, ref.frame.values)
    assert np.array_equal(ds.N.values, ref.N.values)
    assert np.all(ds.N.values[1:, 0, 5] > 0.0)  # the moment turns the pinned end


@pytest.mark.parametrize("load", ["[0, 0, 1]", '"up"', "[0, 0, 0, 0, 0, true]", "[0, 0, 0, 0, 0, 1, 0]"])
def test_a_malformed_held_end_load_is_a_scene_error(tmp_path, load):
    path = tmp_path / "held.toml"
    path.write_text(_SCENE.format(load=load, extra=""))
    with pytest.raises(cartan.SceneError, match=r"boundaries\.start\.load"):
        cartan.load_scene(path)


def test_a_held_end_rejects_unknown_keys_and_a_bad_follower(tmp_path):
    path = tmp_path / "held.toml"
    path.write_text(_SCENE.format(load="[0, 0, 0, 0, 0, 1]", extra=", force = 1"))
    with pytest.raises(cartan.SceneError, match=r"boundaries\.start\.force: unknown key; allowed: components, "
                                                r"follower, kind, load"):
        cartan.load_scene(path)
    path.write_text(_SCENE.format(load="[0, 0, 0, 0, 0, 1]", extra=", follower = 1"))
    with pytest.raises(cartan.SceneError, match=r"boundaries\.start\.follower: must be true or false"):
        cartan.load_scene(path)


def test_a_loaded_held_end_is_a_continuation_parameter():
    """The held end's load is an external load λ scales, named by its end (``parameter = "end"``)."""
    data = {"medium": "cosserat-rod", "parameters": {"E": 1e6, "G": 1e4, "radius": 0.25, "density": 5000.0},
            "grid": {"n": 5}, "initial": {"kind": "straight"}, "mode": "continuation",
            "boundaries": {"start": {"kind": "clamped"},
                           "end": {"kind": "held", "components": [0, 1, 2], "load": [0, 0, 0, 0, 0, 1e-3]}},
            "continuation": {"lambda_max": 1.0, "parameter": "end"}}
    assert cartan.load_scene(data).parameter == "end"
    data["boundaries"]["end"]["load"] = [0.0] * 6  # an unloaded held end is no parameter
    with pytest.raises(cartan.SceneError, match=r"continuation"):
        cartan.load_scene(data)
