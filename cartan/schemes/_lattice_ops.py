"""The lattice scheme's compiled operator set: what the generated integrator loops call.

:func:`lattice_operators` turns a lattice problem into an
:class:`~cartan.compiled.operators.OperatorSet`: the problem as data (:class:`LatticeData`,
flat arrays over nodes and edges, any d), the configuration as a tuple ``C = (G, Phi)`` —
every edge element of every axis in one array ``G`` ``[E, m, m]`` and the stepped frames
``Phi`` ``[n, m, m]`` (or the root frame ``[1, m, m]``) — and the functions below, written
once here as plain Python and compiled inside the generated module of each (integrator,
scheme, group, medium kernels), where ``g_*`` are the group's point kernels and
``m_energy``/``m_stress`` the medium's.

The formulas are those of :class:`~cartan.schemes.lattice.Lattice` (the reference path):
edge strain ``X_e = log(G_e)/h_α`` with the other axes at the rest strain, edge stress
``(cell/h_α) Q_α``, node force ``Σ_out dexp⁻¹(hX_e)ᵀ Q_e − Σ_in dexp⁻¹(−hX_e)ᵀ Q_e`` divided
by the node weight, exact drift ``G_e ← D_i⁻¹ G_e D_j`` with ``D = exp(τN)``.

Operators (``D`` the data, ``C`` the configuration, ``K`` the work arrays of :func:`op_work`):

``op_work(D)``                    work arrays for one call of a loop
``op_velocity(D, S, N)``          Legendre map N = ∂K*/∂S (gauge, clamped nodes, held components zero)
``op_force(D, C, t, N, W, K)``    force density W = D*Q + T (loads, end loads, clamps)
``op_drift(D, C, tau, N, K)``     Φ ← Φ exp(τN) exactly on the group
``op_free_flow(D, C, S, pieces, fracs, dt, Dn, K)`` the exact free flow of ``lie-verlet``
``op_drift_naive(D, C, tau, N, K)`` Φ ← Φ + τΦN̂ (forward Euler; leaves the group)
``op_constrain(D, S)``            zero the momentum of gauge components, clamped nodes, held components
``op_powers(D, C, N, t, K)``      (dissipated, external) power of the loads
``op_kinetic(D, S)``              kinetic energy ``Scheme.kinetic_energy``: ½Σ w S·M⁺S over unclamped nodes
                                  (½ w N·MN, N = M⁺S zero on the held components, at a partly held node)
``op_potential(D, C, K) -> float`` potential energy ``potential_energy(state)``: the medium's
                                  discrete energy plus the conservative loads' (a constant field)
``op_nodal_strains(D, C, X)``     X ``[n, d, r]`` ← ``nodal_strains(state)``, nodes in C order
``op_finite_config(C)``           whether the configuration is finite
``op_copy_config(C, C2)``         C2 ← C (RKMK stages)
``op_new_config(C)``              a copy of C

The loops of ``lie-euler``, ``forward-euler`` and ``rkmk4`` reach the velocity and the force
through ``op_state_velocity(D, C, S, N, K)`` and ``op_state_force(D, C, S, t, N, W, K)``
(:mod:`cartan.integrators.loops`: ``op_velocity`` and ``op_force`` there); a set of a medium
whose Lagrangian couples N and X (d = 1) rebinds them to the half-edge operators of
:func:`coupled_fragment` (the medium's ``m_coupled_velocity``, ``m_coupled_stress``) and serves
those loops only (``OperatorSet.loops``, serially).

Per-node accumulators (:mod:`cartan.accumulators`): a set of a medium whose point kernels give
their rates (``m_accumulator_rate``) rebinds the loops' ``op_accumulate(D, C, S, N, dt, begin)``
to :func:`op_accumulate_rates` (:func:`accumulate_fragment`, after the loops), the values and
the last rates in the data (``acc``, ``acc_rate`` ``[a, n]``, moved by ``pack``/``unpack``), and
names the loops that call it (``OperatorSet.accumulates``).

Threaded build (``docs/performance.md``, "Threads"): :func:`threaded_fragment` adds
``op_x_threaded`` variants of ``op_work``, ``op_velocity``, ``op_constrain``, ``op_force``,
``op_move``, ``op_free_flow``, ``op_drift`` and ``op_kinetic`` (``prange`` over fixed chunks,
the force gathered per node instead of scattered per edge) and rebinds those names to them, in
the set's threaded module only (``OperatorSet.threaded``); the results are the serial ones bit
for bit.

Data fields every set provides (beside its own): ``d``, ``r``, ``m``, ``track``, ``shape``
(the grid shape, a tuple of ints), ``coords`` ``[n, d]`` (node coordinates in C order:
``np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(d)], indexing="ij"), -1)``
flattened), ``w`` ``[n]`` (node weights), ``clamped`` ``[n]``, ``any_clamped``, ``live`` ``[r]``,
``inv_metric`` ``[r, r]``, ``has_power``.

Loads and boundaries (the lattice): ``Damping`` (``−ΓN``), body-frame ``UniformForce``, a
constant field ``ConstantFieldPotential`` (gravity: the pull-back of ``U = −ρf·x`` is the body
force ``Rᵀρf`` on the translations and no moment, paper §IV.B; energy ``−Σ w ρf·x``, x the
translation of Φ), free ends or faces with follower or dead loads (``n_α Q^α = P``, paper §IV.D),
clamped ends or faces, periodic axes.

Held components (``Held`` ends, ``Symmetry`` faces; the collocation set alike): ``held`` ``[n, r]`` is
the scheme's clamp mask (:meth:`~cartan.schemes.lattice.Lattice._clamp_mask`, all r at clamped
nodes), ``clamped`` ``[n]`` its rows that hold every component, ``any_held`` whether a node
holds some components and not all.  As on the numpy path (``N[held] = 0``, ``S[held] = 0``,
``W[held] = 0``): the velocity, the momentum's constraint and the force are zero on the held
components, ``lie-verlet``'s free flow moves a node along its free components only (N_p zero on
the held ones) and the kinetic energy is ``½ w N·MN`` with those N (``metric`` M).  The
velocity, constraint and kinetic energy are shared with the collocation set, whose data
carries the same three fields from its own clamp mask.
The loops that read ``clamped`` themselves (``kinematic``'s prescribed velocity) decline partly
held problems in their integrators (``rattle``'s node operators read ``held``); ``overdamped`` takes
N = Γ⁻¹W, zero on the held components with W.

Driven ends (``Driven``; the lattice only): the driven nodes are held (``clamped``) and listed
with their ξ and ∂K/∂N(ξ) (``dnodes``, ``xi_d``, ``S_d``); a set that has them adds
:func:`driven_fragment` after the loops (``OperatorSet.late``), whose operators give the velocity
ξ, the momentum ∂K/∂N(ξ), the kinetic energy ½wξ·Mξ there and add the supports' power
``−w W·ξ`` (``Scheme._driven_power``) to the external power, and ``op_free_flow`` moves them by
:func:`_driven_flow`; it serves the loops of ``lie-verlet``, ``lie-euler``, ``rkmk4``,
``overdamped``, ``rattle`` and ``implicit-midpoint`` only (``OperatorSet.loops``: not ``ok``),
serially (no threaded build).

Energies (paper §VI.C)
    Edge sum ``V = cell Σ_e U(X_e; X₀_e)`` with the other axes at rest, or, for coupled media,
    the corner sum ``V = Σ_c (w_i/#corners_i) U(X_c; X₀_c)``; the kinetic energy
    ``K = Σ_i w_i ½ N_i·M N_i = ½ Σ_i w_i S_i·M⁺S_i`` (N = M⁺S, zero at clamped nodes).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..compiled.codegen import Fragment, njit_source
from ..compiled.diagnostics import SERVED as DIAGNOSTICS_SERVED

__all__ = ["LatticeData", "lattice_operators"]


class LatticeData(NamedTuple):
    """A lattice problem as flat arrays (n nodes, E edges over all axes, d axes, r = dim 𝔤)."""

    d: int
    r: int
    m: int
    affine: bool
    track: bool
    tail: np.ndarray  # [E] int64, node at the start of each edge
    head: np.ndarray  # [E] int64, node at its end
    eaxis: np.ndarray  # [E] int64, its axis α
    einvh: np.ndarray  # [E] 1/h_α
    escale: np.ndarray  # [E] cell/h_α
    X0e: np.ndarray  # [E, d, r] rest strain at each edge
    coupled: bool  # the potential is evaluated at the corners (d ≥ 2, axes coupled)
    cedge: np.ndarray  # [C, d] int64 the edge of each corner along each axis (global index)
    cw: np.ndarray  # [C] corner weights w_i/#corners_i
    cX0: np.ndarray  # [C, d, r] corner rest strains
    cuniform: bool  # every corner has the same rest strain, ``cX0u`` (coupled)
    cX0u: np.ndarray  # [d, r] that rest strain (zeros when not ``cuniform``)
    params: np.ndarray  # medium kernel parameters
    winv: np.ndarray  # [n] 1/w
    w: np.ndarray  # [n] node weights
    inv_metric: np.ndarray  # [r, r] M⁺: the inverse kinetic metric on the live block, 0 on gauge ones
    live: np.ndarray  # [r] bool
    clamped: np.ndarray  # [n] bool, every component held (clamped ends, held ends that hold all r)
    any_clamped: bool
    held: np.ndarray  # [n, r] bool, the held components (Held ends, Symmetry faces; all r at clamped nodes)
    any_held: bool  # a node holds some of its components and not all (else ``clamped`` says everything)
    metric: np.ndarray  # [r, r] the kinetic metric M (the kinetic energy ½N·MN of partly held nodes)
    damp: np.ndarray  # [r] damping coefficients Γ
    ubody: np.ndarray  # [r] body-frame uniform force density
    end_idx: np.ndarray  # [k] int64 loaded end nodes
    end_load: np.ndarray  # [k, r] their loads P
    end_loaded: np.ndarray  # [k] bool, all True (the collocation set keeps unloaded ends in its list)
    end_follow: np.ndarray  # [k] bool follower (else dead)
    end_div: np.ndarray  # [k] 1/(h_α/2): load per face area → force density
    end_face: np.ndarray  # [k] w/(h_α/2): face area share (powers)
    has_power: bool
    field: np.ndarray  # [k] ρf summed over the constant fields (gravity), k the space dimension (0: none)
    has_field: bool
    cell: float  # Π_α h_α, the volume of a cell (edge energies)
    diagonal: bool  # the kinetic metric is diagonal (M⁺ = diag)
    nscale: np.ndarray  # [n, d] 1/(number of edges of node i along α): the nodal average of the edge strains
    shape: tuple  # the grid shape (ints)
    coords: np.ndarray  # [n, d] node coordinates, C order
    # Driven ends (set by :func:`_driven_data`; the driven nodes are also ``clamped``)
    any_driven: bool = False
    dnodes: np.ndarray = None  # [nd] int64 the driven nodes
    dslot: np.ndarray = None  # [n] int64 a node's row in ``dnodes`` (−1: not driven)
    xi_d: np.ndarray = None  # [n, r] the driven velocity ξ, zero elsewhere ([0, r] without driven ends)
    S_d: np.ndarray = None  # [n, r] the driven momentum ∂K/∂N(ξ), zero on the gauge components and elsewhere
    dedge: np.ndarray = None  # [k] int64 the edges with a driven end, increasing
    dcorner: np.ndarray = None  # [c] int64 the corners with one of those edges, increasing (coupled)
    dcptr: np.ndarray = None  # [k + 1] int64 CSR: ``dedge[p]``'s corners ``dcitem[dcptr[p]:dcptr[p + 1]]``
    dcitem: np.ndarray = None  # [·] int64 ``c·d + b``: row c of ``dcorner`` along axis b, increasing c
    # Per-node accumulators (:func:`accumulate_fragment`; ``[0, n]`` without them)
    acc: np.ndarray = None  # [a, n] the accumulators, loaded by ``pack`` and written back by ``unpack``
    acc_rate: np.ndarray = None  # [a, n] their rates at the last state the loop accumulated at


# ---------------------------------------------------------------------------- operators
# Plain Python: compiled in each generated module (see the module docstring).

def op_work(D):
    """``(Dn, Di, XI, QE, VT, VH)``: the nodes' motions and their inverses ``[n, m, m]``, the edges'
    logarithms, stresses and both ends' force terms ``[E, r]``."""
    n = D.winv.shape[0]
    ne = D.tail.shape[0]
    return (np.empty((n, M_, M_)), np.empty((n, M_, M_)), np.empty((ne, R_)), np.empty((ne, R_)),  # noqa: F821
            np.empty((ne, R_)), np.empty((ne, R_)))  # noqa: F821


