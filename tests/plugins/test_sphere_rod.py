"""The Cosserat rod on a sphere (paper §VIII.A): parameters, conventions, stresses, loads,
initial states, the scene, and its dynamics (VERIFICATION.md §4, sphere-rod rows).

Conventions used throughout (see ``cartan_sphere_rod.rod``): frames R = (e₁ e₂ e₃), centreline
r·e₃, e₁ along the rest tangent, e₂ = e₃ × e₁; so(3) components X = (−θ₂/r, θ₁/r, π_n),
N = (−V₂/r, V₁/r, Ω_n); rest strain X₀ = (0, θ₀/r, 0).
"""

from __future__ import annotations

import json
import math
import pathlib
import tomllib

import numpy as np
import pytest
from cartan_sphere_rod import SphereRod
from cartan_sphere_rod.plugin import SCENES

import cartan
from cartan.grid import Grid
from cartan.integrators import LieVerlet, Overdamped
from cartan.problem import Damping, InitialState, Problem
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice


def _run(scheme, integrator, state, dt, nsteps):
    for _ in range(nsteps):
        integrator.step(scheme, state, dt)
    return state


def _observed_orders(errors):
    e = np.asarray(errors, dtype=float)
    return np.log2(e[:-1] / e[1:])


# ---------------------------------------------------------------------------- registry, parameters
def test_registered():
    assert cartan.registry("media")["sphere-rod"] is SphereRod
    assert set(SCENES) <= set(cartan.registry("scenes"))
    rod = cartan.medium("sphere-rod", radius=2.5)
    assert rod.space == cartan.space("frame-S2", radius=2.5)
    assert rod.group.name == "SO3"


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"radius": 0.0}, "radius"),
        ({"radius": float("inf")}, "radius"),
        ({"radius": "big"}, "radius"),
        ({"density": -1.0}, "density"),
        ({"rotational_inertia": 0.0}, "rotational_inertia"),
        ({"stiffness": [1.0, -1.0]}, "stiffness"),
        ({"stiffness": [1.0, 2.0, 3.0]}, "stiffness"),
        ({"stiffness": [[1.0, 0.5], [0.0, 1.0]]}, "stiffness"),  # not symmetric
        ({"stiffness": [[1.0, 2.0], [2.0, 1.0]]}, "stiffness"),  # indefinite
        ({"stiffness": [1.0, float("nan")]}, "stiffness"),
        ({"bending": -0.1}, "bending"),
        ({"bending": [1.0, 2.0]}, "bending"),
        ({"rest_stretch": 0.0}, "rest_stretch"),
    ],
)
def test_parameters_validated(kwargs, name):
    with pytest.raises(ValueError, match=name):
        SphereRod(**kwargs)


def test_parameters_roundtrip_inertia_and_quadratic_data():
    r, rho, In, Nn, th0 = 2.0, 3.0, 0.2, 0.7, 1.1
    K = [[5.0, 1.0], [1.0, 2.0]]
    rod = SphereRod(radius=r, density=rho, rotational_inertia=In, stiffness=K, bending=Nn, rest_stretch=th0)
    params = json.loads(json.dumps(rod.parameters()))
    again = SphereRod(**params)
    X = rod.rest_strain() + np.random.default_rng(0).standard_normal((4, 1, 3))
    np.testing.assert_array_equal(again.stress(X), rod.stress(X))
    # K = ½ρ₀|V|² + ½𝕀_nΩ_n² with N = (−V₂/r, V₁/r, Ω_n)
    np.testing.assert_allclose(rod.inertia(), [rho * r * r, rho * r * r, In])
    np.testing.assert_allclose(rod.rest_strain(), [[0.0, th0 / r, 0.0]])
    X0, C = rod.quadratic_energy()
    np.testing.assert_allclose(C, [[r * r * 2.0, -r * r * 1.0, 0.0], [-r * r * 1.0, r * r * 5.0, 0.0], [0, 0, Nn]])
    assert rod.stiffness().shape == (1, 3, 1, 3)
    # the potential in physical strains: ½(θ₁ − θ₀, θ₂)𝕂(θ₁ − θ₀, θ₂)ᵀ + ½ℕ_nπ_n²
    th = rod.physical_strains(X[:, 0])
    d = np.stack([th[:, 0] - th0, th[:, 1]], axis=-1)
    U = 0.5 * np.einsum("ni,ij,nj->n", d, np.array(K), d) + 0.5 * Nn * th[:, 2] ** 2
    np.testing.assert_allclose(rod.potential(X), U, rtol=1e-13)
    # Q = (−rF₂, rF₁, M_n)
    F = rod.physical_stress(X[:, 0])
    np.testing.assert_allclose(rod.stress(X)[:, 0], np.stack([-r * F[:, 1], r * F[:, 0], F[:, 2]], -1), rtol=1e-13)
    # component maps are inverse to each other
    np.testing.assert_allclose(rod.strain_components(*th.T), X[:, 0], rtol=1e-14)
    np.testing.assert_allclose(rod.physical_velocities(rod.velocity_components(1.0, 2.0, 3.0)), [1.0, 2.0, 3.0])


