"""Compiled step loops of the ``collocation`` scheme: d = 1 here, d = 2, 3 built on it (ARCHITECTURE.md §7).

The steps between two saves run here, in numba, instead of a Python loop of numpy calls;
:meth:`cartan.schemes.collocation.Collocation.compiled_advance` is the entry point and
``docs/schemes.md`` and ``docs/performance.md`` say what qualifies.  :func:`build_plan`
serves every d; the loops of d = 2 and 3 are in :mod:`cartan.schemes._collocation_compiled_nd`
(:func:`advance` hands them over), built from this module's per-node pieces — the force's
stress, ``ad*`` and load terms (:func:`_stress_of`, :func:`_coadjoint`, :func:`_load_terms`),
the drift's node passes (:func:`_se3_nodes`, :func:`_so3_nodes`, :func:`_drift_nodes`,
:func:`_naive_strains`, :func:`_naive_frames`) — applied axis by axis.  (The d = 1 loops are
not the d-general ones: with an axis loop inside the per-node drift and the derivative data
of every axis in ``Dc``, the d = 1 scalar ``lie-verlet`` measured 5–10 % slower.)  The loops
perform the operations of ``Integrator.step`` with ``Collocation.force``/``drift`` and the
base scheme's ``velocity``/``constrain``/``powers`` in the same order, so that the two paths
agree to round-off.

Design
------
* **Shared with the lattice loops.**  The group is the integer switch ``gid`` over the
  per-point kernels of :mod:`cartan.groups` (SO(2), SE(2), SO(3), SE(3)) in
  :mod:`cartan.schemes._lattice_compiled_kernels`, and the problem travels as the d = 1 part
  of the lattice's plan tuple ``P`` (layout ``I_*``: group, quadratic energy ``(X₀, C)``,
  node weights, inertia, clamps, damping, body-frame force, constant field, loaded ends), so
  that the lattice's serial velocity, constraint, kick, end-load, power and blow-up helpers
  of :mod:`cartan.schemes._lattice_compiled` serve both schemes.
* **The difference operator as data** (tuple ``Dc``, layout ``J_*``).  The central stencil
  of :meth:`~cartan.schemes.collocation.DerivativeOperator.rows` is written out on the nodes
  it reaches without wrapping, the other rows (wrapped stencils of periodic axes, the SBP
  closures of open axes) are CSR rows, with the coefficients and summation order of the
  numpy path.  The Fourier derivative, whose FFT numba does not provide, is applied as the
  circulant it is, ``(Du)_i = Σ_m d_m u_{i+m}`` with ``d`` the first row of
  :meth:`~cartan.schemes.collocation.DerivativeOperator.matrix`: O(n²) per derivative, so
  it qualifies only up to :data:`FOURIER_MAX_NODES` nodes.  The free ends (natural boundary
  condition by the penalty ``(P − n·Q)/H_end``) travel in ``Dc`` too.
* **Fused per-node kernels.**  A drift (paper §V, Eq. (X LGI)) is one derivative pass
  ``∂N`` and one pass over the nodes that forms ``exp(τN)`` and applies
  ``X ← Ad_{exp(−τN)}X + 𝓔(τ, −N)∂N``, ``Φ ← Φ exp(τN)`` and the momentum update of the
  integrator (``Ad*_{exp τN}S`` for the split free flow of ``lie-verlet``,
  ``Ad*_{exp ΔtN}S + 𝓔*(Δt, N)W`` for ``lie-euler``).  On SE(3) the node pass is scalar
  code: with ``exp(τN) = (t; R)``, ``Ad_{exp(−τN)}(x; y) = (Rᵀ(x − t × y); Rᵀy)``,
  ``𝓔(τ, −N) = τ[[J, Q], [0, J]]`` and ``𝓔(τ, N)ᵀ = τ[[J, 0], [Q, J]]`` with the same
  ``J = J(−τω)`` and Barfoot–Furgale block ``Q = Q(−τv, −τω)`` (``J(w)ᵀ = J(−w)``,
  ``Q(r, p)ᵀ = Q(−r, −p)``), and the force ``∂Q − ad_XᵀQ = (∂F + ω × F; ∂M + v × F + ω × M)``
  for ``X = (v; ω)``, ``Q = (F; M)``, without 6 × 6 matrices; the free-flow pieces of
  ``lie-verlet`` (the translations, single body rotations) use their reduced forms.  On SO(3)
  likewise: ``R = exp(w)``, ``w = τN``, ``X ← RᵀX + τJ(−w)∂N``, ``S ← RᵀS (+ τJ(−w)W)``,
  ``Φ ← ΦR``.  SO(2) and SE(2) use the matrix kernels (:func:`_drift_nodes`).
* **Vectorised SE(3) loops.**  ``lie-euler``, ``lie-verlet``, ``rkmk4`` and ``overdamped``
  (orders 1 and 2) on SE(3) work on structure-of-arrays copies of the state (one row per
  component, one column per node), made once per call; every pass over the nodes is a loop
  that LLVM vectorises: one written array per loop, the SO(3)/SE(3) coefficients from their
  Taylor series, and the nodes turning by 0.1 rad or more in one drift (or with a stage
  increment σ of 0.1 rad or more, for the ``dexp⁻¹`` of the RKMK stages) recomputed
  afterwards with the closed forms.  The RKMK stages are the same passes: the increments
  ``σ_i`` and ``S_i``, a drift of stage copies of the strains and frames, the velocity, the
  slope ``dexp⁻¹_{−σ_i}N_i`` in closed form (``(J⁻¹(a − QJ⁻¹b); J⁻¹b)``), the force and the
  momentum slope ``ad_NᵀS + W = (F × ω; F × v + M × ω) + W``.  ``forward-euler`` and the other
  groups run scalar loops on the state arrays.
* **No per-step allocation.**  Work arrays are allocated once per call; ``S [n, r]``, the
  strains ``X [n, r]`` (a view of the state's ``[n, 1, r]``) and the frames ``Phi [n, m, m]``
  (or the root frame as ``[1, m, m]``) are updated in place (or copied back on return).
* **Per-step blow-up test** as in the lattice loops: finite momentum and the kinetic bound
  (or a finite configuration for integrators without momentum), stopping after the first
  failing step.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit, uint64
from numba.extending import register_jitable

from ..groups.se3 import TAYLOR_D, TAYLOR_E, _dexp_coeffs_direct, _exp_coeffs3_direct, _V_apply
from ..groups.so3 import (
    SMALL_THETA2,
    TAYLOR_A,
    TAYLOR_B,
    TAYLOR_C,
    TAYLOR_CINV,
    _cinv_direct,
    _poly_entries,
    cross3,
    horner,
)
from ._lattice_compiled import (
    CHECK_CONFIGURATION,
    CHECK_MOMENTUM,
    GID_SE3,
    GID_SO3,
    I_AFFINE,
    I_C,
    I_CLAMPED,
    I_CONSTRAINED,
    I_DAMP,
    I_DIAG,
    I_END_FOLLOW,
    I_END_IDX,
    I_END_LOAD,
    I_FIELD,
    I_GID,
    I_H,
    I_HAS_DAMP,
    I_HAS_FIELD,
    I_HAS_POWER,
    I_HAS_UBODY,
    I_LIVE,
    I_MASS,
    I_TRACK,
    I_UBODY,
    I_W,
    I_X0,
    _book,
    _constrain,
    _end_load,
    _group_id,
    _kick,
    _powers,
    _same_methods,
    _scratch,
    _unstable,
    _velocity,
    _writable,
    advance_context,
    compiled_kind,
    finish_advance,
    lie_verlet_force,
    rkmk_books,
    rkmk_velocity,
)
from ._lattice_compiled_kernels import (
    _copy_matrix,
    _dexp_slopes,
    _q_block,
    g_Ad,
    g_ad,
    g_compose,
    g_E,
    g_exp,
    g_hat,
    g_inverse,
)
from ._lattice_compiled_plan import _compiled_loads, _quadratic_axes
from ._lattice_compiled_soa import _soa_end_load

__all__ = [
    "FOURIER_MAX_NODES",
    "advance",
    "advance_nd",
    "build_plan",
    "derivative_once",
    "drift_once",
    "force_once",
    "euler_loop",
    "lie_euler_se3_loop",
    "lie_verlet_loop",
    "lie_verlet_se3_loop",
    "overdamped_loop",
    "overdamped_se3_loop",
    "overdamped_velocity",
    "rkmk_loop",
    "rkmk_se3_loop",
    "stiffness_once",
]

#: the Fourier derivative costs O(n²) per application here (a circulant) against O(n log n)
#: for the FFT of the numpy path: above this many nodes the numpy path runs the problem (at
#: 512 nodes the compiled SE(3) loops measured 1× (lie-euler) and 2× (lie-verlet) faster)
FOURIER_MAX_NODES = 512

#: layout of the tuple ``Dc``: the derivative (CSR rows; the central stencil and the nodes
#: ``[lo, hi)`` where it applies without wrapping; the first row of the Fourier matrix, empty
#: for finite differences), then the free ends (node, n_α, H_end, index of the end's load
#: among the plan's loaded ends ``I_END_*`` or −1)
(J_PTR, J_IND, J_DAT, J_OFF, J_COEF, J_LO, J_HI, J_CIRC, J_FREE_IDX, J_FREE_SIGN, J_FREE_H, J_FREE_LOAD) = range(12)

#: momentum update done by the SE(3) node pass together with the drift
MODE_NONE = 0  # drift only
MODE_COAD = 1  # S ← Ad*_{exp τN} S (lie-verlet free-flow piece)
MODE_LIE_EULER = 2  # S ← Ad*_{exp τN} S + 𝓔*(τ, N) W (lie-euler)

#: kinds of SE(3) lie-verlet free-flow pieces: general, the three translations, one body rotation
PIECE_GENERAL = 0
PIECE_TRANSLATION = 1
PIECE_ROTATION = 2

#: every kernel: cached, IEEE division (inf/nan like numpy, and no zero-divisor test, which
#: would keep LLVM from vectorising loops); small helpers inlined in numba's IR, so that no
#: call is left inside the loops LLVM vectorises
_jit = njit(cache=True, error_model="numpy")
_inline = njit(inline="always", error_model="numpy")


# ---------------------------------------------------------------------------- derivative
@_jit
def _deriv(Dc, A, out):
    """``out = D A`` along the nodes, ``A``, ``out`` ``[n, r]``: the central stencil written out
    on the nodes ``[lo, hi)`` it reaches without wrapping, the CSR rows elsewhere, each row
    summed in the order of ``DerivativeOperator.__call__`` (the interior indices unsigned: no
    negative-index wrap-around test); the Fourier derivative as a circulant sum."""
    indptr = Dc[J_PTR]
    indices = Dc[J_IND]
    data = Dc[J_DAT]
    off = Dc[J_OFF]
    coef = Dc[J_COEF]
    lo, hi = Dc[J_LO], Dc[J_HI]
    n, r = A.shape
    d = Dc[J_CIRC]
    if d.shape[0]:
        # the Fourier derivative: circulant, D[i, j] = d[(j − i) mod n]
        for i in range(n):
            for k in range(r):
                out[i, k] = 0.0
        for m in range(n):
            c = d[m]
            for i in range(n - m):
                for k in range(r):
                    out[i, k] += c * A[uint64(i + m), k]
            for i in range(n - m, n):
                for k in range(r):
                    out[i, k] += c * A[uint64(i + m - n), k]
        return
    if off.shape[0] == 2:
        o0, o1 = off[0], off[1]
        c0, c1 = coef[0], coef[1]
        for i in range(lo, hi):
            for k in range(r):
                out[i, k] = c0 * A[uint64(i + o0), k] + c1 * A[uint64(i + o1), k]
    elif off.shape[0] == 4:
        o0, o1, o2, o3 = off[0], off[1], off[2], off[3]
        c0, c1, c2, c3 = coef[0], coef[1], coef[2], coef[3]
        for i in range(lo, hi):
            for k in range(r):
                out[i, k] = (c0 * A[uint64(i + o0), k] + c1 * A[uint64(i + o1), k] + c2 * A[uint64(i + o2), k]
                             + c3 * A[uint64(i + o3), k])
    for b in range(n - (hi - lo)):
        i = b if b < lo else b + hi - lo  # the rows before lo, then from hi on
        for k in range(r):
            out[i, k] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            c = data[p]
            j = indices[p]
            for k in range(r):
                out[i, k] += c * A[j, k]


# ---------------------------------------------------------------------------- forces
# The pieces of the force are inline helpers on a strain given by its columns ``c : c + r`` of
# ``X`` (``c = 0`` here; the axes of ``X [n, d·r]`` in :mod:`._collocation_compiled_nd`).
@_inline
def _stress_of(C, diag, X0, X, c, Q):
    """``Q = C (X_α − X₀_α)`` at every node ``[n, r]`` (``diag``: C is diagonal), the strain in
    the columns ``c : c + r`` of ``X``."""
    n, r = Q.shape
    if diag:
        for i in range(n):
            for k in range(r):
                Q[i, k] = C[k, k] * (X[i, c + k] - X0[k])
        return
    for i in range(n):
        for a in range(r):
            acc = 0.0
            for b in range(r):
                acc += C[a, b] * (X[i, c + b] - X0[b])
            Q[i, a] = acc


@_inline
def _coadjoint(gid, X, c, Q, W, xi, M):
    """``W −= ad_Xᵀ Q`` at every node, the strain in the columns ``c : c + r`` of ``X``; on
    SE(3) ``−ad_XᵀQ = (ω × F; v × F + ω × M)`` for ``X = (v; ω)``, ``Q = (F; M)``, without
    6 × 6 matrices; ``xi`` r-vector and ``M`` r × r work space."""
    n, r = W.shape
    if gid == GID_SE3:
        for i in range(n):
            v0, v1, v2 = X[i, c], X[i, c + 1], X[i, c + 2]
            w0, w1, w2 = X[i, c + 3], X[i, c + 4], X[i, c + 5]
            F0, F1, F2 = Q[i, 0], Q[i, 1], Q[i, 2]
            M0, M1, M2_ = Q[i, 3], Q[i, 4], Q[i, 5]
            a = cross3(w0, w1, w2, F0, F1, F2)
            b = cross3(v0, v1, v2, F0, F1, F2)
            e = cross3(w0, w1, w2, M0, M1, M2_)
            W[i, 0] += a[0]
            W[i, 1] += a[1]
            W[i, 2] += a[2]
            W[i, 3] += b[0] + e[0]
            W[i, 4] += b[1] + e[1]
            W[i, 5] += b[2] + e[2]
        return
    for i in range(n):
        for k in range(r):
            xi[k] = X[i, c + k]
        g_ad(gid, xi, M)
        for a in range(r):
            acc = 0.0
            for b in range(r):
                acc += M[b, a] * Q[i, b]
            W[i, a] -= acc


@_inline
def _load_terms(P, Phi, N, W):
    """``W +=`` the loads of the plan — damping ``−c N``, the body-frame force, the constant
    field ``Rᵀρf`` — then zero at clamped nodes and on gauge components."""
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = W.shape
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        for i in range(n):
            for k in range(r):
                W[i, k] += -N[i, k] * damp[k]
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        for i in range(n):
            for k in range(r):
                W[i, k] += ubody[k]
    if P[I_HAS_FIELD]:
        field = P[I_FIELD]
        ks = field.shape[0]
        for i in range(n):
            for k in range(ks):
                acc = 0.0
                for b in range(ks):
                    acc += Phi[i, b + 1, k + 1] * field[b]
                W[i, k] += acc
    if P[I_CONSTRAINED]:
        for i in range(n):
            for k in range(r):
                if clamped[i] or not live[k]:
                    W[i, k] = 0.0


@_jit
def _force(P, Dc, X, Phi, N, W, Q, scr):
    """``W = Collocation.force(state, N, t)``: ``∂Q − ad_XᵀQ``, the free-end penalties
    ``(P − n·Q)/H_end``, damping, body-frame force, constant field; zero at clamped nodes and
    on gauge components.  ``Q`` ``[n, r]`` is work space (the stress on return)."""
    gid = P[I_GID]
    xi, Qv, tr, M, M2, A1, A2, A3, XI = scr
    n, r = W.shape
    _stress_of(P[I_C], P[I_DIAG], P[I_X0], X, 0, Q)
    _deriv(Dc, Q, W)
    _coadjoint(gid, X, 0, Q, W, xi, M)
    free_idx = Dc[J_FREE_IDX]
    for f in range(free_idx.shape[0]):
        idx = free_idx[f]
        q = Dc[J_FREE_LOAD][f]
        if q >= 0:
            _end_load(gid, P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A1)
        else:
            for a in range(r):
                tr[a] = 0.0
        sign = Dc[J_FREE_SIGN][f]
        H = Dc[J_FREE_H][f]
        for a in range(r):
            W[idx, a] += (tr[a] - sign * Q[idx, a]) / H
    _load_terms(P, Phi, N, W)


# ---------------------------------------------------------------------------- drifts
@register_jitable
def _coeffs(t2):
    """``(A, B, C, D, E)`` of ``se3_exp_coeffs`` and ``se3_dexp_coeffs`` for ``t2 = θ²``: the
    library's Taylor series below θ = 0.1, its closed forms above."""
    if t2 < SMALL_THETA2:
        return _series(t2)
    a, b, c = _exp_coeffs3_direct(t2)
    _, _, d, e = _dexp_coeffs_direct(t2)
    return a, b, c, d, e


