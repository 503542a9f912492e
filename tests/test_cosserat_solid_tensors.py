"""Stress tensors of the micropolar solid in the spatial frame: the nominal (per unit reference
area) tensors P_{iα} = (R F^α)_i, C_{iα} = (R M^α)_i and the Cauchy tensors σ = P Fᵀ/J, C Fᵀ/J.

Every reference here is a closed form: the exact uniaxial equilibrium of the free block, a rigid
motion of an arbitrary state, Eringen's linear tensors for small homogeneous strains and the exact
stresses of uniform micro-rotations and of a micro-rotation field of uniform curvature."""

from __future__ import annotations

import numpy as np
import pytest
from cartan_cosserat_solid.cases import UniaxialStressBlock, uniaxial_stress
from cartan_cosserat_solid.solid import STRESS_OUTPUTS, eringen_stresses, stress_tensor

import cartan
from cartan.schemes.lattice import Lattice

SO3 = cartan.group("SO3")


def hat(v: np.ndarray) -> np.ndarray:
    """The skew matrix v̂ with v̂w = v × w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def skew(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A - np.swapaxes(A, -1, -2))


def node_tensors(solid, init, grid) -> dict[str, np.ndarray]:
    """The solid's stress outputs at the nodes of a state, ``(*shape, 3, 3)`` tensors (the
    strains are the lattice's nodal strains, as in every recorded frame)."""
    scheme = Lattice(cartan.Problem(solid, grid, init))
    state = scheme.initial_state()
    q = np.asarray(scheme.frames(state))
    out = solid.outputs(q, scheme.nodal_strains(state), np.zeros((*grid.shape, 6)), grid)
    tensors = {name: np.asarray(out[name]) for name in STRESS_OUTPUTS if name in out}
    assert all(T.shape == (*grid.shape, 3, 3) for T in tensors.values())
    return tensors


# ---------------------------------------------------------------- (a) uniaxial stress, exactly
@pytest.fixture(scope="module")
def uniaxial():
    """The free block of ``solid-uniaxial-stress`` at 3 × 3 × 3 nodes, solved by Newton's method."""
    case = UniaxialStressBlock()
    problem, settings = case.problem(0)
    return case, problem, cartan.solve_static(problem, **settings)


def test_uniaxial_tensors_are_the_closed_form(uniaxial):
    """Nominal traction p on both ends of a free block: x = diag(s₁, s₂, s₂)X, R = I, so
    P = diag(−p, 0, 0) and σ = P Fᵀ/J = diag(−p s₁/(s₁s₂²), 0, 0) at every node, and no couple
    stress.  The homogeneous state is exact on the lattice (the case's module docstring); the
    tolerance 1e-10·p is the case's (Newton tolerance 1e-12 of the nodal load, round-off measured
    at 4e-15)."""
    case, problem, ds = uniaxial
    p = case.load
    s1, s2, _, _ = uniaxial_stress(p, *(problem.medium.constants[k] for k in ("lam", "mu", "kappa")))
    tol = case.tolerance * p
    P = stress_tensor(ds, "nominal_force_stress")
    assert P.dims == ("time", "u", "v", "w", "row", "axis") and list(P.axis.values) == ["u", "v", "w"]
    assert list(P.row.values) == ["x", "y", "z"]
    np.testing.assert_allclose(P.values[-1], np.broadcast_to(np.diag([-p, 0.0, 0.0]), P.shape[1:]), rtol=0,
                               atol=tol)
    sigma = stress_tensor(ds, "cauchy_force_stress").values[-1]
    np.testing.assert_allclose(sigma, np.broadcast_to(np.diag([-p / s2**2, 0.0, 0.0]), sigma.shape), rtol=0,
                               atol=tol)
    for name in ("nominal_couple_stress", "cauchy_couple_stress", "couple_stress"):
        assert np.max(np.abs(stress_tensor(ds, name).values[-1])) <= tol
    # the body tensor is the nominal one rotated back: R = I here, so F^α_k = P_{kα}
    body = stress_tensor(ds, "force_stress").values[-1]
    np.testing.assert_allclose(body, np.swapaxes(P.values[-1], -1, -2), rtol=0, atol=tol)


