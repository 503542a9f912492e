"""Static equilibria: Newton's method on the group (``cartan.solve_static``).

An equilibrium solves ``D*Q + T = 0`` with the boundary conditions, i.e. the scheme's force
density ``W`` vanishes at ``N = 0``.  The unknowns are one Lie-algebra increment δ_i ∈ 𝔤 per
node (clamped nodes and gauge components excluded), applied on the group,

    Φ_i ← Φ_i exp(δ_i)        (the scheme's exact drift with τ = 1, N = δ),

so the iterates stay in G and the lattice edges stay exact (``G_e ← exp(−δ_i) G_e exp(δ_j)``).

Residual
    ``r(λ) = F_int + λ·F_ext`` on the unknowns: the generalised nodal forces ``w·W`` with the
    external loads scaled by the load factor λ.
Jacobian
    Analytic when the medium provides one (:meth:`cartan.medium.Medium.static_jacobian`,
    ``∂r/∂δ`` over all node components, restricted here to the unknowns); otherwise coloured
    central finite differences of r along drift directions: the lattice force at a node
    depends only on the node and its neighbours along each axis, so perturbing every third
    node (per axis) in one component at once gives 3^d·r force-difference pairs per
    Jacobian, assembled as a sparse banded matrix; the loads, which act at a node alone,
    are differenced apart with every node displaced at once (a block-diagonal part from
    2·r evaluations).  On a lattice whose potential couples the axes at the corners the
    internal force's Jacobian is assembled instead (:meth:`_Equilibrium._corner_tangent`: the
    point stress's derivative at every corner and the edge stresses' geometric stiffness).
    A load that reads its neighbours (``local`` False) is differenced on the same stencil; one
    that reads beyond it through a global quantity (a mean over every node) gives its force with
    that quantity held and the rank-k rest U Vᵀ (:meth:`cartan.problem.Load.jacobian_parts`),
    which the solve adds by the Sherman–Morrison–Woodbury identity (:func:`_low_rank_solve`).
    Either is factorised by sparse LU, for d ≥ 2 in a nested-dissection order of the nodes;
    with ``reuse`` the factorisation is kept while Newton contracts strongly (simplified
    Newton steps).
Mixed Newton iteration
    The edge strains ε_e are carried as independent unknowns beside the increments (the
    mixed-integration-point Newton method of Magisano, Leonetti & Garcea 2017): the Newton
    step solves ``J_ε δ = −r`` where ``J_ε`` is the Jacobian with the geometric stiffness of
    the stresses ``Q(ε)`` in place of ``Q(X)``, and the strains follow their linearisation,
    ``ε ← X + B δ`` (``B δ`` the strain rate of the drift).  For stiff axial and shear
    stiffnesses the displacement-only iteration builds huge spurious stresses from the
    chord error of a rotation step and its next Jacobian is useless; the mixed one is not
    affected.  At an equilibrium ε = X and ``J_ε = J``: the convergence is quadratic.
Constrained strains
    A medium may hold strain components at fixed values
    (:meth:`~cartan.medium.Medium.constrained_strains`; paper §III.E: the inextensible,
    unshearable filament has θ = (1, 0, 0)).  Each edge and constrained component adds a
    multiplier, the edge stress conjugate to that component (the fictitious stress of §IV.E),
    and a row ``X_e[k] − value_k = 0``; its reaction is the lattice's internal force of that
    edge stress, the constraint rows are the exact strain rate ``B_c`` of the drift, and the
    Newton matrix is the saddle-point matrix ``[[K, B_cᵀ], [B_c, 0]]`` (multipliers scaled by
    −cell).  The constraints are converged to 1e-3·tol, i.e. to round-off in practice.
    The rows and the reaction belong to the edge elements, not to the energy's assembly: on a
    lattice whose axes are coupled at the corners (d ≥ 2, e.g. a shell's membrane energy,
    paper §VII.B) the energy is summed over the corners while the constraints and their
    reaction ``B_cᵀν`` stay on the edges; the stress must then not depend on a constrained
    component at any corner (checked on the medium's point stress).
Globalisation
    Deuflhard's error-oriented damped Newton method (NLEQ-ERR): the step length α is
    predicted from the previous contraction, and a trial point is accepted when the
    simplified Newton correction (the old Jacobian applied to the trial residual of the
    mixed system) satisfies the restricted natural monotonicity test ``‖Δx̄‖ ≤ (1 − α/4)‖Δx‖``
    in a scaled norm of (δ, ε) — an affine-invariant test that accepts the full step when
    it is good, although ‖r‖ may rise by orders of magnitude through stiff terms.  Rejected
    trials are shortened with the test's own estimate of the Kantorovich quantity.
Load-step control
    The load is applied in increments of λ, the first ``1/load_steps``, each solved from the
    previous equilibrium; an increment is doubled after a load step that converges in at most
    four iterations (not right after a failure) and halved after a failed one, which is
    retried from the last equilibrium.
Failure
    :class:`ConvergenceError` (a ``RuntimeError``) names the iteration count and the residual
    when the load increment falls below ``min_load_step`` (iteration limit, no acceptable
    damped step, or steps below ``xtol`` or a stagnation with the residual far above its
    round-off floor, :func:`_residual_floor`) or the Jacobian is singular at a load step's
    start (a singular or ill-posed problem, e.g. a free body under an unbalanced load).
Free rigid motions
    Before the first step the rigid motions the supports leave free are found on the first
    Jacobian (:mod:`cartan.rigid_modes`): a ``ValueError`` when the external loads have power
    along one, otherwise an :class:`UnsupportedRigidMotion` warning naming them and (default
    ``rigid_gauge=True``) one bordered row per motion holding its mean at zero.

References: P. Deuflhard, *Newton Methods for Nonlinear Problems: Affine Invariance and
Adaptive Algorithms*, Springer 2011, §3.3 (NLEQ-ERR) and §5.1 (continuation step sizes);
D. Magisano, L. Leonetti, G. Garcea, *How to improve efficiency and robustness of the Newton
method in geometrically non-linear structural problem discretized via displacement-based
finite elements*, Comput. Methods Appl. Mech. Engrg. 313 (2017) 986–1005.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constraints import HeldFunctional, StrainConstraints
from .problem import InitialState, Problem, dead_to_body
from .rigid_modes import RigidMotions, UnsupportedRigidMotion, rigid_gauges, unsupported_rigid_motions
from .scatter import scatter_add

__all__ = ["ConvergenceError", "UnsupportedRigidMotion", "solve_static"]


class ConvergenceError(RuntimeError):
    """Newton's method did not reach an equilibrium.

    Attributes
    ----------
    iterations : int
        Newton iterations done (over all load steps).
    residual : float
        The last residual norm ‖r‖₂.
    history : list of float
        The residual norm at every iteration.
    """

    def __init__(self, message: str, iterations: int, residual: float, history: list[float]):
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual
        self.history = list(history)


class _Static:
    """Stands in for an integrator in :func:`cartan.io.frame_record` (N = 0, S = 0)."""

    uses_momentum = True
    name = "newton"


def _colouring(shape: tuple[int, ...], periodic: tuple[bool, ...]) -> np.ndarray:
    """Colour per node (flat) such that nodes of one colour have disjoint stencils
    (the node and its ±1 neighbours along every axis)."""
    per_axis = []
    for n, p in zip(shape, periodic, strict=True):
        c = np.arange(n) % 3
        if p and n % 3:
            # the last n mod 3 nodes would sit next to colour 0 across the seam: own colours
            c[n - n % 3:] = 3 + np.arange(n % 3)
        per_axis.append(c)
    ncol = [int(c.max()) + 1 for c in per_axis]
    grids = np.meshgrid(*per_axis, indexing="ij")
    colour = np.zeros(shape, dtype=np.int64)
    for c, m in zip(grids, ncol, strict=True):
        colour = colour * m + c
    return colour.ravel()


def _stencil_pairs(shape: tuple[int, ...], periodic: tuple[bool, ...],
                   box: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(source, target) flat node pairs: target in the stencil of source (self included).

    The stencil is the node and its ±1 neighbours along every axis, or with ``box`` every
    node within one step along each axis (the 3^d box: a lattice whose potential couples the
    axes at the corners, where a node's force depends on its diagonal neighbours).  The
    colouring of :func:`_colouring` separates both."""
    import itertools

    idx = np.arange(int(np.prod(shape))).reshape(shape)
    d = len(shape)
    if box:
        offsets = [o for o in itertools.product((-1, 0, 1), repeat=d)]
    else:
        offsets = [(0,) * d] + [tuple(step if k == axis else 0 for k in range(d))
                                for axis in range(d) for step in (-1, 1)]
    src, dst = [], []
    for off in offsets:
        nb = idx
        keep = np.ones(shape, dtype=bool)
        for axis, (n, p, step) in enumerate(zip(shape, periodic, off, strict=True)):
            if step == 0:
                continue
            nb = np.roll(nb, -step, axis=axis)
            if not p:
                pos = np.arange(n) + step
                ok = (pos >= 0) & (pos < n)
                keep &= ok.reshape([-1 if k == axis else 1 for k in range(d)])
        src.append(idx[keep])
        dst.append(nb[keep])
    pairs = np.unique(np.stack([np.concatenate(src), np.concatenate(dst)], axis=1), axis=0)
    return pairs[:, 0], pairs[:, 1]


