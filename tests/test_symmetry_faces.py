"""Symmetry (mirror) faces as a boundary kind, :class:`cartan.Symmetry` (docs/media/cosserat-solid.md,
"Boundaries"): the kinematic conditions u·n = 0, φ ∥ n held exactly on the lattice's numpy path, in
``solve_static``, ``continuation`` and every integrator (the lattice's compiled operators take
them too: tests/test_held_compiled.py).

Fast tests on small grids and the numpy backend (no compilation): a symmetric problem cut by
its mirror planes agrees with the whole one to round-off, which nothing but exact conditions
could give (a penalty shifts the plane by reaction/stiffness, :class:`cartan.supports.SymmetrySupport`).
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_cosserat_solid.cases import UniaxialStressOctantSymmetry, uniaxial_stress

import cartan
from cartan import Clamped, Free, NodeForce, Symmetry
from cartan._backend import use_backend
from cartan.problem import held_components
from cartan.schemes.lattice import Lattice

OCTANT = UniaxialStressOctantSymmetry()
#: the block's half lengths and a small traction (the dynamic runs)
HALF = tuple(0.5 * L for L in OCTANT.length)
P = 0.05


@pytest.fixture(autouse=True)
def _numpy_backend():
    with use_backend("numpy"):
        yield


def _octant(n: int, load=(-P, 0.0, 0.0, 0.0, 0.0, 0.0), **params) -> cartan.Problem:
    solid = cartan.medium("cosserat-solid", **params)
    grid = cartan.Grid((n, n, n), length=HALF)
    boundaries = {"u-start": Symmetry(), "v-start": Symmetry(normal="y"), "w-start": Symmetry(normal=[0, 0, 2.0]),
                  "u-end": Free(load=list(load))}
    return cartan.Problem(solid, grid, solid.initial_state(grid, "undeformed"), boundaries)


def _whole(n: int, **params) -> cartan.Problem:
    """The whole block, 2n − 1 nodes per axis, centred at the origin, loaded on both u-faces."""
    solid = cartan.medium("cosserat-solid", **params)
    grid = cartan.Grid((2 * n - 1,) * 3, length=OCTANT.length)
    init = solid.initial_state(grid, "undeformed")
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] -= np.array(HALF)
    boundaries = {"u-start": Free(load=[P, 0, 0, 0, 0, 0]), "u-end": Free(load=[-P, 0, 0, 0, 0, 0])}
    return cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi), boundaries)


def test_held_components_are_the_mirror_conditions():
    """Face ⊥ e_a with frames R̄ = I: v_a and ω_b (b ≠ a) held; the edge of two planes holds the union;
    nothing elsewhere."""
    held = held_components(_octant(3))
    assert held.shape == (3, 3, 3, 6)
    assert held[0, 1, 1].tolist() == [True, False, False, False, True, True]
    assert held[1, 0, 1].tolist() == [False, True, False, True, False, True]
    assert held[0, 0, 1].tolist() == [True, True, False, True, True, True]   # the z-axis: slides along z only
    assert held[0, 0, 0].all() and not held[1:, 1:, 1:].any()
    assert Lattice(_octant(3))._clamped.shape == (3, 3, 3, 6)
    assert held_components(_whole(2)) is None
    assert cartan.registry("cases")[OCTANT.name].kind == "convergence"   # its levels: test_verification_cases.py


@pytest.mark.parametrize("integrator", ["lie-verlet", pytest.param("rkmk4", marks=pytest.mark.slow),
                                        pytest.param("implicit-midpoint", marks=pytest.mark.slow)])
def test_octant_dynamics_is_the_eighth_of_the_whole_block(integrator):
    """A traction suddenly applied to both u-faces of the whole block (5³ nodes) and to the far face of
    its octant (3³ nodes, three symmetry faces): the octant's nodes follow the whole block's to
    round-off for every integrator (on a mirror plane the whole block's node has twice the one-sided
    force and twice the octant's mass, so the two semi-discrete systems are the same)."""
    settings = {"integrator": integrator, "dt": 0.02, "t_end": 0.2, "save_every": 5, "progress": False}
    part = cartan.simulate(_octant(3), **settings)
    whole = cartan.simulate(_whole(3), **settings)
    x = part.position.values
    assert np.max(np.abs(x - x[0])) > 1e-3                       # it moved
    assert np.max(np.abs(x - whole.position.values[:, 2:, 2:, 2:])) < 1e-14
    assert np.allclose(8 * part.kinetic_energy.values, whole.kinetic_energy.values, rtol=1e-11, atol=1e-18)


def test_symmetry_face_slides_and_turns_about_its_normal_only():
    """A shear traction and a twisting couple on the far face move the nodes of the plane u = 0 along it
    and turn their frames about e_x: n·x stays 0 and Rᵀn = e_x to round-off while both motions are
    order 1e-4 and more (measured 3.4e-4 and 6.9e-3; the subalgebra {(v, ω): v·m = 0, ω ∥ m} is
    closed under exp and the brackets)."""
    problem = _octant(3, load=(0.0, 0.05, 0.02, 0.05, 0.0, 0.0))
    problem.boundaries.pop("v-start")
    problem.boundaries.pop("w-start")
    ds = cartan.simulate(problem, integrator="lie-verlet", dt=0.02, t_end=0.3, save_every=5, progress=False)
    x, R = ds.position.values[:, 0], ds.frame.values[:, 0]       # [time, v, w, 3(, 3)] on the plane u = 0
    assert np.max(np.abs(x[..., 0])) < 1e-15
    assert np.max(np.abs(R[..., 0, :] - np.array([1.0, 0.0, 0.0]))) < 1e-14   # Rᵀe_x = e_x: row 0 of R
    assert np.max(np.abs(x[-1, ..., 1:] - x[0, ..., 1:])) > 1e-4                 # it slid in the plane
    assert np.max(np.abs(R[-1, :, :, 1, 2])) > 1e-4                              # and turned about e_x


def test_continuation_keeps_the_homogeneous_path():
    """``continuation`` of the octant from λ = 0: at every point the homogeneous stretch of load λp."""
    problem, _ = OCTANT.problem(1)
    c = problem.medium.constants
    path = cartan.continuation(problem, 1.0, 0.5, tol=1e-12, detect=False)
    X = np.stack(np.meshgrid(*[problem.grid.coordinates(a) for a in range(3)], indexing="ij"), axis=-1)
    lam = path.load_factor.values
    assert lam[-1] == pytest.approx(1.0) and len(lam) >= 3
    for k, level in enumerate(lam):
        s1, s2, E, _ = uniaxial_stress(level * OCTANT.load, c["lam"], c["mu"], c["kappa"])
        x = path.position.values[k].reshape(X.shape)
        assert np.max(np.abs(x - np.array([s1, s2, s2]) * X)) < 1e-12


@pytest.mark.slow
def test_rod_with_a_symmetry_end_is_half_of_the_clamped_beam():
    """d = 1: a clamped–clamped rod (21 nodes) under a mid-span point force against its half (11 nodes)
    clamped at the start, a symmetry end at mid-span (the tangent's plane) carrying half the force:
    equal nodes to round-off at a large deflection (0.24 of the half length; ≈ 4 s of numpy Jacobians)."""
    rod = cartan.medium("cosserat-rod", E=1e3, G=400.0, radius=0.02, density=1.0)
    F = np.array([0.0, 0.0, -0.02, 0.0, 0.0, 0.0])
    g2, g1 = cartan.Grid(21, length=2.0), cartan.Grid(11, length=1.0)
    full = cartan.Problem(rod, g2, rod.initial_state(g2, "straight"), {"start": Clamped(), "end": Clamped()},
                          [NodeForce(g2, F, node=10)])
    half = cartan.Problem(rod, g1, rod.initial_state(g1, "straight"), {"start": Clamped(), "end": Symmetry()},
                          [NodeForce(g1, F / 2, node=10)])
    a = cartan.solve_static(full, tol=1e-12).position.values[-1][:11]
    b = cartan.solve_static(half, tol=1e-12).position.values[-1]
    assert b[-1, 2] < -0.2
    assert np.max(np.abs(a - b)) < 1e-13


def test_scene_symmetry_faces():
    """The scene ``solid-compressed-octant-symmetry-static`` (three spellings of the normal): the
    homogeneous uniaxial stress, exact on the lattice, so to the Newton tolerance."""
    ds = cartan.scene("solid-compressed-octant-symmetry-static").run()
    _, _, E, nu = uniaxial_stress(0.2, 1.0, 1.0, 0.5)
    x = ds["position"].values[0]
    X = np.stack(np.meshgrid(*[np.linspace(0, 1, 5)] * 3, indexing="ij"), axis=-1)
    assert np.max(np.abs(x - np.array([1 - 0.2 / E, 1 + nu * 0.2 / E, 1 + nu * 0.2 / E]) * X)) < 1e-10


def test_bad_symmetry_faces_are_refused(tmp_path):
    with pytest.raises(ValueError, match="normal must be"):
        Symmetry(normal="q")
    with pytest.raises(ValueError, match="normal must be"):
        Symmetry(normal=[0.0, 0.0, 0.0])
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((3, 3, 3), length=(1.0, 1.0, 1.0))
    init = solid.initial_state(grid, "undeformed")
    turned = init.Phi.copy()
    c, s = np.cos(0.3), np.sin(0.3)
    turned[..., 1:, 1:] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    with pytest.raises(ValueError, match="not a frame axis"):
        Lattice(cartan.Problem(solid, grid, cartan.InitialState(Phi=turned), {"u-start": Symmetry(normal="x")}))
    with pytest.raises(ValueError, match="not in one plane"):  # the default normal R̄e_x is not the face's
        Lattice(cartan.Problem(solid, grid, cartan.InitialState(Phi=turned), {"u-start": Symmetry()}))
    with pytest.raises(ValueError, match="not in one plane"):
        Lattice(cartan.Problem(solid, grid, init, {"u-start": Symmetry(normal="y")}))
    with pytest.raises(ValueError, match="not in one plane"):  # the collocation takes the faces, checked alike
        cartan.simulate(cartan.Problem(solid, grid, init, {"u-start": Symmetry(normal="y")}), scheme="collocation",
                        dt=0.01, t_end=0.01, progress=False)
    rod2 = cartan.medium("planar-cosserat-rod", E=1e3, G=400.0, radius=0.02, density=1.0)
    g = cartan.Grid(5, length=1.0)
    with pytest.raises(ValueError, match="SE\\(3\\)"):
        Lattice(cartan.Problem(rod2, g, rod2.initial_state(g, "straight"), {"end": Symmetry()}))
    scene = tmp_path / "s.toml"
    scene.write_text('medium = "cosserat-solid"\n[grid]\nshape = [3, 3, 3]\nlength = [1.0, 1.0, 1.0]\n'
                     '[boundaries]\nu-start = { kind = "symmetry", normal = "w" }\n[initial]\nkind = "undeformed"\n'
                     '[run]\nt_end = 0.1\n')
    with pytest.raises(cartan.SceneError, match="normal"):
        cartan.load_scene(scene)


@pytest.mark.slow
def test_indented_quarter_is_the_quarter_of_the_whole_slab():
    """A slab 2 × 2 × 0.5 clamped on its base, a point force −0.2e_z at the centre of its top face
    (9 × 9 × 3 nodes) against its quarter (5 × 5 × 3, symmetry faces x = 0 and y = 0, the force/4 on
    the corner node): a non-uniform finite-strain state (the loaded node sinks by 0.176, micro-
    rotations 0.047), equal on the quarter's nodes to round-off (≈ 2.5 s of numpy Jacobians)."""
    solid = cartan.medium("cosserat-solid")
    F = np.array([0.0, 0.0, -0.2, 0.0, 0.0, 0.0])
    gq = cartan.Grid((5, 5, 3), length=(1.0, 1.0, 0.5))
    quarter = cartan.Problem(solid, gq, solid.initial_state(gq, "undeformed"),
                             {"u-start": Symmetry(), "v-start": Symmetry(), "w-start": Clamped()},
                             [NodeForce(gq, F / 4, node=(0, 0, 2))])
    gf = cartan.Grid((9, 9, 3), length=(2.0, 2.0, 0.5))
    full = cartan.Problem(solid, gf, solid.initial_state(gf, "undeformed", origin=[-1.0, -1.0, 0.0]),
                          {"w-start": Clamped()}, [NodeForce(gf, F, node=(4, 4, 2))])
    q, f = cartan.solve_static(quarter, tol=1e-12), cartan.solve_static(full, tol=1e-12)
    assert q.position.values[-1][0, 0, -1, 2] < 0.5 - 0.1
    assert np.max(np.abs(q.position.values[-1] - f.position.values[-1][4:, 4:])) < 1e-13
    for x in "xyz":
        name = f"microrotation_{x}"
        assert np.max(np.abs(q[name].values[-1] - f[name].values[-1][4:, 4:])) < 1e-13


def test_pin_on_a_component_a_symmetry_face_holds_is_refused():
    """The node (0, 1, 1) lies on the x = 0 mirror face: its x position is held by the face, so a
    pin on it would add a reaction with no unknown to act on (a singular Jacobian); y is free."""
    with pytest.raises(ValueError, match=r"pins: component 0 of node .* held by a symmetry face"):
        cartan.solve_static(_octant(3), pins={(0, 1, 1): [0]}, max_iter=1)
    with pytest.raises(ValueError, match=r"pins: component 2 of node .* held by a symmetry face"):
        cartan.solve_static(_octant(3), pins={(1, 1, 0): [2]}, max_iter=1)