def op_velocity(D, S, N):
    """N = M⁺S, zero at clamped nodes and on held components (``Scheme.velocity``)."""
    for i in range(S.shape[0]):
        if D.any_clamped and D.clamped[i]:
            for k in range(R_):  # noqa: F821
                N[i, k] = 0.0
        else:
            for k in range(R_):  # noqa: F821
                if D.any_held and D.held[i, k]:
                    N[i, k] = 0.0
                    continue
                v = 0.0
                for j in range(R_):  # noqa: F821
                    v += D.inv_metric[k, j] * S[i, j]
                N[i, k] = v


def op_constrain(D, S):
    """Zero S on the gauge components, at clamped nodes and on held components (``Scheme.constrain``)."""
    for i in range(S.shape[0]):
        zero = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            if zero or not D.live[k] or (D.any_held and D.held[i, k]):
                S[i, k] = 0.0


def _dead_to_body(D, Phi, P, out):
    """``Ad_Rᵀ P`` with R the rotational part of Φ (dead loads)."""
    tmp = np.empty((M_, M_))  # noqa: F821
    for a in range(M_):  # noqa: F821
        for b in range(M_):  # noqa: F821
            tmp[a, b] = Phi[a, b]
    if D.affine:
        for a in range(1, M_):  # noqa: F821
            tmp[a, 0] = 0.0
    g_Ad_T(tmp, P, out)  # noqa: F821 - a global of the generated module


def _field_force(D, Phi, W):
    """``W_i += Rᵢᵀρf`` on the first k components (the translations): the pull-back of the
    constant field's potential ``U = −ρf·x`` (paper §IV.B), no moment."""
    nf = D.field.shape[0]
    for i in range(W.shape[0]):
        for k in range(nf):
            s = 0.0
            for b in range(nf):
                s += Phi[i, b + 1, k + 1] * D.field[b]
            W[i, k] += s


def op_force(D, C, t, N, W, K):
    """Passes over the edges, each of independent iterations: the logarithms (``g_log_chunk``), the
    stresses (per edge, or per corner gathered to the edges), both ends' terms
    ``s dexp⁻¹(±ξ)ᵀq`` (``g_dexp_inv_T_pair_chunk``, both from ξ, as the reference path takes
    them: the identity dexp⁻¹(−ξ)ᵀ = Ad_Gᵀ dexp⁻¹(ξ)ᵀ fails off the group, where forward Euler
    takes the edges), then those terms added to the nodes in edge order.  The two group passes
    are vectorised across edges where the group has them in closed form (SE(3))."""
    G = C[0]
    X = np.empty((D_, R_))  # noqa: F821
    Q = np.empty((D_, R_))  # noqa: F821
    XI, QE = K[2], K[3]
    n = W.shape[0]
    ne = G.shape[0]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            W[i, k] = 0.0
    g_log_chunk(G, 0, ne, XI)  # noqa: F821
    if D.coupled:
        for e in range(ne):
            for k in range(R_):  # noqa: F821
                QE[e, k] = 0.0
        if D.cuniform:  # one rest strain passed as one array, not as a view per corner
            X0u = D.cX0u
            for c in range(D.cw.shape[0]):
                for b in range(D_):  # noqa: F821
                    e = D.cedge[c, b]
                    for k in range(R_):  # noqa: F821
                        X[b, k] = XI[e, k] * D.einvh[e]
                m_stress(X, X0u, D.params, Q)  # noqa: F821
                for b in range(D_):  # noqa: F821
                    e = D.cedge[c, b]
                    f = D.cw[c] * D.einvh[e]
                    for k in range(R_):  # noqa: F821
                        QE[e, k] += f * Q[b, k]
        else:
            for c in range(D.cw.shape[0]):
                for b in range(D_):  # noqa: F821
                    e = D.cedge[c, b]
                    for k in range(R_):  # noqa: F821
                        X[b, k] = XI[e, k] * D.einvh[e]
                m_stress(X, D.cX0[c], D.params, Q)  # noqa: F821
                for b in range(D_):  # noqa: F821
                    e = D.cedge[c, b]
                    f = D.cw[c] * D.einvh[e]
                    for k in range(R_):  # noqa: F821
                        QE[e, k] += f * Q[b, k]
    else:
        for e in range(ne):
            a = D.eaxis[e]
            for b in range(D_):  # noqa: F821
                for k in range(R_):  # noqa: F821
                    X[b, k] = D.X0e[e, b, k]
            for k in range(R_):  # noqa: F821
                X[a, k] = XI[e, k] * D.einvh[e]
            m_stress(X, D.X0e[e], D.params, Q)  # noqa: F821
            for k in range(R_):  # noqa: F821
                QE[e, k] = Q[a, k]
    _edge_force(D, C, N, W, K)


def _edge_force(D, C, N, W, K):
    """The rest of :func:`op_force` once the edges' logarithms ``K[2]`` and stresses ``K[3]`` are
    known (and W zero): both ends' terms, gathered to the nodes, divided by the weights, the
    loads, the clamps."""
    G, Phi = C
    vec = np.empty(R_)  # noqa: F821
    XI, QE, VT, VH = K[2], K[3], K[4], K[5]
    n = W.shape[0]
    ne = G.shape[0]
    g_dexp_inv_T_pair_chunk(XI, QE, np.empty(0) if D.coupled else D.escale, 0, ne, VT, VH)  # noqa: F821
    for e in range(ne):
        i, j = D.tail[e], D.head[e]
        for k in range(R_):  # noqa: F821
            W[i, k] += VT[e, k]
            W[j, k] -= VH[e, k]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            W[i, k] = W[i, k] * D.winv[i] - D.damp[k] * N[i, k] + D.ubody[k]
    if D.has_field:
        _field_force(D, Phi, W)
    for p in range(D.end_idx.shape[0]):
        i = D.end_idx[p]
        if D.end_follow[p]:
            for k in range(R_):  # noqa: F821
                W[i, k] += D.end_load[p, k] * D.end_div[p]
        else:
            _dead_to_body(D, Phi[i], D.end_load[p], vec)
            for k in range(R_):  # noqa: F821
                W[i, k] += vec[k] * D.end_div[p]
    for i in range(n):
        zero = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            if zero or not D.live[k] or (D.any_held and D.held[i, k]):
                W[i, k] = 0.0


def op_move(D, C, Dn, K):
    """Move every node i by ``Dn[i]``: ``Di_i = Dn_i⁻¹`` and ``Φ_i ← Φ_i Dn_i`` (``g_frames_chunk``),
    ``G_e ← Di_i G_e Dn_j`` (``g_move_chunk``)."""
    G, Phi = C
    Di = K[1]
    g_frames_chunk(Dn, Di, Phi, 0, Dn.shape[0])  # noqa: F821
    g_move_chunk(Di, Dn, G, D.tail, D.head, 0, G.shape[0])  # noqa: F821


def op_free_flow(D, C, S, pieces, fracs, dt, Dn, K):
    """The free flow of ``lie-verlet`` over Δt at every node: the pieces in turn, each
    ``S ← Ad*_{exp(τN_p)}S`` with ``N_p = P_p S`` (``pieces[p]``, zero at clamped nodes) over
    ``τ = fracs[p]·Δt``; returns whether anything moved and leaves each node's total motion
    ``Π_p exp(τN_p)`` in ``Dn``; the free flow is node-local, so the edges and frames then follow
    in one :func:`op_move` by ``Dn``.

    A piece of a diagonal metric is one basis direction or a block of mutually commuting ones
    (``P_p`` diagonal; ``LieVerlet._sequence`` makes the blocks of ``_abelian_pieces``, which
    commute: the flow of a diagonal block of directions that do not commute would not be
    ``exp(τN_p)`` either): its flow is the product of one flow per direction k of the block,
    ``exp(τN_p) = Π_k exp(t_k b_k)`` with ``t_k = τ(P_p)_kk S_k`` (the directions commute, and
    the flow along one leaves the block's components of S unchanged), each by the group's
    ``g_axis_flow`` — a closed form (a turn in one plane, a shift) where the group has one, else
    ``g_exp``, ``g_Ad_T`` and ``g_compose``.  Any other piece (an eigenvector of a non-diagonal
    metric) runs ``g_exp``, ``g_Ad_T`` and ``g_compose``, with ``N_p = P_p S`` over the nonzero
    entries of each row of ``P_p`` only.

    The nodes are taken in chunks of ``FCHUNK_`` (:func:`_flow_chunk`): in a chunk, piece by
    piece and direction by direction, one short pass over the chunk's nodes (momentum rows and
    motions ``Dn`` in place; ``g_axis_flow`` is compiled into this pass,
    ``codegen.INLINED_KERNELS``), whose iterations are independent — each node takes the same
    operations in the same order as one node at a time would, so the results are those to the
    bit, and the chunk's rows stay in the cache.  Where every piece is axial and the group has
    the chunk's flow in closed form (SE(3): ``se3_axial_flow_chunk_point``), those passes run on
    a structure-of-arrays copy of the chunk, vectorised across its nodes."""
    npieces, tau, axial, naxes, axes, coef, cnt, col = _flow_plan(pieces, fracs, dt)
    xi = np.zeros(R_)  # noqa: F821
    out = np.empty(R_)  # noqa: F821
    E = np.empty((M_, M_))  # noqa: F821
    tmp = np.empty((M_, M_))  # noqa: F821
    eye = np.empty((M_, M_))  # noqa: F821
    wk = g_work()  # noqa: F821
    g_exp(xi, eye)  # noqa: F821 - the identity (a node that does not move)
    TK = np.empty((FCHUNK_, R_))  # noqa: F821
    n = S.shape[0]
    moved = False
    for lo in range(0, n, FCHUNK_):  # noqa: F821
        if _flow_chunk(lo, min(n, lo + FCHUNK_), S, Dn, D.any_clamped, D.clamped, D.any_held, D.held,  # noqa: F821
                       pieces, npieces, tau, axial, naxes, axes, coef, cnt, col, eye, xi, out, E, tmp, wk, TK):
            moved = True
    if D.any_driven and _driven_flow(D, S, Dn, npieces, tau, axial, naxes, axes, wk):
        moved = True
    if moved:
        op_move(D, C, Dn, K)
    return moved


