"""The compiled ``rattle`` loop: lie-verlet with constrained edge strains held by multipliers.

:func:`rattle_loop` takes :class:`~cartan.integrators.constrained.Rattle`'s steps as its Python
``_step`` takes them (same formulas, round-off apart; the module docstring of
:mod:`cartan.integrators.constrained` states them), inside the generated module of a
lattice's operator set (:mod:`cartan.compiled.operators`, :data:`LOOP_SOURCES`), where
``op_*`` are the lattice's operators (:mod:`cartan.schemes._lattice_ops`), ``g_*`` the group's
point kernels and ``D`` the lattice as data.

The constraint rows are ``c_{e,a} = X_e[comp_a] − value_a`` on every edge e (``X_e = log(G_e)/h``);
their Jacobian along the drift, ``B_c δ = [dexp⁻¹(−hX_e)δ_j − dexp⁻¹(hX_e)δ_i]_comp / h``, is kept
per edge as its two ``(c, r)`` blocks: ``Bt[e]`` on the tail node i and ``Bh[e]`` on the head
node j (``[E, c, r]``, columns of every component; the node operators ``P`` ``[n, r, r]`` are
zero on the gauge components, at clamped and driven nodes and on the held components of
``Held`` ends and ``Symmetry`` faces — the operator set's ``held`` mask, :func:`_rattle_fixed` —
so only the unknowns enter).  On a chain of
nodes (d = 1, open; edge e from node e to node e + 1) the multiplier matrices
``L P Rᵀ`` couple an edge with its neighbours only: block-tridiagonal, ``[E, c, c]`` blocks,
factored and solved in O(E c³) (:mod:`cartan.compiled.banded`; the symmetric positive definite
``B P Bᵀ`` by the block Cholesky factorisation, the quasi-Newton matrix by the block LU).

Per step: the rows at the start (the previous step's closing rows), the start's velocity
projection (skipped when tangent), the force (first-same-as-last when no force depends on N),
the predicted multiplier λ plus the offset ν − λ extrapolated from the last three steps
(``offset``, :class:`~cartan.state.State`'s ``memory``; its factorization of ``B₀ P B₀ᵀ`` is
the chord matrix of the iteration; Ḃ_c N in closed form from the rows' ``dexp⁻¹`` that
:func:`rattle_rows` keeps, :func:`_rattle_rate`), two to five trial flows (a quasi-Newton
factorization only when the chord gains less than a factor ``SLOW_``), the next step's offset
(ν with one more correction, a solve), the rows at the end (from the last trial's logarithms,
which :func:`rattle_values` keeps) and the closing kick with its velocity projection (one
factorization, reused by the next step's start when no load depends on N, or when the damping
is proportional to the inertia: the closing matrix is then s·I on the live block and ``B
P_closing Bᵀ = s·B P Bᵀ``). With damping the force a step starts from is the one the closing
kick left, ``W(N = 0) − ΓN`` (the damping is linear), and a call that starts without it (the
first, or after a restart) evaluates it the same way: the steps do not depend on how they are
grouped into calls.
A trial flow is a kick (:func:`rattle_trial_kick`), the free flow of the edges alone
(:func:`rattle_trial_flow`: ``op_free_flow``'s passes with its plan and scratch made once per
call; the frames follow the converged trial's motions, ``op_move``'s operations: the same
numbers) and the rows' values (:func:`rattle_values`, the edges' logarithms by the group's
``g_log_chunk``).  The helpers called at every trial or step take the lattice's arrays they read
(``tail``, ``head``, ``winv``, ``einvh`` …) rather than ``D``: numba counts a reference to
each of D's arrays at every call of a function that takes it (≈ 0.35 µs a call at n = 11,
≈ 40 calls a step before); without driven nodes the loop also applies the velocity and the
scheme's constraint itself (:func:`_rattle_velocity`, :func:`_rattle_zero`: ``op_velocity``'s
and ``op_constrain``'s operations).
Driven ends (the operator set's driven nodes, ``D.any_driven``): the velocity the rows are
applied to is ξ there (``op_velocity``), so ``B_c N`` is ``B_u N_u + B_d ξ`` and the projections
solve ``B_u N_u = −B_d ξ`` as they stand; the free flow moves the driven nodes by exp(Δtξ)
(``op_free_flow``); the kinetic energy the start's velocity projection gives (the first step
from rest) is booked as the support's work, and the powers a step books add ``−λᵀB_dξ``, the
rows' force on the driven nodes (:func:`_rattle_support_power`, λ as the Python step's
``Rattle._multipliers``), the powers a call starts from taken where the Python step takes them.
``status`` ``[2]`` int64 returns the outcome (0: steps done, 1: the multipliers' iteration
failed, 2: the initial configuration could not be projected, 3: a multiplier system ``B P Bᵀ``
was singular — dependent rows; the state is then the one the failing step started from, or, for
a closing projection, where that step ended) and the iterations summed over the steps; ``info`` ``[1]`` the
residual of a failure.
"""

from __future__ import annotations

import numpy as np

from ..compiled.banded import bs_factor, bs_solve, bt_factor, bt_solve, small_inverse
from ..compiled.codegen import Fragment, njit_source
from .constrained import _MAX_ITERATIONS as MAX_ITERATIONS
from .constrained import _SLOW as SLOW

__all__ = ["loop_fragment"]


# ---------------------------------------------------------------------------- the rows
def _rattle_fixed(D, n):
    """``fixed[i, k]`` ``[n, r]`` bool: whether component k of node i is not an unknown of the
    rows: a gauge component, a clamped (or driven) node, a held component (``Held`` ends,
    ``Symmetry`` faces: ``D.held``).  Built once per call of :func:`rattle_loop` and read by
    its helpers: the same test made through a helper that takes ``D`` at every entry cost
    ≈ 0.2 µs per entry (numba counts a reference to each of the lattice's arrays where such a
    helper is inlined), 0.3 ms per call at n = 11 for the node operators alone."""
    live = D.live
    clamped = D.clamped
    held = D.held
    any_clamped = D.any_clamped
    any_held = D.any_held
    fixed = np.empty((n, R_), dtype=np.bool_)  # noqa: F821
    for i in range(n):
        for k in range(R_):  # noqa: F821
            fixed[i, k] = (not live[k]) or (any_clamped and clamped[i]) or (any_held and held[i, k])
    return fixed


def rattle_values(einvh, G, comp, value, out, Xe):
    """``out[e, a] = log(G_e)[comp_a]/h − value_a`` ``[E, c]``; returns max |out| (NaN if any is
    NaN).  Keeps the logarithms ``hX_e = log(G_e)`` in ``Xe`` ``[E, r]``: the rows at the same
    configuration (:func:`rattle_rows` with ``have_log``) take them instead of a second log.
    The logarithms are the group's edge pass ``g_log_chunk`` (SE(3): vectorised across the
    edges, :func:`~cartan.groups.se3.se3_log_chunk_point`, the point kernel's results to
    round-off), the one the lattice's force takes; nothing is allocated (a trial flow of the
    loop evaluates the rows' values once: two to five times a step).  ``G`` ``[E, m, m]`` the
    edges, ``einvh`` ``[E]`` their 1/h (``D.einvh``): the arrays, not the lattice's data ``D``
    (numba counts a reference to each of D's arrays at every call of a helper that takes it)."""
    ne = G.shape[0]
    g_log_chunk(G, 0, ne, Xe)  # noqa: F821
    big = 0.0
    finite = True
    for e in range(ne):
        ih = einvh[e]
        for a in range(comp.shape[0]):
            v = Xe[e, comp[a]] * ih - value[a]
            out[e, a] = v
            if not np.isfinite(v):
                finite = False
            elif abs(v) > big:
                big = abs(v)
    return big if finite else np.nan