@pytest.mark.parametrize("stiffness", [[3.0, 0.5], [[3.0, -0.8], [-0.8, 0.5]]])
def test_stress_is_gradient_of_potential(stiffness):
    rod = SphereRod(radius=1.7, stiffness=stiffness, bending=0.3, rest_stretch=1.2)
    X = rod.rest_strain() + 0.3 * np.random.default_rng(1).standard_normal((5, 1, 3))
    Q = rod.stress(X)
    eps = 1e-6
    fd = np.empty_like(X)
    for k in range(3):
        dX = np.zeros_like(X)
        dX[..., 0, k] = eps
        fd[..., 0, k] = (rod.potential(X + dX) - rod.potential(X - dX)) / (2 * eps)
    np.testing.assert_allclose(Q, fd, rtol=1e-7, atol=1e-9 * np.abs(Q).max())
    assert np.all(rod.potential(rod.rest_strain()) == 0.0)


def test_planar_parameters():
    rod = SphereRod(radius=50.0, density=2.0, rotational_inertia=0.1, stiffness=[3.0, 4.0], bending=0.5)
    planar = cartan.medium("planar-cosserat-rod", **rod.planar_parameters())
    np.testing.assert_array_equal(planar.stiffness_diagonal(), [3.0, 4.0, 0.5])
    np.testing.assert_array_equal(planar.inertia(), [2.0, 2.0, 0.1])
    with pytest.raises(ValueError, match="couples"):
        SphereRod(stiffness=[[1.0, 0.1], [0.1, 1.0]]).planar_parameters()
    with pytest.raises(ValueError, match="rest_stretch"):
        SphereRod(rest_stretch=2.0).planar_parameters()


# ---------------------------------------------------------------------------- conventions
def test_strain_and_velocity_components_mean_what_they_say():
    """∂_u(re₃) = θ₁e₁ + θ₂e₂, ∂_ue₁ = π_ne₂ − (θ₁/r)e₃; ∂_t(re₃) = V₁e₁ + V₂e₂, ∂_te₁ = Ω_ne₂ − (V₁/r)e₃."""
    r, th1, th2, pn = 3.0, 1.3, 0.2, 0.5
    rod = SphereRod(radius=r)
    grid = Grid(2001, length=1.0)
    R = rod.initial_state(grid, "arc", stretch=th1, shear=th2, curvature=pn, point=[1, 1, 0]).Phi
    h = grid.spacing[0]
    x = rod.centreline(R)
    mid = slice(1, -1)
    dx = (x[2:] - x[:-2]) / (2 * h)
    de1 = (R[2:, :, 0] - R[:-2, :, 0]) / (2 * h)
    e1, e2, e3 = R[mid, :, 0], R[mid, :, 1], R[mid, :, 2]
    np.testing.assert_allclose(dx, th1 * e1 + th2 * e2, atol=1e-5)
    np.testing.assert_allclose(de1, pn * e2 - th1 / r * e3, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(x, axis=-1), r, rtol=1e-14)
    np.testing.assert_allclose(R[0, :, 2], [2**-0.5, 2**-0.5, 0.0], atol=1e-15)
    # velocities: drift by τ with N from (V₁, V₂, Ω_n)
    V1, V2, Om = 0.7, -0.4, 1.5
    N = rod.velocity_components(V1, V2, Om)
    tau = 1e-6
    R1 = R[0] @ rod.group.exp(tau * N)
    R2 = R[0] @ rod.group.exp(-tau * N)
    np.testing.assert_allclose(r * (R1[:, 2] - R2[:, 2]) / (2 * tau), V1 * R[0, :, 0] + V2 * R[0, :, 1], atol=1e-8)
    np.testing.assert_allclose((R1[:, 0] - R2[:, 0]) / (2 * tau), Om * R[0, :, 1] - V1 / r * R[0, :, 2], atol=1e-8)


