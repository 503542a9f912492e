"""The Cosserat rod media (paper §VI.C): parameters, stresses, loads, initial states, scenes,
and their dynamics on the ``lattice`` scheme (VERIFICATION.md §4, cosserat-rod rows).

Conventions used throughout: e₁ along the rest tangent, rest strain θ₀ = (1, 0, 0);
SE(3) components (θ; π) / (V; Ω), translation first.
"""

from __future__ import annotations

import json
import math
import pathlib
import tomllib

import numpy as np
import pytest
from cartan_cosserat import PLANAR_COMPONENTS, CosseratRod, Gravity, PlanarCosseratRod
from cartan_cosserat.plugin import SCENES

import cartan
from cartan.grid import Grid
from cartan.integrators import ForwardEuler, LieEuler, LieVerlet, Overdamped
from cartan.problem import Clamped, Damping, Free, InitialState, Problem
from cartan.schemes.lattice import Lattice

# PyElastica's butterfly material (E, ν, radius, density), a soft rod that moves a lot
BUTTERFLY = {"E": 1e4, "poisson": 0.5, "radius": 0.25, "density": 5000.0}


def _rod(**kw):
    return CosseratRod(**{**BUTTERFLY, **kw})


def _energy(scheme, state):
    return scheme.kinetic_energy(state) + scheme.potential_energy(state)


def _run(scheme, integrator, state, dt, nsteps, every=None):
    """Step ``nsteps`` times; call ``every(state)`` after each step when given."""
    for _ in range(nsteps):
        integrator.step(scheme, state, dt)
        if every is not None:
            every(state)
    return state


# ---------------------------------------------------------------------------- registry
def test_registered():
    media = cartan.registry("media")
    assert media["cosserat-rod"] is CosseratRod
    assert media["planar-cosserat-rod"] is PlanarCosseratRod
    assert set(SCENES) <= set(cartan.registry("scenes"))


# ---------------------------------------------------------------------------- parameters
@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"E": -1.0}, "E"),
        ({"E": float("nan")}, "E"),
        ({"E": "stiff"}, "E"),
        ({"radius": 0.0}, "radius"),
        ({"density": -5.0}, "density"),
        ({"poisson": 0.7}, "poisson"),
        ({"poisson": float("nan")}, "poisson"),
        ({"shear_coefficient": -0.1}, "shear_coefficient"),
        ({"rest_curvature": [0.0, float("nan"), 0.0]}, "rest_curvature"),
        ({"rest_curvature": [0.0, 1.0]}, "rest_curvature"),
    ],
)
def test_material_parameters_validated(kwargs, name):
    with pytest.raises(ValueError, match=name):
        _rod(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"stretch_shear": [-1.0, 1.0, 1.0]}, "stretch_shear"),
        ({"bend_twist": [1.0, float("nan"), 1.0]}, "bend_twist"),
        ({"bend_twist": [1.0, 1.0]}, "bend_twist"),
        ({"mass": 0.0}, "mass"),
        ({"rotational_inertia": [1.0, -2.0, 3.0]}, "rotational_inertia"),
    ],
)
def test_direct_parameters_validated(kwargs, name):
    base = {
        "stretch_shear": [1.0, 1.0, 1.0],
        "bend_twist": [1.0, 1.0, 1.0],
        "mass": 1.0,
        "rotational_inertia": [1.0, 1.0, 1.0],
    }
    with pytest.raises(ValueError, match=name):
        CosseratRod(**{**base, **kwargs})


def test_parameter_forms_exclusive_and_complete():
    with pytest.raises(ValueError, match="not both"):
        CosseratRod(E=1.0, G=1.0, radius=1.0, density=1.0, mass=1.0)
    with pytest.raises(ValueError, match="exactly one of 'G'"):
        CosseratRod(E=1.0, G=1.0, poisson=0.3, radius=1.0, density=1.0)
    with pytest.raises(ValueError, match="density"):
        CosseratRod(E=1.0, G=1.0, radius=1.0)
    with pytest.raises(ValueError, match="bend_twist"):
        CosseratRod(stretch_shear=[1, 1, 1], mass=1.0, rotational_inertia=[1, 1, 1])
    with pytest.raises(ValueError):
        CosseratRod()