def rattle_rows(tail, head, einvh, G, comp, Bt, Bh, Ae, Xe, have_log, fixed):
    """The rows of B_c at C: ``Bt[e] = −dexp⁻¹(hX_e)[comp]/h``, ``Bh[e] = dexp⁻¹(−hX_e)[comp]/h``
    ``[E, c, r]``; returns the largest entry on the unknowns (live components, free nodes).
    With ``have_log``, ``Xe`` already holds ``hX_e`` at C (:func:`rattle_values` at the same
    configuration was the last to write it): no logarithm is taken again; otherwise the
    logarithms are taken as :func:`rattle_values` takes them (``g_log_chunk``).
    ``dexp⁻¹(−ξ)`` is ``dexp⁻¹(ξ) + ad_ξ`` (``x/(eˣ − 1)`` at −x is ``x/(eˣ − 1) + x``): one
    ``g_dexp_inv`` per edge.  Keeps ``hX_e`` in ``Xe`` ``[E, r]`` and all of ``dexp⁻¹(hX_e)`` in
    ``Ae`` ``[E, r, r]`` (written there directly), for the rows' rate :func:`_rattle_rate`.
    ``G`` ``[E, m, m]`` the edges, ``tail``, ``head``, ``einvh`` ``[E]`` the lattice's arrays
    (not ``D``: see :func:`rattle_values`)."""
    if not have_log:
        g_log_chunk(G, 0, G.shape[0], Xe)  # noqa: F821
    ad = np.empty((R_, R_))  # noqa: F821
    big = 0.0
    for e in range(G.shape[0]):
        ih = einvh[e]
        i, j = tail[e], head[e]
        g_dexp_inv(Xe[e], Ae[e])  # noqa: F821
        for a in range(comp.shape[0]):
            ka = comp[a]
            for k in range(R_):  # noqa: F821
                v = -Ae[e, ka, k] * ih
                Bt[e, a, k] = v
                if abs(v) > big and not fixed[i, k]:
                    big = abs(v)
        g_ad(Xe[e], ad)  # noqa: F821
        for a in range(comp.shape[0]):
            ka = comp[a]
            for k in range(R_):  # noqa: F821
                v = (Ae[e, ka, k] + ad[ka, k]) * ih
                Bh[e, a, k] = v
                if abs(v) > big and not fixed[j, k]:
                    big = abs(v)
    return big


def rattle_metric(D, closing, P, fixed):
    """``P[i] = (M⁺·closing)`` on the live block ``/ w_i`` (zero elsewhere and at clamped
    nodes) ``[n, r, r]``: the velocity change of a nodal impulse (closing: the damped kick's
    ``(I + ½ΔtΓM⁺)⁻¹``, or I)."""
    T = np.empty((R_, R_))  # noqa: F821
    for k in range(R_):  # noqa: F821
        for j in range(R_):  # noqa: F821
            s = 0.0
            if D.live[k] and D.live[j]:
                for m in range(R_):  # noqa: F821
                    s += D.inv_metric[k, m] * closing[m, j]
            T[k, j] = s
    for i in range(P.shape[0]):
        for k in range(R_):  # noqa: F821
            for j in range(R_):  # noqa: F821
                zero = fixed[i, k] or fixed[i, j]
                P[i, k, j] = 0.0 if zero else T[k, j] * D.winv[i]


def _rattle_flow_jacobian(D, N, dt, P, fixed):
    """``P[i] = Δt·dexp(−ΔtN_i)·M⁺`` on the live block ``/ w_i`` (zero elsewhere and at clamped
    nodes): the drift at the flow's end of a change of the nodal impulse (``Δt·dexp(−ΔtN)`` is
    the group's ``g_E(Δt, −N)``, what the Python step takes as ``Δt·group.dexp(−ΔtN)``)."""
    E = np.empty((R_, R_))  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    for i in range(P.shape[0]):
        if D.any_clamped and D.clamped[i]:
            for k in range(R_):  # noqa: F821
                for j in range(R_):  # noqa: F821
                    P[i, k, j] = 0.0
            continue
        for k in range(R_):  # noqa: F821
            xi[k] = -N[i, k]
        g_E(dt, xi, E)  # noqa: F821
        for k in range(R_):  # noqa: F821
            for j in range(R_):  # noqa: F821
                s = 0.0
                if not (fixed[i, k] or fixed[i, j]):
                    if D.diagonal:
                        s = E[k, j] * D.inv_metric[j, j]
                    else:
                        for m in range(R_):  # noqa: F821
                            if not fixed[i, m]:
                                s += E[k, m] * D.inv_metric[m, j]
                P[i, k, j] = s * D.winv[i]


def _rattle_diagonal(P):
    """Whether every block ``P[i]`` ``(r, r)`` of ``P`` ``[n, r, r]`` is diagonal."""
    for i in range(P.shape[0]):
        for k in range(R_):  # noqa: F821
            for j in range(R_):  # noqa: F821
                if j != k and P[i, k, j] != 0.0:
                    return False
    return True


def _rattle_right(P, i, R, e, T, pdiag):
    """``T = P_i R_eᵀ`` ``(r, c)`` for ``P`` ``[n, r, r]`` and ``R`` ``[E, c, r]``; a diagonal
    ``P_i`` (the blocks of a diagonal metric) takes its diagonal only (the same sums: the other
    terms are exact zeros); ``pdiag``: every block of ``P`` is known to be diagonal
    (:func:`_rattle_diagonal`), else each is checked.  Indices rather than views of the
    blocks: no array views in the assembly's inner loops."""
    c = R.shape[1]
    diagonal = True
    if not pdiag:
        for k in range(R_):  # noqa: F821
            for j in range(R_):  # noqa: F821
                if j != k and P[i, k, j] != 0.0:
                    diagonal = False
    for k in range(R_):  # noqa: F821
        for b in range(c):
            if diagonal:
                s = P[i, k, k] * R[e, b, k]
            else:
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += P[i, k, j] * R[e, b, j]
            T[k, b] = s


def _rattle_left(L, e, T, out, f, add):
    """``out_f (+)= L_e T`` for ``L`` ``[E, c, r]``, ``T`` ``(r, c)``, ``out`` ``[E, c, c]``."""
    c = L.shape[1]
    for a in range(c):
        for b in range(c):
            s = 0.0
            for k in range(R_):  # noqa: F821
                s += L[e, a, k] * T[k, b]
            out[f, a, b] = out[f, a, b] + s if add else s