def test_initial_shapes_have_their_strains():
    """Great circles, latitude circles and arcs are orbits of one-parameter subgroups (constant
    strain): the lattice strains equal the continuum strains to round-off and rings close."""
    r = 2.0
    rod = SphereRod(radius=r, rest_stretch=1.5)
    beta, w = 0.7, 2
    L = 3.0
    cases = {
        "great-circle": (Grid(24, length=L, periodic=True), {"winding": w, "axis": [1, 2, 3]},
                         [0.0, 2 * math.pi * w / L, 0.0]),
        "latitude": (Grid(16, length=L, periodic=True), {"colatitude": beta, "phase": 0.3},
                     2 * math.pi / L * np.array([0.0, math.sin(beta), math.cos(beta)])),
        "arc": (Grid(11, length=L), {"curvature": 0.4, "shear": 0.1, "centered": True},
                [-0.1 / r, 1.5 / r, 0.4]),
        "arc-periodic": (Grid(11, length=L, periodic=True), {"curvature": 0.4}, [0.0, 1.5 / r, 0.4]),
    }
    for name, (grid, params, X) in cases.items():
        init = rod.initial_state(grid, name.removesuffix("-periodic"), **params)
        scheme = Lattice(Problem(rod, grid, init))
        state = scheme.initial_state()
        strains = scheme.strains(state)[:, 0, :]
        np.testing.assert_allclose(strains, np.broadcast_to(X, strains.shape), atol=1e-12, err_msg=name)
        if grid.periodic[0]:
            assert scheme.closure_residual(state) < 1e-13, name
    # the great circle about `axis` lies in the plane normal to it, e₂ = axis
    R = rod.initial_state(Grid(24, length=L, periodic=True), "great-circle", axis=[1, 2, 3]).Phi
    a = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
    np.testing.assert_allclose(R[:, :, 2] @ a, 0.0, atol=1e-15)
    np.testing.assert_allclose(R[:, :, 1], np.broadcast_to(a, (24, 3)), atol=1e-15)
    # latitude: e₃ at colatitude β, e₁ eastward, e₂ northward
    R = rod.initial_state(Grid(16, length=L, periodic=True), "latitude", colatitude=beta).Phi
    np.testing.assert_allclose(R[:, 2, 2], math.cos(beta), atol=1e-15)
    assert np.all(R[:, 2, 1] > 0) and np.allclose(R[:, 2, 0], 0.0, atol=1e-15)


def test_perturbed_shape():
    rod = SphereRod()
    grid = Grid(48, length=2 * math.pi, periodic=True)
    init = rod.initial_state(grid, "perturbed", amplitude=0.4, mode=3, director_amplitude=0.5, director_mode=2)
    R = init.Phi
    assert np.max(rod.group.defect(R)) < 1e-14
    lat = np.arcsin(R[:, 2, 2])
    phi = 2 * math.pi * np.arange(48) / 48
    np.testing.assert_allclose(lat, 0.4 * np.sin(3 * phi), atol=1e-14)
    scheme = Lattice(Problem(rod, grid, init))
    th = rod.physical_strains(scheme.strains(scheme.initial_state())[:, 0])
    assert np.abs(th[:, 1]).max() > 0.1 and np.abs(th[:, 2]).max() > 0.1  # shear and bending present
    flat = rod.initial_state(grid, "perturbed", amplitude=0.0)
    np.testing.assert_allclose(flat.Phi, rod.initial_state(grid, "great-circle").Phi, atol=1e-15)