def test_material_constants_and_parameters_roundtrip():
    E, nu, a, rho = 1e6, 0.25, 0.1, 1000.0
    rod = CosseratRod(E=E, poisson=nu, radius=a, density=rho)
    G = E / (2 * (1 + nu))
    A, I = math.pi * a**2, math.pi * a**4 / 4
    alpha = 27.0 / 28.0
    np.testing.assert_allclose(
        rod.stiffness_diagonal(), [E * A, alpha * G * A, alpha * G * A, G * 2 * I, E * I, E * I]
    )
    np.testing.assert_allclose(rod.inertia(), [rho * A] * 3 + [rho * 2 * I, rho * I, rho * I])
    np.testing.assert_array_equal(rod.rest_strain(), [[1, 0, 0, 0, 0, 0]])
    params = json.loads(json.dumps(rod.parameters()))
    again = CosseratRod(**params)
    np.testing.assert_array_equal(again.stiffness_diagonal(), rod.stiffness_diagonal())
    assert rod.wave_speed() == pytest.approx(math.sqrt(E / rho), rel=1e-12)
    planar = PlanarCosseratRod(**params)
    idx = list(PLANAR_COMPONENTS)
    np.testing.assert_array_equal(planar.stiffness_diagonal(), rod.stiffness_diagonal()[idx])
    np.testing.assert_array_equal(planar.inertia(), rod.inertia()[idx])


@pytest.mark.parametrize("medium", [_rod(rest_curvature=[0.3, -0.2, 0.7]), _rod().planar()])
def test_stress_is_gradient_of_potential(medium):
    rng = np.random.default_rng(1)
    r = medium.group.dim
    X = medium.rest_strain() + 0.3 * rng.standard_normal((5, 1, r))
    Q = medium.stress(X)
    assert Q.shape == X.shape
    eps = 1e-6
    fd = np.empty_like(X)
    for k in range(r):
        dX = np.zeros_like(X)
        dX[..., 0, k] = eps
        fd[..., 0, k] = (medium.potential(X + dX) - medium.potential(X - dX)) / (2 * eps)
    np.testing.assert_allclose(Q, fd, rtol=1e-7, atol=1e-9 * np.abs(Q).max())
    assert np.all(medium.potential(medium.rest_strain()) == 0.0)


# ---------------------------------------------------------------------------- initial states
def test_initial_shapes_have_their_strains():
    """Straight, arc, ring and helix are orbits of one-parameter subgroups (constant strain), so
    their lattice edge strains equal the continuum strain to round-off."""
    rod = _rod()
    L = 2.0
    a, pitch = 0.3, 0.5
    b = pitch / (2 * math.pi)
    c2 = a * a + b * b
    cases = {
        "straight": (Grid(21, length=L), {"direction": [0, 1, 1], "stretch": 1.1}, [1.1, 0, 0, 0, 0, 0]),
        "arc": (Grid(21, length=L), {"curvature": 1.5, "centered": True}, [1, 0, 0, 0, 0, 1.5]),
        # Frenet frame (tangent, principal normal, binormal): π = (τ, 0, κ)
        "helix": (Grid(21, length=L), {"radius": a, "pitch": pitch}, [1, 0, 0, b / c2, 0, a / c2]),
        "ring": (Grid(16, length=L, periodic=True), {}, [1, 0, 0, 0, 0, 2 * math.pi / L]),
    }
    for kind, (grid, params, X) in cases.items():
        scheme = Lattice(Problem(rod, grid, rod.initial_state(grid, kind, **params)))
        state = scheme.initial_state()
        strains = scheme.strains(state)[:, 0, :]
        np.testing.assert_allclose(strains, np.broadcast_to(X, strains.shape), atol=1e-12, err_msg=kind)
        if kind == "ring":
            assert scheme.closure_residual(state) < 1e-13


