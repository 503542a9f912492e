"""Face supports and symmetry planes of the core (:mod:`cartan.supports`).

The potentials are quadratic in the entries of q, so central differences of the energy match
the gradient to round-off; the pulled-back force (paper §IV.B) is compared with central
differences along the group's generators, O(ε²) = 1e-12 relative at ε = 1e-6.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.supports import FACES, PenaltySupport, SymmetrySupport, face_nodes, faces_of

SO3 = cartan.group("SO3")
SE3 = cartan.group("SE3")


def _frames(shape: tuple[int, ...], seed: int, spread: float = 0.4) -> np.ndarray:
    """Random SE(3) frames ``(*shape, 4, 4)`` (rotations by up to ~``spread``, positions O(1))."""
    rng = np.random.default_rng(seed)
    Phi = np.zeros((*shape, 4, 4))
    Phi[..., 0, 0] = 1.0
    Phi[..., 1:, 0] = rng.normal(size=(*shape, 3))
    Phi[..., 1:, 1:] = SO3.exp(spread * rng.normal(size=(*shape, 3)))
    return Phi


def _supports(dim: int) -> list:
    k = (2.0, 0.5, 3.0)
    return [PenaltySupport(["u-start", faces_of(dim)[-1]], k, 1.7, dim=dim),
            PenaltySupport(None, k, 0.9, dim=dim, directors=(0, 2)),
            SymmetrySupport(["u-end", faces_of(dim)[-2]], (1.0, -2.0, 0.5), 4.0, 2.5, dim=dim),
            SymmetrySupport(faces_of(dim)[-1], "y", 1.0, 3.0, dim=dim, directors=[1])]


# ---------------------------------------------------------------------------- faces and validation
def test_faces_and_nodes():
    assert faces_of(1) == ("u-start", "u-end") and faces_of(3) == FACES
    assert faces_of(2) == PenaltySupport.EDGES
    assert face_nodes("v-end", 3) == (1, (slice(None), -1, slice(None)))
    assert face_nodes("w-start", 3) == (2, (slice(None), slice(None), 0))
    a = np.arange(24).reshape(2, 3, 4)
    assert np.array_equal(a[face_nodes("u-end", 3)[1]], a[-1])
    with pytest.raises(ValueError, match="face must be one of"):
        face_nodes("w-start", 2)
    with pytest.raises(ValueError, match="dim must be 1, 2 or 3"):
        faces_of(4)


def test_bad_input_names_the_parameter():
    with pytest.raises(ValueError, match="edges must be"):
        PenaltySupport(["w-start"])                               # no w faces on a d = 2 grid
    with pytest.raises(ValueError, match="edges must be"):
        SymmetrySupport(["w-end"], "x", dim=2)
    with pytest.raises(ValueError, match="edges must be"):
        SymmetrySupport([], "x", dim=3)
    with pytest.raises(ValueError, match="dim must be"):
        SymmetrySupport(["u-start"], "x", dim=0)
    for bad in ((), (3,), (0, 0), (0.5,), "e3"):
        with pytest.raises(ValueError, match="directors must be"):
            PenaltySupport(["u-start"], dim=3, directors=bad)
    with pytest.raises(ValueError, match="normal must be"):
        SymmetrySupport(["u-start"], (0.0, 0.0, 0.0), dim=3)
    with pytest.raises(ValueError, match="position_stiffness"):
        SymmetrySupport(["u-start"], "z", -1.0, dim=3)
    with pytest.raises(ValueError, match="director_stiffness"):
        PenaltySupport(["u-start"], director_stiffness=-1.0, dim=3)
    assert SymmetrySupport(["w-start", "w-end"], "z", dim=3).edges == ("w-start", "w-end")
    assert PenaltySupport(dim=3).edges == FACES and PenaltySupport(dim=3).directors == (0, 1, 2)
    assert PenaltySupport().directors == (2,) and PenaltySupport(dim=1).directors == (0, 1, 2)


def test_grid_dimension_and_medium_checked():
    sup = SymmetrySupport(["w-start"], "z", dim=3)
    with pytest.raises(ValueError, match="dim = 3 needs SE\\(3\\) frames"):
        sup.hold(_frames((3, 3), 0))                              # a d = 2 grid
    with pytest.raises(ValueError, match="needs a medium whose points are SE\\(3\\) frames"):
        sup.bind(cartan.medium("sigma-model"))
    assert SymmetrySupport.scaled is False and PenaltySupport.scaled is False   # supports: not scaled by λ


# ---------------------------------------------------------------------------- energy and gradient
@pytest.mark.parametrize("dim, shape", [(2, (4, 3)), (3, (3, 4, 2))])
def test_gradient_matches_central_differences(dim, shape):
    held = _frames(shape, 1)
    q = _frames(shape, 2)
    dq = np.random.default_rng(3).normal(size=q.shape)
    eps = 1e-3                                # U is quadratic in q: central differences are exact
    for sup in _supports(dim):
        sup.hold(held)
        U = sup.potential_energy(q)
        assert U.shape == shape and np.all(U >= 0) and np.any(U > 0)
        assert np.all(U[tuple(slice(1, -1) for _ in shape)] == 0.0)      # interior nodes: no support
        fd = (sup.potential_energy(q + eps * dq) - sup.potential_energy(q - eps * dq)) / (2 * eps)
        an = np.sum(sup.potential_gradient(q) * dq, axis=(-2, -1))
        assert np.max(np.abs(fd - an)) <= 1e-12 * max(1.0, np.max(np.abs(an)))
        assert np.all(sup.potential_energy(held) == 0.0)


@pytest.mark.parametrize("name, dim, shape", [("cosserat-surface", 2, (3, 4)), ("cosserat-solid", 3, (3, 2, 3))])
def test_pulled_back_force_is_minus_the_derivative_along_generators(name, dim, shape):
    """T_i = −d/dε U(Φ exp(ε b_i)) (paper §IV.B), through the core's pull-back."""
    medium = cartan.medium(name)
    Phi = _frames(shape, 4)
    eps = 1e-6
    for sup in _supports(dim):
        sup.hold(_frames(shape, 5))
        sup.bind(medium)
        T = sup.force(Phi, None, 0.0)
        assert T.shape == (*shape, 6)
        for i in range(6):
            b = np.zeros(6)
            b[i] = eps
            up = sup.energy(Phi @ SE3.exp(b))
            down = sup.energy(Phi @ SE3.exp(-b))
            assert np.max(np.abs(T[..., i] + (up - down) / (2 * eps))) <= 1e-8 * max(1.0, np.max(np.abs(T)))