@_inline
def _series(t2):
    """The coefficients ``(A, B, C, D, E)`` from their Taylor series (θ < 0.1)."""
    return (horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C), horner(t2, TAYLOR_D),
            horner(t2, TAYLOR_E))


@_inline
def _se3_node(v0, v1, v2, w0, w1, w2, tau, A, B, C, Dq, Eq, x, a, s, f, mode):
    """One SE(3) node of a drift by ``(v; w) = τN`` with the coefficients of ``θ² = |w|²``:
    strains ``x`` → ``Ad_{exp(−τN)}x + 𝓔(τ, −N)a`` (``a = ∂N``), momentum ``s`` →
    ``Ad*_{exp τN}s`` (``mode`` ≥ ``MODE_COAD``) ``+ 𝓔*(τ, N)f`` (``mode = MODE_LIE_EULER``,
    ``f = W``), and ``exp(τN) = (t; R)``; ``x``, ``a``, ``s``, ``f`` 6-tuples.  Returns
    ``(X⁺, S⁺, t, R)``, R row-major."""
    x0, x1, x2, x3, x4, x5 = x
    a0, a1, a2, a3, a4, a5 = a
    s0, s1, s2, s3, s4, s5 = s
    f0, f1, f2, f3, f4, f5 = f
    R = _poly_entries(w0, w1, w2, A, B, 1.0)
    t = _V_apply(w0, w1, w2, B, C, v0, v1, v2)
    # Ad_{exp(−τN)} X = (Rᵀ(x − t × y); Rᵀy), plus τ[[J, Q], [0, J]] ∂N with J = J(−w), Q = Q(−v, −w)
    c = cross3(t[0], t[1], t[2], x3, x4, x5)
    u0, u1, u2 = x0 - c[0], x1 - c[1], x2 - c[2]
    Ja = _V_apply(-w0, -w1, -w2, B, C, a0, a1, a2)
    Jb = _V_apply(-w0, -w1, -w2, B, C, a3, a4, a5)
    Qb = _q_block(-v0, -v1, -v2, -w0, -w1, -w2, C, Dq, Eq, a3, a4, a5)
    X = ((R[0] * u0 + R[3] * u1 + R[6] * u2) + tau * (Ja[0] + Qb[0]),
         (R[1] * u0 + R[4] * u1 + R[7] * u2) + tau * (Ja[1] + Qb[1]),
         (R[2] * u0 + R[5] * u1 + R[8] * u2) + tau * (Ja[2] + Qb[2]),
         (R[0] * x3 + R[3] * x4 + R[6] * x5) + tau * Jb[0],
         (R[1] * x3 + R[4] * x4 + R[7] * x5) + tau * Jb[1],
         (R[2] * x3 + R[5] * x4 + R[8] * x5) + tau * Jb[2])
    if mode == MODE_NONE:
        return X, (s0, s1, s2, s3, s4, s5), t, R
    # Ad_{(t; R)}ᵀ (F; M) = (RᵀF; Rᵀ(M − t × F))
    d = cross3(t[0], t[1], t[2], s0, s1, s2)
    m0, m1, m2 = s3 - d[0], s4 - d[1], s5 - d[2]
    S0 = R[0] * s0 + R[3] * s1 + R[6] * s2
    S1 = R[1] * s0 + R[4] * s1 + R[7] * s2
    S2 = R[2] * s0 + R[5] * s1 + R[8] * s2
    S3 = R[0] * m0 + R[3] * m1 + R[6] * m2
    S4 = R[1] * m0 + R[4] * m1 + R[7] * m2
    S5 = R[2] * m0 + R[5] * m1 + R[8] * m2
    if mode == MODE_LIE_EULER:
        # 𝓔(τ, N)ᵀ (Wf; Wm) = τ (J Wf; Q Wf + J Wm), the same J and Q
        JF = _V_apply(-w0, -w1, -w2, B, C, f0, f1, f2)
        JM = _V_apply(-w0, -w1, -w2, B, C, f3, f4, f5)
        QF = _q_block(-v0, -v1, -v2, -w0, -w1, -w2, C, Dq, Eq, f0, f1, f2)
        S0 += tau * JF[0]
        S1 += tau * JF[1]
        S2 += tau * JF[2]
        S3 += tau * (QF[0] + JM[0])
        S4 += tau * (QF[1] + JM[1])
        S5 += tau * (QF[2] + JM[2])
    return X, (S0, S1, S2, S3, S4, S5), t, R


@_inline
def _se3_node_translation(v0, v1, v2, tau, x, a, s):
    """:func:`_se3_node` with ``mode = MODE_COAD`` for a translation ``τN = (v; 0)`` (a free-flow
    piece of ``lie-verlet``): ``exp = (v; I)``, ``J = I``, ``Q = ½(−v)^``, so ``X⁺ = (x − v × y
    + τ(a + ½(−v) × b); y + τb)`` and ``S⁺ = (F; M − v × F)``; the general formulas at ω = 0,
    term by term.  Returns ``(X⁺, S⁺)``."""
    x0, x1, x2, x3, x4, x5 = x
    a0, a1, a2, a3, a4, a5 = a
    s0, s1, s2, s3, s4, s5 = s
    c = cross3(v0, v1, v2, x3, x4, x5)
    q = cross3(-v0, -v1, -v2, a3, a4, a5)
    d = cross3(v0, v1, v2, s0, s1, s2)
    X = ((x0 - c[0]) + tau * (a0 + 0.5 * q[0]), (x1 - c[1]) + tau * (a1 + 0.5 * q[1]),
         (x2 - c[2]) + tau * (a2 + 0.5 * q[2]), x3 + tau * a3, x4 + tau * a4, x5 + tau * a5)
    return X, (s0, s1, s2, s3 - d[0], s4 - d[1], s5 - d[2])