def test_initial_state_errors():
    rod = _rod()
    with pytest.raises(ValueError, match="periodic"):
        rod.initial_state(Grid(10), "ring")
    straight = rod.initial_state(Grid(10, length=2.0, periodic=True), "straight")
    assert np.allclose(straight.holonomy[1:, 0], [2.0, 0.0, 0.0]) and np.allclose(straight.holonomy[1:, 1:], np.eye(3))
    with pytest.raises(ValueError, match="no initial state kind 'spiral'"):
        rod.initial_state(Grid(10), "spiral")
    with pytest.raises(ValueError, match="velocity"):
        rod.initial_state(Grid(10), "straight", velocity=[1, 2, 3])
    with pytest.raises(ValueError, match="frames"):
        rod.initial_state(Grid(3), "arrays", positions=np.zeros((3, 3)), frames=np.ones((3, 3, 3)))
    with pytest.raises(ValueError, match="helix"):
        _rod().planar().initial_state(Grid(10), "helix", radius=1.0, pitch=1.0)
    with pytest.raises(ValueError, match="g"):
        Problem(rod, Grid(5), rod.initial_state(Grid(5), "straight"), loads=[Gravity([0, -9.81], 1.0)])


def test_rigid_velocity_is_rigid():
    """A rigid twist gives body velocities that leave every edge element unchanged."""
    rod = _rod()
    grid = Grid(9, length=1.0)
    init = rod.initial_state(
        grid, "helix", radius=0.2, pitch=0.3, rigid_velocity=[0.1, -0.2, 0.3, 1.0, 2.0, -0.5]
    )
    g = rod.group
    Phi, N = init.Phi, init.N
    G = g.compose(g.inverse(Phi[:-1]), Phi[1:])
    # the drift Φ ← Φ exp(τN) with these N is a rigid motion: edges unchanged
    tau = 0.01
    Phi1 = g.compose(Phi, g.exp(tau * N))
    G1 = g.compose(g.inverse(Phi1[:-1]), Phi1[1:])
    np.testing.assert_allclose(G1, G, atol=1e-14)


# ---------------------------------------------------------------------------- ring: geometry to round-off
def _wobbly_ring(n=8, L=2.0):
    rod = _rod()
    grid = Grid(n, length=L, periodic=True)
    u = 2 * math.pi * np.arange(n) / n
    vel = np.stack(
        [
            0.3 * np.cos(2 * u),
            0.2 * np.sin(u),
            0.4 * np.sin(2 * u),
            1.0 * np.cos(u),
            0.5 * np.sin(3 * u),
            0.7 + 0 * u,
        ],
        axis=-1,
    )
    init = rod.initial_state(
        grid,
        "ring",
        amplitude=0.2,
        mode=2,
        out_of_plane=0.15,
        velocity=vel,
        rigid_velocity=[0, 0, 0, 0.5, 1.0, 2.0],
    )
    # remove the net linear momentum so that the ring stays near the origin
    R = init.Phi[:, 1:, 1:]
    v_mean = np.einsum("nij,nj->i", R, init.N[:, :3]) / n
    init.N[:, :3] -= np.einsum("nji,j->ni", R, v_mean)
    return Problem(rod, grid, init)