def test_uniaxial_traction_equilibrium(uniaxial):
    """P N equals the applied nominal traction on every face (outer reference normal N): −p e₁ on
    u = L, +p e₁ on u = 0, zero on the four free lateral faces; and the Cauchy traction σ n on the
    loaded face times the current face area s₂² A equals the applied force −p A (Nanson)."""
    case, problem, ds = uniaxial
    p = case.load
    tol = case.tolerance * p
    P = ds["nominal_force_stress"].values[-1]
    applied = {("u", 1): [-p, 0, 0], ("u", -1): [p, 0, 0]}
    for axis, name in enumerate("uvw"):
        for sign, index in ((1, -1), (-1, 0)):
            face = np.take(P, index, axis=axis)                       # (n, n, 3, 3) nodes of the face
            N = sign * np.eye(3)[axis]
            traction = face @ N
            target = np.broadcast_to(np.asarray(applied.get((name, sign), [0.0, 0.0, 0.0])), traction.shape)
            np.testing.assert_allclose(traction, target, rtol=0, atol=tol, err_msg=f"face {name} {sign:+d}")
    s1, s2, _, _ = uniaxial_stress(p, *(problem.medium.constants[k] for k in ("lam", "mu", "kappa")))
    sigma = ds["cauchy_force_stress"].values[-1][-1]  # the face u = L
    np.testing.assert_allclose(sigma @ np.array([1.0, 0.0, 0.0]) * s2**2,
                               np.broadcast_to([-p, 0.0, 0.0], sigma.shape[:-1]), rtol=0, atol=tol)


LABELS = {"row": ["x", "y", "z"], "axis": ["u", "v", "w"], "col": ["d1", "d2", "d3"], "normal": ["x", "y", "z"]}


def test_recorded_variables_have_cf_attributes(uniaxial, tmp_path):
    """Each tensor is one variable ``(time, u, v, w, *dims)`` with its labels, long name and
    units, and comes back unchanged from a netCDF file."""
    _, _, ds = uniaxial
    for name, (dims, long_name, units, _) in STRESS_OUTPUTS.items():
        var = ds[name]
        assert var.dims == ("time", "u", "v", "w", *dims)
        assert var.attrs["units"] == units and var.attrs["long_name"] == long_name
        for dim in dims:
            assert list(var[dim].values) == LABELS[dim], dim
    assert ds["normal"].attrs["long_name"] == "spatial direction of the face normal"
    path = cartan.io.write_dataset(ds, tmp_path / "uniaxial.nc")
    back = cartan.open(path)
    for name in STRESS_OUTPUTS:
        assert back[name].dims == ds[name].dims and back[name].attrs == ds[name].attrs
        np.testing.assert_array_equal(back[name].values, ds[name].values)
        for dim in STRESS_OUTPUTS[name][0]:
            assert list(back[dim].values) == LABELS[dim]
    with pytest.raises(ValueError, match="name must be one of"):
        stress_tensor(ds, "stress")
    with pytest.raises(ValueError, match="output_stresses containing 'cauchy'"):
        stress_tensor(ds.drop_vars("cauchy_force_stress"), "cauchy_force_stress")


def test_output_stresses_selects_the_recorded_tensors():
    solid = cartan.medium("cosserat-solid", output_stresses=["nominal", "cauchy"])
    names = set(solid.output_fields)
    assert "nominal_force_stress" in names and "cauchy_couple_stress" in names
    assert "force_stress" not in names and len(names) == 6 + 4
    assert solid.output_fields["cauchy_couple_stress"][2] == ("row", "normal")
    assert type(solid)(**solid.parameters()).output_fields == solid.output_fields
    assert cartan.medium("cosserat-solid", output_stresses=False).output_fields.keys() == {
        f"{k}_{x}" for k in ("displacement", "microrotation") for x in "xyz"}
    assert cartan.medium("cosserat-solid").parameters()["output_stresses"] is True
    for bad in ("spatial", ["body", "piola"], [], 3):
        with pytest.raises(ValueError, match="output_stresses"):
            cartan.medium("cosserat-solid", output_stresses=bad)


