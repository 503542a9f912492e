"""Closed forms of the Lorentz group SO⁺(1,3) and the Poincaré group M(1,3).

The references are 50-digit matrix exponentials (``mpmath.expm``) of the paper's matrices
``Z = [[0, cᵀ], [c, d̂]]`` and ``{y; Z} = [[0, 0ᵀ], [y, Z]]`` (section "Relativistic Cosserat
rods"), built here independently of the code under test.  Unless stated otherwise an error
is relative in the Frobenius norm, ``‖A − A_ref‖_F / ‖A_ref‖_F``.

The grid covers boost rapidities 0 … 5, rotation angles up to π − 1e-6 and *null* generators
(``|c| = |d|``, ``c ⊥ d``: ``θ² = w·w = 0`` with ``w = d + ic ≠ 0``, ``Z`` nilpotent) of
size 1e-8 … 10, where eigen-projector formulas lose all accuracy.
"""

from __future__ import annotations

import functools

import mpmath
import numpy as np
import pytest
import scipy.linalg

from cartan._backend import use_backend
from cartan.groups.base import SymmetryGroup
from cartan.groups.poincare import Poincare
from cartan.groups.so13 import SO13, rotation_angle_np

ETA = np.diag([-1.0, 1.0, 1.0, 1.0])
RAPIDITIES = [0.0, 1e-12, 1e-8, 1e-4, 0.1, 1.0, 5.0]
ANGLES = [0.0, 1e-8, 1e-3, 1.0, np.pi - 1e-6]
NULL_SIZES = [1e-8, 1e-6, 1e-4, 1e-2, 0.1, 1.0, 3.0, 10.0]
# θ² = w·w on both sides of the series/closed-form switch |θ²| = 1, for |c| = 1 and 10
THRESHOLD_THETA2 = [0.999, 1.001, -0.999, -1.001, 0.999j, 1.001j, 0.7 + 0.72j, -0.72 - 0.7j]
BACKENDS = ["numba", "numpy"]

G = SO13()
P = Poincare()

# Two fixed orthonormal directions, not aligned with the coordinate axes.
_N1 = np.array([0.48, -0.6, 0.64])
_N2 = np.cross(_N1, np.array([0.0, 0.0, 1.0]))
_N2 /= np.linalg.norm(_N2)