def test_initial_state_errors():
    rod = SphereRod()
    open_grid, ring = Grid(10), Grid(10, periodic=True)
    for kind in ("great-circle", "latitude", "perturbed"):
        with pytest.raises(ValueError, match="periodic"):
            rod.initial_state(open_grid, kind, **({"colatitude": 1.0} if kind == "latitude" else {}))
    with pytest.raises(ValueError, match="colatitude"):
        rod.initial_state(ring, "latitude", colatitude=math.pi)
    with pytest.raises(ValueError, match="colatitude"):
        rod.initial_state(ring, "latitude")
    with pytest.raises(ValueError, match="winding"):
        rod.initial_state(ring, "great-circle", winding=1.5)
    with pytest.raises(ValueError, match="amplitude"):
        rod.initial_state(ring, "perturbed", amplitude=2.0)
    for mode in (math.inf, math.nan, 1e308, 11, 0):  # 10 nodes resolve modes 1 … 10 (higher ones alias)
        with pytest.raises(ValueError, match=r"mode must be an integer in \[1, 10\]"):
            rod.initial_state(ring, "perturbed", mode=mode)
        with pytest.raises(ValueError, match="director_mode"):
            rod.initial_state(ring, "perturbed", director_mode=mode)
    with pytest.raises(ValueError, match="no initial state kind 'helix'"):
        rod.initial_state(open_grid, "helix")
    with pytest.raises(ValueError, match="takes no parameter"):
        rod.initial_state(open_grid, "arc", radius=1.0)
    with pytest.raises(ValueError, match="velocity"):
        rod.initial_state(open_grid, "arc", velocity=[1.0, 2.0])
    with pytest.raises(ValueError, match="frames"):
        rod.initial_state(Grid(3), "arrays", frames=np.ones((3, 3, 3)))
    with pytest.raises(ValueError, match="direction"):
        rod.initial_state(open_grid, "arc", point=[1, 0, 0], direction=[2, 0, 0])
    # velocity and physical velocity add
    init = rod.initial_state(open_grid, "arc", velocity=[0.1, 0.2, 0.3], physical_velocity=[1.0, 0.0, 0.0])
    np.testing.assert_allclose(init.N, np.broadcast_to([0.1, 1.2, 0.3], (10, 3)))


# ---------------------------------------------------------------------------- drag
def test_drag_is_the_papers_dissipation():
    r, gT, gR = 3.0, 0.5, 0.02
    rod = SphereRod(radius=r)
    drag = rod.make_load("drag", gamma_T=gT, gamma_R=gR)
    assert isinstance(drag, Damping)
    np.testing.assert_allclose(drag.coefficients, [gT * r * r, gT * r * r, gR])
    V = np.random.default_rng(2).standard_normal((7, 3))
    N = rod.velocity_components(*V.T)
    drag.bind(rod)
    T = drag.force(None, N, 0.0)
    # power: −γ_T|V|² − γ_RΩ²; the force itself: T = (−rf₂, rf₁, m) with f = −γ_T V, m = −γ_RΩ
    np.testing.assert_allclose(np.sum(T * N, axis=-1), -gT * (V[:, 0] ** 2 + V[:, 1] ** 2) - gR * V[:, 2] ** 2)
    f = -gT * V[:, :2]
    np.testing.assert_allclose(T, np.stack([-r * f[:, 1], r * f[:, 0], -gR * V[:, 2]], -1), rtol=1e-14)
    with pytest.raises(ValueError, match="gamma_R"):
        rod.make_load("drag", gamma_T=1.0)
    with pytest.raises(ValueError, match="gamma_T"):
        rod.make_load("drag", gamma_T=-1.0, gamma_R=1.0)
    with pytest.raises(ValueError, match="no load kind 'gravity'"):
        rod.make_load("gravity", g=[0, 0, -1])


# ---------------------------------------------------------------------------- great circle: rest and slide
def _great_circle_problem(v=0.0, loads=()):
    """Closed rod of reference length L₀ = 2πr/θ₀ on the great circle: its stress-free state."""
    r, th0 = 2.0, 1.5
    rod = SphereRod(radius=r, rest_stretch=th0, stiffness=[[3.0, 0.4], [0.4, 2.0]], bending=0.7)
    grid = Grid(20, length=2 * math.pi * r / th0, periodic=True)
    X_gc = rod.rest_strain()[0]
    init = rod.initial_state(grid, "great-circle", axis=[0.0, 1.0, 1.0], velocity=v * X_gc)
    return Problem(rod, grid, init, loads=list(loads)), X_gc