def _ring_geometry_check(nsteps):
    prob = _wobbly_ring()
    scheme = Lattice(prob, track_frames=True)
    state = scheme.initial_state()
    integ = LieVerlet()
    dt = 0.2 * integ.dt_max(scheme, state)
    E0 = _energy(scheme, state)
    x0 = scheme.frames(state)[:, 1:, 0].copy()
    _run(scheme, integ, state, dt, nsteps)
    Phi = scheme.frames(state)
    R = Phi[:, 1:, 1:]
    # the motion is large: the centreline moved by more than its own radius of ~0.3
    assert np.abs(Phi[:, 1:, 0] - x0).max() > 0.3
    assert scheme.integrability_residual(state) <= 1e-12
    assert scheme.closure_residual(state) <= 1e-12
    assert np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max() <= 1e-12
    G = state.arrays["G_u"]
    assert np.abs(np.swapaxes(G[:, 1:, 1:], -1, -2) @ G[:, 1:, 1:] - np.eye(3)).max() <= 1e-12
    assert abs(_energy(scheme, state) - E0) / E0 < 1e-2


def test_ring_closure_lie_verlet():
    _ring_geometry_check(1000)


@pytest.mark.slow
def test_ring_closure_lie_verlet_1e4_steps():
    _ring_geometry_check(10_000)


def test_forward_euler_leaves_the_group_lie_euler_does_not():
    results = {}
    for integ in (ForwardEuler(), LieEuler()):
        prob = _wobbly_ring()
        scheme = Lattice(prob, track_frames=True)
        state = scheme.initial_state()
        dt = 0.02 * LieVerlet().dt_max(scheme, state)
        _run(scheme, integ, state, dt, 200)
        Phi = scheme.frames(state)
        G = state.arrays["G_u"]
        prod = G[0]
        for k in range(1, len(G)):
            prod = prod @ G[k]
        results[integ.name] = (
            float(np.max(prob.medium.group.defect(Phi))),
            float(np.abs(prod - np.eye(4)).max()),
        )
    fe_defect, fe_closure = results["forward-euler"]
    le_defect, le_closure = results["lie-euler"]
    assert fe_defect > 1e-6 and fe_closure > 1e-6
    assert le_defect <= 1e-12 and le_closure <= 1e-12


# ---------------------------------------------------------------------------- butterfly: energy and momentum
def _butterfly(n=11, **velocity):
    rod = _rod()
    grid = Grid(n, length=3.0)
    return Problem(rod, grid, rod.initial_state(grid, "arc", curvature=0.5, centered=True, **velocity))


def _max_energy_error(dt, T):
    scheme = Lattice(_butterfly())
    state = scheme.initial_state()
    E0 = _energy(scheme, state)
    errs = []
    _run(scheme, LieVerlet(), state, dt, round(T / dt), lambda s: errs.append(abs(_energy(scheme, s) - E0)))
    return max(errs) / E0, errs


def test_butterfly_energy_error_second_order():
    """Lie–Verlet: max relative energy error over [0, 1.2] scales as Δt²; no drift."""
    e1, errs = _max_energy_error(4e-3, 1.2)
    e2, _ = _max_energy_error(2e-3, 1.2)
    ratio = e1 / e2
    assert 3.5 <= ratio <= 4.5, ratio
    assert e1 < 1e-4
    # bounded: the second half of the run is no worse than the first (an oscillation, not a drift)
    half = len(errs) // 2
    assert max(errs[half:]) < 2 * max(errs[:half])


def test_butterfly_momentum_conserved():
    prob = _butterfly(rigid_velocity=[0.3, -0.1, 0.2, 0.4, -0.3, 1.0])
    scheme = Lattice(prob)
    state = scheme.initial_state()
    J0 = scheme.total_momentum(state)
    _run(scheme, LieVerlet(), state, 4e-3, 250)
    J1 = scheme.total_momentum(state)
    lin, ang = np.linalg.norm(J0[:3]), np.linalg.norm(J0[3:])
    assert np.linalg.norm(J1[:3] - J0[:3]) <= 1e-10 * lin
    assert np.linalg.norm(J1[3:] - J0[3:]) <= 1e-10 * ang