# ---------------------------------------------------------------------------- references
def hat3(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def lorentz_matrix(xi):
    """The paper's ``Z = [[0, cᵀ], [c, d̂]]`` for ``xi = (c; d)``."""
    Z = np.zeros((4, 4))
    Z[0, 1:] = xi[:3]
    Z[1:, 0] = xi[:3]
    Z[1:, 1:] = hat3(xi[3:])
    return Z


def poincare_matrix(xi):
    """The paper's ``{y; Z} = [[0, 0ᵀ], [y, Z]]`` for ``xi = (y; c; d)``."""
    A = np.zeros((5, 5))
    A[1:, 0] = xi[:4]
    A[1:, 1:] = lorentz_matrix(xi[4:])
    return A


def _mp_expm(A):
    with mpmath.workdps(50):
        E = mpmath.expm(mpmath.matrix(A.tolist()))
        return np.array([[float(E[i, j]) for j in range(A.shape[1])] for i in range(A.shape[0])])


@functools.cache
def _mp_expm_cached(key):
    n = int(round(len(key) ** 0.5))
    return _mp_expm(np.array(key).reshape(n, n))


def mp_expm(A):
    """50-digit ``exp(A)`` rounded to float64."""
    return _mp_expm_cached(tuple(np.asarray(A, dtype=float).ravel()))


def mp_phi1(A, dt=1.0):
    """``dt·Σ (dt A)ᵏ/(k+1)!`` from the 50-digit exponential of ``[[dt A, dt I], [0, 0]]``."""
    n = A.shape[0]
    B = np.zeros((2 * n, 2 * n))
    B[:n, :n] = dt * A
    B[:n, n:] = dt * np.eye(n)
    return mp_expm(B)[:n, n:]


def rel(a, ref):
    ref = np.asarray(ref)
    return np.linalg.norm(np.asarray(a) - ref) / np.linalg.norm(ref)


def null(m, n1=_N1, n2=_N2):
    """A null generator ``(m n1; m n2)``."""
    return np.r_[m * n1, m * n2]


def with_theta2(x, size):
    """``(c; d)`` with ``w·w = |d|² − |c|² + 2i c·d = x`` and ``|c| ≥ size``."""
    x = complex(x)
    alpha = size * max(1.0, np.sqrt(2.0 * abs(x)))
    beta = x.imag / (2.0 * alpha)
    gamma = np.sqrt(x.real + alpha**2 - beta**2)
    return np.r_[alpha * _N1, beta * _N1 + gamma * _N2]


def grid():
    """Boost along n1 with rapidity ζ combined with a rotation about n1 or n2."""
    cases = []
    for zeta in RAPIDITIES:
        for angle in ANGLES:
            for axis, tag in ((_N1, "par"), (_N2, "perp")):
                cases.append(pytest.param(np.r_[zeta * _N1, angle * axis], id=f"z{zeta:g}-a{angle:g}-{tag}"))
    return cases


NULLS = [pytest.param(null(m), id=f"null{m:g}") for m in NULL_SIZES] + [
    pytest.param(null(m, _N2, np.cross(_N1, _N2)), id=f"null{m:g}-b") for m in (1e-4, 1.0, 10.0)
]
THRESHOLD = [
    pytest.param(with_theta2(x, s), id=f"theta2={x}-c{s:g}") for x in THRESHOLD_THETA2 for s in (1.0, 10.0)
]


@pytest.fixture(params=BACKENDS)
def backend(request):
    with use_backend(request.param):
        yield request.param


# ---------------------------------------------------------------------------- SO(1,3): basics
def test_basis_and_hat_follow_the_paper():
    rng = np.random.default_rng(0)
    xi = rng.normal(size=(3, 6))
    np.testing.assert_array_equal(G.hat(xi), np.stack([lorentz_matrix(x) for x in xi]))
    np.testing.assert_array_equal(G.vee(G.hat(xi)), xi)
    np.testing.assert_array_equal(G.basis(), np.stack([lorentz_matrix(e) for e in np.eye(6)]))
    for b in G.basis():  # generators of so(1,3): ZᵀηZ... i.e. ηZ antisymmetric
        np.testing.assert_array_equal(ETA @ b, -(ETA @ b).T)
    assert (G.name, G.dim, G.matrix_size, G.affine, G.space_dim) == ("SO13", 6, 4, False, 4)


# ---------------------------------------------------------------------------- SO(1,3): exp
@pytest.mark.parametrize("xi", grid() + NULLS + THRESHOLD)
def test_exp_matches_mpmath(xi, backend):
    """Relative Frobenius error ≤ 1e-13 (measured ≤ 7e-16 on the grid, ≤ 1.2e-15 for null
    generators of size 10, whose ``Λ`` has entries ~50)."""
    assert rel(G.exp(xi), mp_expm(lorentz_matrix(xi))) <= 1e-13


@pytest.mark.parametrize("m", NULL_SIZES)
def test_null_generators_are_nilpotent_and_exp_is_quadratic(m, backend):
    xi = null(m)
    Z = lorentz_matrix(xi)
    assert np.max(np.abs(Z @ Z @ Z)) <= 1e-15 * max(m, 1.0) ** 3
    # Z³ = 0 ⇒ exp Z = I + Z + Z²/2, a second, exact-arithmetic reference
    assert rel(G.exp(xi), np.eye(4) + Z + 0.5 * Z @ Z) <= 1e-14


@pytest.mark.parametrize("xi", grid() + NULLS)
def test_exp_is_in_the_group(xi, backend):
    L = G.exp(xi)
    assert G.defect(L) <= 1e-13 * np.linalg.norm(L) ** 2
    assert L[0, 0] >= 1.0 - 1e-15 and np.linalg.det(L) > 0.0


@pytest.mark.parametrize(("a", "b"), [(0.7, 0.8), (3.0, -2.5), (1e-9, 2.0), (-5.0, 1e-12), (2.5, 2.5)])
def test_boost_rapidities_add(a, b, backend):
    """exp(a K) exp(b K) = exp((a + b) K) for boosts K along one axis; log recovers a + b."""
    K = np.r_[_N1, 0.0, 0.0, 0.0]
    prod = G.compose(G.exp(a * K), G.exp(b * K))
    assert rel(prod, G.exp((a + b) * K)) <= 1e-14
    assert np.linalg.norm(G.log(prod) - (a + b) * K) <= 1e-14 * max(1.0, abs(a) + abs(b))
    # along a coordinate axis the closed form cosh/sinh is exact
    e1 = np.r_[1.0, 0, 0, 0, 0, 0]
    L = G.exp((a + b) * e1)
    ref = np.eye(4)
    ref[0, 0] = ref[1, 1] = np.cosh(a + b)
    ref[0, 1] = ref[1, 0] = np.sinh(a + b)
    assert rel(L, ref) <= 4e-16


# ---------------------------------------------------------------------------- SO(1,3): log
@pytest.mark.parametrize("xi", grid() + NULLS + THRESHOLD)
def test_log_inverts_exp(xi, backend):
    """``|log(exp ξ) − ξ| ≤ 1e-13 |ξ|`` inside the domain (measured ≤ 2e-15)."""
    assert rotation_angle_np(xi) < np.pi  # the principal domain |Re θ| < π
    out = G.log(G.exp(xi))
    assert np.linalg.norm(out - xi) <= 1e-13 * np.linalg.norm(xi)


def test_log_is_principal_beyond_pi(backend):
    """A rotation by 2π − δ comes back as a rotation by −δ (principal branch)."""
    d = 0.3
    xi = np.r_[0.2 * _N2, (2 * np.pi - d) * _N1]
    out = G.log(G.exp(xi))
    np.testing.assert_allclose(G.exp(out), G.exp(xi), rtol=0, atol=1e-13)
    assert np.linalg.norm(out[3:]) < np.pi


# ---------------------------------------------------------------------------- SO(1,3): algebra
def test_bracket_is_an_algebra_isomorphism(backend):
    rng = np.random.default_rng(2)
    x, y = rng.normal(size=(2, 10, 6))
    br = G.bracket(x, y)
    X, Y = G.hat(x), G.hat(y)
    np.testing.assert_allclose(G.hat(br), X @ Y - Y @ X, rtol=0, atol=1e-14)
    # so(1,3) ≅ so(3, C) through w = d + ic: the bracket is the complex cross product
    wx, wy = x[:, 3:] + 1j * x[:, :3], y[:, 3:] + 1j * y[:, :3]
    wb = np.cross(wx, wy)
    np.testing.assert_allclose(br, np.concatenate([wb.imag, wb.real], axis=-1), rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", G.ad(x), y), br, rtol=0, atol=1e-14)


@pytest.mark.parametrize("xi", [np.r_[0.3, -0.2, 0.5, 1.1, 0.4, -0.7], null(3.0), null(1e-3),
                                np.r_[1.2 * _N1, 0.9 * _N2], with_theta2(1.001j, 10.0),
                                with_theta2(-0.999, 1.0), np.r_[2.0 * _N1, 0.0, 0.0, 0.0]])
def test_dexp_and_E_match_mpmath(xi, backend):
    """dexp(ξ) = Σ ad_ξᵏ/(k+1)!, 𝓔(Δt, Y) = Δt dexp(ΔtY) and dexp⁻¹ against 50-digit series
    (relative ≤ 1e-13; measured ≤ 2e-15), and against the generic Van Loan form."""
    ad = lorentz_ad(xi)
    ref = mp_phi1(ad)
    assert rel(G.dexp(xi), ref) <= 1e-13
    assert rel(G.E(0.37, xi), mp_phi1(ad, 0.37)) <= 1e-13
    assert rel(G.E(0.37, xi), G.E_vanloan(0.37, xi)) <= 1e-12
    with mpmath.workdps(50):
        inv = mpmath.inverse(mpmath.matrix(ref.tolist()))
        inv = np.array([[float(inv[i, j]) for j in range(6)] for i in range(6)])
    assert rel(G.dexp_inv(xi), inv) <= 1e-13 * np.linalg.cond(ref)


def lorentz_ad(xi):
    """``ad_ξ`` from matrix commutators with the basis (independent of the closed form)."""
    Z = lorentz_matrix(xi)
    basis = [lorentz_matrix(e) for e in np.eye(6)]
    cols = []
    for b in basis:
        C = Z @ b - b @ Z
        cols.append(np.r_[C[0, 1:], C[3, 2], C[1, 3], C[2, 1]])
    return np.array(cols).T


def test_Ad_is_conjugation_and_exp_of_ad(backend):
    rng = np.random.default_rng(3)
    for xi in [*rng.normal(size=(4, 6)), null(2.0), np.r_[3.0 * _N1, 1.0 * _N2]]:
        L = G.exp(xi)
        Linv = np.linalg.inv(L)
        Ad = G.Ad(L)
        for k, e in enumerate(np.eye(6)):
            C = L @ lorentz_matrix(e) @ Linv
            col = np.r_[C[0, 1:], C[3, 2], C[1, 3], C[2, 1]]
            np.testing.assert_allclose(Ad[:, k], col, rtol=0, atol=1e-13 * np.linalg.norm(L) ** 2)
        assert rel(Ad, mp_expm(lorentz_ad(xi))) <= 1e-13 * np.linalg.norm(L)


def test_act_inverse_compose(backend):
    rng = np.random.default_rng(4)
    xi = rng.normal(size=(6, 6))
    L = G.exp(xi)
    x = rng.normal(size=(6, 4))
    Lx = G.act(L, x)
    np.testing.assert_allclose(Lx, np.einsum("nij,nj->ni", L, x), rtol=1e-15, atol=1e-15)
    # the Minkowski square is preserved
    mink = lambda v: -v[..., 0] ** 2 + np.sum(v[..., 1:] ** 2, axis=-1)  # noqa: E731
    np.testing.assert_allclose(mink(Lx), mink(x), rtol=1e-12, atol=1e-12 * np.max(np.abs(L)) ** 2)
    np.testing.assert_allclose(G.compose(G.inverse(L), L), np.broadcast_to(np.eye(4), L.shape), atol=1e-12)
    np.testing.assert_allclose(G.compose(L, L[::-1]), L @ L[::-1], rtol=1e-15, atol=1e-14)


# ---------------------------------------------------------------------------- closed vs generic
def _random_batch(r, rng, shape=(5, 7)):
    """Algebra batches mixing magnitudes 1e-8 … 2 and null directions."""
    xi = rng.normal(size=(*shape, r))
    xi *= 10.0 ** rng.uniform(-8, 0.3, size=(*shape, 1))
    lor = xi[..., -6:]
    m = np.linalg.norm(lor[..., :3], axis=-1, keepdims=True)
    nul = np.concatenate([m * _N1, m * _N2], axis=-1)
    pick = rng.random(shape)[..., None] < 0.2
    xi[..., -6:] = np.where(pick, nul, lor)
    return xi


@pytest.mark.parametrize("group", [G, P], ids=["SO13", "Poincare"])
def test_closed_forms_match_generic_base_methods(group):
    rng = np.random.default_rng(5)
    xi = rng.normal(size=(8, group.dim)) * 0.8
    eta = rng.normal(size=(8, group.dim))
    base = SymmetryGroup
    with use_backend("numpy"):
        g = group.exp(xi)
        assert rel(g, base._exp(group, xi)) <= 1e-13
        assert rel(group.log(g), base._log(group, g)) <= 1e-11
        assert rel(group.Ad(g), base._Ad(group, g)) <= 1e-13
        assert rel(group.ad(xi), base._ad(group, xi)) <= 1e-15
        assert rel(group.bracket(xi, eta), base._bracket(group, xi, eta)) <= 1e-15
        assert rel(group.dexp(xi), base._dexp(group, xi)) <= 1e-12
        assert rel(group.dexp_inv(xi), base._dexp_inv(group, xi)) <= 1e-12
        dt = rng.uniform(0.1, 1.0, size=8)
        assert rel(group.E(dt, xi), base._E(group, dt, xi)) <= 1e-12
        assert rel(group.inverse(g), np.linalg.inv(g)) <= 1e-13
        assert rel(group.vee(group.hat(xi)), base._vee(group, base._hat(group, xi))) <= 1e-15


@pytest.mark.parametrize("group", [G, P], ids=["SO13", "Poincare"])
def test_numba_matches_numpy(group):
    """Both backends evaluate the same formulas: per-point relative difference ≤ 1e-14."""
    rng = np.random.default_rng(6)
    r = group.dim
    xi = _random_batch(r, rng)
    eta = _random_batch(r, rng)
    dt = rng.uniform(0.0, 1.5, size=(5, 7))
    x = rng.normal(size=(5, 7, group.space_dim))
    with use_backend("numpy"):
        g = group.exp(xi)
        h = group.exp(eta)
    calls = {
        "hat": lambda: group.hat(xi),
        "vee": lambda: group.vee(group.hat(xi)),
        "exp": lambda: group.exp(xi),
        "log": lambda: group.log(g),
        "Ad": lambda: group.Ad(g),
        "ad": lambda: group.ad(xi),
        "bracket": lambda: group.bracket(xi, eta),
        "dexp": lambda: group.dexp(xi),
        "dexp_inv": lambda: group.dexp_inv(xi),
        "E": lambda: group.E(dt, xi),
        "compose": lambda: group.compose(g, h),
        "inverse": lambda: group.inverse(g),
        "act": lambda: group.act(g, x),
    }
    for op, call in calls.items():
        with use_backend("numpy"):
            a = call()
        with use_backend("numba"):
            b = call()
        assert a.shape == b.shape and a.shape[:2] == (5, 7), op
        diff = np.linalg.norm((a - b).reshape(35, -1), axis=-1)
        scale = np.maximum(np.linalg.norm(a.reshape(35, -1), axis=-1), 1e-300)
        assert np.max(diff / scale) <= 1e-14, op


def test_kernels_cover_the_required_operations():
    need = {"exp", "log", "Ad", "ad", "dexp", "dexp_inv", "E", "compose", "inverse", "act", "bracket"}
    assert need <= set(SO13._kernels)
    assert {"exp", "log", "Ad", "compose", "inverse", "act"} <= set(Poincare._kernels)


@pytest.mark.parametrize("group", [G, P], ids=["SO13", "Poincare"])
def test_wrong_shapes_raise(group, backend):
    m, r = group.matrix_size, group.dim
    with pytest.raises(ValueError):
        group.exp(np.zeros(r + 1))
    with pytest.raises(ValueError):
        group.log(np.eye(m + 1))
    with pytest.raises(ValueError):
        group.Ad(np.eye(m - 1))
    with pytest.raises(ValueError):
        group.act(np.eye(m), np.zeros(group.space_dim + 1))
    with pytest.raises(ValueError):
        group.E(0.1, np.zeros((2, r - 1)))
    with pytest.raises(ValueError):
        group.bracket(np.zeros(r), np.zeros(3))
    with pytest.raises(ValueError):
        group.defect(np.zeros(m))


def test_defect_detects_non_lorentz_matrices():
    L = G.exp(np.r_[0.3, 0.1, -0.2, 0.5, 0.2, 0.1])
    assert G.defect(L) < 1e-14
    P_par = np.diag([1.0, -1.0, -1.0, -1.0])  # parity: Lorentz, improper
    T_rev = np.diag([-1.0, 1.0, 1.0, 1.0])  # time reversal: Lorentz, not orthochronous
    assert G.defect(P_par) >= 1.0
    assert G.defect(T_rev) >= 1.0
    assert G.defect(-np.eye(4)) >= 1.0  # PT: proper but not orthochronous
    assert G.defect(np.diag([1.0, 2.0, 1.0, 1.0])) >= 1.0


# ---------------------------------------------------------------------------- Poincaré
Y0 = np.array([0.3, -1.2, 0.7, 2.0])


def poincare_cases():
    cases = [pytest.param(np.r_[Y0, p.values[0]], id=p.id) for p in grid()[::3]]
    cases += [pytest.param(np.r_[Y0, p.values[0]], id=p.id) for p in NULLS + THRESHOLD]
    return cases


def test_poincare_basics():
    rng = np.random.default_rng(7)
    xi = rng.normal(size=(3, 10))
    np.testing.assert_array_equal(P.hat(xi), np.stack([poincare_matrix(x) for x in xi]))
    np.testing.assert_array_equal(P.vee(P.hat(xi)), xi)
    assert (P.name, P.dim, P.matrix_size, P.affine, P.space_dim) == ("Poincare", 10, 5, True, 4)


@pytest.mark.parametrize("xi", poincare_cases())
def test_poincare_exp_log_match_mpmath(xi, backend):
    """exp relative ≤ 1e-13 (measured ≤ 1.1e-15); log∘exp ≤ 1e-13 |ξ|; defect ≤ 1e-13 |g|²."""
    g = P.exp(xi)
    assert rel(g, mp_expm(poincare_matrix(xi))) <= 1e-13
    assert P.defect(g) <= 1e-13 * np.linalg.norm(g) ** 2
    assert np.linalg.norm(P.log(g) - xi) <= 1e-13 * np.linalg.norm(xi)


@pytest.mark.parametrize("xi", [p.values[0] for p in NULLS + THRESHOLD] + [np.r_[5.0 * _N1, 1.0 * _N2]])
def test_poincare_V_matches_mpmath(xi):
    """V = Σ Zᵏ/(k+1)!, including null Z and both sides of the series switch."""
    assert rel(P.V(xi), mp_phi1(lorentz_matrix(xi))) <= 1e-14


@pytest.mark.parametrize("xi", [np.r_[Y0, 0.3, -0.2, 0.5, 1.1, 0.4, -0.7], np.r_[Y0, null(3.0)],
                                np.r_[Y0, with_theta2(0.999j, 1.0)], np.r_[Y0, 1e-9, 0, 0, 0, 2e-9, 0]])
def test_poincare_dexp_and_E(xi, backend):
    """dexp and 𝓔 against 50-digit series of ad (relative ≤ 1e-13) and Van Loan."""
    ad = poincare_ad(xi)
    assert rel(P.ad(xi), ad) <= 1e-15
    ref = mp_phi1(ad)
    assert rel(P.dexp(xi), ref) <= 1e-13
    assert rel(P.E(0.6, xi), mp_phi1(ad, 0.6)) <= 1e-13
    assert rel(P.E(0.6, xi), P.E_vanloan(0.6, xi)) <= 1e-12
    np.testing.assert_allclose(P.dexp_inv(xi) @ P.dexp(xi), np.eye(10), atol=1e-13 * np.linalg.cond(ref))


def poincare_ad(xi):
    A = poincare_matrix(xi)
    cols = []
    for e in np.eye(10):
        B = poincare_matrix(e)
        C = A @ B - B @ A
        cols.append(np.r_[C[1:, 0], C[1, 2:], C[4, 3], C[2, 4], C[3, 2]])
    return np.array(cols).T


def test_poincare_group_operations(backend):
    rng = np.random.default_rng(8)
    xi, eta = rng.normal(size=(2, 6, 10))
    g, h = P.exp(xi), P.exp(eta)
    x = rng.normal(size=(6, 4))
    xh = np.concatenate([np.ones((6, 1)), x], axis=-1)
    np.testing.assert_allclose(P.act(g, x), np.einsum("nij,nj->ni", g, xh)[:, 1:], rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(P.compose(g, h), g @ h, rtol=1e-14, atol=1e-13)
    np.testing.assert_allclose(P.compose(P.inverse(g), g), np.broadcast_to(np.eye(5), g.shape), atol=1e-11)
    Ad = P.Ad(g)
    for n in range(6):
        ginv = np.linalg.inv(g[n])
        for k, e in enumerate(np.eye(10)):
            C = g[n] @ poincare_matrix(e) @ ginv
            col = np.r_[C[1:, 0], C[1, 2:], C[4, 3], C[2, 4], C[3, 2]]
            np.testing.assert_allclose(Ad[n, :, k], col, rtol=0, atol=1e-12 * np.linalg.norm(g[n]) ** 2)
    # bracket: {Z₁y₂ − Z₂y₁; [Z₁, Z₂]} is the matrix commutator
    X, Y = P.hat(xi), P.hat(eta)
    np.testing.assert_allclose(P.hat(P.bracket(xi, eta)), X @ Y - Y @ X, rtol=0, atol=1e-14)
    # the first row of exp is exactly (1, 0, 0, 0, 0) and the Lorentz block is SO13.exp
    np.testing.assert_array_equal(g[:, 0], np.broadcast_to(np.eye(5)[0], (6, 5)))
    np.testing.assert_allclose(g[:, 1:, 1:], G.exp(xi[:, 4:]), rtol=0, atol=1e-15 * np.max(np.abs(g)))


def test_poincare_defect():
    g = P.exp(np.r_[Y0, 0.3, 0.1, -0.2, 0.5, 0.2, 0.1])
    assert P.defect(g) < 1e-14
    bad = g.copy()
    bad[0, 2] = 1e-3
    assert P.defect(bad) >= 1e-3
    bad = g.copy()
    bad[1:, 1:] = ETA
    assert P.defect(bad) >= 1.0


def test_generic_expm_matches_scipy_on_poincare():
    """Sanity of the reference itself: scipy's expm agrees with the 50-digit one."""
    xi = np.r_[Y0, 0.3, -0.2, 0.5, 1.1, 0.4, -0.7]
    assert rel(scipy.linalg.expm(poincare_matrix(xi)), mp_expm(poincare_matrix(xi))) <= 1e-13


@pytest.mark.slow  # compiles the Poincaré dexp⁻¹ point kernel on its own (≈ 25 s on a fresh cache); the
# relativistic string's loops run the same kernel in the fast suite
@pytest.mark.parametrize("z", [0.0, 1e-7, 5e-3, 0.05, 1.5])
def test_poincare_dexp_inv_and_E_point_kernels(z):
    """The compiled dexp⁻¹, 𝓔, dexp⁻¹ᵀ pair, Ad_gᵀ and log of the Poincaré group against the numpy
    reference, with a
    Lorentz part of size z: exact (z = 0, a pure translation: ad² = 0), series in ad (below
    1e-2) and Van Loan (above); 1e-12 relative (the series' remainder is ≤ 2e-14 |ξ|)."""
    from cartan.groups.poincare import (
        poincare_Ad_T_point,
        poincare_dexp_inv_point,
        poincare_dexp_inv_T_pair_point,
        poincare_E_point,
        poincare_log_point,
    )

    P = Poincare()
    rng = np.random.default_rng(7)
    for _ in range(4):
        xi = np.concatenate([2.0 * rng.standard_normal(4), z * rng.uniform(-1.0, 1.0, 6)])
        out = np.empty((10, 10))
        poincare_dexp_inv_point(xi, out)
        ref = P.dexp_inv(xi)
        assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))
        for tau in (0.3, -1.7):
            poincare_E_point(tau, xi, out)
            ref = P.E(tau, xi)
            assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))
        v = rng.standard_normal(10)
        pos, neg = np.empty(10), np.empty(10)
        poincare_dexp_inv_T_pair_point(xi, v, pos, neg)
        for got, ref in ((pos, P.dexp_inv(xi).T @ v), (neg, P.dexp_inv(-xi).T @ v)):
            assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(ref))
        g = P.exp(xi)
        poincare_Ad_T_point(g, v, pos)
        assert np.max(np.abs(pos - P.Ad(g).T @ v)) <= 1e-12 * np.max(np.abs(P.Ad(g).T @ v))
        log = np.empty(10)
        poincare_log_point(g, log)  # Λ = I exactly for z = 0: the translation read off
        assert np.max(np.abs(log - P.log(P.exp(xi)))) <= 1e-12 * np.max(np.abs(xi))