@pytest.mark.parametrize("scheme_cls", [Lattice, Collocation])
def test_great_circle_is_a_rest_state(scheme_cls):
    drag = Damping([1.0, 1.0, 0.1])
    for integ, loads in ((LieVerlet(), ()), (Overdamped(order=1), (drag,)), (Overdamped(order=2), (drag,))):
        prob, X_gc = _great_circle_problem(loads=loads)
        scheme = scheme_cls(prob, track_frames=True)
        state = scheme.initial_state()
        W = scheme.force(state, np.zeros_like(state.S), 0.0)
        assert np.abs(W).max() < 1e-12
        assert scheme.potential_energy(state) < 1e-24
        dt = 0.5 * integ.dt_max(scheme, state)
        _run(scheme, integ, state, dt, 100)
        np.testing.assert_allclose(scheme.frames(state), prob.initial.Phi, atol=1e-13)
        np.testing.assert_allclose(scheme.strains(state)[:, 0], np.broadcast_to(X_gc, (20, 3)), atol=1e-13)


@pytest.mark.parametrize("v", [0.1, -3.0, 40.0, 1e3])
def test_rigid_slide_along_the_great_circle_has_zero_stress(v):
    """N = v·X_gc (every point moves along the circle with speed V₁ = vθ₀): the strain stays X_gc,
    the stress is zero at any v, and the rod turns rigidly about the circle's axis at rate vθ₀/r."""
    prob, X_gc = _great_circle_problem(v=v)
    rod = prob.medium
    scheme = Lattice(prob, track_frames=True)
    state = scheme.initial_state()
    np.testing.assert_allclose(rod.physical_velocities(scheme.velocity(state))[:, 0], v * rod.rest_stretch)
    # the ring spins about its axis at ω = vθ₀/r; lie-verlet's splitting resolves a fast spin
    # only for ωΔt ≲ 0.02 here (𝕀_n/ρ₀r² = 0.0025: the frame's own spin is the stiff part), a
    # limit its CFL estimate (from the stiffness alone) does not see
    omega = abs(v) * rod.rest_stretch / rod.radius
    dt, nsteps = min(1e-3, 0.01 / omega), 200
    stresses = []
    for _ in range(nsteps):
        LieVerlet().step(scheme, state, dt)
        stresses.append(np.abs(rod.stress(scheme.strains(state))).max())
    scale = np.abs(rod.quadratic_energy()[1]).max() * np.abs(X_gc).max()
    assert max(stresses) <= 1e-13 * scale
    np.testing.assert_allclose(scheme.strains(state)[:, 0], np.broadcast_to(X_gc, (20, 3)), atol=1e-13)
    np.testing.assert_allclose(scheme.velocity(state), prob.initial.N, rtol=1e-12, atol=1e-12 * abs(v))
    axis = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)
    angle = v * rod.rest_stretch / rod.radius * dt * nsteps
    turn = rod.group.exp(angle * axis)
    np.testing.assert_allclose(scheme.frames(state), turn @ prob.initial.Phi, atol=1e-11 * max(1.0, abs(angle)))
    assert scheme.kinetic_energy(state) == pytest.approx(0.5 * rod.density * (v * rod.rest_stretch) ** 2
                                                         * prob.grid.length[0], rel=1e-12)


# ---------------------------------------------------------------------------- VERIFICATION: circle of latitude
def _metric_rod():
    """Unit sphere, L₀ = 1, U = ½|X − X_gc|² in so(3) components.

    X_gc = (0, 2π, 0) is the strain of the great circle traversed once by u ∈ [0, 1); in the
    medium's parameters U = ½(θ₁ − θ₀, θ₂)𝕂(θ₁ − θ₀, θ₂)ᵀ + ½ℕ_nπ_n² = ½|X − X₀|² means
    θ₀ = 2πr/L₀ = 2π, 𝕂 = 𝟙/r² = 𝟙, ℕ_n = 1.
    """
    rod = SphereRod(radius=1.0, stiffness=[1.0, 1.0], bending=1.0, rest_stretch=2 * math.pi)
    X = rod.rest_strain() + np.random.default_rng(3).standard_normal((4, 1, 3))
    np.testing.assert_allclose(rod.potential(X), 0.5 * np.sum((X - [0.0, 2 * math.pi, 0.0]) ** 2, axis=(-2, -1)))
    return rod


def _beta_exact(t, beta0, lam):
    """sin β(t) = tanh(4π²t/λ + artanh sin β₀), β the colatitude (on the branch of β₀)."""
    s = math.tanh(4 * math.pi**2 * t / lam + math.atanh(math.sin(beta0)))
    return math.asin(s) if beta0 <= math.pi / 2 else math.pi - math.asin(s)