def _driven_flow(D, S, Dn, npieces, tau, axial, naxes, axes, wk):
    """The free flow's motion of the driven nodes (held, hence left at the identity by
    :func:`_flow_chunk`): piece by piece, direction by direction, ``exp(τ_p ξ_k b_k)`` — the
    flow of ``Lattice``'s ``velocity``, ξ at a driven node — composed into ``Dn``; ``S`` there
    flows along (``op_constrain`` sets it to ∂K/∂N(ξ) after).  With ξ's parts in the pieces
    commuting (``LieVerlet.driven_reason``) the product is ``exp(Δtξ)``.  A piece that is not
    diagonal (a non-diagonal metric, whose free flow holds the driven nodes: that integrator
    refuses them) is skipped.  Returns whether a driven node moved."""
    moved = False
    for s in range(D.dnodes.shape[0]):
        i = D.dnodes[s]
        for p in range(npieces):
            if not axial[p]:
                continue
            for c in range(naxes[p]):
                k = axes[p, c]
                t = tau[p] * D.xi_d[i, k]
                if t != 0.0:
                    g_axis_flow(k, t, S[i], Dn[i], wk)  # noqa: F821
                    moved = True
    return moved


def _flow_plan(pieces, fracs, dt):
    """The pieces of :func:`op_free_flow` read once: ``(P, tau [P], axial [P], naxes [P], axes
    [P, r], coef [P, r], cnt [P, r], col [P, r, r])`` — τ of each piece, whether it is diagonal,
    its directions and their ``(P_p)_kk``, and each row's nonzero columns."""
    npieces = pieces.shape[0]
    cnt = np.zeros((npieces, R_), dtype=np.int64)  # noqa: F821
    col = np.empty((npieces, R_, R_), dtype=np.int64)  # noqa: F821
    tau = np.empty(npieces)
    axial = np.ones(npieces, dtype=np.bool_)
    naxes = np.zeros(npieces, dtype=np.int64)  # an axial piece: its directions and (P_p)_kk
    axes = np.empty((npieces, R_), dtype=np.int64)  # noqa: F821
    coef = np.empty((npieces, R_))  # noqa: F821
    for p in range(npieces):
        tau[p] = fracs[p] * dt
        for k in range(R_):  # noqa: F821
            for j in range(R_):  # noqa: F821
                if pieces[p, k, j] != 0.0:
                    col[p, k, cnt[p, k]] = j
                    cnt[p, k] += 1
                    if j != k:
                        axial[p] = False
            if cnt[p, k]:
                axes[p, naxes[p]] = k
                coef[p, naxes[p]] = pieces[p, k, k]
                naxes[p] += 1
    return npieces, tau, axial, naxes, axes, coef, cnt, col


def _flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, pieces, npieces, tau, axial, naxes, axes,
                coef, cnt, col, eye, xi, out, E, tmp, wk, TK):
    """The free flow of :func:`op_free_flow` at the nodes ``lo ≤ i < hi`` (``hi − lo ≤`` the rows of
    ``TK``, the directions' times): ``Dn_i`` from the identity, then each piece as passes over the
    nodes; returns whether a node moved.  When every piece is axial and the group has the whole
    chunk's flow in closed form (``AXIAL_FLOW_CLOSED_``: SE(3), SE(2)), ``g_axial_flow_chunk`` runs the
    same steps as passes vectorised across the chunk's nodes (the same results, to the bit)."""
    if AXIAL_FLOW_CLOSED_:  # noqa: F821 - every piece axial: the group's pass over the chunk (SE(3), SE(2))
        every = True
        for p in range(npieces):
            every = every and axial[p]
        if every:
            return g_axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau,  # noqa: F821
                                      naxes, axes, coef)
    moved = False
    for i in range(lo, hi):
        for a in range(M_):  # noqa: F821
            for b in range(M_):  # noqa: F821
                Dn[i, a, b] = eye[a, b]
    for p in range(npieces):
        if axial[p]:
            na = naxes[p]
            taup = tau[p]
            for c in range(na):  # every time of the block first (the flows leave the block's S alone)
                k = axes[p, c]
                cp = coef[p, c]
                for i in range(lo, hi):
                    t = taup * (cp * S[i, k])
                    if (any_clamped and clamped[i]) or (any_held and held[i, k]):
                        t = 0.0
                    TK[i - lo, c] = t
            for c in range(na):
                k = axes[p, c]
                for i in range(lo, hi):
                    t = TK[i - lo, c]
                    if t != 0.0:
                        g_axis_flow(k, t, S[i], Dn[i], wk)  # noqa: F821
                        moved = True
            continue
        for i in range(lo, hi):
            if any_clamped and clamped[i]:
                continue
            moving = False
            for k in range(R_):  # noqa: F821
                v = 0.0
                if not (any_held and held[i, k]):
                    for c in range(cnt[p, k]):
                        j = col[p, k, c]
                        v += pieces[p, k, j] * S[i, j]
                xi[k] = tau[p] * v
                if v != 0.0:
                    moving = True
            if not moving:
                continue
            moved = True
            g_exp(xi, E)  # noqa: F821
            g_Ad_T(E, S[i], out)  # noqa: F821
            for k in range(R_):  # noqa: F821
                S[i, k] = out[k]
            g_compose(Dn[i], E, tmp)  # noqa: F821
            for a in range(M_):  # noqa: F821
                for b in range(M_):  # noqa: F821
                    Dn[i, a, b] = tmp[a, b]
    return moved


def op_drift(D, C, tau, N, K):
    Dn = K[0]
    xi = np.empty(R_)  # noqa: F821
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            xi[k] = tau * N[i, k]
        g_exp(xi, Dn[i])  # noqa: F821
    op_move(D, C, Dn, K)


def op_drift_naive(D, C, tau, N, K):
    G, Phi = C
    Nh = K[0]
    tmp = np.empty((M_, M_))  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            xi[k] = tau * N[i, k]
        g_hat(xi, Nh[i])  # noqa: F821
    for e in range(G.shape[0]):
        i, j = D.tail[e], D.head[e]
        for a in range(M_):  # noqa: F821
            for b in range(M_):  # noqa: F821
                s = G[e, a, b]
                for c in range(M_):  # noqa: F821
                    s += -Nh[i, a, c] * G[e, c, b] + G[e, a, c] * Nh[j, c, b]
                tmp[a, b] = s
        for a in range(M_):  # noqa: F821
            for b in range(M_):  # noqa: F821
                G[e, a, b] = tmp[a, b]
    for i in range(Phi.shape[0]):
        for a in range(M_):  # noqa: F821
            for b in range(M_):  # noqa: F821
                s = Phi[i, a, b]
                for c in range(M_):  # noqa: F821
                    s += Phi[i, a, c] * Nh[i, c, b]
                tmp[a, b] = s
        for a in range(M_):  # noqa: F821
            for b in range(M_):  # noqa: F821
                Phi[i, a, b] = tmp[a, b]


def op_powers(D, C, N, t, K):
    if not D.has_power:
        return 0.0, 0.0
    Phi = C[1]
    vec = np.empty(R_)  # noqa: F821
    diss = 0.0
    ext = 0.0
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            diss += D.w[i] * D.damp[k] * N[i, k] * N[i, k]
            ext += D.w[i] * D.ubody[k] * N[i, k]
    for p in range(D.end_idx.shape[0]):
        if not D.end_loaded[p]:
            continue
        i = D.end_idx[p]
        if D.end_follow[p]:
            for k in range(R_):  # noqa: F821
                ext += D.end_face[p] * D.end_load[p, k] * N[i, k]
        else:
            _dead_to_body(D, Phi[i], D.end_load[p], vec)
            for k in range(R_):  # noqa: F821
                ext += D.end_face[p] * vec[k] * N[i, k]
    return diss, ext


def op_kinetic(D, S):
    """:func:`op_kinetic` with held components (:func:`_kinetic_held_node` at the nodes that hold some)."""
    Nv = np.empty(R_)  # noqa: F821
    e = 0.0
    for i in range(S.shape[0]):
        if D.any_clamped and D.clamped[i]:
            continue
        if D.any_held and _held_row(D.held, i):
            e += _kinetic_held_node(S, i, D.w[i], D.diagonal, D.inv_metric, D.metric, D.held, Nv)
            continue
        for k in range(R_):  # noqa: F821
            if D.diagonal:
                e += 0.5 * D.w[i] * S[i, k] * S[i, k] * D.inv_metric[k, k]
            else:
                v = 0.0
                for j in range(R_):  # noqa: F821
                    v += D.inv_metric[k, j] * S[i, j]
                e += 0.5 * D.w[i] * S[i, k] * v
    return e


def op_potential(D, C, K):
    G, Phi = C
    xi = np.empty(R_)  # noqa: F821
    X = np.empty((D_, R_))  # noqa: F821
    V = 0.0
    if D.coupled:
        XI = K[2]
        for e in range(G.shape[0]):
            g_log(G[e], xi)  # noqa: F821
            for k in range(R_):  # noqa: F821
                XI[e, k] = xi[k]
        for c in range(D.cw.shape[0]):
            for b in range(D_):  # noqa: F821
                e = D.cedge[c, b]
                for k in range(R_):  # noqa: F821
                    X[b, k] = XI[e, k] * D.einvh[e]
            V += D.cw[c] * m_energy(X, D.cX0[c], D.params)  # noqa: F821
    else:
        for e in range(G.shape[0]):
            a = D.eaxis[e]
            g_log(G[e], xi)  # noqa: F821
            for b in range(D_):  # noqa: F821
                for k in range(R_):  # noqa: F821
                    X[b, k] = D.X0e[e, b, k]
            for k in range(R_):  # noqa: F821
                X[a, k] = xi[k] * D.einvh[e]
            V += D.cell * m_energy(X, D.X0e[e], D.params)  # noqa: F821
    if D.has_field:
        for i in range(Phi.shape[0]):
            s = 0.0
            for b in range(D.field.shape[0]):
                s += D.field[b] * Phi[i, b + 1, 0]
            V -= D.w[i] * s
    return V


def op_nodal_strains(D, C, X):
    G = C[0]
    xi = np.empty(R_)  # noqa: F821
    for i in range(X.shape[0]):
        for a in range(D_):  # noqa: F821
            for k in range(R_):  # noqa: F821
                X[i, a, k] = 0.0
    for e in range(G.shape[0]):
        a = D.eaxis[e]
        g_log(G[e], xi)  # noqa: F821
        for k in range(R_):  # noqa: F821
            v = xi[k] * D.einvh[e]
            X[D.tail[e], a, k] += v
            X[D.head[e], a, k] += v
    for i in range(X.shape[0]):
        for a in range(D_):  # noqa: F821
            for k in range(R_):  # noqa: F821
                X[i, a, k] *= D.nscale[i, a]


def op_finite_config(C):
    for arr in C:
        for v in arr.ravel():
            if not np.isfinite(v):
                return False
    return True


def op_copy_config(C, C2):
    for k in range(len(C)):
        C2[k][...] = C[k]


def op_new_config(C):
    return (C[0].copy(), C[1].copy())


_OPERATORS = (op_work, op_velocity, op_constrain, _dead_to_body, _field_force, op_force, _edge_force, op_move,
              op_free_flow, _driven_flow, _flow_plan, _flow_chunk, op_drift, op_drift_naive, op_powers, op_kinetic,
              op_potential, op_nodal_strains, op_finite_config, op_copy_config, op_new_config)


def _held_row(held, i):
    """Whether node i holds any component."""
    for k in range(R_):  # noqa: F821
        if held[i, k]:
            return True
    return False


