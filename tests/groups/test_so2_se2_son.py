"""SO(2), SE(2) and SO(n): closed forms against the generic matrix-group path, against 50-digit
mpmath references near θ → 0 and θ → π, the SO(n) basis conventions, and backend agreement."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
import scipy.linalg

from cartan._backend import use_backend
from cartan.groups.base import SymmetryGroup
from cartan.groups.se2 import SE2
from cartan.groups.so2 import SO2
from cartan.groups.son import SO

GROUPS = {"SO2": SO2(), "SE2": SE2(), **{f"SO({n})": SO(n) for n in range(2, 8)}}
BACKENDS = ["numpy", "numba"]
OPS = ["exp", "log", "Ad", "ad", "bracket", "dexp", "dexp_inv", "E", "compose", "inverse", "act",
       "hat", "vee"]


def _rel(a, b) -> float:
    """Norm-wise relative error ``max|a − b| / max|b|``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def _random_algebra(G, shape, rng, top=0.95 * np.pi):
    """Algebra elements ``[*shape, r]`` with log-domain norm uniform in ``[0, top)``."""
    xi = rng.normal(size=(*shape, G.dim))
    xi *= (top * rng.uniform(0, 1, size=shape) / np.maximum(G.log_domain_norm(xi), 1e-300))[..., None]
    return xi


def _with_angles(G, angles, rng):
    """An element of 𝔤 whose rotation angles are ``angles`` (random planes; SE2: random v)."""
    if isinstance(G, SE2):
        return np.array([rng.normal(), rng.normal(), angles[0]])
    n = G.matrix_size
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    B = np.zeros((n, n))
    for a, t in enumerate(angles):
        B[2 * a + 1, 2 * a] = t
        B[2 * a, 2 * a + 1] = -t
    return G._vee(Q @ B @ Q.T)


# ---------------------------------------------------------------------- construction
@pytest.mark.parametrize("n", [1, 0, -3, 2.5, 3.0, True, "3", None])
def test_SO_rejects_invalid_n(n):
    with pytest.raises(ValueError, match=r"n >= 2.*n="):
        SO(n)


def test_SO_accepts_numpy_integers_and_sets_sizes():
    G = SO(np.int64(5))
    assert (G.n, G.dim, G.matrix_size, G.name) == (5, 10, 5, "SO")
    assert type(G.n) is int
    assert G == SO(5) and G != SO(4) and hash(G) == hash(SO(5))
    assert repr(G) == "SO(n=5)"


# ---------------------------------------------------------------------- basis conventions
def test_SO_basis_reduces_to_SO2_and_the_paper_hat_map():
    np.testing.assert_array_equal(SO(2).basis(), SO2().basis())
    v1, v2, v3 = 0.3, -1.1, 2.5
    paper = np.array([[0, -v3, v2], [v3, 0, -v1], [-v2, v1, 0]])
    np.testing.assert_array_equal(SO(3).hat([v1, v2, v3]), paper)
    with use_backend("numpy"):
        np.testing.assert_array_equal(SO(3).hat([v1, v2, v3]), paper)


@pytest.mark.parametrize("n", range(2, 8))
def test_SO_basis_ordering_and_signs(n):
    G = SO(n)
    b = G.basis()
    r = G.dim
    # orthogonal for the trace form, every generator of Frobenius norm² 2
    np.testing.assert_array_equal(np.einsum("kij,lij->kl", b, b), 2 * np.eye(r))
    k = 0
    for j in range(n - 1, 0, -1):
        for i in range(j - 1, -1, -1):
            s = (-1) ** (i + j + 1)
            expected = np.zeros((n, n))
            expected[j, i], expected[i, j] = s, -s
            np.testing.assert_array_equal(b[k], expected)
            k += 1
    # the first n − 1 generators move e_(n−1); the rest are so(n−1) on the first n − 1 axes
    moved = np.linalg.norm(b[:, :, n - 1], axis=-1)
    np.testing.assert_array_equal(moved > 0, np.arange(r) < n - 1)
    if n > 2:
        np.testing.assert_array_equal(b[n - 1:, : n - 1, : n - 1], SO(n - 1).basis())
    # hence |hat(ξ) e_(n−1)|² = Σ_(k<n−1) ξ_k²  (the sigma model's operator A)
    xi = np.random.default_rng(n).normal(size=r)
    np.testing.assert_allclose(np.sum((G.hat(xi) @ np.eye(n)[n - 1]) ** 2), np.sum(xi[: n - 1] ** 2),
                               rtol=1e-14)


