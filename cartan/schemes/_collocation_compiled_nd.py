"""Compiled step loops of the ``collocation`` scheme for d = 2 and 3 (ARCHITECTURE.md §7).

:func:`cartan.schemes._collocation_compiled.advance` hands the problems with d ≥ 2 to
:func:`advance` here (:func:`~cartan.schemes._collocation_compiled.build_plan` decides what
qualifies, for every d).  The loops perform the operations of ``Integrator.step`` with
``Collocation.force``/``drift`` and the base scheme's ``velocity``/``constrain``/``powers`` in
the same order as the numpy path, so that the two agree to round-off
(``tests/test_collocation_compiled_nd.py``).

Design
------
* **The grid as flat arrays.**  The nodes are numbered in C order: ``S``, ``N``, ``W``
  ``[n, r]``, the strains ``X [n, d·r]`` (axis α's in the columns ``αr : αr + r``), the frames
  ``[n, m, m]`` or the root frame ``[1, m, m]`` — views of the state's arrays, updated in
  place.  The plan ``P`` is the d = 1 layout of the lattice's plan (weights and clamps
  flattened), so that the serial velocity, constraint, kick, end-load, power and blow-up
  helpers of :mod:`cartan.schemes._lattice_compiled` serve here too.
* **The derivative along an axis** (tuple ``Dc``, layout ``J_*``, one numba type for d = 2
  and 3): axis α of ``n_α`` nodes and stride ``s_α`` splits the nodes into blocks of
  ``n_α s_α`` consecutive ones, each holding ``s_α`` lines of the axis; the central stencil
  of :meth:`~cartan.schemes.collocation.DerivativeOperator.rows` is one run of consecutive
  nodes per block (offsets ``o·s_α``), the closure rows of open axes and the wrapped rows of
  periodic ones are CSR rows over the positions along the axis, and the Fourier derivative
  is the circulant ``(Du)_j = Σ_m c_m u_{j+m mod n_α}`` (``c`` the first row of the axis'
  matrix), each sum in the order of ``DerivativeOperator.__call__``.
* **The force axis by axis** (paper §IV, §V): ``W = Σ_α (∂_αQ^α − ad_{X_α}ᵀQ^α)`` with
  ``Q^α = C(X_α − X₀_α)``, the axes in order, as ``Collocation.internal_force`` adds them;
  then the natural boundary condition at every node of every free end face,
  ``W += (P − n_α Q^α)/H_end`` (P the face's load per unit reference area in body
  components); then the loads and the constraints.  The stress, ``ad*`` and load terms are
  the d = 1 module's (:func:`~cartan.schemes._collocation_compiled._stress_of`,
  ``_coadjoint``, ``_load_terms``) on axis α's columns.
* **The drift axis by axis** (paper §V, Eq. (X LGI)): after the derivatives ``∂_αN`` of all
  axes, the d = 1 node pass (the closed forms ``_se3_nodes``, ``_so3_nodes`` for SE(3),
  SO(3), the matrix kernels ``_drift_nodes`` for SO(2), SE(2)) updates the first axis'
  strains, the momentum (mode of the integrator) and the frames, then the strains of every
  further axis with the same ``exp(τN)`` and no momentum or frame update:
  ``X_α ← Ad_{exp(−τN)} X_α + 𝓔(τ, −N) ∂_αN``.  (The node maps are formed again for each
  axis: scalar per-node work, as in d = 1.)
* **Energy books and blow-up test** as in d = 1: the powers by the trapezoidal rule, the
  boundary power of the loaded faces ``Σ face·P·N`` (``face = w/H_end`` integrates the
  traction over the face), and after every step finite momentum and the kinetic bound (or a
  finite configuration), stopping after the first failing step.
* **No per-step allocation**: work arrays once per call.
"""

from __future__ import annotations

import time

import numpy as np
from numba import uint64

