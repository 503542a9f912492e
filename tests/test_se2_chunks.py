"""SE(2)'s fused kernels and passes over edges and nodes (``cartan.groups.se2``) against its point kernels.

The generated compiled loops bind ``se2_Ad_T_point``, ``se2_dexp_inv_T_pair_point``,
``se2_axis_flow_point``, ``se2_log_chunk_point`` … instead of the forms built from the 3 × 3
matrices of the point kernels (``cartan.compiled.kernels.FUSED_OPS``).  Each must give those
forms' values: the matrices here come from the group's methods (the point kernels' batch loops),
on random elements with rotation angles spread over (−π, π) and clustered near 0 (the series
branches, below and above the 0.1 rad switch) and near ±π (the closed forms, the logarithm's
fallback where ``g₂₂ + g₃₃ ≤ 0``).

Tolerance ``TOL = 1e-14`` relative to each result's scale: the fused kernels take the same
products in the same order or leave out products by exact zeros and ones (the same values), and
the logarithm, the cosines and the sines of the free flow come from series (``atan(u)/u``,
``1 − Bt²``, ``At``) instead of ``atan2``, ``cos`` and ``sin``: a few ulps (observed ≤ 2e-16
relative), against a few 1e-13 for a run's compiled-vs-reference bound.

Compile budget: the edge passes and the node updates in ``make test`` (their compiled functions
are those of the SE(2) loops the fast suite compiles anyway); the fused products and the free
flow, ≈ 5–8 s of compilation each on a fresh cache, in ``make test-slow`` (the SE(2) rods of
``tests/test_lattice_compiled.py`` run them in whole loops against the numpy path).
"""

from __future__ import annotations

import numpy as np
import pytest

from cartan.groups import se2
from cartan.groups.se2 import SE2

TOL = 1e-14
G = SE2()


def _angles(rng, n):
    """Rotation angles: uniform in (−π, π), tiny (series), near the 0.1 switch, near ±π."""
    return np.concatenate([rng.uniform(-np.pi, np.pi, n), 10.0 ** rng.uniform(-12, -1, n) * rng.choice([-1, 1], n),
                           rng.uniform(0.095, 0.105, n) * rng.choice([-1, 1], n),
                           (np.pi - 10.0 ** rng.uniform(-10, -1, n)) * rng.choice([-1, 1], n),
                           [0.0, np.pi, -np.pi + 1e-15, 0.1, -0.1]])


def _algebra(rng, n=40):
    w = _angles(rng, n)
    return np.column_stack([rng.standard_normal((w.size, 2)), w])


def _close(a, b, tol=TOL):
    scale = max(1.0, float(np.max(np.abs(b))))
    assert np.all(np.isfinite(a)) and np.max(np.abs(a - b)) <= tol * scale, np.max(np.abs(a - b)) / scale


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def test_edge_passes_match_the_point_kernels(rng):
    """``log`` over edges, and both ends' ``s dexp(±ξ)⁻ᵀ q`` with and without the scale."""
    xi = _algebra(rng)
    g = G.exp(xi)
    ne = g.shape[0]
    XI = np.full((ne, 3), np.nan)
    se2.se2_log_chunk_point(g, 0, ne, XI)
    _close(XI, G.log(g))
    # the angles are principal: the logarithm gives back ξ (up to the turn at ±π)
    inside = np.abs(xi[:, 2]) < np.pi - 1e-9
    _close(XI[inside], xi[inside], 1e-9)
    Q = rng.standard_normal((ne, 3))
    A = G.dexp_inv(xi)
    ref_t = np.einsum("ejk,ej->ek", A, Q)
    ref_h = ref_t + np.einsum("ejk,ej->ek", G.ad(xi), Q)
    _close(np.einsum("ejk,ej->ek", G.dexp_inv(-xi), Q), ref_h, 1e-13)  # dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ
    scale = rng.uniform(0.5, 2.0, ne)
    for s in (np.empty(0), scale):
        VT, VH = np.full((ne, 3), np.nan), np.full((ne, 3), np.nan)
        se2.se2_dexp_inv_T_pair_chunk_point(xi, Q, s, 0, ne, VT, VH)
        f = s[:, None] if s.size else 1.0
        _close(VT, f * ref_t)
        _close(VH, f * ref_h)
    # a part of the edges only: the others untouched
    VT[:] = 0.0
    se2.se2_dexp_inv_T_pair_chunk_point(xi, Q, scale, 3, 7, VT, VH)
    assert np.all(VT[:3] == 0.0) and np.all(VT[7:] == 0.0) and np.all(VT[3:7] != 0.0)


def test_node_and_edge_updates_match_compose_and_inverse(rng):
    """``G[e] ← Dn[tail]⁻¹ G[e] Dn[head]``, ``Di = Dn⁻¹`` and ``Φ ← Φ Dn`` (every row, and a root row)."""
    n = 30
    Dn = G.exp(_algebra(rng, 8)[:n])
    G0 = G.exp(_algebra(rng, 8)[:n])
    Phi0 = G.exp(_algebra(rng, 8)[:n])
    tail, head = np.arange(n - 1), np.arange(1, n)
    Di = np.empty_like(Dn)
    Phi = Phi0.copy()
    se2.se2_frames_chunk_point(Dn, Di, Phi, 0, n)
    _close(Di, G.inverse(Dn))
    _close(Phi, G.compose(Phi0, Dn))
    root = Phi0[:1].copy()
    se2.se2_frames_chunk_point(Dn, Di, root, 0, n)
    _close(root, G.compose(Phi0[:1], Dn[:1]))
    E = G0[: n - 1].copy()
    se2.se2_move_chunk_point(Di, Dn, E, tail, head, 0, n - 1)
    _close(E, G.compose(G.compose(Di[tail], G0[: n - 1]), Dn[head]))


