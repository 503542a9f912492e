"""Compiled step loops of the ``lattice`` scheme, d = 1, 2, 3 (ARCHITECTURE.md §7).

Whole multi-step loops between saves run here, in numba, instead of a Python loop of numpy
calls.  :meth:`cartan.schemes.lattice.Lattice.compiled_advance` is the entry point;
``docs/performance.md`` describes what qualifies and what it gains.

Design
------
* **Groups by integer switch, media and loads as data.**  The group is a static integer
  ``gid`` over the per-point kernels of :mod:`cartan.groups` (SO(2), SE(2), SO(3), SE(3);
  :mod:`cartan.schemes._lattice_compiled_kernels`, with scalar code for SO(3) and SE(3)).  A
  qualifying medium has a quadratic potential ``U = ½Σ_α(X_α − X₀_α)ᵀC(X_α − X₀_α)``
  (``Medium.quadratic_energy``, or a :class:`~cartan.medium.QuadraticMedium` for d ≥ 2);
  loads are reduced to damping coefficients, a uniform body-frame force, a constant spatial
  field acting on positions (``ConstantFieldPotential``: ``T = (Rᵀ ρf, 0)``), end loads
  (follower or dead, on the end nodes or faces of open axes) and clamps.  They travel as
  the tuple ``P`` built by :func:`build_plan` (indices ``I_*``).
* **The grid as flat arrays.**  Nodes are numbered in C order, ``S [n, r]``, frames
  ``Phi [n, m, m]`` (or the root frame ``[1, m, m]``); the edges of axis α are the state's
  ``G_α`` flattened to ``[ne_α, m, m]`` and travel as a tuple ``Gs``.  The node shape is
  padded to three axes, so that one loop serves d = 1, 2, 3: an edge's tail and head, and a
  node's out- and in-edges along each axis, follow from its multi-index, tracked by
  increments along each chunk.
* **Passes over chunks.**  Every pass runs over fixed chunks of :data:`CHUNK` nodes or edges
  (``prange``), with per-chunk work arrays; the edge passes write each edge's force terms —
  ``dexp⁻¹(ξ)ᵀQ`` for its tail, ``dexp⁻¹(−ξ)ᵀQ`` for its head, ``Q = (cell/h_α)C(ξ/h_α − X₀_α)``
  as in ``Lattice.internal_force`` — into edge buffers, and the node passes gather them
  (``F_i = Σ_α out − in``, in the reference path's order), so that no two chunks write the
  same element.  Sums over the grid (powers, the blow-up test) add per-chunk partial sums in
  chunk order.  The results are therefore the same, bit for bit, for any number of threads;
  the threaded variants (:func:`cartan._threads.threaded_twins`, ``*__threaded``) compile
  the same passes with ``parallel=True`` and are used only when ``CARTAN_THREADS`` (or
  :func:`cartan.set_threads`) allows more than one thread and the grid has at least
  :data:`cartan._threads.MIN_NODES` nodes.
* **Fused passes.**  A ``lie-verlet`` step is three passes: the nodes (half kick, clamps and
  gauge, the palindromic free flow composed into one element ``D_i = D₁⋯D_k`` per node,
  frames ``Φ_i ← Φ_i D_i``, velocity), the edges (``G_e ← D_i⁻¹ G_e D_j`` then the force
  terms of the new ``G_e``), the nodes again (force density with loads, end loads and
  constraints, second half kick, velocity, power and blow-up partial sums).  The other
  integrators (``lie-euler``, ``forward-euler``, ``rkmk4``, ``overdamped``) reuse the same
  passes.
* **Same formulas as the reference path.**  Every step performs the operations of
  ``Integrator.step`` with ``Lattice.force``/``drift``/``velocity``/``constrain``/``powers``,
  including the trapezoidal booking of dissipated power and external work, in the same
  order, so that the compiled and the Python paths agree to round-off (≈1e-13 in the
  tests).  What differs changes round-off only: products by ``τ/m`` and ``1/w`` instead of
  quotients;
  the series of the SO(3)/SE(3) coefficients; ``dexp⁻¹(−ξ)ᵀ = Ad_Gᵀ dexp⁻¹(ξ)ᵀ`` for the
  integrators that keep G on the group (all but ``forward-euler``); one conjugation by the
  composed free flow per edge.
* **Vectorised SE(3) rods.**  ``lie-verlet`` on SE(3) with d = 1 and closed-form pieces
  (every Cosserat rod with positive inertias), and ``overdamped`` of order 1 on SE(3) with
  d = 1, run the structure-of-arrays loops of :mod:`cartan.schemes._lattice_compiled_soa`.
* **No per-step allocation.**  Work arrays are allocated once per call; the state arrays are
  updated in place.
* **Per-step blow-up test.**  After every step the loop tests what the run's guard tests
  (``cartan.simulate``): finite momentum and ``½Σ w S²/m ≤ kinetic_limit`` (or, for
  integrators without momentum, a finite configuration), and stops after the first failing
  step so that the caller can name it.

The serial helpers ``_velocity``, ``_constrain``, ``_kick``, ``_powers``, ``_unstable``,
``_end_load`` and ``_scratch`` work on the d = 1 layout.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np
from numba import prange

from .._threads import loop_threads, numba_threads, threaded_twins
from . import _lattice_compiled_soa as soa
from ._lattice_compiled_kernels import (
    ATAN_SERIES,
    ATAN_SERIES5,
    ATAN_SERIES5_X2,
    ATAN_SERIES_X2,
    GID_SE2,
    GID_SE3,
    GID_SO2,
    GID_SO3,
    KIND_GENERIC,
    KIND_ROTATION,
    KIND_SE3_TRANSLATION,
    SERIES4_THETA2,
    _ad_T,
    _chunk,
    _cinv,
    _copy_matrix,
    _dexp_slopes,
    _exp3_coeffs,
    _inline,
    _jinv_T,
    _jit,
    _next3,
    _q_block,
    _q_coeffs,
    _rot_coeffs,
    _se3_dexp_inv_T,
    _se3_log12,
    _se3_log_at,
    _sum_parts,
    _turn,
    _unravel3,
    edges_generic,
    edges_se3,
    edges_so3,
    exp_nodes,
    frames_update,
    free_flow_nodes,
    g_Ad,
    g_ad,
    g_compose,
    g_E,
    g_exp,
    g_hat,
    g_inverse,
    g_log,
)
from ._lattice_compiled_plan import (
    CHECK_CONFIGURATION,
    CHECK_MOMENTUM,
    CHUNK,
    I_AFFINE,
    I_C,
    I_CLAMPED,
    I_CONSTRAINED,
    I_D,
    I_DAMP,
    I_DIAG,
    I_ECH,
    I_END_CHUNK,
    I_END_DIV,
    I_END_FACE,
    I_END_FOLLOW,
    I_END_IDX,
    I_END_LOAD,
    I_EOFF,
    I_ESTR,
    I_FIELD,
    I_GID,
    I_H,
    I_HAS_DAMP,
    I_HAS_FIELD,
    I_HAS_POWER,
    I_HAS_UBODY,
    I_HS,
    I_LIVE,
    I_MASS,
    I_NE,
    I_PERIODIC,
    I_SCALES,
    I_SHAPE,
    I_TRACK,
    I_UBODY,
    I_W,
    I_WINV,
    I_X0,
    I_X0S,
    _group_id,
    _same_methods,
    build_plan,
)
from ._lattice_compiled_soa import lie_verlet_se3_loop, overdamped_se3_loop

__all__ = [
    "GROUP_IDS",
    "advance",
    "build_plan",
    "euler_loop",
    "finish_advance",
    "force_once",
    "lie_verlet_loop",
    "lie_verlet_se3_loop",
    "overdamped_loop",
    "overdamped_se3_loop",
    "overdamped_velocity",
    "rkmk_loop",
]

#: registered group names with compiled kernels → static group id
GROUP_IDS = {"SO2": GID_SO2, "SE2": GID_SE2, "SO3": GID_SO3, "SE3": GID_SE3}
#: the former name of :data:`KIND_ROTATION` (rotations about one body axis)
KIND_SE3_ROTATION = KIND_ROTATION

#: edge drifts: none, exact conjugation ``G ← D_i⁻¹GD_j``, naive Euler ``G ← G − D_iG + GD_j``
DRIFT_NONE = 0
DRIFT_EXACT = 1
DRIFT_EULER = 2

#: velocities a node pass sets: none, ``N = ∂K*/∂S``, the overdamped ``N = Γ⁻¹W`` (with S = 0)
VEL_NONE = 0
VEL_MOMENTUM = 1
VEL_DRAG = 2

# names kept importable from this module (other callers use them; the per-point kernels live
# in ``_lattice_compiled_kernels``)
_REEXPORTED = (I_AFFINE, I_H, I_TRACK, I_X0, g_exp, g_ad, g_compose, g_E, g_hat, g_inverse, g_log, _group_id,
               _same_methods, KIND_SE3_TRANSLATION, ATAN_SERIES, ATAN_SERIES5, ATAN_SERIES5_X2, ATAN_SERIES_X2,
               SERIES4_THETA2, _ad_T, _cinv, _exp3_coeffs, _jinv_T, _q_block, _q_coeffs, _rot_coeffs, _se3_dexp_inv_T,
               _se3_log12, _se3_log_at, _turn)


# ---------------------------------------------------------------------------- serial helpers (d = 1 layout)
@_jit
def _scratch(r, m, ne):
    """Per-call work arrays of the d = 1 helpers: three r-vectors, two r×r and three m×m
    matrices, and ``[ne, 7]``."""
    return (np.empty(r), np.empty(r), np.empty(r), np.empty((r, r)), np.empty((r, r)),
            np.empty((m, m)), np.empty((m, m)), np.empty((m, m)), np.empty((ne, 7)))


@_jit
def _end_load(gid, affine, Phi, idx, load, follower, out, M, A):
    """Body components of an end load: ``load`` (follower) or ``Ad_Rᵀ load`` (dead), R the
    rotational part of the end frame."""
    r = load.shape[0]
    if follower:
        for a in range(r):
            out[a] = load[a]
        return
    _copy_matrix(Phi[idx], A)
    if affine:
        for a in range(1, A.shape[0]):
            A[a, 0] = 0.0
    g_Ad(gid, A, M)
    for a in range(r):
        acc = 0.0
        for b in range(r):
            acc += M[b, a] * load[b]
        out[a] = acc


@_jit
def _velocity(P, S, N):
    """``N = ∂K*/∂S``: ``S/m`` on live components, zero on gauge components and clamped nodes."""
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = S.shape
    for c in prange((n + CHUNK - 1) // CHUNK):
        for i in range(*_chunk(c, n)):
            for k in range(r):
                N[i, k] = 0.0 if clamped[i] or not live[k] else S[i, k] / mass[k]


@_jit
def _constrain(P, S):
    """Zero the momentum of gauge components and clamped nodes."""
    if not P[I_CONSTRAINED]:
        return
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = S.shape
    for c in prange((n + CHUNK - 1) // CHUNK):
        for i in range(*_chunk(c, n)):
            for k in range(r):
                if clamped[i] or not live[k]:
                    S[i, k] = 0.0


@_jit
def _kick(S, W, half):
    n, r = S.shape
    for c in prange((n + CHUNK - 1) // CHUNK):
        for i in range(*_chunk(c, n)):
            for k in range(r):
                S[i, k] = S[i, k] + half * W[i, k]


@_jit
def load_powers(P, N, Phi, face, weighted, tr, M, A):
    """``(dissipated, external)`` power of the loads of the plan ``P`` at the velocity ``N``
    ``[n, r]`` and frames ``Phi`` (``Scheme.powers``): damping, body-frame uniform force and the
    end loads, each end's power weighted by ``face[q]`` when ``weighted`` (the lattice's
    ``weights/(h/2)`` on a face).  ``tr`` ``(r,)``, ``M`` ``[r, r]``, ``A`` ``[m, m]`` work."""
    if not P[I_HAS_POWER]:
        return 0.0, 0.0
    w = P[I_W]
    n, r = N.shape
    dissipated = 0.0
    external = 0.0
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(r):
                s += (-N[i, k] * damp[k]) * N[i, k]
            p += w[i] * s
        dissipated -= p
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(r):
                s += ubody[k] * N[i, k]
            p += w[i] * s
        external += p
    end_idx = P[I_END_IDX]
    p = 0.0
    for q in range(end_idx.shape[0]):
        idx = end_idx[q]
        _end_load(P[I_GID], P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A)
        s = 0.0
        for a in range(r):
            s += tr[a] * N[idx, a]
        p += face[q] * s if weighted else s
    external += p
    return dissipated, external


@_jit
def _powers(P, N, Phi, scr):
    """(dissipated, external) power of the loads at velocity N (``Scheme.powers``), d = 1."""
    return load_powers(P, N, Phi, P[I_W], False, scr[2], scr[3], scr[5])  # (the weights: not read)


@_jit
def _unstable(check, kinetic_limit, S, G, Phi, w, inv):
    """True when the state fails the run's per-step blow-up test (one edge array)."""
    if check == CHECK_MOMENTUM:
        n, r = S.shape
        tot = 0.0
        for i in range(n):
            for k in range(r):
                tot += S[i, k]
        if not np.isfinite(tot):
            return True
        if kinetic_limit < np.inf:
            K = 0.0
            for i in range(n):
                for k in range(r):
                    K += w[i] * S[i, k] * S[i, k] * inv[k]
            if not 0.5 * K <= kinetic_limit:
                return True
        return False
    if check == CHECK_CONFIGURATION:
        for x in S.ravel():
            if not np.isfinite(x):
                return True
        for x in G.ravel():
            if not np.isfinite(x):
                return True
        for x in Phi.ravel():
            if not np.isfinite(x):
                return True
    return False