def _kinetic_held_node(S, i, w, diagonal, inv_metric, metric, held, N):
    """``½ w N·MN`` of a node that holds some components: N = M⁺S zero on them (``N`` ``[r]``
    scratch), as ``Scheme.kinetic_energy`` takes it; ``½ w Σ S_k² M⁺_kk`` over the free k for a
    diagonal metric (the same energy, the formula of :func:`op_kinetic`)."""
    e = 0.0
    if diagonal:
        for k in range(R_):  # noqa: F821
            if not held[i, k]:
                e += 0.5 * w * S[i, k] * S[i, k] * inv_metric[k, k]
        return e
    for k in range(R_):  # noqa: F821
        v = 0.0
        if not held[i, k]:
            for j in range(R_):  # noqa: F821
                v += inv_metric[k, j] * S[i, j]
        N[k] = v
    for k in range(R_):  # noqa: F821
        v = 0.0
        for j in range(R_):  # noqa: F821
            v += metric[k, j] * N[j]
        e += 0.5 * w * N[k] * v
    return e


_HELD = (_held_row, _kinetic_held_node)


# ---------------------------------------------------------------------------- driven ends
# ``Driven`` ends (the lattice only): the operators of a set with driven nodes, compiled after
# the loops (``OperatorSet.late``), wrap the shared ones and take their names, as the threaded
# build does; a set without driven nodes compiles none of this.  The driven nodes are held
# (``clamped``: the force is zero there, the loops' own passes skip them) and, as on the numpy
# path (``Scheme.velocity``, ``constrain``, ``kinetic_energy``, ``_driven_power``): their
# velocity is ξ, their momentum ∂K/∂N(ξ), their kinetic energy ½wξ·Mξ, and the supports' power
# ``R·ξ = −w W·ξ`` (W the force density before it is zeroed there; ⟨ad_ξᵀS, ξ⟩ = 0) joins the
# external power.  The drift moves them by exp(τξ) with the rest; ``lie-verlet``'s free flow by
# :func:`_driven_flow`.

def op_drive_driven(D, N):
    """N ← ξ at the driven nodes (the velocity of ``Scheme.velocity`` there)."""
    for s in range(D.dnodes.shape[0]):
        i = D.dnodes[s]
        for k in range(R_):  # noqa: F821
            N[i, k] = D.xi_d[i, k]


def op_velocity_driven(D, S, N):
    op_velocity_plain(D, S, N)  # noqa: F821
    op_drive_driven(D, N)


def op_constrain_driven(D, S):
    op_constrain_plain(D, S)  # noqa: F821
    for s in range(D.dnodes.shape[0]):
        i = D.dnodes[s]
        for k in range(R_):  # noqa: F821
            S[i, k] = D.S_d[i, k]


def op_kinetic_driven(D, S):
    e = op_kinetic_plain(D, S)  # noqa: F821
    for s in range(D.dnodes.shape[0]):
        i = D.dnodes[s]
        for k in range(R_):  # noqa: F821
            v = 0.0
            for j in range(R_):  # noqa: F821
                v += D.metric[k, j] * D.xi_d[i, j]
            e += 0.5 * D.w[i] * D.xi_d[i, k] * v
    return e


def op_powers_driven(D, C, N, t, K):
    diss, ext = op_powers_plain(D, C, N, t, K)  # noqa: F821
    return diss, ext + _driven_power(D, C)


def _driven_power(D, C):
    """``Σ_driven −w W·ξ``: W the force density of :func:`op_force` at the driven nodes before it
    is zeroed there (the same terms in the same order, over the edges with a driven end only —
    and, coupled, their corners — so the cost is that of the ends), N = ξ in the damping."""
    G, Phi = C
    nd = D.dnodes.shape[0]
    WD = np.zeros((nd, R_))  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    q = np.empty(R_)  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    vec2 = np.empty(R_)  # noqa: F821
    X = np.empty((D_, R_))  # noqa: F821
    Q = np.empty((D_, R_))  # noqa: F821
    QC = np.empty((D.dcorner.shape[0], D_, R_))  # noqa: F821
    if D.coupled:
        for c_ in range(D.dcorner.shape[0]):
            c = D.dcorner[c_]
            for b in range(D_):  # noqa: F821
                e = D.cedge[c, b]
                g_log(G[e], xi)  # noqa: F821
                for k in range(R_):  # noqa: F821
                    X[b, k] = xi[k] * D.einvh[e]
            m_stress(X, D.cX0[c], D.params, Q)  # noqa: F821
            for b in range(D_):  # noqa: F821
                for k in range(R_):  # noqa: F821
                    QC[c_, b, k] = Q[b, k]
    for p in range(D.dedge.shape[0]):
        e = D.dedge[p]
        g_log(G[e], xi)  # noqa: F821
        s = 1.0
        if D.coupled:
            for k in range(R_):  # noqa: F821
                q[k] = 0.0
            for it in range(D.dcptr[p], D.dcptr[p + 1]):
                c_ = D.dcitem[it] // D_  # noqa: F821
                b = D.dcitem[it] - c_ * D_  # noqa: F821
                f = D.cw[D.dcorner[c_]] * D.einvh[e]
                for k in range(R_):  # noqa: F821
                    q[k] += f * QC[c_, b, k]
        else:
            a = D.eaxis[e]
            for b in range(D_):  # noqa: F821
                for k in range(R_):  # noqa: F821
                    X[b, k] = D.X0e[e, b, k]
            for k in range(R_):  # noqa: F821
                X[a, k] = xi[k] * D.einvh[e]
            m_stress(X, D.X0e[e], D.params, Q)  # noqa: F821
            for k in range(R_):  # noqa: F821
                q[k] = Q[a, k]
            s = D.escale[e]
        g_dexp_inv_T_pair(xi, q, vec, vec2)  # noqa: F821
        i, j = D.dslot[D.tail[e]], D.dslot[D.head[e]]
        for k in range(R_):  # noqa: F821
            if i >= 0:
                WD[i, k] += s * vec[k]
            if j >= 0:
                WD[j, k] -= s * vec2[k]
    nf = D.field.shape[0]
    power = 0.0
    for sl in range(nd):
        i = D.dnodes[sl]
        for k in range(R_):  # noqa: F821
            q[k] = WD[sl, k] * D.winv[i] - D.damp[k] * D.xi_d[i, k] + D.ubody[k]
        if D.has_field:
            for k in range(nf):
                v = 0.0
                for b in range(nf):
                    v += Phi[i, b + 1, k + 1] * D.field[b]
                q[k] += v
        for p in range(D.end_idx.shape[0]):
            if D.end_idx[p] == i:
                if D.end_follow[p]:
                    for k in range(R_):  # noqa: F821
                        q[k] += D.end_load[p, k] * D.end_div[p]
                else:
                    _dead_to_body(D, Phi[i], D.end_load[p], vec)
                    for k in range(R_):  # noqa: F821
                        q[k] += vec[k] * D.end_div[p]
        for k in range(R_):  # noqa: F821
            if D.live[k]:
                power -= D.w[i] * q[k] * D.xi_d[i, k]
    return power


_DRIVEN = (op_drive_driven, op_velocity_driven, op_constrain_driven, op_kinetic_driven, op_powers_driven,
           _driven_power)
#: the operators a set with driven nodes replaces (``op_x = op_x_driven``, the shared one kept as
#: ``op_x_plain``; ``op_drive``'s default, in the loops, does nothing)
_DRIVEN_REPLACED = ("op_velocity", "op_constrain", "op_kinetic", "op_powers")


def driven_fragment() -> Fragment:
    """The driven ends' operators (see above) and the rebinding of the operators' names, to
    follow the loops in a generated module (``OperatorSet.late``)."""
    keep = "\n".join(f"{name}_plain = {name}" for name in _DRIVEN_REPLACED)
    rebind = "\n".join(f"{name} = {name}_driven" for name in (*_DRIVEN_REPLACED, "op_drive"))
    return Fragment(source=keep + "\n\n\n" + njit_source(*_DRIVEN) + "\n\n\n" + rebind + "\n")


# ---------------------------------------------------------------------------- coupled Lagrangians
# A medium whose Lagrangian couples N and X (``Medium.coupled_lagrangian``, d = 1): the half-edge
# discretisation of :mod:`cartan.schemes._coupled` with the medium's coupled point kernels
# (``m_coupled_velocity``, ``m_coupled_stress``, :class:`cartan.medium.MediumKernels`).  The
# loops of ``lie-euler``, ``forward-euler`` and ``rkmk4`` reach the state through
# ``op_state_velocity(D, C, S, N, K)`` and ``op_state_force(D, C, S, t, N, W, K)``
# (:mod:`cartan.integrators.loops`), which :func:`coupled_fragment` rebinds to the functions
# below after the loops (``OperatorSet.late``); every other operator is the lattice's own.
# The work arrays of :func:`op_work_coupled` add the half-edge velocities ``[E, 2, r]`` and the
# momenta and edge logarithms they were solved at: the force at the state whose velocity was
# just computed (every stage of those loops) reuses them, so that each half-edge's Legendre
# map is solved once per stage — the result being a function of (S, X) alone either way.

def op_work_coupled(D):
    """:func:`op_work`'s arrays and ``(NH [E, 2, r], SK [n, r], XK [E, r], valid [1])``: the
    half-edge velocities N(S_tail, X_e), N(S_head, X_e), the momenta and logarithms they belong
    to, and whether they are set."""
    n = D.winv.shape[0]
    ne = D.tail.shape[0]
    return (np.empty((n, M_, M_)), np.empty((n, M_, M_)), np.empty((ne, R_)), np.empty((ne, R_)),  # noqa: F821
            np.empty((ne, R_)), np.empty((ne, R_)), np.empty((ne, 2, R_)), np.empty((n, R_)),  # noqa: F821
            np.empty((ne, R_)), np.zeros(1, dtype=np.int64))  # noqa: F821


def _coupled_solve(D, C, S, K):
    """The edges' logarithms into ``K[2]`` and, unless they and S are those of the last solve
    (bit for bit), the half-edge velocities ``K[6]``: the medium's ``m_coupled_velocity`` at
    (S_i, X_e = log(G_e)/h) for both ends i of every edge.

    Raises
    ------
    ValueError
        When the medium finds no velocity at a half-edge (the momentum is outside the range of
        its Legendre map), as the reference path's ``Medium.velocity_at`` raises."""
    G = C[0]
    XI, NH, SK, XK, valid = K[2], K[6], K[7], K[8], K[9]
    ne = G.shape[0]
    n = S.shape[0]
    g_log_chunk(G, 0, ne, XI)  # noqa: F821
    if valid[0] != 0:
        same = True
        for e in range(ne):
            for k in range(R_):  # noqa: F821
                if XI[e, k] != XK[e, k]:
                    same = False
        for i in range(n):
            for k in range(R_):  # noqa: F821
                if S[i, k] != SK[i, k]:
                    same = False
        if same:
            return
    valid[0] = 0
    X = np.empty((D_, R_))  # noqa: F821
    for e in range(ne):
        for k in range(R_):  # noqa: F821
            X[0, k] = XI[e, k] / D.cell
        if not (m_coupled_velocity(S[D.tail[e]], X, D.params, NH[e, 0])  # noqa: F821
                and m_coupled_velocity(S[D.head[e]], X, D.params, NH[e, 1])):  # noqa: F821
            raise ValueError("the Legendre map N(S, X) of the medium has no inverse at a node's momentum and an "
                             "adjacent edge's strain (its coupled_velocity kernel found no velocity: the momentum "
                             "is outside the range of the Legendre map); reduce the time step")
    for e in range(ne):
        for k in range(R_):  # noqa: F821
            XK[e, k] = XI[e, k]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            SK[i, k] = S[i, k]
    valid[0] = 1