def _latitude_run(beta0, lam, n, dt, T, order, scheme_cls=Lattice, **opts):
    rod = _metric_rod()
    grid = Grid(n, length=1.0, periodic=True)
    init = rod.initial_state(grid, "latitude", colatitude=beta0)
    prob = Problem(rod, grid, init, loads=[rod.make_load("drag", gamma_T=lam, gamma_R=lam)])
    scheme = scheme_cls(prob, track_frames=True, **opts)
    state = scheme.initial_state()
    _run(scheme, Overdamped(order=order), state, dt, round(T / dt))
    z = scheme.frames(state)[:, 2, 2]
    return np.arccos(z), scheme, state


def test_latitude_circle_energy_and_force():
    """U(β) = 4π²(1 − sin β) and the force D*Q = (4π² cos β, 0, 0) at every node: λβ̇ = 4π² cos β."""
    rod = _metric_rod()
    beta = 0.6
    grid = Grid(12, length=1.0, periodic=True)
    scheme = Lattice(Problem(rod, grid, rod.initial_state(grid, "latitude", colatitude=beta)))
    state = scheme.initial_state()
    assert scheme.potential_energy(state) == pytest.approx(4 * math.pi**2 * (1 - math.sin(beta)), rel=1e-13)
    W = scheme.force(state, np.zeros_like(state.S), 0.0)
    np.testing.assert_allclose(W, np.broadcast_to([4 * math.pi**2 * math.cos(beta), 0, 0], W.shape), atol=1e-11)


@pytest.mark.parametrize("beta0", [0.3, 2.5])
@pytest.mark.parametrize(("order", "expected"), [(1, 1.0), (2, 2.0)])
def test_latitude_circle_follows_tanh_law_at_the_integrators_order(beta0, order, expected):
    """VERIFICATION.md §4: a closed rod on the circle of colatitude β₀ stays a circle of latitude
    and follows sin β(t) = tanh(4π²t/λ + artanh sin β₀) (β the colatitude; for β₀ > π/2 on the
    southern branch β = π − arcsin).  Error at T against Δt = T/8 … T/64: the overdamped
    integrator's order (1: Lie–Euler, 2: RKMK2).  The lattice is exact in space here (the
    circle is a one-parameter orbit, its edge strains and forces are exact), so n = 8 suffices."""
    lam, T = 1.0, 0.02
    errors = []
    for k in (8, 16, 32, 64):
        beta, _, _ = _latitude_run(beta0, lam, 8, T / k, T, order)
        assert np.ptp(beta) < 1e-13  # still a circle of latitude
        errors.append(abs(beta.mean() - _beta_exact(T, beta0, lam)))
    p = _observed_orders(errors)
    assert np.all(np.abs(p - expected) < 0.1), (errors, p)
    assert errors[-1] < (2e-3 if order == 1 else 2e-5)


@pytest.mark.parametrize(("scheme_cls", "opts"), [(Lattice, {}), (Collocation, {"derivative": "fd2"}),
                                                  (Collocation, {"derivative": "fourier"})])
def test_latitude_circle_is_exact_in_space(scheme_cls, opts):
    """The spatial error of the latitude case is round-off for every grid: the error at T is the
    time-stepping error alone, the same for n = 6 … 48."""
    errors = []
    for n in (6, 12, 24, 48):
        beta, _, _ = _latitude_run(0.4, 4 * math.pi**2, n, 1e-3, 0.2, 2, scheme_cls, **opts)
        errors.append(beta.mean() - _beta_exact(0.2, 0.4, 4 * math.pi**2))
    assert abs(errors[0]) > 1e-9  # the O(Δt²) time error is there …
    assert np.ptp(errors) < 1e-13  # … and nothing depends on dx


@pytest.mark.slow
def test_latitude_circle_reaches_the_great_circle():
    lam, T = 2.0, 0.5
    beta, scheme, state = _latitude_run(0.1, lam, 16, 1e-4, T, 2)
    assert abs(beta.mean() - _beta_exact(T, 0.1, lam)) < 1e-8
    assert abs(beta.mean() - math.pi / 2) < 1e-3
    assert scheme.potential_energy(state) < 1e-4