@pytest.mark.slow
def test_fused_products_match_the_matrices(rng):
    """``Ad_gᵀv``, ``dexp(ξ)⁻ᵀv`` and its pair, ``dexp(ξ)⁻¹v``, ``Ad_{g⁻¹}X``, ``𝓔(Δt, ξ)V`` and
    ``exp`` with ``Ad_expᵀ`` in place, point by point."""
    xi = _algebra(rng, 10)
    g = G.exp(_algebra(rng, 10))
    v = rng.standard_normal(xi.shape)
    X = rng.standard_normal((xi.shape[0], 2, 3))
    out, neg, E = np.empty(3), np.empty(3), np.empty((3, 3))
    outs = np.empty((2, 3))
    for p in range(xi.shape[0]):
        se2.se2_Ad_T_point(g[p], v[p], out)
        _close(out, G.Ad(g[p]).T @ v[p])
        se2.se2_dexp_inv_T_point(xi[p], v[p], out)
        _close(out, G.dexp_inv(xi[p]).T @ v[p])
        se2.se2_dexp_inv_T_pair_point(xi[p], v[p], out, neg)
        _close(out, G.dexp_inv(xi[p]).T @ v[p])
        _close(neg, (G.dexp_inv(xi[p]) + G.ad(xi[p])).T @ v[p])
        se2.se2_dexp_inv_apply_point(xi[p], v[p], out, None)
        _close(out, G.dexp_inv(xi[p]) @ v[p])
        se2.se2_Ad_inv_apply_point(g[p], X[p], outs, None)
        _close(outs, X[p] @ G.Ad(G.inverse(g[p])).T)
        se2.se2_E_apply_point(0.3, xi[p], X[p], outs, None)
        _close(outs, X[p] @ G.E(0.3, xi[p]).T)
        s = v[p].copy()
        se2.se2_coad_exp_point(xi[p], s, E, None)
        _close(E, G.exp(xi[p]))
        _close(s, G.Ad(G.exp(xi[p])).T @ v[p])


@pytest.mark.slow
def test_free_flow_matches_exp_and_Ad(rng):
    """One axis (``exp(t b_k)``: ``s ← Ad_Eᵀs``, ``acc ← acc E``) and the chunk's flow of axial
    pieces, with clamped nodes and held components, against the matrices."""
    n = 25
    t = _angles(rng, 6)[:n]
    S0 = rng.standard_normal((n, 3))
    acc0 = G.exp(_algebra(rng, 8)[:n])
    for k in range(3):
        for i in range(n):
            s, acc = S0[i].copy(), acc0[i].copy()
            se2.se2_axis_flow_point(k, t[i], s, acc, None)
            Ek = G.exp(t[i] * np.eye(3)[k])
            _close(s, G.Ad(Ek).T @ S0[i])
            _close(acc, acc0[i] @ Ek)
    # pieces: the translations (commuting) then the rotation, then the translations again
    tau = np.array([0.02, 0.05, 0.02])
    naxes = np.array([2, 1, 2])
    axes = np.array([[0, 1, 0], [2, 0, 0], [0, 1, 0]])
    coef = np.array([[3.0, 2.0, 0.0], [40.0, 0.0, 0.0], [3.0, 2.0, 0.0]])
    clamped = np.zeros(n, dtype=bool)
    clamped[0] = True
    held = np.zeros((n, 3), dtype=bool)
    held[-1, :2] = True
    S = S0.copy()
    Dn = np.full((n, 3, 3), np.nan)
    assert se2.se2_axial_flow_chunk_point(0, n, S, Dn, True, clamped, True, held, 3, tau, naxes, axes, coef)
    S_ref, D_ref = S0.copy(), np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    for p in range(3):
        for i in range(n):
            times = [0.0 if clamped[i] or held[i, axes[p, c]] else tau[p] * coef[p, c] * S_ref[i, axes[p, c]]
                     for c in range(naxes[p])]
            for c in range(naxes[p]):
                Ek = G.exp(times[c] * np.eye(3)[axes[p, c]])
                S_ref[i] = G.Ad(Ek).T @ S_ref[i]
                D_ref[i] = D_ref[i] @ Ek
    _close(S, S_ref)
    _close(Dn, D_ref)
    assert np.all(Dn[0] == np.eye(3)) and np.all(S[0] == S0[0])  # the clamped node stays
    # nothing moves when every node is clamped
    assert not se2.se2_axial_flow_chunk_point(0, n, S0.copy(), Dn, True, np.ones(n, dtype=bool), False, held,
                                              3, tau, naxes, axes, coef)


def test_the_generated_loops_bind_the_closed_forms():
    """Every fused operation of the generated loops is SE(2)'s closed form, none the default."""
    from cartan.compiled.kernels import FUSED_OPS

    frag = G.point_kernels()
    for op in FUSED_OPS:
        assert frag.imports[f"g_{op}"] == ("cartan.groups.se2", f"se2_{op}_point"), op
    assert frag.constants["AXIAL_FLOW_CLOSED_"] is True
