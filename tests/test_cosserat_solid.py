"""The ``cosserat-solid`` medium: micropolar (Cosserat) solids on SE(3), d = 3 (paper §VI.A)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from cartan_cosserat_solid.cases import optical_potential, uniform_rotation_exact
from cartan_cosserat_solid.solid import CosseratSolid, eringen_stresses, micropolar_stiffness

import cartan
from cartan.integrators import LieVerlet
from cartan.schemes.lattice import Lattice
from cartan.testing import check_medium

SE3 = cartan.group("SE3")
SO3 = cartan.group("SO3")


@pytest.fixture(scope="module")
def solid() -> CosseratSolid:
    return cartan.medium("cosserat-solid")


def _box(n=4, length=1.0, periodic=False):
    return cartan.Grid((n, n, n), length=length, periodic=periodic)


def _perturbed(solid, grid, amplitude=0.05, seed=1):
    """The undeformed box with small random frame perturbations and velocities (every component)."""
    rng = np.random.default_rng(seed)
    base = solid.initial_state(grid, "undeformed")
    Phi = SE3.compose(base.Phi, SE3.exp(amplitude * rng.standard_normal((*grid.shape, 6))))
    N = amplitude * rng.standard_normal((*grid.shape, 6))
    return cartan.InitialState(Phi=Phi, N=N, holonomy=base.holonomy)


# ---------------------------------------------------------------------------- medium contract
@pytest.mark.slow
def test_registered_and_conformant(solid):
    assert isinstance(solid, CosseratSolid) and solid.material_dim == 3 and solid.group.name == "SE3"
    # the full kit over every scheme × integrator runs in tests/test_conformance.py
    report = check_medium("cosserat-solid", {}, schemes=["lattice"], integrators=["lie-verlet"])
    assert not report.failed


@pytest.mark.parametrize(("params", "condition"), [
    ({"lam": -2.0}, "3·lam + 2·mu + kappa"),
    ({"mu": -0.5, "kappa": 0.5}, "2·mu + kappa"),
    ({"kappa": 0.0}, "kappa > 0"),
    ({"alpha": -0.2}, "3·alpha"),
    ({"beta": -0.1, "gamma": 0.05}, "beta + gamma"),
    ({"beta": 0.1, "gamma": 0.1}, "gamma − beta"),
])
def test_energy_must_be_positive_definite(params, condition):
    with pytest.raises(ValueError, match=re.escape(condition)):
        CosseratSolid(**params)


@pytest.mark.parametrize(("params", "name"), [
    ({"density": 0.0}, "density"), ({"micro_inertia": -1.0}, "micro_inertia"), ({"lam": float("nan")}, "lam"),
    ({"output_stresses": 1}, "output_stresses"),
])
def test_bad_parameters_are_named(params, name):
    with pytest.raises(ValueError, match=name):
        CosseratSolid(**params)


def test_positive_definite_exactly_when_the_conditions_hold():
    # the eigenvalues of the 18 × 18 stiffness are the six moduli of the docstring's split
    c = dict(lam=1.0, mu=1.0, kappa=0.5, alpha=0.1, beta=0.05, gamma=0.1)
    ev = np.linalg.eigvalsh(micropolar_stiffness(**c))
    expected = {3 * c["lam"] + 2 * c["mu"] + c["kappa"], 2 * c["mu"] + c["kappa"], c["kappa"],
                3 * c["alpha"] + c["beta"] + c["gamma"], c["beta"] + c["gamma"], c["gamma"] - c["beta"]}
    found = set(np.round(ev, 12))
    # every eigenvalue is one of the six moduli of the split, and each of them occurs
    assert found <= {round(v, 12) for v in expected} and len(found) == 6


def test_energy_is_the_stated_formula(solid):
    rng = np.random.default_rng(3)
    X = solid.rest_strain() + 0.3 * rng.standard_normal((5, 3, 6))
    E, K = solid.strain_tensors(X)
    c = solid.constants
    tr = np.trace
    U = np.array([0.5 * c["lam"] * tr(e) ** 2 + 0.5 * (c["mu"] + c["kappa"]) * np.sum(e * e)
                  + 0.5 * c["mu"] * np.sum(e * e.T) + 0.5 * c["alpha"] * tr(k) ** 2
                  + 0.5 * c["beta"] * np.sum(k * k.T) + 0.5 * c["gamma"] * np.sum(k * k) for e, k in zip(E, K)])
    assert np.allclose(solid.potential(X), U, rtol=1e-13, atol=0)
    # stress = ∂U/∂X by central differences (error O(ε²) ≈ 1e-12 relative)
    eps = 1e-6
    fd = np.empty((3, 6))
    for a in range(3):
        for k in range(6):
            d = np.zeros((3, 6))
            d[a, k] = eps
            fd[a, k] = (solid.potential(X[0] + d) - solid.potential(X[0] - d)) / (2 * eps)
    assert np.max(np.abs(fd - solid.stress(X[0]))) <= 1e-7 * np.max(np.abs(fd))


# ---------------------------------------------------------------------------- small-strain limit
def _continuum_strain(Phi_of, p, s=1e-4):
    """X_α = Φ⁻¹∂_αΦ at p by central differences of log(Φ(p)⁻¹Φ(p ± s e_α)) (error O(s²))."""
    Phi = Phi_of(p)
    X = np.empty((3, 6))
    for a in range(3):
        e = np.zeros(3)
        e[a] = s
        plus = SE3.log(SE3.compose(SE3.inverse(Phi), Phi_of(p + e)))
        minus = SE3.log(SE3.compose(SE3.inverse(Phi), Phi_of(p - e)))
        X[a] = (plus - minus) / (2 * s)
    return X


def test_small_strain_limit_is_eringen_linear_theory(solid):
    """The stresses at the exact strains of u = εf(x), R = exp(εg(x)) equal Eringen's linear
    t_kl, m_kl (convention ε_kl = u_l,k + e_lkm φ_m) up to O(ε²): the error ratio is 4 when ε halves."""
    A = np.array([[0.3, -0.7, 0.2], [0.5, 0.1, -0.4], [-0.2, 0.6, 0.9]])
    B = np.array([[0.8, 0.1, -0.3], [-0.5, 0.4, 0.2], [0.1, -0.6, 0.7]])
    p = np.array([0.3, -0.2, 0.5])

    def fields(x, eps):
        u = eps * np.sin(A @ x)
        phi = eps * np.cos(B @ x)
        return u, phi

    def grads(x, eps):  # ∇u[k, l] = u_l,k ; ∇φ[k, l] = φ_l,k
        gu = (eps * np.cos(A @ x))[:, None] * A  # [l, k]
        gp = (-eps * np.sin(B @ x))[:, None] * B
        return gu.T, gp.T

    c = solid.constants
    errors = []
    for eps in (1e-2, 5e-3, 2.5e-3):
        def Phi_of(x, eps=eps):
            u, phi = fields(x, eps)
            return _se3(x + u, SO3.exp(phi))

        X = _continuum_strain(Phi_of, p)
        t, m = solid.stress_tensors(X)
        gu, gp = grads(p, eps)
        t_lin, m_lin = eringen_stresses(gu, fields(p, eps)[1], gp, **c)
        errors.append(max(np.max(np.abs(t - t_lin)), np.max(np.abs(m - m_lin))) / eps)
        assert np.max(np.abs(t_lin)) > 0.1 * eps  # a genuine, non-zero linear stress
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    # error/ε = O(ε): order 1 in the relative error, i.e. the stresses agree to O(ε²)
    assert np.all(np.abs(orders - 1.0) < 0.1), (errors, orders)


def _se3(x, R):
    g = np.eye(4)
    g[1:, 0] = x
    g[1:, 1:] = R
    return g


# ---------------------------------------------------------------------------- exact states on the lattice
def test_undeformed_and_stretched_boxes_have_exact_strains(solid):
    grid = _box(4, 1.0)
    for kind, params in (("undeformed", {"rotation": (0.3, -1.1, 0.4), "origin": (1.0, 2.0, 3.0)}),
                         ("stretch", {"stretch": (1.02, 0.97, 1.05), "rotation": (0.2, 0.1, -0.5)})):
        problem = cartan.Problem(solid, grid, solid.initial_state(grid, kind, **params))
        scheme = Lattice(problem)
        state = scheme.initial_state()
        s = np.asarray(params.get("stretch", (1.0, 1.0, 1.0)))
        for axis, X in enumerate(scheme.edge_strains(state)):
            expected = np.zeros(6)
            expected[axis] = s[axis]
            assert np.max(np.abs(X - expected)) <= 1e-14
        U = solid.potential(np.concatenate([np.diag(s), np.zeros((3, 3))], axis=1))
        assert scheme.potential_energy(state) == pytest.approx(U * 1.0, rel=1e-12, abs=1e-15)


def test_rigid_motion_leaves_strains_and_energy_unchanged(solid):
    """Frame indifference: Φ → exp(tξ)Φ keeps every lattice edge strain and the energy, and the
    dynamics commutes with it (final frames related by the same rigid motion)."""
    grid = _box(4, 1.0)
    init = _perturbed(solid, grid)
    xi = np.array([0.4, -0.3, 0.8, 1.2, -0.7, 0.5])
    base = Lattice(cartan.Problem(solid, grid, init))
    s0 = base.initial_state()
    V0 = base.potential_energy(s0)
    X0 = base.edge_strains(s0)
    for t in (0.5, 2.0, 7.0):
        moved = cartan.InitialState(Phi=SE3.compose(SE3.exp(t * xi), init.Phi), N=init.N)
        scheme = Lattice(cartan.Problem(solid, grid, moved))
        state = scheme.initial_state()
        for a, b in zip(X0, scheme.edge_strains(state)):
            assert np.max(np.abs(a - b)) <= 1e-12
        assert scheme.potential_energy(state) == pytest.approx(V0, rel=1e-12)
    # the Python path: the micropolar compiled loops (≈ 25 s to compile) run in make test-slow
    kw = dict(integrator="lie-verlet", dt=0.01, t_end=0.2, save_every=20, progress=False, compiled=False)
    g = SE3.exp(2.0 * xi)
    ds0 = cartan.simulate(cartan.Problem(solid, grid, init), **kw)
    ds1 = cartan.simulate(cartan.Problem(solid, grid, cartan.InitialState(Phi=SE3.compose(g, init.Phi), N=init.N)),
                          **kw)
    assert np.max(np.abs(ds0.S.values - ds1.S.values)) <= 1e-11
    R0, R1 = ds0.frame.values[-1], ds1.frame.values[-1]
    assert np.max(np.abs(g[1:, 1:] @ R0 - R1)) <= 1e-11
    x0, x1 = ds0.position.values[-1], ds1.position.values[-1]
    assert np.max(np.abs(x0 @ g[1:, 1:].T + g[1:, 0] - x1)) <= 1e-11


@pytest.mark.slow  # the micropolar loop: ≈ 12 s to compile on a fresh cache
def test_homogeneous_stretch_with_face_tractions_stays_exactly_uniform(solid):
    """A homogeneous stretch loaded on all six faces by n_αQ^α is an exact equilibrium of the
    lattice: after a dynamic run the strain is uniform, the kinetic energy round-off, the energy constant."""
    grid = _box(4, 1.0)
    s = np.array([1.03, 0.98, 1.01])
    init = solid.initial_state(grid, "stretch", stretch=s)
    X = solid.rest_strain().copy()
    X[:, :3] = np.diag(s)
    Q = solid.stress(X)
    assert np.max(np.abs(Q)) > 1e-2
    faces = {}
    for a, name in enumerate("uvw"):
        faces[f"{name}-start"] = cartan.Free(load=-Q[a])
        faces[f"{name}-end"] = cartan.Free(load=Q[a])
    problem = cartan.Problem(solid, grid, init, boundaries=faces)
    ds = cartan.simulate(problem, integrator="lie-verlet", dt=0.02, t_end=1.0, save_every=10, progress=False)
    dev = np.max(np.abs(ds.X.values - X))
    assert dev <= 1e-12, dev
    E = ds.kinetic_energy.values + ds.potential_energy.values - ds.external_work.values
    assert float(ds.kinetic_energy.max()) <= 1e-24
    assert np.max(np.abs(E - E[0])) <= 1e-12 * abs(E[0])
    # outputs: displacement of the stretch, no rotation, the uniform stress
    u = grid.coordinates(0)
    assert np.allclose(ds.displacement_x.values[-1], ((s[0] - 1) * u)[:, None, None], atol=1e-12)
    assert np.max(np.abs(ds.microrotation_x.values)) <= 1e-12
    assert np.allclose(ds.force_stress.sel(axis="u", col="d1").values[-1], Q[0, 0], rtol=1e-10)
    assert np.allclose(ds.force_stress.sel(axis="v", col="d2").values[-1], Q[1, 1], rtol=1e-10)


# ---------------------------------------------------------------------------- dynamic invariants
@pytest.fixture(scope="module")
def free_box_runs(solid):
    grid = _box(4, 1.0)
    problem = cartan.Problem(solid, grid, _perturbed(solid, grid, 0.1))
    runs = {}
    for dt in (0.02, 0.01, 0.005):
        runs[dt] = cartan.simulate(problem, integrator="lie-verlet", dt=dt, t_end=1.0, save_every=round(0.05 / dt),
                                   progress=False)
    return problem, runs


def test_plaquette_holonomy_of_every_axis_pair_is_round_off(solid):
    grid = _box(4, 1.0)
    problem = cartan.Problem(solid, grid, _perturbed(solid, grid, 0.1))
    scheme = Lattice(problem)
    state = scheme.initial_state()
    integ = LieVerlet()
    for _ in range(50):
        integ.step(scheme, state, 0.01)
    assert np.max(np.abs(state.S)) > 1e-2  # it moved
    for a in range(3):
        for b in range(a + 1, 3):
            Ga, Gb = state.arrays[scheme._key(a)], state.arrays[scheme._key(b)]
            Ga_i, Ga_next = scheme._ends(Ga, b)
            Gb_i, Gb_next = scheme._ends(Gb, a)
            loop = SE3.compose(SE3.compose(Ga_i, Gb_next), SE3.inverse(SE3.compose(Gb_i, Ga_next)))
            assert np.max(np.abs(SE3.log(loop))) <= 1e-13, (a, b)
    assert scheme.plaquette_residual(state) <= 1e-13


@pytest.mark.slow  # the micropolar loop: ≈ 25 s to compile on a fresh cache
def test_energy_balance_is_second_order_with_lie_verlet(free_box_runs):
    _, runs = free_box_runs
    errors = []
    for ds in runs.values():
        E = ds.kinetic_energy.values + ds.potential_energy.values
        assert float(ds.spatial_residual.max()) <= 1e-13
        errors.append(float(np.max(np.abs(E - E[0])) / E[0]))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[0] > 1e-8  # measurable, not round-off
    assert np.all(np.abs(orders - 2.0) <= 0.2), (errors, orders)


@pytest.mark.slow  # the micropolar loop (as above)
def test_momentum_of_the_free_box_is_conserved(free_box_runs):
    _, runs = free_box_runs
    P = runs[0.005].total_momentum.values
    assert np.max(np.abs(P - P[0])) <= 1e-11 * max(1.0, np.max(np.abs(P)))


# ---------------------------------------------------------------------------- point kernels
@pytest.mark.slow  # compiles the medium's batch kernels (medium_batch)
def test_point_kernels_equal_the_numpy_stiffness_to_round_off(solid):
    """The compiled point kernels (stress_at, potential_at) are the 18 × 18 stiffness's energy and
    gradient, U = ½ DᵀCD with D the deviation in the orthonormal frame of the reference directors,
    on the identity chart and on general charts (Q[α] = det Θ₀ Σ_j (Θ₀⁻¹)_{jα} Q_phys[j]), at
    small and large strains; the difference is summation-order round-off (a few ulps of the
    largest term, hence the tolerances 1e-14 and 1e-13 relative to the largest term)."""
    C = micropolar_stiffness(**solid.constants)
    rng = np.random.default_rng(11)
    P = 200
    X0 = np.broadcast_to(solid.rest_strain(), (P, 3, 6)).copy()
    Theta = np.eye(3) + 0.3 * rng.standard_normal((P, 3, 3))
    Theta[np.linalg.det(Theta) < 0, 0] *= -1.0
    X0c = np.zeros((P, 3, 6))
    X0c[:, :, :3] = Theta
    X0c[:, :, 3:] = 0.2 * rng.standard_normal((P, 3, 3))
    for amplitude in (1e-3, 0.5):
        X = X0 + amplitude * rng.standard_normal((P, 3, 6))
        D = (X - X0).reshape(P, 18)
        Q_ref = (D @ C).reshape(P, 3, 6)
        scale = np.max(np.abs(C)) * np.max(np.abs(D))
        assert np.max(np.abs(solid.stress_at(X, X0) - Q_ref)) <= 1e-14 * scale
        assert np.max(np.abs(solid.potential_at(X, X0) - 0.5 * np.einsum("pi,ij,pj->p", D, C, D))) <= (
            1e-14 * scale * np.max(np.abs(D)))
        Xc = X0c + amplitude * rng.standard_normal((P, 3, 6))
        T = np.linalg.inv(Theta)
        det = np.linalg.det(Theta)
        Dc = (T @ (Xc - X0c)).reshape(P, 18)
        Q_phys = (Dc @ C).reshape(P, 3, 6)
        Q_ref = det[:, None, None] * np.swapaxes(T, -1, -2) @ Q_phys
        scale = np.max(np.abs(Q_ref))
        assert np.max(np.abs(solid.stress_at(Xc, X0c) - Q_ref)) <= 1e-13 * scale
        U_ref = det * 0.5 * np.einsum("pi,ij,pj->p", Dc, C, Dc)
        assert np.max(np.abs(solid.potential_at(Xc, X0c) - U_ref)) <= 1e-13 * np.max(np.abs(U_ref))


# ---------------------------------------------------------------------------- compiled = reference
@pytest.mark.slow  # the solid's own lie-verlet loop: ≈ 25 s to compile on a fresh cache
def test_compiled_matches_reference_on_periodic_and_loaded_boxes(solid):
    periodic = cartan.Grid((3, 4, 3), length=(0.75, 1.0, 0.75), periodic=True)
    open_box = _box(4, 1.0)
    cases = [
        (cartan.Problem(solid, periodic, _perturbed(solid, periodic, 0.05, seed=4)), "lattice"),
        (cartan.Problem(solid, open_box, _perturbed(solid, open_box, 0.05, seed=5),
                        boundaries={"u-start": cartan.Clamped(),
                                    "u-end": cartan.Free(load=[0.0, 0.1, -0.2, 0.05, 0.0, 0.0])},
                        loads=[solid.make_load("gravity", g=[0.0, 0.0, -1.0])]), "lattice"),
    ]
    for problem, scheme in cases:
        kw = dict(integrator="lie-verlet", scheme=scheme, dt=0.01, t_end=0.1, save_every=5, progress=False)
        fast, ref = cartan.simulate(problem, **kw), cartan.simulate(problem, **kw, compiled=False)
        for key in ("S", "X", "position", "frame"):
            err = float(np.max(np.abs(fast[key].values - ref[key].values)) / np.max(np.abs(ref[key].values)))
            assert err <= 1e-12, (key, err)
        assert float(fast.closure_residual.max()) <= 1e-13


def test_periodic_box_is_a_plane_wave_medium(solid):
    """On the periodic box (a translation holonomy per axis) a uniform translation velocity is a
    rigid motion (no strain), while without the holonomy the closing edges would carry the whole
    box's length."""
    grid = cartan.Grid((3, 3, 3), length=1.0, periodic=True)
    init = solid.initial_state(grid, "undeformed", velocity=[0.3, -0.2, 0.1, 0.0, 0.0, 0.0])
    assert sorted(init.holonomy) == [0, 1, 2]
    problem = cartan.Problem(solid, grid, init)
    scheme = Lattice(problem)
    state = scheme.initial_state()
    assert scheme.potential_energy(state) <= 1e-28
    bare = cartan.Problem(solid, grid, cartan.InitialState(Phi=init.Phi, N=init.N))
    assert Lattice(bare).potential_energy(Lattice(bare).initial_state()) > 1.0
    ds = cartan.simulate(problem, integrator="lie-verlet", dt=0.05, t_end=1.0, save_every=20, progress=False,
                         compiled=False)  # the solid's loop compiles in make test-slow
    assert float(ds.potential_energy.max()) <= 1e-26
    assert float(ds.closure_residual.max()) <= 1e-13
    assert np.allclose(ds.displacement_x.values[-1], 0.3, atol=1e-12)
    with pytest.raises(ValueError, match="homogeneous"):
        solid.initial_state(grid, "twist", rate=0.1)