def rattle_factor(tail, head, Lt, Lh, P, Rt, Rh, F, pdiag):
    """Assemble and factor ``L P Rᵀ`` on the chain (``F = (sub, diag, sup, inv, mult)``, each
    ``[E, c, c]``): diagonal ``Lt_e P_i Rt_eᵀ + Lh_e P_j Rh_eᵀ``, below ``Lt_e P_i Rh_{e−1}ᵀ``
    (node i = tail of e = head of e − 1), above ``Lh_e P_j Rt_{e+1}ᵀ``; returns False when it
    is singular (``pdiag``: every block of ``P`` is diagonal, see :func:`_rattle_right`).  Each
    node's products ``P_i Rt_eᵀ``, ``P_j Rh_eᵀ`` are formed once and serve two blocks:
    ``P_i Rt_eᵀ`` the diagonal of e and the block above it in row e − 1,
    ``P_j Rh_eᵀ`` the diagonal of e and the block below it in row e + 1."""
    sub, dia, sup, inv, mult = F
    ne = Lt.shape[0]
    Tt = np.empty((R_, Lt.shape[1]))  # noqa: F821
    Th = np.empty((R_, Lt.shape[1]))  # noqa: F821
    for e in range(ne):
        i, j = tail[e], head[e]
        _rattle_right(P, i, Rt, e, Tt, pdiag)
        _rattle_right(P, j, Rh, e, Th, pdiag)
        _rattle_left(Lt, e, Tt, dia, e, False)
        _rattle_left(Lh, e, Th, dia, e, True)
        if e > 0:
            _rattle_left(Lh, e - 1, Tt, sup, e - 1, False)
        if e < ne - 1:
            _rattle_left(Lt, e + 1, Th, sub, e + 1, False)
    return bt_factor(sub, dia, sup, inv, mult)


def rattle_factor_sym(tail, head, B_t, B_h, P, F, pdiag):
    """Assemble and factor the symmetric positive definite ``B P Bᵀ`` on the chain by the block
    Cholesky factorisation (:func:`~cartan.compiled.banded.bs_factor`; ``F = (sub, diag, -, L,
    M)``, each ``[E, c, c]``, solved by ``bs_solve(F[3], F[4], ·, ·)``): the lower triangle of
    the diagonal ``Bt_e P_i Bt_eᵀ + Bh_e P_j Bh_eᵀ`` and the block below it
    ``Bt_e P_i Bh_{e−1}ᵀ`` (node i = tail of e = head of e − 1; the block above is its
    transpose, P symmetric), each node's ``P Bᵀ`` formed once; returns False when the matrix is
    not positive definite to working precision (``pdiag`` as in :func:`rattle_factor`)."""
    sub, dia = F[0], F[1]
    ne = B_t.shape[0]
    c = B_t.shape[1]
    Tt = np.empty((R_, c))  # noqa: F821
    Th = np.empty((R_, c))  # noqa: F821
    for e in range(ne):
        i, j = tail[e], head[e]
        _rattle_right(P, i, B_t, e, Tt, pdiag)
        _rattle_right(P, j, B_h, e, Th, pdiag)
        for a in range(c):
            for b in range(a + 1):
                s = 0.0
                for k in range(R_):  # noqa: F821
                    s += B_t[e, a, k] * Tt[k, b] + B_h[e, a, k] * Th[k, b]
                dia[e, a, b] = s
        if e < ne - 1:
            _rattle_left(B_t, e + 1, Th, sub, e + 1, False)
    return bs_factor(sub, dia, F[3], F[4])


def rattle_apply(tail, head, Bt, Bh, V, out):
    """``out[e] = Bt_e V_i + Bh_e V_j`` ``[E, c]`` (B_c applied to a nodal field ``V`` ``[n, r]``)."""
    for e in range(Bt.shape[0]):
        i, j = tail[e], head[e]
        for a in range(Bt.shape[1]):
            s = 0.0
            for k in range(R_):  # noqa: F821
                s += Bt[e, a, k] * V[i, k] + Bh[e, a, k] * V[j, k]
            out[e, a] = s


def rattle_impulse(tail, head, winv, Bt, Bh, nu, out):
    """``out[i] = (B_cᵀν)_i / w_i`` ``[n, r]``: the force density of the nodal impulse B_cᵀν."""
    for i in range(out.shape[0]):
        for k in range(R_):  # noqa: F821
            out[i, k] = 0.0
    for e in range(Bt.shape[0]):
        i, j = tail[e], head[e]
        for k in range(R_):  # noqa: F821
            si = 0.0
            sj = 0.0
            for a in range(Bt.shape[1]):
                si += Bt[e, a, k] * nu[e, a]
                sj += Bh[e, a, k] * nu[e, a]
            out[i, k] += si
            out[j, k] += sj
    for i in range(out.shape[0]):
        for k in range(R_):  # noqa: F821
            out[i, k] *= winv[i]


def rattle_project_velocity(tail, head, winv, S, N, Bt, Bh, bmax, F, factored, P, pdiag, fscale, closing, use_closing,
                            half, skip, res, mu, imp, fixed):
    """Add the impulse ``½Δt·closing·B_cᵀμ/w`` that makes ``B_c N = 0``: ``(B P Bᵀ)μ = −B N/(½Δt)``
    with ``F`` the block Cholesky factors of ``B P Bᵀ/fscale`` (:func:`rattle_factor_sym`; built
    here, with ``fscale`` = 1, unless ``factored``); with ``skip``, nothing when
    ``max|B N| ≤ 1e-13·max|B|·max|N|`` (tangent to round-off).  ``N`` is the velocity of ``S``
    on entry.  Returns ``(projected, factored, ok)``; after a projection the caller applies the
    scheme's constraint to S (``op_constrain``, or :func:`_rattle_zero` without driven nodes):
    the lattice's arrays are passed (``tail``, ``head`` ``[E]``, ``winv`` ``[n]``), not ``D``."""
    rattle_apply(tail, head, Bt, Bh, N, res)
    if skip:
        rmax = 0.0
        for e in range(res.shape[0]):
            for a in range(res.shape[1]):
                rmax = max(rmax, abs(res[e, a]))
        nmax = 0.0  # (over the unknowns: a driven node's ξ is not one)
        for i in range(N.shape[0]):
            for k in range(R_):  # noqa: F821
                if not fixed[i, k]:
                    nmax = max(nmax, abs(N[i, k]))
        if rmax <= 1e-13 * bmax * nmax:
            return False, factored, True
    if not factored:
        if not rattle_factor_sym(tail, head, Bt, Bh, P, F, pdiag):
            return False, False, False
        factored = True
    bs_solve(F[3], F[4], res, mu)
    for e in range(mu.shape[0]):
        for a in range(mu.shape[1]):
            mu[e, a] = -mu[e, a] / (half * fscale)
    rattle_impulse(tail, head, winv, Bt, Bh, mu, imp)
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            if use_closing:
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += closing[k, j] * imp[i, j]
            else:
                s = imp[i, k]
            S[i, k] += half * s
    return True, factored, True