def test_lattice_is_second_order_in_space_on_a_perturbed_ring():
    """Self-convergence of the overdamped relaxation of a perturbed ring (no exact solution):
    differences of centrelines at the shared nodes between n and 2n fall as h²."""
    rod = SphereRod(radius=1.0, stiffness=[4.0, 4.0], bending=1.0)
    T, dt = 0.02, 5e-5
    lines = {}
    for n in (16, 32, 64, 128):
        grid = Grid(n, length=2 * math.pi, periodic=True)
        init = rod.initial_state(grid, "perturbed", amplitude=0.3, mode=2, director_amplitude=0.3, director_mode=1)
        prob = Problem(rod, grid, init, loads=[rod.make_load("drag", gamma_T=1.0, gamma_R=1.0)])
        scheme = Lattice(prob)
        state = scheme.initial_state()
        _run(scheme, Overdamped(order=2), state, dt, round(T / dt))
        lines[n] = rod.centreline(scheme.frames(state))
    diffs = [np.abs(lines[n] - lines[2 * n][::2]).max() for n in (16, 32, 64)]
    p = _observed_orders(diffs)
    assert np.all((p > 1.8) & (p < 2.3)), (diffs, p)


# ---------------------------------------------------------------------------- r → ∞: the planar rod
def _limit_difference(r, dt=2e-3, T=0.5):
    data = {"stiffness": [20.0, 10.0], "bending": 1.0, "density": 1.0, "rotational_inertia": 0.05}
    grid = Grid(21, length=2.0)
    u = grid.coordinates()
    vel = np.stack([0.1 * np.sin(math.pi * u / 2), 0.5 * np.cos(math.pi * u / 2), np.full(21, 0.3)], -1)
    rod = SphereRod(radius=r, **data)
    planar = cartan.medium("planar-cosserat-rod", **rod.planar_parameters())
    sphere = Lattice(Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0, centered=True,
                                                          physical_velocity=vel)))
    plane = Lattice(Problem(planar, grid, planar.initial_state(grid, "arc", curvature=1.0, centered=True,
                                                               velocity=vel)))
    s1, s2 = sphere.initial_state(), plane.initial_state()
    nsteps = round(T / dt)
    _run(sphere, LieVerlet(), s1, dt, nsteps)
    _run(plane, LieVerlet(), s2, dt, nsteps)
    strain = np.abs(rod.physical_strains(sphere.strains(s1)[:, 0]) - plane.strains(s2)[:, 0]).max()
    velocity = np.abs(rod.physical_velocities(sphere.velocity(s1)) - plane.velocity(s2)).max()
    moved = np.abs(plane.strains(s2)[:, 0] - [1.0, 0.0, 1.0]).max()
    return strain, velocity, moved


def test_large_radius_limit_is_the_planar_rod():
    """The same rod data (stretch, shear, geodesic bending, mass, initial strains and physical
    velocities) on spheres of radius 10, 100, 1000 vs the planar rod, Lie–Verlet with the same
    Δt: the differences of strains (θ₁, θ₂, π) and velocities (V₁, V₂, Ω) fall as r⁻²."""
    radii = [10.0, 100.0, 1000.0]
    res = [_limit_difference(r) for r in radii]
    assert min(m for _, _, m in res) > 0.1  # the rod really moved
    for k in (0, 1):
        slope = np.polyfit(np.log(radii), np.log([x[k] for x in res]), 1)[0]
        assert -2.2 <= slope <= -1.8, (k, slope, res)


# ---------------------------------------------------------------------------- geometry under lie-verlet
def test_group_membership_and_ring_closure_under_lie_verlet():
    rod = SphereRod(radius=1.0, stiffness=[10.0, 10.0], bending=0.5, rotational_inertia=0.02)
    grid = Grid(24, length=2 * math.pi, periodic=True)
    phi = 2 * math.pi * np.arange(24) / 24
    vel = np.stack([0.3 * np.sin(2 * phi), 0.5 * np.cos(phi), 0.2 * np.sin(3 * phi)], -1)
    init = rod.initial_state(grid, "perturbed", amplitude=0.4, mode=2, director_amplitude=0.4, velocity=vel)
    scheme = Lattice(Problem(rod, grid, init), track_frames=True)
    state = scheme.initial_state()
    integ = LieVerlet()
    dt = 0.1 * integ.dt_max(scheme, state)
    E0 = scheme.kinetic_energy(state) + scheme.potential_energy(state)
    energies = []
    for _ in range(1000):
        integ.step(scheme, state, dt)
        energies.append(scheme.kinetic_energy(state) + scheme.potential_energy(state))
    R = scheme.frames(state)
    assert np.abs(R - init.Phi).max() > 0.1  # it moved
    assert np.max(rod.group.defect(R)) <= 1e-12
    assert np.max(rod.group.defect(state.arrays["G_u"])) <= 1e-12
    assert scheme.integrability_residual(state) <= 1e-12
    assert scheme.closure_residual(state) <= 1e-12
    assert np.max(np.abs(np.array(energies) - E0)) / E0 < 1e-2


