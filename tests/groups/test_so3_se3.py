"""Closed-form SO(3) and SE(3): accuracy against 50-digit references, the generic matrix
path, scipy's Rotation, numba/numpy agreement and input validation."""

from __future__ import annotations

import numpy as np
import pytest
from mpmath import mp
from scipy.spatial.transform import Rotation

from cartan._backend import use_backend
from cartan.groups.base import SymmetryGroup
from cartan.groups.se3 import SE3
from cartan.groups.so3 import SO3

BACKENDS = ("numpy", "numba")
THETAS = (0.0, 1e-12, 1e-8, 1e-4, 0.1, 1.0, np.pi - 1e-6, np.pi - 1e-9)
RTOL = 1e-13
_seed = np.random.default_rng(314159)
AXES = [a / np.linalg.norm(a) for a in _seed.normal(size=(3, 3))]
TRANSLATIONS = [s * t for s, t in zip((1e-3, 1.0, 10.0), _seed.normal(size=(3, 3)), strict=True)]
DT = 0.3

G_SO3 = SO3()
G_SE3 = SE3()


# ---------------------------------------------------------------------- helpers
def relerr(a, ref) -> float:
    """Frobenius-norm relative error (absolute when the reference vanishes)."""
    a, ref = np.asarray(a, dtype=float), np.asarray(ref, dtype=float)
    scale = np.linalg.norm(ref)
    err = np.linalg.norm(a - ref)
    return float(err / scale) if scale > 0 else float(err)


def _mp_hat3(w):
    return mp.matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _mp_block(blocks):
    """Assemble an mpmath matrix from a nested list of equally sized square blocks."""
    n = blocks[0][0].rows
    out = mp.zeros(n * len(blocks))
    for bi, row in enumerate(blocks):
        for bj, blk in enumerate(row):
            for i in range(n):
                for j in range(n):
                    out[bi * n + i, bj * n + j] = blk[i, j]
    return out


def _mp_so3_ad(w):
    return _mp_hat3(w)


def _mp_se3_ad(xi):
    K = _mp_hat3(xi[3:])
    return _mp_block([[K, _mp_hat3(xi[:3])], [mp.zeros(3), K]])


def _mp_se3_hat(xi):
    out = mp.zeros(4)
    K = _mp_hat3(xi[3:])
    for i in range(3):
        out[i + 1, 0] = xi[i]
        for j in range(3):
            out[i + 1, j + 1] = K[i, j]
    return out


def _mp_dexp(ad):
    """``Σ ad^k/(k+1)!`` as the upper-right block of ``expm([[ad, I], [0, 0]])`` (Van Loan)."""
    r = ad.rows
    big = _mp_block([[ad, mp.eye(r)], [mp.zeros(r), mp.zeros(r)]])
    full = mp.expm(big)
    out = mp.zeros(r)
    for i in range(r):
        for j in range(r):
            out[i, j] = full[i, r + j]
    return out


def _to_np(M) -> np.ndarray:
    return np.array([[float(M[i, j]) for j in range(M.cols)] for i in range(M.rows)])


def _references(v: np.ndarray, dt: float, Y: np.ndarray, hat, ad) -> dict[str, np.ndarray]:
    """50-digit references for exp, dexp, dexp_inv at ``v`` and 𝓔(dt, Y)."""
    with mp.workdps(50):
        mv = [mp.mpf(float(c)) for c in v]
        D = _mp_dexp(ad(mv))
        mdt = mp.mpf(dt)
        E = _mp_dexp(ad([mdt * mp.mpf(float(c)) for c in Y])) * mdt
        return {
            "exp": _to_np(mp.expm(hat(mv))),
            "dexp": _to_np(D),
            "dexp_inv": _to_np(mp.inverse(D)),
            "E": _to_np(E),
        }


def _so3_case(theta: float, k: int):
    w = theta * AXES[k]
    Y = w / DT
    return w, Y, _references(w, DT, Y, _mp_hat3, _mp_so3_ad)


def _se3_case(theta: float, k: int):
    xi = np.concatenate([TRANSLATIONS[k], theta * AXES[k]])
    Y = xi / DT
    return xi, Y, _references(xi, DT, Y, _mp_se3_hat, _mp_se3_ad)


_CASES: dict[tuple[str, float, int], tuple] = {}