def op_state_velocity_coupled(D, C, S, N, K):
    """``N_i = Σ_{e∋i} (h/2w_i) N(S_i, X_e)`` (``cartan.schemes._coupled.coupled_velocity``),
    zero at clamped nodes (``Scheme.velocity``)."""
    _coupled_solve(D, C, S, K)
    NH = K[6]
    n = S.shape[0]
    half = 0.5 * D.cell
    for i in range(n):
        for k in range(R_):  # noqa: F821
            N[i, k] = 0.0
    for e in range(D.tail.shape[0]):
        i = D.tail[e]
        for k in range(R_):  # noqa: F821
            N[i, k] += half * NH[e, 0, k]
    for e in range(D.tail.shape[0]):
        j = D.head[e]
        for k in range(R_):  # noqa: F821
            N[j, k] += half * NH[e, 1, k]
    for i in range(n):
        zero = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            N[i, k] = 0.0 if zero else N[i, k] / D.w[i]


def op_state_force_coupled(D, C, S, t, N, W, K):
    """:func:`op_force` with the Hamiltonian edge stress ``Q_e = ½[Q(S_i, X_e) + Q(S_j, X_e)]``
    (``cartan.schemes._coupled.coupled_stress``; the medium's ``m_coupled_stress`` at the
    half-edge velocities of :func:`_coupled_solve`)."""
    _coupled_solve(D, C, S, K)
    XI, QE, NH = K[2], K[3], K[6]
    X = np.empty((D_, R_))  # noqa: F821
    Qt = np.empty((D_, R_))  # noqa: F821
    Qh = np.empty((D_, R_))  # noqa: F821
    for i in range(W.shape[0]):
        for k in range(R_):  # noqa: F821
            W[i, k] = 0.0
    for e in range(D.tail.shape[0]):
        for k in range(R_):  # noqa: F821
            X[0, k] = XI[e, k] / D.cell
        m_coupled_stress(S[D.tail[e]], X, NH[e, 0], D.params, Qt)  # noqa: F821
        m_coupled_stress(S[D.head[e]], X, NH[e, 1], D.params, Qh)  # noqa: F821
        for k in range(R_):  # noqa: F821
            QE[e, k] = 0.5 * (Qt[0, k] + Qh[0, k])
    _edge_force(D, C, N, W, K)


def op_coupled_logs(D, C, K):
    """The edges' logarithms into ``K[2]``, for :func:`op_coupled_velocities` (``implicit-midpoint``'s
    stage momenta, :func:`cartan.integrators.newton.im_coupled_momentum`)."""
    g_log_chunk(C[0], 0, D.tail.shape[0], K[2])  # noqa: F821


def op_coupled_velocities(D, C, S, N, K):
    """``N_i = Σ_{e∋i} (h/2w_i) N(S_i, X_e)`` ``[n, r]`` at the logarithms of
    :func:`op_coupled_logs` (in ``K[2]``), every node (no clamping), the half-edge velocities in
    ``K[6]`` (the cache of :func:`_coupled_solve` invalidated; :func:`op_coupled_keep` validates
    it); False where the medium's ``m_coupled_velocity`` finds no velocity (instead of raising)."""
    XI, NH = K[2], K[6]
    K[9][0] = 0
    n = S.shape[0]
    half = 0.5 * D.cell
    X = np.empty((D_, R_))  # noqa: F821
    for i in range(n):
        for k in range(R_):  # noqa: F821
            N[i, k] = 0.0
    for e in range(D.tail.shape[0]):
        for k in range(R_):  # noqa: F821
            X[0, k] = XI[e, k] / D.cell
        i = D.tail[e]
        if not m_coupled_velocity(S[i], X, D.params, NH[e, 0]):  # noqa: F821
            return False
        for k in range(R_):  # noqa: F821
            N[i, k] += half * NH[e, 0, k]
        j = D.head[e]
        if not m_coupled_velocity(S[j], X, D.params, NH[e, 1]):  # noqa: F821
            return False
        for k in range(R_):  # noqa: F821
            N[j, k] += half * NH[e, 1, k]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            N[i, k] = N[i, k] / D.w[i]
    return True


def op_coupled_keep(D, C, S, K):
    """Validate the cache of :func:`_coupled_solve` for the last :func:`op_coupled_velocities`
    (at ``S`` and the logarithms in ``K[2]``), so that the force at S reuses its half-edge
    velocities — the same values, a function of (S, X) alone."""
    XI, SK, XK = K[2], K[7], K[8]
    for e in range(XI.shape[0]):
        for k in range(R_):  # noqa: F821
            XK[e, k] = XI[e, k]
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            SK[i, k] = S[i, k]
    K[9][0] = 1


def op_coupled_jacobian_kernel(D, C, S, idx, J, K):
    """``J[i, a, b] = ∂N_i[idx[a]]/∂S_i[idx[b]] = Σ_{e∋i} (h/2w_i) ∂N/∂S(S_i, X_e)`` by the medium's
    ``m_coupled_jacobian`` at the half-edge velocities of the last :func:`op_coupled_velocities`
    (at ``S``, in ``K[6]``); False where the kernel has none (the caller takes forward differences)."""
    XI, NH = K[2], K[6]
    nl = idx.shape[0]
    half = 0.5 * D.cell
    X = np.empty((D_, R_))  # noqa: F821
    Jp = np.empty((R_, R_))  # noqa: F821
    for i in range(S.shape[0]):
        for a in range(nl):
            for b in range(nl):
                J[i, a, b] = 0.0
    for e in range(D.tail.shape[0]):
        for k in range(R_):  # noqa: F821
            X[0, k] = XI[e, k] / D.cell
        for end in range(2):
            i = D.tail[e] if end == 0 else D.head[e]
            if not m_coupled_jacobian(S[i], X, NH[e, end], D.params, Jp):  # noqa: F821
                return False
            for a in range(nl):
                for b in range(nl):
                    J[i, a, b] += half * Jp[idx[a], idx[b]]
    for i in range(S.shape[0]):
        for a in range(nl):
            for b in range(nl):
                J[i, a, b] = J[i, a, b] / D.w[i]
    return True


_COUPLED = (op_work_coupled, _coupled_solve, op_state_velocity_coupled, op_state_force_coupled, op_coupled_logs,
            op_coupled_velocities, op_coupled_keep)
#: the loops that run a coupled Lagrangian (``lie-euler``, ``forward-euler``: ``euler_loop``;
#: ``rkmk4``: ``rkmk_loop``; ``implicit-midpoint``: ``implicit_loop``, with the stage momenta of
#: :func:`cartan.integrators.newton.im_coupled_momentum`); the integrators without momentum
#: (``overdamped``, ``kinematic``), which share ``rkmk_loop``, decline it (``Integrator.run_compiled_loop``)
COUPLED_LOOPS = ("euler_loop", "rkmk_loop", "implicit_loop")
#: the rebinding of the stage operators of ``implicit-midpoint`` (:mod:`cartan.integrators.newton`)
COUPLED_STAGE = "op_stage_momentum = im_coupled_momentum\nop_stage_held = im_coupled_held\n"
#: why a set of a coupled Lagrangian serves those loops only
COUPLED_REASON = ("a Lagrangian coupling N and X runs compiled in the loops of lie-euler, forward-euler, rkmk4 "
                  "and implicit-midpoint only; the compiled diagnostics leave it to the numpy path")


#: the rebinding of the stage momenta's Jacobian to the medium's closed form (``coupled_jacobian``)
COUPLED_JACOBIAN = "op_coupled_jacobian = op_coupled_jacobian_kernel\n"


def coupled_fragment(jacobian: bool = False) -> Fragment:
    """The coupled operators (see above) and the rebinding of ``op_work``, ``op_state_velocity``,
    ``op_state_force`` and ``implicit-midpoint``'s stage operators (:data:`COUPLED_STAGE`) to them,
    to follow the loops in a generated module (``OperatorSet.late``); with ``jacobian`` (the medium
    declares ``MediumKernels.coupled_jacobian``) also :func:`op_coupled_jacobian_kernel`."""
    rebind = "\n".join(f"{name} = {name}_coupled" for name in ("op_work", "op_state_velocity", "op_state_force"))
    extra = (op_coupled_jacobian_kernel,) if jacobian else ()
    return Fragment(source=njit_source(*_COUPLED, *extra) + "\n\n\n" + rebind + "\n" + COUPLED_STAGE
                    + (COUPLED_JACOBIAN if jacobian else ""))


# ---------------------------------------------------------------------------- per-node accumulators
# A medium that declares accumulators (``Medium.accumulators``, :mod:`cartan.accumulators`) and
# their rates as a point kernel of the node's velocity (``MediumKernels.accumulator_rate``,
# ``m_accumulator_rate``): :func:`accumulate_fragment` rebinds the loops' ``op_accumulate``
# (:mod:`cartan.integrators.loops`) to :func:`op_accumulate_rates` after the loops
# (``OperatorSet.late``).  The accumulators ride in the data (``D.acc`` ``[a, n]``: ``pack`` loads
# them from the state, ``unpack`` writes them back), with the rates of the last state
# (``D.acc_rate``), and are updated by the trapezoidal rule in the floating-point order of
# :func:`cartan.accumulators.add`, ``a + (½Δt)(r_before + r_after)``.  The collocation's sets
# (:mod:`._collocation_ops`) take the same fragment with the same fields in their data.

def op_accumulate_rates(D, C, S, N, dt, begin):
    """``D.acc_rate`` ← the rates at velocity N (``m_accumulator_rate`` per node); unless
    ``begin``, first ``D.acc += ½Δt (D.acc_rate + rates)``."""
    A, R = D.acc, D.acc_rate
    na = A.shape[0]
    out = np.empty(na)
    for i in range(N.shape[0]):
        m_accumulator_rate(N[i], D.params, out)  # noqa: F821
        for j in range(na):
            if not begin:
                A[j, i] = A[j, i] + 0.5 * dt * (R[j, i] + out[j])
            R[j, i] = out[j]


#: the loops that call ``op_accumulate`` (``lie-verlet``; ``lie-euler``, ``forward-euler``;
#: ``rkmk4`` with momentum; ``implicit-midpoint``'s Newton blocks, :mod:`cartan.integrators.newton`)
ACCUMULATE_LOOPS = ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop")
#: those of them a set of a coupled Lagrangian serves
COUPLED_ACCUMULATE_LOOPS = tuple(name for name in COUPLED_LOOPS if name in ACCUMULATE_LOOPS)


def accumulate_fragment() -> Fragment:
    """:func:`op_accumulate_rates` and the rebinding of ``op_accumulate`` to it, to follow the
    loops in a generated module (``OperatorSet.late``); ``ACCUMULATES_`` (False in
    :mod:`cartan.integrators.newton`) tells ``implicit_loop`` to compute the velocities it needs."""
    return Fragment(constants={"ACCUMULATES_": True},
                    source=njit_source(op_accumulate_rates) + "\n\n\nop_accumulate = op_accumulate_rates\n")


def _accumulated(medium, kernels) -> tuple[str, ...]:
    """The names of the medium's accumulators the loops integrate: all it declares when its
    kernels give their rates (``accumulator_rate``), else none (the numpy path)."""
    from .. import accumulators

    names = tuple(accumulators.declared(medium))
    return names if names and getattr(kernels, "accumulator_rate", None) is not None else ()


# ---------------------------------------------------------------------------- threaded build
# The operators' passes over nodes, edges and corners as ``prange`` loops over fixed chunks of
# ``TCHUNK_`` items (compiled with ``parallel=True`` in the threaded module only,
# ``OperatorSet.generated(threaded=True)``; ``cartan._threads``).  Each chunk has its own work
# arrays, and no pass writes what another chunk writes: the force, which the serial
# ``op_force`` scatters from each edge to both its nodes, is computed per edge into edge arrays
# and gathered per node over the node's edges in increasing edge order (the corner stresses of a
# coupled lattice likewise, per corner and gathered per edge in increasing corner order), so that
# every sum is taken in the serial order: the results are those of the serial operators bit for
# bit, whatever the number of threads.  The powers stay serial (a sum over the grid in node
# order); the kinetic energy of the blow-up test adds per-chunk sums in chunk order.

