"""The ``cosserat-surface`` medium: geometrically exact Cosserat shells on SE(3) (paper §VI.B).

Energy and stress against an independent implementation and finite differences (axes coupled),
the linear plate constants, rigid motions and drill rotations strain-free (flat, cylindrical and
a general reference shape), the lattice invariants of a dynamic run (plaquette holonomy, group
membership, energy error O(Δt²)), compiled loop against the reference path, and the simply
supported Mindlin plate without shear locking.
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_cosserat_surface.cases import navier_plate_problem
from cartan_cosserat_surface.surface import CosseratSurface, PenaltySupport

import cartan
from cartan.problem import InitialState, Problem
from cartan.schemes.lattice import Lattice

SE3 = cartan.group("SE3")


# ---------------------------------------------------------------------------- helpers
def reference_energy(X: np.ndarray, X0: np.ndarray, E: float, nu: float, h: float, ks: float) -> float:
    """The shell energy written with matrices (the kernels write it component by component)."""
    th, pi = X[:, :3], X[:, 3:]
    th0, pi0 = X0[:, :3], X0[:, 3:]
    a, a0 = th @ th.T, th0 @ th0.T
    A = np.linalg.inv(a0)
    J = np.sqrt(np.linalg.det(a0))

    def bend(t, p):
        d = np.stack([p[:, 1], -p[:, 0], np.zeros(2)], axis=-1)  # ∂_β p in the frame
        b = t @ d.T
        return 0.5 * (b + b.T)

    eps = 0.5 * (a - a0)
    kap = bend(th, pi) - bend(th0, pi0)
    gam = th[:, 2] - th0[:, 2]

    def energy(x, c):  # ½ 𝒞(x, x) with 𝒞 = c[ν A⊗A + (1 − ν) sym(A⊗A)]
        return 0.5 * c * (nu * np.trace(A @ x) ** 2 + (1 - nu) * np.trace(A @ x @ A @ x))

    cs = E / (1 - nu ** 2)
    G = E / (2 * (1 + nu))
    return J * (energy(eps, cs * h) + 0.5 * ks * G * h * gam @ A @ gam + energy(kap, cs * h ** 3 / 12))


def random_rest(rng: np.random.Generator) -> np.ndarray:
    """A curved, sheared, non-orthonormal rest strain (a general reference point)."""
    X0 = np.zeros((2, 6))
    X0[0, :3] = (1.2, 0.1, 0.0)
    X0[1, :3] = (0.3, 0.9, 0.0)
    X0[:, 3:] = 0.4 * rng.standard_normal((2, 3))
    return X0


def sphere_patch(R: float):
    """r(u, v) of a sphere of radius R around its north pole (u, v small): a doubly curved shape."""
    def position(u, v):
        x, y = R * np.sin(u / R) * np.cos(v / R), R * np.sin(v / R)
        z = R * np.cos(u / R) * np.cos(v / R)
        return np.stack([x, y, z], axis=-1)
    return position


def potential_and_force(problem: Problem) -> tuple[float, float]:
    sch = Lattice(problem)
    st = sch.initial_state()
    return sch.potential_energy(st), float(np.max(np.abs(sch.internal_force(st))))


# ---------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(("kw", "name"), [
    ({"E": 0.0}, "E"), ({"poisson": 0.5}, "poisson"), ({"poisson": -1.0}, "poisson"),
    ({"thickness": -1.0}, "thickness"), ({"density": 0.0}, "density"), ({"shear_correction": 0.0}, "shear_correction"),
    ({"rest_curvature": (1.0, 1.0)}, "rest_curvature"), ({"rest_curvature": (1.0,)}, "rest_curvature"),
    ({"E": "1"}, "E"),
])
def test_bad_parameters_name_the_parameter(kw, name):
    with pytest.raises(ValueError, match=name):
        CosseratSurface(**kw)


def test_bad_initial_and_load_parameters():
    med = CosseratSurface()
    grid = cartan.Grid((5, 5))
    with pytest.raises(ValueError, match="radius"):
        med.initial_state(grid, "cylinder")                 # open u axis: the radius is needed
    with pytest.raises(ValueError, match="radius"):
        med.initial_state(cartan.Grid((8, 5), length=(1.0, 1.0), periodic=(True, False)), "cylinder", radius=1.0)
    with pytest.raises(ValueError, match="curl"):
        med.initial_state(grid, "flat", curl=1.0)
    with pytest.raises(ValueError, match="edges"):
        PenaltySupport(edges=["w-start"])
    with pytest.raises(ValueError, match="director_stiffness"):
        PenaltySupport(director_stiffness=-1.0)
    with pytest.raises(ValueError, match="g"):
        med.make_load("gravity", g=[0, 0])


# ---------------------------------------------------------------------------- energy and stress
def test_energy_matches_an_independent_implementation():
    rng = np.random.default_rng(1)
    med = CosseratSurface(E=3.0, poisson=0.25, thickness=0.2, shear_correction=0.9)
    for _ in range(5):
        X0 = random_rest(rng)
        X = X0 + 0.3 * rng.standard_normal((2, 6))
        U = float(med.potential_at(X, X0))
        ref = reference_energy(X, X0, 3.0, 0.25, 0.2, 0.9)
        assert abs(U - ref) <= 1e-13 * abs(ref)


def test_stress_is_the_gradient_with_axis_coupling():
    """Q = ∂U/∂X by central differences far from rest, and its Jacobian (the stiffness) is
    symmetric with a non-zero u–v block: the membrane energy couples the axes."""
    rng = np.random.default_rng(2)
    med = CosseratSurface(E=2.0, poisson=0.3, thickness=0.3)
    X0 = random_rest(rng)
    X = X0 + 0.3 * rng.standard_normal((2, 6))
    Q = med.stress_at(X, X0)
    eps = 1e-6
    H = np.empty((2, 6, 2, 6))
    fd = np.empty((2, 6))
    for a in range(2):
        for k in range(6):
            dX = np.zeros((2, 6))
            dX[a, k] = eps
            fd[a, k] = (med.potential_at(X + dX, X0) - med.potential_at(X - dX, X0)) / (2 * eps)
            H[:, :, a, k] = (med.stress_at(X + dX, X0) - med.stress_at(X - dX, X0)) / (2 * eps)
    # central differences: O(ε²) truncation, round-off ε_mach|U|/ε ≈ 1e-10 relative
    assert np.max(np.abs(fd - Q)) <= 1e-8 * np.max(np.abs(Q))
    Hm = H.reshape(12, 12)
    assert np.max(np.abs(Hm - Hm.T)) <= 1e-7 * np.max(np.abs(Hm))
    assert np.max(np.abs(H[0, :, 1, :])) > 0.1 * np.max(np.abs(Hm))   # the axes are coupled
    # the drill components of π enter nothing
    assert np.all(Q[:, 5] == 0.0) and np.all(H[:, 5] == 0.0) and np.all(H[..., 5] == 0.0)


def test_linear_plate_constants():
    """About the flat rest state the Hessian holds the plate constants: Eh/(1−ν²), νEh/(1−ν²)
    (u–v coupling), Gh in shear of the membrane, κGh transverse shear, D = Eh³/(12(1−ν²))."""
    E, nu, h, ks = 2.0, 0.3, 0.1, 5.0 / 6.0
    med = CosseratSurface(E=E, poisson=nu, thickness=h, shear_correction=ks)
    H = med.stiffness(eps=1e-5)
    G, C, D = E / (2 * (1 + nu)), E * h / (1 - nu ** 2), E * h ** 3 / (12 * (1 - nu ** 2))
    expected = {(0, 0, 0, 0): C, (0, 0, 1, 1): nu * C, (0, 1, 0, 1): G * h, (0, 1, 1, 0): G * h,
                (0, 2, 0, 2): ks * G * h, (1, 2, 1, 2): ks * G * h,
                (0, 4, 0, 4): D, (1, 3, 1, 3): D, (0, 4, 1, 3): -nu * D, (0, 3, 0, 3): D * (1 - nu) / 2}
    for (a, i, b, j), value in expected.items():
        assert H[a, i, b, j] == pytest.approx(value, rel=1e-8), (a, i, b, j)


def test_inertia_and_gauge():
    med = CosseratSurface(thickness=0.2, density=3.0)
    assert np.allclose(med.inertia(), [0.6, 0.6, 0.6, 0.002, 0.002, 0.0])
    assert med.gauge_mask().tolist() == [False] * 5 + [True]


# ---------------------------------------------------------------------------- rigid motions
def drill_and_move(Phi: np.ndarray, seed: int) -> np.ndarray:
    """g Φ exp(ψ b₆): a rigid motion g and a drill rotation ψ of every frame.

    ψ is uniform: the continuum energy is invariant under any drill field ψ(u, v), the lattice's
    under a uniform one exactly (its edge logarithms of a varying drill differ at O(h²))."""
    rng = np.random.default_rng(seed)
    g = SE3.exp(rng.standard_normal(6))
    psi = np.zeros(6)
    psi[5] = rng.uniform(-3.0, 3.0)
    return SE3.compose(SE3.compose(g, Phi), SE3.exp(psi))


def test_rigid_motion_and_drill_are_strain_free_flat_and_cylinder():
    R = 0.7
    flat = CosseratSurface()
    grid = cartan.Grid((7, 6), length=(1.0, 0.8))
    cyl = CosseratSurface(rest_curvature=(1.0 / R, 0.0))
    cgrid = cartan.Grid((12, 5), length=(2 * np.pi * R, 1.0), periodic=(True, False))
    for med, gr, kind, kw in ((flat, grid, "flat", {}), (cyl, cgrid, "cylinder", {})):
        Phi = med.initial_state(gr, kind, **kw).Phi
        for seed in range(3):
            V, F = potential_and_force(Problem(med, gr, InitialState(Phi=drill_and_move(Phi, seed))))
            assert abs(V) <= 1e-26 and F <= 1e-13, (kind, V, F)
    # a genuine bending is not strain-free (the check can fail)
    Phi = flat.initial_state(grid, "flat").Phi
    bent = SE3.compose(Phi, SE3.exp(np.einsum("i,k->ik", grid.coordinates(0), [0, 0, 0, 0, 0.3, 0])[:, None, :]
                                    + np.zeros((7, 6, 6))))
    assert potential_and_force(Problem(flat, grid, InitialState(Phi=bent)))[0] > 1e-6


def test_general_reference_shape_is_stress_free_under_rigid_motion():
    """A doubly curved stress-free configuration (a sphere patch, Problem.reference): the
    reference, moved rigidly and drilled, has zero energy and zero force; a closed cylinder
    on a periodic axis with the constant rest curvature as well."""
    med = CosseratSurface(thickness=0.05)
    grid = cartan.Grid((7, 7), length=(0.8, 0.8))
    ref = med.initial_state(grid, "surface", position=sphere_patch(1.3)).Phi
    for seed in range(2):
        V, F = potential_and_force(Problem(med, grid, InitialState(Phi=drill_and_move(ref, seed)), reference=ref))
        assert abs(V) <= 1e-26 and F <= 1e-13
    flat = med.initial_state(grid, "flat").Phi       # the flat plate is not stress-free against the sphere
    assert potential_and_force(Problem(med, grid, InitialState(Phi=flat), reference=ref))[0] > 1e-6


def test_uniform_translation_stays_stress_free():
    med = CosseratSurface(rest_curvature=(0.0, -2.0))   # concave: e₃ points to the axis
    grid = cartan.Grid((6, 9), length=(0.5, np.pi))
    init = med.initial_state(grid, "surface", position=lambda u, v: np.stack(
        [u, 0.5 * np.sin(2 * v), 0.5 - 0.5 * np.cos(2 * v)], -1), twist=[0.3, -0.2, 0.5, 0, 0, 0])
    # the Python path (the surface's compiled loop, ≈ 30 s to compile, runs in make test-slow)
    ds = cartan.simulate(Problem(med, grid, init), integrator="lie-verlet", dt=1e-3, t_end=0.05, save_every=25,
                         progress=False, compiled=False)
    assert float(np.max(np.abs(ds.potential_energy))) <= 1e-24
    shift = ds.position.values[-1] - ds.position.values[0]
    assert np.allclose(shift, 0.05 * np.array([0.3, -0.2, 0.5]), atol=1e-13)


# ---------------------------------------------------------------------------- outputs
def test_curvature_outputs_of_cylinder_and_sphere():
    """Mean and Gauss curvature of the director field: cylinder 1/(2R) and 0, sphere 1/R and
    1/R².  Exact on the lattice's edge strains: the frames turn at a constant rate along every
    chart line of both charts (latitude circles and great circles of the sphere), so each edge
    logarithm is the exact strain; what remains is the error of the central-difference tangents
    that build the sphere's frames (≈ 1e-8)."""
    med = CosseratSurface()
    R = 0.5
    cgrid = cartan.Grid((16, 4), length=(2 * np.pi * R, 1.0), periodic=(True, False))
    pb = Problem(med, cgrid, med.initial_state(cgrid, "cylinder"))
    sch = Lattice(pb)
    res = med.resultants(sch.nodal_strains(sch.initial_state()))
    assert np.allclose(res[..., 9], 0.5 / R, rtol=1e-12) and np.allclose(res[..., 8], 0.0, atol=1e-12)
    for n in (9, 17):
        grid = cartan.Grid((n, n), length=(0.4, 0.4))
        pb = Problem(med, grid, med.initial_state(grid, "surface", position=sphere_patch(1.0)))
        sch = Lattice(pb)
        res = med.resultants(sch.nodal_strains(sch.initial_state()))[1:-1, 1:-1]
        assert np.max(np.abs(res[..., 9] - 1.0)) < 1e-6 and np.max(np.abs(res[..., 8] - 1.0)) < 1e-6