def _rattle_project_config(D, C, comp, value, scale, Bt, Bh, Ae, Xe, P, pdiag, F, cres, y, delta, K, fixed):
    """Bring C onto c = 0 by Gauss–Newton steps ``δ = −P Bᵀ(B P Bᵀ)⁻¹c`` along the drift (the
    Python step's ``_project_configuration``); returns the residual, or −1 when it did not
    converge in ``MAX_ITERATIONS_`` steps (the Python step's limit)."""
    row = np.empty(R_)  # noqa: F821
    err = rattle_values(D.einvh, C[0], comp, value, cres, Xe)
    for _ in range(MAX_ITERATIONS_):  # noqa: F821
        if err <= 1e-13 * scale:
            return err
        rattle_rows(D.tail, D.head, D.einvh, C[0], comp, Bt, Bh, Ae, Xe, err >= 0.0, fixed)
        if not rattle_factor_sym(D.tail, D.head, Bt, Bh, P, F, pdiag):
            return -1.0
        bs_solve(F[3], F[4], cres, y)
        rattle_impulse(D.tail, D.head, D.winv, Bt, Bh, y, delta)  # (B_cᵀy)_i / w_i
        for i in range(delta.shape[0]):  # δ_i = −w_i P_i (B_cᵀy)_i / w_i (P carries the 1/w)
            for k in range(R_):  # noqa: F821
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += P[i, k, j] * delta[i, j]
                row[k] = -s * D.w[i]
            for k in range(R_):  # noqa: F821
                delta[i, k] = row[k]
        op_drift(D, C, 1.0, delta, K)  # noqa: F821
        nxt = rattle_values(D.einvh, C[0], comp, value, cres, Xe)
        if nxt > 0.5 * err and nxt <= 1e-10 * scale:
            return nxt
        err = nxt
    return err if err <= 1e-13 * scale else -1.0


def _rattle_rate(tail, head, einvh, N, comp, Ae, Xe, out, vs, ms):
    """``out[e, a]`` = (Ḃ_c N)_{e,a} ``[E, c]``, the rows' second derivative along the drift
    Φ ← Φ exp(εN) (the Python step's ``_rows_rate``): ``ξ'' = ½[ξ', N_i + N_j] +
    (1/12)(ad_ξ ad_ξ' + ad_ξ' ad_ξ)(N_j − N_i)`` over h, with ξ = hX_e, ξ' = dexp⁻¹(−ξ)N_j −
    dexp⁻¹(ξ)N_i (from ``Ae``, ``Xe`` of :func:`rattle_rows` at the same configuration).
    ``vs`` ``[5, r]`` and ``ms`` ``[2, r, r]`` are scratch, allocated once by the loop (this
    helper is inlined into every step)."""
    u, sm, df, w1, w2 = vs[0], vs[1], vs[2], vs[3], vs[4]
    adx, adu = ms[0], ms[1]
    for e in range(Ae.shape[0]):
        i, j = tail[e], head[e]
        g_ad(Xe[e], adx)  # noqa: F821
        for k in range(R_):  # noqa: F821
            v = 0.0
            for m in range(R_):  # noqa: F821
                v += (Ae[e, k, m] + adx[k, m]) * N[j, m] - Ae[e, k, m] * N[i, m]
            u[k] = v
            sm[k] = N[i, k] + N[j, k]
            df[k] = N[j, k] - N[i, k]
        g_ad(u, adu)  # noqa: F821
        for k in range(R_):  # noqa: F821
            p = 0.0
            q = 0.0
            for m in range(R_):  # noqa: F821
                p += adu[k, m] * df[m]
                q += adx[k, m] * df[m]
            w1[k] = p
            w2[k] = q
        for a in range(comp.shape[0]):
            k = comp[a]
            p = 0.0
            q = 0.0
            for m in range(R_):  # noqa: F821
                p += adu[k, m] * sm[m]
                q += adx[k, m] * w1[m] + adu[k, m] * w2[m]
            out[e, a] = (0.5 * p + (1.0 / 12.0) * q) * einvh[e]


def _rattle_accelerations(tail, head, inv_metric, S, N, W, Bt, Bh, work, acc, out, fixed):
    """``out = B[M⁺(ad_NᵀS + W)]`` ``[E, c]``: the rows of the unconstrained acceleration ``acc``
    ``[n, r]`` (zero on the components that are no unknowns); ``work`` ``[n, r]`` is scratch."""
    n = S.shape[0]
    _lie_poisson(N, S, W, work)  # noqa: F821 - W + ad_NᵀS (cartan.integrators.loops)
    for i in range(n):
        for k in range(R_):  # noqa: F821
            s = 0.0
            for j in range(R_):  # noqa: F821
                s += inv_metric[k, j] * work[i, j]
            acc[i, k] = 0.0 if fixed[i, k] else s
    rattle_apply(tail, head, Bt, Bh, acc, out)


def _rattle_predict(tail, head, einvh, inv_metric, S, N, W, Bt, Bh, F, comp, Ae, Xe, work, acc, nu, rate, fixed, vs,
                    ms):
    """The force-level multiplier at the step's start (the Python step's ``_predict``):
    ``(B P Bᵀ)λ = −B[M⁺(ad_NᵀS + W)] − Ḃ_c N`` (:func:`_rattle_rate`), ``F`` the block Cholesky
    factors of ``B P Bᵀ`` (:func:`rattle_factor_sym`); λ into ``nu``; ``rate`` ``[E, c]``,
    ``vs`` ``[5, r]`` and ``ms`` ``[2, r, r]`` are scratch."""
    _rattle_accelerations(tail, head, inv_metric, S, N, W, Bt, Bh, work, acc, nu, fixed)
    _rattle_rate(tail, head, einvh, N, comp, Ae, Xe, rate, vs, ms)
    for e in range(nu.shape[0]):
        for a in range(nu.shape[1]):
            nu[e, a] += rate[e, a]
    bs_solve(F[3], F[4], nu, nu)
    for e in range(nu.shape[0]):
        for a in range(nu.shape[1]):
            nu[e, a] = -nu[e, a]