def _t_chunks(count):
    return (count + TCHUNK_ - 1) // TCHUNK_  # noqa: F821


def _t_incidence(keys, count, rows):
    """CSR of ``rows`` lists: ``(ptr [rows + 1], item [len(keys)])`` with item ``p`` listed in
    row ``keys[p]``, each row's items in increasing p."""
    ptr = np.zeros(rows + 1, dtype=np.int64)
    for p in range(count):
        ptr[keys[p] + 1] += 1
    for i in range(rows):
        ptr[i + 1] += ptr[i]
    pos = ptr[:rows].copy()
    item = np.empty(count, dtype=np.int64)
    for p in range(count):
        item[pos[keys[p]]] = p
        pos[keys[p]] += 1
    return ptr, item


def op_work_threaded(D):
    """The work arrays of :func:`op_work` and those of the threaded passes: the edges' end
    forces ``VT``, ``VH`` ``[E, r]``, each node's edges (``2e`` as tail, ``2e + 1`` as head,
    CSR ``nptr``/``nedge``), the corner stresses ``QC`` ``[C, d, r]`` and each edge's corners
    (``c·d + b``, CSR ``cptr``/``ccorner``)."""
    n = D.winv.shape[0]
    ne = D.tail.shape[0]
    nc = D.cw.shape[0] if D.coupled else 0
    ends = np.empty(2 * ne, dtype=np.int64)
    for e in range(ne):
        ends[2 * e] = D.tail[e]
        ends[2 * e + 1] = D.head[e]
    nptr, nedge = _t_incidence(ends, 2 * ne, n)
    sides = np.empty(nc * D_, dtype=np.int64)  # noqa: F821
    for c in range(nc):
        for b in range(D_):  # noqa: F821
            sides[c * D_ + b] = D.cedge[c, b]  # noqa: F821
    cptr, ccorner = _t_incidence(sides, nc * D_, ne if D.coupled else 0)  # noqa: F821
    return (np.empty((n, M_, M_)), np.empty((n, M_, M_)), np.empty((ne, R_)), np.empty((ne, R_)),  # noqa: F821
            np.empty((ne, R_)), np.empty((ne, R_)), nptr, nedge, np.empty((nc, D_, R_)), cptr, ccorner)  # noqa: F821


def op_velocity_threaded(D, S, N):
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_any_clamped = D.any_clamped
    d_clamped = D.clamped
    d_any_held = D.any_held
    d_held = D.held
    d_inv_metric = D.inv_metric
    n = S.shape[0]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            if d_any_clamped and d_clamped[i]:
                for k in range(R_):  # noqa: F821
                    N[i, k] = 0.0
            else:
                for k in range(R_):  # noqa: F821
                    if d_any_held and d_held[i, k]:
                        N[i, k] = 0.0
                        continue
                    v = 0.0
                    for j in range(R_):  # noqa: F821
                        v += d_inv_metric[k, j] * S[i, j]
                    N[i, k] = v


def op_constrain_threaded(D, S):
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_any_clamped = D.any_clamped
    d_clamped = D.clamped
    d_any_held = D.any_held
    d_held = D.held
    d_live = D.live
    n = S.shape[0]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            zero = d_any_clamped and d_clamped[i]
            for k in range(R_):  # noqa: F821
                if zero or not d_live[k] or (d_any_held and d_held[i, k]):
                    S[i, k] = 0.0


def op_force_threaded(D, C, t, N, W, K):
    """:func:`op_force` in threaded passes: per edge (and corner), then per node."""
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_X0e = D.X0e
    d_any_clamped = D.any_clamped
    d_any_held = D.any_held
    d_held = D.held
    d_cX0 = D.cX0
    d_cX0u = D.cX0u
    d_cuniform = D.cuniform
    d_cedge = D.cedge
    d_clamped = D.clamped
    d_coupled = D.coupled
    d_cw = D.cw
    d_damp = D.damp
    d_eaxis = D.eaxis
    d_einvh = D.einvh
    d_end_div = D.end_div
    d_end_follow = D.end_follow
    d_end_idx = D.end_idx
    d_end_load = D.end_load
    d_escale = D.escale
    d_field = D.field
    d_has_field = D.has_field
    d_live = D.live
    d_params = D.params
    d_ubody = D.ubody
    d_winv = D.winv
    G, Phi = C
    XI, QE, VT, VH, nptr, nedge = K[2], K[3], K[4], K[5], K[6], K[7]
    ne = G.shape[0]
    n = W.shape[0]
    if d_coupled:
        QC, cptr, ccorner = K[8], K[9], K[10]
        for ch in prange(_t_chunks(ne)):  # noqa: F821
            g_log_chunk(G, ch * TCHUNK_, min(ne, (ch + 1) * TCHUNK_), XI)  # noqa: F821
        nc = d_cw.shape[0]
        for ch in prange(_t_chunks(nc)):  # noqa: F821
            X = np.empty((D_, R_))  # noqa: F821
            Q = np.empty((D_, R_))  # noqa: F821
            for c in range(ch * TCHUNK_, min(nc, (ch + 1) * TCHUNK_)):  # noqa: F821
                for b in range(D_):  # noqa: F821
                    e = d_cedge[c, b]
                    for k in range(R_):  # noqa: F821
                        X[b, k] = XI[e, k] * d_einvh[e]
                if d_cuniform:  # one rest strain passed as one array (op_force)
                    m_stress(X, d_cX0u, d_params, Q)  # noqa: F821
                else:
                    m_stress(X, d_cX0[c], d_params, Q)  # noqa: F821
                for b in range(D_):  # noqa: F821
                    for k in range(R_):  # noqa: F821
                        QC[c, b, k] = Q[b, k]
        for ch in prange(_t_chunks(ne)):  # noqa: F821
            lo, hi = ch * TCHUNK_, min(ne, (ch + 1) * TCHUNK_)  # noqa: F821
            for e in range(lo, hi):
                for k in range(R_):  # noqa: F821
                    QE[e, k] = 0.0
                for p in range(cptr[e], cptr[e + 1]):
                    c = ccorner[p] // D_  # noqa: F821
                    b = ccorner[p] - c * D_  # noqa: F821
                    f = d_cw[c] * d_einvh[e]
                    for k in range(R_):  # noqa: F821
                        QE[e, k] += f * QC[c, b, k]
            g_dexp_inv_T_pair_chunk(XI, QE, np.empty(0), lo, hi, VT, VH)  # noqa: F821
    else:
        for ch in prange(_t_chunks(ne)):  # noqa: F821
            X = np.empty((D_, R_))  # noqa: F821
            Q = np.empty((D_, R_))  # noqa: F821
            lo, hi = ch * TCHUNK_, min(ne, (ch + 1) * TCHUNK_)  # noqa: F821
            g_log_chunk(G, lo, hi, XI)  # noqa: F821
            for e in range(lo, hi):
                a = d_eaxis[e]
                for b in range(D_):  # noqa: F821
                    for k in range(R_):  # noqa: F821
                        X[b, k] = d_X0e[e, b, k]
                for k in range(R_):  # noqa: F821
                    X[a, k] = XI[e, k] * d_einvh[e]
                m_stress(X, d_X0e[e], d_params, Q)  # noqa: F821
                for k in range(R_):  # noqa: F821
                    QE[e, k] = Q[a, k]
            g_dexp_inv_T_pair_chunk(XI, QE, d_escale, lo, hi, VT, VH)  # noqa: F821
    nf = d_field.shape[0]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            for k in range(R_):  # noqa: F821
                W[i, k] = 0.0
            for p in range(nptr[i], nptr[i + 1]):
                e = nedge[p] // 2
                if nedge[p] - 2 * e == 0:
                    for k in range(R_):  # noqa: F821
                        W[i, k] += VT[e, k]
                else:
                    for k in range(R_):  # noqa: F821
                        W[i, k] -= VH[e, k]
            for k in range(R_):  # noqa: F821
                W[i, k] = W[i, k] * d_winv[i] - d_damp[k] * N[i, k] + d_ubody[k]
            if d_has_field:
                for k in range(nf):
                    s = 0.0
                    for b in range(nf):
                        s += Phi[i, b + 1, k + 1] * d_field[b]
                    W[i, k] += s
    if d_end_idx.shape[0]:
        vec = np.empty(R_)  # noqa: F821
        for p in range(d_end_idx.shape[0]):
            i = d_end_idx[p]
            if d_end_follow[p]:
                for k in range(R_):  # noqa: F821
                    W[i, k] += d_end_load[p, k] * d_end_div[p]
            else:
                _dead_to_body(D, Phi[i], d_end_load[p], vec)
                for k in range(R_):  # noqa: F821
                    W[i, k] += vec[k] * d_end_div[p]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            zero = d_any_clamped and d_clamped[i]
            for k in range(R_):  # noqa: F821
                if zero or not d_live[k] or (d_any_held and d_held[i, k]):
                    W[i, k] = 0.0


def op_move_threaded(D, C, Dn, K):
    """:func:`op_move` in threaded passes (the edges read the nodes' motions only)."""
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_head = D.head
    d_tail = D.tail
    G, Phi = C
    Di = K[1]
    n = Dn.shape[0]
    ne = G.shape[0]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        g_frames_chunk(Dn, Di, Phi, ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_))  # noqa: F821
    for ch in prange(_t_chunks(ne)):  # noqa: F821
        g_move_chunk(Di, Dn, G, d_tail, d_head, ch * TCHUNK_, min(ne, (ch + 1) * TCHUNK_))  # noqa: F821


def op_free_flow_threaded(D, C, S, pieces, fracs, dt, Dn, K):
    """:func:`op_free_flow` with its pass over the nodes threaded (the same per-node steps)."""
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_any_clamped = D.any_clamped
    d_clamped = D.clamped
    d_any_held = D.any_held
    d_held = D.held
    npieces, tau, axial, naxes, axes, coef, cnt, col = _flow_plan(pieces, fracs, dt)
    eye = np.empty((M_, M_))  # noqa: F821
    g_exp(np.zeros(R_), eye)  # noqa: F821 - the identity (a node that does not move)
    n = S.shape[0]
    nch = _t_chunks(n)
    moved_chunk = np.zeros(nch, dtype=np.bool_)
    for ch in prange(nch):  # noqa: F821
        xi = np.zeros(R_)  # noqa: F821
        out = np.empty(R_)  # noqa: F821
        E = np.empty((M_, M_))  # noqa: F821
        tmp = np.empty((M_, M_))  # noqa: F821
        wk = g_work()  # noqa: F821
        TK = np.empty((FCHUNK_, R_))  # noqa: F821
        moved = False
        hi = min(n, (ch + 1) * TCHUNK_)  # noqa: F821
        for lo in range(ch * TCHUNK_, hi, FCHUNK_):  # noqa: F821
            if _flow_chunk(lo, min(hi, lo + FCHUNK_), S, Dn, d_any_clamped, d_clamped, d_any_held,  # noqa: F821
                           d_held, pieces, npieces, tau, axial, naxes, axes, coef, cnt, col, eye, xi, out, E, tmp,
                           wk, TK):
                moved = True
        moved_chunk[ch] = moved
    any_moved = False
    for ch in range(nch):
        if moved_chunk[ch]:
            any_moved = True
    if any_moved:
        op_move_threaded(D, C, Dn, K)
    return any_moved