# ---------------------------------------------------------------------------- work arrays
@_jit
def _chunk_scratch(nch, r, m, ne):
    """Per-chunk work arrays ``(xi, tr, q [nch, r], M, M2 [nch, r, r], A1, A2 [nch, m, m])`` and
    per-edge ones: flags ``[ne]`` (SO(3)) and logarithms ``[ne, 7]`` (SE(3))."""
    return (np.empty((nch, r)), np.empty((nch, r)), np.empty((nch, r)), np.empty((nch, r, r)),
            np.empty((nch, r, r)), np.empty((nch, m, m)), np.empty((nch, m, m)),
            np.zeros(ne if r == 3 else 0, dtype=np.int64), np.empty((ne if r == 6 else 0, 7)))


@_jit
def _work(P, n, r, m):
    """Per-call work arrays: edge buffers ``OUT, INC [Σ ne_α, r]``, chunk partial sums and the
    per-chunk scratch."""
    nch = (n + CHUNK - 1) // CHUNK
    ech = P[I_ECH][P[I_D]]
    ne = P[I_EOFF][P[I_D]]
    return (np.empty((ne, r)), np.empty((ne, r)), np.zeros((nch + ech, 4)), _chunk_scratch(max(nch, ech), r, m, ne))


# ---------------------------------------------------------------------------- edge pass
@_jit
def _edge_pass(P, Gs, D, mode, force, on_group, OUT, INC, scr):
    """Over every edge of every axis: the drift ``mode`` by the node elements ``D``, then (when
    ``force``) the edge's force terms into ``OUT``/``INC`` (:func:`edges_so3`, :func:`edges_se3`,
    :func:`edges_generic`)."""
    gid = P[I_GID]
    d = P[I_D]
    shp = P[I_SHAPE]
    ne = P[I_NE]
    ech = P[I_ECH]
    eoff = P[I_EOFF]
    X0s = P[I_X0S]
    C = P[I_C]
    diag = P[I_DIAG]
    hs = P[I_HS]
    scales = P[I_SCALES]
    n1 = shp[1]
    n2 = shp[2]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    # SO(3), SE(3) on the group: scalar kernels, with the head term as Ad_Gᵀ of the tail term
    fast = on_group and mode != DRIFT_EULER
    for c in prange(ech[d]):
        a = 0
        while c >= ech[a + 1]:
            a += 1
        G = Gs[a]
        na = shp[a]
        E1 = ne[a] if a == 1 else n1
        E2 = ne[a] if a == 2 else n2
        st = n1 * n2 if a == 0 else (n2 if a == 1 else 1)
        lo, hi = _chunk(c - ech[a], G.shape[0])
        if fast and gid == GID_SO3:
            edges_so3(G, lo, hi, a, E1, E2, n1, n2, na, st, D, mode == DRIFT_EXACT, force, X0s[a], C, diag, hs[a],
                      scales[a], OUT, INC, eoff[a], BAD)
        elif fast and gid == GID_SE3:
            edges_se3(G, lo, hi, a, E1, E2, n1, n2, na, st, D, mode == DRIFT_EXACT, force, X0s[a], C, diag, hs[a],
                      scales[a], OUT, INC, eoff[a], LOGS)
        else:
            edges_generic(gid, G, lo, hi, a, E1, E2, n1, n2, na, st, D, mode, force, X0s[a], C, hs[a], scales[a],
                          OUT, INC, eoff[a], XI[c], TR[c], QV[c], M1[c], M2[c], A1[c], A2[c])