# ---------------------------------------------------------------------------- dynamics on the lattice
@pytest.fixture(scope="module")
def plate_problem():
    """A free plate on a slightly curved, non-uniform reference with a smooth initial velocity."""
    med = CosseratSurface(E=1.0, poisson=0.3, thickness=0.1)
    grid = cartan.Grid((9, 7), length=(1.0, 0.8))
    ref = med.initial_state(grid, "surface", position=lambda u, v: np.stack(
        [u, v, 0.2 * u * v + 0.1 * np.sin(2 * u)], -1)).Phi
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    N = np.zeros((9, 7, 6))
    N[..., 2] = 0.3 * np.sin(np.pi * u) * np.cos(np.pi * v)
    N[..., 0] = 0.05 * np.cos(np.pi * v)
    N[..., 3] = 0.4 * u * v
    return Problem(med, grid, InitialState(Phi=ref, N=N), reference=ref)


@pytest.mark.slow  # the surface's loop: ≈ 12 s to compile on a fresh cache
def test_invariants_and_energy_order_lie_verlet(plate_problem):
    """Plaquette holonomy and group membership at round-off; the energy error of lie-verlet
    falls as Δt² (observed order asserted)."""
    errors = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(plate_problem, integrator="lie-verlet", dt=dt, t_end=0.4, save_every=round(0.02 / dt),
                             progress=False)
        E = (ds.kinetic_energy + ds.potential_energy).values
        errors.append(float(np.max(np.abs(E - E[0]))) / E[0])
        assert float(ds.spatial_residual.max()) <= 1e-12
        assert float(ds.group_defect.max()) <= 1e-12
        assert float(ds.potential_energy.max()) > 1e-2 * float(ds.kinetic_energy[0])  # the plate deforms
    order = np.log2(errors[0] / errors[1])
    assert 1.8 <= order <= 2.3, (errors, order)