def op_drift_threaded(D, C, tau, N, K):
    Dn = K[0]
    n = N.shape[0]
    for ch in prange(_t_chunks(n)):  # noqa: F821
        xi = np.empty(R_)  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            for k in range(R_):  # noqa: F821
                xi[k] = tau * N[i, k]
            g_exp(xi, Dn[i])  # noqa: F821
    op_move_threaded(D, C, Dn, K)


def op_kinetic_threaded(D, S):
    """:func:`op_kinetic` as per-chunk sums added in chunk order (the same for any number of
    threads; it differs from the serial sum by round-off, and only decides the blow-up test)."""
    # (the data's fields as locals: a prange body takes arrays and numbers, not the named tuple)
    d_any_clamped = D.any_clamped
    d_clamped = D.clamped
    d_any_held = D.any_held
    d_held = D.held
    d_diagonal = D.diagonal
    d_inv_metric = D.inv_metric
    d_metric = D.metric
    d_w = D.w
    n = S.shape[0]
    nch = _t_chunks(n)
    part = np.zeros(nch)
    for ch in prange(nch):  # noqa: F821
        e = 0.0
        Nv = np.empty(R_)  # noqa: F821
        for i in range(ch * TCHUNK_, min(n, (ch + 1) * TCHUNK_)):  # noqa: F821
            if d_any_clamped and d_clamped[i]:
                continue
            if d_any_held and _held_row(d_held, i):
                e += _kinetic_held_node(S, i, d_w[i], d_diagonal, d_inv_metric, d_metric, d_held, Nv)
                continue
            for k in range(R_):  # noqa: F821
                if d_diagonal:
                    e += 0.5 * d_w[i] * S[i, k] * S[i, k] * d_inv_metric[k, k]
                else:
                    v = 0.0
                    for j in range(R_):  # noqa: F821
                        v += d_inv_metric[k, j] * S[i, j]
                    e += 0.5 * d_w[i] * S[i, k] * v
        part[ch] = e
    total = 0.0
    for ch in range(nch):
        total += part[ch]
    return total


_THREADED = (_t_chunks, _t_incidence, op_work_threaded, op_velocity_threaded, op_constrain_threaded,
             op_force_threaded, op_move_threaded, op_free_flow_threaded, op_drift_threaded, op_kinetic_threaded)
#: the operators the threaded build replaces (``op_x = op_x_threaded`` after the loops)
_REPLACED = ("op_work", "op_velocity", "op_constrain", "op_force", "op_move", "op_free_flow", "op_drift",
             "op_kinetic")
#: items (nodes, edges, corners) per chunk of a threaded pass
THREAD_CHUNK = 512
#: nodes per chunk of the free flow's passes (:func:`_flow_chunk`: their rows, ≈ 20 KB on SE(3), stay in
#: the first-level cache)
FLOW_CHUNK = 128


def threaded_fragment() -> Fragment:
    """The threaded build's operators (see above) and the rebinding of the operators' names."""
    rebind = "\n".join(f"{name} = {name}_threaded" for name in _REPLACED)
    return Fragment(constants={"TCHUNK_": THREAD_CHUNK}, source=njit_source(*_THREADED) + "\n\n\n" + rebind + "\n",
                    parallel=tuple(f.__name__ for f in _THREADED if "prange" in f.__code__.co_names))


# ---------------------------------------------------------------------------- building the set
def _field_loads(scheme) -> np.ndarray | None:
    """``ρf`` ``(k,)`` summed over the ``ConstantFieldPotential`` loads (``(0,)`` without one), or
    None when one of them is not the core's constant field: a load that changes its force,
    energy or position methods, or whose ``force`` and ``energy`` at a few frames differ from
    ``Rᵀρf`` on the first k components and ``−ρf·x`` (x = Φ[1:, 0]) — the formulas of
    :func:`_field_force` and :func:`op_potential`."""
    from ..problem import ConstantFieldPotential, PotentialLoad

    loads = [ld for ld in scheme.problem.loads if isinstance(ld, ConstantFieldPotential)]
    if not loads:
        return np.zeros(0)
    methods = ("potential_gradient", "potential_energy", "position", "_matrix")
    if any(type(ld).force is not PotentialLoad.force or type(ld).energy is not PotentialLoad.energy
           or any(getattr(type(ld), name) is not getattr(ConstantFieldPotential, name) for name in methods)
           for ld in loads):
        return None
    g = scheme.group
    field = sum(ld.density * np.asarray(ld.field, dtype=float) for ld in loads)
    k = field.shape[0]
    if k >= g.matrix_size or k > g.dim:
        return None
    Phi = g.exp(np.random.default_rng(0).standard_normal((3, g.dim)))
    T = np.zeros((3, g.dim))
    T[:, :k] = np.einsum("ibk,b->ik", Phi[:, 1:k + 1, 1:k + 1], field)
    force = sum(ld.force(Phi, np.zeros((3, g.dim)), 0.0) for ld in loads)
    energy = sum(ld.energy(Phi) for ld in loads)
    # both sides are a few products of O(1) frames with ρf: they agree to round-off of |ρf|
    scale = 1e-12 * max(1.0, float(np.max(np.abs(field))) * float(np.max(np.abs(Phi))))
    if np.max(np.abs(force - T)) > scale or np.max(np.abs(energy + Phi[:, 1:k + 1, 0] @ field)) > scale:
        return None
    return field


def _supported_loads(scheme, held: bool = False) -> tuple | None:
    """``(damp, ubody, field)`` of the loads the operators run — ``Damping``, body-frame
    ``UniformForce`` and the core's ``ConstantFieldPotential`` (:func:`_field_loads`) — or
    None when a load or a boundary is of another kind (boundaries: ``Free`` and ``Clamped``,
    and with ``held`` also ``Held`` and ``Symmetry``, whose components ``LatticeData.held`` holds,
    and ``Driven``, whose nodes ``LatticeData.dnodes`` lists)."""
    from ..problem import Clamped, ConstantFieldPotential, Damping, Driven, Free, Held, Symmetry, UniformForce

    r = scheme.group.dim
    damp, ubody = np.zeros(r), np.zeros(r)
    for load in scheme.problem.loads:
        if type(load) is Damping:
            damp = damp + np.asarray(load.coefficients, dtype=float)
        elif type(load) is UniformForce and load.frame == "body":
            ubody = ubody + np.asarray(load.components, dtype=float)
        elif not isinstance(load, ConstantFieldPotential):
            return None
    field = _field_loads(scheme)
    kinds = (Free, Clamped, Held, Symmetry, Driven) if held else (Free, Clamped)
    if field is None or any(type(b) not in kinds for b in scheme.problem.boundaries.values()):
        return None
    return damp, ubody, field


def _why_not(scheme, reference: type) -> str | None:
    """Why the operator set does not cover this problem, or None when it does (``reference``:
    the scheme class whose methods the operators implement)."""
    from ..medium import Medium
    from .base import Scheme

    medium = scheme.medium
    if scheme.group.point_kernels() is None:
        return f"the group {scheme.group!r} has no numba point kernels"
    kernels = medium.point_kernels()
    if kernels is None:
        return f"the medium {medium.name!r} declares no point kernels (Medium.point_kernels)"
    if scheme.coupled_lagrangian and (getattr(kernels, "coupled_velocity", None) is None
                                      or getattr(kernels, "coupled_stress", None) is None):
        return (f"the medium {medium.name!r} couples N and X and declares no coupled point kernels "
                "(MediumKernels.coupled_velocity, coupled_stress)")
    for name in ("force", "internal_force", "drift", "frames", "_boundary_power", "_axis_stress", "initial_state",
                 "_key"):
        if getattr(type(scheme), name) is not getattr(reference, name):
            return f"the scheme overrides {name}"
    for name in ("velocity", "constrain", "powers", "has_external_power", "drag"):
        if getattr(type(scheme), name) is not getattr(Scheme, name):
            return f"the scheme overrides {name}"
    for name in ("velocity", "body_force"):
        if getattr(type(medium), name) is not getattr(Medium, name):
            return f"the medium overrides {name}"
    if getattr(medium, "velocity_dependent_forces", False):
        return "the medium has velocity-dependent forces"
    loads = _supported_loads(scheme, held=True)
    if loads is None:
        return ("a load or boundary is not one of Damping, body-frame UniformForce, ConstantFieldPotential "
                "(the core's constant field), Free, Clamped, Held, Symmetry, Driven")
    if any(not b.follower for _, b in scheme._end_loads) and not scheme.track:
        return "a dead end load needs stepped frames"
    if loads[2].size and not scheme.track:
        return "a constant field (gravity) needs stepped frames"
    return None


def check_kernels(medium, kernels, d: int, r: int) -> None:
    """Raise ``ValueError`` naming the medium when its point kernels disagree with its
    ``stress_at`` at a few strains near the rest strain (a declaration that does not describe
    the medium would make the compiled loops run other physics than the reference path)."""
    X0 = np.ascontiguousarray(np.asarray(medium.rest_strain(), dtype=float).reshape(d, r))
    params = np.ascontiguousarray(kernels.params, dtype=float).ravel()
    rng = np.random.default_rng(0)
    for _ in range(3):
        X = np.ascontiguousarray(X0 + 0.05 * rng.standard_normal((d, r)))
        Q = np.empty((d, r))
        kernels.stress(X, X0, params, Q)
        ref = np.asarray(medium.stress_at(X[None], X0[None]), dtype=float).reshape(d, r)
        scale = max(float(np.max(np.abs(ref))), 1e-300)
        if not float(np.max(np.abs(Q - ref))) <= 1e-9 * scale:
            raise ValueError(
                f"medium {medium.name!r}: point_kernels() disagree with stress() (relative difference "
                f"{float(np.max(np.abs(Q - ref))) / scale:.1e} at a strain near the rest strain); fix the kernels, "
                "or return None from point_kernels() to run the medium on the numpy path")


def check_coupled_kernels(medium, kernels, r: int) -> None:
    """Raise ``ValueError`` naming the medium when its coupled point kernels
    (``MediumKernels.coupled_velocity``, ``coupled_stress``) disagree with its
    :meth:`~cartan.medium.Medium.velocity_at` and :meth:`~cartan.medium.Medium.stress_with` at a
    few small momenta (on the live components) and strains near the rest strain (d = 1)."""
    X0 = np.ascontiguousarray(np.asarray(medium.rest_strain(), dtype=float).reshape(1, r))
    live = ~np.asarray(medium.gauge_mask(), dtype=bool)
    params = np.ascontiguousarray(kernels.params, dtype=float).ravel()
    rng = np.random.default_rng(0)
    scale = max(float(np.max(np.abs(X0))), 1.0)
    for _ in range(3):
        X = np.ascontiguousarray(X0 + 0.05 * scale * rng.standard_normal((1, r)))
        S = np.ascontiguousarray(np.where(live, 0.05 * rng.standard_normal(r), 0.0))
        N, Q = np.empty(r), np.empty((1, r))
        ok = kernels.coupled_velocity(S, X, params, N)
        if ok:
            kernels.coupled_stress(S, X, N, params, Q)
        N_ref = np.asarray(medium.velocity_at(S[None], X[None]), dtype=float).reshape(r)
        Q_ref = np.asarray(medium.stress_with(S[None], X[None]), dtype=float).reshape(1, r)
        for what, got, ref in (("velocity_at", N, N_ref), ("stress_with", Q, Q_ref)):
            top = max(float(np.max(np.abs(ref))), 1e-300)
            if not (ok and float(np.max(np.abs(got - ref))) <= 1e-9 * top):
                raise ValueError(
                    f"medium {medium.name!r}: the coupled point kernels disagree with {what}() at a momentum "
                    "near zero and a strain near the rest strain; fix the kernels, or declare no coupled_velocity "
                    "and coupled_stress in point_kernels() to run the medium on the numpy path")