# ---------------------------------------------------------------------------- SE(3) with planar data ≡ SE(2)
def test_planar_scene_se3_equals_se2():
    rod3 = _rod(rest_curvature=[0.0, 0.0, 0.2])
    rod2 = rod3.planar()
    grid = Grid(12, length=3.0)
    u = grid.coordinates()
    v3 = np.zeros((12, 6))
    v3[:, 0], v3[:, 1], v3[:, 5] = 0.1 * np.sin(u), 0.3 * np.cos(2 * u), 0.8 * u
    loads3 = [rod3.make_load("gravity", g=[0.0, -9.81, 0.0]), Damping([0.5, 0.5, 0.5, 0.1, 0.1, 0.1])]
    loads2 = [rod2.make_load("gravity", g=[0.0, -9.81]), Damping([0.5, 0.5, 0.1])]
    b3 = {"start": Clamped(), "end": Free(load=[0.2, -0.5, 0.0, 0.0, 0.0, 0.1])}
    b2 = {"start": Clamped(), "end": Free(load=[0.2, -0.5, 0.1])}
    idx = list(PLANAR_COMPONENTS)
    p3 = Problem(
        rod3, grid, rod3.initial_state(grid, "arc", curvature=0.7, angle=0.3, velocity=v3), b3, loads3
    )
    p2 = Problem(
        rod2, grid, rod2.initial_state(grid, "arc", curvature=0.7, angle=0.3, velocity=v3[:, idx]), b2, loads2
    )
    s3, s2 = Lattice(p3), Lattice(p2)
    st3, st2 = s3.initial_state(), s2.initial_state()
    i3, i2 = LieVerlet(), LieVerlet()
    _run(s3, i3, st3, 2e-3, 300)
    _run(s2, i2, st2, 2e-3, 300)
    P3, P2 = s3.frames(st3), s2.frames(st2)
    assert np.abs(P3[:, 1:3, 0] - P2[:, 1:, 0]).max() <= 1e-12
    assert np.abs(P3[:, 1:3, 1:3] - P2[:, 1:, 1:]).max() <= 1e-12
    # the motion stays exactly in the plane: z, e₁·ẑ, e₂·ẑ, e₃ − ẑ are zero, not just small
    assert np.all(P3[:, 3, :] == [0, 0, 0, 1]) and np.all(P3[:, :, 3] == [0, 0, 0, 1])
    X3, X2 = s3.strains(st3)[..., 0, :], s2.strains(st2)[..., 0, :]
    assert np.abs(X3[:, idx] - X2).max() <= 1e-12
    assert np.abs(st3.S[:, idx] - st2.S).max() <= 1e-12 * np.abs(st2.S).max()  # S ~ 5e3 here
    assert abs(s3.potential_energy(st3) - s2.potential_energy(st2)) <= 1e-12 * abs(s2.potential_energy(st2))
    # the run moved: clearly away from the initial arc
    assert np.abs(P2[:, 1:, 0] - p2.initial.Phi[:, 1:, 0]).max() > 1e-2