@_inline
def _se3_node_rotation(w0, w1, w2, tau, A, B, C, x, a, s):
    """:func:`_se3_node` with ``mode = MODE_COAD`` for a rotation ``τN = (0; w)`` (a free-flow
    piece of ``lie-verlet``): ``exp = (0; R)``, ``Q = 0``, so ``X⁺ = (Rᵀx + τJa; Rᵀy + τJb)``
    and ``S⁺ = (RᵀF; RᵀM)`` with ``J = J(−w)``.  Returns ``(X⁺, S⁺)``."""
    x0, x1, x2, x3, x4, x5 = x
    a0, a1, a2, a3, a4, a5 = a
    s0, s1, s2, s3, s4, s5 = s
    R = _poly_entries(w0, w1, w2, A, B, 1.0)
    Ja = _V_apply(-w0, -w1, -w2, B, C, a0, a1, a2)
    Jb = _V_apply(-w0, -w1, -w2, B, C, a3, a4, a5)
    X = ((R[0] * x0 + R[3] * x1 + R[6] * x2) + tau * Ja[0], (R[1] * x0 + R[4] * x1 + R[7] * x2) + tau * Ja[1],
         (R[2] * x0 + R[5] * x1 + R[8] * x2) + tau * Ja[2], (R[0] * x3 + R[3] * x4 + R[6] * x5) + tau * Jb[0],
         (R[1] * x3 + R[4] * x4 + R[7] * x5) + tau * Jb[1], (R[2] * x3 + R[5] * x4 + R[8] * x5) + tau * Jb[2])
    S = (R[0] * s0 + R[3] * s1 + R[6] * s2, R[1] * s0 + R[4] * s1 + R[7] * s2, R[2] * s0 + R[5] * s1 + R[8] * s2,
         R[0] * s3 + R[3] * s4 + R[6] * s5, R[1] * s3 + R[4] * s4 + R[7] * s5, R[2] * s3 + R[5] * s4 + R[8] * s5)
    return X, S


@_jit
def _se3_nodes(X, Phi, S, W, N, DN, tau, mode):
    """SE(3) node pass of a drift by ``τN`` (``DN = ∂N``) on ``[n, r]`` arrays, in place:
    :func:`_se3_node` at every node and ``Φ ← Φ exp(τN)`` on the first ``Phi.shape[0]``."""
    n = X.shape[0]
    nf = Phi.shape[0]
    for i in range(n):
        v0, v1, v2 = tau * N[i, 0], tau * N[i, 1], tau * N[i, 2]
        w0, w1, w2 = tau * N[i, 3], tau * N[i, 4], tau * N[i, 5]
        A, B, C, Dq, Eq = _coeffs(w0 * w0 + w1 * w1 + w2 * w2)
        Xn, Sn, t, R = _se3_node(v0, v1, v2, w0, w1, w2, tau, A, B, C, Dq, Eq,
                                 (X[i, 0], X[i, 1], X[i, 2], X[i, 3], X[i, 4], X[i, 5]),
                                 (DN[i, 0], DN[i, 1], DN[i, 2], DN[i, 3], DN[i, 4], DN[i, 5]),
                                 (S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4], S[i, 5]),
                                 (W[i, 0], W[i, 1], W[i, 2], W[i, 3], W[i, 4], W[i, 5]), mode)
        for k in range(6):
            X[i, k] = Xn[k]
            S[i, k] = Sn[k]
        if i < nf:
            # Φ (t; R) = (P t + p; P R) for Φ = (p; P)
            for a in range(1, 4):
                x0, x1, x2, x3 = Phi[i, a, 0], Phi[i, a, 1], Phi[i, a, 2], Phi[i, a, 3]
                Phi[i, a, 0] = x1 * t[0] + x2 * t[1] + x3 * t[2] + x0
                Phi[i, a, 1] = x1 * R[0] + x2 * R[3] + x3 * R[6]
                Phi[i, a, 2] = x1 * R[1] + x2 * R[4] + x3 * R[7]
                Phi[i, a, 3] = x1 * R[2] + x2 * R[5] + x3 * R[8]


@register_jitable
def _so3_coeffs(t2):
    """``(A, B, C)`` of ``exp`` and ``J`` on SO(3) for ``t2 = θ²``: the library's Taylor
    series below θ = 0.1, its closed forms above."""
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)
    return _exp_coeffs3_direct(t2)


@_jit
def _so3_nodes(X, Phi, S, W, N, DN, tau, mode):
    """SO(3) node pass of a drift by ``τN`` (``DN = ∂N``) on ``[n, 3]`` arrays, in place, in
    closed form (no 3 × 3 matrices of ``Ad`` and ``𝓔``): with ``w = τN_i`` and
    ``R = exp(w) = I + Aŵ + Bŵ²``, ``X ← RᵀX + τJ(−w)DN`` (``Ad_{exp(−w)} = Rᵀ``,
    ``𝓔(τ, −N) = τJ(−w)``, ``J(v)u = u + B v × u + C v × (v × u)``), the momentum ``S ← RᵀS``
    (``mode`` ≥ ``MODE_COAD``) ``+ τJ(−w)W`` (``MODE_LIE_EULER``: ``𝓔(τ, N)ᵀ = τJ(w)ᵀ =
    τJ(−w)``), and ``Φ ← ΦR`` on the first ``Phi.shape[0]`` nodes."""
    n = N.shape[0]
    nf = Phi.shape[0]
    for i in range(n):
        w0, w1, w2 = tau * N[i, 0], tau * N[i, 1], tau * N[i, 2]
        A, B, C = _so3_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
        R = _poly_entries(w0, w1, w2, A, B, 1.0)
        J = _V_apply(-w0, -w1, -w2, B, C, DN[i, 0], DN[i, 1], DN[i, 2])
        x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
        X[i, 0] = (R[0] * x0 + R[3] * x1 + R[6] * x2) + tau * J[0]
        X[i, 1] = (R[1] * x0 + R[4] * x1 + R[7] * x2) + tau * J[1]
        X[i, 2] = (R[2] * x0 + R[5] * x1 + R[8] * x2) + tau * J[2]
        if mode != MODE_NONE:
            s0, s1, s2 = S[i, 0], S[i, 1], S[i, 2]
            u0 = R[0] * s0 + R[3] * s1 + R[6] * s2
            u1 = R[1] * s0 + R[4] * s1 + R[7] * s2
            u2 = R[2] * s0 + R[5] * s1 + R[8] * s2
            if mode == MODE_LIE_EULER:
                F = _V_apply(-w0, -w1, -w2, B, C, W[i, 0], W[i, 1], W[i, 2])
                u0 += tau * F[0]
                u1 += tau * F[1]
                u2 += tau * F[2]
            S[i, 0], S[i, 1], S[i, 2] = u0, u1, u2
        if i < nf:
            for a in range(3):
                p0, p1, p2 = Phi[i, a, 0], Phi[i, a, 1], Phi[i, a, 2]
                Phi[i, a, 0] = p0 * R[0] + p1 * R[3] + p2 * R[6]
                Phi[i, a, 1] = p0 * R[1] + p1 * R[4] + p2 * R[7]
                Phi[i, a, 2] = p0 * R[2] + p1 * R[5] + p2 * R[8]


@_jit
def _drift(P, Dc, X, Phi, S, W, N, tau, DN, D, scr, mode):
    """Exact drift by ``τN`` (``Collocation.drift(exact=True)``) with the momentum update of
    ``mode`` in the same pass over the nodes; ``DN``, ``D`` ``[n, m, m]`` work space."""
    gid = P[I_GID]
    _deriv(Dc, N, DN)
    if gid == GID_SE3:
        _se3_nodes(X, Phi, S, W, N, DN, tau, mode)
        return
    if gid == GID_SO3:
        _so3_nodes(X, Phi, S, W, N, DN, tau, mode)
        return
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    _drift_nodes(gid, X, Phi, S, W, N, DN, tau, D, xi, tr, M, M2, A1, mode)


@_inline
def _drift_nodes(gid, X, Phi, S, W, N, DN, tau, D, xi, tr, M, M2, A1, mode):
    """The node pass of :func:`_drift` for the groups other than SE(3): per node
    ``D_i = exp(τN_i)``, the momentum update of ``mode``, ``X ← Ad_{exp(−τN)}X + 𝓔(τ, −N) DN``
    (``X``, ``DN`` ``[n, r]``), then ``Φ ← Φ exp(τN)`` on the first ``Phi.shape[0]`` nodes;
    ``xi``, ``tr`` r-vectors, ``M``, ``M2`` r × r, ``A1`` m × m work space (the scratch arrays
    one by one: a call pays a reference count for every array it is passed)."""
    n, r = N.shape
    for i in range(n):
        for k in range(r):
            xi[k] = tau * N[i, k]
        g_exp(gid, xi, D[i])
        if mode != MODE_NONE:
            g_Ad(gid, D[i], M)
            if mode == MODE_LIE_EULER:
                g_E(gid, tau, N[i], M2)
            for a in range(r):
                u = 0.0
                for b in range(r):
                    u += M[b, a] * S[i, b]
                if mode == MODE_LIE_EULER:
                    v = 0.0
                    for b in range(r):
                        v += M2[b, a] * W[i, b]
                    u = u + v
                tr[a] = u
            for a in range(r):
                S[i, a] = tr[a]
        g_inverse(gid, D[i], A1)
        g_Ad(gid, A1, M)
        for k in range(r):
            xi[k] = -N[i, k]
        g_E(gid, tau, xi, M2)
        for a in range(r):
            u = 0.0
            v = 0.0
            for b in range(r):
                u += M[a, b] * X[i, b]
                v += M2[a, b] * DN[i, b]
            tr[a] = u + v
        for a in range(r):
            X[i, a] = tr[a]
    for i in range(Phi.shape[0]):
        g_compose(gid, Phi[i], D[i], A1)
        _copy_matrix(A1, Phi[i])


@_jit
def _naive_drift(P, Dc, X, Phi, N, tau, DN, D, scr):
    """``Collocation.drift(exact=False)``: ``X ← X + τ(∂N − ad_N X)``, ``Φ ← Φ + τΦN̂``."""
    gid = P[I_GID]
    _deriv(Dc, N, DN)
    _naive_strains(gid, X, N, DN, tau, scr)
    _naive_frames(gid, Phi, N, tau, scr)


@_jit
def _naive_strains(gid, X, N, DN, tau, scr):
    """``X ← X + τ(DN − ad_N X)`` at every node (``X``, ``DN`` ``[n, r]``)."""
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    n, r = N.shape
    for i in range(n):
        g_ad(gid, N[i], M)
        for a in range(r):
            acc = 0.0
            for b in range(r):
                acc += M[a, b] * X[i, b]
            tr[a] = X[i, a] + tau * (DN[i, a] - acc)
        for a in range(r):
            X[i, a] = tr[a]


@_jit
def _naive_frames(gid, Phi, N, tau, scr):
    """``Φ ← Φ + τΦN̂`` on the first ``Phi.shape[0]`` nodes."""
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    r = N.shape[1]
    m = Phi.shape[1]
    for i in range(Phi.shape[0]):
        for k in range(r):
            xi[k] = tau * N[i, k]
        g_hat(gid, xi, A2)
        for a in range(m):
            for b in range(m):
                acc = 0.0
                for c in range(m):
                    acc += Phi[i, a, c] * A2[c, b]
                A1[a, b] = Phi[i, a, b] + acc
        _copy_matrix(A1, Phi[i])


# ---------------------------------------------------------------------------- scalar loops: shared pieces
@_jit
def _work(n, r, m):
    """Per-call work arrays of the scalar loops: the force ``W``, the stress ``Q`` and the
    derivative ``DN`` ``[n, r]``, the node exponentials ``D [n, m, m]``, the helpers' scratch."""
    return np.empty((n, r)), np.empty((n, r)), np.empty((n, r)), np.empty((n, m, m)), _scratch(r, m, 0)


@_jit
def _end_step(P, S, X, Phi, N, scr, dt, books, check, kinetic_limit, w, inv):
    """The close of a scalar loop's step at its final velocity ``N``: the powers booked by the
    trapezoidal rule (``books = (dissipated, external, p0d, p0e)``, the powers at the step's
    start; returned updated) and the per-step blow-up test (True: stop)."""
    dissipated, external, p0d, p0e = books
    p1d, p1e = _powers(P, N, Phi, scr)
    dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
    return (dissipated, external, p1d, p1e), _unstable(check, kinetic_limit, S, X, Phi, w, inv)