# ---------------------------------------------------------------- (b) objectivity
def test_rigid_motion_rotates_the_spatial_tensors():
    """Φ → gΦ, g = (c, Q) constant: the strains are unchanged, so the body tensors are unchanged,
    P → QP, C → QC, σ → QσQᵀ.  A non-homogeneous stressed state (random positions and frames);
    the strains of the two states differ by the round-off of the edge logarithms (~1e-15/h), so
    the tensors (of order 0.1–1) agree to 1e-12."""
    rng = np.random.default_rng(7)
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((4, 3, 3), length=(1.0, 0.6, 0.8))
    X = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(3)], indexing="ij"), axis=-1)
    pos = X @ np.diag([1.05, 0.97, 1.02]) + 0.02 * rng.standard_normal(X.shape)
    frames = SO3.exp(0.15 * rng.standard_normal(X.shape))
    Q, c = SO3.exp(np.array([0.3, -1.1, 0.7])), np.array([1.0, -2.0, 0.5])
    a = node_tensors(solid, solid.initial_state(grid, "arrays", positions=pos, frames=frames), grid)
    b = node_tensors(solid, solid.initial_state(grid, "arrays", positions=pos @ Q.T + c, frames=Q @ frames), grid)
    assert np.max(np.abs(a["nominal_force_stress"])) > 0.1 and np.max(np.abs(a["nominal_couple_stress"])) > 0.01
    for name in ("force_stress", "couple_stress"):
        np.testing.assert_allclose(b[name], a[name], rtol=0, atol=1e-12)
    for name in ("nominal_force_stress", "nominal_couple_stress"):
        np.testing.assert_allclose(b[name], Q @ a[name], rtol=0, atol=1e-12)
    for name in ("cauchy_force_stress", "cauchy_couple_stress"):
        np.testing.assert_allclose(b[name], Q @ a[name] @ Q.T, rtol=0, atol=1e-12)
    # and the nominal tensor is not the body one: the frames do rotate it
    assert np.max(np.abs(a["nominal_force_stress"] - np.swapaxes(a["force_stress"], -1, -2))) > 1e-2


# ---------------------------------------------------------------- (c) symmetry
def homogeneous(solid, F: np.ndarray, rotation: np.ndarray) -> dict[str, np.ndarray]:
    """Tensors at x = F X with uniform frames exp(rotation) (uniform strains θ_α = RᵀF e_α, π = 0,
    exact on the lattice) on a 2 × 2 × 2 block."""
    grid = cartan.Grid((2, 2, 2), length=(1.0, 0.6, 0.8))
    return node_tensors(solid, solid.initial_state(grid, "deformation", F=F, rotation=rotation), grid)


EPS = 1e-6
GRAD = np.array([[0.3, -0.1, 0.2], [0.5, 0.4, -0.2], [0.0, 0.7, -0.6]])   # u = ε G X: u_l,k = ε G_lk
PHI = np.array([0.2, -0.4, 0.1])


@pytest.mark.parametrize("kappa", [0.5, 0.05])
def test_small_strain_force_stress_is_eringens(kappa):
    """u = εGX, φ uniform = εφ₀: P_{iα} → t_{αi} (P = tᵀ + O(ε²)) and the antisymmetric part of
    Eringen's t is κ(ε_kl − ε_lk) = 2κ e_lkm(φ_m − ω_m), ω = ½∇×u: so skew P = −κ(φ − ω)^ +
    O(ε²), proportional to κ (it vanishes for κ = 0, which the positive-definite energy excludes:
    the two values of κ show the proportionality).  The quadratic terms are below
    10(λ + 2μ + κ)ε² = 3.5e-11 with |G|, |φ₀| < 1; the stresses are O(ε) = 1e-6."""
    solid = cartan.medium("cosserat-solid", kappa=kappa)
    t = homogeneous(solid, np.eye(3) + EPS * GRAD, EPS * PHI)
    c = solid.constants
    tol = 10 * (c["lam"] + 2 * c["mu"] + c["kappa"]) * EPS**2
    t_lin, _ = eringen_stresses(EPS * GRAD.T, EPS * PHI, np.zeros((3, 3)), **c)
    for P in (t["nominal_force_stress"], t["cauchy_force_stress"]):
        np.testing.assert_allclose(P, np.broadcast_to(t_lin.T, P.shape), rtol=0, atol=tol)
    omega = 0.5 * EPS * np.array([GRAD[2, 1] - GRAD[1, 2], GRAD[0, 2] - GRAD[2, 0], GRAD[1, 0] - GRAD[0, 1]])
    np.testing.assert_allclose(skew(t["nominal_force_stress"]) / kappa,
                               np.broadcast_to(-hat(EPS * PHI - omega), (2, 2, 2, 3, 3)), rtol=0, atol=tol / kappa)
    assert np.max(np.abs(skew(t["nominal_force_stress"]))) > 100 * tol  # the antisymmetric part is seen


def test_small_strain_force_stress_is_symmetric_without_relative_rotation():
    """φ = ω (the micro-rotation follows the material rotation): ε is symmetric, so t is, for any
    κ; the output is symmetric to the O(ε²) of the linearisation, though not diagonal."""
    solid = cartan.medium("cosserat-solid")
    omega = 0.5 * np.array([GRAD[2, 1] - GRAD[1, 2], GRAD[0, 2] - GRAD[2, 0], GRAD[1, 0] - GRAD[0, 1]])
    P = homogeneous(solid, np.eye(3) + EPS * GRAD, EPS * omega)["nominal_force_stress"]
    tol = 10 * (1.0 + 2.0 + 0.5) * EPS**2
    assert np.max(np.abs(skew(P))) <= tol
    off_diagonal = P[0, 0, 0] - np.diag(np.diag(P[0, 0, 0]))
    assert np.max(np.abs(off_diagonal)) > 0.1 * EPS


