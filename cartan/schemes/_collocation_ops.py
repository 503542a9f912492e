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
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..compiled.codegen import Fragment, njit_source
from ._lattice_ops import (
    _HELD,
    _dead_to_body,
    _supported_loads,
    check_kernels,
    op_constrain,
    op_copy_config,
    op_finite_config,
    op_kinetic,
    op_new_config,
    op_powers,
    op_velocity,
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
    X, Phi = C
    Q = K[0]
    n = W.shape[0]
    A = np.empty((R_, R_))  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    for i in range(n):
        m_stress(X[i], D.X0n[i * D.x0step], D.params, Q[i])  # noqa: F821
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
        if not D.end_loaded[p]:
            for k in range(R_):  # noqa: F821
                vec[k] = 0.0
        elif D.end_follow[p]:
            for k in range(R_):  # noqa: F821
                vec[k] = D.end_load[p, k]
        else:
            _dead_to_body(D, Phi[i], D.end_load[p], vec)
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
        if not moving:
            continue
        moved = True
        for i in range(S.shape[0]):
            for k in range(R_):  # noqa: F821
                row[k] = tau * Np[i, k]
            g_coad_exp(row, S[i], E, wk)  # noqa: F821
            _c_move_node(D, C, i, E, Np, tau, xi, dn, U, V, tmp, wk)
    return moved


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


_OPERATORS = (op_work, op_velocity, op_constrain, _dead_to_body, _c_diff, _c_move_node, _c_move_work, op_force,
              op_drift, op_move, op_free_flow, op_drift_naive, op_powers, op_kinetic, op_potential, op_nodal_strains,
              op_finite_config, op_copy_config, op_new_config)


# ---------------------------------------------------------------------------- building the set
def _why_not(scheme, reference: type) -> str | None:
    """Why the operator set does not cover this problem, or None when it does (``reference``:
    the scheme class whose methods the operators implement)."""
    from ..medium import Medium
    from .base import Scheme

    medium = scheme.medium
    if getattr(scheme, "_driven", None) is not None:
        return "a Driven end runs on the numpy path (the operators hold clamped nodes at rest)"
    if scheme.group.point_kernels() is None:
        return f"the group {scheme.group!r} has no numba point kernels"
    if medium.point_kernels() is None:
        return f"the medium {medium.name!r} declares no point kernels (Medium.point_kernels)"
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
    loads = _supported_loads(scheme, held=True)
    if loads is None:
        return ("a load or boundary is not one of Damping, body-frame UniformForce, ConstantFieldPotential "
                "(of the library's force), Free, Clamped, Held, Symmetry")
    if scheme.problem.needs_structure_field and not scheme.track:
        return "a load needs the frames, which are not stepped (track_frames=False)"
    for a, op in enumerate(scheme.D):
        if op.kind == "fourier" and op.n > FOURIER_MAX_NODES:
            return (f"the Fourier derivative along axis {a} has {op.n} nodes: applied as its dense circulant "
                    f"(numba has no FFT) it costs O(n²), slower than the reference's FFT beyond "
                    f"{FOURIER_MAX_NODES} nodes")
    return None


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
    damp, ubody, field = _supported_loads(scheme, held=True)
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
    )
    frame_key = "Phi" if scheme.track else "Phi_root"

    def pack(state):
        X = np.ascontiguousarray(state.arrays["X"], dtype=float).reshape(n, d, r).copy()
        Phi = np.ascontiguousarray(state.arrays[frame_key], dtype=float).reshape(-1, m, m).copy()
        return (X, Phi)

    def unpack(state, C):
        state.arrays["X"] = C[0].reshape(state.arrays["X"].shape).copy()
        state.arrays[frame_key] = C[1].reshape(state.arrays[frame_key].shape).copy()

    def accepts(state) -> bool:
        return set(state.arrays) == {"X", frame_key}

    fragments = [group.point_kernels(), medium_fragment(kernels),
                 Fragment(imports={"CollocationData": (__name__, "CollocationData")},
                          constants={"D_": d, "R_": r, "M_": m}, source=njit_source(*_OPERATORS, *_HELD))]
    return OperatorSet(label=f"collocation × {group!r} × {medium.name}",
                       key=f"collocation-{group!r}-{kernel_stem(kernels)}",
                       fragments=fragments, data=data, pack=pack, unpack=unpack, accepts=accepts, nodes=n)