@pytest.mark.slow  # the surface's loop: ≈ 12 s to compile on a fresh cache
def test_compiled_loop_matches_reference_path(plate_problem):
    """The generated lattice loop runs the same formulas as the numpy path: 1e-12 relative."""
    kw = dict(integrator="lie-verlet", dt=2e-3, t_end=0.04, save_every=10, progress=False)
    fast = cartan.simulate(plate_problem, **kw)
    ref = cartan.simulate(plate_problem, **kw, compiled=False)
    for key in ("S", "X", "position", "potential_energy", "kinetic_energy"):
        scale = float(np.max(np.abs(ref[key].values)))
        assert float(np.max(np.abs(fast[key].values - ref[key].values))) <= 1e-12 * scale, key


# ---------------------------------------------------------------------------- plate without shear locking
@pytest.fixture(scope="module")
def navier_errors():
    def error(n, ratio):
        pb, w_ref = navier_plate_problem(n, ratio)
        ds = cartan.solve_static(pb, tol=1e-10)
        return abs(-float(ds.position.values[0][n // 2, n // 2, 2]) / w_ref - 1.0)
    return {(9, 0.1): error(9, 0.1), (9, 0.001): error(9, 0.001), (17, 0.001): error(17, 0.001)}


def test_navier_plate_no_shear_locking(navier_errors):
    """Same grid: the thin plate (h/a = 0.001) is at most 2× less accurate than the thick one."""
    assert navier_errors[(9, 0.001)] <= 2.0 * navier_errors[(9, 0.1)]
    assert navier_errors[(9, 0.1)] < 0.03          # O(dx²): 2.2e-2 measured at n = 9


def test_navier_plate_second_order(navier_errors):
    order = np.log2(navier_errors[(9, 0.001)] / navier_errors[(17, 0.001)])
    assert 1.8 <= order <= 2.3, order


# ---------------------------------------------------------------------------- registry
def test_registered_medium_scenes_and_cases():
    assert cartan.registry("media")["cosserat-surface"] is CosseratSurface
    scenes = cartan.registry("scenes")
    assert {"plate-navier", "plate-cantilever-gravity"} <= set(scenes)
    cases = cartan.registry("cases")
    assert {"plate-navier-thick", "plate-navier-thin"} <= set(cases)
    from cartan.scene import scene

    sc = scene("plate-cantilever-gravity")
    assert sc.problem.medium.name == "cosserat-surface" and sc.problem.grid.shape == (17, 9)


@pytest.mark.slow
def test_conformance_kit():
    from cartan.testing import check_medium

    report = check_medium("cosserat-surface", {})
    assert not report.failed