def case(group: str, theta: float, k: int):
    key = (group, theta, k)
    if key not in _CASES:
        _CASES[key] = (_so3_case if group == "SO3" else _se3_case)(theta, k)
    return _CASES[key]


def max_errors(G: SymmetryGroup, theta: float) -> dict[str, float]:
    """Largest relative error over the axes (and translations) at angle ``theta``."""
    errs = {op: 0.0 for op in ("exp", "log", "dexp", "dexp_inv", "E")}
    for k in range(len(AXES)):
        v, Y, ref = case(G.name, theta, k)
        errs["exp"] = max(errs["exp"], relerr(G.exp(v), ref["exp"]))
        errs["log"] = max(errs["log"], relerr(G.log(ref["exp"]), v))
        errs["dexp"] = max(errs["dexp"], relerr(G.dexp(v), ref["dexp"]))
        errs["dexp_inv"] = max(errs["dexp_inv"], relerr(G.dexp_inv(v), ref["dexp_inv"]))
        errs["E"] = max(errs["E"], relerr(G.E(DT, Y), ref["E"]))
    return errs


def random_algebra(G: SymmetryGroup, shape, rng, max_angle=3.0) -> np.ndarray:
    """Random components whose rotation angles span the series branch, O(1) and near π."""
    n = int(np.prod(shape))
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.concatenate([
        10.0 ** rng.uniform(-9, -1, n // 3),
        rng.uniform(0.1, max_angle, n - 2 * (n // 3)),
        max_angle - 10.0 ** rng.uniform(-9, -3, n // 3),
    ])
    rot = axes * rng.permutation(angles)[:, None]
    if G.dim == 3:
        return rot.reshape(*shape, 3)
    return np.concatenate([rng.normal(size=(n, 3)) * 2.0, rot], axis=-1).reshape(*shape, 6)


GROUPS = pytest.mark.parametrize("G", [G_SO3, G_SE3], ids=["SO3", "SE3"])


# ---------------------------------------------------------------------- high precision
@GROUPS
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("theta", THETAS, ids=[f"{t:.10g}" for t in THETAS])
def test_accuracy_against_mpmath(G, backend, theta):
    with use_backend(backend):
        errs = max_errors(G, theta)
    bad = {op: e for op, e in errs.items() if not e <= RTOL}
    assert not bad, f"{G.name} θ={theta!r} [{backend}]: relative errors {bad}"


@GROUPS
@pytest.mark.parametrize("backend", BACKENDS)
def test_log_at_pi(G, backend):
    """At exactly θ = π the axis sign is arbitrary: compare the rotation and the axis up to sign."""
    rng = np.random.default_rng(7)
    with use_backend(backend):
        for n in [np.eye(3)[0], np.eye(3)[2], *AXES, rng.normal(size=3)]:
            n = n / np.linalg.norm(n)
            R = 2.0 * np.outer(n, n) - np.eye(3)
            if G.dim == 3:
                g, w_slice = R, slice(0, 3)
            else:
                g = np.eye(4)
                g[1:, 1:] = R
                g[1:, 0] = TRANSLATIONS[1]
                w_slice = slice(3, 6)
            xi = G.log(g)
            w = xi[w_slice]
            assert abs(np.linalg.norm(w) - np.pi) <= 4e-16 * np.pi
            assert min(relerr(w, np.pi * n), relerr(w, -np.pi * n)) <= RTOL
            assert relerr(G.exp(xi), g) <= RTOL


@GROUPS
@pytest.mark.parametrize("backend", BACKENDS)
def test_dexp_inverse_and_E_identities(G, backend):
    rng = np.random.default_rng(11)
    xi = random_algebra(G, (30,), rng)
    eye = np.eye(G.dim)
    with use_backend(backend):
        assert np.abs(G.dexp(xi) @ G.dexp_inv(xi) - eye).max() <= 1e-13
        assert np.abs(G.dexp_inv(xi) @ G.dexp(xi) - eye).max() <= 1e-13
        dt = rng.uniform(0.1, 1.0, size=30)
        ref = dt[:, None, None] * G.dexp(dt[:, None] * xi)
        assert np.abs(G.E(dt, xi) - ref).max() <= 1e-15
        g = G.exp(xi)
        assert np.abs(G.log(g) - xi).max() <= 1e-12
        assert G.defect(g).max() <= 1e-14


# ---------------------------------------------------------------------- generic path
@GROUPS
def test_closed_forms_match_generic_path(G):
    rng = np.random.default_rng(3)
    shape = (4, 6)
    xi = random_algebra(G, shape, rng, max_angle=2.5)
    eta = random_algebra(G, shape, rng, max_angle=2.5)
    x = rng.normal(size=(*shape, G.space_dim))
    base = SymmetryGroup
    g, h = base._exp(G, xi), base._exp(G, eta)
    dt = rng.uniform(0.1, 1.5, size=shape)

    def check(name, a, b, tol=1e-13):
        assert a.shape == b.shape, name
        assert relerr(a, b) <= tol, f"{name}: {relerr(a, b):.3g}"

    check("basis/hat", G._hat(xi), base._hat(G, xi), 0.0)
    check("vee", G._vee(G._hat(xi)), base._vee(G, G._hat(xi)), 1e-15)
    check("exp", G._exp(xi), g)
    check("log", G._log(g), base._log(G, g), 1e-12)
    check("compose", G._compose(g, h), base._compose(G, g, h), 1e-15)
    check("inverse", G._inverse(g), base._inverse(G, g))
    check("act", G._act(g, x), base._act(G, g, x), 1e-15)
    check("Ad", G._Ad(g), base._Ad(G, g))
    check("ad", G._ad(xi), base._ad(G, xi), 0.0)
    check("bracket", G._bracket(xi, eta), base._bracket(G, xi, eta), 1e-15)
    check("dexp", G._dexp(xi), base._dexp(G, xi))
    check("dexp_inv", G._dexp_inv(xi), base._dexp_inv(G, xi))
    check("E", G._E(dt, xi), G.E_vanloan(dt, xi))
    check("E (base)", G._E(dt, xi), base._E(G, dt, xi), 1e-15)


@GROUPS
def test_Ad_of_exp_is_exp_of_ad(G):
    from scipy.linalg import expm

    rng = np.random.default_rng(5)
    xi = random_algebra(G, (20,), rng)
    assert relerr(G.Ad(G.exp(xi)), expm(G.ad(xi))) <= 1e-13


# ---------------------------------------------------------------------- backends
def _backend_pairs(G: SymmetryGroup, rng):
    shape = (5, 7)
    xi = random_algebra(G, shape, rng)
    eta = random_algebra(G, (7,), rng)
    g = G.exp(xi)
    h = G.exp(eta)
    x = rng.normal(size=(1, 7, G.space_dim))
    dt = rng.uniform(0.05, 2.0, size=(5, 1))
    return {
        "hat": (xi,),
        "vee": (G.hat(xi),),
        "compose": (g, h),
        "inverse": (g,),
        "act": (g, x),
        "exp": (xi,),
        "log": (g,),
        "Ad": (g,),
        "coAd": (g,),
        "ad": (xi,),
        "coad": (xi,),
        "bracket": (xi, eta),
        "dexp": (xi,),
        "dexp_inv": (xi,),
        "E": (dt, xi),
    }


@GROUPS
def test_numba_matches_numpy(G):
    rng = np.random.default_rng(17)
    for op, args in _backend_pairs(G, rng).items():
        with use_backend("numpy"):
            a = getattr(G, op)(*args)
        with use_backend("numba"):
            b = getattr(G, op)(*args)
        assert a.shape == b.shape, op
        assert a.shape[:2] == (5, 7), op
        scale = max(1.0, float(np.abs(a).max()))
        assert np.abs(a - b).max() <= 1e-14 * scale, f"{op}: {np.abs(a - b).max():.3g}"


@GROUPS
def test_kernels_cover_the_contract(G):
    required = {"exp", "log", "Ad", "ad", "dexp", "dexp_inv", "E", "compose", "inverse", "act", "bracket"}
    assert required <= set(G._kernels)


@GROUPS
@pytest.mark.parametrize("backend", BACKENDS)
def test_single_points_and_scalar_dt(G, backend):
    rng = np.random.default_rng(23)
    xi = random_algebra(G, (3,), rng)[1]
    with use_backend(backend):
        assert G.exp(xi).shape == (G.matrix_size,) * 2
        assert G.log(G.exp(xi)).shape == (G.dim,)
        assert G.E(0.5, xi).shape == (G.dim, G.dim)
        assert G.act(G.exp(xi), np.ones(G.space_dim)).shape == (G.space_dim,)


# ---------------------------------------------------------------------- scipy oracle
@pytest.mark.parametrize("backend", BACKENDS)
def test_so3_against_scipy_rotation(backend):
    rng = np.random.default_rng(29)
    w = random_algebra(G_SO3, (60,), rng, max_angle=np.pi - 1e-3)
    with use_backend(backend):
        R = G_SO3.exp(w)
        np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), rtol=0, atol=2e-15)
        np.testing.assert_allclose(G_SO3.log(R), Rotation.from_matrix(R).as_rotvec(), rtol=0, atol=1e-13)


# ---------------------------------------------------------------------- structure
def test_se3_conventions():
    """The paper's layout: g = [[1, 0ᵀ], [a, A]], ξ = (a1, a2), ad = [[â2, â1], [0, â2]]."""
    a1, a2 = np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 0.0])
    g = G_SE3.exp(np.concatenate([a1, a2]))
    np.testing.assert_array_equal(g[0], [1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(g[1:, 0], a1)
    xi = np.array([1.0, 2.0, 3.0, 0.4, -0.5, 0.6])
    K, P = G_SO3.hat(xi[3:]), G_SO3.hat(xi[:3])
    np.testing.assert_array_equal(G_SE3.ad(xi)[:3, :3], K)
    np.testing.assert_array_equal(G_SE3.ad(xi)[:3, 3:], P)
    np.testing.assert_array_equal(G_SE3.ad(xi)[3:, :3], np.zeros((3, 3)))
    np.testing.assert_array_equal(G_SO3.hat([1.0, 2.0, 3.0]), [[0, -3, 2], [3, 0, -1], [-2, 1, 0]])
    x = np.array([0.3, -0.2, 0.7])
    g = G_SE3.exp(xi)
    np.testing.assert_allclose(G_SE3.act(g, x), g[1:, 1:] @ x + g[1:, 0], atol=1e-15)
    np.testing.assert_allclose(G_SE3.log_domain_norm(xi), np.linalg.norm(xi[3:]))


@GROUPS
def test_defect(G):
    rng = np.random.default_rng(31)
    g = G.exp(random_algebra(G, (4, 5), rng))
    d = G.defect(g)
    assert d.shape == (4, 5)
    assert d.max() <= 1e-14
    bad = g.copy()
    bad[..., -1, -1] += 1e-3
    assert (G.defect(bad) > 5e-4).all()
    if G.affine:
        bad = g.copy()
        bad[..., 0, 2] = 0.5
        np.testing.assert_allclose(G.defect(bad), 0.5, atol=1e-14)


# ---------------------------------------------------------------------- validation
@GROUPS
@pytest.mark.parametrize("backend", BACKENDS)
def test_wrong_shapes_name_the_argument(G, backend):
    r, m, n = G.dim, G.matrix_size, G.space_dim
    xi, g = np.zeros(r), np.eye(m)
    cases = [
        (lambda: G.exp(np.zeros(r + 1)), "xi"),
        (lambda: G.exp(1.0), "xi"),
        (lambda: G.hat(np.zeros((2, r - 1))), "xi"),
        (lambda: G.dexp(np.zeros(r + 1)), "xi"),
        (lambda: G.dexp_inv(np.zeros(r - 1)), "xi"),
        (lambda: G.ad(np.zeros(2)), "xi"),
        (lambda: G.log(np.eye(m + 1)), "g"),
        (lambda: G.log(np.zeros(m)), "g"),
        (lambda: G.Ad(np.zeros((m, m + 1))), "g"),
        (lambda: G.inverse(np.zeros((2, m - 1, m - 1))), "g"),
        (lambda: G.compose(g, np.eye(m + 1)), "h"),
        (lambda: G.act(g, np.zeros(n + 1)), "x"),
        (lambda: G.bracket(xi, np.zeros(r + 2)), "eta"),
        (lambda: G.E(0.1, np.zeros(r + 1)), "Y"),
        (lambda: G.vee(np.zeros((m + 1, m + 1))), "A"),
        (lambda: G.defect(np.zeros((m - 1, m))), "g"),
    ]
    with use_backend(backend):
        for call, name in cases:
            with pytest.raises(ValueError, match=rf"^{name} must have shape"):
                call()