def _rattle_support_power(D, C, S, N, W, comp, Bt, Bh, P, pdiag, F, factored, work, acc, lam, rate, rp, Cd, Btd,
                          Bhd, Aed, Xed, K, no, fixed):
    """The power ``−λᵀB_dξ`` of the constraint force on the driven nodes (the Python step's
    ``Rattle._powers``, part of the supports'): λ ``[E, c]`` the force-level multipliers at C,
    ``(B P Bᵀ)λ = −B[M⁺(ad_NᵀS + W)] − Ḃ_c N`` with the rows' rate to round-off — the central
    difference of ``B_c(Φ exp(εN))N`` over ε = ±ε₀, ε₀ = 1e-5/max|N| (``_rows_rate_exact``; the
    drifts of a copy ``Cd`` of C, the rows there in ``Btd``/``Bhd``/``Aed``/``Xed``) — and
    ``B_dᵀλ`` the rows' force on the driven nodes' components (``Bt``/``Bh`` ``[E, c, r]`` the
    rows at C, ``N`` ``[n, r]`` the velocity there, ξ at the driven nodes).  ``F`` the block
    Cholesky factors of ``B P Bᵀ`` when ``factored``, else factored here.  Returns
    ``(power, factored, ok)``."""
    if not factored:
        if not rattle_factor_sym(D.tail, D.head, Bt, Bh, P, F, pdiag):
            return 0.0, False, False
        factored = True
    _rattle_accelerations(D.tail, D.head, D.inv_metric, S, N, W, Bt, Bh, work, acc, lam, fixed)
    n = S.shape[0]
    nmax = 0.0
    for i in range(n):
        for k in range(R_):  # noqa: F821
            nmax = max(nmax, abs(N[i, k]))
    eps = 1e-5 / max(nmax, 1e-300)
    for side in range(2):
        sign = 1.0 if side == 0 else -1.0
        _rattle_copy(C, Cd)
        op_drift(D, Cd, sign * eps, N, K)  # noqa: F821
        rattle_rows(D.tail, D.head, D.einvh, Cd[0], comp, Btd, Bhd, Aed, Xed, no, fixed)
        rattle_apply(D.tail, D.head, Btd, Bhd, N, rate if side == 0 else rp)
    for e in range(lam.shape[0]):
        for a in range(lam.shape[1]):
            lam[e, a] += (rate[e, a] - rp[e, a]) / (2.0 * eps)
    bs_solve(F[3], F[4], lam, lam)
    power = 0.0
    for e in range(Bt.shape[0]):
        i, j = D.tail[e], D.head[e]
        di = D.dslot[i] >= 0
        dj = D.dslot[j] >= 0
        if not (di or dj):
            continue
        for k in range(R_):  # noqa: F821
            si = 0.0
            sj = 0.0
            for a in range(Bt.shape[1]):
                si += Bt[e, a, k] * lam[e, a]
                sj += Bh[e, a, k] * lam[e, a]
            if di:  # (lam holds −λ: −λᵀB_dξ = Σ (B_dᵀ lam)·ξ)
                power += si * D.xi_d[i, k]
            if dj:
                power += sj * D.xi_d[j, k]
    return power, factored, True


def _rattle_powers(D, C, S, N, W, t, comp, Bt, Bh, P, pdiag, F, factored, work, acc, lam, rate, rp, Cd, Btd, Bhd,
                   Aed, Xed, K, no, fixed):
    """The loads' powers at (C, N, t) with the rows' power on the driven nodes added to the external
    one (:func:`_rattle_support_power`, same arguments); returns ``(dissipated, external,
    factored, ok)``."""
    pd, pe = op_powers(D, C, N, t, K)  # noqa: F821
    pw, factored, ok = _rattle_support_power(D, C, S, N, W, comp, Bt, Bh, P, pdiag, F, factored, work, acc, lam,
                                             rate, rp, Cd, Btd, Bhd, Aed, Xed, K, no, fixed)
    return pd, pe + pw, factored, ok


def _rattle_copy(src, dst):
    """``dst ← src`` for configurations of 3-D arrays (the lattice's ``(G, Phi)``)."""
    for a in range(len(src)):
        x = src[a]
        y = dst[a]
        for i in range(x.shape[0]):
            for j in range(x.shape[1]):
                for k in range(x.shape[2]):
                    y[i, j, k] = x[i, j, k]


def rattle_trial_flow(tail, head, any_clamped, clamped, any_held, held, G, S, pieces, plan, Dn, Di, Pz, xi, out, E,
                      tmp, eye, wk, TK):
    """A trial's free flow: ``op_free_flow`` (the lattice's, :mod:`cartan.schemes._lattice_ops`)
    on the edges ``G`` ``[E, m, m]`` only, its pieces read once per call of the loop (``plan``,
    ``_flow_plan``) and its scratch (``xi``, ``out`` ``[r]``, ``E``, ``tmp``, ``eye`` (the identity)
    ``[m, m]``, ``wk`` (``g_work()``), ``TK`` ``[FCHUNK_, r]``) allocated once: the same passes
    (``_flow_chunk``, ``_driven_flow``) leave each node's motion in ``Dn`` ``[n, m, m]``, then
    ``Di = Dn⁻¹`` ``[n, m, m]`` (``g_frames_chunk`` with ``Pz`` ``[0, m, m]``: no frame) and the
    edges ``G_e ← Di_i G_e Dn_j`` (``g_move_chunk``) — ``op_move``'s operations, so the edges
    are those of ``op_free_flow`` to the bit.  The frames Φ, which the rows do not read, follow
    once the iteration has converged (``g_frames_chunk`` by the last trial's ``Dn``: the loop).
    Returns whether a node moved (``op_free_flow``'s result).  The lattice's arrays it reads
    (``tail``, ``head`` ``[E]``, ``clamped`` ``[n]``, ``held`` ``[n, r]`` and their flags) are
    passed, not ``D`` (see :func:`rattle_values`); no driven node (the loop takes
    ``op_free_flow`` then)."""
    npieces, tau, axial, naxes, axes, coef, cnt, col = plan
    n = S.shape[0]
    moved = False
    for lo in range(0, n, FCHUNK_):  # noqa: F821
        if _flow_chunk(lo, min(n, lo + FCHUNK_), S, Dn, any_clamped, clamped, any_held, held,  # noqa: F821
                       pieces, npieces, tau, axial, naxes, axes, coef, cnt, col, eye, xi, out, E, tmp, wk, TK):
            moved = True
    if moved:
        g_frames_chunk(Dn, Di, Pz, 0, n)  # noqa: F821
        g_move_chunk(Di, Dn, G, tail, head, 0, G.shape[0])  # noqa: F821
    return moved


def rattle_trial_kick(tail, head, winv, Bt, Bh, nu, S0, W, half, imp, S, fixed, own):
    """A trial's kick ``S = S0 + ½Δt(W + B_cᵀν/w)`` ``[n, r]`` (``imp`` ``[n, r]`` the impulse
    :func:`rattle_impulse` makes: the same sums in the same order), then, with ``own``, S zeroed
    where ``fixed`` ``[n, r]`` (:func:`_rattle_fixed`: ``op_constrain``'s components, without
    driven nodes); ``tail``, ``head`` ``[E]`` and ``winv`` ``[n]`` the lattice's arrays."""
    rattle_impulse(tail, head, winv, Bt, Bh, nu, imp)
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            S[i, k] = S0[i, k] + half * (W[i, k] + imp[i, k])
            if own and fixed[i, k]:
                S[i, k] = 0.0


def _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N):
    """``N = M⁺S`` ``[n, r]``, zero at clamped nodes and on held components: ``op_velocity`` on
    a lattice without driven nodes (the same sums), from the lattice's arrays rather than ``D``."""
    for i in range(S.shape[0]):
        if any_clamped and clamped[i]:
            for k in range(R_):  # noqa: F821
                N[i, k] = 0.0
        else:
            for k in range(R_):  # noqa: F821
                if any_held and held[i, k]:
                    N[i, k] = 0.0
                    continue
                v = 0.0
                for j in range(R_):  # noqa: F821
                    v += inv_metric[k, j] * S[i, j]
                N[i, k] = v


def _rattle_zero(S, fixed):
    """``S[i, k] = 0`` where ``fixed[i, k]`` ``[n, r]``: ``op_constrain`` on a lattice without
    driven nodes (the gauge components, clamped nodes, held components: :func:`_rattle_fixed`)."""
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            if fixed[i, k]:
                S[i, k] = 0.0