# ---------------------------------------------------------------------- closed forms vs generic
@pytest.mark.parametrize("name", GROUPS)
def test_closed_forms_match_the_generic_matrix_group_path(name):
    G = GROUPS[name]
    rng = np.random.default_rng(11)
    xi = _random_algebra(G, (5, 7), rng)
    eta = rng.normal(size=(5, 7, G.dim))
    x = rng.normal(size=(5, 7, G.space_dim))
    dt = rng.uniform(0.05, 1.0, size=(5, 7))
    g = G._exp(xi)
    base = SymmetryGroup
    pairs = {
        "hat": (G._hat(xi), base._hat(G, xi)),
        "vee": (G._vee(G._hat(eta)), base._vee(G, base._hat(G, eta))),
        "exp": (g, base._exp(G, xi)),
        "log": (G._log(g[0]), base._log(G, g[0])),  # scipy's logm is slow: one row
        "inverse": (G._inverse(g), base._inverse(G, g)),
        "act": (G._act(g, x), base._act(G, g, x)),
        "Ad": (G._Ad(g), base._Ad(G, g)),
        "ad": (G._ad(xi), base._ad(G, xi)),
        "bracket": (G._bracket(xi, eta), base._bracket(G, xi, eta)),
        "dexp": (G._dexp(xi), base._dexp(G, xi)),
        "dexp_inv": (G._dexp_inv(xi), base._dexp_inv(G, xi)),
        "E": (G._E(dt, xi), G.E_vanloan(dt, xi)),
    }
    for op, (closed, generic) in pairs.items():
        assert closed.shape == generic.shape, op
        err = float(np.max(np.abs(closed - generic))) / max(1.0, float(np.max(np.abs(generic))))
        assert err <= 1e-13, f"{name} {op}: closed form vs generic differ by {err:.2e}"
    assert np.max(G.defect(g)) <= 1e-13
    np.testing.assert_allclose(G._log(g), xi, rtol=0, atol=1e-13)


# ---------------------------------------------------------------------- mpmath references
MP_DPS = 50
SMALL = [1e-12, 1e-8]
NEAR_PI = [np.pi - 1e-6, np.pi - 1e-9]
MP_GROUPS = ["SO2", "SE2", "SO(2)", "SO(3)", "SO(4)", "SO(5)", "SO(6)", "SO(7)"]


def _mp_expm(A: np.ndarray) -> np.ndarray:
    with mpmath.workdps(MP_DPS):
        return np.array(mpmath.expm(mpmath.matrix(A.tolist())).tolist(), dtype=float)