def _nodal_scale(n: int, d: int, tails: list, heads: list) -> np.ndarray:
    """``[n, d]``: 1 over the number of edges along α at each node (2 inside, 1 at the ends of
    an open axis; 0 where there is none) — :meth:`Lattice.nodal_strains` averages them."""
    count = np.zeros((n, d))
    for a in range(d):
        np.add.at(count[:, a], tails[a], 1.0)
        np.add.at(count[:, a], heads[a], 1.0)
    return np.where(count > 0, 1.0 / np.where(count > 0, count, 1.0), 0.0)


def lattice_operators(scheme, reference: type):
    """The compiled operator set of a lattice scheme, or a declined set that says why
    (``OperatorSet.reason``); ``reference`` is :class:`~cartan.schemes.lattice.Lattice`, whose
    methods the operators implement (a subclass that overrides one is declined)."""
    from ..compiled.kernels import kernel_stem, medium_fragment
    from ..compiled.operators import OperatorSet

    reason = _why_not(scheme, reference)
    if reason is not None:
        return OperatorSet.declined(reason)
    grid, group, medium = scheme.grid, scheme.group, scheme.medium
    kernels = medium.point_kernels()
    d, r, m = grid.d, group.dim, group.matrix_size
    check_kernels(medium, kernels, d, r)
    shape = tuple(int(s) for s in grid.shape)
    n = int(np.prod(shape))
    h = [float(v) for v in scheme.h]
    cell = float(np.prod(h))
    tails, heads = scheme.edge_nodes()
    axes = [np.full(t.size, a) for a, t in enumerate(tails)]
    invh = [np.full(t.size, 1.0 / h[a]) for a, t in enumerate(tails)]
    scale = [np.full(t.size, cell / h[a]) for a, t in enumerate(tails)]
    E = int(sum(t.size for t in tails))
    X0 = np.asarray(medium.rest_strain(), dtype=float).reshape(d, r)
    if scheme.problem.reference is not None:
        X0e = np.concatenate([scheme.edge_rest_strains(a).reshape(-1, d, r) for a in range(d)])
    else:
        X0e = np.broadcast_to(X0, (E, d, r))
    if scheme.coupled:
        corners = scheme.corners()
        offsets = np.cumsum([0] + [t.size for t in tails])[:d]
        cedge = corners["edge"] + offsets[None, :]
        cw, cX0 = corners["weight"], corners["X0"]
    else:
        cedge, cw, cX0 = np.zeros((0, d), dtype=np.int64), np.zeros(0), np.zeros((0, d, r))
    cX0 = np.asarray(cX0, dtype=float)
    cuniform = bool(cX0.shape[0]) and bool(np.all(cX0 == cX0[:1]))
    cX0u = np.ascontiguousarray(cX0[0]) if cuniform else np.zeros((d, r))
    damp, ubody, field = _supported_loads(scheme, held=True)
    weights = np.ascontiguousarray(scheme.weights, dtype=float).reshape(n)
    entries = scheme.end_load_entries()
    held = np.asarray(scheme._clamped, dtype=np.bool_)
    held = np.ascontiguousarray(np.broadcast_to(held.reshape(*shape, -1), (*shape, r)).reshape(n, r))
    clamped = np.ascontiguousarray(held.all(axis=1))
    data = LatticeData(
        d=d, r=r, m=m, affine=bool(getattr(group, "affine", False)), track=bool(scheme.track),
        tail=np.concatenate(tails).astype(np.int64), head=np.concatenate(heads).astype(np.int64),
        eaxis=np.concatenate(axes).astype(np.int64), einvh=np.concatenate(invh), escale=np.concatenate(scale),
        X0e=np.ascontiguousarray(X0e), coupled=bool(scheme.coupled), cedge=np.ascontiguousarray(cedge, dtype=np.int64),
        cw=np.ascontiguousarray(cw, dtype=float), cX0=np.ascontiguousarray(cX0, dtype=float),
        cuniform=cuniform, cX0u=cX0u,
        params=np.ascontiguousarray(kernels.params, dtype=float).ravel(),
        winv=1.0 / weights, w=weights,
        inv_metric=np.ascontiguousarray(scheme.inverse_metric, dtype=float),
        live=np.ascontiguousarray(scheme.live, dtype=np.bool_), clamped=clamped, any_clamped=bool(clamped.any()),
        held=held, any_held=bool(np.any(held.any(axis=1) & ~clamped)),
        metric=np.ascontiguousarray(medium.kinetic_metric(), dtype=float).reshape(r, r),
        damp=damp, ubody=ubody,
        end_idx=np.array([i for i, _, _ in entries], dtype=np.int64),
        end_load=np.array([np.asarray(b.load, dtype=float) for _, b, _ in entries], dtype=float).reshape(-1, r),
        end_loaded=np.ones(len(entries), dtype=np.bool_),
        end_follow=np.array([bool(b.follower) for _, b, _ in entries], dtype=np.bool_),
        end_div=np.array([1.0 / (0.5 * h[a]) for _, _, a in entries], dtype=float),
        end_face=np.array([weights[i] / (0.5 * h[a]) for i, _, a in entries], dtype=float),
        has_power=bool(scheme.has_external_power()),
        field=np.ascontiguousarray(field, dtype=float), has_field=bool(field.size), cell=cell,
        diagonal=bool(scheme.diagonal_metric), nscale=_nodal_scale(n, d, tails, heads), shape=shape,
        coords=np.ascontiguousarray(
            np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(d)], indexing="ij"), -1).reshape(n, d),
            dtype=float),
    )
    data = data._replace(**_driven_data(scheme, data, n, r))
    keys = [scheme._key(a) for a in range(d)]
    frame_key = "Phi" if scheme.track else "Phi_root"
    # per-node accumulators (not with driven ends, whose set serves the loops without the hook too)
    acc_names = () if data.any_driven else _accumulated(medium, kernels)
    acc_keys = [f"accumulator_{name}" for name in acc_names]  # (cartan.accumulators.key)
    data = data._replace(acc=np.zeros((len(acc_names), n)), acc_rate=np.zeros((len(acc_names), n)))

    def pack(state):
        G = np.concatenate([np.asarray(state.arrays[k], dtype=float).reshape(-1, m, m) for k in keys])
        Phi = np.ascontiguousarray(state.arrays[frame_key], dtype=float).reshape(-1, m, m).copy()
        for j, k in enumerate(acc_keys):
            data.acc[j] = np.asarray(state.arrays[k], dtype=float).reshape(n)
        return (np.ascontiguousarray(G), Phi)

    def unpack(state, C):
        G, Phi = C
        start = 0
        for k in keys:
            shape_k = state.arrays[k].shape
            count = math.prod(shape_k[:-2])
            state.arrays[k] = G[start:start + count].reshape(shape_k).copy()
            start += count
        state.arrays[frame_key] = Phi.reshape(state.arrays[frame_key].shape).copy()
        for j, k in enumerate(acc_keys):
            state.arrays[k] = data.acc[j].reshape(shape).copy()

    def accepts(state) -> bool:
        return set(state.arrays) == {*keys, frame_key, *acc_keys}

    fragments = [group.point_kernels(), medium_fragment(kernels),
                 Fragment(imports={"LatticeData": (__name__, "LatticeData")},
                          constants={"D_": d, "R_": r, "M_": m, "FCHUNK_": FLOW_CHUNK},
                          source=njit_source(*_OPERATORS, *_HELD))]
    label, key = f"lattice × {group!r} × {medium.name}", f"lattice-{group!r}-{kernel_stem(kernels)}"
    acc_late, acc_stem = ([accumulate_fragment()], "-acc") if acc_names else ([], "")
    if scheme.coupled_lagrangian:  # (d = 1, no driven ends or held components: the scheme refuses them)
        check_coupled_kernels(medium, kernels, r)
        return OperatorSet(label=label + " (coupled Lagrangian)", key=key + "-coupled" + acc_stem, fragments=fragments,
                           data=data, pack=pack, unpack=unpack, accepts=accepts, nodes=n,
                           late=[coupled_fragment(getattr(kernels, "coupled_jacobian", None) is not None), *acc_late],
                           reason=COUPLED_REASON, loops=COUPLED_LOOPS,
                           accumulates=COUPLED_ACCUMULATE_LOOPS if acc_names else ())
    if data.any_driven:  # (no threaded build: its passes over the nodes know no driven node)
        return OperatorSet(label=label + " (driven ends)", key=key + "-driven", fragments=fragments, data=data,
                           pack=pack, unpack=unpack, accepts=accepts, nodes=n, late=[driven_fragment()],
                           reason=DRIVEN_REASON, loops=DRIVEN_LOOPS)
    return OperatorSet(label=label, key=key + acc_stem, fragments=fragments, data=data, pack=pack, unpack=unpack,
                       accepts=accepts, nodes=n, threaded=[threaded_fragment()], late=acc_late,
                       accumulates=ACCUMULATE_LOOPS if acc_names else ())


#: the loops that move driven ends (``lie-verlet``, ``lie-euler``, ``rkmk4``, ``overdamped``, ``rattle``,
#: ``implicit-midpoint``:
#: their Python steps move a driven node by exp(Δtξ), ``Integrator.driven_reason``)
DRIVEN_LOOPS = ("lie_verlet_loop", "euler_loop", "rkmk_loop", "rattle_loop", "implicit_loop", DIAGNOSTICS_SERVED)
#: why a set with driven nodes serves those loops only
DRIVEN_REASON = ("a Driven end runs compiled in the loops of lie-verlet, lie-euler, rkmk4, overdamped, rattle and "
                 "implicit-midpoint and in the compiled diagnostics only")


def _driven_data(scheme, data: LatticeData, n: int, r: int) -> dict:
    """The ``LatticeData`` fields of the driven ends (``Scheme._driven``): the nodes, their ξ
    and ∂K/∂N(ξ), the edges with a driven end and, coupled, those edges' corners (CSR)."""
    d = data.d
    none = np.zeros(0, dtype=np.int64)
    fields = dict(any_driven=False, dnodes=none, dslot=np.full(n, -1, dtype=np.int64), xi_d=np.zeros((0, r)),
                  S_d=np.zeros((0, r)), dedge=none, dcorner=none, dcptr=np.zeros(1, dtype=np.int64), dcitem=none)
    if scheme._driven is None:
        return fields
    mask, Nd, Sd = scheme._driven
    mask = np.asarray(mask, dtype=bool).reshape(n)
    dnodes = np.flatnonzero(mask).astype(np.int64)
    fields["dslot"][dnodes] = np.arange(dnodes.size)
    dedge = np.flatnonzero(mask[data.tail] | mask[data.head]).astype(np.int64)
    pos = np.full(data.tail.size, -1, dtype=np.int64)
    pos[dedge] = np.arange(dedge.size)
    items: list[list[int]] = [[] for _ in range(dedge.size)]
    dcorner = none
    if data.coupled:
        dcorner = np.flatnonzero((pos[data.cedge] >= 0).any(axis=1)).astype(np.int64)
        for c_, c in enumerate(dcorner):
            for b in range(d):
                if pos[data.cedge[c, b]] >= 0:
                    items[pos[data.cedge[c, b]]].append(c_ * d + b)
    fields.update(any_driven=True, dnodes=dnodes, xi_d=np.ascontiguousarray(Nd, dtype=float).reshape(n, r),
                  S_d=np.ascontiguousarray(Sd, dtype=float).reshape(n, r), dedge=dedge, dcorner=dcorner,
                  dcptr=np.cumsum([0] + [len(it) for it in items]).astype(np.int64),
                  dcitem=np.array([v for it in items for v in it], dtype=np.int64))
    return fields