# ---------------------------------------------------------------------------- node passes
@_jit
def _node_pass(P, OUT, INC, Phi, S, N, W, gam, half, gather, close, kick, constrain, vmode, inv, PART, scr):
    """One pass over the nodes, chunk by chunk.

    ``gather``: ``W = Lattice.force`` from the edge terms in ``OUT``/``INC`` — the internal
    force ``F_i = Σ_α (out-edge term − in-edge term)`` over the weight, damping at ``N``
    (omitted for ``vmode = VEL_DRAG``: W at N = 0), body-frame force, constant field, end
    loads, then zero on clamped nodes and gauge components.
    ``close``: per node, ``S += half·W`` (``kick``), clamps and gauge (``constrain``), the
    velocity ``vmode``, and the chunk's partial sums of the damping power, the external
    power, ΣS and Σw S²/m.  Returns ``(dissipated power, external power, ΣS, Σw S²/m)``
    (zeros without ``close``).
    """
    gid = P[I_GID]
    d = P[I_D]
    shp = P[I_SHAPE]
    ne = P[I_NE]
    per = P[I_PERIODIC]
    estr = P[I_ESTR]
    eoff = P[I_EOFF]
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
    field = P[I_FIELD]
    has_power = P[I_HAS_POWER]
    affine = P[I_AFFINE]
    end_idx = P[I_END_IDX]
    end_load = P[I_END_LOAD]
    end_follow = P[I_END_FOLLOW]
    end_div = P[I_END_DIV]
    end_face = P[I_END_FACE]
    end_chunk = P[I_END_CHUNK]
    damp_force = has_damp and vmode != VEL_DRAG
    writes_S = kick or constrain or vmode == VEL_DRAG
    ks = field.shape[0]
    n, r = S.shape
    n1 = shp[1]
    n2 = shp[2]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    nch = (n + CHUNK - 1) // CHUNK
    for c in prange(nch):
        lo, hi = _chunk(c, n)
        tr = TR[c]
        if gather:
            # F_i = Σ_α (term of the edge out of i − term of the edge into i), axis by axis
            for k in range(hi - lo):
                for q in range(r):
                    W[lo + k, q] = 0.0
            for a in range(d):
                es0, es1, es2 = estr[a, 0], estr[a, 1], estr[a, 2]
                sa = estr[a, a]
                nea = ne[a]
                wrap = (nea - 1) * sa if per[a] else -1
                off = eoff[a]
                i0, i1, i2 = _unravel3(lo, n1, n2)
                for k in range(hi - lo):
                    i = lo + k
                    ia = i0 if a == 0 else (i1 if a == 1 else i2)
                    base = off + i0 * es0 + i1 * es1 + i2 * es2
                    if ia < nea:
                        for q in range(r):
                            W[i, q] += OUT[base, q]
                    if ia > 0:
                        for q in range(r):
                            W[i, q] += -INC[base - sa, q]
                    elif wrap >= 0:
                        for q in range(r):
                            W[i, q] += -INC[base + wrap, q]
                    i0, i1, i2 = _next3(i0, i1, i2, n1, n2)
            for k in range(hi - lo):
                i = lo + k
                wi = winv[i]
                for q in range(r):
                    W[i, q] = W[i, q] * wi
                if damp_force:
                    for q in range(r):
                        W[i, q] += -N[i, q] * damp[q]
                if has_ubody:
                    for q in range(r):
                        W[i, q] += ubody[q]
                if has_field:
                    for q in range(ks):
                        acc = 0.0
                        for b in range(ks):
                            acc += Phi[i, b + 1, q + 1] * field[b]
                        W[i, q] += acc
            for q in range(end_chunk[c], end_chunk[c + 1]):
                i = end_idx[q]
                _end_load(gid, affine, Phi, i, end_load[q], end_follow[q], tr, M1[c], A1[c])
                for k in range(r):
                    W[i, k] += tr[k] / end_div[q]
            if constrained:
                for i in range(lo, hi):
                    for k in range(r):
                        if clamped[i] or not live[k]:
                            W[i, k] = 0.0
        if close:
            pd = 0.0
            pe = 0.0
            tot = 0.0
            kin = 0.0
            for i in range(lo, hi):
                sd = 0.0
                se = 0.0
                sk = 0.0
                fixed = clamped[i]
                for k in range(r):
                    s = S[i, k]
                    if kick and damp_force and live[k] and not fixed:
                        # lie-verlet's closing kick, implicit in the damping (trapezoidal):
                        # (1 + ½Δt c/m) S⁺ = S½ + ½Δt W(N = 0), W(N = 0) = W + cN
                        w0 = W[i, k] + N[i, k] * damp[k]
                        s = (s + half * w0) / (1.0 + half * damp[k] / mass[k])
                        W[i, k] = w0 - damp[k] * (s / mass[k])
                    elif kick:
                        s = s + half * W[i, k]
                    if constrain and (fixed or not live[k]):
                        s = 0.0
                    if vmode == VEL_DRAG:
                        s = 0.0
                        N[i, k] = 0.0 if fixed or not live[k] else W[i, k] / gam[k]
                    elif vmode == VEL_MOMENTUM:
                        N[i, k] = 0.0 if fixed or not live[k] else s / mass[k]
                    if writes_S:
                        S[i, k] = s
                    tot += s
                    sk += s * s * inv[k]
                    if has_power:
                        v = N[i, k]
                        if has_damp:
                            sd += (-v * damp[k]) * v
                        if has_ubody:
                            se += ubody[k] * v
                wi = wts[i]
                pd += wi * sd
                pe += wi * se
                kin += wi * sk
            if has_power:
                for q in range(end_chunk[c], end_chunk[c + 1]):
                    i = end_idx[q]
                    _end_load(gid, affine, Phi, i, end_load[q], end_follow[q], tr, M1[c], A1[c])
                    s = 0.0
                    for k in range(r):
                        s += tr[k] * N[i, k]
                    pe += end_face[q] * s
            PART[c, 0] = pd
            PART[c, 1] = pe
            PART[c, 2] = tot
            PART[c, 3] = kin
    if not close:
        return 0.0, 0.0, 0.0, 0.0
    return _sum_parts(PART, nch)


