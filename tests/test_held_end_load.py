"""A load at a ``cartan.Held`` end: the held components of the force are the support's reaction,
the free ones drive the end (the lattice's numpy path, the only one that takes held ends).

A Cosserat rod pinned at u = 0 (``Held((0, 1, 2))``: the position held, the frame free) under a
point force-and-moment at the pin (``NodeForce`` on node 0): the force on the held components
changes nothing (bit for bit), the pin stays put exactly, and the moment turns the end; the
angular momentum about the pin grows as M t (the reaction, a force through the pin, has no
moment about it; Lie–Verlet's kicks add exactly Δt·M per step).  In statics the pinned end of
a propped cantilever turns by the closed form under a moment.  A ``Held`` end takes no
``load`` of its own: in a scene file that key is refused."""

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
    geometric nonlinearity at θ² ≈ 6e-8.  A force on the held components is the pin's reaction
    and changes nothing."""
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


def test_a_held_end_takes_no_load_key_in_a_scene(tmp_path):
    path = tmp_path / "held.toml"
    path.write_text('medium = "cosserat-rod"\n[parameters]\nE = 1e6\nG = 1e4\nradius = 0.25\ndensity = 5000.0\n'
                    '[grid]\nn = 5\nlength = 1.0\n[initial]\nkind = "straight"\n'
                    '[boundaries]\nstart = { kind = "held", components = [0, 1, 2], load = [0, 0, 0, 0, 0, 1] }\n'
                    '[run]\nintegrator = "lie-verlet"\ndt = 1e-4\nt_end = 2e-4\nsave_every = 1\n')
    with pytest.raises(cartan.SceneError, match=r"boundaries\.start\.load: unknown key; allowed: components, kind"):
        cartan.load_scene(path)