# ---------------------------------------------------------------------------- scene and figure
SCHEMA = {"name", "description", "medium", "parameters", "grid", "initial", "run"}


def test_scene_file_and_a_few_steps():
    data = tomllib.loads(pathlib.Path(SCENES["sphere-rod-relax"]).read_text())
    assert SCHEMA <= set(data)
    assert data["name"] == "sphere-rod-relax" and data["medium"] == "sphere-rod"
    scene = cartan.scene("sphere-rod-relax")
    prob = scene.problem
    rod = prob.medium
    # reference length 2πr: the stress-free state is a great circle
    assert prob.grid.length[0] * rod.rest_stretch == pytest.approx(2 * math.pi * rod.radius)
    scheme = Lattice(prob)
    state = scheme.initial_state()
    assert scene.dt <= Overdamped().dt_max(scheme, state)
    ds = cartan.simulate("sphere-rod-relax", t_end=20 * scene.dt, save_every=5, compiled=False)  # Python path
    U = ds.potential_energy.values
    assert len(U) == 5 and np.all(np.diff(U) < 0)
    assert ds.frame.shape == (5, prob.grid.shape[0], 3, 3)
    assert ds.position.shape == (5, prob.grid.shape[0], 3)
    assert float(ds.group_defect.max()) < 1e-12


def test_plot_sphere_rod(tmp_path):
    from cartan_sphere_rod.plotting import plot_sphere_rod

    ds = cartan.simulate("sphere-rod-relax", t_end=2e-3, save_every=5, compiled=False)  # Python path
    fig = plot_sphere_rod(ds, tmp_path / "rod.png")
    assert (tmp_path / "rod.png").stat().st_size > 10_000
    assert len(fig.axes) == 3


@pytest.mark.slow
def test_scene_relaxes_to_a_great_circle():
    ds = cartan.simulate("sphere-rod-relax")
    rod = cartan.scene("sphere-rod-relax").problem.medium
    U = ds.potential_energy.values
    assert np.all(np.diff(U) <= 0) and U[-1] < 1e-8 * U[0]
    th = rod.physical_strains(ds.X.values[-1])
    assert np.abs(th - [1.0, 0.0, 0.0]).max() < 1e-4
    # a great circle: the centreline lies in a plane through the centre
    x = ds.position.values[-1]
    np.testing.assert_allclose(x, rod.centreline(ds.frame.values[-1]), atol=1e-14)
    normal = np.linalg.svd(x)[2][-1]
    assert np.abs(x @ normal).max() < 1e-4
    # energy balance V(t) + dissipated(t) = V(0), to the first-order integrator's O(Δt): the
    # error (1.9 % of V(0)) is made in the first save interval, where V drops by 2.6 decades
    balance = np.abs((ds.potential_energy + ds.dissipated_energy - U[0]).values)
    assert balance.max() < 3e-2 * U[0]
    assert balance[-1] - balance[1] < 1e-3 * U[0]


def test_arrays_kind_and_holonomy():
    rod = SphereRod()
    grid = Grid(8, length=1.0, periodic=True)
    arc = rod.initial_state(grid, "arc", curvature=0.3)
    assert arc.holonomy is not None and rod.group.defect(arc.holonomy) < 1e-14
    again = rod.initial_state(grid, "arrays", frames=arc.Phi, holonomy=arc.holonomy)
    np.testing.assert_array_equal(again.Phi, arc.Phi)
    s1 = Lattice(Problem(rod, grid, arc)).initial_state()
    s2 = Lattice(Problem(rod, grid, InitialState(Phi=again.Phi, holonomy=again.holonomy))).initial_state()
    np.testing.assert_allclose(s1.arrays["G_u"], s2.arrays["G_u"], atol=0)
    np.testing.assert_allclose(Lattice(Problem(rod, grid, arc)).strains(s1)[:, 0],
                               np.broadcast_to([0.0, 1.0, 0.3], (8, 3)), atol=1e-13)