# ---------------------------------------------------------------------------- the rotational part
def test_all_directors_hold_exactly_the_rotations_about_the_normal():
    """Σ_i (n·(R − R̄)e_i)² = |Rᵀn − R̄ᵀn|² = 2(1 − n·R R̄ᵀ n): zero for a rotation about n at any angle."""
    n = np.array([1.0, 2.0, -2.0]) / 3.0
    sup = SymmetrySupport(["u-start"], n, 0.0, 2.0, dim=3)
    held = _frames((2, 2, 2), 6)
    sup.hold(held)
    q = held.copy()
    for angle in (0.3, 2.5):
        q[..., 1:, 1:] = SO3.exp(angle * n) @ held[..., 1:, 1:]     # spatial rotation about n
        q[..., 1:, 0] = held[..., 1:, 0] + 0.7 * np.cross(n, [0.0, 0.0, 1.0])   # a move in the plane
        assert np.max(np.abs(sup.potential_energy(q))) < 1e-14
    R = SO3.exp(np.array([0.0, 0.4, 0.1])) @ held[..., 1:, 1:]
    q[..., 1:, 1:] = R
    U = sup.potential_energy(q)
    closed = 2.0 * (1.0 - np.einsum("i,...ij,...kj,k->...", n, R, held[..., 1:, 1:], n))   # s/2 · 2(1 − n·RR̄ᵀn)
    assert np.all(U[0] > 1e-3) and np.allclose(U[0], closed[0], rtol=1e-13, atol=0)
    assert np.all(U[1:] == 0.0)


def test_surface_reduction_is_todays_shell_energy():
    """d = 2 defaults: director p = R e₃ alone; ½k(n·Δx)² + ½s(n·Δp)² and ½Δxᵀdiag(k)Δx + ½s Σ(t·Δp)²,
    t = R̄e₂ on u-edges, R̄e₁ on v-edges, written out here independently."""
    from cartan_cosserat_surface import surface

    assert surface.SymmetrySupport is SymmetrySupport and surface.PenaltySupport is PenaltySupport
    held, q = _frames((4, 5), 7), _frames((4, 5), 8)
    dx = q[..., 1:, 0] - held[..., 1:, 0]
    dp = q[..., 1:, 3] - held[..., 1:, 3]
    n = np.array([0.0, 0.6, 0.8])
    sym = SymmetrySupport(["u-start", "v-end"], n, 3.0, 2.0).hold(held)
    mask = np.zeros((4, 5))
    mask[0, :] = mask[:, -1] = 1.0
    expected = mask * 0.5 * (3.0 * (dx @ n) ** 2 + 2.0 * (dp @ n) ** 2)
    assert np.allclose(sym.potential_energy(q), expected, rtol=1e-13, atol=0)
    k = np.array([1.0, 2.0, 3.0])
    pen = PenaltySupport(["u-end", "v-start"], k, 5.0).hold(held)
    expected = np.zeros((4, 5))
    expected[-1, :] += 0.5 * np.sum(k * dx[-1] ** 2, axis=-1) + 2.5 * np.einsum("...i,...i", held[-1, :, 1:, 2],
                                                                                dp[-1]) ** 2
    expected[:, 0] += 0.5 * np.sum(k * dx[:, 0] ** 2, axis=-1) * (np.arange(4) != 3)   # corner (3, 0): K once
    expected[:, 0] += 2.5 * np.einsum("...i,...i", held[:, 0, 1:, 1], dp[:, 0]) ** 2
    assert np.allclose(pen.potential_energy(q), expected, rtol=1e-13, atol=0)
    grad = sym.potential_gradient(q)
    assert np.all(grad[..., 1:, 1:3] == 0.0)                  # e₁, e₂ free: the drill is a gauge


def test_supports_hold_the_initial_state_not_the_first_configuration_evaluated():
    """The held x̄, p̄ are the problem's initial state (``attach``): a Jacobian's finite differences
    may evaluate the load at a displaced state first, which must not become the support's rest
    (it did: a solve whose first call was such a difference held a displaced plane)."""
    from cartan_kirchhoff_love import cases

    problem = cases.helfrich_tube_problem(5)
    Phi0 = np.asarray(problem.initial.Phi)
    displaced = Phi0.copy()
    displaced[..., 1:, 0] += 1e-3
    for load in problem.loads:
        assert np.all(np.isfinite(load.potential_energy(displaced)))  # the first evaluation: displaced
        np.testing.assert_array_equal(load._held[2], Phi0[..., 1:, 0])
        assert np.all(load.potential_energy(Phi0) == 0.0)
    explicit = PenaltySupport(None, (1.0, 1.0, 1.0), 1.0).hold(displaced)  # an explicit hold is kept
    cartan.Problem(problem.medium, problem.grid, problem.initial, loads=[explicit])
    np.testing.assert_array_equal(explicit._held[2], displaced[..., 1:, 0])