# ---------------------------------------------------------------------------- loads and optical cutoff
def test_gravity_is_pulled_back_to_a_body_force(solid):
    grid = _box(3, 1.0)
    init = solid.initial_state(grid, "undeformed", rotation=(0.4, -0.2, 0.9))
    grav = solid.make_load("gravity", g=[0.0, 0.0, -9.81])
    problem = cartan.Problem(solid, grid, init, loads=[grav])
    T = grav.force(problem.initial.Phi, None, 0.0)
    R = problem.initial.Phi[..., 1:, 1:]
    assert np.allclose(T[..., :3], np.einsum("...ji,j->...i", R, [0.0, 0.0, -9.81 * solid.rho]), atol=1e-14)
    assert np.max(np.abs(T[..., 3:])) <= 1e-14
    with pytest.raises(ValueError, match="'g'"):
        solid.make_load("gravity", g=[0, 0, -1], mass=2.0)


@pytest.mark.slow  # the micropolar RKMK loop: ≈ 25 s to compile on a fresh cache
def test_optical_cutoff_small_amplitude(solid):
    """A uniform micro-rotation of amplitude 1e-3 oscillates at ρjω² = 2κ (error O(φ₀²) + O(Δt²))."""
    c = solid.constants
    rho_j = solid.rho * solid.j
    omega = math.sqrt(2 * c["kappa"] / rho_j)
    # the exact potential's curvature is 2κ: V(φ) = κφ² + O(φ⁴)
    phi = 1e-3
    assert optical_potential(phi, c["lam"], c["mu"], c["kappa"]) == pytest.approx(c["kappa"] * phi**2, rel=1e-5)
    t = 2.0
    assert uniform_rotation_exact(phi, t, c["lam"], c["mu"], c["kappa"], rho_j) == pytest.approx(
        phi * math.cos(omega * t), rel=1e-5)
    grid = cartan.Grid((3, 3, 3), length=1.0, periodic=True)
    init = solid.initial_state(grid, "undeformed")
    Phi = init.Phi.copy()
    Phi[..., 1:, 1:] = SO3.exp(np.array([0.0, phi, 0.0]))
    ds = cartan.simulate(cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi, holonomy=init.holonomy)),
                         integrator="rkmk4", dt=0.005, t_end=t, save_every=100, progress=False)
    observed = ds.microrotation_y.values.mean(axis=(1, 2, 3))
    exact = phi * np.cos(omega * ds.time.values)
    assert np.max(np.abs(observed - exact)) <= 1e-5 * phi
    assert np.max(np.abs(ds.displacement_x.values)) <= 1e-14