# ---------------------------------------------------------------------------- free rigid body
def test_uncoupled_nodes_are_free_rigid_bodies():
    """With zero stiffness each node is a free rigid body (VERIFICATION.md §4: 𝕀 = diag(1, 2, 3),
    ω₀ = (1, 0, 0.5)): the lattice + lie-verlet node equals the rigid-body Lie–Verlet splitting
    to round-off, conserves |M| to round-off and energy to O(Δt²), and follows the exact
    (Jacobi elliptic) motion to O(Δt²)."""
    from cartan.rigid_body import rigid_body_exact, step_rigid_body

    inertia = np.array([1.0, 2.0, 3.0])
    w0 = np.array([1.0, 0.0, 0.5])
    rod = CosseratRod(stretch_shear=[0, 0, 0], bend_twist=[0, 0, 0], mass=1.0, rotational_inertia=inertia)
    grid = Grid(2, length=1.0)
    prob = Problem(rod, grid, rod.initial_state(grid, "straight", velocity=[0, 0, 0, *w0]))
    scheme = Lattice(prob)
    state = scheme.initial_state()
    dt, nsteps = 0.01, 300
    M0 = inertia * w0
    E0 = 0.5 * np.sum(M0**2 / inertia)
    norms, energies = [], []

    def record(st):
        M = st.S[0, 3:]
        norms.append(np.linalg.norm(M))
        energies.append(0.5 * np.sum(M**2 / inertia))

    _run(scheme, LieVerlet(), state, dt, nsteps, record)
    R = scheme.frames(state)[:, 1:, 1:]
    M = state.S[:, 3:]
    _, R_ref, M_ref = step_rigid_body(cartan.group("SO3"), np.eye(3), M0, inertia, dt, nsteps)
    np.testing.assert_allclose(M, np.broadcast_to(M_ref[-1], M.shape), atol=1e-12)
    np.testing.assert_allclose(R, np.broadcast_to(R_ref[-1], R.shape), atol=1e-12)
    assert np.max(np.abs(np.array(norms) - np.linalg.norm(M0))) <= 1e-13
    assert np.max(np.abs(np.array(energies) - E0)) / E0 < 1e-3
    omega, R_exact = rigid_body_exact(inertia, w0, [nsteps * dt])
    np.testing.assert_allclose(M[0] / inertia, omega[0], atol=1e-3)
    np.testing.assert_allclose(R[0], R_exact[0], atol=1e-3)


# ---------------------------------------------------------------------------- axial wave speed
def test_axial_wave_speed():
    """Periodic straight rod, axial standing wave u = ε sin(ks) (mode m, k = 2πm/L).

    On the lattice the axial motion is exactly a linear mass–spring chain (edges stay pure
    translations along e₁, so strain, stress and force are linear in the node positions); its
    frequency is ω_h = (2c/h) sin(kh/2), c = √(EA/ρA), and Lie–Verlet (Störmer–Verlet on this
    motion) measures ω̃ with sin(ω̃Δt/2) = ω_hΔt/2.  Hence the tolerance: the relative error
    against the continuum ω = ck is 1 − sin(kh/2)/(kh/2) ≈ (kh)²/24 (the scheme's O(h²)),
    plus (ωΔt)²/24 from time stepping.
    """
    rod = _rod()
    c = math.sqrt(rod.stiffness_diagonal()[0] / rod.inertia()[0])
    n, L, m, eps = 40, 2.0, 2, 1e-4
    h, k = L / n, 2 * math.pi * m / L
    grid = Grid(n, length=L, periodic=True)
    s = grid.coordinates()
    Phi = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    Phi[:, 1, 0] = s + eps * np.sin(k * s)
    # a straight periodic rod: Φ(u + L) = HΦ(u) with H the translation by L along e₁
    H = rod.group.exp(np.array([L, 0, 0, 0, 0, 0]))
    scheme = Lattice(Problem(rod, grid, InitialState(Phi=Phi, holonomy=H)))
    state = scheme.initial_state()
    assert scheme.closure_residual(state) < 1e-13
    omega = c * k
    dt = 0.05 / omega
    steps = round(2 * (2 * math.pi / omega) / dt)  # two periods
    amp = []

    def record(st):
        x = scheme.frames(st)[:, 1, 0]
        amp.append(np.dot(x - s, np.sin(k * s)) * 2 / n)

    _run(scheme, LieVerlet(), state, dt, steps, record)
    a = np.array([eps, *amp])
    # three-term recurrence a_{j+1} + a_{j−1} = 2 cos(ω̃Δt) a_j, least squares
    cosw = np.dot(a[2:] + a[:-2], a[1:-1]) / (2 * np.dot(a[1:-1], a[1:-1]))
    w_meas = math.acos(cosw) / dt
    w_h = 2 * c / h * math.sin(k * h / 2)
    w_pred = 2 / dt * math.asin(w_h * dt / 2)
    assert abs(w_meas - w_pred) / w_pred < 1e-8
    tol = (k * h) ** 2 / 24 + (omega * dt) ** 2 / 24
    err = abs(w_meas - omega) / omega
    assert err <= 1.05 * tol
    assert err >= 0.5 * (k * h) ** 2 / 24 - (omega * dt) ** 2 / 24  # the O(h²) error is really there
    # transverse and rotational components stay exactly zero
    assert np.abs(scheme.frames(state)[:, 2:, 0]).max() == 0.0
    assert np.abs(state.S[:, 1:]).max() == 0.0