def _rattle_copy_edges(src, dst):
    """``dst ← src`` for ``[E, m, m]`` arrays (a trial restores the edges only)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            for k in range(src.shape[2]):
                dst[i, j, k] = src[i, j, k]


def _rattle_factors(ne, c):
    return (np.zeros((ne, c, c)), np.zeros((ne, c, c)), np.zeros((ne, c, c)), np.zeros((ne, c, c)),
            np.zeros((ne, c, c)))


# ---------------------------------------------------------------------------- the loop
def rattle_loop(D, C, S, W, have_w, velocity_free, pieces, fracs, closing, comp, value, scale, offset, offset_dt,
                status, info, t, dt, nsteps, diss, ext, check, limit):
    """``rattle`` (see the module docstring): ``W`` ``[n, r]`` carries the force between steps
    (first-same-as-last when ``velocity_free``), ``pieces``/``fracs`` lie-verlet's split free flow,
    ``closing`` ``(I + ½ΔtΓM⁺)⁻¹`` ``[r, r]``, ``comp``/``value`` ``[c]`` the held components and
    their values, ``scale`` max(1, max|value|) (the tolerances' unit), ``offset`` ``[3, E, c]``
    the last three steps' ν − λ, newest first, and ``offset_dt`` ``[3]`` their Δt (0: none;
    ``State.memory``: read, and written after every step); the predictor extrapolates the
    offsets of the leading run of those taken with this Δt (constant, linear or quadratic in
    the step for one, two or three)."""
    K = op_work(D)  # noqa: F821
    n = S.shape[0]
    ne = D.tail.shape[0]
    nc = comp.shape[0]
    half = 0.5 * dt
    fixed = _rattle_fixed(D, n)  # which components are no unknowns of the rows [n, r]
    # the lattice's arrays the helpers called at every step or trial take, rather than D itself:
    # numba counts a reference to each of D's arrays at every call of a function that takes it
    # (≈ 0.35 µs a call, ≈ 40 calls a step)
    tail, head, winv, einvh, inv_metric = D.tail, D.head, D.winv, D.einvh, D.inv_metric
    any_clamped, clamped, any_held, held = D.any_clamped, D.clamped, D.any_held, D.held
    plain = not D.any_driven  # (driven nodes: the operators' op_velocity and op_constrain)
    N = np.empty((n, R_))  # noqa: F821
    Dn = np.empty((n, M_, M_))  # noqa: F821
    rhs = np.empty(R_)  # noqa: F821
    work = np.empty((n, R_))  # noqa: F821
    acc = np.empty((n, R_))  # noqa: F821
    imp = np.empty((n, R_))  # noqa: F821
    S0 = S.copy()
    C0 = op_new_config(C)  # noqa: F821
    Bt0 = np.zeros((ne, nc, R_))  # noqa: F821 - rows at the step's start (the last step's closing rows)
    Bh0 = np.zeros((ne, nc, R_))  # noqa: F821
    Bt1 = np.zeros((ne, nc, R_))  # noqa: F821 - rows at the first trial
    Bh1 = np.zeros((ne, nc, R_))  # noqa: F821
    c0 = np.empty((ne, nc))
    cres = np.empty((ne, nc))  # the rows' values at the trial (at the end of a step: at C)
    pres = np.empty((ne, nc))
    nu = np.empty((ne, nc))
    lam = np.empty((ne, nc))
    mu = np.empty((ne, nc))
    dnu = np.empty((ne, nc))
    eye = np.zeros((R_, R_))  # noqa: F821
    for k in range(R_):  # noqa: F821
        eye[k, k] = 1.0
    Pm = np.empty((n, R_, R_))  # noqa: F821
    Pc = np.empty((n, R_, R_))  # noqa: F821
    Pj = np.empty((n, R_, R_))  # noqa: F821
    rattle_metric(D, eye, Pm, fixed)
    rattle_metric(D, closing, Pc, fixed)
    pm_diag = _rattle_diagonal(Pm)
    pc_diag = _rattle_diagonal(Pc)
    # a closing matrix s·I on the live block (Γ_k M⁺_kk the same on every live component: damping
    # proportional to the inertia) makes B P_closing Bᵀ = s·B P Bᵀ: the closing kick's projection
    # then solves with the factors of B P Bᵀ, which the next step's start needs anyway
    sc = 1.0
    uniform = False
    if not velocity_free:
        uniform = True
        first = -1
        for k in range(R_):  # noqa: F821
            if not D.live[k]:
                continue
            if first < 0:
                first = k
                sc = closing[k, k]
            for j in range(R_):  # noqa: F821
                if D.live[j] and j != k and closing[k, j] != 0.0:
                    uniform = False
            if abs(closing[k, k] - sc) > 1e-14 * abs(sc):
                uniform = False
        if first < 0 or not sc > 0.0:
            uniform = False
    Z = np.zeros((n, R_))  # noqa: F821 - N = 0: the velocity-free part of the force
    cp = np.empty((ne, nc))
    Ae = np.empty((ne, R_, R_))  # noqa: F821 - dexp⁻¹(hX_e) and hX_e of the last rows (_rattle_rate)
    Xe = np.empty((ne, R_))  # noqa: F821
    Fs = _rattle_factors(ne, nc)  # B₀ P B₀ᵀ (start; block Cholesky, rattle_factor_sym)
    Fc = _rattle_factors(ne, nc)  # B⁺ P_closing B⁺ᵀ (closing kick; block Cholesky)
    Fq = _rattle_factors(ne, nc)  # B₁ J B₀ᵀ (quasi-Newton)
    # driven ends: the power of the rows' force on the driven nodes (_rattle_support_power) and
    # the start's velocity projection's work; the powers a call starts from are taken once the
    # first step's start is known (after its velocity projection, as the Python step takes them)
    driven = D.any_driven
    pending = driven
    nd_e = ne if driven else 0
    Cd = op_new_config(C)  # noqa: F821
    Btd = np.zeros((nd_e, nc, R_))  # noqa: F821
    Bhd = np.zeros((nd_e, nc, R_))  # noqa: F821
    Aed = np.empty((nd_e, R_, R_))  # noqa: F821
    Xed = np.empty((nd_e, R_))  # noqa: F821
    rq = np.empty((ne, nc))
    Wp = np.empty((n, R_))  # noqa: F821
    rvs = np.empty((5, R_))  # noqa: F821 - the scratch of the rows' rate (_rattle_rate), once per call
    # the trials' free flow (rattle_trial_flow): its plan and scratch once per call, on chains of at
    # most FCHUNK_ nodes (one chunk of the flow's passes: the threaded build's op_free_flow, which
    # longer chains take, would split nothing there either)
    own_flow = n <= FCHUNK_ and plain  # noqa: F821
    plan = _flow_plan(pieces, fracs, dt)  # noqa: F821
    fxi = np.zeros(R_)  # noqa: F821
    fout = np.empty(R_)  # noqa: F821
    fE = np.empty((M_, M_))  # noqa: F821
    ftmp = np.empty((M_, M_))  # noqa: F821
    feye = np.empty((M_, M_))  # noqa: F821
    g_exp(fxi, feye)  # noqa: F821 - the identity
    fwk = g_work()  # noqa: F821
    fTK = np.empty((FCHUNK_, R_))  # noqa: F821
    Di = np.empty((n, M_, M_))  # noqa: F821
    Pz = np.empty((0, M_, M_))  # noqa: F821
    moved = False
    rms = np.empty((2, R_, R_))  # noqa: F821
    # run-time booleans (not literals: a literal argument would compile the callee once per value)
    yes = nsteps >= 0
    no = not yes
    have_b = False  # Bt0/Bh0 hold the rows at C
    have_fs = False  # Fs factors B₀ Pm B₀ᵀ
    bmax = 0.0
    nforce = 0
    niter = 0
    if plain:
        _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
    else:
        op_velocity(D, S, N)  # noqa: F821
    p0d, p0e = 0.0, 0.0
    if not driven:
        p0d, p0e = op_powers(D, C, N, t, K)  # noqa: F821
    done = 0
    for _ in range(nsteps):
        # the step starts on the manifold ...
        if have_b:  # the values at the end of the last step's iteration: the same configuration
            err0 = 0.0
            for e in range(ne):
                for a in range(nc):
                    c0[e, a] = cres[e, a]
                    err0 = max(err0, abs(cres[e, a]))
        else:
            err0 = rattle_values(D.einvh, C[0], comp, value, c0, Xe)
        # the offsets of the last steps taken with this Δt, newest first (at most three)
        nprev = 0
        while nprev < 3 and offset_dt[nprev] == dt:
            nprev += 1
        on_manifold = err0 <= 1e-10 * scale
        if not on_manifold and pending:  # the powers at the state as it is (the Python step's order)
            if plain:
                _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
            else:
                op_velocity(D, S, N)  # noqa: F821
            if have_w and velocity_free:
                for i in range(n):
                    for k in range(R_):  # noqa: F821
                        Wp[i, k] = W[i, k]
            else:
                op_force(D, C, t, N, Wp, K)  # noqa: F821
            rattle_rows(tail, head, einvh, C[0], comp, Btd, Bhd, Aed, Xed, no, fixed)
            p0d, p0e = op_powers(D, C, N, t, K)  # noqa: F821
            pw, _, ok = _rattle_support_power(D, C, S, N, Wp, comp, Btd, Bhd, Pm, pm_diag, Fc, no, work, acc, dnu, cp,
                                              rq, Cd, Bt1, Bh1, Ae, Xe, K, no, fixed)
            if not ok:
                status[0] = 3
                info[0] = np.nan
                break
            p0e += pw
            pending = False
        if not on_manifold:
            nprev = 0
            err0 = _rattle_project_config(D, C, comp, value, scale, Bt0, Bh0, Ae, Xe, Pm, pm_diag, Fs, cres, dnu, imp,
                                          K, fixed)
            if err0 < 0.0:
                status[0] = 2
                info[0] = rattle_values(D.einvh, C[0], comp, value, c0, Xe)
                break
            have_w = False
            have_b = False
            have_fs = False
        if not have_b:  # (the last values, c0 or the projection's, were taken at C: their logs)
            bmax = rattle_rows(tail, head, einvh, C[0], comp, Bt0, Bh0, Ae, Xe, yes, fixed)
            have_fs = False
        # ... with a tangent velocity
        if plain:
            _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
        else:
            op_velocity(D, S, N)  # noqa: F821
        k0 = op_kinetic(D, S) if driven and on_manifold else 0.0  # noqa: F821
        projected, have_fs, ok = rattle_project_velocity(tail, head, winv, S, N, Bt0, Bh0, bmax, Fs, have_fs, Pm,
                                                         pm_diag, 1.0, eye, no, half, yes, pres, mu, imp, fixed)
        if projected:
            if plain:
                _rattle_zero(S, fixed)
            else:
                op_constrain(D, S)  # noqa: F821
        if not ok:
            status[0] = 3
            info[0] = np.nan
            break
        if projected:
            have_w = False
            if plain:
                _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
            else:
                op_velocity(D, S, N)  # noqa: F821
            if driven and on_manifold:  # the support's impulse sets the free nodes in motion: its work
                ext += op_kinetic(D, S) - k0  # noqa: F821
        if not have_w:
            if velocity_free:
                op_force(D, C, t, N, W, K)  # noqa: F821
            else:  # as the closing kick leaves it, W(N = 0) − ΓN: the same W whether the last step ran
                op_force(D, C, t, Z, W, K)  # noqa: F821 - in this call, an earlier one or before a restart
                _damped(D, W, N)  # noqa: F821
            nforce += 1
        if pending:
            p0d, p0e, have_fs, ok = _rattle_powers(D, C, S, N, W, t, comp, Bt0, Bh0, Pm, pm_diag, Fs, have_fs, work,
                                                   acc, dnu, cp, rq, Cd, Btd, Bhd, Aed, Xed, K, no, fixed)
            if not ok:
                status[0] = 3
                info[0] = np.nan
                break
            pending = False
        for i in range(n):
            for k in range(R_):  # noqa: F821
                S0[i, k] = S[i, k]
        _rattle_copy(C, C0)
        if not have_fs:
            if not rattle_factor_sym(tail, head, Bt0, Bh0, Pm, Fs, pm_diag):
                status[0] = 3
                info[0] = np.nan
                break
            have_fs = True
        _rattle_predict(tail, head, einvh, inv_metric, S, N, W, Bt0, Bh0, Fs, comp, Ae, Xe, work, acc, nu, cp, fixed,
                        rvs, rms)
        for e in range(ne):  # λ, and the predictor λ + (ν − λ) extrapolated from the last steps
            for a in range(nc):
                lam[e, a] = nu[e, a]
                if nprev == 1:
                    nu[e, a] += offset[0, e, a]
                elif nprev == 2:
                    nu[e, a] += 2.0 * offset[0, e, a] - offset[1, e, a]
                elif nprev == 3:
                    nu[e, a] += 3.0 * offset[0, e, a] - 3.0 * offset[1, e, a] + offset[2, e, a]
        # the position multipliers: c(Φₙ₊₁(ν)) = 0 by quasi-Newton steps
        prev = np.inf
        factored = False
        failed = False
        it = 0
        while True:
            rattle_trial_kick(tail, head, winv, Bt0, Bh0, nu, S0, W, half, imp, S, fixed, own_flow)
            if own_flow:  # the edges only (rattle_trial_flow); the frames once converged, below
                _rattle_copy_edges(C0[0], C[0])
                moved = rattle_trial_flow(tail, head, any_clamped, clamped, any_held, held, C[0], S, pieces, plan, Dn,
                                          Di, Pz, fxi, fout, fE, ftmp, feye, fwk, fTK)
                _rattle_zero(S, fixed)
            else:
                op_constrain(D, S)  # noqa: F821
                _rattle_copy(C0, C)
                op_free_flow(D, C, S, pieces, fracs, dt, Dn, K)  # noqa: F821
                op_constrain(D, S)  # noqa: F821
            err = rattle_values(D.einvh, C[0], comp, value, cres, Xe)
            if err <= 1e-13 * scale or (factored and err <= 1e-10 * scale and err > 0.5 * prev):
                break
            if not np.isfinite(err) or it == MAX_ITERATIONS_:  # noqa: F821
                failed = True
                info[0] = err
                break
            if not factored and it > 0 and err > SLOW_ * prev:  # noqa: F821 - the chord gains too little
                rattle_rows(tail, head, einvh, C[0], comp, Bt1, Bh1, Ae, Xe, yes, fixed)
                if plain:
                    _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
                else:
                    op_velocity(D, S, N)  # noqa: F821
                _rattle_flow_jacobian(D, N, dt, Pj, fixed)
                if not rattle_factor(tail, head, Bt1, Bh1, Pj, Bt0, Bh0, Fq, no):
                    failed = True
                    info[0] = err
                    break
                factored = True
            if factored:  # Newton's matrix ½Δt B₁ J B₀ᵀ
                bt_solve(Fq[2], Fq[3], Fq[4], cres, dnu)
                for e in range(ne):
                    for a in range(nc):
                        nu[e, a] -= dnu[e, a] / half
            else:  # the chord ½Δt·Δt B₀ P B₀ᵀ
                bs_solve(Fs[3], Fs[4], cres, dnu)
                for e in range(ne):
                    for a in range(nc):
                        nu[e, a] -= dnu[e, a] / (half * dt)
            prev = err
            it += 1
        if failed:
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    S[i, k] = S0[i, k]
            _rattle_copy(C0, C)
            status[0] = 1
            break
        if own_flow and moved:  # the frames by the converged trial's motions: Φ_i ← Φ_i Dn_i (op_move's)
            g_frames_chunk(Dn, Di, C[1], 0, n)  # noqa: F821
        niter += it
        # the next step's offset ν − λ, ν with one more correction of the last matrix (no flow),
        # the older ones moved down (after a projection they do not count: their Δt is cleared)
        for m in range(2, 0, -1):
            offset_dt[m] = offset_dt[m - 1] if nprev > 0 else 0.0
            for e in range(ne):
                for a in range(nc):
                    offset[m, e, a] = offset[m - 1, e, a]
        if factored:
            bt_solve(Fq[2], Fq[3], Fq[4], cres, dnu)
            for e in range(ne):
                for a in range(nc):
                    offset[0, e, a] = nu[e, a] - dnu[e, a] / half - lam[e, a]
        else:
            bs_solve(Fs[3], Fs[4], cres, dnu)
            for e in range(ne):
                for a in range(nc):
                    offset[0, e, a] = nu[e, a] - dnu[e, a] / (half * dt) - lam[e, a]
        offset_dt[0] = dt
        # the closing kick and its velocity multiplier
        t1 = t + dt
        bmax = rattle_rows(tail, head, einvh, C[0], comp, Bt0, Bh0, Ae, Xe, yes, fixed)  # (the last trial's logs: at C)
        have_b = True
        if velocity_free:
            if plain:
                _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
            else:
                op_velocity(D, S, N)  # noqa: F821
            op_force(D, C, t1, N, W, K)  # noqa: F821
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    S[i, k] += half * W[i, k]
            if plain:
                _rattle_zero(S, fixed)
            else:
                op_constrain(D, S)  # noqa: F821
            if plain:
                _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
            else:
                op_velocity(D, S, N)  # noqa: F821
            projected, have_fs, ok = rattle_project_velocity(tail, head, winv, S, N, Bt0, Bh0, bmax, Fs, no, Pm,
                                                             pm_diag, 1.0, eye, no, half, no, pres, mu, imp, fixed)
        else:
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    N[i, k] = 0.0
            op_force(D, C, t1, N, W, K)  # noqa: F821
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    rhs[k] = S[i, k] + half * W[i, k]
                for k in range(R_):  # noqa: F821
                    v = 0.0
                    for j in range(R_):  # noqa: F821
                        v += closing[k, j] * rhs[j]
                    S[i, k] = v
            if plain:
                _rattle_zero(S, fixed)
            else:
                op_constrain(D, S)  # noqa: F821
            if plain:
                _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
            else:
                op_velocity(D, S, N)  # noqa: F821
            if uniform:  # B P_closing Bᵀ = s·B P Bᵀ: the factors of B P Bᵀ, kept for the next step
                projected, have_fs, ok = rattle_project_velocity(tail, head, winv, S, N, Bt0, Bh0, bmax, Fs, no, Pm,
                                                                 pm_diag, sc, closing, yes, half, no, pres, mu, imp,
                                                                 fixed)
            else:
                projected, _, ok = rattle_project_velocity(tail, head, winv, S, N, Bt0, Bh0, bmax, Fc, no, Pc, pc_diag,
                                                           1.0, closing, yes, half, no, pres, mu, imp, fixed)
                have_fs = False
        if projected:  # (the projection's S under the scheme's constraint)
            if plain:
                _rattle_zero(S, fixed)
            else:
                op_constrain(D, S)  # noqa: F821
        if not ok:
            status[0] = 3
            info[0] = np.nan
            break
        nforce += 1
        have_w = True
        if plain:
            _rattle_velocity(inv_metric, any_clamped, clamped, any_held, held, S, N)
        else:
            op_velocity(D, S, N)  # noqa: F821
        if not velocity_free:
            _damped(D, W, N)  # noqa: F821
        t = t1
        done += 1
        if driven:  # the loads' powers and the rows' on the driven nodes (W: the force at the step's end)
            p1d, p1e, have_fs, ok = _rattle_powers(D, C, S, N, W, t, comp, Bt0, Bh0, Pm, pm_diag, Fs, have_fs, work,
                                                   acc, dnu, cp, rq, Cd, Btd, Bhd, Aed, Xed, K, no, fixed)
            if not ok:
                status[0] = 3
                info[0] = np.nan
                break
            diss += 0.5 * dt * (p0d + p1d)
            ext += 0.5 * dt * (p0e + p1e)
            p0d, p0e = p1d, p1e
            blown = _blown(D, C, S, check, limit)  # noqa: F821
        else:
            p0d, p0e, diss, ext, blown = _book(D, C, S, N, t, dt, p0d, p0e, diss, ext, K, check, limit)  # noqa: F821
        if blown:
            break
    status[1] = niter
    return done, nforce, t, diss, ext


def loop_fragment() -> Fragment:
    """The rattle loop, its helpers and the block-tridiagonal solver as one fragment of a
    generated module (it uses ``_lie_poisson``, ``_damped``, ``_book`` and ``_blown`` of
    :mod:`cartan.integrators.loops`)."""
    return Fragment(constants={"MAX_ITERATIONS_": MAX_ITERATIONS, "SLOW_": SLOW},
                    source=njit_source(small_inverse, bt_factor, bt_solve, bs_factor, bs_solve, _rattle_fixed,
                                       rattle_values, rattle_rows, rattle_metric, _rattle_flow_jacobian,
                                       _rattle_diagonal, _rattle_right, _rattle_left, rattle_factor, rattle_factor_sym,
                                       rattle_apply, rattle_impulse, rattle_project_velocity, _rattle_project_config,
                                       _rattle_rate, _rattle_accelerations, _rattle_predict,
                                       _rattle_support_power, _rattle_powers, _rattle_copy,
                                       rattle_trial_flow, rattle_trial_kick, _rattle_velocity, _rattle_zero,
                                       _rattle_copy_edges,
                                       _rattle_factors, rattle_loop))
