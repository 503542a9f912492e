"""Property tests of the Lie-group identities for every built-in group and both backends.

Each identity is exact mathematically, so the tolerances below only budget floating-point
round-off: a few hundred ulps of the quantities involved (matrix entries grow like
``exp(|ξ|)`` for the non-compact Lorentz and Poincaré groups, hence the relative scaling).
The magnitude strategy deliberately includes θ → 0 (0, 1e-12, 1e-8, 1e-4) and θ → π
(π − 1e-6, π − 1e-9), where naive formulas cancel catastrophically.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given
from hypothesis import strategies as st
from toys import params_of

import cartan
from cartan import use_backend

GROUPS = [
    ("SO2", {}),
    ("SE2", {}),
    ("SO3", {}),
    ("SE3", {}),
    ("SO", {"n": 2}),
    ("SO", {"n": 3}),
    ("SO", {"n": 4}),
    ("SO", {"n": 5}),
    ("SO", {"n": 6}),
    ("SO13", {}),
    ("Poincare", {}),
]
IDS = [name + "".join(f"-{k}{v}" for k, v in p.items()) for name, p in GROUPS]
BACKENDS = ["numba", "numpy"]
SPECIAL = [0.0, 1e-12, 1e-8, 1e-4, 0.1, 1.0, np.pi - 1e-6, np.pi - 1e-9]
EPS = 1e-12  # round-off budget per unit of magnitude (≈ 4500 ulps; cf. module docstring)

def _group(name, params):
    return cartan.group(name, **params)


@st.composite
def algebra(draw, g, max_mag=np.pi, special=True):
    """An algebra element whose log-domain norm is a drawn magnitude (special values included)."""
    r = g.dim
    direction = np.array(draw(st.lists(st.floats(-1, 1), min_size=r, max_size=r)))
    if np.linalg.norm(direction) < 1e-3:
        direction = np.eye(r)[0]
    mags = st.floats(0, max_mag)
    if special:
        mags = st.sampled_from([m for m in SPECIAL if m <= max_mag]) | mags
    mag = draw(mags)
    xi = direction / np.linalg.norm(direction)
    norm = float(g.log_domain_norm(xi))
    if norm > 1e-12:  # scale so that the group's own log-domain norm equals mag
        xi = xi * (mag / norm)
    else:  # a pure translation: any size is fine
        xi = xi * mag
    # A tiny rotation part would blow the translation up; cap |ξ| (the log-domain norm only
    # shrinks, so the element stays a valid draw) to keep round-off budgets meaningful.
    big = np.linalg.norm(xi)
    if big > 10.0:
        xi = xi * (10.0 / big)
    return xi


def _close(a, b, scale=1.0, eps=EPS):
    err = np.max(np.abs(np.asarray(a) - np.asarray(b)))
    assert err <= eps * max(scale, 1.0), f"error {err:.3e} > {eps:.0e} x {max(scale, 1.0):.3g}"


def _scale(g_elem):
    return float(np.max(np.abs(g_elem))) ** 2


# Moderate magnitudes for the non-compact groups keep |Λ| ~ e^3 so round-off stays visible.
def _max_mag(g):
    return 3.0 if g.name in ("SO13", "Poincare") else np.pi


#: the groups whose compiled kernels only the slow media use (the sigma model on S³, the
#: relativistic string): their numba kernels compile (≈ 5-15 s each on a fresh cache) in
#: ``make test-slow``; ``make test`` checks their numpy kernels
SLOW_COMPILED = {("SO", 4), ("SO13", None), ("Poincare", None)}


def slow_when(item) -> bool:
    """The compiled-kernel tests of :data:`SLOW_COMPILED` (tests/conftest.py)."""
    p = params_of(item)
    key = (p.get("name"), (p.get("params") or {}).get("n"))
    compiled = p.get("backend") == "numba" or item.originalname in {"test_vectorised_over_leading_axes",
                                                                   "test_numba_and_numpy_agree"}
    return key in SLOW_COMPILED and compiled


@pytest.fixture(params=BACKENDS)
def backend(request):
    with use_backend(request.param):
        yield request.param


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_exp_is_in_group_and_exp_log_is_identity(name, params, backend):
    g = _group(name, params)

    @given(algebra(g, _max_mag(g)))
    def check(xi):
        G = g.exp(xi)
        _close(g.defect(G), 0.0, _scale(G))
        _close(g.exp(g.log(G)), G, _scale(G))

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_log_exp_is_identity_inside_injectivity_radius(name, params, backend):
    g = _group(name, params)
    top = min(_max_mag(g), g.injectivity_radius - 1e-9)

    @given(algebra(g, top))
    def check(xi):
        # log is Lipschitz with constant ~ 1/(π − θ) near the cut locus: budget for it.
        dist = max(g.injectivity_radius - float(g.log_domain_norm(xi)), 1e-9)
        _close(g.log(g.exp(xi)), xi, (1 + np.abs(xi).max()) * max(1.0, 1e-6 / dist) * _scale(g.exp(xi)))

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_Ad_is_a_homomorphism_and_coAd_its_transpose(name, params, backend):
    g = _group(name, params)

    @given(algebra(g, _max_mag(g)), algebra(g, _max_mag(g)))
    def check(a, b):
        A, B = g.exp(a), g.exp(b)
        AB = g.compose(A, B)
        lhs, rhs = g.Ad(AB), g.Ad(A) @ g.Ad(B)
        _close(lhs, rhs, _scale(AB) ** 1.5)
        _close(g.Ad(g.inverse(A)) @ g.Ad(A), np.eye(g.dim), _scale(A) ** 2)
        _close(g.coAd(A), np.swapaxes(g.Ad(A), -1, -2))

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_Ad_of_exp_is_exp_of_ad(name, params, backend):
    g = _group(name, params)

    @given(algebra(g, _max_mag(g)), algebra(g, 1.0, special=False))
    def check(xi, eta):
        G = g.exp(xi)
        Ad = g.Ad(G)
        _close(Ad, scipy.linalg.expm(g.ad(xi)), _scale(G) ** 1.5)
        # Ad_g η = vee(g η̂ g⁻¹)
        _close(Ad @ eta, g.vee(G @ g.hat(eta) @ g.inverse(G)), _scale(G))
        # the paper's Ad*_{exp ξ} = exp(−ad*_ξ)
        _close(g.coAd(G), scipy.linalg.expm(-g.coad(xi)), _scale(G) ** 1.5)

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_bracket_ad_and_jacobi_identity(name, params, backend):
    g = _group(name, params)

    @given(algebra(g, 2.0, special=False), algebra(g, 2.0, special=False), algebra(g, 2.0, special=False))
    def check(x, y, z):
        br = g.bracket
        nx, ny, nz = (float(np.linalg.norm(v)) for v in (x, y, z))
        _close(br(x, y), g.ad(x) @ y, 10 * nx * ny)
        _close(br(x, y), -br(y, x), 10 * nx * ny)
        _close(g.hat(br(x, y)), g.hat(x) @ g.hat(y) - g.hat(y) @ g.hat(x), 10 * nx * ny)
        jac = br(x, br(y, z)) + br(y, br(z, x)) + br(z, br(x, y))
        _close(jac, 0.0, 100 * nx * ny * nz)
        _close(g.coad(x), -g.ad(x).T)

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_dexp_times_dexp_inv_is_identity(name, params, backend):
    g = _group(name, params)
    top = min(_max_mag(g), g.injectivity_radius - 1e-6)

    @given(algebra(g, top))
    def check(xi):
        D, Dinv = g.dexp(xi), g.dexp_inv(xi)
        cond = np.linalg.norm(D, 2) * np.linalg.norm(Dinv, 2)
        _close(D @ Dinv, np.eye(g.dim), cond)
        _close(Dinv @ D, np.eye(g.dim), cond)

    check()


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(24)


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_E_against_gauss_legendre_quadrature(name, params, backend):
    """𝓔(Δt, Y) = ∫₀^Δt Ad_{exp((Δt−s)Y)} ds.  The integrand is entire in s, so 24-point
    Gauss–Legendre is exact to round-off for |ΔtY| ≤ 3 (error ~ |ΔtY|^48/48!)."""
    g = _group(name, params)

    @given(st.floats(1e-3, 1.0), algebra(g, 3.0))
    def check(dt, Y):
        s = 0.5 * dt * (_GL_NODES + 1.0)
        Ads = g.Ad(g.exp((dt - s)[:, None] * Y[None, :]))
        quad = 0.5 * dt * np.einsum("k,kij->ij", _GL_WEIGHTS, Ads)
        E = g.E(dt, Y)
        _close(E, quad, dt * _scale(g.exp(dt * Y)) ** 1.5)
        _close(E, dt * g.dexp(dt * Y), dt * _scale(g.exp(dt * Y)))

    check()


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_vectorised_over_leading_axes(name, params):
    g = _group(name, params)
    rng = np.random.default_rng(1)
    xi = rng.normal(size=(2, 3, g.dim)) * 0.7
    G = g.exp(xi)
    assert G.shape == (2, 3, g.matrix_size, g.matrix_size)
    for i in range(2):
        for j in range(3):
            np.testing.assert_allclose(G[i, j], g.exp(xi[i, j]), rtol=0, atol=1e-15)
    assert g.log(G).shape == (2, 3, g.dim)
    assert g.Ad(G).shape == (2, 3, g.dim, g.dim)
    assert g.E(np.full((2, 1), 0.1), xi).shape == (2, 3, g.dim, g.dim)
    x = rng.normal(size=(3, g.space_dim))
    assert g.act(G, x).shape == (2, 3, g.space_dim)
    assert g.compose(G, g.identity()).shape == G.shape


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_numba_and_numpy_agree(name, params):
    """The two backends compute the same formulas: agreement to 1e-14 relative."""
    g = _group(name, params)
    rng = np.random.default_rng(7)
    xi = rng.normal(size=(5, 7, g.dim))
    xi *= (np.pi * rng.uniform(0, 0.999, size=(5, 7)) / np.maximum(g.log_domain_norm(xi), 1e-300))[..., None]
    xi[0, 0] = 0.0
    xi[0, 1] *= 1e-9
    eta = rng.normal(size=(5, 7, g.dim))
    x = rng.normal(size=(5, 7, g.space_dim))
    dt = rng.uniform(0.01, 1.0, size=(5, 7))
    results = {}
    for be in BACKENDS:
        with use_backend(be):
            G = g.exp(xi)
            results[be] = {
                "exp": G,
                "log": g.log(G),
                "Ad": g.Ad(G),
                "ad": g.ad(xi),
                "bracket": g.bracket(xi, eta),
                "dexp": g.dexp(xi),
                "dexp_inv": g.dexp_inv(xi),
                "E": g.E(dt, xi),
                "compose": g.compose(G, G),
                "inverse": g.inverse(G),
                "act": g.act(G, x),
                "hat": g.hat(xi),
            }
    for op, a in results["numba"].items():
        b = results["numpy"][op]
        scale = max(1.0, float(np.max(np.abs(b))))
        err = float(np.max(np.abs(a - b))) / scale
        assert err <= 1e-14, f"{op}: numba vs numpy differ by {err:.2e} (relative)"


@pytest.mark.parametrize(("name", "params"), GROUPS, ids=IDS)
def test_bad_shapes_are_clear_errors(name, params):
    g = _group(name, params)
    with pytest.raises(ValueError, match=rf"xi must have shape \[\.\.\., {g.dim}\]"):
        g.exp(np.zeros(g.dim + 1))
    with pytest.raises(ValueError, match="g must have shape"):
        g.log(np.zeros((g.matrix_size + 1, g.matrix_size + 1)))
