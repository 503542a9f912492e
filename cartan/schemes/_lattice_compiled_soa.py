"""Vectorised ``lie-verlet`` for SE(3) rods (d = 1) on structure-of-arrays copies of the state.

Used by :func:`cartan.schemes._lattice_compiled.advance` for SE(3), d = 1, with every
free-flow piece in closed form (the three translations, then single body axes: every rod
with positive inertias).  The loop works on copies of the state with one row per component
and one column per node or edge, made once per call, so that LLVM vectorises the passes over
nodes and edges.  Their bodies have no branches: the SO(3)/SE(3) coefficients come from
their Taylor series (the library's own, valid for θ < 0.1) and the edge logarithm from the
trace quaternion; each pass flags the elements outside that range (an edge turning by
0.1 rad or more; a node turning by 0.1 rad or more in one piece of the free flow, decided
per chunk of nodes) and recomputes them with the closed forms of the scalar kernels.

A step does three things to every fixed chunk of :data:`~cartan.schemes._lattice_compiled_plan.CHUNK`
nodes or edges: the nodes (half kick, constraints, free flow composed into one element per
node, frames, velocity: :func:`_drift_chunk`), the edges (conjugation ``G_e ← D_i⁻¹G_eD_j`` by
the composed free flow, then the logarithms and force terms of the new edges:
:func:`_edges_chunk`), the nodes again (force density with loads and end loads, constraints,
half kick, velocity, power and blow-up partial sums; for a chunk without loads or
constraints the force and the kick in one loop: :func:`_close_chunk`).  :func:`_soa_step`
pipelines them chunk by chunk — drift chunk ``c``, then the edges and the closing of chunk
``c − 1`` — so that the work set of a step is two chunks (about 1 MB, in the L2 cache)
however long the rod: each row of the state is read from memory once per step, not three
times (a rod of 10⁶ elements: 50 → 43 ns per element-step; 10⁴ elements, in the L3 cache:
31–32 ns either way).  The chunks form contiguous blocks, one per thread (``prange``; serial unless threads are
enabled, and then with the same results); the edge pass keeps the logarithms and stresses
of a chunk in its block's small scratch.  The SE(3) arithmetic is the scalar kernels of
:mod:`cartan.groups.se3` that the group's own passes (``se3_log_chunk_point``,
``se3_dexp_inv_T_pair_chunk_point``, ``se3_frames_chunk_point``, the axial free flow) are made
of — the logarithm's series ``_log_series12``, ``_dexp_inv_T12`` with ``_pair_coeffs_*``,
``_Ad_T12``, ``_compose12`` / ``_inv_compose12``, ``_turn`` with ``_turn_coeffs_*`` — one
implementation for both loops; these passes differ from the group's in their layout (the
state stays in rows across steps; the group's passes read ``(E, 4, 4)`` arrays) and in the
head term of an edge, ``Ad_Gᵀ`` of the tail term here (cheaper in this loop than the pair
pass's ``+ ad_ξᵀq``, equal to round-off).  The closed form of the logarithm and the chunking
come from :mod:`cartan.schemes._lattice_compiled_kernels` (round-off agreement with the
reference path).

``overdamped`` of order 1 on SE(3) rods (d = 1) reuses these passes: the exponentials of the
node velocities with the frames (series or closed forms per chunk, as the free flow), the
edge pass, the force of the closing node pass without its kick (damping at zero velocity),
then ``N = Γ⁻¹W`` with the partial sums of the powers.

Writing these loops: helpers inlined into a vectorised loop take and return scalars (an
inlined helper that takes arrays keeps LLVM from vectorising the loop), and an offset added
to a loop index is stated non-negative (``max(lo, 0)``, :func:`_chunk`) so that LLVM can
drop numba's negative-index test.
"""

from __future__ import annotations

import numpy as np
from numba import prange

from .._threads import threaded_twins
from ..groups.se3 import (
    TAYLOR_D,
    TAYLOR_E,
    _Ad_T12,
    _compose12,
    _dexp_inv_T12,
    _inv_compose12,
    _log_series12,
    _pair_coeffs_direct,
    _turn,
    _turn_coeffs_direct,
    _turn_coeffs_series,
    _V_apply,
)
from ..groups.so3 import SMALL_THETA2, TAYLOR_A, TAYLOR_B, TAYLOR_C, _poly_entries, cross3, horner
from ._lattice_compiled_kernels import (
    KIND_SE3_TRANSLATION,
    _chunk,
    _exp3_coeffs,
    _inline,
    _jit,
    _se3_log12,
    _stress6,
    _sum_parts,
)
from ._lattice_compiled_plan import (
    CHECK_CONFIGURATION,
    CHECK_MOMENTUM,
    CHUNK,
    I_C,
    I_CLAMPED,
    I_CONSTRAINED,
    I_DAMP,
    I_DIAG,
    I_END_CHUNK,
    I_END_DIV,
    I_END_FACE,
    I_END_FOLLOW,
    I_END_IDX,
    I_END_LOAD,
    I_FIELD,
    I_H,
    I_HAS_DAMP,
    I_HAS_FIELD,
    I_HAS_POWER,
    I_HAS_UBODY,
    I_LIVE,
    I_MASS,
    I_UBODY,
    I_W,
    I_WINV,
    I_X0,
)

__all__ = ["THREADED", "force_at", "lie_verlet_se3_loop", "overdamped_se3_loop", "overdamped_velocity",
           "workspace"]


#: steps advanced together, chunk by chunk, by the loop on open rods
#: (:func:`_soa_steps_blocked`): the work set is ``TIME_BLOCK + 1`` chunks per thread
#: (≈ 6 MB, in the L3 cache), so each row of the state comes from memory once per block of steps
TIME_BLOCK = 8
#: chunks per thread from which the threaded loop steps in blocks of steps too
THREAD_BLOCK_CHUNKS = 8 * TIME_BLOCK


# ---------------------------------------------------------------------------- edges
@_jit
def _soa_edges(P, g, D, conj, OUT, INC, nblocks, scratch):
    """The edges in chunks (:func:`_edges_chunk`), grouped in ``nblocks`` contiguous blocks, one
    per thread, each with its scratch."""
    nch = (g.shape[1] + CHUNK - 1) // CHUNK
    for b in prange(nblocks):
        for c in range(*_blocks(b, nblocks, nch)):
            _edges_chunk(P, g, D, conj, OUT, INC, c, scratch[0][b], scratch[1][b], scratch[2][b])


