"""The closed-form point kernels of the generated loops against the groups' numpy reference.

Every kernel is compared with the numpy path of the same group (``G._exp``, ``G._log``,
``G._Ad``, ``G._dexp_inv`` …) over random inputs and near-singular ones (θ → 0, θ → π),
to 1e-13 relative to the size of the result.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from cartan.groups import son
from cartan.groups.se3 import SE3, se3_dexp_inv_T_pair_point, se3_dexp_inv_T_point
from cartan.groups.so3 import SO3, so3_dexp_inv_T_pair_point, so3_dexp_inv_T_point
from cartan.medium import quadratic_stress_point

TOL = 1e-13


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def _algebra(r: int, seed: int = 0) -> np.ndarray:
    """Random directions at the scales where the kernels switch formulas, and zero."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((40, r))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    scales = [0.0, 1e-12, 1e-8, 1e-4, 0.05, 0.0999, 0.1001, 0.5, 1.0, 2.0, 3.0]
    return np.concatenate([s * u for s in scales] + [rng.standard_normal((40, r))])


def _batch(kernel, *arrays, out_shape):
    """Apply a point kernel row by row."""
    out = np.empty((arrays[0].shape[0], *out_shape))
    for p in range(arrays[0].shape[0]):
        kernel(*(a[p] for a in arrays), out[p])
    return out


def _near_pi_so4(rng) -> np.ndarray:
    """so(4) elements whose two rotation angles are close to or at π."""
    G = son.SO(4)
    xs = []
    for a, b in [(np.pi, 0.3), (np.pi - 1e-9, np.pi - 1e-6), (np.pi, np.pi), (0.7, np.pi - 1e-12), (1e-9, np.pi)]:
        Z = np.linalg.qr(rng.standard_normal((4, 4)))[0]
        K = np.zeros((4, 4))
        K[1, 0], K[0, 1], K[3, 2], K[2, 3] = a, -a, b, -b
        xs.append(G._vee(Z @ K @ Z.T))
    return np.array(xs)


# ---------------------------------------------------------------------------- SO(4)
def test_so4_exp_and_log():
    G = son.SO(4)
    xi = _algebra(6)
    ref = G._exp(xi)
    got = _batch(son.so4_exp_point, xi, out_shape=(4, 4))
    assert _rel(got, ref) <= TOL
    back = _batch(son.so4_log_point, ref, out_shape=(6,))
    for p in range(xi.shape[0]):
        assert _rel(back[p], G._log(ref[p])) <= TOL, p


def test_so4_log_near_pi():
    G = son.SO(4)
    R = G._exp(_near_pi_so4(np.random.default_rng(1)))
    got = _batch(son.so4_log_point, R, out_shape=(6,))
    # at an angle of π the logarithm is not unique: compare the rotations
    assert _rel(G._exp(got), R) <= 1e-12
    assert np.all(G.log_domain_norm(got) <= np.pi + 1e-9)


def test_so4_group_products():
    G = son.SO(4)
    rng = np.random.default_rng(2)
    g = G._exp(_algebra(6, 3))
    h = G._exp(_algebra(6, 4))
    v = rng.standard_normal((g.shape[0], 6))
    assert _rel(_batch(son.so4_compose_point, g, h, out_shape=(4, 4)), g @ h) <= TOL
    assert _rel(_batch(son.so4_inverse_point, g, out_shape=(4, 4)), np.swapaxes(g, -1, -2)) <= TOL
    ref = np.einsum("pji,pj->pi", G._Ad(g), v)
    for p in range(g.shape[0]):
        got = np.empty(6)
        son.so4_Ad_T_point(g[p], v[p], got)
        assert _rel(got, ref[p]) <= TOL, p


def test_so4_dexp_inv_T_and_pair():
    G = son.SO(4)
    xi = np.concatenate([_algebra(6), _near_pi_so4(np.random.default_rng(5))])
    v = np.random.default_rng(6).standard_normal(xi.shape)
    plus = np.einsum("pji,pj->pi", G._dexp_inv(xi), v)
    minus = np.einsum("pji,pj->pi", G._dexp_inv(-xi), v)
    for p in range(xi.shape[0]):
        a, b, c = np.empty(6), np.empty(6), np.empty(6)
        son.so4_dexp_inv_T_point(xi[p], v[p], a)
        son.so4_dexp_inv_T_pair_point(xi[p], v[p], b, c)
        assert _rel(a, plus[p]) <= TOL, p
        assert _rel(b, plus[p]) <= TOL, p
        assert _rel(c, minus[p]) <= TOL, p


# ---------------------------------------------------------------------------- SO(3), SE(3)
@pytest.mark.parametrize("group, single, pair", [
    (SO3(), so3_dexp_inv_T_point, so3_dexp_inv_T_pair_point),
    # the SE(3) pair compiled on its own takes ≈ 9 s; every SE(3) loop of the fast suite runs it
    pytest.param(SE3(), se3_dexp_inv_T_point, se3_dexp_inv_T_pair_point, marks=pytest.mark.slow)])