# ---------------------------------------------------------------------------- lie-verlet
@_jit
def lie_verlet_loop(P, Dc, S, X, Phi, W, have_force, velocity_free, seq_mask, seq_frac,
                    t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``LieVerlet``: half kick, the palindromic split free flow (each
    piece an exact drift of the collocation strains with ``S ← Ad*_{exp τN_p}S``), half kick.

    ``W`` holds the force at the current state when ``have_force`` (first-same-as-last) and
    the force at the final state on return.  Returns
    ``(steps done, force evaluations, t, dissipated, external)``.
    """
    n, r = S.shape
    m = Phi.shape[1]
    N = np.zeros((n, r))
    Np = np.zeros((n, r))
    _, Q, DN, D, scr = _work(n, r, m)
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _velocity(P, S, N)
    books = (dissipated, external) + _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        if not (have_force and velocity_free):
            _force(P, Dc, X, Phi, N, W, Q, scr)
            nforce += 1
        _kick(S, W, half)
        _constrain(P, S)
        for p in range(seq_frac.shape[0]):
            _velocity(P, S, Np)
            moving = False
            for i in range(n):
                for k in range(r):
                    if not seq_mask[p, k]:
                        Np[i, k] = 0.0
                    elif Np[i, k] != 0.0:
                        moving = True
            if not moving:  # exp(0) = I: nothing moves
                continue
            _drift(P, Dc, X, Phi, S, W, Np, seq_frac[p] * dt, DN, D, scr, MODE_COAD)
        _constrain(P, S)
        if need_N:
            _velocity(P, S, N)
        _force(P, Dc, X, Phi, N, W, Q, scr)
        nforce += 1
        have_force = True
        _kick(S, W, half)
        _constrain(P, S)
        t = t + dt
        if need_N:
            _velocity(P, S, N)
        books, stop = _end_step(P, S, X, Phi, N, scr, dt, books, check, kinetic_limit, P[I_W], inv)
        done += 1
        if stop:
            break
    return done, nforce, t, books[0], books[1]


# ---------------------------------------------------------------------------- lie-euler, forward-euler
@_jit
def _lie_poisson(gid, N, S, W, out, M):
    """``out = ad_NᵀS + W`` at every node (``Ṡ`` of the momentum balance), ``M`` r × r work space."""
    n, r = S.shape
    for i in range(n):
        g_ad(gid, N[i], M)
        for a in range(r):
            acc = 0.0
            for b in range(r):
                acc += M[b, a] * S[i, b]
            out[i, a] = acc + W[i, a]


@_jit
def euler_loop(P, Dc, S, X, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv, geometric):
    """``nsteps`` steps of ``LieEuler`` (``geometric``, paper §V: ``S⁺ = Ad*_{exp ΔtN}S +
    𝓔*(Δt, N)W``, ``X⁺ = Ad_{exp(−ΔtN)}X + 𝓔(Δt, −N)∂N``, ``Φ⁺ = Φ exp(ΔtN)``) or of
    ``ForwardEuler`` (``X += Δt(∂N − ad_N X)``, ``Φ += ΔtΦN̂``, ``S += Δt(ad_NᵀS + W)``).
    Returns ``(steps done, t, dissipated, external)``."""
    n, r = S.shape
    N = np.empty((n, r))
    Sd = np.empty((n, r))
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1])
    _velocity(P, S, N)
    books = (dissipated, external) + _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _force(P, Dc, X, Phi, N, W, Q, scr)
        if geometric:
            _drift(P, Dc, X, Phi, S, W, N, dt, DN, D, scr, MODE_LIE_EULER)
        else:
            _lie_poisson(P[I_GID], N, S, W, Sd, scr[3])
            _naive_drift(P, Dc, X, Phi, N, dt, DN, D, scr)
            for i in range(n):
                for k in range(r):
                    S[i, k] = S[i, k] + dt * Sd[i, k]
        _constrain(P, S)
        t = t + dt
        _velocity(P, S, N)
        books, stop = _end_step(P, S, X, Phi, N, scr, dt, books, check, kinetic_limit, P[I_W], inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


# ---------------------------------------------------------------------------- overdamped, RKMK
@_jit
def _drift_velocity(P, Dc, X, Phi, Z, W, Q, N, gam, scr):
    """Overdamped velocity ``N = Γ⁻¹W(N = 0)`` (live components; zero at clamped nodes)."""
    _force(P, Dc, X, Phi, Z, W, Q, scr)
    _drag_velocity(P, W, N, gam)


@_inline
def _drag_velocity(P, W, N, gam):
    """``N = Γ⁻¹W`` on the live components, zero on the others and at clamped nodes."""
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = N.shape
    for i in range(n):
        for k in range(r):
            N[i, k] = W[i, k] / gam[k] if live[k] else 0.0
        if clamped[i]:
            for k in range(r):
                N[i, k] = 0.0


@_jit
def overdamped_velocity(P, Dc, X, Phi, N, gam):
    """``N = Γ⁻¹W(N = 0)`` at the current state (the overdamped integrator's velocity)."""
    n, r = N.shape
    _drift_velocity(P, Dc, X, Phi, np.zeros((n, r)), np.empty((n, r)), np.empty((n, r)), N, gam,
                    _scratch(r, Phi.shape[1], 0))


@_jit
def overdamped_loop(P, Dc, S, X, Phi, N, gam, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``Overdamped(order=1)``: a drift by ``ΔtN``, ``N = Γ⁻¹W(N = 0)``.

    ``N`` holds the velocity of the current state on entry and of the final state on return.
    Returns ``(steps done, t, dissipated, external)``.
    """
    n, r = S.shape
    Z = np.zeros((n, r))
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1])
    books = (dissipated, external) + _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _drift(P, Dc, X, Phi, S, W, N, dt, DN, D, scr, MODE_NONE)
        S[:] = 0.0
        t = t + dt
        _drift_velocity(P, Dc, X, Phi, Z, W, Q, N, gam, scr)
        books, stop = _end_step(P, S, X, Phi, N, scr, dt, books, check, kinetic_limit, P[I_W], inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


@_jit
def _increment(k, coef, m, dt, out):
    """``out = Σ_{j < m, coef_j ≠ 0} (Δt coef_j) k[j]`` (``k`` ``[s, ...]``, ``out`` its
    ``[...]``), summed from zero in the order of ``j`` as the reference ``_rkmk`` does; True
    when an entry of the sum is not zero."""
    a = out.reshape(-1)
    a[:] = 0.0
    for j in range(m):
        if coef[j] != 0.0:
            c = dt * coef[j]
            kj = k[j].reshape(-1)
            for i in range(a.shape[0]):
                a[i] = a[i] + c * kj[i]
    nz = 0
    for i in range(a.shape[0]):
        nz += a[i] != 0.0
    return nz > 0


@_jit
def rkmk_loop(P, Dc, S, X, Phi, N, gam, dynamics, A, b, t, dt, nsteps, dissipated, external, check,
              kinetic_limit, inv):
    """``nsteps`` explicit Runge–Kutta–Munthe-Kaas steps with tableau ``(A, b)``.

    ``dynamics``: ``rkmk4`` (S by the same tableau on ``Ṡ = ad_NᵀS + W``, N = velocity(S));
    otherwise the overdamped flow of order 2 (N = Γ⁻¹W(N = 0), S = 0), with ``N`` the drift
    velocity of the current state on entry and of the final state on return.  Stage ``i``
    drifts a copy of the configuration by ``σ_i`` (``X ← Ad_{exp(−σ)}X + 𝓔(1, −σ)∂σ``).
    Returns ``(steps done, t, dissipated, external)``.
    """
    gid = P[I_GID]
    n, r = S.shape
    s = b.shape[0]
    ksig = np.empty((s, n, r))
    kS = np.empty((s, n, r))
    sigma = np.empty((n, r))
    Sst = np.empty((n, r))
    Nst = np.empty((n, r))
    Z = np.zeros((n, r))
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1])
    Xst = np.empty_like(X)
    Phist = np.empty_like(Phi)
    xi, Qv, tr, M, M2, A1, A2, A3, XI = scr
    if dynamics:
        _velocity(P, S, N)
    books = (dissipated, external) + _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        for st in range(s):
            moved = _increment(ksig, A[st], st, dt, sigma)
            if dynamics:
                _increment(kS, A[st], st, dt, Sst)
                for i in range(n):
                    for k in range(r):
                        Sst[i, k] = S[i, k] + Sst[i, k]
            Xst[:] = X
            Phist[:] = Phi
            if moved:
                _drift(P, Dc, Xst, Phist, Sst, W, sigma, 1.0, DN, D, scr, MODE_NONE)
            if dynamics:
                _velocity(P, Sst, Nst)
            elif st == 0:
                Nst[:] = N
            else:
                _drift_velocity(P, Dc, Xst, Phist, Z, W, Q, Nst, gam, scr)
            _dexp_slopes(gid, sigma, Nst, ksig[st], tr, M)
            if dynamics:
                _force(P, Dc, Xst, Phist, Nst, W, Q, scr)
                _lie_poisson(gid, Nst, Sst, W, kS[st], M)
        _increment(ksig, b, s, dt, sigma)
        _drift(P, Dc, X, Phi, S, W, sigma, 1.0, DN, D, scr, MODE_NONE)
        if dynamics:
            _increment(kS, b, s, dt, Sst)
            for i in range(n):
                for k in range(r):
                    S[i, k] = S[i, k] + Sst[i, k]
            _constrain(P, S)
            _velocity(P, S, N)
        else:
            S[:] = 0.0
            _drift_velocity(P, Dc, X, Phi, Z, W, Q, N, gam, scr)
        t = t + dt
        books, stop = _end_step(P, S, X, Phi, N, scr, dt, books, check, kinetic_limit, P[I_W], inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


# ---------------------------------------------------------------------------- SE(3), structure of arrays
# For SE(3), lie-euler, lie-verlet, rkmk4 and overdamped (orders 1 and 2) work on
# structure-of-arrays copies of the state — one row per component, one column per node, made
# once per call — so that LLVM vectorises the passes over the nodes.  The node passes have no
# branches: the coefficients come from their Taylor series, and the nodes where those do not
# apply (a turn of 0.1 rad or more in one drift, a stage increment of 0.1 rad or more) are
# flagged and recomputed with the closed forms from the unchanged inputs (the passes write to
# second buffers — strains, momentum, frames — swapped afterwards).  Helpers inlined into a
# vectorised loop take and return scalars or read and write one column (``_col6``, ``_put6``);
# an inlined helper that both reads the arrays and computes keeps LLVM from vectorising.
@_jit
def _soa_deriv(Dc, A, out, rows):
    """``out[k] = D A[k]`` for the rows ``k`` with ``rows[k]``, zero for the others (``A``,
    ``out`` ``[6, n]``); the same stencils and summation order as :func:`_deriv`.  The interior
    indices are unsigned (``i + o ≥ 0`` there), which spares numba's negative-index wrap-around
    test and lets LLVM vectorise the loop; the CSR rows are summed for the six components at
    once (one pass over each row's entries)."""
    indptr = Dc[J_PTR]
    indices = Dc[J_IND]
    data = Dc[J_DAT]
    off = Dc[J_OFF]
    coef = Dc[J_COEF]
    lo, hi = Dc[J_LO], Dc[J_HI]
    ns = off.shape[0]
    n = A.shape[1]
    d = Dc[J_CIRC]
    if d.shape[0]:
        # the Fourier derivative: circulant, D[i, j] = d[(j − i) mod n]
        for k in range(6):
            for i in range(n):
                out[k, i] = 0.0
            if not rows[k]:
                continue
            for m in range(n):
                c = d[m]
                for i in range(n - m):
                    out[k, i] += c * A[k, uint64(i + m)]
                for i in range(n - m, n):
                    out[k, i] += c * A[k, uint64(i + m - n)]
        return
    for k in range(6):
        if not rows[k]:
            continue
        if ns == 2:
            o0, o1 = off[0], off[1]
            c0, c1 = coef[0], coef[1]
            for i in range(lo, hi):
                out[k, i] = c0 * A[k, uint64(i + o0)] + c1 * A[k, uint64(i + o1)]
        elif ns == 4:
            o0, o1, o2, o3 = off[0], off[1], off[2], off[3]
            c0, c1, c2, c3 = coef[0], coef[1], coef[2], coef[3]
            for i in range(lo, hi):
                out[k, i] = (c0 * A[k, uint64(i + o0)] + c1 * A[k, uint64(i + o1)] + c2 * A[k, uint64(i + o2)]
                             + c3 * A[k, uint64(i + o3)])
    for b in range(n - (hi - lo)):
        i = b if b < lo else b + hi - lo  # the rows before lo, then from hi on
        a0 = a1 = a2 = a3 = a4 = a5 = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            c = data[p]
            j = uint64(indices[p])
            a0 += c * A[0, j]
            a1 += c * A[1, j]
            a2 += c * A[2, j]
            a3 += c * A[3, j]
            a4 += c * A[4, j]
            a5 += c * A[5, j]
        _put6(out, i, (a0, a1, a2, a3, a4, a5))
    for k in range(6):
        if not rows[k]:
            for i in range(n):
                out[k, i] = 0.0


@_jit
def _soa_force(P, Dc, x, phi, nv, w, q, rows):
    """``w`` ← :func:`_force` on the structure-of-arrays state (``q`` the stress on return;
    ``rows`` all True)."""
    X0 = P[I_X0]
    C = P[I_C]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n = x.shape[1]
    if P[I_DIAG]:
        for k in range(6):
            ck = C[k, k]
            x0 = X0[k]
            for i in range(n):
                q[k, i] = ck * (x[k, i] - x0)
    else:
        for i in range(n):
            for a in range(6):
                acc = 0.0
                for b in range(6):
                    acc += C[a, b] * (x[b, i] - X0[b])
                q[a, i] = acc
    _soa_deriv(Dc, q, w, rows)
    # − ad_Xᵀ Q = (ω × F; v × F + ω × M)
    for i in range(n):
        a = cross3(x[3, i], x[4, i], x[5, i], q[0, i], q[1, i], q[2, i])
        b = cross3(x[0, i], x[1, i], x[2, i], q[0, i], q[1, i], q[2, i])
        c = cross3(x[3, i], x[4, i], x[5, i], q[3, i], q[4, i], q[5, i])
        w[0, i] += a[0]
        w[1, i] += a[1]
        w[2, i] += a[2]
        w[3, i] += b[0] + c[0]
        w[4, i] += b[1] + c[1]
        w[5, i] += b[2] + c[2]
    free_idx = Dc[J_FREE_IDX]
    for f in range(free_idx.shape[0]):
        i = free_idx[f]
        e = Dc[J_FREE_LOAD][f]
        load = _soa_end_load(P, phi, e) if e >= 0 else (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        sign = Dc[J_FREE_SIGN][f]
        H = Dc[J_FREE_H][f]
        for k in range(6):
            w[k, i] += (load[k] - sign * q[k, i]) / H
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        for k in range(6):
            for i in range(n):
                w[k, i] += -nv[k, i] * damp[k]
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        for k in range(6):
            for i in range(n):
                w[k, i] += ubody[k]
    if P[I_HAS_FIELD]:
        f0, f1, f2 = P[I_FIELD][0], P[I_FIELD][1], P[I_FIELD][2]
        for k in range(3):
            for i in range(n):
                w[k, i] += phi[3 + k, i] * f0 + phi[6 + k, i] * f1 + phi[9 + k, i] * f2
    if P[I_CONSTRAINED]:
        for k in range(6):
            for i in range(n):
                if clamped[i] or not live[k]:
                    w[k, i] = 0.0


@_inline
def _col6(a, i):
    """Column ``i`` of a ``[6, n]`` array as a 6-tuple."""
    return a[0, i], a[1, i], a[2, i], a[3, i], a[4, i], a[5, i]


@_inline
def _put6(a, i, v):
    """Column ``i`` of a ``[6, n]`` array ← the 6-tuple ``v``."""
    a[0, i] = v[0]
    a[1, i] = v[1]
    a[2, i] = v[2]
    a[3, i] = v[3]
    a[4, i] = v[4]
    a[5, i] = v[5]


@_inline
def _scale6(tau, v):
    """``τv`` for a 6-tuple ``v`` = (translation; rotation), and θ² of its rotation."""
    v0, v1, v2, w0, w1, w2 = tau * v[0], tau * v[1], tau * v[2], tau * v[3], tau * v[4], tau * v[5]
    return v0, v1, v2, w0, w1, w2, w0 * w0 + w1 * w1 + w2 * w2


@_inline
def _soa_node(i, x, s, f, nv, dn, tau, mode):
    """:func:`_se3_node` at node ``i`` of the structure-of-arrays state with the coefficients
    of :func:`_coeffs` (series or closed forms); also returns θ² (for the loops that are not
    vectorised: the nodes beyond the series)."""
    v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
    A, B, C, Dq, Eq = _coeffs(t2)
    Xn, Sn, t, R = _se3_node(v0, v1, v2, w0, w1, w2, tau, A, B, C, Dq, Eq, _col6(x, i), _col6(dn, i), _col6(s, i),
                             _col6(f, i), mode)
    return Xn, Sn, t, R, t2


@_jit
def _soa_nodes(x, s, f, nv, dn, tau, mode, xo, so, phi, phio):
    """The node pass of a drift by ``τ nv`` (``dn = ∂nv``) with the momentum update of
    ``mode``: strains into ``xo``, momentum into ``so`` (``mode`` ≠ ``MODE_NONE``), the frames
    ``phi`` of the first ``phi.shape[1]`` nodes into ``phio``.

    LLVM vectorises a loop that writes one array and calls :func:`_se3_node` directly (with
    two written arrays its run-time overlap tests exceed its limit; a further inlined wrapper
    that reads the arrays also stops it), hence one loop per written array, each with the
    series coefficients; the nodes beyond the series' range are then recomputed with the
    closed forms from the unchanged inputs.  Returns the number of those nodes.
    """
    n = x.shape[1]
    nbad = 0
    for i in range(n):
        v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
        A, B, C, Dq, Eq = _series(t2)
        Xn, _, _, _ = _se3_node(v0, v1, v2, w0, w1, w2, tau, A, B, C, Dq, Eq, _col6(x, i), _col6(dn, i),
                                _col6(s, i), _col6(f, i), MODE_NONE)
        _put6(xo, i, Xn)
        nbad += t2 >= SMALL_THETA2
    if mode != MODE_NONE:
        for i in range(n):
            v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
            A, B, C, Dq, Eq = _series(t2)
            _, Sn, _, _ = _se3_node(v0, v1, v2, w0, w1, w2, tau, A, B, C, Dq, Eq, _col6(x, i), _col6(dn, i),
                                    _col6(s, i), _col6(f, i), mode)
            _put6(so, i, Sn)
    if nbad:
        for i in range(n):
            Xn, Sn, _, _, t2 = _soa_node(i, x, s, f, nv, dn, tau, mode)
            if t2 < SMALL_THETA2:
                continue
            _put6(xo, i, Xn)
            if mode != MODE_NONE:
                _put6(so, i, Sn)
    _soa_frames(nv, tau, phi, phio, nbad == 0)
    return nbad


@_inline
def _frame_times_exp(f, v0, v1, v2, w0, w1, w2, A, B, C):
    """``Φ exp(v; w)`` for the 12-tuple ``f`` = (p; P row-major) of ``Φ = (p; P)``, with the
    coefficients ``(A, B, C)`` of θ² = |w|²: ``exp(v; w) = (t; R)`` as :func:`_se3_node` forms
    it, and ``Φ(t; R) = (Pt + p; PR)``."""
    R = _poly_entries(w0, w1, w2, A, B, 1.0)
    t = _V_apply(w0, w1, w2, B, C, v0, v1, v2)
    return (f[3] * t[0] + f[4] * t[1] + f[5] * t[2] + f[0], f[6] * t[0] + f[7] * t[1] + f[8] * t[2] + f[1],
            f[9] * t[0] + f[10] * t[1] + f[11] * t[2] + f[2],
            f[3] * R[0] + f[4] * R[3] + f[5] * R[6], f[3] * R[1] + f[4] * R[4] + f[5] * R[7],
            f[3] * R[2] + f[4] * R[5] + f[5] * R[8],
            f[6] * R[0] + f[7] * R[3] + f[8] * R[6], f[6] * R[1] + f[7] * R[4] + f[8] * R[7],
            f[6] * R[2] + f[7] * R[5] + f[8] * R[8],
            f[9] * R[0] + f[10] * R[3] + f[11] * R[6], f[9] * R[1] + f[10] * R[4] + f[11] * R[7],
            f[9] * R[2] + f[10] * R[5] + f[11] * R[8])


@_inline
def _col12(a, i):
    """Column ``i`` of a ``[12, n]`` array as a 12-tuple."""
    return (a[0, i], a[1, i], a[2, i], a[3, i], a[4, i], a[5, i], a[6, i], a[7, i], a[8, i], a[9, i], a[10, i],
            a[11, i])


@_inline
def _put6_at(a, row, i, v):
    """Rows ``row … row + 5`` of column ``i`` of ``a`` ← the 6-tuple ``v``."""
    a[row, i] = v[0]
    a[row + 1, i] = v[1]
    a[row + 2, i] = v[2]
    a[row + 3, i] = v[3]
    a[row + 4, i] = v[4]
    a[row + 5, i] = v[5]


@_jit
def _soa_frames(nv, tau, phi, out, series):
    """``out ← Φ exp(τ nv)`` for the frames ``Φ = phi`` of the first ``phi.shape[1]`` nodes.
    ``series``: every node turns by less than 0.1 rad, so the coefficients come from their
    Taylor series in loops LLVM vectorises, one for each half of the rows (it vectorises a
    loop that writes six rows, not one that writes twelve); otherwise from :func:`_coeffs`,
    node by node."""
    if not series:
        for i in range(phi.shape[1]):
            v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
            A, B, C, _, _ = _coeffs(t2)
            g = _frame_times_exp(_col12(phi, i), v0, v1, v2, w0, w1, w2, A, B, C)
            _put6_at(out, 0, i, g[:6])
            _put6_at(out, 6, i, g[6:])
        return
    for i in range(phi.shape[1]):
        v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
        A, B, C, _, _ = _series(t2)
        _put6_at(out, 0, i, _frame_times_exp(_col12(phi, i), v0, v1, v2, w0, w1, w2, A, B, C)[:6])
    for i in range(phi.shape[1]):
        v0, v1, v2, w0, w1, w2, t2 = _scale6(tau, _col6(nv, i))
        A, B, C, _, _ = _series(t2)
        _put6_at(out, 6, i, _frame_times_exp(_col12(phi, i), v0, v1, v2, w0, w1, w2, A, B, C)[6:])


@_inline
def _rotation_node(th, axis, tau, A, B, C, x, a, s):
    """:func:`_se3_node_rotation` for the turn ``th`` about the body axis ``axis``."""
    return _se3_node_rotation(th if axis == 0 else 0.0, th if axis == 1 else 0.0, th if axis == 2 else 0.0, tau,
                              A, B, C, x, a, s)


@_jit
def _soa_piece(x, s, f, nv, dn, tau, piece, axis, xo, so, phi, phio):
    """:func:`_soa_nodes` with ``mode = MODE_COAD`` for the free-flow pieces of ``lie-verlet``
    on SE(3) that have closed forms: the translations (``piece = PIECE_TRANSLATION``) and a
    rotation about the body axis ``axis`` (``piece = PIECE_ROTATION``); the other components
    of ``nv`` are zero.  The same results as the general pass, with less arithmetic."""
    n = x.shape[1]
    nbad = 0
    if piece == PIECE_TRANSLATION:
        for i in range(n):
            Xn, _ = _se3_node_translation(tau * nv[0, i], tau * nv[1, i], tau * nv[2, i], tau, _col6(x, i),
                                          _col6(dn, i), _col6(s, i))
            _put6(xo, i, Xn)
        for i in range(n):
            _, Sn = _se3_node_translation(tau * nv[0, i], tau * nv[1, i], tau * nv[2, i], tau, _col6(x, i),
                                          _col6(dn, i), _col6(s, i))
            _put6(so, i, Sn)
    else:
        for i in range(n):
            th = tau * nv[3 + axis, i]
            A, B, C, _, _ = _series(th * th)
            Xn, _ = _rotation_node(th, axis, tau, A, B, C, _col6(x, i), _col6(dn, i), _col6(s, i))
            _put6(xo, i, Xn)
            nbad += th * th >= SMALL_THETA2
        for i in range(n):
            th = tau * nv[3 + axis, i]
            A, B, C, _, _ = _series(th * th)
            _, Sn = _rotation_node(th, axis, tau, A, B, C, _col6(x, i), _col6(dn, i), _col6(s, i))
            _put6(so, i, Sn)
        if nbad:
            for i in range(n):
                th = tau * nv[3 + axis, i]
                if th * th < SMALL_THETA2:
                    continue
                A, B, C, _, _ = _coeffs(th * th)
                Xn, Sn = _rotation_node(th, axis, tau, A, B, C, _col6(x, i), _col6(dn, i), _col6(s, i))
                _put6(xo, i, Xn)
                _put6(so, i, Sn)
    _soa_frames(nv, tau, phi, phio, nbad == 0)
    return nbad


@_inline
def _dexp_inv_neg(sig, cinv, c, d, e, a):
    """``dexp⁻¹(−σ) a`` for 6-tuples ``σ`` and ``a = (a_t; a_r)``: with ``ξ = −σ = (r; p)``,
    ``dexp⁻¹(ξ) = [[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]``, ``J⁻¹u = u − ½p × u + c_inv p × (p × u)`` and
    Barfoot–Furgale's ``Q = Q(r, p)`` (coefficients ``c, d, e``), it is
    ``(J⁻¹(a_t − QJ⁻¹a_r); J⁻¹a_r)``."""
    r0, r1, r2, p0, p1, p2 = -sig[0], -sig[1], -sig[2], -sig[3], -sig[4], -sig[5]
    j = _V_apply(p0, p1, p2, -0.5, cinv, a[3], a[4], a[5])
    q = _q_block(r0, r1, r2, p0, p1, p2, c, d, e, j[0], j[1], j[2])
    o = _V_apply(p0, p1, p2, -0.5, cinv, a[0] - q[0], a[1] - q[1], a[2] - q[2])
    return o[0], o[1], o[2], j[0], j[1], j[2]


@_jit
def _soa_dexp_inv(sig, nv, out):
    """``out = dexp⁻¹(−σ) nv`` at every node, the slope ``σ̇ = dexp⁻¹_{−σ}N`` of an RKMK stage
    (``_rkmk`` of :mod:`cartan.integrators.explicit`), ``σ = sig``: a vectorised pass with the
    Taylor series of the coefficients, then the nodes with θ = |σ_ω| ≥ 0.1 recomputed with the
    closed forms (``so3_dexp_inv_coeff``, ``se3_dexp_coeffs``).  Returns their number."""
    n = sig.shape[1]
    nbad = 0
    for i in range(n):
        sg = _col6(sig, i)
        t2 = sg[3] * sg[3] + sg[4] * sg[4] + sg[5] * sg[5]
        _put6(out, i, _dexp_inv_neg(sg, horner(t2, TAYLOR_CINV), horner(t2, TAYLOR_C), horner(t2, TAYLOR_D),
                                    horner(t2, TAYLOR_E), _col6(nv, i)))
        nbad += t2 >= SMALL_THETA2
    if nbad:
        for i in range(n):
            sg = _col6(sig, i)
            t2 = sg[3] * sg[3] + sg[4] * sg[4] + sg[5] * sg[5]
            if t2 < SMALL_THETA2:
                continue
            _, c, d, e = _dexp_coeffs_direct(t2)
            _put6(out, i, _dexp_inv_neg(sg, _cinv_direct(t2), c, d, e, _col6(nv, i)))
    return nbad


@_jit
def _soa_lie_poisson(nv, s, f, out):
    """``out = ad_NᵀS + W`` at every node (``Ṡ`` of the momentum balance): for ``N = (v; ω)``
    and ``S = (F; M)``, ``ad_NᵀS = (F × ω; F × v + M × ω)``."""
    for i in range(nv.shape[1]):
        a = cross3(s[0, i], s[1, i], s[2, i], nv[3, i], nv[4, i], nv[5, i])
        b = cross3(s[0, i], s[1, i], s[2, i], nv[0, i], nv[1, i], nv[2, i])
        c = cross3(s[3, i], s[4, i], s[5, i], nv[3, i], nv[4, i], nv[5, i])
        out[0, i] = a[0] + f[0, i]
        out[1, i] = a[1] + f[1, i]
        out[2, i] = a[2] + f[2, i]
        out[3, i] = (b[0] + c[0]) + f[3, i]
        out[4, i] = (b[1] + c[1]) + f[4, i]
        out[5, i] = (b[2] + c[2]) + f[5, i]


@_jit
def _soa_nonfinite(x, phi):
    """True when an entry of ``x`` or ``phi`` is not finite (``v − v ≠ 0`` exactly then; an
    integer count, which LLVM vectorises)."""
    bad = 0
    for k in range(x.shape[0]):
        for i in range(x.shape[1]):
            bad += x[k, i] - x[k, i] != 0.0
    for k in range(phi.shape[0]):
        for i in range(phi.shape[1]):
            bad += phi[k, i] - phi[k, i] != 0.0
    return bad > 0


@_jit
def _to_soa(A, a):
    """``a[k, i] = A[i, k]``."""
    for i in range(A.shape[0]):
        for k in range(A.shape[1]):
            a[k, i] = A[i, k]


@_jit
def _from_soa(a, A):
    """``A[i, k] = a[k, i]``."""
    for i in range(A.shape[0]):
        for k in range(A.shape[1]):
            A[i, k] = a[k, i]


@_jit
def _soa_state(S, X, Phi):
    """Structure-of-arrays copies ``(s [6, n], x [6, n], phi [12, nf])`` of the state: one row
    per component, one column per node; ``phi[:, i]`` = rows 1–3 of the SE(3) element
    ``Phi[i]`` = (translation; rotation row-major)."""
    n = S.shape[0]
    s, x, phi = np.empty((6, n)), np.empty((6, n)), np.empty((12, Phi.shape[0]))
    _to_soa(S, s)
    _to_soa(X, x)
    for i in range(Phi.shape[0]):
        for r in range(3):
            phi[r, i] = Phi[i, r + 1, 0]
            for c in range(3):
                phi[3 + 3 * r + c, i] = Phi[i, r + 1, c + 1]
    return s, x, phi


@_jit
def _soa_store(s, x, phi, S, X, Phi):
    """Inverse of :func:`_soa_state` (the first row of ``Phi[i]`` is left as it is)."""
    _from_soa(s, S)
    _from_soa(x, X)
    for i in range(Phi.shape[0]):
        for r in range(3):
            Phi[i, r + 1, 0] = phi[r, i]
            for c in range(3):
                Phi[i, r + 1, c + 1] = phi[3 + 3 * r + c, i]


@_jit
def _soa_scaled(P, a, out, div, mask):
    """``out[k] = a[k]/div[k]`` on the live components ``k`` in ``mask``, zero on the others and
    at clamped nodes: the velocity ``S/m`` (with ``mask`` a ``lie-verlet`` piece, its
    components ``N[..., piece]`` only) or the overdamped velocity ``Γ⁻¹W``.  True when an
    entry of ``out`` is not zero."""
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n = a.shape[1]
    for k in range(6):
        if not (mask[k] and live[k]):
            for i in range(n):
                out[k, i] = 0.0
            continue
        d = div[k]
        for i in range(n):
            out[k, i] = a[k, i] / d
    if P[I_CONSTRAINED]:
        for i in range(n):
            if clamped[i]:
                for k in range(6):
                    out[k, i] = 0.0
    moving = 0
    for k in range(6):
        for i in range(n):
            moving += out[k, i] != 0.0
    return moving > 0


@_jit
def _soa_constrain(P, s):
    """Zero the momentum of gauge components and clamped nodes."""
    if not P[I_CONSTRAINED]:
        return
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    for k in range(6):
        for i in range(s.shape[1]):
            if clamped[i] or not live[k]:
                s[k, i] = 0.0


@_jit
def _soa_kick(s, f, half):
    for k in range(6):
        for i in range(s.shape[1]):
            s[k, i] = s[k, i] + half * f[k, i]


@_jit
def _soa_powers(P, nv, phi):
    """(dissipated, external) power at velocity ``nv`` (``Scheme.powers``)."""
    if not P[I_HAS_POWER]:
        return 0.0, 0.0
    w = P[I_W]
    n = nv.shape[1]
    dissipated = 0.0
    external = 0.0
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        p = 0.0
        for i in range(n):
            acc = 0.0
            for k in range(6):
                acc += (-nv[k, i] * damp[k]) * nv[k, i]
            p += w[i] * acc
        dissipated -= p
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        p = 0.0
        for i in range(n):
            acc = 0.0
            for k in range(6):
                acc += ubody[k] * nv[k, i]
            p += w[i] * acc
        external += p
    p = 0.0
    end_idx = P[I_END_IDX]
    for q in range(end_idx.shape[0]):
        i = end_idx[q]
        b = _soa_end_load(P, phi, q)
        for k in range(6):
            p += b[k] * nv[k, i]
    external += p
    return dissipated, external


@_jit
def _soa_unstable(kinetic_limit, s, w, inv):
    """The per-step blow-up test of integrators with momentum: a non-finite momentum, or a
    kinetic energy ``½Σ w s²/m`` above ``kinetic_limit``."""
    n = s.shape[1]
    tot = 0.0
    for k in range(6):
        for i in range(n):
            tot += s[k, i]
    if not np.isfinite(tot):
        return True
    if kinetic_limit < np.inf:
        K = 0.0
        for k in range(6):
            for i in range(n):
                K += w[i] * s[k, i] * s[k, i] * inv[k]
        if not 0.5 * K <= kinetic_limit:
            return True
    return False


@_jit
def _soa_end_step(P, s, x, phi, nv, dt, books, check, kinetic_limit, inv):
    """:func:`_end_step` on the structure-of-arrays state: the powers at the final velocity
    ``nv`` booked into ``books``, and the blow-up test of ``check`` (momentum, or a finite
    configuration for integrators without momentum)."""
    dissipated, external, p0d, p0e = books
    p1d, p1e = _soa_powers(P, nv, phi)
    dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
    if check == CHECK_MOMENTUM:
        stop = _soa_unstable(kinetic_limit, s, P[I_W], inv)
    else:
        stop = check == CHECK_CONFIGURATION and _soa_nonfinite(x, phi)
    return (dissipated, external, p1d, p1e), stop


@_jit
def lie_euler_se3_loop(P, Dc, S, X, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """:func:`euler_loop` (Lie–Euler) for SE(3) on structure-of-arrays copies of ``S``, ``X``, ``Phi``
    (copied back on return)."""
    n = S.shape[0]
    s, x, phi = _soa_state(S, X, Phi)
    phio = np.empty_like(phi)
    so, xo, f, q = np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n))
    nv, dn = np.empty((6, n)), np.empty((6, n))
    rows = np.ones(6, dtype=np.bool_)
    mass = P[I_MASS]
    _soa_scaled(P, s, nv, mass, rows)
    books = (dissipated, external) + _soa_powers(P, nv, phi)
    done = 0
    for _ in range(nsteps):
        _soa_force(P, Dc, x, phi, nv, f, q, rows)
        _soa_deriv(Dc, nv, dn, rows)
        _soa_nodes(x, s, f, nv, dn, dt, MODE_LIE_EULER, xo, so, phi, phio)
        x, xo = xo, x
        s, so = so, s
        phi, phio = phio, phi
        _soa_constrain(P, s)
        t = t + dt
        _soa_scaled(P, s, nv, mass, rows)
        books, stop = _soa_end_step(P, s, x, phi, nv, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    _soa_store(s, x, phi, S, X, Phi)
    return done, t, books[0], books[1]


@_jit
def lie_verlet_se3_loop(P, Dc, S, X, Phi, W, have_force, velocity_free, seq_mask, seq_frac, seq_kind,
                        t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """:func:`lie_verlet_loop` for SE(3) on structure-of-arrays copies of ``S``, ``X``, ``Phi``
    and ``W`` (copied back on return); the derivative of each free-flow piece's velocity is
    taken on that piece's components only (the others are zero)."""
    n = S.shape[0]
    s, x, phi = _soa_state(S, X, Phi)
    phio = np.empty_like(phi)
    so, xo, f, q = np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n))
    npc, dn = np.empty((6, n)), np.empty((6, n))
    nv = np.zeros((6, n))
    rows = np.ones(6, dtype=np.bool_)
    mass = P[I_MASS]
    _to_soa(W, f)
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _soa_scaled(P, s, nv, mass, rows)
    books = (dissipated, external) + _soa_powers(P, nv, phi)
    done = 0
    for _ in range(nsteps):
        if not (have_force and velocity_free):
            _soa_force(P, Dc, x, phi, nv, f, q, rows)
            nforce += 1
        _soa_kick(s, f, half)
        _soa_constrain(P, s)
        for p in range(seq_frac.shape[0]):
            if not _soa_scaled(P, s, npc, mass, seq_mask[p]):
                continue  # exp(0) = I: nothing moves
            _soa_deriv(Dc, npc, dn, seq_mask[p])
            tau = seq_frac[p] * dt
            if seq_kind[p, 0] == PIECE_GENERAL:
                _soa_nodes(x, s, f, npc, dn, tau, MODE_COAD, xo, so, phi, phio)
            else:
                _soa_piece(x, s, f, npc, dn, tau, seq_kind[p, 0], seq_kind[p, 1], xo, so, phi, phio)
            x, xo = xo, x
            s, so = so, s
            phi, phio = phio, phi
        _soa_constrain(P, s)
        if need_N:
            _soa_scaled(P, s, nv, mass, rows)
        _soa_force(P, Dc, x, phi, nv, f, q, rows)
        nforce += 1
        have_force = True
        _soa_kick(s, f, half)
        _soa_constrain(P, s)
        t = t + dt
        if need_N:
            _soa_scaled(P, s, nv, mass, rows)
        books, stop = _soa_end_step(P, s, x, phi, nv, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    _soa_store(s, x, phi, S, X, Phi)
    _from_soa(f, W)
    return done, nforce, t, books[0], books[1]


@_jit
def overdamped_se3_loop(P, Dc, S, X, Phi, N, gam, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """:func:`overdamped_loop` for SE(3) on structure-of-arrays copies of ``X``, ``Phi`` and
    ``N`` (copied back on return; ``S`` is zero)."""
    n = S.shape[0]
    S[:] = 0.0
    s, x, phi = _soa_state(S, X, Phi)
    phio = np.empty_like(phi)
    xo, f, q, nv, dn = np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n))
    z = np.zeros((6, n))
    rows = np.ones(6, dtype=np.bool_)
    _to_soa(N, nv)
    books = (dissipated, external) + _soa_powers(P, nv, phi)
    done = 0
    for _ in range(nsteps):
        _soa_deriv(Dc, nv, dn, rows)
        _soa_nodes(x, s, f, nv, dn, dt, MODE_NONE, xo, s, phi, phio)
        x, xo = xo, x
        phi, phio = phio, phi
        t = t + dt
        _soa_force(P, Dc, x, phi, z, f, q, rows)
        _soa_scaled(P, f, nv, gam, rows)
        books, stop = _soa_end_step(P, s, x, phi, nv, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    _soa_store(s, x, phi, S, X, Phi)
    _from_soa(nv, N)
    return done, t, books[0], books[1]


@_jit
def rkmk_se3_loop(P, Dc, S, X, Phi, N, gam, dynamics, A, b, t, dt, nsteps, dissipated, external, check,
                  kinetic_limit, inv):
    """:func:`rkmk_loop` for SE(3) on structure-of-arrays copies of ``S``, ``X``, ``Phi`` and
    ``N`` (copied back on return): ``rkmk4`` (``dynamics``) or the overdamped flow of order 2.

    Stage ``i``: ``σ_i = Δt Σ_j a_ij kσ_j`` (and ``S_i = S + Δt Σ_j a_ij kS_j``); unless
    ``σ_i = 0``, the configuration drifted by ``σ_i`` with τ = 1 into the stage buffers (the
    state is left as it is); ``N_i`` = velocity(``S_i``) (or ``Γ⁻¹W(N = 0)`` at the stage, the
    current ``N`` at the first); ``kσ_i = dexp⁻¹_{−σ_i}N_i`` and ``kS_i = ad_{N_i}ᵀS_i + W_i``.
    Then the state drifts by ``σ = Δt Σ_i b_i kσ_i`` and ``S += Δt Σ_i b_i kS_i``.  Every pass is
    one of the vectorised node passes above.  Returns ``(steps done, t, dissipated, external)``.
    """
    n = S.shape[0]
    ns = b.shape[0]
    if not dynamics:
        S[:] = 0.0
    s, x, phi = _soa_state(S, X, Phi)
    phio = np.empty_like(phi)
    xo, xst, sst, nst, sig = np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n))
    f, q, nv, dn = np.empty((6, n)), np.empty((6, n)), np.empty((6, n)), np.empty((6, n))
    z = np.zeros((6, n))
    ksig, kS = np.empty((ns, 6, n)), np.empty((ns, 6, n))
    phist = np.empty_like(phi)
    rows = np.ones(6, dtype=np.bool_)
    mass = P[I_MASS]
    if dynamics:
        _soa_scaled(P, s, nv, mass, rows)
    else:
        _to_soa(N, nv)
    books = (dissipated, external) + _soa_powers(P, nv, phi)
    done = 0
    for _ in range(nsteps):
        for st in range(ns):
            moved = _increment(ksig, A[st], st, dt, sig)
            if dynamics:
                _increment(kS, A[st], st, dt, sst)
                sst += s
            xs, ps = x, phi
            if moved:
                _soa_deriv(Dc, sig, dn, rows)
                _soa_nodes(x, s, f, sig, dn, 1.0, MODE_NONE, xst, s, phi, phist)
                xs, ps = xst, phist
            if dynamics:
                _soa_scaled(P, sst, nst, mass, rows)
                _soa_dexp_inv(sig, nst, ksig[st])
                _soa_force(P, Dc, xs, ps, nst, f, q, rows)
                _soa_lie_poisson(nst, sst, f, kS[st])
            elif st == 0:
                _soa_dexp_inv(sig, nv, ksig[st])
            else:
                _soa_force(P, Dc, xs, ps, z, f, q, rows)
                _soa_scaled(P, f, nst, gam, rows)
                _soa_dexp_inv(sig, nst, ksig[st])
        _increment(ksig, b, ns, dt, sig)
        _soa_deriv(Dc, sig, dn, rows)
        _soa_nodes(x, s, f, sig, dn, 1.0, MODE_NONE, xo, s, phi, phio)
        x, xo = xo, x
        phi, phio = phio, phi
        if dynamics:
            _increment(kS, b, ns, dt, sst)
            s += sst
            _soa_constrain(P, s)
            _soa_scaled(P, s, nv, mass, rows)
        else:
            _soa_force(P, Dc, x, phi, z, f, q, rows)
            _soa_scaled(P, f, nv, gam, rows)
        t = t + dt
        books, stop = _soa_end_step(P, s, x, phi, nv, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    _soa_store(s, x, phi, S, X, Phi)
    _from_soa(nv, N)
    return done, t, books[0], books[1]


# ---------------------------------------------------------------------------- single operations (tests, CFL estimate)
@_jit
def force_once(P, Dc, X, Phi, N, W):
    """One force evaluation ``W`` at ``(X, Phi, N)`` (compared with ``Collocation.force``)."""
    n, r = W.shape
    _force(P, Dc, X, Phi, N, W, np.empty((n, r)), _scratch(r, Phi.shape[1], 0))


@_jit
def drift_once(P, Dc, X, Phi, N, tau, exact):
    """One drift of ``(X, Phi)`` by ``τN`` in place, exact or naive (``Collocation.drift``)."""
    n, r = X.shape
    m = Phi.shape[1]
    scr = _scratch(r, m, 0)
    Z = np.zeros((n, r))
    if exact:
        _drift(P, Dc, X, Phi, Z, Z, N, tau, np.empty((n, r)), np.empty((n, m, m)), scr, MODE_NONE)
    else:
        _naive_drift(P, Dc, X, Phi, N, tau, np.empty((n, r)), np.empty((n, m, m)), scr)


@_jit
def stiffness_once(P, Dc, X, Phi, v, eps, K):
    """One product ``K = −[W(Φ exp(εv)) − W(Φ exp(−εv))]/(2ε)`` of the stiffness with ``v``
    ``[n, r]`` (``Scheme.stiffness_probe``): W the force at N = 0 after an exact drift of a
    copy of ``(X [n, r], Phi [nf, m, m])`` by ``±εv`` (left as they are)."""
    n, r = X.shape
    m = Phi.shape[1]
    W, Q, DN, D, scr = _work(n, r, m)
    Z = np.zeros((n, r))
    Wm = np.empty((n, r))
    Xs = np.empty_like(X)
    Phis = np.empty_like(Phi)
    for tau, Ws in ((eps, W), (-eps, Wm)):
        Xs[:] = X
        Phis[:] = Phi
        _drift(P, Dc, Xs, Phis, Z, Z, v, tau, DN, D, scr, MODE_NONE)
        _force(P, Dc, Xs, Phis, Z, Ws, Q, scr)
    for i in range(n):
        for k in range(r):
            K[i, k] = -(W[i, k] - Wm[i, k]) / (2.0 * eps)


@_jit
def derivative_once(Dc, A, out):
    """``out = ∂A`` by the CSR operator of ``Dc`` (compared with ``DerivativeOperator``)."""
    _deriv(Dc, A, out)


# ---------------------------------------------------------------------------- Python glue
def _csr(D) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The derivative operator ``D`` (a :class:`~cartan.schemes.collocation.DerivativeOperator`)
    as CSR arrays ``(indptr (n+1,), indices (nnz,), data (nnz,))``, each row's entries in the
    order ``D.__call__`` sums them."""
    n = D.n
    if D.kind == "fourier":  # applied as a circulant (:func:`_circulant`), no CSR rows
        return np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    (off, c), boundary = D.rows()
    rows = [None] * n
    for i, o_row, c_row in boundary:
        rows[i] = (np.array([i + o for o in o_row]), np.asarray(c_row))
    for i in range(n):
        if rows[i] is None:
            rows[i] = (np.array([(i + o) % n for o in off]), np.asarray(c))
    indptr = np.zeros(n + 1, dtype=np.int64)
    indptr[1:] = np.cumsum([len(idx) for idx, _ in rows])
    indices = np.ascontiguousarray(np.concatenate([idx for idx, _ in rows]), dtype=np.int64)
    data = np.ascontiguousarray(np.concatenate([c for _, c in rows]), dtype=float)
    return indptr, indices, data


def _lie_verlet_pieces(integrator, scheme, cache: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``LieVerlet._sequence`` as arrays, cached in ``cache`` (it depends on the group and the
    live components only): component masks ``[p, r]``, fractions of Δt ``(p,)``, and per piece
    ``(kind, body axis)`` ``[p, 2]`` for SE(3): the three translations, one rotation, or
    anything else (general)."""
    if "lie-verlet" in cache:
        return cache["lie-verlet"]
    seq = integrator._sequence(scheme)
    mask = np.zeros((len(seq), scheme.group.dim), dtype=np.bool_)
    frac = np.empty(len(seq))
    kinds = np.zeros((len(seq), 2), dtype=np.int64)
    for p, (P, f) in enumerate(seq):
        idx = sorted(int(i) for i in np.flatnonzero(np.diag(P)))
        mask[p, idx] = True
        frac[p] = f
        if mask.shape[1] == 6 and idx == [0, 1, 2]:
            kinds[p] = (PIECE_TRANSLATION, 0)
        elif mask.shape[1] == 6 and len(idx) == 1 and idx[0] >= 3:
            kinds[p] = (PIECE_ROTATION, idx[0] - 3)
    cache["lie-verlet"] = (mask, frac, kinds)
    return cache["lie-verlet"]


def _circulant(D) -> np.ndarray:
    """The first row ``d`` of the Fourier derivative matrix of ``D`` (``D[i, j] = d[(j − i) mod n]``,
    the operator being translation invariant), or an empty array for the finite differences."""
    if D.kind != "fourier":
        return np.zeros(0)
    return np.ascontiguousarray(D.matrix()[0], dtype=float)


def _interior(D) -> tuple[np.ndarray, np.ndarray, int, int]:
    """The central stencil ``(offsets, coefficients)`` of ``D`` and the nodes ``[lo, hi)`` where
    it applies without wrapping (no nodes for the Fourier operator)."""
    if D.kind == "fourier":
        return np.zeros(0, dtype=np.int64), np.zeros(0), 0, 0
    (off, c), _ = D.rows()
    reach = max(abs(o) for o in off)
    lo = max(reach, D.halfwidth)
    return np.array(off, dtype=np.int64), np.asarray(c, dtype=float), lo, D.n - lo


def build_plan(scheme) -> tuple[tuple, tuple] | None:
    """The problem of a collocation scheme as compiled-loop data ``(P, Dc)``, or None when it
    does not qualify.

    Qualifies: d = 1, 2 or 3, every axis open or periodic; SO(2), SE(2), SO(3), SE(3); the
    ``fd2`` or ``fd4`` derivative, or ``fourier`` up to :data:`FOURIER_MAX_NODES` nodes per
    axis; a medium with a quadratic potential ``U = ½Σ_α(X_α − X₀_α)ᵀC(X_α − X₀_α)`` —
    :meth:`~cartan.medium.Medium.quadratic_energy` returning ``(X0, C)`` (X0 of shape (r,)
    for d = 1, or (d, r)), or for d ≥ 2 a :class:`~cartan.medium.QuadraticMedium` that keeps
    the base energy methods: the sigma model of the ``sigma`` plugin on S² (SO(3)) in d = 1,
    2, 3 and quadratic SE(3)/SE(2) Cosserat surfaces and solids qualify, the sigma model on
    Sⁿ, n ≥ 3 (SO(n+1)) does not — and the base kinetic energy and body force; ``Damping``,
    body-frame ``UniformForce`` and ``ConstantFieldPotential`` loads; free (loaded or not)
    and clamped ends (end faces for d ≥ 2); frames stepped when a load needs them.

    ``P`` has the d = 1 layout of the lattice's plan (``I_*`` up to ``I_HAS_POWER``), the
    nodes numbered in C order (weights and clamps flattened, ``I_X0`` the first axis' rest
    strain); ``Dc`` the layout ``J_*`` for d = 1 and
    :data:`cartan.schemes._collocation_compiled_nd.J_PTR` … for d ≥ 2 (the derivative of
    every axis, the rest strains, the nodes of the free end faces).

    Raises
    ------
    ValueError
        When the medium's ``quadratic_energy`` is malformed or disagrees with its ``stress``.
    """
    from ..medium import Medium
    from .base import Scheme
    from .collocation import Collocation

    problem, medium, group, grid = scheme.problem, scheme.medium, scheme.group, scheme.grid
    gid = _group_id(group)
    d = grid.d
    if gid is None or not 1 <= d <= 3 or problem.reference is not None:
        return None
    if scheme.derivative == "fourier" and max(grid.shape) > FOURIER_MAX_NODES:
        return None
    if not _same_methods(scheme, Collocation, ("force", "internal_force", "drift", "frames", "_boundary_power",
                                               "_end_load", "initial_state")):
        return None
    if not _same_methods(scheme, Scheme, ("velocity", "constrain", "powers", "has_external_power", "drag")):
        return None
    if not scheme.diagonal_metric or np.any(scheme.mass < 0):
        return None  # the kinetic metric of these loops is a positive diagonal
    if not _same_methods(medium, Medium, ("velocity", "body_force")):
        return None
    if getattr(medium, "velocity_dependent_forces", False):
        return None
    r = group.dim
    quad = _quadratic_axes(medium, d, r)
    if quad is None:
        return None
    X0s, C = quad
    loads = _compiled_loads(problem, group, r)
    if loads is None:
        return None
    damp, has_damp, ubody, has_ubody, field, has_field = loads
    if (has_field or any(not b.follower for *_, b, _ in scheme._end_loads)) and not scheme.track:
        return None
    n = grid.size
    # the loaded ends (d = 1) or end faces (d ≥ 2), one load row each
    loaded = [(int(np.arange(n).reshape(grid.shape)[sl].reshape(-1)[0]), b) for _, sl, *_, b, _ in scheme._end_loads]
    P: list = [None] * (I_HAS_POWER + 1)  # the d = 1 entries of the lattice's plan, all the helpers read
    live = np.ascontiguousarray(scheme.live, dtype=np.bool_)
    clamped = np.ascontiguousarray(scheme._clamped, dtype=np.bool_).reshape(n)
    P[I_GID] = int(gid)
    P[I_TRACK] = bool(scheme.track)
    P[I_AFFINE] = bool(getattr(group, "affine", False))
    P[I_H] = float(scheme.h[0])
    P[I_X0] = np.ascontiguousarray(X0s[0])
    P[I_C] = np.ascontiguousarray(C)
    P[I_DIAG] = bool(np.count_nonzero(C - np.diag(np.diag(C))) == 0)
    P[I_W] = np.ascontiguousarray(scheme.weights, dtype=float).reshape(n)
    P[I_MASS] = np.ascontiguousarray(scheme.mass, dtype=float)
    P[I_LIVE] = live
    P[I_CLAMPED] = clamped
    P[I_CONSTRAINED] = bool(clamped.any() or not live.all())
    P[I_DAMP], P[I_HAS_DAMP] = damp, has_damp
    P[I_UBODY], P[I_HAS_UBODY] = ubody, has_ubody
    P[I_FIELD], P[I_HAS_FIELD] = field, has_field
    # d = 1: the loaded end nodes, whose power the shared helpers book; d ≥ 2: none (the loops
    # book the power of the loaded faces from the face nodes of Dc)
    P[I_END_IDX] = np.array([i for i, _ in loaded] if d == 1 else [], dtype=np.int64)
    P[I_END_LOAD] = np.array([np.asarray(b.load, dtype=float) for _, b in loaded], dtype=float).reshape(len(loaded), r)
    P[I_END_FOLLOW] = np.array([bool(b.follower) for _, b in loaded], dtype=np.bool_)
    P[I_HAS_POWER] = bool(scheme.has_external_power())
    if d > 1:
        from ._collocation_compiled_nd import derivative_data

        return tuple(P), derivative_data(scheme, X0s)
    free = [(0 if sl[0] == 0 else n - 1, sign, H, b) for _, sl, sign, H, b, _ in scheme._free_ends]
    indptr, indices, data = _csr(scheme.D[0])
    off, coef, lo, hi = _interior(scheme.D[0])
    Dc = (
        indptr,
        indices,
        data,
        off,
        coef,
        lo,
        hi,
        _circulant(scheme.D[0]),
        np.array([i for i, _, _, _ in free], dtype=np.int64),
        np.array([s for _, s, _, _ in free], dtype=float),
        np.array([H for _, _, H, _ in free], dtype=float),
        np.array([-1 if b.load is None else [j for j, _ in loaded].index(i) for i, _, _, b in free], dtype=np.int64),
    )
    return tuple(P), Dc


def advance_nd(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """:func:`advance` for d = 2 and 3: :func:`cartan.schemes._collocation_compiled_nd.advance`."""
    from ._collocation_compiled_nd import advance as advance_axes

    return advance_axes(scheme, plan, integrator, state, dt, nsteps, kinetic_limit)


def advance(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """Run up to ``nsteps`` steps of ``integrator`` on ``state`` in compiled code (see
    :meth:`cartan.schemes.collocation.Collocation.compiled_advance`); False, touching nothing,
    when the integrator is not supported."""
    if scheme.grid.d >= 2:
        return advance_nd(scheme, plan, integrator, state, dt, nsteps, kinetic_limit)
    from ..compiled.tableaux import TABLEAUX as _TABLEAUX
    from . import _kinematic_compiled as kinematic

    P, Dc = plan
    supported = compiled_kind(scheme, integrator)
    if supported is None:
        return False
    kind, gam = supported
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {"X", frame_key}:
        return False
    n, r = state.S.shape[0], scheme.group.dim
    if state.arrays["X"].shape != (n, 1, r):
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    dt = float(dt)
    S = state.S = _writable(state.S)
    X3 = state.arrays["X"] = _writable(state.arrays["X"])
    X = X3.reshape(n, r)
    Phi = state.arrays[frame_key] = _writable(state.arrays[frame_key])
    Phi3 = Phi if scheme.track else Phi.reshape(1, *Phi.shape)
    if kind == "kinematic":
        def work(inv):  # the work arrays of kinematic.COLLOCATION_OPS
            W, _, DN, D, scr = _work(n, r, Phi3.shape[-1])
            return Dc, np.zeros((n, r)), W, DN, D, scr, inv

        return kinematic.advance(scheme, "collocation", P, (X, Phi3), work, integrator, state, dt, nsteps,
                                 kinetic_limit)
    nstep0, stamp, t0, diss, ext, check, limit, cache, inv = advance_context(scheme, integrator, state,
                                                                             kinetic_limit)
    W = None
    se3 = P[I_GID] == GID_SE3
    if kind == "lie-verlet":
        velocity_free, have, W = lie_verlet_force(scheme, integrator, stamp, S)
        mask, frac, kinds = _lie_verlet_pieces(integrator, scheme, cache)
        if se3:
            done, nforce, t, diss, ext = lie_verlet_se3_loop(
                P, Dc, S, X, Phi3, W, have, bool(velocity_free), mask, frac, kinds, t0, dt, nsteps,
                diss, ext, check, limit, inv)
        else:
            done, nforce, t, diss, ext = lie_verlet_loop(
                P, Dc, S, X, Phi3, W, have, bool(velocity_free), mask, frac, t0, dt, nsteps, diss, ext, check,
                limit, inv)
    elif kind == "lie-euler" or kind == "forward-euler":
        if kind == "lie-euler" and se3:
            done, t, diss, ext = lie_euler_se3_loop(P, Dc, S, X, Phi3, t0, dt, nsteps, diss, ext, check, limit, inv)
        else:
            done, t, diss, ext = euler_loop(P, Dc, S, X, Phi3, t0, dt, nsteps, diss, ext, check, limit, inv,
                                            kind == "lie-euler")
        nforce = done
    else:
        dynamics = kind == "rkmk4"
        order = 4 if dynamics else integrator.order
        hit, N = rkmk_velocity(integrator, stamp, S, dynamics)
        if not dynamics:  # from the state alone (rkmk_velocity)
            overdamped_velocity(P, Dc, X, Phi3, N, gam)
        if order == 1:
            loop = overdamped_se3_loop if se3 else overdamped_loop
            done, t, diss, ext = loop(P, Dc, S, X, Phi3, N, gam, t0, dt, nsteps, diss, ext, check, limit, inv)
        else:
            A, b, _ = _TABLEAUX[order]
            loop = rkmk_se3_loop if se3 else rkmk_loop
            done, t, diss, ext = loop(
                P, Dc, S, X, Phi3, N, np.ones(r) if gam is None else gam, dynamics,
                np.ascontiguousarray(A, dtype=float), np.ascontiguousarray(b, dtype=float),
                t0, dt, nsteps, diss, ext, check, limit, inv)
        nforce = rkmk_books(integrator, state, dynamics, order, done, hit, t, nstep0, N)
    return finish_advance(integrator, state, t, diss, ext, nstep0, done, nforce, W, t_start)
