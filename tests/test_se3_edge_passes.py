"""The SE(3) passes of the generated lattice operators against the SE(3) point kernels.

``se3_log_chunk_point`` (the edges' logarithms), ``se3_dexp_inv_T_pair_chunk_point`` (both
ends' terms of the edge stresses), ``se3_move_chunk_point`` and ``se3_frames_chunk_point``
(the update by the nodes' motions) and ``se3_axial_flow_chunk_point`` (``lie-verlet``'s free
flow, every piece axial) run over many edges or nodes at once, vectorised across them; each is
compared with the point kernel it replaces, applied element by element, on elements that cover
both branches of every coefficient (turns from 1e-9 to 3 rad: the Taylor series below 0.1 rad,
the closed forms above; rotations near π, whose quaternion is not the trace one).

Tolerances: the dexp⁻¹ᵀ pair, the products and the free flow take the point kernels'
operations in the same order (series and closed forms chosen by the same test), so they agree
exactly (``==``; the free flow turns a node at rest by the identity, which may turn −0 into +0,
equal under ``==``).  The logarithm takes ``atan(x)/x`` from its series below θ = 0.1 instead of
``atan2`` (nine terms: truncation < 1e-24), so it agrees to round-off: 1e-14 relative to the
largest component (a few ulps of O(1) quantities, observed ≤ 3e-16), on the group and off it
(forward Euler's edges: the same quaternion formula there).
"""

from __future__ import annotations

import numpy as np
from toys import check_move_and_frames_passes

from cartan.groups import se3