def test_dexp_inv_T_pair(group, single, pair):
    r = group.dim
    xi = _algebra(r, 7)
    if r == 6:  # rotations near π with any translation
        u = np.random.default_rng(8).standard_normal((20, 3))
        w = (np.pi - np.logspace(-12, -1, 20))[:, None] * u / np.linalg.norm(u, axis=1, keepdims=True)
        xi = np.concatenate([xi, np.concatenate([u, w], axis=1)])
    else:
        u = np.random.default_rng(8).standard_normal((20, 3))
        xi = np.concatenate([xi, (np.pi - np.logspace(-12, -1, 20))[:, None] * u / np.linalg.norm(u, axis=1,
                                                                                               keepdims=True)])
    v = np.random.default_rng(9).standard_normal(xi.shape)
    plus = np.einsum("pji,pj->pi", group._dexp_inv(xi), v)
    minus = np.einsum("pji,pj->pi", group._dexp_inv(-xi), v)
    for p in range(xi.shape[0]):
        a, b, c = np.empty(r), np.empty(r), np.empty(r)
        single(xi[p], v[p], a)
        pair(xi[p], v[p], b, c)
        assert _rel(a, plus[p]) <= TOL, p
        assert _rel(b, plus[p]) <= TOL, p
        assert _rel(c, minus[p]) <= TOL, p


def test_generic_pair_identity():
    """The default ``g_dexp_inv_T_pair`` rests on dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ."""
    for group in (SO3(), SE3(), son.SO(4), son.SO(5)):
        xi = _algebra(group.dim, 10)[::7]
        lhs = group._dexp_inv(-xi)
        rhs = group._dexp_inv(xi) + group._ad(xi)
        assert _rel(lhs, rhs) <= 1e-12, group


# ---------------------------------------------------------------------------- quadratic stress
@njit(cache=True)
def _full_stress(X, X0, p, Q):  # pragma: no cover - compiled
    d, r = X.shape
    col = 0
    for a in range(d):
        for k in range(r):
            s = 0.0
            for b in range(d):
                for j in range(r):
                    s += p[col] * (X[b, j] - X0[b, j])
                    col += 1
            Q[a, k] = s


@pytest.mark.parametrize("d, r", [(1, 3), (2, 6), (3, 6)])
def test_quadratic_stress_skips_axes_at_rest(d, r):
    rng = np.random.default_rng(d * r)
    B = rng.standard_normal((d * r, d * r))
    p = (B @ B.T).ravel()
    X0 = rng.standard_normal((d, r))
    for axis in range(-1, d):
        X = X0.copy()
        if axis < 0:
            X += rng.standard_normal((d, r))
        else:
            X[axis] += rng.standard_normal(r)
        got, ref = np.empty((d, r)), np.empty((d, r))
        quadratic_stress_point(X, X0, p, got)
        _full_stress(X, X0, p, ref)
        assert np.array_equal(got, ref)


# ---------------------------------------------------------------------------- inlined into a loop
def _inlined_rows(kernel, nout):
    """A compiled loop applying ``kernel`` row by row with the kernel inlined, as a generated
    module compiles it (the kernels it calls are inlined in turn)."""
    inner = njit(inline="always", error_model="numpy")(kernel.py_func)
    if nout == 1:
        @njit(error_model="numpy")
        def rows(x, out):  # pragma: no cover - compiled
            for p in range(x.shape[0]):
                inner(x[p], out[p])
    else:
        @njit(error_model="numpy")
        def rows(x, v, out, out2):  # pragma: no cover - compiled
            for p in range(x.shape[0]):
                inner(x[p], v[p], out[p], out2[p])
    return rows


@pytest.mark.slow  # a loop of its own per group: 10-40 s each to compile on a fresh cache
@pytest.mark.parametrize("group, prefix", [(SO3(), "so3"), (SE3(), "se3"), (son.SO(4), "so4")])
def test_kernels_inlined_into_a_loop(group, prefix):
    """Inlined, the kernels compile without numba IR warnings and give the results of the
    kernels called alone."""
    import importlib
    import warnings

    from numba.core.errors import NumbaIRAssumptionWarning

    mod = importlib.import_module(type(group).__module__)
    exp, log, pair = (getattr(mod, f"{prefix}_{op}_point") for op in ("exp", "log", "dexp_inv_T_pair"))
    r, m = group.dim, group.matrix_size
    xi = _algebra(r, 11)
    v = np.random.default_rng(12).standard_normal(xi.shape)
    g = group._exp(xi)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumbaIRAssumptionWarning)
        got_log = np.empty((xi.shape[0], r))
        _inlined_rows(log, 1)(g, got_log)
        got_exp = np.empty((xi.shape[0], m, m))
        _inlined_rows(exp, 1)(xi, got_exp)
        got_a, got_b = np.empty(xi.shape), np.empty(xi.shape)
        _inlined_rows(pair, 2)(xi, v, got_a, got_b)
    assert _rel(got_log, _batch(log, g, out_shape=(r,))) <= TOL
    assert _rel(got_exp, _batch(exp, xi, out_shape=(m, m))) <= TOL
    for p in range(xi.shape[0]):
        a, b = np.empty(r), np.empty(r)
        pair(xi[p], v[p], a, b)
        assert _rel(got_a[p], a) <= TOL and _rel(got_b[p], b) <= TOL, p