@_jit
def _edges_chunk(P, g, D, conj, OUT, INC, c, XI, QS, bad):
    """Chunk ``c`` of edges: (``conj``) ``G_e ← D_i⁻¹ G_e D_j``; then the logarithms of the edges
    with their ``J⁻¹`` coefficient and the stresses ``C(ξ/h − X₀)`` (into the scratch
    ``XI [7, CHUNK]``, ``QS [6, CHUNK]``, ``bad [CHUNK]``, which stay in the cache), the tail
    terms ``OUT`` and head terms ``INC`` (``Ad_Gᵀ OUT``); the edges beyond the series' range by
    the closed forms."""
    X0 = P[I_X0]
    C = P[I_C]
    diag = P[I_DIAG]
    h = P[I_H]
    hinv = 1.0 / h
    ne = g.shape[1]
    n = D.shape[1]
    lo, hi = _chunk(c, ne)
    if conj:
        # translations first: they read the old rotation; the last edge of a ring closes onto node 0
        top = min(hi, n - 1)
        _conjugate(g, D, lo, top - lo, lo + 1)
        if hi == ne and ne == n:
            _conjugate(g, D, ne - 1, 1, 0)
    nbad = 0
    for e0 in range(hi - lo):
        e = lo + e0
        v = _log_series12(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e],
                          g[9, e], g[10, e], g[11, e])
        XI[0, e0] = v[0]
        XI[1, e0] = v[1]
        XI[2, e0] = v[2]
        XI[3, e0] = v[3]
        XI[4, e0] = v[4]
        XI[5, e0] = v[5]
        XI[6, e0] = v[6]
        bad[e0] = v[7]
        nbad += v[7]
    if nbad:
        for e0 in range(hi - lo):
            e = lo + e0
            if bad[e0]:
                v = _se3_log12(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e],
                               g[9, e], g[10, e], g[11, e])
                for k in range(7):
                    XI[k, e0] = v[k]
    if diag:
        for k in range(6):
            ck = C[k, k]
            x0 = X0[k]
            for e0 in range(hi - lo):
                e = lo + e0
                QS[k, e0] = ck * (XI[k, e0] * hinv - x0)
    else:
        for e0 in range(hi - lo):
            e = lo + e0
            q = _stress6(X0, C, False, 1.0, XI[0, e0], XI[1, e0], XI[2, e0], XI[3, e0], XI[4, e0], XI[5, e0], h)
            for k in range(6):
                QS[k, e0] = q[k]
    # tail terms dexp(ξ)⁻ᵀq, then head terms dexp(−ξ)⁻ᵀq = Ad_Gᵀ(tail): two short loops vectorise
    # where one long one does not (the head as tail + ad_ξᵀq, as the group's pair pass takes it,
    # reads three scratch rows' worth more and costs ≈ 2 ns more per edge here)
    for e0 in range(hi - lo):
        e = lo + e0
        t2 = XI[3, e0] * XI[3, e0] + XI[4, e0] * XI[4, e0] + XI[5, e0] * XI[5, e0]
        o = _dexp_inv_T12(XI[0, e0], XI[1, e0], XI[2, e0], XI[3, e0], XI[4, e0], XI[5, e0], XI[6, e0],
                          horner(t2, TAYLOR_C), horner(t2, TAYLOR_D), horner(t2, TAYLOR_E), QS[0, e0], QS[1, e0],
                          QS[2, e0], QS[3, e0], QS[4, e0], QS[5, e0])
        OUT[0, e] = o[0]
        OUT[1, e] = o[1]
        OUT[2, e] = o[2]
        OUT[3, e] = o[3]
        OUT[4, e] = o[4]
        OUT[5, e] = o[5]
    if nbad:  # the Q block's coefficients in closed form (the logarithm gave c)
        for e0 in range(hi - lo):
            e = lo + e0
            t2 = XI[3, e0] * XI[3, e0] + XI[4, e0] * XI[4, e0] + XI[5, e0] * XI[5, e0]
            if bad[e0] and t2 >= SMALL_THETA2:
                k = _pair_coeffs_direct(t2)
                o = _dexp_inv_T12(XI[0, e0], XI[1, e0], XI[2, e0], XI[3, e0], XI[4, e0], XI[5, e0], XI[6, e0],
                                  k[1], k[2], k[3], QS[0, e0], QS[1, e0], QS[2, e0], QS[3, e0], QS[4, e0], QS[5, e0])
                for j in range(6):
                    OUT[j, e] = o[j]
    for e0 in range(hi - lo):
        e = lo + e0
        v = _Ad_T12(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e], g[9, e],
                    g[10, e], g[11, e], OUT[0, e], OUT[1, e], OUT[2, e], OUT[3, e], OUT[4, e], OUT[5, e])
        INC[0, e] = v[0]
        INC[1, e] = v[1]
        INC[2, e] = v[2]
        INC[3, e] = v[3]
        INC[4, e] = v[4]
        INC[5, e] = v[5]


@_jit
def _conjugate(g, D, e0, count, head0):
    """``G_e ← D_i⁻¹ G_e D_j`` (:func:`~cartan.groups.se3._compose12`, then
    :func:`~cartan.groups.se3._inv_compose12`) for the edges ``e = e0 + k`` (``k < count``),
    tail node ``i = e``, head node ``j = head0 + k``: translations first (they read the old
    rotation), then rotations."""
    e0 = max(e0, 0)  # (stated: no negative-index test)
    head0 = max(head0, 0)
    for k in range(count):
        e = e0 + k
        j = head0 + k
        u = _conj12(g, D, e, j)
        g[0, e] = u[0]
        g[1, e] = u[1]
        g[2, e] = u[2]
    for k in range(count):
        e = e0 + k
        j = head0 + k
        u = _conj12(g, D, e, j)
        g[3, e] = u[3]
        g[4, e] = u[4]
        g[5, e] = u[5]
        g[6, e] = u[6]
        g[7, e] = u[7]
        g[8, e] = u[8]
        g[9, e] = u[9]
        g[10, e] = u[10]
        g[11, e] = u[11]


@_inline
def _conj12(g, D, e, j):
    """The 12 entries of ``D_e⁻¹ G_e D_j`` (rows of ``g`` and ``D``)."""
    h = _compose12(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e], g[9, e],
                   g[10, e], g[11, e], D[0, j], D[1, j], D[2, j], D[3, j], D[4, j], D[5, j], D[6, j], D[7, j],
                   D[8, j], D[9, j], D[10, j], D[11, j])
    return _inv_compose12(D[0, e], D[1, e], D[2, e], D[3, e], D[4, e], D[5, e], D[6, e], D[7, e], D[8, e],
                          D[9, e], D[10, e], D[11, e], h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8], h[9],
                          h[10], h[11])


@_inline
def _blocks(b, nblocks, nch):
    """The chunks ``c0 ≤ c < c1`` of block ``b`` (contiguous blocks, one per thread)."""
    return b * nch // nblocks, (b + 1) * nch // nblocks


# ---------------------------------------------------------------------------- nodes
@_inline
def _soa_end_load(P, phi, q):
    """Body components of end load ``q``: the load (follower) or ``(Rᵀf; Rᵀm)`` (dead), R the
    rotation of the end frame."""
    load = P[I_END_LOAD][q]
    if P[I_END_FOLLOW][q]:
        return load[0], load[1], load[2], load[3], load[4], load[5]
    i = P[I_END_IDX][q]
    R = (phi[3, i], phi[4, i], phi[5, i], phi[6, i], phi[7, i], phi[8, i], phi[9, i], phi[10, i], phi[11, i])
    return (R[0] * load[0] + R[3] * load[1] + R[6] * load[2], R[1] * load[0] + R[4] * load[1] + R[7] * load[2],
            R[2] * load[0] + R[5] * load[1] + R[8] * load[2], R[0] * load[3] + R[3] * load[4] + R[6] * load[5],
            R[1] * load[3] + R[4] * load[4] + R[7] * load[5], R[2] * load[3] + R[5] * load[4] + R[8] * load[5])