def test_pure_micro_rotation_closed_form():
    """Positions fixed, every frame R = exp(φn̂) (φ = 0.3, any axis n): θ_α = Rᵀe_α, E = R − I,
    tr E = 2(cos φ − 1), so the body tensor is T = λ trE I + (μ+κ)(R − I) + μ(Rᵀ − I) and the
    nominal one P = RTᵀ = λ trE R + (μ+κ)(I − R) + μ(R² − R), whose antisymmetric part is
    [λ trE sin φ − (μ+κ) sin φ + μ(sin 2φ − sin φ)] n̂ (→ −κφn̂ for small φ: Eringen's
    t_kl − t_lk = 2κ e_lkm φ_m, transposed).  F = I, J = 1 so σ = P.  Exact on the lattice:
    round-off."""
    solid = cartan.medium("cosserat-solid")
    c = solid.constants
    lam, mu, kap = c["lam"], c["mu"], c["kappa"]
    n, phi = np.array([1.0, 2.0, 2.0]) / 3.0, 0.3
    R = SO3.exp(phi * n)
    t = homogeneous(solid, np.eye(3), phi * n)
    trE = 2 * (np.cos(phi) - 1)
    P_exact = lam * trE * R + (mu + kap) * (np.eye(3) - R) + mu * (R @ R - R)
    for name in ("nominal_force_stress", "cauchy_force_stress"):
        np.testing.assert_allclose(t[name], np.broadcast_to(P_exact, t[name].shape), rtol=0, atol=1e-14)
    w = lam * trE * np.sin(phi) - (mu + kap) * np.sin(phi) + mu * (np.sin(2 * phi) - np.sin(phi))
    np.testing.assert_allclose(skew(t["nominal_force_stress"]), np.broadcast_to(w * hat(n), (2, 2, 2, 3, 3)),
                               rtol=0, atol=1e-14)
    assert abs(w) > 0.1


# ---------------------------------------------------------------- (d) couple stress
def test_couple_stress_under_uniform_curvature():
    """Positions fixed, frames R = exp((a u + b w) ê₃): a rotation about the fixed axis e₃ that
    varies along u (bending) and along w (twist), so π_u = a e₃, π_v = 0, π_w = b e₃ exactly on
    every edge and K = [[0, 0, a], [0, 0, 0], [0, 0, b]], tr K = b.  M^α_k = α trK δ_αk + βK_kα +
    γK_αk gives M^u_3 = γa, M^w_1 = βa, M^w_3 = (α + β + γ)b, M^u_1 = M^v_2 = αb, the rest 0, and
    the nominal couple stress is C = R Mᵀ at each node.  Round-off (the edge logarithms)."""
    al, be, ga = 0.1, 0.05, 0.1
    a, b = 0.4, 0.3
    solid = cartan.medium("cosserat-solid", alpha=al, beta=be, gamma=ga)
    grid = cartan.Grid((5, 3, 4), length=(1.0, 0.6, 0.8))
    X = np.stack(np.meshgrid(*[grid.coordinates(k) for k in range(3)], indexing="ij"), axis=-1)
    angle = a * X[..., 0] + b * X[..., 2]
    R = SO3.exp(angle[..., None] * np.array([0.0, 0.0, 1.0]))
    t = node_tensors(solid, solid.initial_state(grid, "arrays", positions=X, frames=R), grid)
    M = np.zeros((3, 3))
    M[0, 2], M[2, 0], M[2, 2] = ga * a, be * a, (al + be + ga) * b
    M[0, 0] = M[1, 1] = al * b
    np.testing.assert_allclose(t["couple_stress"], np.broadcast_to(M, t["couple_stress"].shape), rtol=0, atol=1e-14)
    np.testing.assert_allclose(t["nominal_couple_stress"], R @ M.T, rtol=0, atol=1e-14)
    # β and γ are told apart: the couple on the face ⊥ u about e₃ is γa, on the face ⊥ w about e₁ βa
    C = t["nominal_couple_stress"][2, 1, 1]
    assert C[:, 0] @ (R[2, 1, 1] @ [0.0, 0.0, 1.0]) == pytest.approx(ga * a, abs=1e-14)
    assert C[:, 2] @ (R[2, 1, 1] @ [1.0, 0.0, 0.0]) == pytest.approx(be * a, abs=1e-14)