# ---------------------------------------------------------------------------- torsion size effect (closed form)
GJ_CONSTANTS = dict(lam=1.0, mu=1.0, kappa=0.5, alpha=0.1, beta=0.1, gamma=0.1)


def test_torsion_ratio_reproduces_gauthier_jahsman():
    from cartan_cosserat_solid.solid import torsion_stiffness_ratio

    ratio = torsion_stiffness_ratio([0.5, 1.0, 2.0], **GJ_CONSTANTS)
    # the published ratios (Gauthier & Jahsman 1975, λ = μ = 1, κ = 0.5, α = β = γ = 0.1), given to 6 decimals
    assert np.allclose(ratio, [2.642003, 1.428487, 1.112666], rtol=0, atol=6e-7)
    # classical limit: Ω − 1 = O((ℓ/a)²), about 4e-7 at a = 1e3
    assert 0 < torsion_stiffness_ratio(1e3, **GJ_CONSTANTS) - 1 <= 1e-6
    assert np.all(np.diff(torsion_stiffness_ratio(np.linspace(0.2, 5, 30), **GJ_CONSTANTS)) < 0)  # stiffer when thin


def test_torsion_micro_rotation_solves_the_couple_balance():
    """φ_r = −τr/2 + A I₁(pr) solves (α+β+γ)(ψ′ + ψ/r)′ = κ(τr + 2ψ) and m_rr(a) = 0 (finite differences)."""
    from scipy.special import iv

    c = GJ_CONSTANTS
    a, tau = 1.0, 1.0
    s = c["alpha"] + c["beta"] + c["gamma"]
    p = math.sqrt(2 * c["kappa"] / s)
    A = (c["beta"] + c["gamma"]) * tau / (2 * (s * p * iv(0, p * a) - (c["beta"] + c["gamma"]) * iv(1, p * a) / a))

    def psi(r):
        return -tau * r / 2 + A * iv(1, p * r)

    def div_part(r, e=1e-4):  # ψ′ + ψ/r
        return (psi(r + e) - psi(r - e)) / (2 * e) + psi(r) / r

    for r in (0.3, 0.6, 0.9):
        e = 1e-3
        lhs = s * (div_part(r + e) - div_part(r - e)) / (2 * e)
        assert lhs == pytest.approx(c["kappa"] * (tau * r + 2 * psi(r)), rel=1e-5)
    e = 1e-5
    dpsi = (psi(a + e) - psi(a - e)) / (2 * e)
    m_rr = c["alpha"] * (dpsi + psi(a) / a + tau) + (c["beta"] + c["gamma"]) * dpsi
    assert abs(m_rr) <= 1e-8