@_inline
def _soa_turn_node(s, D, i, pp, qq, cs, sn):
    """Rotate node i about e_k by (cos, sin): ``S ← Ad*S`` on the plane (pp, qq), ``R ← R Rot``."""
    s[pp, i], s[qq, i] = _turn(cs, sn, s[pp, i], s[qq, i])
    s[3 + pp, i], s[3 + qq, i] = _turn(cs, sn, s[3 + pp, i], s[3 + qq, i])
    D[3 + pp, i], D[3 + qq, i] = _turn(cs, sn, D[3 + pp, i], D[3 + qq, i])
    D[6 + pp, i], D[6 + qq, i] = _turn(cs, sn, D[6 + pp, i], D[6 + qq, i])
    D[9 + pp, i], D[9 + qq, i] = _turn(cs, sn, D[9 + pp, i], D[9 + qq, i])


@_jit
def _drift_chunk(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, c):
    """First half of a step on chunk ``c`` of nodes: ``S += half·W`` and constraints; the
    palindromic free flow composed into ``D[:, i] = (t; R)``, piece by piece — translations
    ``(a; I)`` with ``L ← L − a × P``, rotations about ``e_k`` of cosine ``1 − Bθ²`` and sine
    ``Aθ`` (``fac[p, k] = τ_p/m_k``; clamped nodes have zero momentum, so every piece is the
    identity there) —; constraints; frames ``Φ_i ← Φ_i D_i``; and, when ``velocity``,
    ``N = ∂K*/∂S``."""
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    constrained = P[I_CONSTRAINED]
    n = s.shape[1]
    nf = phi.shape[1]
    lo, hi = _chunk(c, n)
    for k in range(6):
        for i0 in range(hi - lo):
            i = lo + i0
            s[k, i] = s[k, i] + half * w[k, i]
    if constrained:
        _soa_constrain(clamped, live, s, lo, hi)
    for i0 in range(hi - lo):
        i = lo + i0
        for a in range(12):
            D[a, i] = 0.0
        D[3, i] = 1.0
        D[7, i] = 1.0
        D[11, i] = 1.0
    for p in range(kinds.shape[0]):
        if kinds[p] == KIND_SE3_TRANSLATION:
            f0, f1, f2 = fac[p, 0], fac[p, 1], fac[p, 2]
            for i0 in range(hi - lo):
                i = lo + i0
                P0, P1, P2 = s[0, i], s[1, i], s[2, i]
                a0, a1, a2 = f0 * P0, f1 * P1, f2 * P2
                c0, c1, c2 = cross3(a0, a1, a2, P0, P1, P2)
                s[3, i] -= c0
                s[4, i] -= c1
                s[5, i] -= c2
                D[0, i] += D[3, i] * a0 + D[4, i] * a1 + D[5, i] * a2
                D[1, i] += D[6, i] * a0 + D[7, i] * a1 + D[8, i] * a2
                D[2, i] += D[9, i] * a0 + D[10, i] * a1 + D[11, i] * a2
            continue
        k = axes[p]
        pp = k + 1 if k < 2 else 0  # the plane (e_pp, e_qq) turned about e_k
        qq = k + 2 if k < 1 else k - 1
        f = fac[p, 3 + k]
        big = 0
        for i0 in range(hi - lo):
            i = lo + i0
            th = f * s[3 + k, i]
            big += th * th >= SMALL_THETA2
        if big:  # some angle beyond the series: closed forms for this piece of this chunk
            for i0 in range(hi - lo):
                i = lo + i0
                th = f * s[3 + k, i]
                cs, sn = _turn_coeffs_series(th) if th * th < SMALL_THETA2 else _turn_coeffs_direct(th)
                _soa_turn_node(s, D, i, pp, qq, cs, sn)
        else:
            for i0 in range(hi - lo):
                i = lo + i0
                cs, sn = _turn_coeffs_series(f * s[3 + k, i])
                _soa_turn_node(s, D, i, pp, qq, cs, sn)
    if constrained:
        _soa_constrain(clamped, live, s, lo, hi)
    if velocity:
        _soa_velocity(mass, live, clamped, constrained, s, Nv, lo, hi)
    _soa_frames(phi, D, lo, min(hi, nf))


@_jit
def _soa_frames(phi, D, lo, hi):
    """Frames ``Φ_i ← Φ_i D_i`` for the nodes ``lo ≤ i < hi`` (every node, or the root)."""
    lo = max(lo, 0)  # (stated: no negative-index test)
    for i0 in range(hi - lo):
        i = lo + i0
        o = _compose12(phi[0, i], phi[1, i], phi[2, i], phi[3, i], phi[4, i], phi[5, i], phi[6, i], phi[7, i],
                       phi[8, i], phi[9, i], phi[10, i], phi[11, i], D[0, i], D[1, i], D[2, i], D[3, i], D[4, i],
                       D[5, i], D[6, i], D[7, i], D[8, i], D[9, i], D[10, i], D[11, i])
        phi[0, i] = o[0]
        phi[1, i] = o[1]
        phi[2, i] = o[2]
        phi[3, i] = o[3]
        phi[4, i] = o[4]
        phi[5, i] = o[5]
        phi[6, i] = o[6]
        phi[7, i] = o[7]
        phi[8, i] = o[8]
        phi[9, i] = o[9]
        phi[10, i] = o[10]
        phi[11, i] = o[11]


@_inline
def _soa_exp_node(tau, x0, x1, x2, w0, w1, w2, a, b, c):
    """``exp(τ(x; w)) = (V τx; R)`` from the SE(3) coefficients ``(A, B, C)`` of ``θ = τ|w|``:
    translation, then the rotation row-major (12 scalars)."""
    R = _poly_entries(tau * w0, tau * w1, tau * w2, a, b, 1.0)
    t = _V_apply(tau * w0, tau * w1, tau * w2, b, c, tau * x0, tau * x1, tau * x2)
    return t[0], t[1], t[2], R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8]