def _elements(count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``(ξ [count, 6], exp ξ [count, 4, 4])`` with turns |ω| spread log-uniformly over
    1e-9 … 3 rad (a few near π) and translations of order one."""
    rng = np.random.default_rng(seed)
    xi = rng.standard_normal((count, 6))
    axis = xi[:, 3:] / np.linalg.norm(xi[:, 3:], axis=1, keepdims=True)
    angle = 10.0 ** rng.uniform(-9, np.log10(3.0), count)
    angle[::17] = np.pi - 10.0 ** rng.uniform(-6, -1, angle[::17].size)
    xi[:, 3:] = axis * angle[:, None]
    G = np.empty((count, 4, 4))
    for e in range(count):
        se3.se3_exp_point(xi[e], G[e])
    return xi, G


def test_log_pass_equals_the_point_logarithm_to_round_off():
    """On the group and off it (entries perturbed by 1e-3), several blocks and a partial one."""
    _, G = _elements(300)
    off = G + 1e-3 * np.random.default_rng(1).standard_normal(G.shape)
    off[:, 0, :] = (1.0, 0.0, 0.0, 0.0)
    for elements in (G, off):
        ref = np.empty((elements.shape[0], 6))
        for e in range(elements.shape[0]):
            se3.se3_log_point(elements[e], ref[e])
        got = np.full_like(ref, np.nan)
        se3.se3_log_chunk_point(elements, 0, 5, got)
        se3.se3_log_chunk_point(elements, 5, elements.shape[0], got)
        scale = np.max(np.abs(ref), axis=1)
        assert np.all(np.max(np.abs(got - ref), axis=1) <= 1e-14 * scale)


def test_pair_pass_equals_the_point_kernel():
    xi, _ = _elements(300, seed=2)
    Q = np.random.default_rng(3).standard_normal(xi.shape)
    scale = np.random.default_rng(4).uniform(0.5, 2.0, xi.shape[0])
    out, neg = np.empty(6), np.empty(6)
    for s in (scale, np.empty(0)):
        VT, VH = np.full_like(xi, np.nan), np.full_like(xi, np.nan)
        se3.se3_dexp_inv_T_pair_chunk_point(xi, Q, s, 0, xi.shape[0], VT, VH)
        for e in range(xi.shape[0]):
            se3.se3_dexp_inv_T_pair_point(xi[e], Q[e], out, neg)
            f = s[e] if s.size else 1.0
            assert np.array_equal(VT[e], f * out) and np.array_equal(VH[e], f * neg)


def test_move_and_frames_passes_equal_the_products():
    _, Dn = _elements(40, seed=5)
    _, G = _elements(60, seed=6)
    _, Phi = _elements(40, seed=7)
    check_move_and_frames_passes(se3.se3_frames_chunk_point, se3.se3_move_chunk_point, se3.se3_inverse_point,
                                 se3.se3_compose_point, Dn, G, Phi, seed=8)


def test_axial_flow_pass_equals_the_axis_flows():
    """The seven pieces of a rod's Strang splitting (translations, the three body axes and back)
    with times up to 0.6 rad (both branches of the turn's coefficients), a clamped node and a
    held component."""
    n = 150
    rng = np.random.default_rng(9)
    S = rng.standard_normal((n, 6))
    clamped = np.zeros(n, dtype=np.bool_)
    clamped[3] = True
    held = np.zeros((n, 6), dtype=np.bool_)
    held[7, 4] = True
    tau = rng.uniform(0.01, 0.2, 7)
    naxes = np.array([3, 1, 1, 1, 1, 1, 3])
    axes = np.zeros((7, 6), dtype=np.int64)
    axes[0, :3] = axes[6, :3] = (0, 1, 2)
    axes[1:6, 0] = (3, 4, 5, 4, 3)
    coef = rng.uniform(0.5, 1.5, (7, 6))
    S_ref, Dn_ref = S.copy(), np.tile(np.eye(4), (n, 1, 1))
    times = np.empty(6)
    for i in range(n):
        for p in range(7):
            for c in range(naxes[p]):
                k = axes[p, c]
                times[c] = 0.0 if clamped[i] or held[i, k] else tau[p] * (coef[p, c] * S_ref[i, k])
            for c in range(naxes[p]):
                if times[c] != 0.0:
                    se3.se3_axis_flow_point(axes[p, c], times[c], S_ref[i], Dn_ref[i], None)
    Dn = np.full((n, 4, 4), np.nan)
    moved = se3.se3_axial_flow_chunk_point(0, n, S, Dn, True, clamped, True, held, 7, tau, naxes, axes, coef)
    assert moved
    assert np.array_equal(S, S_ref) and np.array_equal(Dn, Dn_ref)
    assert np.array_equal(Dn[3], np.eye(4))


# ------------------------------------------------------------------ the shared scalar kernels
# The rod's structure-of-arrays loop (cartan.schemes._lattice_compiled_soa) and the passes above
# take their arithmetic from the same scalar kernels of cartan.groups.se3; these tests check the
# kernels against their definitions.  Tolerances: different operation orders of O(1) quantities,
# 1e-13 relative to the largest entry (a few hundred ulps; observed ≲ 1e-15).


def _hat3(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def test_Q_kernel_equals_the_block_by_its_definition():
    """``_Q_apply`` (seven cross products) against ``Q = ½P + C(KP + PK + KPK) + D(K²P + PK² −
    3KPK) + E(KPK² + K²PK)`` formed as matrices, on both branches of the coefficients."""
    xi, _ = _elements(60, seed=10)
    v = np.random.default_rng(11).standard_normal((60, 3))
    for e in range(60):
        r, w = xi[e, :3], xi[e, 3:]
        _, c, d, ee = se3.se3_dexp_coeffs(float(w @ w))
        P, K = _hat3(r), _hat3(w)
        Q = 0.5 * P + c * (K @ P + P @ K + K @ P @ K) + d * (K @ K @ P + P @ K @ K - 3.0 * K @ P @ K) \
            + ee * (K @ P @ K @ K + K @ K @ P @ K)
        ref = Q @ v[e]
        got = np.array(se3._Q_apply(*r, *w, c, d, ee, *v[e]))
        assert np.max(np.abs(got - ref)) <= 1e-13 * max(1.0, np.max(np.abs(Q))) * np.max(np.abs(v[e]))


def test_head_term_by_Ad_T_equals_the_pair_kernel_to_round_off():
    """``Ad_Gᵀ dexp(ξ)⁻ᵀq`` (the rod loop's head term, ``_Ad_T12``) against ``dexp(−ξ)⁻ᵀq`` of
    :func:`se3_dexp_inv_T_pair_point` for ``G = exp ξ`` (``dexp(−ξ)⁻ᵀ = Ad_Gᵀ dexp(ξ)⁻ᵀ``, which
    holds on the group only); ``_Ad_T12`` is :func:`se3_Ad_T_point` to the bit."""
    xi, G = _elements(200, seed=12)
    Q = np.random.default_rng(13).standard_normal(xi.shape)
    out, neg, ad = np.empty(6), np.empty(6), np.empty(6)
    for e in range(200):
        se3.se3_dexp_inv_T_pair_point(xi[e], Q[e], out, neg)
        g = G[e]
        got = np.array(se3._Ad_T12(g[1, 0], g[2, 0], g[3, 0], *g[1, 1:], *g[2, 1:], *g[3, 1:], *out))
        se3.se3_Ad_T_point(g, out, ad)
        assert np.array_equal(got, ad)
        assert np.max(np.abs(got - neg)) <= 1e-13 * max(1.0, np.max(np.abs(neg)))


def test_inverse_compose_kernel_equals_the_products():
    """``_inv_compose12(D, h) = D⁻¹h`` (the rod loop's edge update) against
    :func:`se3_inverse_point` and :func:`se3_compose_point`."""
    _, D = _elements(50, seed=14)
    _, H = _elements(50, seed=15)
    inv, ref = np.empty((4, 4)), np.empty((4, 4))
    for e in range(50):
        d, h = D[e], H[e]
        got = se3._inv_compose12(d[1, 0], d[2, 0], d[3, 0], *d[1, 1:], *d[2, 1:], *d[3, 1:],
                                 h[1, 0], h[2, 0], h[3, 0], *h[1, 1:], *h[2, 1:], *h[3, 1:])
        se3.se3_inverse_point(d, inv)
        se3.se3_compose_point(inv, h, ref)
        want = np.concatenate([ref[1:, 0], ref[1:, 1:].ravel()])
        assert np.max(np.abs(np.array(got) - want)) <= 1e-13 * max(1.0, np.max(np.abs(want)))