# ---------------------------------------------------------------------------- gravity
def test_gravity_pullback_at_rest():
    rod = _rod()
    g = np.array([0.0, 0.0, -9.81])
    grid = Grid(21, length=3.0)
    init = rod.initial_state(grid, "straight", direction=[1.0, 1.0, 0.0])
    gravity = rod.make_load("gravity", g=g)
    prob = Problem(rod, grid, init, {"start": Clamped()}, [gravity])
    scheme = Lattice(prob)
    state = scheme.initial_state()
    W = scheme.force(state, np.zeros_like(state.S), 0.0)
    R = init.Phi[:, 1:, 1:]
    rhoA = rod.inertia()[0]
    f_expected = np.einsum("nji,j->ni", R, rhoA * g)
    np.testing.assert_allclose(W[1:, :3], f_expected[1:], atol=1e-9)
    assert np.abs(W[:, 3:]).max() < 1e-9  # no moment from gravity
    assert np.all(W[0] == 0.0)  # clamped
    T = gravity.force(init.Phi, np.zeros_like(state.S), 0.0)
    total = np.einsum("n,nij,nj->i", scheme.weights, R, T[:, :3])
    np.testing.assert_allclose(total, rhoA * g * 3.0, rtol=1e-12)
    # potential energy of gravity: −ρA g·r integrated (trapezoid, exact for a straight rod)
    r = init.Phi[:, 1:, 0]
    V = scheme.potential_energy(state)
    assert V == pytest.approx(float(np.sum(scheme.weights * (-rhoA * r @ g))), rel=1e-12, abs=1e-12)
    with pytest.raises(ValueError, match="'g'"):
        rod.make_load("gravity", acceleration=g)
    with pytest.raises(ValueError, match="no load kind 'wind'"):
        rod.make_load("wind")


def test_cantilever_under_gravity_settles_at_timoshenko_deflection():
    """Clamped–free cantilever under a small gravity load q = ρAg, relaxed by damped Lie–Verlet
    dynamics (Rayleigh damping Γ = 2ω₁·mass, every mode decays as e^{−ω₁t}, ω₁ = 1.875²√(EI/ρAL⁴)):
    the tip settles at the Timoshenko deflection qL⁴/(8EI) + qL²/(2α_cGA).  The lattice with
    trapezoidal node loads reproduces it at the nodes up to the geometric nonlinearity (w/L ~ 1e-4)."""
    EI, GA, rhoA = 1.0, 100.0, 1.0
    rod = CosseratRod(
        stretch_shear=[100.0, GA, GA],
        bend_twist=[1.0, EI, EI],
        mass=rhoA,
        rotational_inertia=[0.02, 0.01, 0.01],
    )
    L, n = 1.0, 11
    grid = Grid(n, length=L)
    g = np.array([0.0, 0.0, -1e-3])
    omega1 = 1.875**2 * math.sqrt(EI / (rhoA * L**4))
    drag = 2 * omega1 * rod.inertia()
    prob = Problem(
        rod,
        grid,
        rod.initial_state(grid, "straight"),
        {"start": Clamped()},
        [rod.make_load("gravity", g=g), Damping(drag)],
    )
    scheme = Lattice(prob)
    state = scheme.initial_state()
    integ = LieVerlet()
    dt = 0.5 * integ.dt_max(scheme, state)
    _run(scheme, integ, state, dt, round(6.0 / dt))  # e^{−ω₁·6} ≈ 1e-9
    q = rhoA * abs(g[2])
    w = q * L**4 / (8 * EI) + q * L**2 / (2 * GA)
    tip = -scheme.frames(state)[-1, 3, 0]
    assert tip == pytest.approx(w, rel=1e-5)
    assert np.abs(scheme.velocity(state)).max() < 1e-8