@_jit
def _soa_exp_nodes(nv, tau, D, phi):
    """Per chunk of nodes: ``D_i = exp(τN_i)`` (SE(3); the Taylor coefficients, or the closed
    forms for a chunk with a node turning by 0.1 rad or more) and the frames ``Φ_i ← Φ_i D_i``."""
    n = nv.shape[1]
    nf = phi.shape[1]
    for c in prange((n + CHUNK - 1) // CHUNK):
        lo, hi = _chunk(c, n)
        big = 0
        for i0 in range(hi - lo):
            i = lo + i0
            w0, w1, w2 = tau * nv[3, i], tau * nv[4, i], tau * nv[5, i]
            big += w0 * w0 + w1 * w1 + w2 * w2 >= SMALL_THETA2
        if big:
            for i0 in range(hi - lo):
                i = lo + i0
                w0, w1, w2 = tau * nv[3, i], tau * nv[4, i], tau * nv[5, i]
                a, b, cc = _exp3_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
                e = _soa_exp_node(tau, nv[0, i], nv[1, i], nv[2, i], nv[3, i], nv[4, i], nv[5, i], a, b, cc)
                for k in range(12):
                    D[k, i] = e[k]
        else:
            for i0 in range(hi - lo):
                i = lo + i0
                w0, w1, w2 = tau * nv[3, i], tau * nv[4, i], tau * nv[5, i]
                q2 = w0 * w0 + w1 * w1 + w2 * w2
                e = _soa_exp_node(tau, nv[0, i], nv[1, i], nv[2, i], nv[3, i], nv[4, i], nv[5, i],
                                  horner(q2, TAYLOR_A), horner(q2, TAYLOR_B), horner(q2, TAYLOR_C))
                D[0, i] = e[0]
                D[1, i] = e[1]
                D[2, i] = e[2]
                D[3, i] = e[3]
                D[4, i] = e[4]
                D[5, i] = e[5]
                D[6, i] = e[6]
                D[7, i] = e[7]
                D[8, i] = e[8]
                D[9, i] = e[9]
                D[10, i] = e[10]
                D[11, i] = e[11]
        _soa_frames(phi, D, lo, min(hi, nf))


@_jit
def _soa_drag(P, w, gam, nv, phi, PART):
    """Per chunk of nodes, component by component: the overdamped velocity ``N = Γ⁻¹W`` (zero on
    clamped nodes and gauge components) and the partial sums of the powers at ``N`` (as
    :func:`_soa_powers`).  Returns ``(dissipated, external)``."""
    wts = P[I_W]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    damp = P[I_DAMP]
    ubody = P[I_UBODY]
    has_power = P[I_HAS_POWER]
    has_damp = has_power and P[I_HAS_DAMP]
    has_ubody = has_power and P[I_HAS_UBODY]
    n = w.shape[1]
    nch = (n + CHUNK - 1) // CHUNK
    for c in prange(nch):
        lo, hi = _chunk(c, n)
        pd = 0.0
        pe = 0.0
        for k in range(6):
            if not live[k]:
                for i0 in range(hi - lo):
                    nv[k, lo + i0] = 0.0
                continue
            gk = gam[k]
            for i0 in range(hi - lo):
                i = lo + i0
                nv[k, i] = 0.0 if clamped[i] else w[k, i] / gk
            td, te = _soa_body_powers(wts, damp, ubody, has_damp, has_ubody, nv, k, lo, hi)
            pd += td
            pe += te
        if has_power:
            pe = _soa_end_powers(P, phi, nv, c, pe)
        PART[c, 0] = pd
        PART[c, 1] = pe
        PART[c, 2] = 0.0
        PART[c, 3] = 0.0
    total = _sum_parts(PART, nch)
    return total[0], total[1]


@_jit
def _soa_finite(g, phi, PART):
    """True when any entry of the edges or the frames is not finite (``x − x ≠ 0``), counted per chunk of edges."""
    ne = g.shape[1]
    nf = phi.shape[1]
    nch = (max(ne, nf) + CHUNK - 1) // CHUNK
    for c in prange(nch):
        acc = 0
        lo, hi = _chunk(c, max(ne, nf))
        for k in range(12):
            for i0 in range(max(min(hi, ne) - lo, 0)):
                i = lo + i0
                acc += g[k, i] - g[k, i] != 0.0
            for i0 in range(max(min(hi, nf) - lo, 0)):
                i = lo + i0
                acc += phi[k, i] - phi[k, i] != 0.0
        PART[c, 0] = acc
    for c in range(nch):
        if PART[c, 0] != 0.0:
            return True
    return False


@_inline
def _soa_constrain(clamped, live, s, lo, hi):
    """Zero the components of ``s`` on clamped nodes and gauge components, nodes ``lo ≤ i < hi``."""
    for k in range(6):
        for i0 in range(hi - lo):
            i = lo + i0
            if clamped[i] or not live[k]:
                s[k, i] = 0.0


@_inline
def _soa_body_powers(wts, damp, ubody, has_damp, has_ubody, V, k, lo, hi):
    """Component ``k`` of (−Σ w V·cV, Σ w u·V) over the nodes ``lo ≤ i < hi``: the damping and
    body-frame force powers at the velocity ``V``."""
    td = 0.0
    te = 0.0
    if has_damp:
        ck = damp[k]
        for i0 in range(hi - lo):
            i = lo + i0
            td += wts[i] * ((-V[k, i] * ck) * V[k, i])
    if has_ubody:
        uk = ubody[k]
        for i0 in range(hi - lo):
            i = lo + i0
            te += wts[i] * (uk * V[k, i])
    return td, te


@_inline
def _soa_end_powers(P, phi, V, c, pe):
    """``pe`` plus the powers of the end loads of chunk ``c`` at the velocity ``V``."""
    end_idx = P[I_END_IDX]
    end_face = P[I_END_FACE]
    end_chunk = P[I_END_CHUNK]
    for q in range(end_chunk[c], end_chunk[c + 1]):
        v = _soa_end_load(P, phi, q)
        t = 0.0
        for k in range(6):
            t += v[k] * V[k, end_idx[q]]
        pe += end_face[q] * t
    return pe


@_inline
def _soa_velocity(mass, live, clamped, constrained, s, Nv, lo, hi):
    """``N = ∂K*/∂S`` on the nodes ``lo ≤ i < hi``."""
    for k in range(6):
        if not live[k]:
            for i0 in range(hi - lo):
                i = lo + i0
                Nv[k, i] = 0.0
            continue
        m = mass[k]
        for i0 in range(hi - lo):
            i = lo + i0
            Nv[k, i] = s[k, i] / m
    if constrained:
        for i0 in range(hi - lo):
            i = lo + i0
            if clamped[i]:
                for k in range(6):
                    Nv[k, i] = 0.0


@_jit
def _soa_close(P, OUT, INC, phi, s, Nv, w, half, close, velocity, inv, need_kin, PART):
    """The force and (``close``) the closing half of a step (:func:`_close_chunk`) on every chunk
    of nodes.  Returns ``(dissipated, external, ΣS, Σw S²/m)`` (zeros without ``close``)."""
    nch = (w.shape[1] + CHUNK - 1) // CHUNK
    for c in prange(nch):
        _close_chunk(P, OUT, INC, phi, s, Nv, w, half, close, velocity, inv, need_kin, PART, c)
    if not close:
        return 0.0, 0.0, 0.0, 0.0
    return _sum_parts(PART, nch)


@_jit
def _close_chunk(P, OUT, INC, phi, s, Nv, w, half, close, velocity, inv, need_kin, PART, c):
    """Chunk ``c`` of nodes, component by component: ``w = Lattice.force`` from the edge terms —
    ``F_i = out_i − in_{i−1}`` over the weight, damping, body-frame force, field, end loads,
    constraints —; then, when ``close``, ``S += half·W``, constraints, the velocity
    (``velocity``) and the partial sums of the powers, ΣS and (``need_kin``) Σw S²/m.
    The partial sums go to ``PART[c]`` (with ``close``)."""
    wts = P[I_W]
    winv = P[I_WINV]
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    constrained = P[I_CONSTRAINED]
    has_damp = P[I_HAS_DAMP]
    damp = P[I_DAMP]
    has_ubody = P[I_HAS_UBODY]
    ubody = P[I_UBODY]
    has_field = P[I_HAS_FIELD]
    has_power = P[I_HAS_POWER]
    end_idx = P[I_END_IDX]
    end_div = P[I_END_DIV]
    end_chunk = P[I_END_CHUNK]
    n = w.shape[1]
    ne = OUT.shape[1]
    ring = ne == n
    f0, f1, f2 = P[I_FIELD][0], P[I_FIELD][1], P[I_FIELD][2]
    plain = not (has_damp or has_ubody or has_field or constrained)
    lo, hi = _chunk(c, n)
    a = max(lo, 1)
    b = min(hi, n - 1)
    pd = 0.0
    pe = 0.0
    tot = 0.0
    # a free chunk (no loads, end loads or constraints): the force and the kick in one loop
    free = close and plain and end_chunk[c] == end_chunk[c + 1]
    for k in range(6):
        if free:
            t = 0.0
            for i0 in range(b - a):
                i = a + i0
                v = (OUT[k, i] - INC[k, i - 1]) * winv[i]
                w[k, i] = v
                x = s[k, i] + half * v
                s[k, i] = x
                t += x
            if lo == 0:
                v = ((OUT[k, 0] - INC[k, ne - 1]) if ring else OUT[k, 0]) * winv[0]
                w[k, 0] = v
                s[k, 0] = s[k, 0] + half * v
                t += s[k, 0]
            if hi == n:
                v = ((OUT[k, n - 1] - INC[k, n - 2]) if ring else -INC[k, n - 2]) * winv[n - 1]
                w[k, n - 1] = v
                s[k, n - 1] = s[k, n - 1] + half * v
                t += s[k, n - 1]
            tot += t
            continue
        # node i: tail of edge i, head of edge i − 1 (F_i = out_i − inc_{i−1}), over w_i
        for i0 in range(b - a):
            i = a + i0
            w[k, i] = (OUT[k, i] - INC[k, i - 1]) * winv[i]
        if lo == 0:
            w[k, 0] = ((OUT[k, 0] - INC[k, ne - 1]) if ring else OUT[k, 0]) * winv[0]
        if hi == n:
            w[k, n - 1] = ((OUT[k, n - 1] - INC[k, n - 2]) if ring else -INC[k, n - 2]) * winv[n - 1]
        if has_damp:
            ck = damp[k]
            for i0 in range(hi - lo):
                w[k, lo + i0] += -Nv[k, lo + i0] * ck
        if has_ubody:
            uk = ubody[k]
            for i0 in range(hi - lo):
                w[k, lo + i0] += uk
        if has_field and k < 3:
            for i0 in range(hi - lo):
                i = lo + i0
                w[k, i] += phi[3 + k, i] * f0 + phi[6 + k, i] * f1 + phi[9 + k, i] * f2
        for q in range(end_chunk[c], end_chunk[c + 1]):
            w[k, end_idx[q]] += _soa_end_load(P, phi, q)[k] / end_div[q]
        if constrained:
            for i0 in range(hi - lo):
                i = lo + i0
                if clamped[i] or not live[k]:
                    w[k, i] = 0.0
        if not close:
            continue
        t = 0.0
        if has_damp and live[k]:
            # lie-verlet's closing kick, implicit in the damping (trapezoidal):
            # (1 + ½Δt c/m) S⁺ = S½ + ½Δt W(N = 0), W(N = 0) = W + cN
            ck = damp[k]
            m = mass[k]
            den = 1.0 + half * ck / m
            for i0 in range(hi - lo):
                i = lo + i0
                w0 = w[k, i] + Nv[k, i] * ck
                v = (s[k, i] + half * w0) / den
                if constrained and clamped[i]:
                    v = 0.0
                s[k, i] = v
                w[k, i] = w0 - ck * (v / m)
                t += v
        else:
            for i0 in range(hi - lo):
                i = lo + i0
                v = s[k, i] + half * w[k, i]
                if constrained and (clamped[i] or not live[k]):
                    v = 0.0
                s[k, i] = v
                t += v
        tot += t
        if velocity:
            m = mass[k]
            for i0 in range(hi - lo):
                i = lo + i0
                Nv[k, i] = 0.0 if (constrained and clamped[i]) or not live[k] else s[k, i] / m
        if has_power:
            td, te = _soa_body_powers(wts, damp, ubody, has_damp, has_ubody, Nv, k, lo, hi)
            pd += td
            pe += te
    if close:
        if has_power:
            pe = _soa_end_powers(P, phi, Nv, c, pe)
        kin = 0.0
        if need_kin:
            for i0 in range(hi - lo):
                i = lo + i0
                t = 0.0
                for k in range(6):
                    t += s[k, i] * s[k, i] * inv[k]
                kin += wts[i] * t
        PART[c, 0] = pd
        PART[c, 1] = pe
        PART[c, 2] = tot
        PART[c, 3] = kin


@_jit
def _soa_step(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, g, OUT, INC, inv, need_kin, PART, nblocks,
              scratch):
    """One ``lie-verlet`` step after its force is known: :func:`_drift_chunk`, :func:`_edges_chunk`
    (conjugation) and :func:`_close_chunk` on every chunk, pipelined so that a chunk's data is
    used by the three while it is in the cache.

    The chunks of nodes form ``nblocks`` contiguous blocks (one per thread).  Edge chunk ``c``
    needs the drifted nodes of chunk ``c`` and the first node of chunk ``c + 1``; node chunk
    ``c`` closes with edge chunks ``c − 1`` and ``c``.  So a block drifts its chunk ``c``, then
    takes the edges of chunk ``c − 1`` and closes chunk ``c − 1`` (not the block's first);
    the edges of each block's last chunk and the closing of its first and last chunks follow
    once every block has drifted.  Every chunk does the arithmetic of the unpipelined passes
    (:func:`_soa_drift_nodes`, :func:`_soa_edges`, :func:`_soa_close`) with the same partial
    sums, so the results are bitwise those of the passes and independent of ``nblocks``.
    Returns ``(dissipated, external, ΣS, Σw S²/m)`` at the end of the step."""
    nch = (s.shape[1] + CHUNK - 1) // CHUNK
    nche = (g.shape[1] + CHUNK - 1) // CHUNK
    for b in prange(nblocks):
        c0, c1 = _blocks(b, nblocks, nch)
        XI, QS, bad = scratch[0][b], scratch[1][b], scratch[2][b]
        for c in range(c0, c1):
            _drift_chunk(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, c)
            if c > c0:
                _edges_chunk(P, g, D, True, OUT, INC, c - 1, XI, QS, bad)
                if c - 1 > c0:
                    _close_chunk(P, OUT, INC, phi, s, Nv, w, half, True, velocity, inv, need_kin, PART, c - 1)
    for b in prange(nblocks):
        c0, c1 = _blocks(b, nblocks, nch)
        if c0 < c1 and c1 - 1 < nche:
            _edges_chunk(P, g, D, True, OUT, INC, c1 - 1, scratch[0][b], scratch[1][b], scratch[2][b])
    for b in prange(nblocks):
        c0, c1 = _blocks(b, nblocks, nch)
        if c0 < c1:
            _close_chunk(P, OUT, INC, phi, s, Nv, w, half, True, velocity, inv, need_kin, PART, c0)
            if c1 - 1 > c0:
                _close_chunk(P, OUT, INC, phi, s, Nv, w, half, True, velocity, inv, need_kin, PART, c1 - 1)
    return _sum_parts(PART, nch)


@_inline
def _block_drift(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, prog, c, T):
    """The nodes of chunk ``c`` in its next step, when they may go: closed through the step
    before (``prog`` rows: steps drifted, edged, closed).  Returns True when done."""
    j = prog[0, c]
    if j >= T or prog[2, c] != j:
        return False
    _drift_chunk(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, c)
    prog[0, c] = j + 1
    return True


@_inline
def _block_edges(P, g, D, OUT, INC, prog, c, hi, nch, XI, QS, bad):
    """The edges of chunk ``c`` in its next step, when its nodes and the first node of chunk
    ``c + 1`` have drifted in that step (and not beyond); a chunk ``c + 1 ≥ hi`` (another
    thread's) counts as not ready.  Returns True when done."""
    j = prog[1, c]
    if prog[0, c] != j + 1:
        return False
    if c + 1 < nch and (c + 1 >= hi or prog[0, c + 1] != j + 1):
        return False
    _edges_chunk(P, g, D, True, OUT, INC, c, XI, QS, bad)
    prog[1, c] = j + 1
    return True


@_inline
def _block_close(P, OUT, INC, phi, s, Nv, w, half, velocity, inv, need_kin, PARTT, prog, c, lo, nche):
    """The closing of chunk ``c`` in its step, when its edges (if it has some) and those of
    chunk ``c − 1`` are done in that step; a chunk ``c − 1 < lo`` (another thread's) counts as
    not ready.  Returns True when done."""
    j = prog[2, c]
    if prog[0, c] != j + 1 or (c < nche and prog[1, c] != j + 1):
        return False
    if c >= 1 and (c - 1 < lo or prog[1, c - 1] != j + 1):
        return False
    _close_chunk(P, OUT, INC, phi, s, Nv, w, half, True, velocity, inv, need_kin, PARTT[j], c)
    prog[2, c] = j + 1
    return True


@_jit
def _soa_steps_blocked(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, g, OUT, INC, inv, need_kin, PARTT, T,
                       prog, nblocks, scratch):
    """``T`` ``lie-verlet`` steps of an open rod (the force of the current state known), the
    partial sums of step ``j`` into ``PARTT[j]``.

    The pipeline of :func:`_soa_step` (at position ``p``: the nodes of chunk ``p``, the edges
    and the closing of chunk ``p − 1``) run for the ``T`` steps at once, step ``j`` one
    position behind step ``j − 1``: the closing of chunk ``p`` in step ``j − 1`` (position
    ``p + 1``) comes just before the nodes of chunk ``p`` in step ``j`` (position ``p``), in
    the same sweep, which keeps ``T + 1`` chunks in the cache instead of streaming the whole
    rod ``T`` times.  ``prog [3, chunks]`` counts each chunk's steps (nodes, edges,
    closing), and a piece of work goes only when what it reads is at its step and what it
    overwrites has been read — the nodes of chunk ``c`` in step ``j`` after its closing in
    step ``j − 1``, its edges after the nodes of chunks ``c`` and ``c + 1``, its closing after
    the edges of chunks ``c − 1`` and ``c``.  With ``nblocks`` blocks of chunks (one per
    thread), a block sweeps its own chunks; the work that needs a neighbour block's chunks
    (a cone of up to ``T`` chunks on either side of each boundary between blocks) is done
    afterwards, serially, in as many sweeps as it takes.  Every chunk does the arithmetic of
    the one-step pipeline, so the states and the sums are bitwise those of ``T`` calls of
    :func:`_soa_step`, whatever ``nblocks``.  (A ring cannot: its first chunk closes with
    its last one.)"""
    nch = (s.shape[1] + CHUNK - 1) // CHUNK
    nche = (g.shape[1] + CHUNK - 1) // CHUNK
    prog[:] = 0
    for b in prange(nblocks):
        c0, c1 = _blocks(b, nblocks, nch)
        XI, QS, bad = scratch[0][b], scratch[1][b], scratch[2][b]
        for c in range(c0, c1 + T + 1):
            for j in range(T):
                p = c - j
                if c0 <= p < c1 and prog[0, p] == j:
                    _block_drift(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, prog, p, T)
                q = p - 1
                if c0 <= q < c1:
                    if q < nche and prog[1, q] == j:
                        _block_edges(P, g, D, OUT, INC, prog, q, c1, nch, XI, QS, bad)
                    if prog[2, q] == j:
                        _block_close(P, OUT, INC, phi, s, Nv, w, half, velocity, inv, need_kin, PARTT, prog, q, c0,
                                     nche)
    # what waited for a neighbour block: serial sweeps over the whole rod until every chunk
    # has closed its T steps
    XI, QS, bad = scratch[0][0], scratch[1][0], scratch[2][0]
    left = 0
    for c in range(nch):
        left += T - prog[2, c]
    while left > 0:
        moved = False
        for c in range(nch):
            if c < nche and prog[1, c] < prog[0, c]:
                moved |= _block_edges(P, g, D, OUT, INC, prog, c, nch, nch, XI, QS, bad)
            if c >= 1 and prog[2, c - 1] < prog[0, c - 1]:
                if _block_close(P, OUT, INC, phi, s, Nv, w, half, velocity, inv, need_kin, PARTT, prog, c - 1, 0,
                                nche):
                    moved = True
                    left -= 1
            if _block_drift(P, s, w, half, D, phi, fac, kinds, axes, velocity, Nv, prog, c, T):
                moved = True
        c = nch - 1
        if prog[2, c] < prog[0, c] and _block_close(P, OUT, INC, phi, s, Nv, w, half, velocity, inv, need_kin,
                                                    PARTT, prog, c, 0, nche):
            moved = True
            left -= 1
        if not moved:
            raise RuntimeError("blocked lie-verlet steps: no piece of work can go (a dependency cycle)")


@_jit
def _copy_rows(src, dst):
    """``dst[...] = src`` for 2-D arrays of the same shape."""
    for k in range(src.shape[0]):
        for i in range(src.shape[1]):
            dst[k, i] = src[k, i]


@_jit
def _soa_powers(P, Nv, phi, PART):
    """(dissipated, external) power at velocity ``Nv`` (``Scheme.powers``), by chunks."""
    if not P[I_HAS_POWER]:
        return 0.0, 0.0
    wts = P[I_W]
    damp = P[I_DAMP]
    ubody = P[I_UBODY]
    end_idx = P[I_END_IDX]
    end_face = P[I_END_FACE]
    end_chunk = P[I_END_CHUNK]
    n = Nv.shape[1]
    nch = (n + CHUNK - 1) // CHUNK
    for c in range(nch):
        pd = 0.0
        pe = 0.0
        for i in range(*_chunk(c, n)):
            if P[I_HAS_DAMP]:
                t = 0.0
                for k in range(6):
                    t += (-Nv[k, i] * damp[k]) * Nv[k, i]
                pd += wts[i] * t
            if P[I_HAS_UBODY]:
                t = 0.0
                for k in range(6):
                    t += ubody[k] * Nv[k, i]
                pe += wts[i] * t
        for q in range(end_chunk[c], end_chunk[c + 1]):
            v = _soa_end_load(P, phi, q)
            t = 0.0
            for k in range(6):
                t += v[k] * Nv[k, end_idx[q]]
            pe += end_face[q] * t
        PART[c, 0] = pd
        PART[c, 1] = pe
    total = _sum_parts(PART, nch)
    return total[0], total[1]


def workspace(n: int, ne: int, nf: int, nblocks: int) -> tuple:
    """Work arrays of the structure-of-arrays loops for ``n`` nodes, ``ne`` edges and ``nf``
    frames, in the order the loops unpack them: ``(s [6, n], w [6, n], g [12, ne],
    phi [12, nf], D [12, n], N [6, n], OUT [6, ne], INC [6, ne], (XI [nblocks, 7, CHUNK],
    QS [nblocks, 6, CHUNK], bad [nblocks, CHUNK]), PART [chunks, 4], PARTT [TIME_BLOCK,
    chunks, 4], snapshot (s, w, g, phi, N), prog [3, chunks])`` — the snapshot of the state
    that a block of steps starts from (:func:`lie_verlet_se3_loop`) is empty unless the rod
    is open; ``prog`` counts the steps of each chunk in a block of steps.

    The float arrays are views of one numpy buffer (rows aligned to 64 bytes), which numpy
    backs with transparent huge pages where the kernel offers them (``madvise``, buffers of
    4 MiB and more; fewer address translations for the forty-odd rows a chunk streams).  A
    scheme keeps its workspace between calls (``_soa_workspace`` in
    :mod:`cartan.schemes._lattice_compiled`), so that a run touches its pages once.
    """
    nch = (n + CHUNK - 1) // CHUNK
    snap = ne < n  # an open rod steps in blocks of steps (snapshots)
    m, me, mf = (n, ne, nf) if snap else (0, 0, 0)
    shapes = [(6, n), (6, n), (12, ne), (12, nf), (12, n), (6, n), (6, ne), (6, ne),
              (nblocks, 7, CHUNK), (nblocks, 6, CHUNK), (nch, 4), (TIME_BLOCK, nch, 4),
              (6, m), (6, m), (12, me), (12, mf), (6, m)]
    sizes = [-(-int(np.prod(sh)) // 8) * 8 for sh in shapes]
    buf = np.zeros(sum(sizes))
    views = []
    at = 0
    for sh, size in zip(shapes, sizes, strict=True):
        views.append(buf[at:at + int(np.prod(sh))].reshape(sh))
        at += size
    s, w, g, phi, D, N, OUT, INC, XI, QS, PART, PARTT = views[:12]
    return (s, w, g, phi, D, N, OUT, INC, (XI, QS, np.zeros((nblocks, CHUNK), dtype=np.int64)), PART, PARTT,
            tuple(views[12:]), np.zeros((3, nch), dtype=np.int64))


@_jit
def _to_soa(A, a):
    """``a[:, i]`` ← rows 1–3 of ``A[i]`` = (translation; rotation row-major)."""
    for i in range(A.shape[0]):
        for r in range(3):
            a[r, i] = A[i, r + 1, 0]
            for c in range(3):
                a[3 + 3 * r + c, i] = A[i, r + 1, c + 1]


@_jit
def _from_soa(a, A):
    for i in range(A.shape[0]):
        for r in range(3):
            A[i, r + 1, 0] = a[r, i]
            for c in range(3):
                A[i, r + 1, c + 1] = a[3 + 3 * r + c, i]


@_jit
def lie_verlet_se3_loop(P, S, G, Phi, W, have_force, velocity_free, fac, kinds, axes,
                        t, dt, nsteps, dissipated, external, check, kinetic_limit, inv, block_chunks, work, nblocks):
    """``nsteps`` steps of ``LieVerlet`` on an SE(3) rod (d = 1) with closed-form free-flow
    pieces, on structure-of-arrays copies of ``S [n, 6]``, ``G [ne, 4, 4]``, ``Phi`` and
    ``W`` (copied back on return); open rods in blocks of :data:`TIME_BLOCK` steps
    (:func:`_soa_steps_blocked`) when the force is velocity-free and the rod has two chunks
    or more (one block of chunks) or ``block_chunks`` per block (:data:`THREAD_BLOCK_CHUNKS`).
    ``work``: :func:`workspace`.  ``have_force``: ``W`` holds the force of the state (the
    first-same-as-last force); ``fac [k, 6]``: ``τ/m`` per free-flow piece and component;
    ``kinds``, ``axes [k]``: each piece's kind and body axis; ``t``, ``dt``, the energy
    accumulators, the blow-up test ``check`` with ``kinetic_limit`` and ``inv`` (1/m on the
    live components).  Returns ``(steps done, force evaluations, t, dissipated, external)``."""
    n = S.shape[0]
    s, w, g, phi, D, Nv, OUT, INC, scratch, PART, PARTT, snap, prog = work
    Nv[:] = 0.0
    for i in range(n):
        for k in range(6):
            s[k, i] = S[i, k]
            w[k, i] = W[i, k]
    _to_soa(G, g)
    _to_soa(Phi, phi)
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    need_kin = kinetic_limit < np.inf
    nforce = 0
    half = 0.5 * dt
    nch = (n + CHUNK - 1) // CHUNK
    # blocks of steps: an open rod, a force that the step's closing kick leaves for the next
    # (velocity-free), two chunks or more (serial) or block_chunks per thread (the work
    # around the boundaries between threads, ≈ TIME_BLOCK² chunk-steps each, runs serially)
    blocked = velocity_free and G.shape[0] < n and snap[0].shape[1] == n and (
        nch >= 2 if nblocks == 1 else nch >= block_chunks * nblocks)
    if need_N:
        _soa_velocity(P[I_MASS], P[I_LIVE], P[I_CLAMPED], P[I_CONSTRAINED], s, Nv, 0, n)
    p0d, p0e = _soa_powers(P, Nv, phi, PART)
    done = 0
    while done < nsteps:
        if not (have_force and velocity_free):
            _soa_edges(P, g, D, False, OUT, INC, nblocks, scratch)
            _soa_close(P, OUT, INC, phi, s, Nv, w, half, False, False, inv, False, PART)
            nforce += 1
            have_force = True
        T = min(TIME_BLOCK, nsteps - done) if blocked else 1
        if T > 1:
            for a, b in ((s, snap[0]), (w, snap[1]), (g, snap[2]), (phi, snap[3]), (Nv, snap[4])):
                _copy_rows(a, b)
            _soa_steps_blocked(P, s, w, half, D, phi, fac, kinds, axes, need_N, Nv, g, OUT, INC, inv, need_kin,
                               PARTT, T, prog, nblocks, scratch)
        failed = False
        for j in range(T):
            if T > 1:
                p1d, p1e, tot, kin = _sum_parts(PARTT[j], nch)
            else:
                p1d, p1e, tot, kin = _soa_step(P, s, w, half, D, phi, fac, kinds, axes, need_N, Nv, g, OUT, INC,
                                               inv, need_kin, PART, nblocks, scratch)
            nforce += 1
            t = t + dt
            dissipated = dissipated + 0.5 * dt * (p0d + p1d)
            external = external + 0.5 * dt * (p0e + p1e)
            p0d, p0e = p1d, p1e
            done += 1
            if check == CHECK_MOMENTUM and (
                    not np.isfinite(tot) or (kinetic_limit < np.inf and not 0.5 * kin <= kinetic_limit)):
                failed = True
                if T > 1 and j < T - 1:
                    # the block went on past the failing step: back to its start, then its first j + 1 steps
                    for a, b in ((snap[0], s), (snap[1], w), (snap[2], g), (snap[3], phi), (snap[4], Nv)):
                        _copy_rows(a, b)
                    for _ in range(j + 1):
                        _soa_step(P, s, w, half, D, phi, fac, kinds, axes, need_N, Nv, g, OUT, INC, inv, need_kin,
                                  PART, nblocks, scratch)
                break
        if failed:
            break
    for i in range(n):
        for k in range(6):
            S[i, k] = s[k, i]
            W[i, k] = w[k, i]
    _from_soa(g, G)
    _from_soa(phi, Phi)
    return done, nforce, t, dissipated, external


@_jit
def overdamped_se3_loop(P, S, G, Phi, N, gam, t, dt, nsteps, dissipated, external, check, inv, work, nblocks):
    """``nsteps`` steps of ``Overdamped(order=1)`` on an SE(3) rod (d = 1), on
    structure-of-arrays copies of ``G [ne, 4, 4]``, ``Phi`` and ``N [n, 6]`` (copied back on
    return; S = 0 after a step): ``D_i = exp(ΔtN_i)``, ``Φ_i ← Φ_i D_i``, ``G_e ← D_i⁻¹G_eD_j``,
    then ``N = Γ⁻¹W(N = 0)`` with the force of :func:`_soa_close` (damping at zero velocity).
    ``N`` holds the velocity of the current state on entry (:func:`overdamped_velocity`);
    ``gam`` the drag per component, the blow-up test ``check`` (no kinetic limit: S = 0).
    Returns ``(steps done, t, dissipated, external)``."""
    n = S.shape[0]
    nv, w, g, phi, D, zero, OUT, INC, scratch, PART = work[:10]
    zero[:] = 0.0
    for i in range(n):
        for k in range(6):
            nv[k, i] = N[i, k]
    _to_soa(G, g)
    _to_soa(Phi, phi)
    p0d, p0e = _soa_powers(P, nv, phi, PART)
    done = 0
    for _ in range(nsteps):
        _soa_exp_nodes(nv, dt, D, phi)
        _soa_edges(P, g, D, True, OUT, INC, nblocks, scratch)
        # W at N = 0: the damping term reads the zero velocity
        _soa_close(P, OUT, INC, phi, zero, zero, w, 0.0, False, False, inv, False, PART)
        p1d, p1e = _soa_drag(P, w, gam, nv, phi, PART)
        t = t + dt
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if check == CHECK_CONFIGURATION and _soa_finite(g, phi, PART):
            break
    if done:
        S[:] = 0.0
    for i in range(n):
        for k in range(6):
            N[i, k] = nv[k, i]
    _from_soa(g, G)
    _from_soa(phi, Phi)
    return done, t, dissipated, external


@_jit
def force_at(P, G, Phi, N, V, tau, W, inv, work):
    """``W [n, 6]`` ← ``Lattice.force`` at the velocity ``N [n, 6]`` of the rod ``G [ne, 4, 4]``,
    ``Phi [nf, 4, 4]`` drifted by ``Φ ← Φ exp(τV)`` (``V [n, 6]``; τ = 0: the rod as it is),
    with the passes of the loops on the work arrays ``work`` (:func:`workspace`, one block);
    ``G`` and ``Phi`` are read only.  The CFL probe and the tests call it."""
    n = W.shape[0]
    s, w, g, phi, D, nv, OUT, INC, scratch, PART = work[:10]
    _to_soa(G, g)
    _to_soa(Phi, phi)
    for i in range(n):
        for k in range(6):
            nv[k, i] = N[i, k]
    drift = tau != 0.0
    if drift:
        for i in range(n):
            for k in range(6):
                s[k, i] = V[i, k]
        _soa_exp_nodes(s, tau, D, phi)
    _soa_edges(P, g, D, drift, OUT, INC, 1, scratch)
    _soa_close(P, OUT, INC, phi, nv, nv, w, 0.0, False, False, inv, False, PART)
    for i in range(n):
        for k in range(6):
            W[i, k] = w[k, i]


@_jit
def overdamped_velocity(P, G, Phi, N, gam, inv, work):
    """``N [n, 6]`` ← the overdamped velocity ``Γ⁻¹W(N = 0)`` of the rod ``G``, ``Phi`` (zero on
    clamped nodes and gauge components), computed as :func:`overdamped_se3_loop` computes it
    after every step, so that the steps do not depend on how they are grouped into calls."""
    n = N.shape[0]
    s, w, g, phi, D, zero, OUT, INC, scratch, PART = work[:10]
    zero[:] = 0.0
    _to_soa(G, g)
    _to_soa(Phi, phi)
    _soa_edges(P, g, D, False, OUT, INC, 1, scratch)
    _soa_close(P, OUT, INC, phi, zero, zero, w, 0.0, False, False, inv, False, PART)
    _soa_drag(P, w, gam, s, phi, PART)
    for i in range(n):
        for k in range(6):
            N[i, k] = s[k, i]


#: the threaded variants (``prange`` in parallel) of the passes and of the loops
THREADED = threaded_twins(globals(), ("_soa_edges", "_soa_close", "_soa_step", "_soa_steps_blocked", "_soa_exp_nodes",
                                      "_soa_drag", "_soa_finite", "lie_verlet_se3_loop", "overdamped_se3_loop"))