# ---------------------------------------------------------------------------- scenes
@pytest.mark.parametrize("name", ["solid-bar-wave", "solid-compressed-block", "solid-torsion-box"])
def test_scenes_load_and_run(name):
    assert name in cartan.registry("scenes")
    ds = cartan.simulate(name, t_end=0.1, save_every=5, progress=False)
    assert ds.attrs.get("cartan_config") and np.all(np.isfinite(ds.S.values))
    E = ds.kinetic_energy.values + ds.potential_energy.values + ds.dissipated_energy.values - ds.external_work.values
    scale = max(float(np.max(np.abs(ds.potential_energy.values))), float(np.max(np.abs(ds.external_work.values))))
    assert np.max(np.abs(E - E[0])) <= 1e-2 * scale  # the energy budget closes to O(Δt²) over the first steps


def test_twist_initial_state_has_uniform_torsion(solid):
    grid = cartan.Grid((5, 4, 4), length=(1.0, 0.3, 0.3))
    problem = cartan.Problem(solid, grid, solid.initial_state(grid, "twist", rate=0.4))
    scheme = Lattice(problem)
    Xu, Xv, Xw = scheme.edge_strains(scheme.initial_state())
    assert np.allclose(Xu[..., 3:], [0.4, 0.0, 0.0], atol=1e-14)  # π_u = (τ, 0, 0)
    assert np.allclose(Xv, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0], atol=1e-14)
    assert np.allclose(Xw, [0.0, 0.0, 1.0, 0.0, 0.0, 0.0], atol=1e-14)


def test_shear_wave_branches_limits(solid):
    from cartan_cosserat_solid.cases import shear_wave_branches

    c = solid.constants
    rho, rho_j = solid.rho, solid.rho * solid.j
    k = 1e-3  # long waves: the acoustic branch has the classical shear modulus μ + κ/2, the optical its cutoff
    ac, op = shear_wave_branches(k, **c, rho=rho, rho_j=rho_j)
    assert ac / k == pytest.approx(math.sqrt(solid.shear_modulus / rho), rel=1e-5)
    assert op == pytest.approx(math.sqrt(2 * c["kappa"] / rho_j), rel=1e-5)
    for k in (0.5, 3.0, 20.0):  # both roots solve the dispersion relation
        for w in shear_wave_branches(k, **c, rho=rho, rho_j=rho_j):
            lhs = ((c["mu"] + c["kappa"]) * k**2 - rho * w**2) * (c["gamma"] * k**2 + 2 * c["kappa"] - rho_j * w**2)
            assert lhs == pytest.approx(c["kappa"] ** 2 * k**2, rel=1e-9)