def _lattice_stencil(sch: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(colour, source, target) of a lattice from its own edges and corners (any grid, glued axes
    included): target in the stencil of source when an edge joins them (a glued edge joins node
    ``(i, end)`` to ``(i + n_β/2, end)``, :meth:`Lattice.edge_nodes` maps its ghost to that node),
    or, on a lattice coupled at the corners, when both are ends of one corner's edges (a corner
    through a pole included), and with the lattice's ``pole = "cap"`` when both are ends of one
    pole cell's glued edges (the whole pole row; the chord-length strains add no other pair, each
    being a function of its own edge); every node is in its own stencil, and on an open or glued axis the
    first and last node also reach two nodes in (the one-sided second-order differences of a
    load that reads its neighbours, e.g. a surface pressure).  The colouring is an iterated greedy
    colouring of the stencils' conflict graph (:func:`_distance2_colouring`, kept per stencil):
    nodes of one colour have disjoint stencils (as :func:`_colouring` on a grid without glued
    axes, which keeps that structured colouring and :func:`_stencil_pairs`).

    Returns
    -------
    colour : int array ``(nnode,)``; src, dst : int arrays ``(npairs,)``
    """
    import scipy.sparse as sp

    grid = sch.grid
    shape = tuple(grid.shape)
    nnode = int(np.prod(shape))
    idx = np.arange(nnode).reshape(shape)
    tails, heads = sch.edge_nodes()
    groups = [np.stack([t, h], axis=1) for t, h in zip(tails, heads, strict=True)]
    if getattr(sch, "coupled", False):
        c = sch.corners()
        groups.append(np.stack([end[a][c["edge"][:, a]] for a in range(grid.d) for end in (tails, heads)], axis=1))
    if getattr(sch, "pole", "corners") == "cap":  # a pole cell couples the ends of all its glued edges
        from .schemes._pole_cell import cap

        caps = cap(sch)
        a = caps.axis
        for ring in caps.rings:
            groups.append(np.concatenate([tails[a][ring], heads[a][ring]])[None, :])
    for axis, n in enumerate(shape):
        if not grid.periodic[axis] and n >= 3:
            for ends in ((0, 1, 2), (n - 1, n - 2, n - 3)):
                groups.append(np.stack([np.take(idx, k, axis=axis).ravel() for k in ends], axis=1))
    src, dst = [np.arange(nnode)], [np.arange(nnode)]
    for grp in groups:
        k = grp.shape[1]
        for i in range(k):
            for j in range(k):
                src.append(grp[:, i])
                dst.append(grp[:, j])
    pairs = np.unique(np.stack([np.concatenate(src), np.concatenate(dst)], axis=1), axis=0)
    key = (nnode, pairs.tobytes())
    colour = _STENCIL_COLOURS.get(key)
    if colour is None:
        S = sp.csr_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(nnode, nnode))
        colour = _distance2_colouring((S @ S.T).tocsr())  # nodes whose stencils meet
        if len(_STENCIL_COLOURS) >= 16:
            _STENCIL_COLOURS.pop(next(iter(_STENCIL_COLOURS)))
        _STENCIL_COLOURS[key] = colour
    return colour.copy(), pairs[:, 0], pairs[:, 1]


#: :func:`_lattice_stencil`'s colourings by stencil (a few grids: each solve of a flow builds its own
#: :class:`_Equilibrium` on the same lattice)
_STENCIL_COLOURS: dict[tuple[int, bytes], np.ndarray] = {}


def _greedy_colouring(conflict: Any, order: np.ndarray) -> np.ndarray:
    """Colour the nodes in ``order``, each with the smallest colour none of its conflicting
    nodes (the row of ``conflict``, CSR ``(nnode, nnode)``) has yet: ``(nnode,)``."""
    nnode = conflict.shape[0]
    colour = -np.ones(nnode, dtype=np.int64)
    indptr, indices = conflict.indptr, conflict.indices
    for node in order:
        taken = colour[indices[indptr[node]:indptr[node + 1]]]
        used = np.zeros(taken.size + 2, dtype=bool)
        used[taken[(taken >= 0) & (taken < used.size)]] = True
        colour[node] = int(np.argmin(used))
    return colour


def _distance2_colouring(conflict: Any, passes: int = 8) -> np.ndarray:
    """A colouring of the conflict graph (``conflict`` CSR ``(nnode, nnode)``, nonzero where two
    nodes' stencils meet: the distance-2 graph of the stencil) with few colours: greedy in the
    node order, then Culberson's iterated greedy — each pass recolours the nodes class by class
    (the classes in reverse order, then largest first, alternately), which never adds a colour —
    for ``passes`` passes or until two passes in a row gain none.  Deterministic.

    On the sphere's chart (a lattice coupled at the corners, the glued edges across the poles and
    the ends' two nodes in, :func:`_lattice_stencil`) the node-order greedy colouring takes 17, 18,
    16 colours at 16 × 8, 32 × 16, 64 × 32 nodes, this one 16, 16, 15 (every central difference of
    the Jacobian is two force evaluations per colour and component).

    Returns
    -------
    int array ``(nnode,)``
    """
    nnode = conflict.shape[0]
    best = cur = _greedy_colouring(conflict, np.arange(nnode))
    idle = 0
    for k in range(passes):
        ncol = int(cur.max()) + 1
        classes = [np.flatnonzero(cur == c) for c in range(ncol)]
        if k % 2 == 0:
            rank = np.arange(ncol)[::-1]
        else:
            rank = np.argsort([-c.size for c in classes], kind="stable")
        cur = _greedy_colouring(conflict, np.concatenate([classes[c] for c in rank]))
        if cur.max() < best.max():
            best, idle = cur, 0
        else:
            idle += 1
            if idle >= 2:
                break
    return best


def _coloured_jacobian(displaced, colour: np.ndarray, src: np.ndarray, dst: np.ndarray, unknown: np.ndarray,
                       index: np.ndarray, shape: tuple[int, ...], step: float):
    """Sparse Jacobian of a nodal residual by coloured central finite differences.

    Parameters
    ----------
    displaced : callable ``(direction, eps) -> residual``
        The residual ``[*shape, r]`` at the point displaced by ``eps`` along ``direction``
        ``[*shape, r]`` (e.g. the scheme's drift by ``eps·direction``, or ``x + eps·direction``).
    colour : array ``(nnode,)``
        :func:`_colouring` (nodes of one colour have disjoint stencils).
    src, dst : arrays ``(npairs,)``
        :func:`_stencil_pairs`: node ``dst`` is in the stencil of node ``src``.
    unknown : bool array ``(nnode, r)``
        The unknowns (other residual entries and directions are left out).
    index : int array ``(nnode, r)``
        Position of each unknown in the unknown vector (−1 elsewhere).
    shape : tuple of int
        Node shape of the grid.
    step : float
        Finite-difference step ``eps``.

    Returns
    -------
    scipy.sparse.csc_matrix, shape ``(nunk, nunk)``
        ``J[i, j] = ∂r_i/∂x_j``: 2 residual evaluations per colour and component.
    """
    import scipy.sparse as sp

    nnode, r_dim = unknown.shape
    nunk = int(unknown.sum())
    rows, cols, vals = [], [], []
    for c in range(int(colour.max()) + 1):
        nodes = colour == c
        sel = nodes[src]
        s_c, d_c = src[sel], dst[sel]
        for a in range(r_dim):
            pert = np.zeros((nnode, r_dim))
            pert[nodes & unknown[:, a], a] = 1.0
            if not pert.any():
                continue
            pert = pert.reshape(*shape, r_dim)
            diff = ((displaced(pert, step) - displaced(pert, -step)) / (2 * step)).reshape(nnode, r_dim)
            col = index[s_c, a]
            ok = col >= 0
            rr = index[d_c[ok]]  # [pairs, r]
            vv = diff[d_c[ok]]
            cc = np.broadcast_to(col[ok, None], rr.shape)
            m = rr >= 0
            rows.append(rr[m])
            cols.append(cc[m])
            vals.append(vv[m])
    if not rows:
        return sp.csc_matrix((nunk, nunk))
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nunk, nunk))


def _rows_dependent(B: Any, rtol: float = 1e-9) -> bool:
    """Whether the rows of the sparse B ``(k, n)`` are linearly dependent: a pivot of the sparse LU
    of B Bᵀ (SPD when they are not) below ``rtol`` times its largest diagonal entry, or an exactly
    singular factorisation.  B Bᵀ has the rows' sparsity (each constraint couples the edges that
    share a node with it), so its LU costs about what the constraints' block of one Jacobian does."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    B = sp.csr_matrix(B)
    if B.shape[0] == 0:
        return False
    if B.shape[0] > B.shape[1]:
        return True
    G = (B @ B.T).tocsc()
    top = float(np.max(np.abs(G.diagonal()), initial=0.0))
    if not top > 0.0:
        return True
    try:
        with np.errstate(all="ignore"):
            lu = spla.splu(G, diag_pivot_thresh=0.0)
    except RuntimeError:
        return True
    return bool(np.min(np.abs(lu.U.diagonal())) < rtol * top)


def _saddle_order(unknowns: np.ndarray, B: Any, npin: int) -> np.ndarray:
    """The LU's elimination order of the saddle-point matrix ``[[K, Bᵀ], [B, 0]]`` of the strain
    constraints: every constraint multiplier right after the last of its edge's unknowns in the
    order ``unknowns`` (it then couples that edge's nodes only, as a node of the lattice does, and
    the nested dissection keeps its fill), the pins' multipliers last.

    Ordered after all the unknowns instead, the constraint block is eliminated last, against the
    Schur complement ``B K⁻¹ Bᵀ`` (dense): on the sphere's chart with 32 × 16 nodes and 1024
    constraints SuperLU took 0.63 s and 3.8e6 factor entries, interleaved 0.09 s and 1.7e6.

    Parameters
    ----------
    unknowns : int array ``(nunk,)``
        The unknowns (positions in the unknown vector) in their elimination order, e.g. the nested
        dissection of the nodes (:func:`_dissection`).
    B : scipy.sparse matrix, shape ``(ncon, nunk)``
        The constraint rows (only the sparsity is read).
    npin : int
        Number of pin multipliers, which follow the unknowns in the unknown vector (``nunk`` to
        ``nunk + npin``) and the constraint multipliers follow them.

    Returns
    -------
    int array ``(nunk + npin + ncon,)``
        A permutation of the rows of the whole matrix.
    """
    import scipy.sparse as sp

    nunk = unknowns.size
    B = sp.csr_matrix(B)
    ncon = B.shape[0]
    pos = np.empty(nunk, dtype=float)
    pos[unknowns] = np.arange(nunk)
    key = np.full(ncon, np.inf)  # a row without unknowns: last
    nonempty = np.diff(B.indptr) > 0
    if B.nnz:
        last = np.maximum.reduceat(pos[B.indices], B.indptr[:-1][nonempty])
        key[nonempty] = last + 0.5
    rows = np.concatenate([unknowns, nunk + npin + np.arange(ncon)])
    keys = np.concatenate([np.arange(nunk, dtype=float), key])
    order = rows[np.argsort(keys, kind="stable")]
    return np.concatenate([order, nunk + np.arange(npin)]).astype(np.int64)


_JACOBIANS = ("auto", "analytic", "fd")


def _analytic_jacobian(medium, scheme, state, lam: float, cols: np.ndarray, size: int):
    """The medium's :meth:`~cartan.medium.Medium.static_jacobian` restricted to the unknowns.

    Parameters
    ----------
    cols : int array ``(nunk,)``
        Flat positions ``node·r + k`` of the unknowns, in the order of the unknown vector.
    size : int
        ``nnode·r``, the side of the medium's matrix.

    Returns
    -------
    scipy.sparse.csc_matrix, shape ``(nunk, nunk)``, or None when the medium has none.
    """
    import scipy.sparse as sp

    J = medium.static_jacobian(scheme, state, float(lam))
    if J is None:
        return None
    J = sp.csr_matrix(J)
    if J.shape != (size, size):
        raise ValueError(f"jacobian: {type(medium).__name__}.static_jacobian must return a ({size}, {size}) matrix "
                         f"(nnode·r), got shape {J.shape}")
    return J[cols][:, cols].tocsc()


def _initial_phi(problem: Problem, initial: Any) -> InitialState:
    g = problem.medium.group
    if initial is None:
        return problem.initial
    if isinstance(initial, InitialState):
        return initial
    if hasattr(initial, "data_vars"):  # a Dataset from solve_static or simulate: its last frame
        if not getattr(g, "affine", False) or "position" not in initial or "frame" not in initial:
            raise ValueError("initial: a Dataset can seed only media on affine groups (position and frame)")
        pos = np.asarray(initial["position"].isel(time=-1))
        frame = np.asarray(initial["frame"].isel(time=-1))
        m = g.matrix_size
        Phi = np.zeros((*pos.shape[:-1], m, m))
        Phi[..., 0, 0] = 1.0
        Phi[..., 1:, 0] = pos
        Phi[..., 1:, 1:] = frame
        return InitialState(Phi=Phi)
    return InitialState(Phi=np.asarray(initial, dtype=float))


class _Singular(RuntimeError):
    """The Jacobian could not be factorised (or its solve is not finite)."""


PIN_PLACES = ("start", "middle", "end")


def pin_node(where: Any, shape: tuple[int, ...], axis_names: tuple[str, ...] | None = None) -> int:
    """The flat node index (C order over ``shape``) of a pinned node named by ``where``.

    Parameters
    ----------
    where : str, int or sequence
        ``"start"`` or ``"end"`` of a rod (d = 1); a flat node index
        ``−N ≤ i < N`` (N the number of nodes); or one entry per axis — a sequence, or a text
        ``"A,B"`` (``"A,B,C"`` for d = 3) — each ``"start"`` (node 0), ``"middle"`` (node n // 2),
        ``"end"`` (node n − 1) or an index ``−n ≤ i < n`` along that axis: ``("end", "middle")`` or
        ``"end,middle"`` is the midpoint of the u = end edge of a surface, ``"start,start"`` its
        corner at the origin, ``(3, 0)`` the node with grid index (3, 0).
    shape : tuple of int
        The grid's node shape ``(n_u, ...)``.
    axis_names : tuple of str, optional
        The axes' names, for the messages (default u, v, w).

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Naming ``pins``, the node and the allowed values.
    """
    d = len(shape)
    names = axis_names or ("u", "v", "w")[:d]
    nnode = int(np.prod(shape))
    ranges = ", ".join(f"{-n}..{n - 1} along {a}" for n, a in zip(shape, names, strict=False))
    flat = "" if isinstance(where, str) else f", or a flat node index {-nnode}..{nnode - 1}"
    allowed = (f"'start', 'end' or a node index {-nnode}..{nnode - 1}" if d == 1 else
               f"{d} entries (a sequence, or a text such as 'end,middle'), each 'start', 'middle', 'end' or an "
               f"index ({ranges}){flat}")
    if isinstance(where, str):
        parts: list[Any] = [p.strip() for p in where.split(",")]
        parts = [int(p) if p.lstrip("+-").isdigit() else p for p in parts]
        if len(parts) == 1 and isinstance(parts[0], int) and d > 1:
            parts = []  # a bare number of a d ≥ 2 grid in text is ambiguous: refused
    elif isinstance(where, int | np.integer) and not isinstance(where, bool):
        if not -nnode <= int(where) < nnode:
            raise ValueError(f"pins: node {where!r} out of range; allowed: {allowed}")
        return int(where) % nnode
    elif isinstance(where, list | tuple | np.ndarray):
        parts = list(where)
    else:
        parts = []
    if len(parts) != d:
        raise ValueError(f"pins: unknown node {where!r}; allowed: {allowed}")
    idx = []
    places = PIN_PLACES if d > 1 else ("start", "end")  # a rod is pinned at its ends (or by index)
    for p, n in zip(parts, shape, strict=True):
        if isinstance(p, str) and p in places:
            idx.append({"start": 0, "middle": n // 2, "end": n - 1}[p])
        elif isinstance(p, int | np.integer) and not isinstance(p, bool) and -n <= int(p) < n:
            idx.append(int(p) % n)
        else:
            raise ValueError(f"pins: unknown node {where!r}; allowed: {allowed}")
    return int(np.ravel_multi_index(tuple(idx), shape))


class _Equilibrium:
    """The static residual of a lattice problem on its unknowns, its Jacobian, and the edge
    strains and stresses of the mixed Newton iteration.

    Parameters
    ----------
    problem : Problem
        The problem; ``problem.initial`` is the starting configuration.
    jacobian : str
        ``"auto"``, ``"analytic"`` or ``"fd"`` (see :func:`solve_static`).
    fd_step : float
        Finite-difference step along the drift directions.
    t : float
        Time at which time-dependent loads are evaluated.
    pins : dict, optional
        ``{end: components}`` spatial position components held by Lagrange multipliers (see
        :func:`cartan.continuation.continuation`); their multipliers follow the unknowns.  A
        component ``k ≥ m − 1`` (m the matrix size: 3, 4, 5 on SE(3), 2 on SE(2)) holds the
        rotation of the node's frame about the spatial axis ``k − (m − 1)``: the axial component
        of the skew part of ``R R₀ᵀ`` stays 0, its multiplier a spatial reaction moment.
    probe_lam : float
        Load factor at which the medium's analytic Jacobian is probed (and first used).
    pole : str
        The lattice's ``pole`` (:class:`~cartan.schemes.lattice.Lattice`; :func:`solve_static`).
    holds : sequence of HeldFunctional
        Global functionals held by multipliers (:class:`cartan.constraints.HeldFunctional`).

    Attributes
    ----------
    nunk : int
        Number of unknown increments; ``m = nunk + nmult`` with the multipliers,
        ``nmult = npin + ncon + nhold``: the pins' first, then the strain constraints' (``ncon``,
        one per constrained edge and component, scaled by −cell: see :meth:`constraint_stress`),
        then the held functionals' (``nhold``, each μ_k·s_k, :meth:`_hold_terms`).
    kind : str
        ``"analytic"`` or ``"fd"``: the Jacobian used.
    """

    def __init__(self, problem: Problem, *, jacobian: str = "fd", fd_step: float = 1e-6, t: float = 0.0,
                 pins: dict | None = None, probe_lam: float = 1.0, pole: str = "corners",
                 holds: Sequence[HeldFunctional] = ()):
        from .schemes.lattice import Lattice

        if jacobian not in _JACOBIANS:
            raise ValueError(f"jacobian must be one of {', '.join(map(repr, _JACOBIANS))}, got {jacobian!r}")
        self.problem = problem
        self.sch = sch = Lattice(problem, track_frames=True, pole=pole)
        self.g = g = sch.group
        self.shape = shape = tuple(sch.grid.shape)
        self.r_dim = r_dim = g.dim
        self.nnode = nnode = int(np.prod(shape))
        self.fd_step = float(fd_step)
        unknown = np.broadcast_to(sch.live, (*shape, r_dim)).copy()
        unknown[sch._clamped] = False
        self.unknown = unknown
        self.unknown_flat = unknown.reshape(nnode, r_dim)
        self.nunk = int(unknown.sum())
        self.index = -np.ones((nnode, r_dim), dtype=np.int64)
        self.index[self.unknown_flat] = np.arange(self.nunk)
        self.cols = np.flatnonzero(self.unknown_flat.ravel())  # flat node·r + k of each unknown
        self.w = sch.weights[..., None]
        self.zero = np.zeros((*shape, r_dim))
        #: a glued axis (the sphere's chart): the stencil of the lattice's own edges and corners,
        #: the Jacobian by coloured differences of the whole force (the glued ends' Ad_{Γ⁻¹})
        self.glued = sch.grid.glued is not None
        if self.glued:
            self.colour, self.src, self.dst = _lattice_stencil(sch)
        else:
            self.colour = _colouring(shape, tuple(sch.grid.periodic))
            self.src, self.dst = _stencil_pairs(shape, tuple(sch.grid.periodic),
                                                box=bool(getattr(sch, "coupled", False)))
        self.length = max(1.0, float(np.max(sch.grid.length)))
        # scaled norms: translations in units of the rod length, rotations in radians; strains
        # (X = Φ⁻¹∂Φ) carry one more 1/length than the increments
        ref = float(np.max(sch.grid.length))
        comp = np.ones(r_dim)
        if getattr(g, "affine", False):
            comp[: g.matrix_size - 1] = 1.0 / ref
        self.delta_scale = np.broadcast_to(comp, (*shape, r_dim))[unknown]
        self.strain_scale = comp * ref
        self.quadratic = problem.medium.quadratic_energy() is not None
        # pins: (flat node, spatial component)
        self.pins: list[tuple[int, int]] = []
        pin_names: dict[int, Any] = {}
        for where, comps in (pins or {}).items():
            node = self._node(where)
            pin_names[node] = where
            if not self.unknown_flat[node].any():
                raise ValueError(f"pins: node {where!r} is held by a clamped boundary; pins hold free nodes")
            for k in np.atleast_1d(comps):
                if (node, int(k)) in self.pins:
                    raise ValueError(f"pins: component {int(k)} of node {where!r} is pinned twice")
                self.pins.append((node, int(k)))
        if self.pins and not getattr(g, "affine", False):
            raise ValueError("pins need a medium on an affine group (positions)")
        for _, k in self.pins:
            if not 0 <= k < r_dim:
                raise ValueError(f"pins: components must be in [0, {r_dim}) (positions, then rotations), got {k}")
        self.npin = len(self.pins)
        state = sch.initial_state()
        state.S[...] = 0.0
        state.t = float(t)
        self.state0 = state
        self._setup_constraints(problem.medium, state)
        self._setup_holds(problem, state, holds)
        self.nmult = self.npin + self.ncon + self.nhold
        self.m = self.nunk + self.nmult
        # the LU's elimination order on a lattice of d ≥ 2: nested dissection of the nodes, each
        # constraint multiplier after its edge's nodes, the pins' last (on a rod, d = 1, SuperLU's
        # default ordering is as good)
        self.lu_order: np.ndarray | None = None
        if len(shape) >= 2:
            unk = self.index[_dissection(shape)].ravel()
            self.lu_order = np.concatenate([
                _saddle_order(unk[unk >= 0], self._constraint_matrix(state), self.npin),
                self.nunk + self.npin + self.ncon + np.arange(self.nhold)])  # the held functionals' last
        if self.pins:
            msize = g.matrix_size
            self._R0 = self.sch.frames(state).reshape(self.nnode, msize, msize)[:, 1:, 1:].copy()
            for (node, k), basis in zip(self.pins, self._reaction_basis(state), strict=True):
                # a component a symmetry face holds already: the pin's reaction would have no
                # unknown to act on and its row of the Jacobian would vanish (singular)
                if not np.linalg.norm(basis[self.unknown_flat[node]]) > 1e-9 * np.linalg.norm(basis):
                    raise ValueError(f"pins: component {k} of node {pin_names[node]!r} is held by a symmetry "
                                     "face already; pins hold free components")
        self.x0 = np.array([self._pin_value(self.sch.frames(state).reshape(self.nnode, g.matrix_size,
                                                                         g.matrix_size)[n], n, k)
                            for n, k in self.pins])
        self.kind = "fd"
        self._probe: tuple[Any, float, Any] | None = None
        #: (state, λ, the loads' part of the stiffness block) of the last finite-difference Jacobian
        self.last_loads: tuple[Any, float, Any] | None = None
        supports = [type(load).__name__ for load in problem.loads if not load.scaled]
        if supports and jacobian == "analytic":
            raise ValueError(f"jacobian='analytic': the medium's analytic Jacobian scales every load by λ, but "
                             f"{', '.join(supports)} act at every λ (scaled = False); use jacobian='auto' or 'fd'")
        if jacobian != "fd" and not supports:
            K = _analytic_jacobian(problem.medium, sch, state, float(probe_lam), self.cols, nnode * r_dim)
            if K is None and jacobian == "analytic":
                raise ValueError(
                    f"jacobian='analytic': medium {problem.medium.name!r} provides no analytic Jacobian for this "
                    "problem (Medium.static_jacobian returned None); use jacobian='auto' or 'fd'"
                )
            if K is not None:
                self.kind = "analytic"
                self._probe = (state, float(probe_lam), K)

    # ------------------------------------------------------------------ constrained strains
    def _setup_constraints(self, medium: Any, state: Any) -> None:
        """The constrained strain components of the medium (:meth:`~cartan.medium.Medium.
        constrained_strains`): one multiplier per edge (with an unknown at either end) and
        component, after the pin multipliers (:class:`cartan.constraints.StrainConstraints`,
        which also checks that the medium's stress does not depend on them).  Any lattice: with
        axes coupled at the corners too, since the constraint rows and the reaction are per edge."""
        self.con = StrainConstraints(self.sch, self.unknown, state)
        self.ncon = self.con.ncon
        self._edge_shapes = [x.shape for x in self.strains(state)]
        #: the constraint rows are linearly dependent at the start (:meth:`_constraint_regularisation`)
        self.dependent_constraints = bool(self.ncon) and _rows_dependent(self._constraint_matrix(state))

    def constraints_met(self, r: np.ndarray, tol: float) -> bool:
        """Whether the strain-constraint rows of a residual ``r`` ``(m,)`` are within 1e-3·tol
        (dimensionless: one more quadratic step puts them at round-off) and the held functionals'
        rows within tol (relative to their scales s_k)."""
        o = self.nunk + self.npin
        return (float(np.max(np.abs(r[o: o + self.ncon]), initial=0.0)) <= 1e-3 * tol
                and float(np.max(np.abs(r[o + self.ncon: self.m]), initial=0.0)) <= tol)

    @property
    def _con(self) -> slice:
        """The strain constraints' multipliers within μ ``(nmult,)``."""
        return slice(self.npin, self.npin + self.ncon)

    @property
    def _held(self) -> slice:
        """The held functionals' multipliers within μ ``(nmult,)``."""
        return slice(self.npin + self.ncon, self.nmult)

    def constraint_stress(self, mu_c: np.ndarray) -> list[np.ndarray]:
        """Per axis, the edge stresses ``[*edge_shape, r]`` of the strain constraints' unknowns
        ``mu_c`` ``(ncon,)`` (:meth:`cartan.constraints.StrainConstraints.stress`).

        The unknowns are ``ν = −cell·μ``: the reaction ``−cell·B_cᵀ μ`` of the edge stresses μ
        is then ``B_cᵀ ν`` and the Jacobian ``[[K, B_cᵀ], [B_c, 0]]`` is symmetric.  The
        reaction is assembled edge by edge (:meth:`assemble`, the transpose of the exact strain
        rate), never through the medium's stress, so it is the same whether the energy is
        summed over the edges or over the corners of a coupled lattice."""
        return self.con.stress(mu_c, self._edge_shapes)

    def constraint_values(self, state: Any, active_only: bool = True) -> np.ndarray:
        """``X_e[k] − value_k`` on the constrained edges (flat, multiplier order), or with
        ``active_only=False`` on every edge ``[E, c]`` (all axes concatenated)."""
        return self.con.values(state, active_only)

    def edge_multipliers(self, mu_c: np.ndarray) -> np.ndarray:
        """The multipliers on every edge ``[E, c]`` (NaN on edges between fixed nodes)."""
        return self.con.edge_multipliers(mu_c, self._edge_shapes)

    # ------------------------------------------------------------------ held functionals
    def _setup_holds(self, problem: Problem, state: Any, holds: Sequence[HeldFunctional]) -> None:
        """Bind the held functionals to the problem and the lattice; their targets C₀ and row
        scales s (:meth:`cartan.constraints.HeldFunctional.start`)."""
        self.holds = tuple(holds)
        for k, h in enumerate(self.holds):
            if not isinstance(h, HeldFunctional):
                raise ValueError(f"holds[{k}] must be a cartan.constraints.HeldFunctional, got {type(h).__name__}")
        names = [h.name for h in self.holds]
        if len(set(names)) != len(names):
            raise ValueError(f"holds must have distinct names, got {names}")
        for h in self.holds:
            h.bind(problem, self.sch)
        starts = [h.start(self.sch, state) for h in self.holds]
        self.hold_target = np.array([c for c, _ in starts], dtype=float)
        self.hold_scale = np.array([s_ for _, s_ in starts], dtype=float)
        self.nhold = len(self.holds)

    def _hold_gradients(self, state: Any) -> np.ndarray:
        """g_k = ∂C_k/∂η / s_k on the unknowns, ``(nunk, nhold)``."""
        if not self.nhold:
            return np.zeros((self.nunk, 0))
        return np.stack([h.gradient(self.sch, state)[self.unknown] / s_
                         for h, s_ in zip(self.holds, self.hold_scale, strict=True)], axis=1)

    def hold_values(self, state: Any) -> np.ndarray:
        """C_k of ``state`` ``(nhold,)``."""
        return np.array([h.value(self.sch, state) for h in self.holds], dtype=float)

    def _hold_terms(self, state: Any, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reactions ``−Σ_k ν_k g_k`` on the unknowns, rows ``(C₀ − C)/s``) of the held
        functionals, ν_k = μ_k s_k their unknowns (:class:`cartan.constraints.HeldFunctional`)."""
        react = -(self._hold_gradients(state) @ nu)
        return react, (self.hold_target - self.hold_values(state)) / self.hold_scale

    def _hold_jacobian(self, state: Any, nu: np.ndarray):
        """The held functionals' part of the Jacobian: ``(J, low)``, J ``(m, m)`` the columns and
        rows ``−g_k`` and, for multipliers μ_k ≠ 0, ``−Σ μ_k ∂²C_k`` by coloured central
        differences of the gradients on the force stencil (of the frozen gradients of those with
        :meth:`~cartan.constraints.HeldFunctional.hessian_parts`, whose rank-k rests ``−μ_k U_k V_kᵀ``
        are ``low`` = (U, V) ``(m, k)`` each, None without any)."""
        import scipy.sparse as sp

        G = -self._hold_gradients(state)
        rows, cols = np.nonzero(G)
        o = self.nunk + self.npin + self.ncon
        J = sp.csc_matrix((np.concatenate([G[rows, cols], G[rows, cols]]),
                           (np.concatenate([rows, o + cols]), np.concatenate([o + cols, rows]))),
                          shape=(self.m, self.m))
        mu = nu / self.hold_scale
        low = None
        if np.any(mu):
            grads, Us, Vs = [], [], []
            for h, m_ in zip(self.holds, mu, strict=True):
                if not m_:
                    continue
                parts = h.hessian_parts(self.sch, state)
                if parts is None:
                    grads.append((lambda trial, h=h: h.gradient(self.sch, trial), m_))
                    continue
                frozen, U, V = parts
                k = np.shape(U)[-1]
                if np.shape(U) != (*self.shape, self.r_dim, k) or np.shape(V) != np.shape(U):
                    raise ValueError(f"{type(h).__name__}.hessian_parts must return U and V of one shape "
                                     f"{(*self.shape, self.r_dim, 'k')}, got {np.shape(U)} and {np.shape(V)}")
                grads.append((frozen, m_))
                U, V = (np.asarray(x, dtype=float).reshape(self.nnode, self.r_dim, k)[self.unknown_flat]
                        for x in (U, V))
                Us.append(_padded(-m_ * U, self.m))
                Vs.append(_padded(V, self.m))

            def reaction(trial: Any) -> np.ndarray:
                out = np.zeros((*self.shape, self.r_dim))
                for gradient, m_ in grads:
                    out -= m_ * gradient(trial)
                return out

            H = sp.csc_matrix(self._fd(state, reaction))
            J = J + sp.block_diag([H, sp.csc_matrix((self.nmult, self.nmult))], format="csc")
            if Us:
                low = (np.concatenate(Us, axis=1), np.concatenate(Vs, axis=1))
        return J, low

    def _constraint_matrix(self, state: Any):
        """``B_c = ∂(X_e[k])/∂δ`` ``(ncon, nunk)``: the constrained rows of the strain rate
        :meth:`strain_rate`, exact (the reaction of edge stresses μ is ``−cell·B_cᵀ μ``)."""
        return self.con.matrix(state)

    def _constraint_jacobian(self, state: Any):
        """The constraints' part of the Jacobian ``(m, m)``: the reaction columns ``B_cᵀ``
        (multipliers ν = −cell·μ, see :meth:`constraint_stress`) and the constraint rows
        ``B_c`` (the reaction's dependence on the configuration enters the stiffness block
        through the stress offset)."""
        import scipy.sparse as sp

        Bc = self._constraint_matrix(state).tocoo()
        o = self.nunk + self.npin
        return sp.csc_matrix((np.concatenate([Bc.data, Bc.data]),
                              (np.concatenate([Bc.row + o, Bc.col]), np.concatenate([Bc.col, Bc.row + o]))),
                             shape=(self.m, self.m))

    def _constraint_regularisation(self, state: Any, K: Any):
        """``REG_CONSTRAINTS·d_i`` on the strain constraints' diagonal block ``(m, m)`` when the rows
        are dependent (:attr:`dependent_constraints`, :func:`_rows_dependent`), with
        ``d_i = Σ_j B_ij² / max_j |K_jj|`` (at most the diagonal of the Schur complement
        ``−B_c K⁻¹ B_cᵀ``, whose sign it has).

        Dependent constraint rows leave the saddle-point matrix singular: θ_α,3 = 0 on a plate
        clamped on all four faces (the alternating sums of the rows along each line of u and of v
        between the clamps are the same combination of the edges), or a closed clamped boundary
        in general.  The LU then returns an arbitrary, often huge, multiple of the multipliers'
        null vector: it moves no node (B_cᵀv = 0) but its round-off pollutes the force rows and
        the residual floor.  With the regularisation that multiple stays bounded; the residual
        is evaluated exactly, so the regularisation changes the Newton iteration (by a relative
        REG_CONSTRAINTS on independent rows), not its solution."""
        import scipy.sparse as sp

        Bc = self._constraint_matrix(state)
        kd = np.abs(K.diagonal() if sp.issparse(K) else np.diagonal(K))
        top = float(np.max(kd, initial=0.0))
        if not top > 0.0:
            return sp.csc_matrix((self.m, self.m))
        d = np.asarray(sp.csr_matrix(Bc).multiply(Bc).sum(axis=1)).ravel() / top
        diag = np.zeros(self.m)
        o = self.nunk + self.npin
        diag[o: o + self.ncon] = REG_CONSTRAINTS * d
        return sp.diags(diag, format="csc")

    # ------------------------------------------------------------------ layout
    def _node(self, where: Any) -> int:
        return pin_node(where, self.shape, tuple(self.sch.grid.axis_names))

    def _pin_value(self, Phi: np.ndarray, n: int, k: int) -> np.ndarray:
        """The pinned quantity of node ``n``, component ``k``, at the frames ``Phi`` ``[..., m, m]``:
        the spatial position component ``k``, or (``k ≥ m − 1``) the axial component
        ``k − (m − 1)`` of the skew part of ``R R₀ᵀ`` (R the rotation block, R₀ the initial one)."""
        msize = self.g.matrix_size
        if k < msize - 1:
            return Phi[..., 1 + k, 0]
        A = np.einsum("...ij,kj->...ik", Phi[..., 1:, 1:], self._R0[n])
        i, j = (1, 0) if msize == 3 else ((2, 1), (0, 2), (1, 0))[k - (msize - 1)]
        return 0.5 * (A[..., i, j] - A[..., j, i])

    def positions(self, state: Any) -> np.ndarray:
        """Node positions ``[nnode, m − 1]`` (affine groups)."""
        m = self.g.matrix_size
        return self.sch.frames(state).reshape(self.nnode, m, m)[:, 1:, 0]

    def full(self, d: np.ndarray) -> np.ndarray:
        """The node-shaped increment ``[*shape, r]`` of the unknown vector ``d[:nunk]``."""
        out = np.zeros((*self.shape, self.r_dim))
        out[self.unknown] = d[: self.nunk]
        return out

    # ------------------------------------------------------------------ residual
    def _parts_full(self, state: Any) -> tuple[np.ndarray, np.ndarray]:
        """(internal, total) nodal forces ``[*shape, r]``, zero off the unknowns; the forces of
        supports (loads with ``scaled`` False, not multiplied by λ) count as internal."""
        total = self.sch.force(state, self.zero, state.t) * self.w
        internal = self.sch.internal_force(state)
        held = [load for load in self.problem.loads if not load.scaled]
        if held:
            Phi = self.sch.frames(state) if any(load.needs_structure_field for load in held) else None
            for load in held:
                internal = internal + load.force(Phi, self.zero, state.t) * self.w
        internal[~self.unknown] = 0.0
        total[~self.unknown] = 0.0
        return internal, total

    def parts(self, state: Any) -> tuple[np.ndarray, np.ndarray]:
        """(internal, external) nodal forces on the unknowns (flat)."""
        internal, total = self._parts_full(state)
        return internal[self.unknown], (total - internal)[self.unknown]

    def _nodal(self, state: Any, lam: float) -> np.ndarray:
        """``F_int + λ F_ext`` ``[*shape, r]``, zero off the unknowns (one force pass at λ = 1)."""
        if lam == 1.0:
            total = self.sch.force(state, self.zero, state.t) * self.w
            total[~self.unknown] = 0.0
            return total
        internal, total = self._parts_full(state)
        return internal + lam * (total - internal)

    def _reaction_basis(self, state: Any) -> list[np.ndarray]:
        """Body components (per pin) of a unit spatial force at the pinned node."""
        Phi = self.sch.frames(state).reshape(self.nnode, self.g.matrix_size, self.g.matrix_size)
        out = []
        for n, k in self.pins:
            P = np.zeros(self.r_dim)
            P[k] = 1.0
            out.append(dead_to_body(self.g, Phi[n], P))
        return out

    def _pin_terms(self, state: Any, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reactions on the unknowns, constraint values) of the pins."""
        full = np.zeros((self.nnode, self.r_dim))
        for (n, _), b, m_ in zip(self.pins, self._reaction_basis(state), mu, strict=True):
            full[n] += m_ * b
        msize = self.g.matrix_size
        Phi = self.sch.frames(state).reshape(self.nnode, msize, msize)
        c = np.array([self._pin_value(Phi[n], n, k) for n, k in self.pins]) - self.x0
        return full[self.unknown_flat], c

    def residual(self, state: Any, mu: np.ndarray, lam: float) -> np.ndarray:
        """``r = F_int + λ F_ext`` (+ pin and constraint reactions) on the unknowns, then the
        pin constraints, then the strain constraints ``X_e[k] − value_k``."""
        r = self._nodal(state, float(lam))[self.unknown]
        parts = [r]
        if self.npin:
            react, c = self._pin_terms(state, mu[: self.npin])
            parts[0] = r = r + react
            parts.append(c)
        if self.ncon:
            parts[0] = r + self.assemble(state, self.constraint_stress(mu[self._con]))
            parts.append(self.constraint_values(state))
        if self.nhold:
            react, c = self._hold_terms(state, mu[self._held])
            parts[0] = parts[0] + react
            parts.append(c)
        return np.concatenate(parts) if len(parts) > 1 else r

    def dlam(self, state: Any) -> np.ndarray:
        """``∂r/∂λ``: the external forces (zero on the pin and strain constraints)."""
        return np.concatenate([self.parts(state)[1], np.zeros(self.nmult)])

    # ------------------------------------------------------------------ strains and stresses
    def strains(self, state: Any) -> list[np.ndarray]:
        """Per axis, the edge strains ``X_e = log(G_e)/h``."""
        return self.sch.edge_strains(state)

    def stress(self, X: list[np.ndarray]) -> list[np.ndarray]:
        """Per axis, the edge stresses ``Q(X_e)``: on a lattice whose axes are separable, each
        axis with the others at the rest strain; on a lattice coupled at the corners, the
        corner stresses gathered back onto their edges, ``Q̄_e = Σ_{c ∋ e} w_c Q_c[a] / cell``
        (the edge stresses whose assembly is the corner force: with the other axes at rest
        the mixed Newton iteration of a coupled medium takes ≈ 8× the iterations)."""
        if self.sch.coupled:
            return self._corner_edge_stress(X)
        return [self.sch._axis_stress(x, axis)[0] for axis, x in enumerate(X)]

    def _corner_edge_stress(self, X: list[np.ndarray]) -> list[np.ndarray]:
        """:meth:`stress` on a lattice coupled at the corners (``Lattice.corners``)."""
        sch = self.sch
        c = sch.corners()
        flat = [x.reshape(-1, self.r_dim) for x in X]
        Xc = np.stack([flat[a][c["edge"][:, a]] for a in range(sch.grid.d)], axis=1)
        Q = sch.medium.stress_at(Xc, c["X0"]) if self.problem.reference is not None else sch.medium.stress(Xc)
        w = c["weight"] / float(np.prod(sch.h))
        out = []
        for a, x in enumerate(X):
            Qe = np.zeros_like(flat[a])
            scatter_add(Qe, c["edge"][:, a], w[:, None] * Q[:, a, :])
            out.append(Qe.reshape(x.shape))
        return out

    def stress_change(self, X: list[np.ndarray], v: list[np.ndarray]) -> list[np.ndarray]:
        """Per axis, ``(∂Q/∂X)(X_e)·v_e``: exact for quadratic media, central differences otherwise."""
        if self.sch.coupled:
            size = max(float(np.max(np.abs(dv), initial=0.0)) for dv in v)
            if size == 0.0:
                return [np.zeros_like(dv) for dv in v]
            s = 1e-6 * max(1.0, max(float(np.max(np.abs(x), initial=0.0)) for x in X)) / size
            plus = self._corner_edge_stress([x + s * dv for x, dv in zip(X, v, strict=True)])
            minus = self._corner_edge_stress([x - s * dv for x, dv in zip(X, v, strict=True)])
            return [(p_ - m_) / (2.0 * s) for p_, m_ in zip(plus, minus, strict=True)]
        out = []
        for axis, (x, dv) in enumerate(zip(X, v, strict=True)):
            if self.quadratic:
                out.append(self.sch._axis_stress(x + dv, axis)[0] - self.sch._axis_stress(x, axis)[0])
                continue
            size = float(np.max(np.abs(dv), initial=0.0))
            if size == 0.0:
                out.append(np.zeros_like(dv))
                continue
            s = 1e-6 * max(1.0, float(np.max(np.abs(x), initial=0.0))) / size
            plus = self.sch._axis_stress(x + s * dv, axis)[0]
            minus = self.sch._axis_stress(x - s * dv, axis)[0]
            out.append((plus - minus) / (2.0 * s))
        return out

    def _assemble_full(self, state: Any, stress: list[np.ndarray]) -> np.ndarray:
        """The lattice's nodal forces of the edge stresses ``stress`` at ``state`` (the
        assembly of :meth:`Lattice.internal_force` with given Q), ``[*shape, r]``, zero off
        the unknowns."""
        g, sch = self.g, self.sch
        F = np.zeros((*self.shape, self.r_dim))
        cell = float(np.prod(sch.h))
        for axis, Q in enumerate(stress):
            xi = g.log(state.arrays[sch._key(axis)])
            Q = Q * (cell / sch.h[axis])
            out = np.einsum("...ji,...j->...i", g.dexp_inv(xi), Q)
            inc = np.einsum("...ji,...j->...i", g.dexp_inv(-xi), Q)
            sch._scatter(F, out, -inc, axis)
        F[~self.unknown] = 0.0
        return F

    def assemble(self, state: Any, stress: list[np.ndarray]) -> np.ndarray:
        """:meth:`_assemble_full` on the unknowns (flat)."""
        return self._assemble_full(state, stress)[self.unknown]

    def strain_rate(self, state: Any, d: np.ndarray) -> list[np.ndarray]:
        """Per axis, the linearised strain change ``B δ`` of the drift ``Φ_i ← Φ_i exp(δ_i)``:
        ``[dexp⁻¹(−hX_e) δ_j − dexp⁻¹(hX_e) δ_i]/h`` on the edge ``e = (i, j)``."""
        g, sch = self.g, self.sch
        full = self.full(d)
        out = []
        for axis in range(sch.grid.d):
            xi = g.log(state.arrays[sch._key(axis)])
            tail, head = sch._ends(full, axis)
            if sch.grid.is_glued(axis):  # a ghost end moves by Ad_{Γ⁻¹} δ (Lattice, "Glued axes")
                A = g.Ad(g.inverse(sch._glue[axis]))
                sl = [slice(None)] * sch.grid.d
                sl[axis] = 0
                tail[tuple(sl)] = tail[tuple(sl)] @ A.T
                sl[axis] = -1
                head[tuple(sl)] = head[tuple(sl)] @ A.T
            out.append((np.einsum("...ij,...j->...i", g.dexp_inv(-xi), head)
                        - np.einsum("...ij,...j->...i", g.dexp_inv(xi), tail)) / sch.h[axis])
        return out

    # ------------------------------------------------------------------ Jacobian
    def _fd(self, state: Any, func: Callable[[Any], np.ndarray]):
        """Coloured central differences of the node-shaped ``func(state)`` along drifts."""

        def displaced(direction: np.ndarray, eps: float) -> np.ndarray:
            trial = state.copy()
            self.sch.drift(trial, eps, direction)
            out = func(trial)
            out[~self.unknown] = 0.0
            return out

        return _coloured_jacobian(displaced, self.colour, self.src, self.dst, self.unknown_flat, self.index,
                                  self.shape, self.fd_step)

    def _corner_maps(self) -> tuple[list[Any], list[tuple[Any, Any]]]:
        """Per axis of a lattice coupled at the corners, the sparse gather of the corner stresses
        onto the edges ``[E_α, C]`` (weights ``w_c/h_α``, ``Lattice.internal_force``) and the
        scatters of the edges onto their tail and head nodes ``[nnode, E_α]``, built once."""
        import scipy.sparse as sp

        if getattr(self, "_gathers", None) is None:
            sch = self.sch
            c = sch.corners()
            ncorner = c["node"].size
            gathers, scatters = [], []
            for a in range(sch.grid.d):
                ne = c["tail"][a].size
                gathers.append(sp.csr_matrix((c["weight"] / sch.h[a], (c["edge"][:, a], np.arange(ncorner))),
                                             shape=(ne, ncorner)))
                scatters.append((sp.csr_matrix((np.ones(ne), (c["tail"][a], np.arange(ne))), shape=(self.nnode, ne)),
                                 sp.csr_matrix((np.ones(ne), (c["head"][a], np.arange(ne))), shape=(self.nnode, ne))))
            self._gathers, self._scatters = gathers, scatters
        return self._gathers, self._scatters

    def _corner_pairs(self) -> tuple[np.ndarray, list[list[np.ndarray]], list[list[np.ndarray]], tuple]:
        """The node-pair block layout of the tangent of a lattice coupled at the corners, built once.

        Returns
        -------
        (keys, slots, edge_slots, entries)
            ``keys`` ``(P,)`` the sorted distinct node pairs ``i·nnode + j`` a corner couples;
            ``slots[s][s2]`` ``(C,)`` the position in ``keys`` of the pair of end slots ``(s, s2)``
            of every corner, a slot ``s = 2α + e`` being the tail (e = 0) or head (e = 1) of the
            corner's edge along axis α; ``edge_slots[α]`` the positions of the pairs (tail, tail),
            (tail, head), (head, tail), (head, head) of the edges along α ``(E_α,)``; ``entries``
            ``(mask (P·r²,), rows, cols)`` the blocks' entries on the unknowns and their places."""
        held = getattr(self, "_pairs", None)
        if held is not None:
            return held
        c = self.sch.corners()
        d = self.sch.grid.d
        nodes = np.stack([end[a][c["edge"][:, a]] for a in range(d) for end in (c["tail"], c["head"])])
        keys_all = [nodes[s] * self.nnode + nodes[s2] for s in range(2 * d) for s2 in range(2 * d)]
        keys = np.unique(np.concatenate(keys_all))
        slots = [[np.searchsorted(keys, keys_all[s * 2 * d + s2]) for s2 in range(2 * d)] for s in range(2 * d)]
        # the edges' node pairs (tail, tail), (tail, head), (head, tail), (head, head) per axis
        edge_slots = [[np.searchsorted(keys, a_ * self.nnode + b_) for a_, b_ in
                       ((t, t), (t, h), (h, t), (h, h))] for t, h in zip(c["tail"], c["head"], strict=True)]
        # the entries on the unknowns: (mask over the blocks' entries, row, column)
        rn, cn = np.divmod(keys, self.nnode)
        rows, cols = np.broadcast_arrays(self.index[rn][:, :, None], self.index[cn][:, None, :])
        keep = ((rows >= 0) & (cols >= 0)).reshape(-1)
        entries = (keep, rows.reshape(-1)[keep], cols.reshape(-1)[keep])
        self._pairs = (keys, slots, edge_slots, entries)
        return self._pairs

    def _corner_tangent(self, state: Any, offset: list[np.ndarray] | None):
        """The Jacobian of the internal force of a lattice coupled at the corners
        (``Lattice.internal_force``) plus the assembly of the edge stresses ``offset``, assembled.

        With the edge logarithms ξ_e (tail t, head h), ``D±_e = dexp⁻¹(±ξ_e)``, the corner strains
        ``X_c[α] = ξ_{e_α(c)}/h_α`` and the edge stresses ``Q̄_e = Σ_{c ∋ e} (w_c/h_α) Q(X_c)[α]``
        (+ the offset), the force is ``F_t += D+_eᵀ Q̄_e``, ``F_h −= D−_eᵀ Q̄_e`` and a drift
        ``Φ_i ← Φ_i exp(δ_i)`` changes ``ξ_e`` by ``D−_e δ_h − D+_e δ_t``.  Its derivative is

        * the material stiffness ``−Σ_c w_c Aᵀ_c C_c A_c``, ``C_c = ∂Q/∂X`` at ``X_c`` ``(d·r, d·r)``
          and ``A_c`` the map of the corner's end nodes to ``δX_c`` (rows α: ``−D+/h_α`` at the
          tail, ``D−/h_α`` at the head of ``e_α(c)``);
        * the geometric stiffness of ``Q̄``: ``∂(D±_eᵀ Q̄_e)/∂ξ_e`` times ``∂ξ_e/∂δ``.

        ``C_c`` and ``∂(D±ᵀQ̄)/∂ξ`` are central differences of the medium's point stress and of
        ``dexp⁻¹`` (2·d·r stress evaluations over all corners and 4r of ``dexp⁻¹`` over all edges,
        exact to the differences' truncation: a polynomial stress of degree 3 to O(s²)), the
        rest is exact: the same matrix as :meth:`_corner_fd`'s coloured differences of the whole
        force, to their truncation error (3e-10 relative on a shell), at about half the cost (a
        shell on 129 × 65 nodes: 1.1 s against 2.1 s of CPU).  :meth:`jacobian` uses it;
        :meth:`_corner_fd` stays as its check.

        Returns
        -------
        scipy.sparse.csc_matrix, shape ``(nunk, nunk)``
        """
        import scipy.sparse as sp

        g, sch, r = self.g, self.sch, self.r_dim
        c = sch.corners()
        d = sch.grid.d
        keys, slots, edge_slots, (keep, rows, cols) = self._corner_pairs()
        xis = [g.log(state.arrays[sch._key(a)]).reshape(-1, r) for a in range(d)]
        Dp = [g.dexp_inv(xi) for xi in xis]
        Dm = [g.dexp_inv(-xi) for xi in xis]
        ncorner = c["node"].size
        # material stiffness C_c = ∂Q/∂X (d·r, d·r) at the corner strains
        Xc = np.stack([xis[a][c["edge"][:, a]] / sch.h[a] for a in range(d)], axis=1)
        ref = self.problem.reference is not None

        def stress(X: np.ndarray) -> np.ndarray:
            return sch.medium.stress_at(X, c["X0"]) if ref else sch.medium.stress(X)

        Q0 = stress(Xc)
        s = 1e-6 * max(1.0, float(np.max(np.abs(Xc), initial=0.0)))
        C = np.empty((ncorner, d * r, d * r))
        for col in range(d * r):
            a, k = divmod(col, r)
            x0 = Xc[:, a, k].copy()
            Xc[:, a, k] = x0 + s
            plus = stress(Xc)
            Xc[:, a, k] = x0 - s
            C[:, :, col] = ((plus - stress(Xc)) / (2.0 * s)).reshape(ncorner, d * r)
            Xc[:, a, k] = x0
        # A_c per slot: the map of the slot's node increment to δX_c[α] (r, r)
        A = []
        for a in range(d):
            e = c["edge"][:, a]
            A.append(-Dp[a][e] / sch.h[a])
            A.append(Dm[a][e] / sch.h[a])
        w = -c["weight"][:, None, None]
        blocks = np.zeros(keys.size * r * r)
        cols_rr = np.arange(r * r)

        def add(pos: np.ndarray, blk: np.ndarray) -> None:  # sum the blocks per node pair
            nonlocal blocks
            blocks += np.bincount((pos[:, None] * (r * r) + cols_rr).ravel(), weights=blk.reshape(-1),
                                  minlength=blocks.size)
        for s1 in range(2 * d):
            a1 = s1 // 2
            AC = np.swapaxes(A[s1], 1, 2) @ (w * C[:, a1 * r:(a1 + 1) * r, :])  # (C, r, d·r)
            add(np.concatenate(slots[s1]), np.concatenate([AC[:, :, (s2 // 2) * r:(s2 // 2 + 1) * r] @ A[s2]
                                                           for s2 in range(2 * d)]))
        # geometric stiffness of the edge stresses Q̄ (+ offset)
        gathers, _ = self._corner_maps()
        cell = float(np.prod(sch.h))
        for a in range(d):
            Qe = gathers[a] @ Q0[:, a, :]
            if offset is not None:
                Qe = Qe + offset[a].reshape(-1, r) * (cell / sch.h[a])
            if not np.any(Qe):
                continue
            xi = xis[a]
            step = 1e-6 * max(1.0, float(np.max(np.abs(xi), initial=0.0)))
            Hp = np.empty((xi.shape[0], r, r))
            Hm = np.empty((xi.shape[0], r, r))
            for j in range(r):
                dx = np.zeros(r)
                dx[j] = step
                Hp[:, :, j] = np.einsum("eji,ej->ei", g.dexp_inv(xi + dx) - g.dexp_inv(xi - dx), Qe) / (2 * step)
                Hm[:, :, j] = np.einsum("eji,ej->ei", g.dexp_inv(-xi - dx) - g.dexp_inv(-xi + dx), Qe) / (2 * step)
            # F_t = D+ᵀQ̄: ∂/∂δ_t = −Hp D+, ∂/∂δ_h = Hp D−; F_h = −D−ᵀQ̄: ∂/∂δ_t = Hm D+, ∂/∂δ_h = −Hm D−
            add(np.concatenate(edge_slots[a]), np.concatenate([-Hp @ Dp[a], Hp @ Dm[a], Hm @ Dp[a], -Hm @ Dm[a]]))
        return sp.csc_matrix((blocks[keep], (rows, cols)), shape=(self.nunk, self.nunk))

    def _corner_fd(self, state: Any, offset: list[np.ndarray] | None):
        """:meth:`_fd` of the internal force of a lattice coupled at the corners
        (``Lattice.internal_force``) plus the assembly of the edge stresses ``offset``
        (:meth:`_assemble_full`): the same coloured central differences, the gathers and
        scatters as sparse products (:meth:`_corner_maps`), with
        the logarithms, corner stresses and ``dexp⁻¹`` recomputed only on the edges and corners
        a displaced colour moves (each is a function of its own edge or corner: the others keep
        the values at ``state``)."""
        g, sch, r_dim = self.g, self.sch, self.r_dim
        c = sch.corners()
        d = sch.grid.d
        gathers, scatters = self._corner_maps()
        tails, heads = c["tail"], c["head"]
        G = [state.arrays[sch._key(a)].reshape(tails[a].size, *state.arrays[sch._key(a)].shape[-2:])
             for a in range(d)]
        xis = [g.log(Ga) for Ga in G]
        Dp = [g.dexp_inv(xi) for xi in xis]
        Dm = [g.dexp_inv(-xi) for xi in xis]
        ref = self.problem.reference is not None

        def corner_stress(idx: np.ndarray, xs: list[np.ndarray]) -> np.ndarray:
            Xc = np.stack([xs[a][c["edge"][idx, a]] / sch.h[a] for a in range(d)], axis=1)
            return sch.medium.stress_at(Xc, c["X0"][idx]) if ref else sch.medium.stress(Xc)

        Q0 = corner_stress(np.arange(c["node"].size), xis)
        cell = float(np.prod(sch.h))
        extra = [None if offset is None else offset[a].reshape(-1, r_dim) * (cell / sch.h[a]) for a in range(d)]

        def displaced(direction: np.ndarray, eps: float) -> np.ndarray:
            N = direction.reshape(self.nnode, r_dim)
            moved = np.any(N != 0.0, axis=1)
            D = g.exp(eps * N[moved])
            Dinv = g.inverse(D)
            slot = np.cumsum(moved) - 1  # row of a moved node in D
            saved = []  # the values at state of what the displacement changes, restored below
            hit = np.zeros(Q0.shape[0], dtype=bool)
            for a in range(d):
                t, h = tails[a], heads[a]
                E = np.flatnonzero(moved[t] | moved[h])
                Dt = np.where(moved[t[E], None, None], Dinv[slot[t[E]]], np.eye(D.shape[-1]))
                Dh = np.where(moved[h[E], None, None], D[slot[h[E]]], np.eye(D.shape[-1]))
                xi_e = g.log(g.compose(g.compose(Dt, G[a][E]), Dh))  # the drift on the moved edges
                saved.append((E, xis[a][E], Dp[a][E], Dm[a][E]))
                xis[a][E] = xi_e
                Dp[a][E] = g.dexp_inv(xi_e)
                Dm[a][E] = g.dexp_inv(-xi_e)
                on = np.zeros(t.size, dtype=bool)
                on[E] = True
                hit |= on[c["edge"][:, a]]
            idx = np.flatnonzero(hit)
            Q_saved = Q0[idx]
            try:
                Q0[idx] = corner_stress(idx, xis)
                F = np.zeros((self.nnode, r_dim))
                for a in range(d):
                    Qe = gathers[a] @ Q0[:, a, :]
                    if extra[a] is not None:
                        Qe += extra[a]
                    tail, head = scatters[a]
                    F += tail @ np.einsum("...ji,...j->...i", Dp[a], Qe)
                    F -= head @ np.einsum("...ji,...j->...i", Dm[a], Qe)
            finally:
                Q0[idx] = Q_saved
                for a, (E, x, p_, m_) in enumerate(saved):
                    xis[a][E], Dp[a][E], Dm[a][E] = x, p_, m_
            F[~self.unknown_flat] = 0.0
            return F.reshape(*self.shape, r_dim)

        return _coloured_jacobian(displaced, self.colour, self.src, self.dst, self.unknown_flat, self.index,
                                  self.shape, self.fd_step)

    def _local(self, Phi: np.ndarray | None, lam: float, t: float) -> np.ndarray:
        """The nodal forces that act at a node alone, ``[*shape, r]`` (not zeroed off the
        unknowns): the local loads (λ times the scaled ones), the medium's body force and the end
        loads, times the node weights — :meth:`_nodal` minus the lattice's internal force and
        minus :meth:`_neighbour_loads`."""
        sch = self.sch
        W = np.zeros((*self.shape, self.r_dim))
        for load in self.problem.loads:
            if load.local:
                W += (lam if load.scaled else 1.0) * load.force(Phi, self.zero, t)
        T = self.problem.medium.body_force(Phi, self.zero, t)
        if T is not None:
            W += lam * T
        for k, (idx, b) in enumerate(sch._end_loads):
            P = b.load if b.follower else dead_to_body(self.g, Phi[idx], b.load)
            W[idx] += sch.end_load_density(k, lam * P)
        return W * self.w

    def _neighbour_loads(self, state: Any, lam: float) -> np.ndarray:
        """The nodal forces of the loads that read their neighbours (``local`` False), ``[*shape, r]``."""
        W = np.zeros((*self.shape, self.r_dim))
        Phi = self.sch.frames(state)
        for load in self.problem.loads:
            if not load.local:
                W += (lam if load.scaled else 1.0) * load.force(Phi, self.zero, state.t)
        return W * self.w

    def _neighbour_jacobian(self, state: Any, lam: float):
        """The Jacobian of :meth:`_neighbour_loads` along the drifts: ``(K, low)``, K
        ``(nunk, nunk)`` by coloured central differences on the lattice's stencil
        (:func:`_coloured_jacobian`), the frames displaced directly, ``Φ_i exp(±ε δ_i)`` (a load
        reads the frames, not the edges); a load with :meth:`~cartan.problem.Load.jacobian_parts`
        has its frozen force differenced there and its rank-k rest in ``low`` = (U, V)
        ``(nunk, k)`` each (None without), ``J = K + U Vᵀ``."""
        g, t = self.g, state.t
        Phi = self.sch.frames(state)
        loads, Us, Vs = [], [], []
        for load in self.problem.loads:
            if load.local:
                continue
            factor = lam if load.scaled else 1.0
            parts = load.jacobian_parts(Phi, t)
            if parts is None:
                loads.append((lambda moved, load=load: load.force(moved, self.zero, t), factor))
                continue
            frozen, U, V = parts
            loads.append((frozen, factor))
            k = np.shape(U)[-1]
            if np.shape(U) != (*self.shape, self.r_dim, k) or np.shape(V) != np.shape(U):
                raise ValueError(f"{type(load).__name__}.jacobian_parts must return U and V of one shape "
                                 f"{(*self.shape, self.r_dim, 'k')}, got {np.shape(U)} and {np.shape(V)}")
            U = (factor * np.asarray(U, dtype=float) * self.w[..., None]).reshape(self.nnode, self.r_dim, k)
            V = np.asarray(V, dtype=float).reshape(self.nnode, self.r_dim, k)
            Us.append(U[self.unknown_flat])
            Vs.append(V[self.unknown_flat])

        def displaced(direction: np.ndarray, eps: float) -> np.ndarray:
            moved = g.compose(Phi, g.exp(eps * direction))
            W = np.zeros((*self.shape, self.r_dim))
            for force, factor in loads:
                W += factor * force(moved)
            W *= self.w
            W[~self.unknown] = 0.0
            return W

        K = _coloured_jacobian(displaced, self.colour, self.src, self.dst, self.unknown_flat, self.index,
                               self.shape, self.fd_step)
        return K, ((np.concatenate(Us, axis=1), np.concatenate(Vs, axis=1)) if Us else None)

    def _local_jacobian(self, state: Any, lam: float):
        """The Jacobian of :meth:`_local` along the drifts, ``(nunk, nunk)``: block diagonal
        per node, since a load density at a point depends on the frame there only (paper
        §IV.B); by central differences with every node displaced at once (2 evaluations per
        component instead of 2 per colour and component)."""
        import scipy.sparse as sp

        g, r_dim, nnode, eps = self.g, self.r_dim, self.nnode, self.fd_step
        Phi = self.sch.frames(state)
        rows, cols, vals = [], [], []
        for a in range(r_dim):
            nodes = np.flatnonzero(self.unknown_flat[:, a])
            if nodes.size == 0:
                continue
            pert = np.zeros((nnode, r_dim))
            pert[nodes, a] = 1.0
            pert = pert.reshape(*self.shape, r_dim)
            plus = self._local(g.compose(Phi, g.exp(eps * pert)), lam, state.t)
            minus = self._local(g.compose(Phi, g.exp(-eps * pert)), lam, state.t)
            diff = ((plus - minus) / (2 * eps)).reshape(nnode, r_dim)
            rr = self.index[nodes]  # [nodes, r]
            cc = np.broadcast_to(self.index[nodes, a][:, None], rr.shape)
            m = rr >= 0
            rows.append(rr[m])
            cols.append(cc[m])
            vals.append(diff[nodes][m])
        if not rows:
            return sp.csc_matrix((self.nunk, self.nunk))
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.nunk, self.nunk))

    def _analytic(self, state: Any, lam: float):
        probe, self._probe = self._probe, None
        if probe is not None and probe[0] is state and probe[1] == lam:
            return probe[2]
        K = _analytic_jacobian(self.problem.medium, self.sch, state, lam, self.cols, self.nnode * self.r_dim)
        if K is None:
            raise ValueError(f"jacobian: medium {self.problem.medium.name!r} returned an analytic Jacobian at the "
                             "start but None later; Medium.static_jacobian must depend on the problem only")
        return K

    def jacobian(self, state: Any, mu: np.ndarray, lam: float, offset: list[np.ndarray] | None = None,
                 low_rank: bool = False):
        """The Jacobian of :meth:`residual` along the drift directions (and the multipliers).

        Parameters
        ----------
        offset : list of arrays, optional
            Per axis, edge stresses added to ``Q(X)`` and held fixed: the Jacobian then has
            the geometric stiffness of ``Q(X) + offset`` (the mixed iteration's ``Q(ε)``)
            with the material stiffness at X.
        low_rank : bool
            Also return the loads' rank-k part (:meth:`cartan.problem.Load.jacobian_parts`),
            which the sparse matrix leaves out.

        Returns
        -------
        scipy.sparse.csc_matrix, shape ``(m, m)``
            Without ``low_rank``; with it ``(J, low)``, ``low`` = (U, V) ``(m, k)`` each or
            None, the whole Jacobian ``J + U Vᵀ`` (:func:`_low_rank_solve`).
        """
        import scipy.sparse as sp

        if self.ncon:  # the multipliers' edge stresses: their geometric stiffness, like a stress offset
            q_c = self.constraint_stress(mu[self._con])
            offset = q_c if offset is None else [a + b for a, b in zip(offset, q_c, strict=True)]
        if offset is not None and not any(np.any(o) for o in offset):
            offset = None
        lam = float(lam)
        if self.kind == "analytic":
            K = self._analytic(state, lam)
            if offset is not None:
                K = K + self._fd(state, lambda trial: self._assemble_full(trial, offset))
        else:

            def nodal(trial: Any) -> np.ndarray:  # the lattice's forces: coupled between neighbours
                out = self.sch.internal_force(trial)
                if offset is not None:
                    out += self._assemble_full(trial, offset)
                return out

            K = (self._corner_tangent(state, offset) if self.sch.coupled and not self.glued
                 else self._fd(state, nodal))
            KL = self._local_jacobian(state, lam)
            K = K + KL
        low = None
        if any(not load.local for load in self.problem.loads):  # on the lattice's stencil, like the internal force
            Kn, low = self._neighbour_jacobian(state, lam)
            K = K + Kn
            if self.kind != "analytic":
                KL = KL + Kn
        if self.kind != "analytic":  # the loads' part, kept for the rigid-motion check at the start
            self.last_loads = (state, lam, KL)
            if low is not None:  # zero rows for the multipliers
                low = tuple(_padded(x, self.m) for x in low)
        if not self.nmult:
            J = sp.csc_matrix(K)
        else:
            J = sp.block_diag([K, sp.csc_matrix((self.nmult, self.nmult))], format="csc")
            if self.npin:
                J = J + self._pin_jacobian(state, mu[: self.npin])
            if self.ncon:
                J = J + self._constraint_jacobian(state)
                if self.dependent_constraints:
                    J = J + self._constraint_regularisation(state, K)
            if self.nhold:
                Jh, low_h = self._hold_jacobian(state, mu[self._held])
                J = J + Jh
                if low_h is not None:
                    low = low_h if low is None else tuple(
                        np.concatenate([_padded(a, self.m), b], axis=1) for a, b in zip(low, low_h, strict=True))
            J = J.tocsc()
        return (J, low) if low_rank else J

    def _pin_jacobian(self, state: Any, mu: np.ndarray):
        """The pins' part of the Jacobian, ``(m, m)``: reactions and constraints along the
        drifts ``Φ_n ← Φ_n exp(±h e_a)`` of the pinned nodes (central differences; each
        depends on its own node only) and the reaction columns."""
        import scipy.sparse as sp

        g, h, r_dim = self.g, self.fd_step, self.r_dim
        msize = g.matrix_size
        Phi = self.sch.frames(state).reshape(self.nnode, msize, msize)
        steps = g.exp(np.concatenate([h * np.eye(r_dim), -h * np.eye(r_dim)]))  # [2r, m, m]
        rows, cols, vals = [], [], []
        for j, (n, k) in enumerate(self.pins):
            moved = g.compose(np.broadcast_to(Phi[n], steps.shape), steps)  # Φ_n exp(±h e_a)
            P = np.zeros(r_dim)
            P[k] = 1.0
            b = dead_to_body(g, moved, P)  # [2r, r]
            db = (b[:r_dim] - b[r_dim:]) / (2 * h)  # [a, component]
            value = self._pin_value(moved, n, k)  # [2r]
            dc = (value[:r_dim] - value[r_dim:]) / (2 * h)  # [a]
            col = self.index[n]
            ok = col >= 0
            row = self.index[n]
            rr, cc = np.meshgrid(row[ok], col[ok], indexing="ij")
            rows.append(rr.ravel())
            cols.append(cc.ravel())
            vals.append((mu[j] * db[np.ix_(ok, ok)].T).ravel())
            rows.append(np.full(int(ok.sum()), self.nunk + j))
            cols.append(col[ok])
            vals.append(dc[ok])
        for j, b in enumerate(self._reaction_basis(state)):
            idx = self.index[self.pins[j][0]]
            ok = idx >= 0
            rows.append(idx[ok])
            cols.append(np.full(int(ok.sum()), self.nunk + j))
            vals.append(b[ok])
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.m, self.m))

    def update(self, state: Any, mu: np.ndarray, d: np.ndarray, alpha: float = 1.0) -> tuple[Any, np.ndarray]:
        """A new (state, μ) after the increment ``α·d`` (unknowns, then multipliers)."""
        new = state.copy()
        self.sch.drift(new, alpha, self.full(d))
        return new, mu + alpha * d[self.nunk: self.m]


@dataclass
class _Point:
    """An iterate: the configuration, pin multipliers, load factor and (continuation) the
    increments accumulated since the last path point."""

    state: Any
    mu: np.ndarray
    lam: float
    acc: np.ndarray | None = None


@dataclass
class _Outcome:
    """What one damped Newton solve did."""

    point: _Point
    converged: bool
    reason: str = ""
    #: how a converged iteration ended: "residual" (the residual test), "increment" (a full
    #: Newton step below xtol) or "stagnation" (no damped step passed the monotonicity test):
    #: the last two only with the residual at its round-off floor (within FLOOR_RATIO of
    #: :func:`_residual_floor` on every row)
    by: str = ""
    #: max_i |r_i|/floor_i where an increment or stagnation test was met (NaN: not evaluated)
    floor_ratio: float = math.nan
    singular_start: bool = False
    residuals: list[float] = field(default_factory=list)
    corrections: list[float] = field(default_factory=list)
    alphas: list[float] = field(default_factory=list)

    @property
    def iterations(self) -> int:
        return len(self.alphas)


#: the residual's round-off floor: ``FLOOR_FACTOR·ε_mach`` times each row's sum of the magnitudes
#: of the terms that make it (:func:`_residual_floor`)
#: relative regularisation of the strain constraints' block of the Newton matrix
#: (:meth:`_Equilibrium._constraint_regularisation`): dependent constraint rows stay solvable
REG_CONSTRAINTS = 1e-10
#: external nodal forces below EXT_ROUNDOFF·ε·max|F_int| count as none in the tolerance's scale
#: (solve_static ``tol``): the difference of the total and internal force passes of a problem
#: without external loads is of order ε·|F_int|
EXT_ROUNDOFF = 64.0
_EPS = float(np.finfo(float).eps)
FLOOR_FACTOR = 4.0
#: a convergence by increment or stagnation is accepted while ``max_i |r_i|/floor_i ≤ FLOOR_RATIO``
FLOOR_RATIO = 1e3


def _abs_assemble(eq: _Equilibrium, state: Any, stress: list[np.ndarray]) -> np.ndarray:
    """The magnitude of the lattice's assembly of edge stresses, ``Σ_e |dexp⁻¹(±ξ_e)ᵀ|·|Q_e|·cell/h``
    per node and component ``[*shape, r]`` (:meth:`_Equilibrium._assemble_full` with every
    product and sum taken in absolute value), zero off the unknowns."""
    g, sch = eq.g, eq.sch
    F = np.zeros((*eq.shape, eq.r_dim))
    cell = float(np.prod(sch.h))
    for axis, Q in enumerate(stress):
        xi = g.log(state.arrays[sch._key(axis)])
        Q = np.abs(Q) * (cell / sch.h[axis])
        out = np.einsum("...ji,...j->...i", np.abs(g.dexp_inv(xi)), Q)
        inc = np.einsum("...ji,...j->...i", np.abs(g.dexp_inv(-xi)), Q)
        sch._scatter(F, out, inc, axis)
    F = np.abs(F)  # a glued axis maps its ghost ends by Ad (signs)
    F[~eq.unknown] = 0.0
    return F


def _residual_floor(eq: _Equilibrium, state: Any, mu: np.ndarray, lam: float) -> np.ndarray:
    """The round-off floor of :meth:`_Equilibrium.residual` ``(m,)``: per row
    ``FLOOR_FACTOR·ε_mach·S_i``, S_i the sum of the magnitudes of the terms of that row.

    Terms
        * internal force: the assembly in magnitude (:func:`_abs_assemble`) of ``|Q(X)|`` plus
          ``Σ_k |∂Q/∂X_k|·δX_k``, the stresses' error from strains known to relative round-off:
          δX_k = ‖X_trans‖ for the translation components of an affine group (the edge's
          translation is known to ε·|t|) and ‖X_rot‖ + 1/h for the others (the edge's rotation
          entries, of size 1, to ε): e.g. ``EA·|X|`` per node of a stiff rod;
        * loads (λ times the scaled ones, supports in full), the medium's body force and the end
          loads: ``Σ|f_term|`` per row, plus their sensitivity to the frames' round-off,
          ``Σ_j |∂f/∂δ_j|·s_j`` with s_j = ‖x‖ (the node's position) for a translation and 1 for a
          rotation (the load Jacobians :meth:`_Equilibrium._local_jacobian` and
          :meth:`_Equilibrium._neighbour_jacobian`): ``k·|x|`` per node of a penalty support;
        * pin reactions ``|μ_j b_j|`` and the pin rows ``|x| + |x₀| + L``; strain-constraint
          reactions in magnitude, each multiplier known to ε times the largest (the LU solve's
          normwise backward error), and their rows ``|X_e[k] − v_k| + max|v| + 1/h``;
        * every row at least ε times the largest floor: a row whose terms all vanish in exact
          arithmetic holds products of round-off.

    Parameters
    ----------
    eq : _Equilibrium
        The problem.
    state : State
        The iterate.
    mu : array ``(nmult,)``
        Pin and constraint multipliers.
    lam : float
        Load factor.

    Returns
    -------
    array ``(m,)``
        The floor of each row of the residual (unknowns, pins, strain constraints), > 0.
    """
    sch, g, r_dim = eq.sch, eq.g, eq.r_dim
    emach = float(np.finfo(float).eps)
    lam = float(lam)
    affine = bool(getattr(g, "affine", False))
    ntr = g.matrix_size - 1 if affine else 0  # translation components first
    hmin = float(np.min(sch.h))
    # ---- internal force: |Q| and the stresses' sensitivity to the strains' round-off
    X = eq.strains(state)
    Q = eq.stress(X)
    dX = []
    for axis, x in enumerate(X):
        size = np.zeros_like(x)
        if ntr:
            size[..., :ntr] = np.linalg.norm(x[..., :ntr], axis=-1, keepdims=True)
        size[..., ntr:] = np.linalg.norm(x[..., ntr:], axis=-1, keepdims=True) + 1.0 / float(sch.h[axis])
        dX.append(size)
    sens = [np.zeros_like(q) for q in Q]
    # a separable lattice: each axis's stress reads its own strains (all axes at once per component)
    blocks = [(b,) for b in range(len(X))] if sch.coupled else [tuple(range(len(X)))]
    for axes in blocks:
        for k in range(r_dim):
            v = [np.zeros_like(x) for x in X]
            for b in axes:
                v[b][..., k] = dX[b][..., k]
            if not any(np.any(dv) for dv in v):
                continue
            for a, dq in enumerate(eq.stress_change(X, v)):
                sens[a] += np.abs(dq)
    S = _abs_assemble(eq, state, [np.abs(q) + s for q, s in zip(Q, sens, strict=True)])
    # ---- loads, body force, end loads: their magnitudes, and their sensitivity to the frames
    Phi = sch.frames(state)
    W = np.zeros((*eq.shape, r_dim))
    for load in eq.problem.loads:
        W += abs(lam if load.scaled else 1.0) * np.abs(load.force(Phi, eq.zero, state.t))
    T = eq.problem.medium.body_force(Phi, eq.zero, state.t)
    if T is not None:
        W += abs(lam) * np.abs(T)
    for k, (idx, b) in enumerate(sch._end_loads):
        P = b.load if b.follower else dead_to_body(g, Phi[idx], b.load)
        W[idx] += np.abs(sch.end_load_density(k, lam * P))
    S = S + W * eq.w
    col = np.ones((eq.nnode, r_dim))
    if affine:
        col[:, :ntr] = np.linalg.norm(eq.positions(state), axis=-1)[:, None]
    col = col[eq.unknown_flat]
    KL = abs(eq._local_jacobian(state, lam))
    if any(not load.local for load in eq.problem.loads):
        Kn, low = eq._neighbour_jacobian(state, lam)
        KL = KL + abs(Kn)
        if low is not None:  # the rank-k part U Vᵀ in magnitude: |U| (|V|ᵀ s)
            KL_low = np.abs(low[0]) @ (np.abs(low[1]).T @ col)
        else:
            KL_low = 0.0
    else:
        KL_low = 0.0
    rows = np.zeros(eq.m)
    rows[: eq.nunk] = S[eq.unknown] + KL @ col + KL_low
    # ---- pins and strain constraints
    if eq.npin:
        react = np.zeros((eq.nnode, r_dim))
        for (n, _), b, m_ in zip(eq.pins, eq._reaction_basis(state), mu[: eq.npin], strict=True):
            react[n] += np.abs(m_ * b)
        rows[: eq.nunk] += react[eq.unknown_flat]
        msize = g.matrix_size
        Phi_n = Phi.reshape(eq.nnode, msize, msize)
        value = np.array([eq._pin_value(Phi_n[n], n, k) for n, k in eq.pins])
        rows[eq.nunk: eq.nunk + eq.npin] = np.abs(value) + np.abs(eq.x0) + eq.length
    if eq.ncon:  # the multipliers come out of the LU solve: each known to ε times the largest
        qc = eq.constraint_stress(mu[eq._con])
        top = max(float(np.max(np.abs(q), initial=0.0)) for q in qc)
        rows[: eq.nunk] += _abs_assemble(eq, state, [np.abs(q) + top for q in qc])[eq.unknown]
        vmax = float(np.max(np.abs(eq.con.value), initial=0.0))
        rows[eq.nunk + eq.npin: eq.nunk + eq.npin + eq.ncon] = np.abs(eq.constraint_values(state)) + vmax + 1.0 / hmin
    if eq.nhold:  # reactions |ν_k g_k|, each ν known to ε times the largest; rows (|C| + |C₀|)/s
        G = np.abs(eq._hold_gradients(state))
        nu = np.abs(mu[eq._held])
        rows[: eq.nunk] += G @ (nu + float(np.max(nu)))
        C = np.abs(eq.hold_values(state))
        # a functional that sums terms cancelling to C (a rigid-motion gauge: C = 0 from terms of
        # the frames' size) states their magnitude (``round_off_scale``)
        terms = np.array([float(h.round_off_scale(eq.sch, state)) if hasattr(h, "round_off_scale") else 0.0
                          for h in eq.holds])
        rows[eq.nunk + eq.npin + eq.ncon: eq.m] = (C + np.abs(eq.hold_target) + terms) / eq.hold_scale
    floor = FLOOR_FACTOR * emach * rows
    # a row whose terms all vanish in exact arithmetic (e.g. the force rows of an unloaded
    # inextensible filament, its multipliers ≈ 1e-31) holds products of round-off: ε times the
    # largest floor at least
    return np.maximum(floor, max(emach * float(np.max(floor, initial=0.0)), np.finfo(float).tiny))


def _row_name(eq: _Equilibrium, i: int) -> str:
    """Where row ``i`` of the residual acts: a node's component, a pin or a strain constraint."""
    if i < eq.nunk:
        node, k = divmod(int(eq.cols[i]), eq.r_dim)
        where = np.unravel_index(node, eq.shape)
        return f"node {tuple(int(j) for j in where) if len(where) > 1 else int(where[0])}, component {k}"
    if i < eq.nunk + eq.npin:
        node, k = eq.pins[i - eq.nunk]
        return f"pin {i - eq.nunk} (flat node {node}, component {k})"
    if i < eq.nunk + eq.npin + eq.ncon:
        return f"strain constraint {i - eq.nunk - eq.npin}"
    return f"held functional {eq.holds[i - eq.nunk - eq.npin - eq.ncon].name!r}"


def _floor_check(eq: _Equilibrium, point: _Point, r: np.ndarray) -> tuple[float, str]:
    """``(max_i |r_i|/floor_i, message)`` over the rows of :func:`_residual_floor` at ``point``;
    the message names the residual, the floor and the row where the ratio is largest."""
    floor = _residual_floor(eq, point.state, point.mu, point.lam)
    if floor.size == 0:  # nothing to balance
        return 0.0, ""
    res = np.abs(r[: floor.size])
    ratio = res / floor
    i = int(np.argmax(ratio))
    worst = float(ratio[i])
    msg = (f"‖r‖_∞ = {float(np.max(res[: eq.nunk], initial=0.0)):.3e}, and at {_row_name(eq, i)} |r| = {res[i]:.3e} "
           f"is {worst:.3g} times its round-off floor {floor[i]:.3e} (FLOOR_FACTOR·ε_mach·Σ|terms|; accepted up to "
           f"{FLOOR_RATIO:g} times)")
    return worst, msg


def _newton(
    eq: _Equilibrium,
    point: _Point,
    *,
    residual: Callable[[_Point], np.ndarray],
    factorise: Callable[[_Point, list[np.ndarray] | None], Callable[[np.ndarray], np.ndarray]],
    move: Callable[[_Point, float, np.ndarray], _Point],
    converged: Callable[[_Point, np.ndarray], bool],
    scale: np.ndarray,
    max_iter: int,
    max_halvings: int,
    xtol: float,
    min_iter: int = 0,
    strains: list[np.ndarray] | None = None,
    mixed: bool = True,
    reuse: float = 0.0,
) -> _Outcome:
    """Damped mixed Newton iteration (NLEQ-ERR on the increments and the edge strains).

    Parameters
    ----------
    eq : _Equilibrium
        Strains, stresses and the fixed-stress assembly of the problem.
    point : _Point
        The starting iterate; its strains start consistent (ε = X).
    residual : callable
        ``residual(point)``: the residual vector, the unknowns' rows first; its first ``eq.m``
        rows are :meth:`_Equilibrium.residual` at ``point.lam`` (the rows the floor test reads;
        further rows, e.g. continuation's arclength, are left to ``converged``).
    factorise : callable
        ``factorise(point, offset)``: the solve of the Jacobian with the stress offset
        ``Q(ε) − Q(X)`` (None: none); raises :class:`_Singular`.
    move : callable
        ``move(point, α, d)``: the iterate after the step ``α·d``.
    converged : callable
        ``converged(point, r)``: the stopping test on the residual.
    scale : array
        Weights of the entries of a step ``d`` in the scaled norm (0: left out).
    max_iter : int
        Newton steps allowed.
    max_halvings : int
        The smallest step length is ``2^−max_halvings``.
    xtol : float
        A step with ``max|δ| ≤ xtol`` is taken in full; it ends the iteration when the residual
        is then at its round-off floor (``|r_i| ≤ FLOOR_RATIO·floor_i`` on every row of
        :func:`_residual_floor`); otherwise the iteration goes on, and a third such step in a
        row with the residual still above the floor is a failure that names the row.  A stall
        of the damping (no step length down to ``2^−max_halvings`` passes the monotonicity
        test) is a convergence by "stagnation" under the same floor test, and a failure otherwise.
    min_iter : int
        Newton steps required before the stopping test counts.
    strains : list of arrays, optional
        The starting edge strains ε (default: consistent, ε = X): after a predictor step
        from an equilibrium, its linearisation ``X₀ + B Δx``.
    mixed : bool
        False: the displacement-only iteration (ε = X throughout, the ordinary Jacobian and
        the simplified correction ``J⁻¹ r(trial)`` of NLEQ-ERR).
    reuse : float
        After a full step whose contraction θ = ‖Δx̄‖/‖Δx‖ is at most ``reuse``, the next step
        is that simplified correction Δx̄, already solved with the old factorisation (a
        simplified Newton step, converging like θ per step), and no new Jacobian is formed;
        a reused step that fails the monotonicity test is dropped and the Jacobian refreshed
        (Deuflhard 2011, §2.1.4).  0 (default): every step factorises.

    Returns
    -------
    _Outcome
    """
    nunk = eq.nunk
    alpha_min = 2.0 ** -max_halvings
    X = eq.strains(point.state)
    eps = [x.copy() for x in (X if strains is None or not mixed else strains)]
    r = residual(point)
    out = _Outcome(point, False, residuals=[float(np.linalg.norm(r[:nunk]))])
    sw = eq.strain_scale

    def vec(d: np.ndarray, de: list[np.ndarray]) -> np.ndarray:
        return np.concatenate([scale * d] + [(e * sw).ravel() for e in de])

    count = max(1, int(np.count_nonzero(scale)) + sum(x.size for x in X))

    def norm(v: np.ndarray) -> float:
        return float(np.linalg.norm(v)) / math.sqrt(count)

    prev: tuple[float, np.ndarray, float] | None = None  # (‖Δx_{k−1}‖, Δx̄_k, α_{k−1})
    small = 0  # consecutive full steps below xtol with the residual above its floor
    pending: tuple[np.ndarray, list[np.ndarray], np.ndarray] | None = None  # a simplified step to reuse
    solve: Callable[[np.ndarray], np.ndarray] | None = None
    k = 0
    while True:
        if not np.all(np.isfinite(r)):
            out.reason = "the residual is not finite"
            return out
        if k >= min_iter and converged(point, r):
            out.converged, out.by = True, "residual"
            return out
        if k >= max_iter:
            out.reason = f"the iteration limit max_iter = {max_iter} was reached"
            return out
        reused = pending is not None
        if pending is not None:  # the simplified correction of the last trial, with the old factorisation
            d, de, v = pending
            pending = None
        else:
            offset = [q_e - q for q_e, q in zip(eq.stress(eps), eq.stress(X), strict=True)] if mixed else None
            try:
                solve = factorise(point, offset)
                with np.errstate(all="ignore"):
                    d = solve(-r)
                if not np.all(np.isfinite(d)):
                    raise _Singular("non-finite Newton step")
            except _Singular as exc:
                out.reason = f"the Jacobian is singular ({exc})"
                out.singular_start = k == 0
                return out
            de = ([x - e + b for x, e, b in zip(X, eps, eq.strain_rate(point.state, d), strict=True)] if mixed
                  else [np.zeros_like(x) for x in X])
            v = vec(d, de)
        nu = norm(v)
        out.corrections.append(nu)
        step_max = float(np.max(np.abs(d[:nunk]), initial=0.0))
        if prev is None:
            alpha = 1.0
        else:
            nu_prev, vbar_prev, alpha_prev = prev
            denom = norm(vbar_prev - v) * nu
            alpha = 1.0 if denom == 0.0 else min(1.0, nu_prev * norm(vbar_prev) / denom * alpha_prev)
        alpha = max(alpha, alpha_min)
        if step_max <= xtol:
            alpha = 1.0
        raised = refresh = False
        while True:
            trial = move(point, alpha, d)
            X_t = eq.strains(trial.state)
            eps_t = [e + alpha * x for e, x in zip(eps, de, strict=True)] if mixed else X_t
            r_t = residual(trial)
            theta, mu_c, vbar = math.inf, 0.5 * alpha, None
            if np.all(np.isfinite(r_t)) and all(np.all(np.isfinite(x)) for x in X_t):
                # the simplified correction of the mixed system with the old Jacobian:
                # J δ̄ = −(r_t + A_t[Q(ε_t) − Q(X_t)] + A[C (X_t − ε_t)]), Δε̄ = X_t − ε_t + B δ̄
                gap = [xt - et for xt, et in zip(X_t, eps_t, strict=True)]
                rhs = r_t.copy()
                if mixed:
                    rhs[:nunk] += eq.assemble(trial.state, [a - b for a, b in zip(eq.stress(eps_t), eq.stress(X_t),
                                                                                   strict=True)])
                    rhs[:nunk] += eq.assemble(point.state, eq.stress_change(X, gap))
                with np.errstate(all="ignore"):
                    dbar = solve(-rhs)
                if np.all(np.isfinite(dbar)):
                    de_bar = ([g_ + b for g_, b in zip(gap, eq.strain_rate(point.state, dbar), strict=True)] if mixed
                              else gap)
                    vbar = vec(dbar, de_bar)
                    theta = norm(vbar) / nu if nu > 0 else 0.0
                    dist = norm(vbar - (1.0 - alpha) * v)
                    mu_c = math.inf if dist == 0.0 else 0.5 * nu * alpha * alpha / dist
            if step_max <= xtol and vbar is not None:
                break  # at the round-off floor: the full step, whatever the test says
            if theta < 1.0 - alpha / 4.0:
                up = min(1.0, mu_c)
                if not raised and alpha < 1.0 and up >= 4.0 * alpha:
                    alpha, raised = up, True
                    continue
                break
            if reused:  # the old factorisation no longer contracts: drop the step, form the Jacobian here
                refresh = True
                break
            alpha_new = min(mu_c, 0.5 * alpha)
            if not alpha_new >= alpha_min:
                out.alphas.append(0.0)
                # converged only at the residual's round-off floor: no step can reduce it further
                out.floor_ratio, where = _floor_check(eq, point, r)
                if out.floor_ratio <= FLOOR_RATIO:
                    out.converged, out.by = True, "stagnation"
                    return out
                out.reason = (f"the residual stagnates above its round-off floor: no damped Newton step passed the "
                              f"natural monotonicity test down to the step length 2^-{max_halvings} "
                              f"(max|δ| = {step_max:.3e}, contraction {theta:.3g} at the last trial); {where}")
                return out
            alpha = alpha_new
        if refresh:
            out.corrections.pop()
            continue
        out.alphas.append(alpha)
        prev = (nu, vbar, alpha)
        if reuse > 0.0 and alpha == 1.0 and vbar is not None and theta <= reuse:
            pending = (dbar, de_bar, vbar)
        point, X, eps, r = trial, X_t, eps_t, r_t
        out.point = point
        out.residuals.append(float(np.linalg.norm(r[:nunk])))
        k += 1
        if step_max <= xtol:
            if converged(point, r):
                out.converged, out.by = True, "increment"
                return out
            # the increment is at round-off: accepted with the residual at its floor; a residual far
            # above it after three such steps in a row is a wrong Jacobian or a non-smooth residual
            out.floor_ratio, where = _floor_check(eq, point, r)
            if out.floor_ratio <= FLOOR_RATIO:
                out.converged, out.by = True, "increment"
                return out
            small += 1
            if small >= 3:
                out.reason = (f"the Newton increments fell below xtol = {xtol:.3e} ({small} steps in a row, the last "
                              f"max|δ| = {step_max:.3e}) with the residual far above its round-off floor: {where}; "
                              "the Jacobian may be inconsistent with the residual, or the residual not smooth")
                return out
        else:
            small = 0


def _dissection(shape: tuple[int, ...], leaf: int = 2) -> np.ndarray:
    """Geometric nested dissection of a box lattice: the flat nodes ``(nnode,)``, each half
    of the longest axis (recursively) before the node plane that separates them.

    A plane one node thick separates the halves of any stencil reaching the next node along
    each axis and diagonally (the lattice's, :func:`_stencil_pairs`); across a periodic seam
    the halves stay coupled, which costs fill, not correctness.  On a d = 2 lattice of n × n
    nodes the LU factors then hold O(n² log n) entries instead of the O(n³) of a band."""
    parts: list[np.ndarray] = []

    def block(lo: list[int], hi: list[int]) -> None:
        axes = np.meshgrid(*[np.arange(a, b) for a, b in zip(lo, hi, strict=True)], indexing="ij")
        parts.append(np.ravel_multi_index(tuple(x.ravel() for x in axes), shape))

    def split(lo: list[int], hi: list[int]) -> None:
        ext = [b - a for a, b in zip(lo, hi, strict=True)]
        if max(ext) <= leaf:
            block(lo, hi)
            return
        ax = int(np.argmax(ext))
        mid = (lo[ax] + hi[ax]) // 2
        split(lo, [*hi[:ax], mid, *hi[ax + 1:]])
        split([*lo[:ax], mid + 1, *lo[ax + 1:]], hi)
        block([*lo[:ax], mid, *lo[ax + 1:]], [*hi[:ax], mid + 1, *hi[ax + 1:]])

    split([0] * len(shape), list(shape))
    return np.concatenate(parts)


def _lu_solve(K, order: np.ndarray | None = None) -> Callable[[np.ndarray], np.ndarray]:
    """The solve of the sparse LU of K; :class:`_Singular` when K cannot be factorised.

    ``order`` (a permutation of K's rows, optional): factorise ``K[order][:, order]`` in that
    order with SuperLU's symmetric mode (the diagonal pivot preferred unless it is below 0.1
    of its column's largest entry), e.g. the nested dissection of :func:`_dissection`; SuperLU's
    default column ordering (COLAMD, partial pivoting) without it, or when that fails.
    """
    import scipy.sparse.linalg as spla

    K = K.tocsc()
    if order is not None and order.size == K.shape[0]:
        try:
            with np.errstate(all="ignore"):
                lu = spla.splu(K[order][:, order].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.1,
                               options={"SymmetricMode": True})
        except RuntimeError:
            pass
        else:
            def solve(b: np.ndarray) -> np.ndarray:
                x = np.empty(np.shape(b), dtype=np.result_type(b, float))
                x[order] = lu.solve(np.asarray(b)[order])
                return x

            return solve
    try:
        with np.errstate(all="ignore"):
            lu = spla.splu(K)
    except RuntimeError as exc:
        raise _Singular(str(exc)) from None
    return lu.solve


def _padded(x: np.ndarray, m: int) -> np.ndarray:
    """``x`` ``(p, k)`` with zero rows appended to ``(m, k)`` (the multipliers' rows)."""
    return x if x.shape[0] == m else np.concatenate([x, np.zeros((m - x.shape[0], x.shape[1]))])


def _low_rank_solve(solve: Callable[[np.ndarray], np.ndarray], low: tuple[np.ndarray, np.ndarray] | None
                    ) -> Callable[[np.ndarray], np.ndarray]:
    """The solve of ``J + U Vᵀ`` from the solve of J (Sherman–Morrison–Woodbury):
    ``x = y − Z (I + VᵀZ)⁻¹ Vᵀy`` with ``y = J⁻¹b``, ``Z = J⁻¹U`` (k solves, once); ``low`` =
    (U, V) ``(m, k)`` each, None: ``solve`` itself.  :class:`_Singular` when ``I + VᵀZ`` is."""
    if low is None:
        return solve
    U, V = low
    Z = np.column_stack([solve(U[:, j]) for j in range(U.shape[1])])
    C = np.eye(U.shape[1]) + V.T @ Z
    if not np.all(np.isfinite(C)) or np.linalg.cond(C) > 1e14:
        raise _Singular("the Jacobian's low-rank part makes it singular")
    Cinv = np.linalg.inv(C)

    def lowrank(b: np.ndarray) -> np.ndarray:
        y = solve(b)
        return y - Z @ (Cinv @ (V.T @ y))

    return lowrank


def _low_rank_slogdet(solve: Callable[[np.ndarray], np.ndarray], low: tuple[np.ndarray, np.ndarray] | None
                      ) -> tuple[int, float]:
    """(sign, log|det|) of the capacitance matrix ``I_k + Vᵀ J⁻¹ U`` ``(k, k)`` from the solve of J,
    ``low`` = (U, V) ``(m, k)`` each: by the matrix determinant lemma
    ``det(J + U Vᵀ) = det J · det(I_k + Vᵀ J⁻¹ U)`` (k solves); (1, 0.0) for ``low`` None and
    (0, −inf) when the capacitance matrix is singular or not finite."""
    if low is None:
        return 1, 0.0
    U, V = low
    C = np.eye(U.shape[1]) + V.T @ np.column_stack([solve(U[:, j]) for j in range(U.shape[1])])
    if not np.all(np.isfinite(C)):
        return 0, -math.inf
    sign, logabs = np.linalg.slogdet(C)
    return (int(sign), float(logabs)) if sign != 0 else (0, -math.inf)


def _factorise(eq: _Equilibrium, state: Any, mu: np.ndarray, lam: float,
               offset: list[np.ndarray] | None, built: tuple[Any, Any] | None = None
               ) -> Callable[[np.ndarray], np.ndarray]:
    """The solve of the whole Jacobian of ``eq`` at (state, μ, λ): the sparse LU of
    :meth:`_Equilibrium.jacobian` and the loads' rank-k part by :func:`_low_rank_solve`
    (``built``: that ``(J, low)``, already assembled at this point)."""
    J, low = built if built is not None else eq.jacobian(state, mu, lam, offset, low_rank=True)
    return _low_rank_solve(_lu_solve(J, eq.lu_order), low)


RIGID_GAUGE = "rigid"


def rigid_gauge_pins(problem: Problem, pins: dict | str | None) -> dict | None:
    """The pins of ``solve_static(..., pins=...)``: ``pins`` itself, or for ``pins="rigid"`` the
    rigid-body gauge of a free body: every component of node 0 (positions, then rotations).

    A body without clamped boundaries (a closed filament, a free–free rod, a free surface;
    periodic axes with the identity holonomy) keeps its equilibria under every rigid motion,
    and its Jacobian is singular.  The gauge fixes node 0's position and rotation at the
    starting configuration, ``dim G`` multipliers whose values are the wrench that node 0
    would need: zero when the loads are balanced (checked after the solve, :func:`check_rigid_gauge`).

    Parameters
    ----------
    problem : Problem
        Without clamped boundaries; its medium on an affine group.
    pins : dict, ``"rigid"`` or None

    Returns
    -------
    dict or None

    Raises
    ------
    ValueError
        ``pins`` a text other than ``"rigid"``; ``"rigid"`` on a problem with a clamped
        boundary (which holds the rigid motions already), or with a periodic axis whose
        holonomy is not the identity (not every rigid motion keeps its equilibria).
    """
    if not isinstance(pins, str):
        return pins
    if pins != RIGID_GAUGE:
        raise ValueError(f"pins must be a dict {{node: components}}, None or {RIGID_GAUGE!r} (the rigid-body gauge "
                         f"of a free body), got {pins!r}")
    from .problem import Clamped, axis_holonomies

    clamped = sorted(k for k, b in problem.boundaries.items() if isinstance(b, Clamped))
    if clamped:
        raise ValueError(f"pins={RIGID_GAUGE!r} fixes the rigid motions of a free body; this problem has the clamped "
                         f"boundaries {clamped}, which hold them already (give pins as a dict or None)")
    for axis, H in axis_holonomies(problem.initial, problem.grid.d).items():
        if np.max(np.abs(np.asarray(H, dtype=float) - np.eye(H.shape[0]))) > 1e-12:
            raise ValueError(f"pins={RIGID_GAUGE!r} holds every rigid motion of node 0, but the holonomy of the "
                             f"periodic axis {axis} is not the identity: only the rigid motions that commute with it "
                             "leave the equilibria unchanged; give pins as a dict naming those")
    return {0: tuple(range(problem.medium.group.dim))}


def check_rigid_gauge(reaction: np.ndarray, forces: np.ndarray, length: float, tol: float) -> None:
    """Raise when the rigid-body gauge carries a load: the wrench ``reaction`` ``(dim G,)`` at
    node 0 must vanish against the external nodal forces ``forces`` (any shape), to
    ``max(100·tol, 1e-8)·Σ|f|·max(1, L)`` — a free body is in equilibrium only under
    balanced loads (total force and moment zero)."""
    bound = max(100.0 * tol, 1e-8) * max(float(np.sum(np.abs(forces))), 1e-12) * max(1.0, length)
    worst = float(np.max(np.abs(reaction), initial=0.0))
    if worst > bound:
        raise ValueError(f"pins={RIGID_GAUGE!r}: the loads on this free body are unbalanced (a free body has no "
                         f"equilibrium then): node 0 would carry the reaction {np.round(reaction, 12).tolist()}, "
                         f"max {worst:.3e} > {bound:.3e}; balance the loads or hold the body (Clamped, pins)")


def _rigid_motions(eq: _Equilibrium, J: Any, low: tuple[np.ndarray, np.ndarray] | None,
                   lam: float) -> RigidMotions:
    """The rigid motions the supports of ``eq`` leave free at its Newton matrix ``J`` at the start
    (+ ``low``, the loads' rank-k part; λ = ``lam``): :func:`cartan.rigid_modes.
    unsupported_rigid_motions` with the finite-difference Jacobian's loads' part apart, and the
    external forces at the round-off of the force passes counted as none."""
    internal, external = eq.parts(eq.state0)
    if not float(np.max(np.abs(external), initial=0.0)) > EXT_ROUNDOFF * _EPS * float(np.max(np.abs(internal),
                                                                                         initial=0.0)):
        external = np.zeros_like(external)  # the round-off of the force passes: no load (as in the solve)

    def loads() -> Any:
        """The loads' part of J's stiffness block at λ (the finite-difference Jacobian's own parts)."""
        if eq.kind != "fd":
            return None
        kept = getattr(eq, "last_loads", None)  # J's own loads' part, when J was built at the start
        if kept is not None and kept[0] is eq.state0 and kept[1] == lam:
            return kept[2]
        KL = eq._local_jacobian(eq.state0, lam)
        if any(not load.local for load in eq.problem.loads):
            KL = KL + eq._neighbour_jacobian(eq.state0, lam)[0]
        return KL

    return unsupported_rigid_motions(eq, J, low, external, loads)


def _check_rigid_motions(eq: _Equilibrium, J: Any, low: tuple[np.ndarray, np.ndarray] | None, lam: float,
                         gauge: bool = True) -> RigidMotions:
    """The rigid motions the supports of ``eq`` leave free, at its first Newton matrix ``J``
    (+ ``low``, the loads' rank-k part): :func:`cartan.rigid_modes.unsupported_rigid_motions`
    (``gauge``: whether the solve will hold them, for the warning's text).

    Raises
    ------
    ValueError
        The external loads have power along a free rigid motion (an unbalanced resultant or
        moment on a body free to move along it: no static equilibrium exists).

    Warns
    -----
    UnsupportedRigidMotion
        Free rigid motions along which the loads have no power: the equilibrium is determined
        up to them only.
    """
    import warnings

    rigid = _rigid_motions(eq, J, low, lam)
    if not rigid.count:
        return rigid
    free = "; ".join(rigid.names)
    fix = ("hold it with a pin or a Held component (solve_static(..., pins={node: components}), "
           "boundaries={...: cartan.Held(components)}, a Clamped end; pins='rigid' for a free body)")
    if rigid.loaded:
        from .rigid_modes import describe_motion

        worst = describe_motion(eq.g, rigid.loaded_direction())
        raise ValueError(f"solve_static: the supports leave the rigid motion(s) {free} free and the external loads "
                         f"have power along {worst} (an unbalanced resultant or moment, relative power "
                         f"{float(np.max(np.abs(rigid.power))) / rigid.power_scale:.3e}): a body free to move along "
                         f"it has no static equilibrium; {fix}, or balance the loads")
    then = ("held at their mean from the start (rigid_gauge=True)" if gauge else
            "the Newton matrix is singular along them and the solve may add an arbitrary multiple")
    warnings.warn(f"solve_static: the supports leave {rigid.count} rigid motion(s) free: {free}; the equilibrium "
                  f"is determined up to them only ({then}); {fix}", UnsupportedRigidMotion, stacklevel=2)
    return rigid


def solve_static(
    problem: Problem,
    scheme: str = "lattice",
    tol: float = 1e-10,
    max_iter: int = 50,
    initial: Any = None,
    jacobian: str = "auto",
    *,
    xtol: float = 1e-12,
    load_steps: int = 1,
    adaptive_load: bool = True,
    min_load_step: float = 1e-4,
    max_load_steps: int = 1000,
    fd_step: float = 1e-6,
    max_halvings: int = 20,
    mixed: bool = True,
    reuse: float = 0.0,
    t: float = 0.0,
    pins: dict | str | None = None,
    pole: str = "corners",
    holds: Sequence[HeldFunctional] = (),
    rigid_gauge: bool = True,
):
    """An equilibrium of ``problem`` by Newton's method on the group.

    Parameters
    ----------
    problem : Problem
        Medium, grid, boundaries and loads; ``problem.initial.Phi`` is the starting guess
        (velocities are ignored).
    scheme : str
        ``"lattice"`` (the only scheme supported).
    tol : float
        A load step has converged when ``‖r‖_∞ ≤ tol·f``, f the largest external nodal
        force of the load step (or of the first residual when there is none: external forces
        below ``EXT_ROUNDOFF``·ε times the largest internal one are the round-off of the force
        passes).
    max_iter : int
        Newton iterations allowed per load step.
    initial : None, InitialState, array ``[*shape, m, m]`` or Dataset
        Starting configuration instead of ``problem.initial`` (a Dataset: its last frame,
        for media on affine groups — e.g. a previous :func:`solve_static` result).
    jacobian : str
        ``"auto"`` (default): the medium's analytic Jacobian
        (:meth:`~cartan.medium.Medium.static_jacobian`) when it returns one for this
        problem, coloured central finite differences otherwise; ``"analytic"``: the
        medium's, a ``ValueError`` when it has none; ``"fd"``: finite differences.
    xtol : float
        Also converged when a Newton increment satisfies ``‖δ‖_∞ ≤ xtol·max(1, L)`` (L the
        largest grid length) with the residual at its round-off floor, within ``FLOOR_RATIO``
        (1e3) times :func:`_residual_floor` on every row (docs/statics.md, "Convergence").
    load_steps : int
        The first load increment is ``1/load_steps`` of the external loads.
    adaptive_load : bool
        Control the load increment (default): doubled after a load step converged in at
        most ``min(4, max_iter − 1)`` iterations (unless the step before it failed), halved
        and retried from the last equilibrium after a failed one.  False: ``load_steps``
        equal increments, and the first failure raises.
    min_load_step : float
        The smallest load increment before :class:`ConvergenceError` (adaptive control).
    max_load_steps : int
        Load steps allowed, failed ones included.
    fd_step : float
        Finite-difference step along the drift directions.
    max_halvings : int
        The damping stops at the step length ``2^−max_halvings`` (then the load step fails).
    mixed : bool
        The mixed iteration, edge strains carried as unknowns (default); False: the
        displacement-only Newton iteration (same damping and load-step control), which
        converges poorly for stiff stretching and shear.
    reuse : float
        In [0, 1): after a full Newton step whose contraction (the ratio of the simplified
        correction to the correction, NLEQ-ERR's θ) is at most ``reuse``, the next steps keep
        the factorised Jacobian (simplified Newton steps, each contracting by about θ) while
        they pass the monotonicity test, which saves factorisations on a nearly linear
        problem (e.g. 1e-3).  0 (default): a new Jacobian at every step (quadratic convergence).
    t : float
        Time at which time-dependent loads are evaluated.
    pins : dict, optional
        ``{node: components}``: spatial position components (from m − 1 on: rotations) of
        chosen nodes held at their values in the starting configuration by Lagrange
        multipliers, as in :func:`cartan.continuation.continuation` (the node names:
        :func:`pin_node`); a load step has converged when the pins hold to ``tol·max(1, L)``
        too.  Their multipliers, the reactions, are returned as ``reaction`` along ``pin``.
        ``"rigid"``: the rigid-body gauge of a free body (no clamped boundary, e.g. a closed
        filament on a periodic grid): every component of node 0 held
        (:func:`rigid_gauge_pins`); the solve raises a ``ValueError`` when the loads are
        unbalanced (node 0's reaction not zero, :func:`check_rigid_gauge`).
    pole : str
        The lattice's treatment of a glued chart's poles (:class:`~cartan.schemes.lattice.Lattice`
        ``pole``): ``"corners"`` (default) or ``"cap"`` (the pole cell, a d = 2 SE(3) chart with a
        glued axis, a coupled medium and a reference; a ``ValueError`` otherwise).  The cap's
        Jacobian stencil couples the whole pole row (:func:`_lattice_stencil`).
    holds : sequence of HeldFunctional
        Global functionals C_k(Φ) held at their targets by Lagrange multipliers μ_k, one bordered
        row each in the Newton matrix (:class:`cartan.constraints.HeldFunctional`: e.g. a
        vesicle's area and volume, whose multipliers are its tension and pressure changes); a
        load step has converged when ``|C_k − C₀_k| ≤ tol·s_k`` too.  They hold at every load
        factor λ.  Outputs ``held_value`` C_k and ``held_multiplier`` μ_k (the equilibrium of
        E + Σ μ_k (C_k − C₀_k)) along ``held``, whose coordinate is their names.
    rigid_gauge : bool
        The rigid motions the supports leave free are found on the first Newton matrix
        (:func:`cartan.rigid_modes.unsupported_rigid_motions`: the held components, the bordered
        rows and the Jacobian do not resist them), with an :class:`UnsupportedRigidMotion`
        warning that names them, or a ``ValueError`` when the external loads have power along
        one (no equilibrium exists).  True (default): each is then held by a bordered row, its
        mean over the nodes at zero (:class:`cartan.rigid_modes.RigidMotionGauge`; outputs along
        ``held`` as ``rigid_motion_k``), so the equilibrium is the one without rigid motion from
        the start; False: no row (the Newton matrix stays singular along them, and the result may
        carry an arbitrary rigid motion or the solve fail on a zero pivot).

    Returns
    -------
    xarray.Dataset
        One frame (``time`` of length 1) with the usual run variables (position, frame, X,
        energies, residuals) plus, along ``iteration`` (every iterate of every load step,
        failed ones included), ``newton_residual`` ‖r‖₂, ``load_factor`` λ, ``newton_load_step``
        (the load step's index) and ``newton_correction`` (scaled RMS norm of the Newton
        correction computed there, NaN where none was); along ``newton_step`` the step lengths
        ``newton_step_length``; along ``load_step`` ``load_step_factor`` (the λ aimed at),
        ``load_step_iterations`` and ``load_step_converged``.  Attributes
        ``newton_iterations``, ``newton_load_steps`` (converged load steps),
        ``newton_load_step_failures``, ``newton_wall_time``, ``newton_jacobian``
        (``"analytic"`` or ``"fd"``, the Jacobian used), ``newton_converged_by`` (how the last
        load step ended: ``"residual"``, the residual test; ``"increment"``, a full Newton step
        with ``‖δ‖_∞ ≤ xtol·max(1, L)``; ``"stagnation"``, no damped step passed the monotonicity
        test: the last two only with the residual within ``FLOOR_RATIO`` = 1e3 times its round-off
        floor on every row, e.g. ``EA·ε_mach·|X|`` per node of a stiff rod, which can lie far above
        ``tol·f``), ``newton_residual_max`` (the final ‖r‖_∞), ``newton_residual_tol`` (``tol·f`` of
        the last load step), ``newton_residual_floor`` (the largest entry of the floor
        :func:`_residual_floor` on the force rows at the end) and ``newton_residual_floor_ratio``
        (the largest ``|r_i|/floor_i`` at the end).  For a medium with constrained strains
        also ``constraint_force`` ``[time, constrained_edge, constrained_component]`` (the
        multipliers: edge stresses conjugate to the constrained components; NaN on edges between
        fixed nodes), ``constraint_residual`` ``[time]`` and the attributes
        ``constraint_components``, ``constraint_values`` and ``constraint_residual_max``.
        Always ``unsupported_rigid_motions``, the number of rigid motions the supports leave free
        (``rigid_gauge``), and when there are some ``unsupported_rigid_motion_names`` (in words,
        ``"; "``-separated) and ``unsupported_rigid_motion_directions`` (their ξ ∈ 𝔤, flattened
        ``k × dim 𝔤``).

    Raises
    ------
    ValueError
        Bad options; ``jacobian="analytic"`` for a medium without an analytic Jacobian of
        this problem; a :meth:`~cartan.medium.Medium.static_jacobian` of the wrong shape; the
        external loads have power along a rigid motion the supports leave free (no equilibrium
        exists), naming it.

    Warns
    -----
    UnsupportedRigidMotion
        The supports leave rigid motions free (the loads have no power along them), named in the
        message with how to hold them.
    ConvergenceError
        No equilibrium was found (see the module docstring).
    """
    from . import io

    if scheme != "lattice":
        raise ValueError(f"solve_static supports scheme='lattice' only, got {scheme!r}")
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {', '.join(map(repr, _JACOBIANS))}, got {jacobian!r}")
    for name, value in (("load_steps", load_steps), ("max_load_steps", max_load_steps)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}")
    if load_steps > max_load_steps:
        raise ValueError(f"load_steps must be ≤ max_load_steps = {max_load_steps} (the bound on the load steps "
                         f"a solve may take), got {load_steps!r}")
    if isinstance(reuse, (bool, str)) or not 0.0 <= float(reuse) < 1.0:
        raise ValueError(f"reuse must be in [0, 1), got {reuse!r}")
    reuse = float(reuse)
    if isinstance(min_load_step, (bool, str)) or not 0.0 < float(min_load_step) <= 1.0:
        raise ValueError(f"min_load_step must be in (0, 1], got {min_load_step!r}")
    if not isinstance(rigid_gauge, (bool, np.bool_)):
        raise ValueError(f"rigid_gauge must be True or False, got {rigid_gauge!r}")
    start = time.perf_counter()
    init = _initial_phi(problem, initial)
    if init is not problem.initial:
        problem = Problem(problem.medium, problem.grid, InitialState(Phi=init.Phi, holonomy=problem.initial.holonomy,
                                                                     glue=problem.initial.glue),
                          problem.boundaries, problem.loads, problem.name, reference=problem.reference)
    nsteps = int(load_steps)
    pins_option, pins = pins, rigid_gauge_pins(problem, pins)
    eq = _Equilibrium(problem, jacobian=jacobian, fd_step=fd_step, t=t, probe_lam=1.0 / nsteps, pins=pins,
                      pole=pole, holds=holds)
    # the rigid motions the supports leave free, on the first Newton matrix (reused by the first step)
    lam_first = 1.0 if 1.0 / nsteps >= 1.0 - 1e-12 else 1.0 / nsteps
    first: list[Any] = []
    rigid = RigidMotions(np.zeros((0, eq.r_dim)), np.zeros((eq.nnode, eq.r_dim, 0)))
    if eq.nunk:
        J0, low0 = eq.jacobian(eq.state0, np.zeros(eq.nmult), lam_first, None, low_rank=True)
        rigid = _check_rigid_motions(eq, J0, low0, lam_first, bool(rigid_gauge))
        if rigid.count and rigid_gauge:  # one bordered row per free direction: the solve is well posed
            eq = _Equilibrium(problem, jacobian=jacobian, fd_step=fd_step, t=t, probe_lam=1.0 / nsteps, pins=pins,
                              pole=pole, holds=(*holds, *rigid_gauges(eq, rigid)))
        else:
            first.append((J0, low0))
    sch, g, nunk = eq.sch, eq.g, eq.nunk
    mu0 = np.zeros(eq.nmult)  # the pins' multipliers, then the strain constraints'
    pin_tol = tol * eq.length
    x_tol = xtol * eq.length
    delta_scale = np.concatenate([eq.delta_scale, np.zeros(eq.nmult)])  # multipliers: not in the norm

    history: list[float] = []
    factors: list[float] = []
    step_of: list[int] = []
    corrections: list[float] = []
    alphas: list[float] = []
    attempts: list[tuple[float, int, int]] = []
    modes: list[str] = []  # how each load step ended ("" failed; see _Outcome.by)

    def fail(reason: str) -> ConvergenceError:
        rnorm = history[-1] if history else float("nan")
        tail = ", ".join(f"{x:.3e}" for x in history[-6:])
        return ConvergenceError(
            f"solve_static: no equilibrium after {len(alphas)} Newton iteration(s), residual ‖r‖ = {rnorm:.3e}: "
            f"{reason} (last residuals: {tail})",
            len(alphas),
            rnorm,
            history,
        )

    def factorise(pt: _Point, offset: list[np.ndarray] | None) -> Callable[[np.ndarray], np.ndarray]:
        if first:
            J, low = first.pop()
            if (pt.state is eq.state0 and pt.lam == lam_first and not np.any(pt.mu)
                    and (offset is None or not any(np.any(o) for o in offset))):
                return _factorise(eq, pt.state, pt.mu, pt.lam, offset, built=(J, low))
        return _factorise(eq, pt.state, pt.mu, pt.lam, offset)

    def residual(pt: _Point) -> np.ndarray:
        return eq.residual(pt.state, pt.mu, pt.lam)

    def move(pt: _Point, alpha: float, d: np.ndarray) -> _Point:
        return _Point(*eq.update(pt.state, pt.mu, d, alpha), pt.lam)

    state, mu = eq.state0, mu0
    lam = 0.0
    dlam = 1.0 / nsteps
    fast = min(4, max_iter - 1)  # a load step converged in this many iterations doubles the increment
    cut = False  # the last load step failed: hold the increment after the next success
    while lam < 1.0:
        if len(attempts) >= max_load_steps:
            raise fail(f"max_load_steps = {max_load_steps} load steps were taken before λ = 1 (λ = {lam:g})")
        lam_try = 1.0 if lam + dlam >= 1.0 - 1e-12 else lam + dlam
        internal, ext_forces = eq.parts(state)
        ext = float(np.max(np.abs(ext_forces), initial=0.0))
        r0 = internal + lam_try * ext_forces
        # external forces at the round-off of the force passes (total − internal of a problem with
        # none, ~ε·|F_int|) are none: the scale is then the first residual's
        inside = float(np.max(np.abs(internal), initial=0.0))
        scale = ext * lam_try if ext > EXT_ROUNDOFF * _EPS * inside else float(np.max(np.abs(r0), initial=0.0))
        atol = tol * scale if scale > 0 else tol
        last_atol = atol

        def converged(pt: _Point, r: np.ndarray, atol: float = atol) -> bool:
            # the increments' round-off floor, xtol, ends the iteration in any case
            return nunk == 0 or (float(np.max(np.abs(r[:nunk]), initial=0.0)) <= atol and eq.constraints_met(r, tol)
                                 and float(np.max(np.abs(r[nunk: nunk + eq.npin]), initial=0.0)) <= pin_tol)

        out = _newton(eq, _Point(state, mu, lam_try), residual=residual, factorise=factorise, move=move,
                      converged=converged, scale=delta_scale, max_iter=max_iter, max_halvings=max_halvings,
                      xtol=x_tol, mixed=mixed, reuse=reuse)
        index = len(attempts)
        history.extend(out.residuals)
        factors.extend([lam_try] * len(out.residuals))
        step_of.extend([index] * len(out.residuals))
        corrections.extend(out.corrections + [math.nan] * (len(out.residuals) - len(out.corrections)))
        alphas.extend(out.alphas)
        attempts.append((lam_try, out.iterations, int(out.converged)))
        modes.append(out.by)
        if out.converged:
            state, mu, lam = out.point.state, out.point.mu, lam_try
            if adaptive_load and not cut and out.iterations <= fast:
                dlam = min(1.0, 2.0 * dlam)
            cut = False
            continue
        if out.singular_start:
            raise fail(f"{out.reason} at load factor {lam_try:g}; the problem may be ill-posed, e.g. a free body "
                       "under an unbalanced load or without supports (a free body under balanced loads: pins='rigid')")
        if not adaptive_load:
            raise fail(f"{out.reason} at load factor {lam_try:g}")
        dlam *= 0.5
        cut = True
        if dlam < min_load_step:
            raise fail(f"{out.reason} at load factor {lam_try:g}, and the load increment fell below "
                       f"min_load_step = {min_load_step:g}; the problem may be singular or ill-posed, e.g. a free body "
                       "under an unbalanced load, or the load path has a limit point (use cartan.continuation)")
    wall = time.perf_counter() - start
    if isinstance(pins_option, str):  # the rigid-body gauge: node 0 must carry no load
        check_rigid_gauge(mu[: eq.npin], eq.parts(state)[1], eq.length, tol)

    rec = io.frame_record(sch, _Static(), state)
    records = {k: [v] for k, v in rec.items()}
    config = {
        "problem": problem.to_dict(),
        "run": {
            "solver": "newton",
            "scheme": sch.name,
            "scheme_options": sch.options(),
            "tol": tol,
            "xtol": xtol,
            "max_iter": max_iter,
            "jacobian": jacobian,
            "fd_step": fd_step,
            "load_steps": nsteps,
            "adaptive_load": bool(adaptive_load),
            "min_load_step": float(min_load_step),
            "max_load_steps": int(max_load_steps),
            "max_halvings": int(max_halvings),
            "mixed": bool(mixed),
            "reuse": reuse,
            "t": float(t),
            **({"pins": pins_option} if pins_option else {}),
            **({"holds": [h.name for h in eq.holds]} if eq.nhold else {}),
            **({"rigid_gauge": False} if not rigid_gauge else {}),
        },
        "counters": {"newton_iterations": len(alphas), "load_steps": len(attempts), "wall_time": wall},
    }
    name = problem.name or problem.medium.name
    ds = io.build_dataset(
        sch,
        records,
        config=config,
        history=io.history_line(f"cartan.solve_static(problem {name!r}, scheme={scheme!r}, tol={tol!r})"),
        title=f"{name}: static equilibrium of {problem.medium.name} on {g.name}",
    )
    ds["newton_residual"] = (
        "iteration",
        np.asarray(history, dtype=float),
        {"long_name": "Newton residual norm ‖r‖₂ on the unknowns", "units": "force"},
    )
    ds["load_factor"] = (
        "iteration",
        np.asarray(factors, dtype=float),
        {"long_name": "fraction of the external load applied", "units": "1"},
    )
    ds["newton_load_step"] = (
        "iteration",
        np.asarray(step_of, dtype=np.int64),
        {"long_name": "index of the load step of the iterate (along load_step)"},
    )
    ds["newton_correction"] = (
        "iteration",
        np.asarray(corrections, dtype=float),
        {"long_name": "scaled RMS norm of the Newton correction (increments and edge strains) at the iterate",
         "units": "1"},
    )
    ds["newton_step_length"] = (
        "newton_step",
        np.asarray(alphas, dtype=float),
        {"long_name": "damping factor α of each Newton step (0: no step accepted)", "units": "1"},
    )
    ds["load_step_factor"] = (
        "load_step",
        np.asarray([a[0] for a in attempts], dtype=float),
        {"long_name": "load factor aimed at by the load step", "units": "1"},
    )
    ds["load_step_iterations"] = (
        "load_step",
        np.asarray([a[1] for a in attempts], dtype=np.int64),
        {"long_name": "Newton iterations of the load step"},
    )
    ds["load_step_converged"] = (
        "load_step",
        np.asarray([a[2] for a in attempts], dtype=np.int64),
        {"long_name": "1: the load step converged; 0: it failed and the increment was halved"},
    )
    ds.attrs["newton_iterations"] = int(len(alphas))
    ds.attrs["newton_load_steps"] = int(sum(a[2] for a in attempts))
    ds.attrs["newton_load_step_failures"] = int(sum(1 - a[2] for a in attempts))
    ds.attrs["newton_wall_time"] = float(wall)
    ds.attrs["newton_jacobian"] = eq.kind
    # the rigid motions the supports leave free (UnsupportedRigidMotion), in words and in 𝔤
    ds.attrs["unsupported_rigid_motions"] = int(rigid.count)
    if rigid.count:
        ds.attrs["unsupported_rigid_motion_names"] = "; ".join(rigid.names)
        ds.attrs["unsupported_rigid_motion_directions"] = [float(x) for x in rigid.directions.ravel()]
    ds.attrs["newton_residual_final"] = float(history[-1]) if history else 0.0
    ds.attrs["newton_converged"] = 1
    # how the last load step (λ = 1) converged, and its residual against the tolerance tol·f
    ds.attrs["newton_converged_by"] = modes[-1]
    r_final = eq.residual(state, mu, lam)
    ds.attrs["newton_residual_max"] = float(np.max(np.abs(r_final[:nunk]), initial=0.0))
    ds.attrs["newton_residual_tol"] = float(last_atol)
    # the residual's round-off floor (_residual_floor): its largest entry on the force rows, and
    # the largest ratio |r_i|/floor_i over every row (≤ FLOOR_RATIO unless the residual test ended)
    floor = _residual_floor(eq, state, mu, lam)
    ds.attrs["newton_residual_floor"] = float(np.max(floor[:nunk], initial=0.0))
    ds.attrs["newton_residual_floor_ratio"] = float(np.max(np.abs(r_final[: floor.size]) / floor, initial=0.0))
    if eq.ncon:
        _constraint_outputs(ds, eq, state, mu)
    if eq.npin:  # the pins' multipliers: spatial reactions at the pinned nodes
        ds["reaction"] = ("pin", np.asarray(mu[: eq.npin], dtype=float),
                          {"long_name": "reaction at the pin (spatial component)", "units": "force"})
    if eq.nhold:  # the held functionals: values and multipliers μ_k = ν_k/s_k
        ds = ds.assign_coords(held=("held", [h.name for h in eq.holds]))
        ds["held_value"] = ("held", eq.hold_values(state),
                            {"long_name": "value C_k of the held functional at the equilibrium"})
        ds["held_target"] = ("held", eq.hold_target.copy(), {"long_name": "target C0_k of the held functional"})
        ds["held_multiplier"] = ("held", mu[eq._held] / eq.hold_scale,
                                 {"long_name": "Lagrange multiplier mu_k of the held functional "
                                               "(an equilibrium of E + sum mu_k (C_k - C0_k))"})
    return ds


def _constraint_outputs(ds: Any, eq: _Equilibrium, state: Any, mu: np.ndarray) -> None:
    """Record the strain constraints of a converged solve in ``ds``: ``constraint_force``
    ``[time, constrained_edge, constrained_component]`` (the multipliers, the reaction edge
    stresses; NaN on edges between fixed nodes), ``constraint_residual`` ``[time]``
    (max |X_e[k] − value_k|) and the attributes ``constraint_components``,
    ``constraint_values`` and ``constraint_residual_max``."""
    force = eq.edge_multipliers(mu[eq._con])
    res = float(np.max(np.abs(eq.constraint_values(state)), initial=0.0))
    ds["constraint_force"] = (
        ("time", "constrained_edge", "constrained_component"), force[None],
        {"long_name": "multiplier of the strain constraint: the edge stress conjugate to the constrained "
                      "strain component (a reaction)", "units": "force"})
    ds["constraint_residual"] = ("time", np.array([res]),
                                 {"long_name": "max |X_e[k] − value_k| over the constrained edges", "units": "1"})
    ds.coords["constrained_component"] = ("constrained_component", eq.con.comp)
    ds.attrs["constraint_components"] = [int(k) for k in eq.con.comp]
    ds.attrs["constraint_values"] = [float(v) for v in eq.con.value]
    ds.attrs["constraint_residual_max"] = res
