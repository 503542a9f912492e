"""The collocation scheme's compiled operator set: what the generated integrator loops call.

:func:`collocation_operators` turns a collocation problem into an
:class:`~cartan.compiled.operators.OperatorSet` with the operators and signatures of the
lattice's (:mod:`cartan.schemes._lattice_ops`, whose module docstring is the contract), plus
``op_potential(D, C, K) -> float`` and ``op_nodal_strains(D, C, X)``.  The problem is data
(:class:`CollocationData`: nodes in C order of the grid, any d = 1, 2, 3), the configuration
the tuple ``C = (X, Phi)`` — the nodal strains ``X`` ``[n, d, r]`` (the scheme's unknowns) and
the stepped frames ``Phi`` ``[n, m, m]`` (or the root frame ``[1, m, m]``).

The formulas are those of :class:`~cartan.schemes.collocation.Collocation` (the reference
path).  Each axis' difference operator ∂_α (``fd2``, ``fd4`` with their SBP closures on open
axes, ``fourier`` as its dense circulant matrix) is one sparse matrix along the axis
(``indptr``/``col``/``coef``), applied at node i to the row of i's index along the axis.

Force (paper §IV balance law, §V ``W = D*_u Q + T``)
    ``W_i = Σ_α (∂_αQ^α)_i − ad_{X_iα}ᵀ Q_i^α`` with ``Q_i = ∂U/∂X(X_i; X0_i)`` from the
    medium's point kernel (all axes at once: axis-coupled energies are node-local here), the
    free-end penalties ``(P − n_α Q^α)/H_end`` (paper §IV.D), damping ``−ΓN``, a body-frame
    force, a constant field ``Rᵀρf``; zero at clamped nodes, on held components and on gauge
    components.
Drift (paper §V, Eq. (X LGI))
    ``X_α ← Ad_{exp(−τN)} X_α + 𝓔(τ, −N) ∂_αN``, ``Φ ← Φ exp(τN)``; the naive update
    ``X_α ← X_α + τ(∂_αN − ad_N X_α)``, ``Φ ← Φ + τΦN̂``.
Move
    ``op_move(D, C, Dn, K)``: every node by ``Dn_i = exp(σ_i)``, σ = log Dn, i.e. the drift
    with τ = 1 and N = σ: ``X_α ← Ad_{Dn⁻¹} X_α + 𝓔(1, −σ) ∂_ασ``, ``Φ_i ← Φ_i Dn_i``.  The
    strains are not a function of the frames, so successive drifts by different fields do not
    compose into one move: ``op_move`` after several free-flow pieces is not the reference's
    piece-by-piece drift (it is for one piece, e.g. an abelian group).  ``op_free_flow(D, C, S,
    pieces, fracs, dt, Dn, K)`` takes ``lie-verlet``'s free flow as the reference does: each
    piece's momentum update and exact drift in turn (N_p zero at clamped nodes and on held
    components).
Energies
    ``op_potential``: ``Σ_i w_i U(X_i; X0_i) − Σ_i w_i J_i ρf·x_i``; ``op_kinetic``:
    ``½Σ_i w_i J_i S_i·M⁺S_i`` over the unclamped nodes (``Scheme.kinetic_energy``); J_i = 1
    but on a general chart (the medium's reference volume, ``Collocation.weights``), where the
    internal force is divided by J_i too.
Held components (``Held`` ends, ``Symmetry`` faces; paper §IV.D)
    ``held`` ``[n, r]`` is the scheme's clamp mask (``Scheme._clamp_mask``, all r at clamped
    nodes), ``clamped`` its rows that hold every component, ``any_held`` whether a node holds
    some components and not all, as on the lattice (:mod:`cartan.schemes._lattice_ops`, "Held
    components"): the velocity, the momentum's constraint and the force are zero on the held
    components, ``lie-verlet``'s free flow moves a node along its free components only (N_p
    zero on the held ones, as the reference's ``N = M⁺S`` zeroed there), and the kinetic
    energy of a partly held node is ``½ w N·MN`` with those N (``metric`` M).  The free
    components of a held end or a symmetry face take the penalty of an unloaded free end
    (P = 0: ``end_loaded`` False, no power), as ``Collocation._end_load`` does.
Node forces (``NodeForce``)
    ``nf_idx``, ``nf_load``, ``nf_follow``, ``nf_w``: ``W_i += P_body/w_q`` at the node (a dead
    load rotated by Φ there, :func:`_c_node_force`), zero where the node's components are held;
    their power ``w_i (P_body/w_q)·N_i`` joins the external power (``op_powers_nodal``, bound to
    ``op_powers`` in the set's module).
Driven ends (``Driven``; module docstring of :mod:`cartan.schemes.collocation`, "Driven ends")
    The driven nodes are held (``clamped``) and listed with their ξ and ∂K/∂N(ξ) (``dnodes``,
    ``xi_d``, ``S_d``); a set that has them adds :func:`driven_fragment` after the loops
    (``OperatorSet.late``): the velocity ξ, the momentum ∂K/∂N(ξ) and the kinetic energy
    ½wξ·Mξ there (the lattice's wrappers), ``lie-verlet``'s pieces carry ξ on their directions
    (``_c_piece_velocity_driven``: the drift moves the driven frames by exp(τξ) and the strains
    with ξ in ∂_αN, as every other loop's drift does with N = ξ there), and the supports' power
    ``R·ξ = −w W·ξ`` joins the external power, W the raw force of ``Collocation.force(raw=True)``
    at the driven nodes — :func:`op_force`'s terms (free-face penalties at corners included)
    plus the weak-form term ``−n_α Q^α/H_end`` of each clamped or driven end through the node
    (``Collocation._clamped_traction``; ``dtr_*``), the stress computed at the nodes of their
    stencils only (``pnodes``).  It serves the loops of ``lie-verlet``, ``lie-euler``,
    ``rkmk4``, ``overdamped`` and ``implicit-midpoint`` (``OperatorSet.loops``) and the compiled
    diagnostics (:mod:`cartan.compiled.diagnostics`: the CFL probe's drift and force, the driven
    nodes held; the guard's ``op_kinetic`` with their ½wξ·Mξ and ``op_potential``).
Coupled Lagrangians (``Medium.coupled_lagrangian``, d = 1; :mod:`cartan.schemes._collocation_coupled`)
    A medium with coupled point kernels: :func:`coupled_fragment` rebinds the loops'
    ``op_state_velocity`` and ``op_state_force`` to ``N_i = N(S_i, X_i)`` (zero at clamped nodes)
    and to the force of the Hamiltonian stress ``Q_i = Q(S_i, X_i)``, node by node, and
    ``implicit-midpoint``'s stage momenta to ``S_i`` solving ``N(S_i, X_i) = N_i`` per node
    (:func:`cartan.integrators.newton.im_coupled_momentum` over :func:`op_coupled_velocities`); the
    set serves the loops of ``lie-euler``, ``forward-euler``, ``rkmk4`` and ``implicit-midpoint`` only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..compiled.codegen import Fragment, njit_source
from ..compiled.diagnostics import SERVED as DIAGNOSTICS_SERVED
from ..problem import Clamped, Driven, NodeForce
from ._lattice_ops import (
    _HELD,
    ACCUMULATE_LOOPS,
    COUPLED_ACCUMULATE_LOOPS,
    COUPLED_JACOBIAN,
    COUPLED_LOOPS,
    COUPLED_REASON,
    COUPLED_STAGE,
    _accumulated,
    _dead_to_body,
    _supported_loads,
    accumulate_fragment,
    check_coupled_kernels,
    check_kernels,
    op_constrain,
    op_constrain_driven,
    op_copy_config,
    op_drive_driven,
    op_finite_config,
    op_kinetic,
    op_kinetic_driven,
    op_new_config,
    op_powers,
    op_velocity,
    op_velocity_driven,
)

__all__ = ["CollocationData", "collocation_operators"]


class CollocationData(NamedTuple):
    """A collocation problem as flat arrays (n nodes in C order, d axes, r = dim 𝔤, m the matrix size)."""

    d: int
    r: int
    m: int
    affine: bool
    track: bool
    shape: tuple  # the grid shape (ints)
    coords: np.ndarray  # [n, d] node coordinates
    stride: np.ndarray  # [d] int64, C-order stride of each axis
    naxis: np.ndarray  # [d] int64, nodes along each axis
    indptr: np.ndarray  # [d, max naxis + 1] int64: row j of axis α is entries indptr[α, j]:indptr[α, j + 1]
    col: np.ndarray  # [nnz] int64, the column (node index along the axis) of each entry
    coef: np.ndarray  # [nnz] its coefficient (1/h included)
    X0n: np.ndarray  # [n, d, r] rest strain at each node, or [1, d, r] the medium's
    x0step: int  # 1 when X0n varies over the nodes, else 0
    params: np.ndarray  # medium kernel parameters
    w: np.ndarray  # [n] the nodes' reference volumes w·J (mass, loads; w on the chart's own measure)
    wc: np.ndarray  # [n] quadrature weights w of the energy (SBP norm on open axes)
    inv_volume: np.ndarray  # [n] 1/J on a general chart (the internal force per reference volume), else [1]
    charted: bool  # a general chart: J ≠ 1 somewhere
    inv_metric: np.ndarray  # [r, r] M⁺ on the live block, 0 on gauge ones
    live: np.ndarray  # [r] bool
    clamped: np.ndarray  # [n] bool
    any_clamped: bool
    held: np.ndarray  # [n, r] bool, the held components (Held ends, Symmetry faces; all r at clamped nodes)
    any_held: bool  # a node holds some of its components and not all (else ``clamped`` says everything)
    metric: np.ndarray  # [r, r] the kinetic metric M (the kinetic energy ½N·MN of partly held nodes)
    damp: np.ndarray  # [r] damping coefficients Γ
    ubody: np.ndarray  # [r] body-frame uniform force density
    field: np.ndarray  # [k] ρf of the constant fields (gravity), k the space dimension (0: none)
    has_field: bool
    end_idx: np.ndarray  # [e] int64, node of each free-end (face) entry
    end_axis: np.ndarray  # [e] int64, its axis α
    end_sign: np.ndarray  # [e] outward normal n_α (±1)
    end_H: np.ndarray  # [e] the SBP end weight H_end of the axis
    end_load: np.ndarray  # [e, r] the applied load P (zero when unloaded)
    end_loaded: np.ndarray  # [e] bool (False: an unloaded free end, a held end, a symmetry face)
    end_follow: np.ndarray  # [e] bool, follower (else dead)
    end_face: np.ndarray  # [e] w/H_end: the face area share (powers)
    has_power: bool
    diagonal: bool  # the kinetic metric is diagonal (M⁺ = diag)
    # Node forces (``NodeForce``, :func:`_node_forces`)
    nf_idx: np.ndarray = None  # [q] int64 the node of each node force
    nf_load: np.ndarray = None  # [q, r] its force P
    nf_follow: np.ndarray = None  # [q] bool body frame (else spatial: a dead load)
    nf_w: np.ndarray = None  # [q] the weight w (w·J) it divides P by (``NodeForce.weight``)
    # Driven ends (:func:`_driven_data`; the driven nodes are also ``clamped``)
    any_driven: bool = False
    dnodes: np.ndarray = None  # [nd] int64 the driven nodes
    dslot: np.ndarray = None  # [n] int64 a node's row in ``dnodes`` (−1: not driven)
    xi_d: np.ndarray = None  # [n, r] the driven velocity ξ, zero elsewhere ([0, r] without driven ends)
    S_d: np.ndarray = None  # [n, r] the driven momentum ∂K/∂N(ξ), zero on the gauge components and elsewhere
    pnodes: np.ndarray = None  # [p] int64 the nodes whose stress the driven nodes' force reads (stencils)
    dend_ptr: np.ndarray = None  # [nd + 1] int64 CSR: driven node s's end entries ``dend_item[dend_ptr[s]:…]``
    dend_item: np.ndarray = None  # [·] int64 rows of ``end_idx`` (free faces through a driven node)
    dtr_ptr: np.ndarray = None  # [nd + 1] int64 CSR: driven node s's clamped or driven ends ``dtr_*``
    dtr_axis: np.ndarray = None  # [·] int64 the end's axis α
    dtr_sign: np.ndarray = None  # [·] its outward normal n_α (±1)
    dtr_H: np.ndarray = None  # [·] its SBP end weight H_end
    # Per-node accumulators (``_lattice_ops.accumulate_fragment``; ``[0, n]`` without them)
    acc: np.ndarray = None  # [a, n] the accumulators, loaded by ``pack`` and written back by ``unpack``
    acc_rate: np.ndarray = None  # [a, n] their rates at the last state the loop accumulated at


# ---------------------------------------------------------------------------- operators
# Plain Python: compiled in each generated module, where g_* are the group's point kernels,
# m_energy/m_stress the medium's and D_, R_, M_ the sizes.

def op_work(D):
    n = D.w.shape[0]
    return (np.empty((n, D_, R_)), np.empty((n, R_)))  # noqa: F821 - stress, log of a move


def _c_diff(D, a, i, F, out):
    """``out = (∂_αF)_i`` for a nodal field F ``[n, r]``: row j (i's index along axis α) of
    the axis' difference matrix."""
    s = D.stride[a]
    j = (i // s) % D.naxis[a]
    base = i - j * s
    for k in range(R_):  # noqa: F821
        out[k] = 0.0
    for e in range(D.indptr[a, j], D.indptr[a, j + 1]):
        c = D.coef[e]
        row = base + D.col[e] * s
        for k in range(R_):  # noqa: F821
            out[k] += c * F[row, k]


def _c_move_node(D, C, i, E, F, tau, xi, dn, U, V, tmp, wk):
    """Node i moved by ``E = exp(τF_i)`` (paper §V): ``X_iα ← Ad_{E⁻¹} X_iα + 𝓔(τ, −F_i)(∂_αF)_i``
    and ``Φ_i ← Φ_i E`` (the root frame only when the frames are not stepped); ``dn``, ``U``,
    ``V`` ``(d, r)`` scratch, ``tmp`` ``(m, m)``, ``wk`` the group's ``g_work()``."""
    X, Phi = C
    for k in range(R_):  # noqa: F821
        xi[k] = -F[i, k]
    for a in range(D_):  # noqa: F821
        _c_diff(D, a, i, F, dn[a])
    g_Ad_inv_apply(E, X[i], U, wk)  # noqa: F821
    g_E_apply(tau, xi, dn, V, wk)  # noqa: F821
    for a in range(D_):  # noqa: F821
        for k in range(R_):  # noqa: F821
            X[i, a, k] = U[a, k] + V[a, k]
    if D.track or i == 0:
        g_compose(Phi[i], E, tmp)  # noqa: F821
        for p in range(M_):  # noqa: F821
            for q in range(M_):  # noqa: F821
                Phi[i, p, q] = tmp[p, q]


def _c_move_work():
    """Scratch of :func:`_c_move_node`: ``(xi, dn, U, V, tmp, wk)``."""
    return (np.empty(R_), np.empty((D_, R_)), np.empty((D_, R_)), np.empty((D_, R_)),  # noqa: F821
            np.empty((M_, M_)), g_work())  # noqa: F821


def op_force(D, C, t, N, W, K):
    X = C[0]
    Q = K[0]
    for i in range(W.shape[0]):
        m_stress(X[i], D.X0n[i * D.x0step], D.params, Q[i])  # noqa: F821
    _c_force_of_stress(D, C, t, N, W, K)


def _c_force_of_stress(D, C, t, N, W, K):
    """:func:`op_force` from the nodal stress ``K[0]`` ``[n, d, r]``."""
    X, Phi = C
    Q = K[0]
    n = W.shape[0]
    A = np.empty((R_, R_))  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    for i in range(n):
        for k in range(R_):  # noqa: F821
            W[i, k] = 0.0
    for a in range(D_):  # noqa: F821
        Qa = Q[:, a, :]
        for i in range(n):
            _c_diff(D, a, i, Qa, vec)
            g_ad(X[i, a], A)  # noqa: F821
            for k in range(R_):  # noqa: F821
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += A[j, k] * Q[i, a, j]
                W[i, k] = (W[i, k] + vec[k]) - s
    for p in range(D.end_idx.shape[0]):
        i, a = D.end_idx[p], D.end_axis[p]
        _c_end_load(D, Phi, i, p, vec)
        for k in range(R_):  # noqa: F821
            W[i, k] += (vec[k] - D.end_sign[p] * Q[i, a, k]) / D.end_H[p]
    nf = D.field.shape[0]
    for i in range(n):
        zero = D.any_clamped and D.clamped[i]
        if D.charted:  # per unit reference volume on a general chart
            for k in range(R_):  # noqa: F821
                W[i, k] *= D.inv_volume[i]
        for k in range(R_):  # noqa: F821
            W[i, k] += -N[i, k] * D.damp[k] + D.ubody[k]
        if D.has_field:
            for k in range(nf):
                s = 0.0
                for b in range(nf):
                    s += Phi[i, b + 1, k + 1] * D.field[b]
                W[i, k] += s
        for k in range(R_):  # noqa: F821
            if zero or not D.live[k] or (D.any_held and D.held[i, k]):
                W[i, k] = 0.0
    for q in range(D.nf_idx.shape[0]):
        i = D.nf_idx[q]
        _c_node_force(D, Phi, q, vec)
        zero = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            if not (zero or not D.live[k] or (D.any_held and D.held[i, k])):
                W[i, k] += vec[k] / D.nf_w[q]


def _c_end_load(D, Phi, i, p, out):
    """``out`` ``(r,)``: the load P of end entry ``p`` at node ``i`` in body components (zero when
    unloaded, as given for a follower load, a dead load rotated by Φᵢ)."""
    if not D.end_loaded[p]:
        for k in range(R_):  # noqa: F821
            out[k] = 0.0
    elif D.end_follow[p]:
        for k in range(R_):  # noqa: F821
            out[k] = D.end_load[p, k]
    else:
        _dead_to_body(D, Phi[i], D.end_load[p], out)


def _c_node_force(D, Phi, q, out):
    """``out`` ← the body components of node force q's P (a dead load rotated by Φ at its node)."""
    if D.nf_follow[q]:
        for k in range(R_):  # noqa: F821
            out[k] = D.nf_load[q, k]
    else:
        _dead_to_body(D, Phi[D.nf_idx[q]], D.nf_load[q], out)


def op_powers_nodal(D, C, N, t, K):
    """:func:`~cartan.schemes._lattice_ops.op_powers` plus the node forces' power
    ``Σ_q w_i (P_q/w_q)·N_i`` (``Scheme.powers``: the load's density times the node weight)."""
    diss, ext = op_powers_loads(D, C, N, t, K)  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    for q in range(D.nf_idx.shape[0]):
        i = D.nf_idx[q]
        _c_node_force(D, C[1], q, vec)
        for k in range(R_):  # noqa: F821
            ext += D.w[i] * (vec[k] / D.nf_w[q]) * N[i, k]
    return diss, ext


def op_drift(D, C, tau, N, K):
    xi, dn, U, V, tmp, wk = _c_move_work()
    row = np.empty(R_)  # noqa: F821
    E = np.empty((M_, M_))  # noqa: F821
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            row[k] = tau * N[i, k]
        g_exp(row, E)  # noqa: F821
        _c_move_node(D, C, i, E, N, tau, xi, dn, U, V, tmp, wk)


def op_move(D, C, Dn, K):
    """Move every node i by ``Dn[i]`` (see the module docstring)."""
    sig = K[1]
    xi, dn, U, V, tmp, wk = _c_move_work()
    for i in range(Dn.shape[0]):
        g_log(Dn[i], xi)  # noqa: F821
        for k in range(R_):  # noqa: F821
            sig[i, k] = xi[k]
    for i in range(Dn.shape[0]):
        _c_move_node(D, C, i, Dn[i], sig, 1.0, xi, dn, U, V, tmp, wk)


def op_free_flow(D, C, S, pieces, fracs, dt, Dn, K):
    """The free flow of ``lie-verlet`` as the reference takes it, piece by piece: for each
    piece p (``pieces`` ``[P, r, r]``, τ = ``fracs[p]``·Δt), ``N_p = P_p S`` (zero at clamped
    nodes and on held components), ``S_i ← Ad*_{exp(τN_p,i)} S_i`` and the drift by N_p over
    τ, node by node with one exponential (the drift reads N_p, never S); ``Dn`` is unused (the
    signature of a loop that composes node motions).  Returns whether anything moved."""
    Np = K[1]
    xi, dn, U, V, tmp, wk = _c_move_work()
    row = np.empty(R_)  # noqa: F821
    E = np.empty((M_, M_))  # noqa: F821
    moved = False
    for p in range(pieces.shape[0]):
        tau = fracs[p] * dt
        if not _c_piece_velocity(D, S, pieces, p, Np):
            continue
        moved = True
        for i in range(S.shape[0]):
            for k in range(R_):  # noqa: F821
                row[k] = tau * Np[i, k]
            g_coad_exp(row, S[i], E, wk)  # noqa: F821
            _c_move_node(D, C, i, E, Np, tau, xi, dn, U, V, tmp, wk)
    return moved


def _c_piece_velocity(D, S, pieces, p, Np):
    """``Np = P_p S`` of :func:`op_free_flow`'s piece p, zero at clamped nodes and on held
    components; returns whether it is nonzero anywhere (rebound by :func:`driven_fragment`)."""
    moving = False
    for i in range(S.shape[0]):
        clamped = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            v = 0.0
            if not (clamped or (D.any_held and D.held[i, k])):
                for j in range(R_):  # noqa: F821
                    v += pieces[p, k, j] * S[i, j]
            Np[i, k] = v
            moving = moving or v != 0.0
    return moving


def op_drift_naive(D, C, tau, N, K):
    X, Phi = C
    A = np.empty((R_, R_))  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    dn = np.empty(R_)  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    Nh = np.empty((M_, M_))  # noqa: F821
    tmp = np.empty((M_, M_))  # noqa: F821
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            xi[k] = N[i, k]
        g_ad(xi, A)  # noqa: F821
        for a in range(D_):  # noqa: F821
            _c_diff(D, a, i, N, dn)
            for k in range(R_):  # noqa: F821
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += A[k, j] * X[i, a, j]
                vec[k] = X[i, a, k] + tau * (dn[k] - s)
            for k in range(R_):  # noqa: F821
                X[i, a, k] = vec[k]
        if D.track or i == 0:
            for k in range(R_):  # noqa: F821
                xi[k] = tau * N[i, k]
            g_hat(xi, Nh)  # noqa: F821
            for p in range(M_):  # noqa: F821
                for q in range(M_):  # noqa: F821
                    s = Phi[i, p, q]
                    for c in range(M_):  # noqa: F821
                        s += Phi[i, p, c] * Nh[c, q]
                    tmp[p, q] = s
            for p in range(M_):  # noqa: F821
                for q in range(M_):  # noqa: F821
                    Phi[i, p, q] = tmp[p, q]


def op_potential(D, C, K):
    X, Phi = C
    V = 0.0
    for i in range(X.shape[0]):
        V += D.wc[i] * m_energy(X[i], D.X0n[i * D.x0step], D.params)  # noqa: F821
    if D.has_field:
        for i in range(X.shape[0]):
            s = 0.0
            for b in range(D.field.shape[0]):
                s += D.field[b] * Phi[i, b + 1, 0]
            V -= D.w[i] * s
    return V


def op_nodal_strains(D, C, X):
    X[...] = C[0]


_OPERATORS = (op_work, op_velocity, op_constrain, _dead_to_body, _c_end_load, _c_diff, _c_move_node, _c_move_work,
              op_force, _c_force_of_stress, _c_node_force, op_drift, op_move, op_free_flow, _c_piece_velocity,
              op_drift_naive, op_powers, op_kinetic, op_potential, op_nodal_strains, op_finite_config, op_copy_config,
              op_new_config)


# ---------------------------------------------------------------------------- driven ends
# ``Driven`` ends (module docstring, "Driven ends"): compiled after the loops in a set with driven
# nodes (``OperatorSet.late``), as the lattice's (:func:`cartan.schemes._lattice_ops.driven_fragment`,
# whose velocity, constraint and kinetic energy wrappers are shared); a set without driven nodes
# compiles none of this.

def _c_piece_velocity_driven(D, S, pieces, p, Np):
    """:func:`_c_piece_velocity` and, at the driven nodes, ξ on the piece's directions
    (``Scheme.velocity`` there, restricted to the piece as ``LieVerlet._free_flow`` does for a
    diagonal metric; a non-diagonal metric's pieces hold them, and that integrator refuses them)."""
    moving = _c_piece_velocity_plain(D, S, pieces, p, Np)  # noqa: F821
    if D.diagonal:
        for s in range(D.dnodes.shape[0]):
            i = D.dnodes[s]
            for k in range(R_):  # noqa: F821
                v = D.xi_d[i, k] if pieces[p, k, k] != 0.0 else 0.0
                Np[i, k] = v
                moving = moving or v != 0.0
    return moving


def op_powers_driven(D, C, N, t, K):
    diss, ext = op_powers_plain(D, C, N, t, K)  # noqa: F821
    return diss, ext + _c_driven_power(D, C, N, K)


def _c_driven_power(D, C, N, K):
    """``Σ_driven −w W·ξ`` over the live components: W the raw force density at the driven nodes
    (``Collocation.force(raw=True)``: :func:`op_force`'s terms before the node is zeroed, plus the
    weak-form term ``−n_α Q^α/H_end`` of each clamped or driven end through it,
    ``Collocation._clamped_traction``), the stress computed at the nodes of their stencils only
    (``pnodes``, into ``K[0]``) and the damping at the velocity N (ξ there)."""
    X, Phi = C
    Q = K[0]
    for s in range(D.pnodes.shape[0]):
        i = D.pnodes[s]
        m_stress(X[i], D.X0n[i * D.x0step], D.params, Q[i])  # noqa: F821
    A = np.empty((R_, R_))  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    Wv = np.empty(R_)  # noqa: F821
    nf = D.field.shape[0]
    power = 0.0
    for sl in range(D.dnodes.shape[0]):
        i = D.dnodes[sl]
        for k in range(R_):  # noqa: F821
            Wv[k] = 0.0
        for a in range(D_):  # noqa: F821
            _c_diff(D, a, i, Q[:, a, :], vec)
            g_ad(X[i, a], A)  # noqa: F821
            for k in range(R_):  # noqa: F821
                s = 0.0
                for j in range(R_):  # noqa: F821
                    s += A[j, k] * Q[i, a, j]
                Wv[k] = (Wv[k] + vec[k]) - s
        for it in range(D.dend_ptr[sl], D.dend_ptr[sl + 1]):
            p = D.dend_item[it]
            a = D.end_axis[p]
            _c_end_load(D, Phi, i, p, vec)
            for k in range(R_):  # noqa: F821
                Wv[k] += (vec[k] - D.end_sign[p] * Q[i, a, k]) / D.end_H[p]
        for it in range(D.dtr_ptr[sl], D.dtr_ptr[sl + 1]):
            a = D.dtr_axis[it]
            for k in range(R_):  # noqa: F821
                Wv[k] -= D.dtr_sign[it] * Q[i, a, k] / D.dtr_H[it]
        if D.charted:
            for k in range(R_):  # noqa: F821
                Wv[k] *= D.inv_volume[i]
        for k in range(R_):  # noqa: F821
            Wv[k] += -N[i, k] * D.damp[k] + D.ubody[k]
        if D.has_field:
            for k in range(nf):
                v = 0.0
                for b in range(nf):
                    v += Phi[i, b + 1, k + 1] * D.field[b]
                Wv[k] += v
        for q in range(D.nf_idx.shape[0]):
            if D.nf_idx[q] == i:
                _c_node_force(D, Phi, q, vec)
                for k in range(R_):  # noqa: F821
                    Wv[k] += vec[k] / D.nf_w[q]
        for k in range(R_):  # noqa: F821
            if D.live[k]:
                power -= D.w[i] * Wv[k] * D.xi_d[i, k]
    return power


#: the operators a set with driven nodes replaces (``op_x = op_x_driven``, the shared one kept as
#: ``op_x_plain``; ``op_drive``'s default, in the loops, does nothing)
_DRIVEN_REPLACED = ("op_velocity", "op_constrain", "op_kinetic", "op_powers", "_c_piece_velocity")


def driven_fragment() -> Fragment:
    """The driven ends' operators and the rebinding of the operators' names, to follow the loops
    in a generated module (``OperatorSet.late``)."""
    keep = "\n".join(f"{name}_plain = {name}" for name in _DRIVEN_REPLACED)
    rebind = "\n".join(f"{name} = {name}_driven" for name in (*_DRIVEN_REPLACED, "op_drive"))
    source = njit_source(op_drive_driven, op_velocity_driven, op_constrain_driven, op_kinetic_driven,
                         _c_piece_velocity_driven, op_powers_driven, _c_driven_power)
    return Fragment(source=keep + "\n\n\n" + source + "\n\n\n" + rebind + "\n")


#: the loops that move driven ends on the collocation (their Python steps move a driven node by
#: exp(Δtξ), ``Integrator.driven_reason``; rattle's nodal rows run the Python step), and the
#: compiled diagnostics (the CFL probe and the guard's energies, ``cartan.compiled.diagnostics.SERVED``)
DRIVEN_LOOPS = ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop", DIAGNOSTICS_SERVED)
#: why a set with driven nodes serves those loops only
DRIVEN_REASON = ("a Driven end runs compiled in the loops of lie-verlet, lie-euler, rkmk4, overdamped and "
                 "implicit-midpoint and in the compiled diagnostics only (rattle's nodal rows: the numpy path)")


def _driven_data(scheme, data: CollocationData, rows: list) -> dict:
    """The ``CollocationData`` fields of the driven ends (``Scheme._driven``): the nodes, their ξ
    and ∂K/∂N(ξ), the nodes whose stress their force reads (``rows``: each axis' difference rows,
    :func:`_axis_matrix`), the free-face entries through them and the clamped or driven ends
    through them (the weak-form term of ``Collocation._clamped_traction``)."""
    n, r, d = data.w.shape[0], data.r, data.d
    none = np.zeros(0, dtype=np.int64)
    fields = dict(any_driven=False, dnodes=none, dslot=np.full(n, -1, dtype=np.int64), xi_d=np.zeros((0, r)),
                  S_d=np.zeros((0, r)), pnodes=none, dend_ptr=np.zeros(1, dtype=np.int64), dend_item=none,
                  dtr_ptr=np.zeros(1, dtype=np.int64), dtr_axis=none, dtr_sign=np.zeros(0), dtr_H=np.zeros(0))
    if scheme._driven is None:
        return fields
    mask, Nd, Sd = scheme._driven
    dnodes = np.flatnonzero(np.asarray(mask, dtype=bool).reshape(n)).astype(np.int64)
    fields["dslot"][dnodes] = np.arange(dnodes.size)
    # the stencils: node i reads the stress at base + col·stride along each axis, and its own
    pnodes = set()
    for i in dnodes.tolist():
        pnodes.add(i)
        for a in range(d):
            s = int(data.stride[a])
            j = (i // s) % int(data.naxis[a])
            pnodes.update(i - j * s + c * s for c, _ in rows[a][j])
    # the clamped and driven ends through each driven node (Collocation._clamped_traction)
    node = np.arange(n).reshape(data.shape)
    tr: list[list[tuple[int, float, float]]] = [[] for _ in range(dnodes.size)]
    slot = fields["dslot"]
    for a, D in enumerate(scheme.D):
        if scheme.grid.periodic[a]:
            continue
        for side, idx, sign in (("start", 0, -1.0), ("end", -1, 1.0)):
            if isinstance(scheme.problem.boundary(a, side), Clamped | Driven):
                sl = [slice(None)] * d
                sl[a] = idx
                for i in np.ravel(node[tuple(sl)]):
                    if slot[i] >= 0:
                        tr[slot[i]].append((a, sign, float(D.norm()[idx])))
    ends: list[list[int]] = [[] for _ in range(dnodes.size)]
    for p, i in enumerate(data.end_idx.tolist()):
        if slot[i] >= 0:
            ends[slot[i]].append(p)
    fields.update(any_driven=True, dnodes=dnodes, xi_d=np.ascontiguousarray(Nd, dtype=float).reshape(n, r),
                  S_d=np.ascontiguousarray(Sd, dtype=float).reshape(n, r),
                  pnodes=np.array(sorted(pnodes), dtype=np.int64),
                  dend_ptr=np.cumsum([0] + [len(e) for e in ends]).astype(np.int64),
                  dend_item=np.array([p for e in ends for p in e], dtype=np.int64),
                  dtr_ptr=np.cumsum([0] + [len(e) for e in tr]).astype(np.int64),
                  dtr_axis=np.array([a for e in tr for a, _, _ in e], dtype=np.int64),
                  dtr_sign=np.array([sg for e in tr for _, sg, _ in e], dtype=float),
                  dtr_H=np.array([H for e in tr for _, _, H in e], dtype=float))
    return fields


# ---------------------------------------------------------------------------- coupled Lagrangians
# A medium whose Lagrangian couples N and X (``Medium.coupled_lagrangian``, d = 1): the pointwise
# discretisation of :mod:`cartan.schemes._collocation_coupled` with the medium's coupled point
# kernels (``m_coupled_velocity``, ``m_coupled_stress``).  The loops of ``lie-euler``,
# ``forward-euler`` and ``rkmk4`` reach the state through ``op_state_velocity`` and
# ``op_state_force`` (:mod:`cartan.integrators.loops`), which :func:`coupled_fragment` rebinds
# after the loops (``OperatorSet.late``); every other operator is the uncoupled set's.

def _c_coupled_velocity(D, S, X, i, out):
    """``out`` ← N(S_i, X_i) = ∂H/∂S by the medium's ``m_coupled_velocity``.

    Raises
    ------
    ValueError
        When the medium finds no velocity (the momentum is outside the range of its Legendre
        map), as the reference path's ``Medium.velocity_at`` raises."""
    if not m_coupled_velocity(S[i], X[i], D.params, out):  # noqa: F821
        raise ValueError("the Legendre map N(S, X) of the medium has no inverse at a node's momentum and strain "
                         "(its coupled_velocity kernel found no velocity: the momentum is outside the range of the "
                         "Legendre map); reduce the time step")


def op_state_velocity_coupled(D, C, S, N, K):
    """``N_i = ∂H/∂S(S_i, X_i)`` (``_collocation_coupled.coupled_velocity``), zero at clamped nodes
    (``Scheme.velocity``)."""
    X = C[0]
    for i in range(S.shape[0]):
        _c_coupled_velocity(D, S, X, i, N[i])
        if D.any_clamped and D.clamped[i]:
            for k in range(R_):  # noqa: F821
                N[i, k] = 0.0


def op_state_force_coupled(D, C, S, t, N, W, K):
    """:func:`op_force` with the Hamiltonian stress ``Q_i = ∂H/∂X(S_i, X_i)``
    (``_collocation_coupled.coupled_stress``: the medium's ``m_coupled_stress`` at the velocity
    N(S_i, X_i) of its ``m_coupled_velocity``, at every node: a clamped node's stress enters its
    neighbours' differences)."""
    X = C[0]
    Q = K[0]
    NH = np.empty(R_)  # noqa: F821
    for i in range(S.shape[0]):
        _c_coupled_velocity(D, S, X, i, NH)
        m_coupled_stress(S[i], X[i], NH, D.params, Q[i])  # noqa: F821
    _c_force_of_stress(D, C, t, N, W, K)


def op_coupled_logs(D, C, K):
    """Nothing: the strains are the state's (``C[0]``); the lattice's computes its edge logarithms
    here (``implicit-midpoint``'s stage momenta, :func:`cartan.integrators.newton.im_coupled_momentum`)."""
    return


def op_coupled_velocities(D, C, S, N, K):
    """``N_i = N(S_i, X_i)`` ``[n, r]`` at every node (no clamping); False where the medium's
    ``m_coupled_velocity`` finds no velocity (instead of raising)."""
    X = C[0]
    for i in range(S.shape[0]):
        if not m_coupled_velocity(S[i], X[i], D.params, N[i]):  # noqa: F821
            return False
    return True


def op_coupled_keep(D, C, S, K):
    """Nothing: the force solves each node's Legendre map itself."""
    return


def op_coupled_jacobian_kernel(D, C, S, idx, J, K):
    """``J[i, a, b] = ∂N_i[idx[a]]/∂S_i[idx[b]]`` by the medium's ``m_coupled_jacobian`` at
    (S_i, X_i) and the velocity N(S_i, X_i) (solved again: the set keeps none); False where the
    kernels have none (the caller takes forward differences)."""
    X = C[0]
    nl = idx.shape[0]
    N = np.empty(R_)  # noqa: F821
    Jp = np.empty((R_, R_))  # noqa: F821
    for i in range(S.shape[0]):
        if not (m_coupled_velocity(S[i], X[i], D.params, N)  # noqa: F821
                and m_coupled_jacobian(S[i], X[i], N, D.params, Jp)):  # noqa: F821
            return False
        for a in range(nl):
            for b in range(nl):
                J[i, a, b] = Jp[idx[a], idx[b]]
    return True


def coupled_fragment(jacobian: bool = False) -> Fragment:
    """The coupled operators (see above) and the rebinding of ``op_state_velocity``,
    ``op_state_force`` and ``implicit-midpoint``'s stage operators to them, to follow the loops in a
    generated module (``OperatorSet.late``); with ``jacobian`` (``MediumKernels.coupled_jacobian``)
    also :func:`op_coupled_jacobian_kernel`."""
    rebind = "\n".join(f"{name} = {name}_coupled" for name in ("op_state_velocity", "op_state_force"))
    source = njit_source(_c_coupled_velocity, op_state_velocity_coupled, op_state_force_coupled, op_coupled_logs,
                         op_coupled_velocities, op_coupled_keep, *((op_coupled_jacobian_kernel,) if jacobian else ()))
    return Fragment(source=source + "\n\n\n" + rebind + "\n" + COUPLED_STAGE + (COUPLED_JACOBIAN if jacobian else ""))


# ---------------------------------------------------------------------------- building the set
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
    for name in ("force", "internal_force", "drift", "frames", "_boundary_power", "_end_load", "initial_state",
                 "potential_energy", "nodal_strains"):
        if getattr(type(scheme), name) is not getattr(reference, name):
            return f"the scheme overrides {name}"
    for name in ("velocity", "constrain", "powers", "has_external_power", "drag", "kinetic_energy"):
        if getattr(type(scheme), name) is not getattr(Scheme, name):
            return f"the scheme overrides {name}"
    for name in ("velocity", "body_force", "kinetic"):
        if getattr(type(medium), name) is not getattr(Medium, name):
            return f"the medium overrides {name}"
    if getattr(medium, "velocity_dependent_forces", False):
        return "the medium has velocity-dependent forces"
    loads = _supported_loads(_without_node_forces(scheme), held=True)
    if loads is None:
        return ("a load or boundary is not one of Damping, body-frame UniformForce, ConstantFieldPotential "
                "(of the library's force), NodeForce, Free, Clamped, Held, Symmetry, Driven")
    if scheme.problem.needs_structure_field and not scheme.track:
        return "a load needs the frames, which are not stepped (track_frames=False)"
    for a, op in enumerate(scheme.D):
        if op.kind == "fourier" and op.n > FOURIER_MAX_NODES:
            return (f"the Fourier derivative along axis {a} has {op.n} nodes: applied as its dense circulant "
                    f"(numba has no FFT) it costs O(n²), slower than the reference's FFT beyond "
                    f"{FOURIER_MAX_NODES} nodes")
    return None


def _without_node_forces(scheme):
    """A view of ``scheme`` for :func:`~cartan.schemes._lattice_ops._supported_loads` (its group,
    and its problem's boundaries and loads but the ``NodeForce`` ones, which the collocation's
    operators take themselves: ``nf_*``)."""
    from types import SimpleNamespace

    problem = scheme.problem
    loads = [ld for ld in problem.loads if type(ld) is not NodeForce]
    return SimpleNamespace(group=scheme.group, problem=SimpleNamespace(loads=loads, boundaries=problem.boundaries))


#: the largest axis on which the ``fourier`` derivative runs compiled, as the dense circulant
#: (O(n²) per derivative, against the reference path's O(n log n) FFT)
FOURIER_MAX_NODES = 512


def _axis_matrix(op) -> list[list[tuple[int, float]]]:
    """The rows of a :class:`~cartan.schemes.collocation.DerivativeOperator` as
    ``[(column, coefficient), …]`` per node of its axis, in the reference's order of terms."""
    n = op.n
    if op.kind == "fourier":
        M = op.matrix()
        return [[(k, float(M[j, k])) for k in range(n)] for j in range(n)]
    (off, c), boundary = op.rows()
    rows = [[((j + o) % n, float(ck)) for o, ck in zip(off, c, strict=True)] for j in range(n)]
    for i, o_row, c_row in boundary:
        rows[i] = [(i + o, float(ck)) for o, ck in zip(o_row, c_row, strict=True)]
    return rows


def _rest_disagrees(medium, kernels, X0n: np.ndarray) -> bool:
    """Whether the kernel's stress at a node's rest strain differs from ``medium.stress_at``."""
    params = np.ascontiguousarray(kernels.params, dtype=float).ravel()
    for i in (0, X0n.shape[0] // 2, X0n.shape[0] - 1):
        X0 = np.ascontiguousarray(X0n[i])
        X = X0 + 0.05 * np.random.default_rng(i).standard_normal(X0.shape)
        Q = np.empty_like(X0)
        kernels.stress(X, X0, params, Q)
        ref = np.asarray(medium.stress_at(X[None], X0[None]), dtype=float)[0]
        if np.max(np.abs(Q - ref)) > 1e-9 * max(float(np.max(np.abs(ref))), 1e-300):
            return True
    return False


def collocation_operators(scheme, reference: type):
    """The compiled operator set of a collocation scheme, or a declined set that says why
    (``OperatorSet.reason``); ``reference`` is :class:`~cartan.schemes.collocation.Collocation`,
    whose methods the operators implement (a subclass that overrides one is declined).

    Raises
    ------
    ValueError
        When the medium's point kernels disagree with its stress
        (:func:`~cartan.schemes._lattice_ops.check_kernels`).
    """
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
    if scheme.rest is not None:
        X0n = np.ascontiguousarray(scheme.rest, dtype=float).reshape(n, d, r)
        if _rest_disagrees(medium, kernels, X0n):
            return OperatorSet.declined(f"the medium {medium.name!r}: point kernels disagree with stress_at at the "
                                        "reference's rest strains")
    else:
        X0n = np.ascontiguousarray(medium.rest_strain(), dtype=float).reshape(1, d, r)
    rows = [_axis_matrix(op) for op in scheme.D]
    indptr = np.zeros((d, max(shape) + 1), dtype=np.int64)
    entries = []
    for a, axis_rows in enumerate(rows):
        for j, row in enumerate(axis_rows):
            indptr[a, j] = len(entries)
            entries += row
            indptr[a, j + 1] = len(entries)
    damp, ubody, field = _supported_loads(_without_node_forces(scheme), held=True)
    nodal = [ld for ld in scheme.problem.loads if type(ld) is NodeForce]
    node = np.arange(n).reshape(shape)
    ends = [(int(i), axis, sign, H, b, float(f))
            for axis, sl, sign, H, b, face in scheme._free_ends
            for i, f in zip(np.ravel(node[sl]), np.broadcast_to(face, np.shape(node[sl])).ravel(), strict=True)]
    weights = np.ascontiguousarray(scheme.weights, dtype=float).reshape(n)
    # the clamp mask per component (Held ends, Symmetry faces), all r at clamped nodes
    held = np.asarray(scheme._clamped, dtype=np.bool_)
    held = np.ascontiguousarray(np.broadcast_to(held.reshape(*shape, -1), (*shape, r)).reshape(n, r))
    clamped = np.ascontiguousarray(held.all(axis=1))
    # the applied load P of each end entry: None at an unloaded free end, a held end, a symmetry face
    loads = [getattr(e[4], "load", None) for e in ends]  # (Held ends and Symmetry faces have none)
    data = CollocationData(
        d=d, r=r, m=m, affine=bool(getattr(group, "affine", False)), track=bool(scheme.track), shape=shape,
        coords=np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(d)], indexing="ij"), -1).reshape(n, d),
        stride=np.array([int(np.prod(shape[a + 1:])) for a in range(d)], dtype=np.int64),
        naxis=np.array(shape, dtype=np.int64), indptr=indptr,
        col=np.array([c for c, _ in entries], dtype=np.int64), coef=np.array([v for _, v in entries], dtype=float),
        X0n=X0n, x0step=int(X0n.shape[0] > 1), params=np.ascontiguousarray(kernels.params, dtype=float).ravel(),
        w=weights, wc=np.ascontiguousarray(scheme.chart_weights, dtype=float).reshape(n),
        inv_volume=(np.ones(1) if scheme._inv_volume is None
                    else np.ascontiguousarray(scheme._inv_volume, dtype=float).reshape(n)),
        charted=scheme._inv_volume is not None, inv_metric=np.ascontiguousarray(scheme.inverse_metric, dtype=float),
        live=np.ascontiguousarray(scheme.live, dtype=np.bool_), clamped=clamped, any_clamped=bool(clamped.any()),
        held=held, any_held=bool(np.any(held.any(axis=1) & ~clamped)),
        metric=np.ascontiguousarray(medium.kinetic_metric(), dtype=float).reshape(r, r),
        damp=damp, ubody=ubody, field=np.ascontiguousarray(field, dtype=float), has_field=bool(field.size),
        end_idx=np.array([e[0] for e in ends], dtype=np.int64), end_axis=np.array([e[1] for e in ends], dtype=np.int64),
        end_sign=np.array([e[2] for e in ends], dtype=float), end_H=np.array([e[3] for e in ends], dtype=float),
        end_load=np.array([np.zeros(r) if P is None else np.asarray(P, dtype=float) for P in loads],
                          dtype=float).reshape(-1, r),
        end_loaded=np.array([P is not None for P in loads], dtype=np.bool_),
        end_follow=np.array([P is not None and bool(e[4].follower) for P, e in zip(loads, ends, strict=True)],
                            dtype=np.bool_),
        end_face=np.array([e[5] for e in ends], dtype=float), has_power=bool(scheme.has_external_power()),
        diagonal=bool(scheme.diagonal_metric),
        nf_idx=np.array([int(np.ravel_multi_index(ld.node, shape)) for ld in nodal], dtype=np.int64),
        nf_load=np.array([ld.force_components for ld in nodal], dtype=float).reshape(-1, r),
        nf_follow=np.array([ld.frame == "body" for ld in nodal], dtype=np.bool_),
        nf_w=np.array([ld.weight for ld in nodal], dtype=float),
    )
    data = data._replace(**_driven_data(scheme, data, rows))
    frame_key = "Phi" if scheme.track else "Phi_root"
    # per-node accumulators, as the lattice's (``_lattice_ops.accumulate_fragment``): the loops'
    # ``op_accumulate`` gets the nodal velocity N (coupled: N(S_i, X_i) of ``op_state_velocity``);
    # not with driven ends, whose set serves the loops without the hook too
    acc_names = () if data.any_driven else _accumulated(medium, kernels)
    acc_keys = [f"accumulator_{name}" for name in acc_names]  # (cartan.accumulators.key)
    data = data._replace(acc=np.zeros((len(acc_names), n)), acc_rate=np.zeros((len(acc_names), n)))

    def pack(state):
        X = np.ascontiguousarray(state.arrays["X"], dtype=float).reshape(n, d, r).copy()
        Phi = np.ascontiguousarray(state.arrays[frame_key], dtype=float).reshape(-1, m, m).copy()
        for j, k in enumerate(acc_keys):
            data.acc[j] = np.asarray(state.arrays[k], dtype=float).reshape(n)
        return (X, Phi)

    def unpack(state, C):
        state.arrays["X"] = C[0].reshape(state.arrays["X"].shape).copy()
        state.arrays[frame_key] = C[1].reshape(state.arrays[frame_key].shape).copy()
        for j, k in enumerate(acc_keys):
            state.arrays[k] = data.acc[j].reshape(shape).copy()

    def accepts(state) -> bool:
        return set(state.arrays) == {"X", frame_key, *acc_keys}

    fragments = [group.point_kernels(), medium_fragment(kernels),
                 Fragment(imports={"CollocationData": (__name__, "CollocationData")},
                          constants={"D_": d, "R_": r, "M_": m},
                          source=njit_source(*_OPERATORS, *_HELD) + "\n\n\nop_powers_loads = op_powers\n\n\n"
                          + njit_source(op_powers_nodal) + "\n\n\nop_powers = op_powers_nodal\n")]
    label, key = f"collocation × {group!r} × {medium.name}", f"collocation-{group!r}-{kernel_stem(kernels)}"
    acc_late, acc_stem = ([accumulate_fragment()], "-acc") if acc_names else ([], "")
    if scheme.coupled_lagrangian:  # (d = 1, no reference, driven ends or held components: the scheme refuses them)
        check_coupled_kernels(medium, kernels, r)
        return OperatorSet(label=label + " (coupled Lagrangian)", key=key + "-coupled" + acc_stem,
                           fragments=fragments, data=data, pack=pack, unpack=unpack, accepts=accepts, nodes=n,
                           late=[coupled_fragment(getattr(kernels, "coupled_jacobian", None) is not None), *acc_late],
                           reason=COUPLED_REASON, loops=COUPLED_LOOPS,
                           accumulates=COUPLED_ACCUMULATE_LOOPS if acc_names else ())
    if data.any_driven:
        return OperatorSet(label=label + " (driven ends)", key=key + "-driven", fragments=fragments, data=data,
                           pack=pack, unpack=unpack, accepts=accepts, nodes=n, late=[driven_fragment()],
                           reason=DRIVEN_REASON, loops=DRIVEN_LOOPS)
    return OperatorSet(label=label, key=key + acc_stem, fragments=fragments, data=data, pack=pack, unpack=unpack,
                       accepts=accepts, nodes=n, late=acc_late, accumulates=ACCUMULATE_LOOPS if acc_names else ())