# ---------------------------------------------------------------------------- scenes
SCHEMA = {"name", "description", "medium", "parameters", "grid", "initial", "run"}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_files(name):
    path = SCENES[name]
    data = tomllib.loads(pathlib.Path(path).read_text())
    assert SCHEMA <= set(data), SCHEMA - set(data)
    assert data["name"] == name
    assert set(data["grid"]) <= {"n", "length", "periodic"}
    assert {"integrator", "scheme", "dt", "t_end", "save_every"} <= set(data["run"])
    for end in data.get("boundaries", {}).values():
        assert end["kind"] in ("free", "clamped")
    # the medium, loads and initial state build from the file's own data
    medium = cartan.registry("media")[data["medium"]](**data["parameters"])
    grid = Grid(
        data["grid"]["n"], length=data["grid"]["length"], periodic=data["grid"].get("periodic", False)
    )
    init_params = {k: v for k, v in data["initial"].items() if k != "kind"}
    init = medium.initial_state(grid, data["initial"]["kind"], **init_params)
    loads = []
    for entry in data.get("loads", []):
        params = {k: v for k, v in entry.items() if k != "kind"}
        if entry["kind"] == "damping":
            loads.append(Damping(**params))
        else:
            loads.append(medium.make_load(entry["kind"], **params))
    bounds = {}
    for end, spec in data.get("boundaries", {}).items():
        spec = dict(spec)
        bounds[end] = Clamped() if spec.pop("kind") == "clamped" else Free(**spec)
    prob = Problem(medium, grid, init, bounds, loads, name=name)
    scheme = Lattice(prob)
    state = scheme.initial_state()
    integ = {"lie-verlet": LieVerlet, "overdamped": Overdamped}[data["run"]["integrator"]]()
    assert data["run"]["dt"] <= integ.dt_max(scheme, state)
    E0 = _energy(scheme, state)
    _run(scheme, integ, state, data["run"]["dt"], 20)
    assert state.is_finite()
    if integ.name == "overdamped":
        assert _energy(scheme, state) < E0


# ---------------------------------------------------------------------------- quadratic energy
@pytest.mark.parametrize("planar", [False, True])
def test_quadratic_energy_is_the_potential_as_data(planar):
    """``quadratic_energy()`` = (X₀, C) with U = ½(X − X₀)ᵀC(X − X₀) and Q = C(X − X₀)."""
    kappa = [0.0, 0.0, 0.3] if planar else [0.1, 0.2, 0.3]
    rod = CosseratRod(E=1e6, poisson=0.3, radius=0.02, density=1000.0, rest_curvature=kappa)
    rod = rod.planar() if planar else rod
    X0, C = rod.quadratic_energy()
    r = rod.group.dim
    assert X0.shape == (r,) and C.shape == (r, r)
    np.testing.assert_array_equal(X0, rod.rest_strain()[0])
    np.testing.assert_array_equal(C, np.diag(rod.stiffness_diagonal()))
    X = np.random.default_rng(0).standard_normal((5, 1, r))
    D = X[:, 0] - X0
    np.testing.assert_allclose(rod.potential(X), 0.5 * np.einsum("nk,kl,nl->n", D, C, D), rtol=1e-14)
    np.testing.assert_allclose(rod.stress(X)[:, 0], D @ C.T, rtol=1e-14)