def _mp_dexp(ad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Σ adᵏ/(k+1)!`` and its inverse, summed in 50-digit arithmetic."""
    with mpmath.workdps(MP_DPS):
        A = mpmath.matrix(ad.tolist())
        term = mpmath.eye(ad.shape[0])
        acc = mpmath.eye(ad.shape[0])
        k = 1
        while mpmath.mnorm(term, 1) > mpmath.mpf(10) ** (-MP_DPS + 5):
            term = term * A / (k + 1)
            acc += term
            k += 1
        inv = mpmath.inverse(acc)
        return np.array(acc.tolist(), dtype=float), np.array(inv.tolist(), dtype=float)


def _informative(G, g):
    """The entries of ``g`` that carry its information as θ → 0: the skew part of the rotation
    block (its symmetric part is 1 + O(θ²)) and, for SE(2), the translation."""
    R = g[..., 1:, 1:] if G.affine else g
    skew = 0.5 * (R - np.swapaxes(R, -1, -2))
    return np.concatenate([skew.ravel(), g[..., 1:, 0].ravel()]) if G.affine else skew.ravel()


@pytest.mark.parametrize("theta", SMALL + NEAR_PI, ids=["1e-12", "1e-8", "pi-1e-6", "pi-1e-9"])
@pytest.mark.parametrize("name", MP_GROUPS)
def test_against_mpmath_near_zero_and_pi(name, theta):
    G = GROUPS[name]
    rng = np.random.default_rng(int(1e3 * theta) + G.dim)
    if theta < 1:  # everything small
        xi = rng.normal(size=G.dim)
        xi *= theta / G.log_domain_norm(xi)
    else:  # one plane (or the rotation of SE(2)) close to π, the others moderate
        others = rng.uniform(0.1, 1.5, size=G.matrix_size // 2 - 1) if not G.affine else []
        xi = _with_angles(G, [theta, *others], rng)
    np.testing.assert_allclose(G.log_domain_norm(xi), theta, rtol=1e-14)
    R = _mp_expm(G._hat(xi))
    refs = {}
    if G.dim <= 10:
        refs["dexp"], refs["dexp_inv"] = _mp_dexp(G._ad(xi))
    for backend in BACKENDS:
        with use_backend(backend):
            g = G.exp(xi)
            errors = {"exp": _rel(g, R), "log": _rel(G.log(R), xi)}
            if theta < 1:
                errors["exp (informative part)"] = _rel(_informative(G, g), _informative(G, R))
            if refs:
                errors["dexp"] = _rel(G.dexp(xi), refs["dexp"])
                errors["dexp_inv"] = _rel(G.dexp_inv(xi), refs["dexp_inv"])
                errors["E"] = _rel(G.E(0.5, 2.0 * xi), 0.5 * refs["dexp"])
        for what, err in errors.items():
            assert err <= 1e-13, f"{name} θ={theta!r} [{backend}] {what}: relative error {err:.2e}"


# ---------------------------------------------------------------------- SO(n) identities
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("n", range(2, 8))
def test_SO_exp_log_round_trips_and_membership(n, backend):
    G = SO(n)
    rng = np.random.default_rng(100 + n)
    with use_backend(backend):
        # exp ∘ log on random rotations (QR of Gaussian matrices, determinant fixed to +1)
        Q, Rr = np.linalg.qr(rng.normal(size=(20, n, n)))
        Q = Q * np.sign(np.diagonal(Rr, axis1=-2, axis2=-1))[..., None, :]
        Q[..., 0] *= np.linalg.det(Q)[..., None]
        assert np.max(G.defect(Q)) <= 1e-13
        np.testing.assert_allclose(G.exp(G.log(Q)), Q, rtol=0, atol=1e-13)
        assert np.all(G.log_domain_norm(G.log(Q)) <= np.pi)
        # log ∘ exp inside the injectivity radius
        xi = _random_algebra(G, (20,), rng, top=0.999 * np.pi)
        g = G.exp(xi)
        assert np.max(G.defect(g)) <= 1e-13
        np.testing.assert_allclose(G.log(g), xi, rtol=0, atol=1e-13)
        # ... including one plane close to π
        for theta in NEAR_PI:
            xi = _with_angles(G, [theta, *rng.uniform(0.0, 2.0, size=n // 2 - 1)], rng)
            np.testing.assert_allclose(G.log_domain_norm(xi), theta, rtol=1e-14)
            g = G.exp(xi)
            assert G.defect(g) <= 1e-13
            np.testing.assert_allclose(G.log(g), xi, rtol=0, atol=1e-13 * np.pi)


def test_SO3_is_SO3():
    from cartan.groups.so3 import SO3

    G, H = SO(3), SO3()
    np.testing.assert_array_equal(G.basis(), H.basis())
    rng = np.random.default_rng(3)
    xi = _random_algebra(H, (5, 7), rng, top=np.pi)
    eta = rng.normal(size=(5, 7, 3))
    for backend in BACKENDS:
        with use_backend(backend):
            g = H.exp(xi)
            for op, args in _op_args(H, xi, eta, g, rng).items():
                np.testing.assert_array_equal(getattr(G, op)(*args), getattr(H, op)(*args), err_msg=op)
            np.testing.assert_array_equal(G.log_domain_norm(xi), H.log_domain_norm(xi))


@pytest.mark.parametrize("backend", BACKENDS)
def test_SO4_closed_form_equals_the_generic_path(backend):
    G = SO(4)
    rng = np.random.default_rng(4)
    xi = _random_algebra(G, (40,), rng, top=0.99 * np.pi)
    # isoclinic (u = 0 or w = 0) and single-plane rotations, where |u| = |w|
    xi[0] = G._vee(G._hat(np.eye(6)[0]) + G._hat(np.eye(6)[5])) * 1.3
    xi[1] = G._vee(G._hat(np.eye(6)[0]) - G._hat(np.eye(6)[5])) * 1.3
    xi[2] = np.eye(6)[2] * (np.pi - 1e-6)
    with use_backend(backend):
        g = G.exp(xi)
        np.testing.assert_allclose(g, scipy.linalg.expm(G.hat(xi)), rtol=0, atol=1e-14)
        np.testing.assert_allclose(G.log(g[:8]), SymmetryGroup._log(G, g[:8]), rtol=0, atol=1e-11)
        np.testing.assert_allclose(G.log(g), xi, rtol=0, atol=1e-14 * np.pi)
        np.testing.assert_allclose(G.dexp(xi), SymmetryGroup._dexp(G, xi), rtol=0, atol=1e-13)
        np.testing.assert_allclose(G.dexp_inv(xi) @ G.dexp(xi), np.broadcast_to(np.eye(6), (40, 6, 6)),
                                   rtol=0, atol=1e-12)
        # rotation angles |u| ± |w|: the largest is the spectral norm of hat(ξ)
        angles = np.max(np.abs(np.linalg.eigvals(G.hat(xi))), axis=-1)
        np.testing.assert_allclose(G.log_domain_norm(xi), angles, rtol=1e-13)
        # 𝓔 with a broadcast time step
        dt = rng.uniform(0.1, 1.0, size=(40, 1))
        E = G.E(dt, xi[:, None, :])
        np.testing.assert_allclose(E[:, 0], dt[:, :, None] * G.dexp(dt * xi), rtol=0, atol=1e-15)


def test_defects_detect_leaving_the_group():
    reflection = np.diag([-1.0, 1.0, 1.0, 1.0, 1.0])
    assert SO(5).defect(reflection) >= 2.0 - 1e-15
    assert SO2().defect(2.0 * np.eye(2)) > 1.0
    g = SE2().exp([0.3, -0.2, 1.0])
    assert SE2().defect(g) <= 1e-15
    g[0, 1] = 1e-3
    assert SE2().defect(g) >= 1e-3


# ---------------------------------------------------------------------- backends
def _op_args(G, xi, eta, g, rng):
    lead = xi.shape[:-1]
    return {
        "exp": (xi,),
        "log": (g,),
        "Ad": (g,),
        "ad": (xi,),
        "bracket": (xi, eta),
        "dexp": (xi,),
        "dexp_inv": (xi,),
        "E": (rng.uniform(0.01, 1.0, size=lead), xi),
        "compose": (g, G.inverse(g)[::-1]),
        "inverse": (g,),
        "act": (g, rng.normal(size=(*lead, G.space_dim))),
        "hat": (xi,),
        "vee": (G.hat(eta) + 1e-3 * rng.normal(size=g.shape),),
    }


@pytest.mark.parametrize("name", GROUPS)
def test_numba_and_numpy_agree(name):
    G = GROUPS[name]
    rng = np.random.default_rng(21)
    xi = _random_algebra(G, (5, 7), rng, top=0.999 * np.pi)
    xi[0, 0] = 0.0
    xi[0, 1] *= 1e-9
    eta = rng.normal(size=(5, 7, G.dim))
    with use_backend("numpy"):
        g = G.exp(xi)
    args = _op_args(G, xi, eta, g, rng)
    assert set(args) == set(OPS)
    for op, a in args.items():
        with use_backend("numba"):
            fast = getattr(G, op)(*a)
        with use_backend("numpy"):
            ref = getattr(G, op)(*a)
        assert fast.shape == ref.shape, op
        err = float(np.max(np.abs(fast - ref))) / max(1.0, float(np.max(np.abs(ref))))
        assert err <= 1e-14, f"{name} {op}: numba vs numpy differ by {err:.2e}"


def test_kernels_cover_every_operation():
    for G in (SO2(), SE2(), SO(2), SO(3), SO(4)):
        assert set(G._kernels) == set(OPS), G
    # n ≥ 5: the structural operations are compiled, the transcendental ones use numpy
    assert set(SO(6)._kernels) == {"hat", "vee", "compose", "inverse", "act", "Ad", "ad", "bracket"}


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("eps", [1e-6, 1e-9, 1e-12])
def test_so4_log_of_double_rotation_near_pi_keeps_its_branch(backend, eps):
    """Rotation by π − ε in two orthogonal planes (isoclinic): the principal branch must be
    decided by a first-order quantity; p₀ + q₀ is O(ε²) there and rounding once flipped it."""
    g = SO(4)
    xi = np.zeros(6)
    xi[2] = xi[3] = np.pi - eps  # the two planes of this example (components of the failing draw)
    with use_backend(backend):
        back = g.log(g.exp(xi))
    # log is Lipschitz with constant ~1/ε at distance ε from the cut locus
    assert np.max(np.abs(back - xi)) <= 1e-15 / eps + 1e-13