@_jit
def _lv_drift_pass(P, S, W, half, D, Phi, seq_mask, seq_frac, fac, kinds, axes, dt, velocity, N, scr):
    """First half of a ``lie-verlet`` step, per node: ``S += half·W``, constraints, the exact
    free flow composed into ``D_i`` (:func:`free_flow_nodes`), constraints, the frame
    ``Φ_i ← Φ_i D_i`` (every node, or the root) and, when ``velocity``, ``N = ∂K*/∂S``."""
    gid = P[I_GID]
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = S.shape
    nf = Phi.shape[0]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    for c in prange((n + CHUNK - 1) // CHUNK):
        lo, hi = _chunk(c, n)
        for k in range(hi - lo):
            i = lo + k
            for q in range(r):
                v = S[i, q] + half * W[i, q]
                S[i, q] = 0.0 if clamped[i] or not live[q] else v
        free_flow_nodes(gid, S, D, lo, hi, clamped, mass, seq_mask, seq_frac, fac, kinds, axes, dt,
                        XI[c], TR[c], M1[c], A1[c], A2[c])
        for k in range(hi - lo):
            i = lo + k
            for q in range(r):
                if clamped[i] or not live[q]:
                    S[i, q] = 0.0
                if velocity:
                    N[i, q] = 0.0 if clamped[i] or not live[q] else S[i, q] / mass[q]
        frames_update(gid, Phi, D, lo, min(hi, nf), A1[c])


@_jit
def _exp_pass(P, N, tau, D, Phi, scr):
    """``D_i = exp(τN_i)`` and the frames ``Φ_i ← Φ_i D_i`` (every node, or the root)."""
    gid = P[I_GID]
    n = N.shape[0]
    nf = Phi.shape[0]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    for c in prange((n + CHUNK - 1) // CHUNK):
        lo, hi = _chunk(c, n)
        exp_nodes(gid, tau, N, D, lo, hi, XI[c])
        frames_update(gid, Phi, D, lo, min(hi, nf), A1[c])


@_jit
def _lie_euler_pass(P, S, N, W, dt, D, Phi, scr):
    """Per node: ``D_i = exp(ΔtN_i)``, ``S_i ← Ad*_{D_i}S_i + 𝓔(Δt, N_i)ᵀW_i``, ``Φ_i ← Φ_i D_i``."""
    gid = P[I_GID]
    n, r = S.shape
    nf = Phi.shape[0]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    for c in prange((n + CHUNK - 1) // CHUNK):
        lo, hi = _chunk(c, n)
        tr, M, ME = TR[c], M1[c], M2[c]
        exp_nodes(gid, dt, N, D, lo, hi, XI[c])
        for k in range(hi - lo):
            i = lo + k
            g_Ad(gid, D[i], M)
            g_E(gid, dt, N[i], ME)
            for a in range(r):
                u = 0.0
                v = 0.0
                for b in range(r):
                    u += M[b, a] * S[i, b]
                    v += ME[b, a] * W[i, b]
                tr[a] = u + v
            for a in range(r):
                S[i, a] = tr[a]
        frames_update(gid, Phi, D, lo, min(hi, nf), A1[c])


@_jit
def _euler_pass(P, S, N, W, dt, D, Phi, scr):
    """``forward-euler`` per node: ``S_i += Δt(ad_{N_i}ᵀS_i + W_i)``, ``D_i = ΔtN̂_i``,
    ``Φ_i ← Φ_i + Φ_i D_i``."""
    gid = P[I_GID]
    n, r = S.shape
    m = D.shape[1]
    nf = Phi.shape[0]
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    for c in prange((n + CHUNK - 1) // CHUNK):
        xi = XI[c]
        tr = TR[c]
        M = M1[c]
        A = A1[c]
        for i in range(*_chunk(c, n)):
            g_ad(gid, N[i], M)
            for a in range(r):
                acc = 0.0
                for b in range(r):
                    acc += M[b, a] * S[i, b]
                tr[a] = acc + W[i, a]
            for k in range(r):
                xi[k] = dt * N[i, k]
            g_hat(gid, xi, D[i])
            for k in range(r):
                S[i, k] = S[i, k] + dt * tr[k]
            if i < nf:
                for a in range(m):
                    for b in range(m):
                        acc = 0.0
                        for q in range(m):
                            acc += Phi[i, a, q] * D[i, q, b]
                        A[a, b] = Phi[i, a, b] + acc
                _copy_matrix(A, Phi[i])


@_jit
def _finite_pass(P, S, Gs, Phi, PART):
    """True when any entry of ``S``, the edges or the frames is not finite (``x − x ≠ 0``: NaN
    for ±inf and NaN), counted per chunk."""
    d = P[I_D]
    ech = P[I_ECH]
    n, r = S.shape
    m = Phi.shape[1]
    nf = Phi.shape[0]
    nch = (n + CHUNK - 1) // CHUNK
    for c in prange(nch + ech[d]):
        acc = 0
        if c < nch:
            lo, hi = _chunk(c, n)
            flat = S.reshape(n * r)
            base = max(lo * r, 0)  # (stated non-negative: no negative-index test, vectorised)
            for k in range((hi - lo) * r):
                acc += flat[base + k] - flat[base + k] != 0.0
            flat = Phi.reshape(nf * m * m)
            base = max(lo * m * m, 0)
            for k in range(max(min(hi, nf) - lo, 0) * m * m):
                acc += flat[base + k] - flat[base + k] != 0.0
        else:
            a = 0
            while c - nch >= ech[a + 1]:
                a += 1
            G = Gs[a]
            lo, hi = _chunk(c - nch - ech[a], G.shape[0])
            flat = G.reshape(G.shape[0] * m * m)
            base = max(lo * m * m, 0)
            for k in range((hi - lo) * m * m):
                acc += flat[base + k] - flat[base + k] != 0.0
        PART[c, 0] = acc
    for q in range(nch + ech[d]):
        if PART[q, 0] != 0.0:
            return True
    return False


@_jit
def _fails(P, check, kinetic_limit, tot, kin, S, Gs, Phi, PART):
    """The per-step blow-up test, from the partial sums ``tot = ΣS``, ``kin = Σw S²/m`` of the
    closing node pass (momentum) or from a pass over the configuration."""
    if check == CHECK_MOMENTUM:
        if not np.isfinite(tot):
            return True
        return kinetic_limit < np.inf and not 0.5 * kin <= kinetic_limit
    if check == CHECK_CONFIGURATION:
        return _finite_pass(P, S, Gs, Phi, PART)
    return False


@_jit
def _copy_pass(Gs, Gx, Phi, Phx):
    """``Gx ← Gs`` (every axis) and ``Phx ← Phi``."""
    for a in range(len(Gs)):
        src = Gs[a]
        dst = Gx[a]
        ne = src.shape[0]
        for c in prange((ne + CHUNK - 1) // CHUNK):
            for e in range(*_chunk(c, ne)):
                _copy_matrix(src[e], dst[e])
    for i in range(Phi.shape[0]):
        _copy_matrix(Phi[i], Phx[i])


@_jit
def _rk_combine(coef, nj, K, dt, base, with_base, out):
    """``out = [base +] Σ_{j < nj, coef_j ≠ 0} Δt coef_j K_j`` (the Runge–Kutta sums, in the
    reference path's order)."""
    n, r = out.shape
    for c in prange((n + CHUNK - 1) // CHUNK):
        for i in range(*_chunk(c, n)):
            for k in range(r):
                acc = 0.0
                for j in range(nj):
                    if coef[j] != 0.0:
                        acc = acc + dt * coef[j] * K[j, i, k]
                out[i, k] = base[i, k] + acc if with_base else acc


@_jit
def _rk_dexp_pass(P, sigma, Nst, ksig, st, scr):
    """``ksig[st, i] = dexp⁻¹(−σ_i) Nst_i``."""
    n = Nst.shape[0]
    TR, M1 = scr[1], scr[3]
    for c in prange((n + CHUNK - 1) // CHUNK):
        lo, hi = _chunk(c, n)
        _dexp_slopes(P[I_GID], sigma[lo:hi], Nst[lo:hi], ksig[st, lo:hi], TR[c], M1[c])


@_jit
def _rk_adT_pass(P, Nst, Sst, W, kS, st, scr):
    """``kS[st, i] = ad_{N_i}ᵀ S_i + W_i``."""
    gid = P[I_GID]
    n, r = Nst.shape
    XI, TR, QV, M1, M2, A1, A2, BAD, LOGS = scr
    for c in prange((n + CHUNK - 1) // CHUNK):
        M = M1[c]
        for i in range(*_chunk(c, n)):
            g_ad(gid, Nst[i], M)
            for a in range(r):
                acc = 0.0
                for b in range(r):
                    acc += M[b, a] * Sst[i, b]
                kS[st, i, a] = acc + W[i, a]


# ---------------------------------------------------------------------------- force, drift
@_jit
def _force(P, Gs, Phi, S, N, W, gam, vmode, on_group, D, OUT, INC, PART, scr):
    """``W = Lattice.force(state, N, t)``; with ``vmode = VEL_DRAG`` the overdamped velocity
    ``N = Γ⁻¹W(N = 0)`` as well (and S = 0).  ``D`` is not read."""
    _edge_pass(P, Gs, D, DRIFT_NONE, True, on_group, OUT, INC, scr)
    # (the partial sums of a closing pass are not used here: ``gam`` stands in for 1/m)
    _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, True, vmode == VEL_DRAG, False, False, vmode, gam, PART, scr)


@_jit
def _exp_drift_nd(P, Gs, Phi, N, tau, D, OUT, INC, scr):
    """Exact drift ``Φ ← Φ exp(τN)`` (``Lattice.drift(exact=True)``); ``OUT``, ``INC`` are not read."""
    _exp_pass(P, N, tau, D, Phi, scr)
    _edge_pass(P, Gs, D, DRIFT_EXACT, False, True, OUT, INC, scr)


# ---------------------------------------------------------------------------- loops
@_inline
def _book(dt, dissipated, external, p0d, p0e, p1d, p1e):
    """Trapezoidal booking of the powers over a step (``Integrator.step``)."""
    return dissipated + 0.5 * dt * (p0d + p1d), external + 0.5 * dt * (p0e + p1e)


@_jit
def lie_verlet_loop(P, S, Gs, Phi, W, have_force, velocity_free, seq_mask, seq_frac, fac, kinds, axes,
                    t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``LieVerlet`` (half kick, exact split free flow, half kick).

    ``W`` holds the force at the current state when ``have_force`` (first-same-as-last) and
    the force at the final state on return.  ``seq_mask``, ``seq_frac``, ``fac``, ``kinds``,
    ``axes``: the palindromic pieces (see :func:`free_flow_node`).  Returns
    ``(steps done, force evaluations, t, dissipated, external)``.
    """
    n, r = S.shape
    m = Phi.shape[1]
    N = np.zeros((n, r))
    D = np.empty((n, m, m))
    gam = np.ones(r)
    OUT, INC, PART, scr = _work(P, n, r, m)
    # N enters the force only through damping, and the bookkeeping only through the powers
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    vmode = VEL_MOMENTUM if need_N else VEL_NONE
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _velocity(P, S, N)
    p0d, p0e, _, _ = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, False, VEL_NONE, inv,
                                PART, scr)
    done = 0
    for _ in range(nsteps):
        if not (have_force and velocity_free):
            _force(P, Gs, Phi, S, N, W, gam, VEL_NONE, True, D, OUT, INC, PART, scr)
            nforce += 1
        _lv_drift_pass(P, S, W, half, D, Phi, seq_mask, seq_frac, fac, kinds, axes, dt, need_N, N, scr)
        _edge_pass(P, Gs, D, DRIFT_EXACT, True, True, OUT, INC, scr)
        nforce += 1
        have_force = True
        p1d, p1e, tot, kin = _node_pass(P, OUT, INC, Phi, S, N, W, gam, half, True, True, True, True, vmode, inv,
                                        PART, scr)
        t = t + dt
        dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _fails(P, check, kinetic_limit, tot, kin, S, Gs, Phi, PART):
            break
    return done, nforce, t, dissipated, external


@_jit
def euler_loop(P, S, Gs, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv, geometric):
    """``nsteps`` steps of ``LieEuler`` (``geometric``: ``S⁺ = Ad*_{exp ΔtN}S + 𝓔(Δt,N)ᵀW``,
    ``Φ⁺ = Φ exp(ΔtN)``) or of ``ForwardEuler`` (``Φ += ΔtΦN̂``, edges ``G += Δt(−N̂_iG + GN̂_j)``,
    ``S += Δt(ad_NᵀS + W)``).  Returns ``(steps done, t, dissipated, external)``."""
    n, r = S.shape
    m = Phi.shape[1]
    N = np.empty((n, r))
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    gam = np.ones(r)
    OUT, INC, PART, scr = _work(P, n, r, m)
    _velocity(P, S, N)
    p0d, p0e, _, _ = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, False, VEL_NONE, inv,
                                PART, scr)
    done = 0
    for _ in range(nsteps):
        _force(P, Gs, Phi, S, N, W, gam, VEL_NONE, geometric, D, OUT, INC, PART, scr)
        if geometric:
            _lie_euler_pass(P, S, N, W, dt, D, Phi, scr)
            _edge_pass(P, Gs, D, DRIFT_EXACT, False, True, OUT, INC, scr)
        else:
            _euler_pass(P, S, N, W, dt, D, Phi, scr)
            _edge_pass(P, Gs, D, DRIFT_EULER, False, False, OUT, INC, scr)
        p1d, p1e, tot, kin = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, True, VEL_MOMENTUM,
                                        inv, PART, scr)
        t = t + dt
        dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _fails(P, check, kinetic_limit, tot, kin, S, Gs, Phi, PART):
            break
    return done, t, dissipated, external


@_jit
def overdamped_velocity(P, Gs, Phi, N, gam):
    """``N = Γ⁻¹W(N = 0)`` at the current state (the overdamped integrator's velocity)."""
    n, r = N.shape
    m = Phi.shape[1]
    OUT, INC, PART, scr = _work(P, n, r, m)
    _force(P, Gs, Phi, np.zeros((n, r)), N, np.empty((n, r)), gam, VEL_DRAG, True, Phi, OUT, INC, PART, scr)


@_jit
def overdamped_loop(P, S, Gs, Phi, N, gam, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``Overdamped(order=1)``: ``Φ ← Φ exp(ΔtN)``, ``N = Γ⁻¹W(N = 0)``, S = 0.

    ``N`` holds the velocity of the current state on entry and of the final state on return.
    Returns ``(steps done, t, dissipated, external)``.
    """
    n, r = S.shape
    m = Phi.shape[1]
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    OUT, INC, PART, scr = _work(P, n, r, m)
    p0d, p0e, _, _ = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, False, VEL_NONE, inv,
                                PART, scr)
    done = 0
    for _ in range(nsteps):
        _exp_pass(P, N, dt, D, Phi, scr)
        _edge_pass(P, Gs, D, DRIFT_EXACT, True, True, OUT, INC, scr)
        p1d, p1e, tot, kin = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, True, True, False, False, VEL_DRAG,
                                        inv, PART, scr)
        t = t + dt
        dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _fails(P, check, kinetic_limit, tot, kin, S, Gs, Phi, PART):
            break
    return done, t, dissipated, external


@_jit
def rkmk_loop(P, S, Gs, Gst, Phi, Phist, N, gam, dynamics, A, b, t, dt, nsteps, dissipated, external, check,
              kinetic_limit, inv):
    """``nsteps`` explicit Runge–Kutta–Munthe-Kaas steps with tableau ``(A, b)``.

    ``dynamics``: ``rkmk4`` (S by the same tableau on ``Ṡ = ad_NᵀS + W``, N = velocity(S));
    otherwise the overdamped flow of order 2 (N = Γ⁻¹W(N = 0), S = 0), with ``N`` the drift
    velocity of the current state on entry and of the final state on return.  ``Gst``,
    ``Phist``: work arrays shaped like ``Gs``, ``Phi`` for the stages.
    Returns ``(steps done, t, dissipated, external)``.
    """
    n, r = S.shape
    m = Phi.shape[1]
    s = b.shape[0]
    ksig = np.empty((s, n, r))
    kS = np.empty((s, n, r))
    sigma = np.empty((n, r))
    Sst = np.zeros((n, r))
    Nst = np.empty((n, r))
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    OUT, INC, PART, scr = _work(P, n, r, m)
    if dynamics:
        _velocity(P, S, N)
    p0d, p0e, _, _ = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, False, VEL_NONE, inv,
                                PART, scr)
    done = 0
    for _ in range(nsteps):
        for st in range(s):
            moved = False
            for j in range(st):
                if A[st, j] != 0.0:
                    moved = True
            _rk_combine(A[st], st, ksig, dt, sigma, False, sigma)
            if dynamics:
                _rk_combine(A[st], st, kS, dt, S, True, Sst)
            Gx, Phx = Gs, Phi
            if moved:
                _copy_pass(Gs, Gst, Phi, Phist)
                _exp_drift_nd(P, Gst, Phist, sigma, 1.0, D, OUT, INC, scr)
                Gx, Phx = Gst, Phist
            if dynamics:
                _velocity(P, Sst, Nst)
            elif st == 0:
                Nst[:] = N
            else:
                _force(P, Gx, Phx, Sst, Nst, W, gam, VEL_DRAG, True, D, OUT, INC, PART, scr)
            _rk_dexp_pass(P, sigma, Nst, ksig, st, scr)
            if dynamics:
                _force(P, Gx, Phx, Sst, Nst, W, gam, VEL_NONE, True, D, OUT, INC, PART, scr)
                _rk_adT_pass(P, Nst, Sst, W, kS, st, scr)
        _rk_combine(b, s, ksig, dt, sigma, False, sigma)
        _exp_pass(P, sigma, 1.0, D, Phi, scr)
        if dynamics:
            _edge_pass(P, Gs, D, DRIFT_EXACT, False, True, OUT, INC, scr)
            _rk_combine(b, s, kS, dt, S, True, S)
            p1d, p1e, tot, kin = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, False, True, False, True,
                                            VEL_MOMENTUM, inv, PART, scr)
        else:
            _edge_pass(P, Gs, D, DRIFT_EXACT, True, True, OUT, INC, scr)
            p1d, p1e, tot, kin = _node_pass(P, OUT, INC, Phi, S, N, W, gam, 0.0, True, True, False, False, VEL_DRAG,
                                            inv, PART, scr)
        t = t + dt
        dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _fails(P, check, kinetic_limit, tot, kin, S, Gs, Phi, PART):
            break
    return done, t, dissipated, external


@_jit
def _force_once(P, Gs, Phi, N, W, on_group):
    n, r = W.shape
    m = Phi.shape[1]
    OUT, INC, PART, scr = _work(P, n, r, m)
    _force(P, Gs, Phi, np.zeros((n, r)), N, W, np.ones(r), VEL_NONE, on_group, Phi, OUT, INC, PART, scr)


# ---------------------------------------------------------------------------- threaded variants
_LOOPS = ("lie_verlet_loop", "euler_loop", "overdamped_loop", "rkmk_loop")
#: the threaded variants of the passes and of the loops that call them (``prange`` in parallel)
THREADED = threaded_twins(globals(), (
    "_velocity", "_constrain", "_kick", "_edge_pass", "_node_pass", "_lv_drift_pass", "_exp_pass",
    "_lie_euler_pass", "_euler_pass", "_finite_pass", "_fails", "_copy_pass", "_rk_combine", "_rk_dexp_pass",
    "_rk_adT_pass", "_force", "_exp_drift_nd", *_LOOPS,
))
SERIAL = {name: globals()[name] for name in _LOOPS}


# ---------------------------------------------------------------------------- Python glue
def _writable(a: np.ndarray) -> np.ndarray:
    """``a`` itself when it is a writable C-contiguous float64 array, else such a copy."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


def _edge_tuple(G) -> tuple:
    """A tuple of flattened ``[ne, m, m]`` edge arrays from one array or a sequence of them."""
    arrays = (G,) if isinstance(G, np.ndarray) else tuple(G)
    return tuple(np.ascontiguousarray(g, dtype=float).reshape(-1, g.shape[-2], g.shape[-1]) for g in arrays)


def force_once(P: tuple, G, Phi: np.ndarray, N: np.ndarray, W: np.ndarray, on_group: bool) -> None:
    """One force evaluation ``W`` ``[n, r]`` (filled in place) at the edges ``G`` (one array for
    d = 1, or one per axis), frames ``Phi [n or 1, m, m]`` and velocity ``N [n, r]``; compared
    with ``Lattice.force`` by the tests."""
    _force_once(P, _edge_tuple(G), Phi, np.ascontiguousarray(N, dtype=float), W, bool(on_group))


def _exp_drift(P: tuple, G, Phi: np.ndarray, N: np.ndarray, tau: float, D: np.ndarray, scr=None) -> None:
    """Exact drift ``Φ ← Φ exp(τN)`` in place: edges ``G`` (one C-contiguous array, d = 1, or
    one per axis), frames ``Phi``, node elements ``D [n, m, m]`` (work); ``scr`` is unused."""
    n, r = N.shape
    nch = max((n + CHUNK - 1) // CHUNK, int(P[I_ECH][P[I_D]]))
    Gs = (G,) if isinstance(G, np.ndarray) else tuple(G)
    Gs = tuple(g.reshape(-1, g.shape[-2], g.shape[-1]) for g in Gs)
    empty = np.empty((0, r))
    _exp_drift_nd(P, Gs, Phi, np.ascontiguousarray(N, dtype=float), float(tau), D, empty, empty,
                  _chunk_scratch(nch, r, Phi.shape[-1], 0))


def _lie_verlet_sequence(integrator, scheme, gid: int, dt: float, cache: dict):
    """``LieVerlet._sequence`` as arrays, cached per Δt in ``cache`` (the sequence depends on
    the scheme's group and live components only): component masks, fractions of Δt, ``τ/m``
    per component, and (kind, body axis) per piece (:data:`KIND_ROTATION` about one body axis
    on SO(3) and SE(3), :data:`KIND_SE3_TRANSLATION`, else :data:`KIND_GENERIC`)."""
    key = ("lie-verlet", dt)
    if key in cache:
        return cache[key]
    seq = integrator._sequence(scheme)
    r = scheme.group.dim
    mask = np.zeros((len(seq), r), dtype=np.bool_)
    frac = np.empty(len(seq))
    kind = np.zeros((len(seq), 2), dtype=np.int64)
    for p, (P, f) in enumerate(seq):
        idx = sorted(int(i) for i in np.flatnonzero(np.diag(P)))
        mask[p, idx] = True
        frac[p] = f
        if gid == GID_SE3 and idx == [0, 1, 2]:
            kind[p] = (KIND_SE3_TRANSLATION, 0)
        elif gid == GID_SE3 and len(idx) == 1 and idx[0] >= 3:
            kind[p] = (KIND_ROTATION, idx[0] - 3)
        elif gid == GID_SO3 and len(idx) == 1:
            kind[p] = (KIND_ROTATION, idx[0])
    fac = np.where(mask, (frac * dt)[:, None] / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    if len(cache) > 16:
        cache.clear()
    cache[key] = (mask, frac, np.ascontiguousarray(fac), kind)
    return cache[key]


def _soa_workspace(cache: dict, n: int, ne: int, nf: int, nblocks: int) -> tuple:
    """The work arrays of the structure-of-arrays loops (:func:`~cartan.schemes._lattice_compiled_soa.workspace`),
    kept in the scheme's cache between calls so that a run touches their pages once (the
    latest size only)."""
    key = (n, ne, nf, nblocks)
    held = cache.get("soa_work")
    if held is None or held[0] != key:
        held = cache["soa_work"] = (key, soa.workspace(n, ne, nf, nblocks))
    return held[1]


def advance(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """Run up to ``nsteps`` steps of ``integrator`` on ``state`` in compiled code (see
    :meth:`cartan.schemes.lattice.Lattice.compiled_advance`); False, touching nothing, when
    the integrator is not supported."""
    from ..compiled.tableaux import TABLEAUX as _TABLEAUX
    supported = compiled_kind(scheme, integrator)
    if supported is None:
        return False
    kind, gam = supported
    d = scheme.grid.d
    keys = [scheme._key(a) for a in range(d)]
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {*keys, frame_key}:
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    dt = float(dt)
    n, r, m = scheme.grid.size, scheme.group.dim, state.arrays[frame_key].shape[-1]
    S = state.S = _writable(state.S)
    S2 = S.reshape(n, r)
    Gs = []
    for key in keys:
        G = state.arrays[key] = _writable(state.arrays[key])
        Gs.append(G.reshape(-1, m, m))
    Gs = tuple(Gs)
    Phi = state.arrays[frame_key] = _writable(state.arrays[frame_key])
    Phi3 = Phi.reshape(-1, m, m)
    nstep0, stamp, t0, diss, ext, check, limit, cache, inv = advance_context(scheme, integrator, state,
                                                                             kinetic_limit)
    threads = loop_threads(n)
    loops = THREADED if threads > 1 else SERIAL
    W = None
    with numba_threads(threads) if threads > 1 else contextlib.nullcontext():
        if kind == "lie-verlet":
            velocity_free, have, W = lie_verlet_force(scheme, integrator, stamp, S)
            mask, frac, fac, kinds = _lie_verlet_sequence(integrator, scheme, plan[I_GID], dt, cache)
            if plan[I_GID] == GID_SE3 and d == 1 and np.all(kinds[:, 0] != KIND_GENERIC):
                loop = soa.THREADED["lie_verlet_se3_loop"] if threads > 1 else soa.lie_verlet_se3_loop
                done, nforce, t, diss, ext = loop(
                    plan, S2, Gs[0], Phi3, W.reshape(n, r), have, bool(velocity_free), fac,
                    np.ascontiguousarray(kinds[:, 0]), np.ascontiguousarray(kinds[:, 1]), t0, dt, nsteps, diss, ext,
                    check, limit, inv, soa.THREAD_BLOCK_CHUNKS,
                    _soa_workspace(cache, n, Gs[0].shape[0], Phi3.shape[0], threads), threads)
            else:
                done, nforce, t, diss, ext = loops["lie_verlet_loop"](
                    plan, S2, Gs, Phi3, W.reshape(n, r), have, bool(velocity_free), mask, frac, fac,
                    np.ascontiguousarray(kinds[:, 0]), np.ascontiguousarray(kinds[:, 1]), t0, dt, nsteps, diss, ext,
                    check, limit, inv)
        elif kind == "lie-euler" or kind == "forward-euler":
            done, t, diss, ext = loops["euler_loop"](plan, S2, Gs, Phi3, t0, dt, nsteps, diss, ext, check, limit, inv,
                                                     kind == "lie-euler")
            nforce = done
        else:
            dynamics = kind == "rkmk4"
            order = 4 if dynamics else integrator.order
            hit, N = rkmk_velocity(integrator, stamp, S, dynamics)
            if not dynamics:  # from the state alone (rkmk_velocity)
                overdamped_velocity(plan, Gs, Phi3, N.reshape(n, r), gam)
            N2 = N.reshape(n, r)
            if order == 1 and plan[I_GID] == GID_SE3 and d == 1:
                loop = soa.THREADED["overdamped_se3_loop"] if threads > 1 else soa.overdamped_se3_loop
                done, t, diss, ext = loop(plan, S2, Gs[0], Phi3, N2, gam, t0, dt, nsteps, diss, ext, check, inv,
                                          _soa_workspace(cache, n, Gs[0].shape[0], Phi3.shape[0], threads), threads)
            elif order == 1:
                done, t, diss, ext = loops["overdamped_loop"](plan, S2, Gs, Phi3, N2, gam, t0, dt, nsteps, diss, ext,
                                                              check, limit, inv)
            else:
                A, b, _ = _TABLEAUX[order]
                done, t, diss, ext = loops["rkmk_loop"](
                    plan, S2, Gs, tuple(np.empty_like(g) for g in Gs), Phi3, np.empty_like(Phi3), N2,
                    np.ones(r) if gam is None else gam, dynamics, np.ascontiguousarray(A, dtype=float),
                    np.ascontiguousarray(b, dtype=float), t0, dt, nsteps, diss, ext, check, limit, inv)
            nforce = rkmk_books(integrator, state, dynamics, order, done, hit, t, nstep0, N)
    return finish_advance(integrator, state, t, diss, ext, nstep0, done, nforce, W, t_start)


def compiled_kind(scheme, integrator) -> tuple | None:
    """``(integrator name, drag Γ or None)`` when the compiled loops run ``integrator``, else
    None: ``lie-verlet``, ``lie-euler``, ``forward-euler``, ``rkmk4``, and ``overdamped`` of
    order 1 or 2 with a positive drag on every live component (without, the reference path
    raises the error)."""
    # the built-in integrators (known by name; the loops below are their steps), not subclasses
    kind = integrator.name if type(integrator).__module__ == "cartan.integrators.explicit" else None
    if kind not in ("lie-verlet", "lie-euler", "forward-euler", "overdamped", "rkmk4"):
        return None  # (kinematic runs the generated RKMK loop with its compiled velocity)
    gam = None
    if kind == "overdamped":
        gam = np.asarray(scheme.drag(), dtype=float)
        if np.any(scheme.live & ~(gam > 0)) or integrator.order not in (1, 2):
            return None
    return kind, gam


def lie_verlet_force(scheme, integrator, stamp: tuple, S: np.ndarray) -> tuple[bool, bool, np.ndarray]:
    """``(velocity_free, have, W)`` for a compiled ``lie-verlet`` loop: whether no force depends
    on the velocity, whether the integrator's first-same-as-last force belongs to the state
    (``stamp`` of :func:`advance_context`), and that force (a C-ordered copy shaped like
    ``S``) or zeros."""
    velocity_free = scheme.problem.velocity_free
    fsal = integrator._fsal
    have = bool(velocity_free and fsal is not None and fsal[0] == stamp)
    W = np.array(fsal[1], dtype=float, order="C").reshape(S.shape) if have else np.zeros_like(S)
    return velocity_free, have, W


def rkmk_velocity(integrator, stamp: tuple, S: np.ndarray, dynamics: bool) -> tuple[bool, np.ndarray]:
    """``(hit, N)`` for a compiled RKMK or overdamped loop: zeros for ``rkmk4`` (``dynamics``);
    for ``overdamped`` an empty array for the caller to fill with the velocity of the state
    computed by the compiled kernels (:func:`overdamped_velocity`), and ``hit`` when the
    integrator holds a velocity for the state (``Overdamped.velocity``, e.g. from a saved
    frame), which the reference path would reuse — for the force count only.

    That velocity is not taken: it comes from the reference path, which agrees with the
    compiled kernels to round-off only, and a restarted run, whose state comes from a file,
    has none.  Computed from the state alone — bit for bit the velocity the loops carry from
    one step to the next — the steps do not depend on how they are grouped into calls, and a
    restart continues a run bit for bit."""
    if dynamics:
        return False, np.zeros_like(S)
    cached = integrator._cache
    return bool(cached is not None and cached[0] == stamp), np.empty_like(S)


def rkmk_books(integrator, state, dynamics: bool, order: int, done: int, hit: bool, t: float, nstep0: int,
               N: np.ndarray) -> int:
    """The force evaluations of ``done`` RKMK or overdamped steps as the reference path counts
    them (``rkmk4`` 4 per step; ``overdamped`` the velocity of the state after every step, which
    is also the first stage of the next, plus the second stage of order 2, and the velocity of
    the initial state unless the integrator's cache holds it (``hit``, as :func:`rkmk_velocity`
    reports it)), and the overdamped velocity ``N`` of the final state cached on the integrator."""
    if dynamics:
        return 4 * done
    integrator._cache = ((id(state), t, nstep0 + done), N.copy(), True)
    return order * done + (0 if hit else 1)


def advance_context(scheme, integrator, state, kinetic_limit: float) -> tuple:
    """What a compiled ``advance`` reads from ``state`` and the scheme before its loop:
    ``(nstep0, stamp, t0, dissipated, external, check, kinetic_limit, cache, inv)`` — the step
    count, the continuation stamp of the integrator's caches, the time and energy
    accumulators, the blow-up test (:data:`CHECK_MOMENTUM` for integrators that carry momenta,
    else :data:`CHECK_CONFIGURATION`), the scheme's cache of compiled data and ``1/m`` on the
    live components (0 on gauge ones)."""
    nstep0 = state.scalars.get("nstep", 0)
    cache = scheme.__dict__.setdefault("_compiled_cache", {})
    inv = cache.get("inv")
    if inv is None:
        inv = cache["inv"] = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    return (nstep0, (id(state), state.t, nstep0), float(state.t), float(state.scalars.get("dissipated_energy", 0.0)),
            float(state.scalars.get("external_work", 0.0)),
            CHECK_MOMENTUM if integrator.uses_momentum else CHECK_CONFIGURATION, float(kinetic_limit), cache, inv)


def finish_advance(integrator, state, t: float, diss: float, ext: float, nstep0: int, done: int, nforce: int,
                   W, t_start: float) -> bool:
    """Book ``done`` compiled steps as ``integrator.step`` would: ``state.t``, the energy
    accumulators and ``"nstep"`` of ``state.scalars``, the FSAL force ``W`` (or None), and the
    integrator's counters (``wall_time`` since ``t_start``).  Returns True (steps were taken)."""
    state.t = t
    state.scalars["dissipated_energy"] = diss
    state.scalars["external_work"] = ext
    state.scalars["nstep"] = nstep0 + done
    if W is not None:
        integrator._fsal = ((id(state), t, nstep0 + done), W)
    integrator.nstep += done
    integrator.nforce += nforce
    integrator.wall_time += time.perf_counter() - t_start
    return True