from ._collocation_compiled import (
    MODE_COAD,
    MODE_LIE_EULER,
    MODE_NONE,
    _circulant,
    _coadjoint,
    _csr,
    _dexp_slopes,
    _drag_velocity,
    _drift_nodes,
    _increment,
    _inline,
    _interior,
    _jit,
    _lie_poisson,
    _lie_verlet_pieces,
    _load_terms,
    _naive_frames,
    _naive_strains,
    _se3_nodes,
    _so3_nodes,
    _stress_of,
)
from ._lattice_compiled import (
    GID_SE3,
    GID_SO3,
    I_AFFINE,
    I_C,
    I_DIAG,
    I_END_FOLLOW,
    I_END_LOAD,
    I_GID,
    I_HAS_DAMP,
    I_HAS_POWER,
    I_W,
    _book,
    _constrain,
    _end_load,
    _kick,
    _powers,
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

__all__ = [
    "advance",
    "axis_derivative_once",
    "derivative_data",
    "drift_once",
    "euler_loop",
    "force_once",
    "lie_verlet_loop",
    "overdamped_loop",
    "overdamped_velocity",
    "rkmk_loop",
]

#: layout of the tuple ``Dc``: the CSR rows of every axis (``J_PTR``: row pointers, ``n_α + 1``
#: for axis α from ``J_AXES[α, A_PSTART]``, into ``J_IND`` — positions along the axis — and
#: ``J_DAT``), the offsets ``J_OFF`` of the central stencil (shared by the axes) and its
#: coefficients ``J_ACOEF [d, len(J_OFF)]``, the first rows of the Fourier matrices (``J_CIRC``,
#: axis α's from ``J_AXES[α, A_CSTART]``; empty for finite differences), the grid
#: (``J_AXES [d, 6]``, columns ``A_*``), the rest strains ``J_X0S [d, r]``, one row per node of
#: each free end face — ``J_FREE [nf, 3]`` (columns ``F_NODE``, ``F_LOAD``: the face's row of
#: the plan's ``I_END_LOAD`` or −1, ``F_AXIS``) and ``J_FREE_COEF [nf, 3]`` (``F_SIGN`` n_α,
#: ``F_H`` H_end, ``F_FACE`` the face weight w/H_end) — and ``J_FACES``: a face carries a load.
#: Few arrays: every call that passes the tuple pays a reference count for each.
(J_PTR, J_IND, J_DAT, J_OFF, J_CIRC, J_AXES, J_ACOEF, J_X0S, J_FREE, J_FREE_COEF, J_FACES) = range(11)
#: columns of ``J_AXES``: nodes, stride in the C-ordered numbering, the starts of the axis' CSR
#: row pointers and Fourier row, the positions ``[lo, hi)`` where the central stencil applies
#: without wrapping
(A_N, A_STRIDE, A_PSTART, A_CSTART, A_LO, A_HI) = range(6)
#: columns of ``J_FREE`` and of ``J_FREE_COEF``
(F_NODE, F_LOAD, F_AXIS) = range(3)
(F_SIGN, F_H, F_FACE) = range(3)


# ---------------------------------------------------------------------------- derivative
@_jit
def _deriv_lines(indptr, p0, indices, data, off, coef, lo, hi, circ, c0, nl, stride, A, out, accumulate):
    """``out = D A`` (or ``out += D A`` when ``accumulate``) along one axis of ``nl`` nodes and
    node stride ``stride`` in the C-ordered numbering of ``A``, ``out`` ``[n, r]``.

    The nodes are blocks of ``nl·stride`` consecutive ones, a block holding ``stride`` lines of
    the axis, node ``(j, q)`` of a block at ``j·stride + q``: the central stencil (offsets
    ``off``, coefficients ``coef``) is written out at the positions ``j ∈ [lo, hi)`` it reaches
    without wrapping — one run of consecutive nodes per block —, the CSR rows (row pointers
    ``indptr[p0:p0 + nl + 1]``, positions ``indices``, ``data``) at the others, each row summed
    in the order of ``DerivativeOperator.__call__`` (the interior indices unsigned: no
    negative-index wrap-around test); the Fourier derivative (``circ`` not empty) is the
    circulant sum ``(DA)_j = Σ_m c_m A_{j+m mod nl}`` with ``c = circ[c0:c0 + nl]``, in the order
    of ``m``.  A sum is formed before it is added to ``out``, as ``out += D(A)`` does."""
    n, r = A.shape
    block = nl * stride
    ns = off.shape[0]
    for base in range(0, n, block):
        if circ.shape[0]:
            if accumulate:
                for j in range(nl):
                    for q in range(stride):
                        i = base + j * stride + q
                        for k in range(r):
                            acc = 0.0
                            for m in range(nl):
                                jm = j + m if j + m < nl else j + m - nl
                                acc += circ[c0 + m] * A[uint64(base + jm * stride + q), k]
                            out[i, k] += acc
                continue
            for i in range(base, base + block):
                for k in range(r):
                    out[i, k] = 0.0
            for m in range(nl):
                c = circ[c0 + m]
                split = base + (nl - m) * stride
                s1, s2 = m * stride, (m - nl) * stride
                for i in range(base, split):
                    for k in range(r):
                        out[i, k] += c * A[uint64(i + s1), k]
                for i in range(split, base + block):
                    for k in range(r):
                        out[i, k] += c * A[uint64(i + s2), k]
            continue
        start, stop = base + lo * stride, base + hi * stride
        if ns == 2:
            o0, o1 = off[0] * stride, off[1] * stride
            k0, k1 = coef[0], coef[1]
            for i in range(start, stop):
                for k in range(r):
                    v = k0 * A[uint64(i + o0), k] + k1 * A[uint64(i + o1), k]
                    out[i, k] = out[i, k] + v if accumulate else v
        elif ns == 4:
            o0, o1, o2, o3 = off[0] * stride, off[1] * stride, off[2] * stride, off[3] * stride
            k0, k1, k2, k3 = coef[0], coef[1], coef[2], coef[3]
            for i in range(start, stop):
                for k in range(r):
                    v = (k0 * A[uint64(i + o0), k] + k1 * A[uint64(i + o1), k] + k2 * A[uint64(i + o2), k]
                         + k3 * A[uint64(i + o3), k])
                    out[i, k] = out[i, k] + v if accumulate else v
        for b in range(nl - (hi - lo)):
            j = b if b < lo else b + hi - lo  # the rows before lo, then from hi on
            for q in range(stride):
                i = base + j * stride + q
                for k in range(r):
                    acc = 0.0
                    for p in range(indptr[p0 + j], indptr[p0 + j + 1]):
                        acc += data[p] * A[uint64(base + indices[p] * stride + q), k]
                    out[i, k] = out[i, k] + acc if accumulate else acc


@_inline
def _deriv_axis(Dc, a, A, out, accumulate):
    """``out = ∂_α A`` (``out += ∂_α A`` when ``accumulate``) along axis ``a`` of the grid,
    ``A``, ``out`` ``[n, r]`` (:func:`_deriv_lines` with the axis' data)."""
    ax = Dc[J_AXES]
    _deriv_lines(Dc[J_PTR], ax[a, A_PSTART], Dc[J_IND], Dc[J_DAT], Dc[J_OFF], Dc[J_ACOEF][a], ax[a, A_LO],
                 ax[a, A_HI], Dc[J_CIRC], ax[a, A_CSTART], ax[a, A_N], ax[a, A_STRIDE], A, out, accumulate)


@_inline
def _derivatives(Dc, N, DN):
    """``DN [d·n, r]`` ← ``∂_αN`` of every axis, one block of ``n`` rows after the other."""
    n = N.shape[0]
    for a in range(Dc[J_AXES].shape[0]):
        _deriv_axis(Dc, a, N, DN[a * n:(a + 1) * n], False)


# ---------------------------------------------------------------------------- force, drifts
@_jit
def _force(P, Dc, X, Phi, N, W, Q, scr):
    """``W = Collocation.force(state, N, t)`` ``[n, r]`` for the strains ``X [n, d·r]``:
    ``Σ_α ∂_αQ^α − ad_{X_α}ᵀQ^α`` axis by axis, the penalties ``(P − n_α Q^α)/H_end`` at the
    nodes of every free end face, damping, body-frame force, constant field; zero at clamped
    nodes and on gauge components.  ``Q`` ``[n, r]`` is work space."""
    gid = P[I_GID]
    xi, Qv, tr, M, M2, A1, A2, A3, XI = scr
    n, r = W.shape
    C, diag = P[I_C], P[I_DIAG]
    X0s = Dc[J_X0S]
    for a in range(X0s.shape[0]):
        _stress_of(C, diag, X0s[a], X, a * r, Q)
        _deriv_axis(Dc, a, Q, W, a > 0)
        _coadjoint(gid, X, a * r, Q, W, xi, M)
    free = Dc[J_FREE]
    coef = Dc[J_FREE_COEF]
    Q1 = Qv.reshape((1, r))
    for f in range(free.shape[0]):
        idx = free[f, F_NODE]
        q = free[f, F_LOAD]
        if q >= 0:
            _end_load(gid, P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A1)
        else:
            for k in range(r):
                tr[k] = 0.0
        a = free[f, F_AXIS]
        _stress_of(C, diag, X0s[a], X[idx:idx + 1], a * r, Q1)  # Q^α at the node, as above
        sign, H = coef[f, F_SIGN], coef[f, F_H]
        for k in range(r):
            W[idx, k] += (tr[k] - sign * Qv[k]) / H
    _load_terms(P, Phi, N, W)


@_jit
def _drift(P, Dc, X, Phi, S, W, N, tau, DN, D, scr, mode):
    """Exact drift by ``τN`` (``Collocation.drift(exact=True)``) of the strains ``X [n, d·r]``,
    the frames and (``mode``) the momentum: the d = 1 node pass on the first axis with the
    momentum and frame updates, then on each further axis' strains alone; ``DN [d·n, r]``,
    ``D [n, m, m]`` work space."""
    gid = P[I_GID]
    n, r = N.shape
    _derivatives(Dc, N, DN)
    for a in range(Dc[J_AXES].shape[0]):
        Xa = X[:, a * r:(a + 1) * r]
        DNa = DN[a * n:(a + 1) * n]
        frames = Phi if a == 0 else Phi[:0]
        how = mode if a == 0 else MODE_NONE
        if gid == GID_SE3:
            _se3_nodes(Xa, frames, S, W, N, DNa, tau, how)
        elif gid == GID_SO3:
            _so3_nodes(Xa, frames, S, W, N, DNa, tau, how)
        else:
            _drift_nodes(gid, Xa, frames, S, W, N, DNa, tau, D, scr[0], scr[2], scr[3], scr[4], scr[5], how)


@_jit
def _naive_drift(P, Dc, X, Phi, N, tau, DN, D, scr):
    """``Collocation.drift(exact=False)``: ``X_α ← X_α + τ(∂_αN − ad_N X_α)`` for the strains
    ``X [n, d·r]``, ``Φ ← Φ + τΦN̂``."""
    gid = P[I_GID]
    n, r = N.shape
    _derivatives(Dc, N, DN)
    for a in range(Dc[J_AXES].shape[0]):
        _naive_strains(gid, X[:, a * r:(a + 1) * r], N, DN[a * n:(a + 1) * n], tau, scr)
    _naive_frames(gid, Phi, N, tau, scr)


# ---------------------------------------------------------------------------- shared pieces of the loops
@_jit
def _work(n, r, m, d):
    """Per-call work arrays: the force ``W``, the stress ``Q`` ``[n, r]``, the derivatives
    ``DN [d·n, r]``, the node exponentials ``D [n, m, m]``, the helpers' scratch."""
    return np.empty((n, r)), np.empty((n, r)), np.empty((d * n, r)), np.empty((n, m, m)), _scratch(r, m, 0)


@_inline
def _ends(Dc):
    """``(J_FACES, J_FREE, J_FREE_COEF)`` of ``Dc``: what the powers read, taken out of the
    tuple once per loop."""
    return Dc[J_FACES], Dc[J_FREE], Dc[J_FREE_COEF]


@_jit
def _scheme_powers(P, ends, N, Phi, scr):
    """(dissipated, external) power at velocity N (``Scheme.powers``): the loads' (``_powers``)
    and the power ``Σ face·P·N`` of the loaded end faces (``Collocation._boundary_power``;
    ``ends`` = :func:`_ends`)."""
    dissipated, external = _powers(P, N, Phi, scr)
    faces, free, coef = ends
    if faces:
        xi, Q, tr, M, M2, A1, A2, A3, XI = scr
        r = N.shape[1]
        p = 0.0
        for f in range(free.shape[0]):
            q = free[f, F_LOAD]
            if q < 0:
                continue
            idx = free[f, F_NODE]
            _end_load(P[I_GID], P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A1)
            acc = 0.0
            for k in range(r):
                acc += tr[k] * N[idx, k]
            p += coef[f, F_FACE] * acc
        external += p
    return dissipated, external


@_jit
def _end_step(P, ends, S, X, Phi, N, scr, dt, books, check, kinetic_limit, inv):
    """The close of a step at its final velocity ``N``: the powers booked by the trapezoidal
    rule (``books = (dissipated, external, p0d, p0e)``, the powers at the step's start;
    returned updated) and the per-step blow-up test (True: stop)."""
    dissipated, external, p0d, p0e = books
    p1d, p1e = _scheme_powers(P, ends, N, Phi, scr)
    dissipated, external = _book(dt, dissipated, external, p0d, p0e, p1d, p1e)
    return (dissipated, external, p1d, p1e), _unstable(check, kinetic_limit, S, X, Phi, P[I_W], inv)


@_jit
def _drift_velocity(P, Dc, X, Phi, Z, W, Q, N, gam, scr):
    """Overdamped velocity ``N = Γ⁻¹W(N = 0)`` (live components; zero at clamped nodes)."""
    _force(P, Dc, X, Phi, Z, W, Q, scr)
    _drag_velocity(P, W, N, gam)


# ---------------------------------------------------------------------------- loops
@_jit
def lie_verlet_loop(P, Dc, S, X, Phi, W, have_force, velocity_free, seq_mask, seq_frac,
                    t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``LieVerlet``: half kick, the palindromic split free flow (each
    piece an exact drift with ``S ← Ad*_{exp τN_p}S``), half kick.

    ``W`` holds the force at the current state when ``have_force`` (first-same-as-last) and
    the force at the final state on return.  Returns
    ``(steps done, force evaluations, t, dissipated, external)``.
    """
    n, r = S.shape
    N = np.zeros((n, r))
    Np = np.zeros((n, r))
    _, Q, DN, D, scr = _work(n, r, Phi.shape[1], X.shape[1] // r)
    ends = _ends(Dc)
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _velocity(P, S, N)
    books = (dissipated, external) + _scheme_powers(P, ends, N, Phi, scr)
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
        books, stop = _end_step(P, ends, S, X, Phi, N, scr, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    return done, nforce, t, books[0], books[1]


@_jit
def euler_loop(P, Dc, S, X, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv, geometric):
    """``nsteps`` steps of ``LieEuler`` (``geometric``, paper §V: ``S⁺ = Ad*_{exp ΔtN}S +
    𝓔*(Δt, N)W``, ``X_α⁺ = Ad_{exp(−ΔtN)}X_α + 𝓔(Δt, −N)∂_αN``, ``Φ⁺ = Φ exp(ΔtN)``) or of
    ``ForwardEuler`` (``X_α += Δt(∂_αN − ad_N X_α)``, ``Φ += ΔtΦN̂``, ``S += Δt(ad_NᵀS + W)``).
    Returns ``(steps done, t, dissipated, external)``."""
    n, r = S.shape
    N = np.empty((n, r))
    Sd = np.empty((n, r))
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1], X.shape[1] // r)
    ends = _ends(Dc)
    _velocity(P, S, N)
    books = (dissipated, external) + _scheme_powers(P, ends, N, Phi, scr)
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
        books, stop = _end_step(P, ends, S, X, Phi, N, scr, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


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
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1], X.shape[1] // r)
    ends = _ends(Dc)
    books = (dissipated, external) + _scheme_powers(P, ends, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _drift(P, Dc, X, Phi, S, W, N, dt, DN, D, scr, MODE_NONE)
        S[:] = 0.0
        t = t + dt
        _drift_velocity(P, Dc, X, Phi, Z, W, Q, N, gam, scr)
        books, stop = _end_step(P, ends, S, X, Phi, N, scr, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


@_jit
def rkmk_loop(P, Dc, S, X, Phi, N, gam, dynamics, A, b, t, dt, nsteps, dissipated, external, check,
              kinetic_limit, inv):
    """``nsteps`` explicit Runge–Kutta–Munthe-Kaas steps with tableau ``(A, b)``.

    ``dynamics``: ``rkmk4`` (S by the same tableau on ``Ṡ = ad_NᵀS + W``, N = velocity(S));
    otherwise the overdamped flow of order 2 (N = Γ⁻¹W(N = 0), S = 0), with ``N`` the drift
    velocity of the current state on entry and of the final state on return.  Stage ``i``
    drifts a copy of the configuration by ``σ_i``.  Returns ``(steps done, t, dissipated,
    external)``.
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
    W, Q, DN, D, scr = _work(n, r, Phi.shape[1], X.shape[1] // r)
    Xst = np.empty_like(X)
    Phist = np.empty_like(Phi)
    xi, Qv, tr, M, M2, A1, A2, A3, XI = scr
    ends = _ends(Dc)
    if dynamics:
        _velocity(P, S, N)
    books = (dissipated, external) + _scheme_powers(P, ends, N, Phi, scr)
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
        books, stop = _end_step(P, ends, S, X, Phi, N, scr, dt, books, check, kinetic_limit, inv)
        done += 1
        if stop:
            break
    return done, t, books[0], books[1]


# ---------------------------------------------------------------------------- single operations (tests)
@_jit
def force_once(P, Dc, X, Phi, N, W):
    """One force evaluation ``W [n, r]`` at ``(X [n, d·r], Phi, N [n, r])`` (compared with
    ``Collocation.force``)."""
    n, r = W.shape
    _force(P, Dc, X, Phi, N, W, np.empty((n, r)), _scratch(r, Phi.shape[1], 0))


@_jit
def drift_once(P, Dc, X, Phi, N, tau, exact):
    """One drift of ``(X [n, d·r], Phi)`` by ``τN`` (``N`` ``[n, r]``) in place, exact or naive
    (``Collocation.drift``)."""
    n, r = N.shape
    _, _, DN, D, scr = _work(n, r, Phi.shape[1], X.shape[1] // r)
    Z = np.zeros((n, r))
    if exact:
        _drift(P, Dc, X, Phi, Z, Z, N, tau, DN, D, scr, MODE_NONE)
    else:
        _naive_drift(P, Dc, X, Phi, N, tau, DN, D, scr)


@_jit
def axis_derivative_once(Dc, axis, A, out):
    """``out = ∂_α A`` along grid axis ``axis``, ``A``, ``out`` ``[n, r]`` on the C-ordered
    nodes (compared with ``DerivativeOperator(A, axis)``)."""
    _deriv_axis(Dc, axis, A, out, False)


# ---------------------------------------------------------------------------- Python glue
def derivative_data(scheme, X0s: np.ndarray) -> tuple:
    """``Dc`` (layout ``J_*``) of a collocation scheme on a d ≥ 2 grid: the derivative operators
    of every axis, the rest strains ``X0s [d, r]`` and the nodes of the free end faces (in the
    order of ``Collocation.internal_force``; the loaded faces' rows of the plan's ``I_END_LOAD``
    in the order of ``Collocation._end_loads``)."""
    grid = scheme.grid
    shape = tuple(int(s) for s in grid.shape)
    ptr, ind, dat, circ, coefs, axes = [], [], [], [], [], []
    nnz = rows = columns = 0
    off = np.zeros(0, dtype=np.int64)
    for a, D in enumerate(scheme.D):
        indptr, indices, data = _csr(D)
        off, coef, lo, hi = _interior(D)  # the same offsets on every axis (one derivative kind)
        ptr.append(indptr + nnz)
        ind.append(indices)
        dat.append(data)
        circ.append(_circulant(D))
        coefs.append(coef)
        axes.append((shape[a], int(np.prod(shape[a + 1:])), rows, columns, lo, hi))
        nnz += indices.shape[0]
        rows += indptr.shape[0]
        columns += circ[-1].shape[0]
    numbers = np.arange(grid.size).reshape(shape)
    free, coef_rows, loaded = [], [], 0
    for axis, sl, sign, H, b, face in scheme._free_ends:
        nodes = numbers[sl].reshape(-1)
        weights = np.broadcast_to(face, numbers[sl].shape).reshape(-1)
        row = -1
        if b.load is not None:
            row, loaded = loaded, loaded + 1
        free += [(int(i), row, int(axis)) for i in nodes]
        coef_rows += [(float(sign), float(H), float(w)) for w in weights]
    return (np.concatenate(ptr).astype(np.int64), np.concatenate(ind).astype(np.int64),
            np.concatenate(dat).astype(float), off, np.concatenate(circ).astype(float),
            np.array(axes, dtype=np.int64).reshape(len(shape), 6),
            np.array(coefs, dtype=float).reshape(len(shape), off.shape[0]), np.ascontiguousarray(X0s, dtype=float),
            np.array(free, dtype=np.int64).reshape(-1, 3), np.array(coef_rows, dtype=float).reshape(-1, 3),
            bool(loaded))


def advance(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """Up to ``nsteps`` steps of ``integrator`` on a d ≥ 2 collocation ``state`` in compiled code
    (the contract of :meth:`cartan.schemes.collocation.Collocation.compiled_advance`): the
    state's arrays are viewed on the C-ordered nodes and updated in place, and the
    integrator's caches (lie-verlet's force, the overdamped velocity) are kept in the state's
    shape ``[*shape, r]``, as the Python path keeps them.  False, touching nothing, when the
    integrator or the state's layout is not supported."""
    from ..compiled.tableaux import TABLEAUX as _TABLEAUX
    from . import _kinematic_compiled as kinematic

    P, Dc = plan
    supported = compiled_kind(scheme, integrator)
    if supported is None:
        return False
    kind, gam = supported
    grid = scheme.grid
    n, d, r = grid.size, grid.d, scheme.group.dim
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {"X", frame_key} or np.shape(state.arrays["X"]) != (*grid.shape, d, r):
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    dt = float(dt)
    S = state.S = _writable(state.S)
    S2 = S.reshape(n, r)
    X = state.arrays["X"] = _writable(state.arrays["X"])
    X2 = X.reshape(n, d * r)
    Phi = state.arrays[frame_key] = _writable(state.arrays[frame_key])
    Phi3 = Phi.reshape(-1, *Phi.shape[-2:])
    if kind == "kinematic":
        def work(inv):  # the work arrays of kinematic.COLLOCATION_ND_OPS
            W, _, DN, D, scr = _work(n, r, Phi3.shape[-1], d)
            return Dc, np.zeros((n, r)), W, DN, D, scr, inv

        return kinematic.advance(scheme, "collocation-nd", P, (X2, Phi3), work, integrator, state, dt, nsteps,
                                 kinetic_limit)
    nstep0, stamp, t0, diss, ext, check, limit, cache, inv = advance_context(scheme, integrator, state,
                                                                             kinetic_limit)
    W = None
    if kind == "lie-verlet":
        velocity_free, have, W = lie_verlet_force(scheme, integrator, stamp, S)
        mask, frac, _ = _lie_verlet_pieces(integrator, scheme, cache)
        done, nforce, t, diss, ext = lie_verlet_loop(P, Dc, S2, X2, Phi3, W.reshape(n, r), have, bool(velocity_free),
                                                     mask, frac, t0, dt, nsteps, diss, ext, check, limit, inv)
    elif kind == "lie-euler" or kind == "forward-euler":
        done, t, diss, ext = euler_loop(P, Dc, S2, X2, Phi3, t0, dt, nsteps, diss, ext, check, limit, inv,
                                        kind == "lie-euler")
        nforce = done
    else:
        dynamics = kind == "rkmk4"
        order = 4 if dynamics else integrator.order
        hit, N = rkmk_velocity(integrator, stamp, S, dynamics)
        if not dynamics:  # from the state alone (rkmk_velocity)
            overdamped_velocity(P, Dc, X2, Phi3, N.reshape(n, r), gam)
        if order == 1:
            done, t, diss, ext = overdamped_loop(P, Dc, S2, X2, Phi3, N.reshape(n, r), gam, t0, dt, nsteps, diss,
                                                 ext, check, limit, inv)
        else:
            A, b, _ = _TABLEAUX[order]
            done, t, diss, ext = rkmk_loop(
                P, Dc, S2, X2, Phi3, N.reshape(n, r), np.ones(r) if gam is None else gam, dynamics,
                np.ascontiguousarray(A, dtype=float), np.ascontiguousarray(b, dtype=float),
                t0, dt, nsteps, diss, ext, check, limit, inv)
        nforce = rkmk_books(integrator, state, dynamics, order, done, hit, t, nstep0, N)
    return finish_advance(integrator, state, t, diss, ext, nstep0, done, nforce, W, t_start)
