"""Strain components held fixed on a lattice's edges (paper §III.E, §IV.E).

A medium may hold some components of its strain at fixed values
(:meth:`~cartan.medium.Medium.constrained_strains`): the inextensible, unshearable filament
has θ = (1, 0, 0) (§VII.A), the Kirchhoff–Love surface θ_{α,3} = 0 (§VII.B).  On the lattice
each edge e = (i, j) along an axis carries the exact strain X_e = log(Φ_i⁻¹Φ_j)/h, so the
constraint is one row per edge and component,

    c_{e,k}(Φ) = X_e[k] − value_k = 0,

whose derivative along the drift Φ_i ← Φ_i exp(δ_i) is exact,

    B_c δ = [dexp⁻¹(−hX_e) δ_j − dexp⁻¹(hX_e) δ_i]_k / h.

Its reaction is the lattice's internal force of edge stresses μ whose component k is the
multiplier (the fictitious stress of §IV.E): ``−cell·B_cᵀμ`` on the nodes.  The statics
(:mod:`cartan.statics`) solve the saddle-point system with these rows, and the ``rattle``
integrator (:mod:`cartan.integrators.constrained`) keeps them in time.

:class:`StrainConstraints` holds the rows of one problem on one lattice: which edges are
constrained (every edge with an unknown at either end), the values, the Jacobian ``B_c`` and
the edge stresses of given multipliers.  It knows no medium beyond the declaration.

On the ``collocation`` scheme the strains are stored at the nodes and drift by the
compatibility equation ∂_tX = ∂_uN + ad_X N (§III) with the scheme's difference operator:
:class:`NodalStrainConstraints` holds one row per node and component, ``X_i[k] − value_k``,
with ``B_c δ = [Dδ + ad_X δ]_k`` (``rattle``'s rows there, :meth:`Collocation.constraint_rows
<cartan.schemes.collocation.Collocation.constraint_rows>`).

Glued axes (a chart closed over poles, :class:`~cartan.grid.Grid` ``glued``; the sphere's)
    The edges across the ends are rows like the others: the strain of an edge whose end is a
    ghost, ``G_e = Φ_i⁻¹Φ_j'Γ`` (or ``Γ⁻¹Φ_j'⁻¹Φ_i``), moves with the node j' it stands for by
    ``Ad_{Γ⁻¹}δ_j'`` (:class:`~cartan.schemes.lattice.Lattice`, "Glued axes"), so that end's
    block of ``B_c`` is ``±dexp⁻¹(∓hX_e) Ad_{Γ⁻¹}/h``, and the reaction goes back to j' through
    ``Ad_{Γ⁻¹}ᵀ`` as the lattice's forces do.  Every physical edge across an end is stored
    twice (lines i_β and i_β + n_β/2), the copies related by ``X' = −Ad_Γ X``: the rows are
    held on the first copy only (the second would repeat them and make ``B_c`` rank
    deficient), which requires ``−Ad_Γ`` to map the constrained components onto themselves
    with their values (θ_α,3 = 0 under the sphere's half-turn about e₃: θ_3 → −θ_3); another
    glue is refused (``ValueError``).  ``rattle`` does not take glued axes yet.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .scatter import scatter_add

__all__ = ["HeldFunctional", "NodalStrainConstraints", "StrainConstraints"]


class HeldFunctional:
    """A scalar functional C(Φ) of the whole configuration held at a value by one Lagrange
    multiplier in the statics (:func:`cartan.solve_static` ``holds``): the total area and the
    enclosed volume of a vesicle, a centre of mass, a total length.

    The static problem becomes the stationarity of the Lagrangian ``E(Φ) + μ (C(Φ) − C₀)``: the
    residual's force rows gain the reaction ``−μ ∂C/∂η_i`` and one row ``(C₀ − C)/s`` is added
    (its unknown μs), so the Newton matrix is the symmetric bordered saddle-point matrix

        [[K − μ ∂²C, −gᵀ], [−g, 0]],      g = ∂C/∂η / s,      K = ∂F/∂η = −∂²E,

    whose stiffness block acts on the tangent space of C = C₀ only: a step that would lose its
    convexity along a mode changing C (a vesicle's shape mode at fixed tension and pressure)
    stays well posed.  μ is the multiplier of C, e.g. a tension for an area and minus a pressure
    for a volume (the energy of a pressure p is −pV).

    Contract (a subclass implements :meth:`value` and :meth:`gradient`; it may override
    :meth:`bind`):

    * :meth:`value` and :meth:`gradient` read the scheme's state only; the gradient is exact
      (derivatives along the drift Φ_i ← Φ_i exp(η_i), summed over the lattice, not per unit
      weight: the units of the lattice's nodal forces), since the constraint row's Jacobian is
      taken from it;
    * the term μ ∂²C of the Jacobian is the coloured central difference of ``μ·gradient`` on the
      lattice's force stencil: exact for a functional whose gradient at a node reads that node's
      stencil.  A global coupling (e.g. through the mean position of all nodes) is not on the
      stencil: a functional that has one declares it by :meth:`hessian_parts` (the gradient with
      the global quantities frozen, differenced on the stencil, plus an exact rank-k rest U Vᵀ,
      which the solve adds by the Sherman–Morrison–Woodbury identity, as a load's
      :meth:`cartan.problem.Load.jacobian_parts`); without it the coupling is left out of the
      Jacobian and Newton contracts linearly by a factor of order μ times that coupling.

    Parameters
    ----------
    target : float, optional
        C₀ (default: C of the starting configuration).
    scale : float, optional
        The row's unit s > 0: the row holds ``(C − C₀)/s`` and the solve ends with
        ``|C − C₀| ≤ tol·s`` (default ``max(|C₀|, tiny)``: a relative tolerance).
    name : str, optional
        The name in the outputs (default the class's ``name``).
    """

    name = "held"

    def __init__(self, target: float | None = None, scale: float | None = None, name: str | None = None):
        if target is not None and not np.isfinite(target):
            raise ValueError(f"target must be finite, got {target!r}")
        if scale is not None and not (np.isfinite(scale) and scale > 0.0):
            raise ValueError(f"scale must be finite and > 0, got {scale!r}")
        self.target = None if target is None else float(target)
        self.scale = None if scale is None else float(scale)
        if name is not None:
            self.name = str(name)

    def bind(self, problem: Any, scheme: Any) -> None:
        """Called once by the statics with the problem and its lattice before any evaluation
        (e.g. to build a lattice of its own on the same chart).  Default: nothing."""

    def value(self, scheme: Any, state: Any) -> float:
        """C of the configuration ``state`` on ``scheme``."""
        raise NotImplementedError(f"{type(self).__name__}.value")

    def gradient(self, scheme: Any, state: Any) -> np.ndarray:
        """∂C/∂η_i ``[*shape, r]`` (body components, the drift Φ_i ← Φ_i exp(η_i)), exact."""
        raise NotImplementedError(f"{type(self).__name__}.gradient")

    def hessian_parts(self, scheme: Any, state: Any) -> tuple[Callable[[Any], np.ndarray], np.ndarray,
                                                                np.ndarray] | None:
        """The Hessian ∂²C along the drifts at ``state`` split as a stencil part and a rank-k rest,
        or None (default: the whole of :meth:`gradient` is differenced on the stencil).

        Returns
        -------
        frozen : callable
            A state → ``[*shape, r]``: the gradient with its global quantities held at their values
            at ``state``, so that it reads each node's stencil only.
        U, V : arrays ``[*shape, r, k]``
            ``∂²C = ∂frozen/∂η + U Vᵀ`` (nodes and components flattened in C order).
        """
        return None

    def start(self, scheme: Any, state: Any) -> tuple[float, float]:
        """(C₀, s) at the starting configuration: the given target and scale, or their defaults."""
        target = self.value(scheme, state) if self.target is None else self.target
        scale = self.scale if self.scale is not None else max(abs(target), float(np.finfo(float).tiny))
        return float(target), float(scale)


def _constrained_spec(medium: Any, r: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The medium's ``constrained_strains()`` as ``(components int [k], values [k])``, checked
    against the algebra's dimension ``r``; None when it constrains none.

    Raises
    ------
    ValueError
        Components that repeat, fall outside ``[0, r)``, or values that are not finite or not
        one per component.
    """
    spec = medium.constrained_strains() if hasattr(medium, "constrained_strains") else None
    if spec is None:
        return None
    comp, val = spec
    comp = np.atleast_1d(np.asarray(comp)).astype(np.int64)
    val = np.atleast_1d(np.asarray(val, dtype=float))
    if comp.shape != val.shape or comp.ndim != 1 or len(set(comp.tolist())) != comp.size:
        raise ValueError(f"constrained_strains: {type(medium).__name__} must return distinct components and "
                         f"as many values, got components {comp.tolist()} and values {val.tolist()}")
    if np.any(comp < 0) or np.any(comp >= r) or not np.all(np.isfinite(val)):
        raise ValueError(f"constrained_strains: components must be in [0, {r}) and values finite, got "
                         f"components {comp.tolist()} and values {val.tolist()}")
    return comp, val


class StrainConstraints:
    """The constrained strain rows of a problem on a lattice.

    Parameters
    ----------
    scheme : Lattice
        The lattice (its ``edge_strains``, ``edge_nodes``, ``_key`` and ``h``).
    unknown : array of bool ``[*shape, r]``
        The node components that move (live, not clamped, not held by a
        :class:`~cartan.problem.Held` end or a :class:`~cartan.problem.Symmetry` face: a partly
        held node keeps its free components as unknowns, its held ones are fixed like a
        clamped node's).
    state : State
        A state of the lattice at which the medium's stress is probed (see
        :meth:`check_stress`).
    check : bool
        Probe the medium's stress for a dependence on a constrained component.

    Attributes
    ----------
    ncon : int
        Number of rows: constrained edges × constrained components (0 when the medium holds
        nothing fixed).
    comp, value : ndarray ``(c,)``
        The constrained components and their values.
    active : list of bool arrays ``[E_α]``
        Per axis, the edges with an unknown at either end (the others are fixed by the clamps).
    unit : float
        ``−1/cell``: the multipliers ν of the rows are ``−cell·μ``, so that the reaction on the
        unknowns is ``B_cᵀν`` (see :meth:`stress`).
    """

    def __init__(self, scheme: Any, unknown: np.ndarray, state: Any, check: bool = True):
        medium = scheme.medium
        self.sch = scheme
        self.g = scheme.group
        self.r_dim = r_dim = scheme.group.dim
        nnode = int(np.prod(scheme.grid.shape))
        flat = np.asarray(unknown, dtype=bool).reshape(nnode, r_dim)
        self.nunk = int(flat.sum())
        self.index = -np.ones((nnode, r_dim), dtype=np.int64)
        self.index[flat] = np.arange(self.nunk)
        self.comp = np.zeros(0, dtype=np.int64)
        self.value = np.zeros(0)
        self.active: list[np.ndarray] = []
        self.tails: list[np.ndarray] = []
        self.heads: list[np.ndarray] = []
        self.ghost_tails: list[np.ndarray] = []
        self.ghost_heads: list[np.ndarray] = []
        self.copy: list[np.ndarray] = []
        self.original: list[np.ndarray] = []
        self.copy_map: dict[int, np.ndarray] = {}
        self.unit = -1.0 / float(np.prod(scheme.h))
        self.ncon = 0
        spec = _constrained_spec(medium, r_dim)
        if spec is None:
            return
        comp, val = spec
        if check:  # the energy must not depend on the constrained components: their stress is the multiplier
            self.check_stress(state, comp)
        tails, heads = scheme.edge_nodes()
        live_node = flat.any(axis=1)
        self.tails, self.heads = tails, heads
        self.ghost_tails, self.ghost_heads = scheme.ghost_ends()
        self.comp, self.value = comp, val
        self._glued_copies(scheme)
        self.active = [(live_node[t] | live_node[h]) & ~copy
                       for t, h, copy in zip(tails, heads, self.copy, strict=True)]
        self.ncon = int(sum(int(a.sum()) for a in self.active)) * comp.size

    # ------------------------------------------------------------------ glued axes
    def _glued_copies(self, scheme: Any) -> None:
        """The second copies of the edges across the ends of glued axes (module docstring,
        "Glued axes"): ``copy`` per axis ``[E_α]`` bool, ``original`` ``[E_α]`` the edge each copy
        repeats (−1 elsewhere), ``copy_map`` ``{axis: T (c, c)}`` with ``X'[comp] = T X[comp]``.

        Every physical edge across an end of an axis glued half way round β is stored twice,
        on the lines i_β and i_β + n_β/2, the copies related by ``G' = ΓG⁻¹Γ``, i.e.
        ``X' = −Ad_Γ X`` (Γ² = I).  The rows are kept on the copy with ``i_β < n_β/2`` only:
        the other copy's rows are the same constraint when ``−Ad_Γ`` maps the constrained
        components onto themselves, ``X'[comp] = T X[comp]``, and ``T·value = value``
        (otherwise the two copies would hold different, generally incompatible, conditions
        on one edge: ``ValueError``)."""
        g, grid, r = self.g, scheme.grid, self.r_dim
        comp, val = self.comp, self.value
        for axis in range(grid.d):
            es = grid.edge_shape(axis)
            ne = int(np.prod(es))
            copy = np.zeros(ne, dtype=bool)
            original = -np.ones(ne, dtype=np.int64)
            if grid.is_glued(axis):
                beta = grid.glued[axis]
                half = grid.shape[beta] // 2
                M = -np.asarray(g.Ad(np.asarray(scheme._glue[axis], dtype=float)), dtype=float)  # X' = M X
                rest = np.setdiff1d(np.arange(r), comp)
                T = M[np.ix_(comp, comp)]
                scale = max(1.0, float(np.max(np.abs(val), initial=0.0)))
                if (float(np.max(np.abs(M[np.ix_(comp, rest)]), initial=0.0)) > 1e-10
                        or float(np.max(np.abs(T @ val - val), initial=0.0)) > 1e-10 * scale):
                    raise ValueError(
                        f"constrained_strains: the glue of axis {axis} (initial.glue Γ, X' = −Ad_Γ X across the "
                        f"ends) does not map the constrained components {comp.tolist()} with values "
                        f"{val.tolist()} onto themselves: the two copies of an edge across the ends would hold "
                        "different conditions")
                idx = np.arange(ne).reshape(es)
                ends = self.ghost_tails[axis] | self.ghost_heads[axis]
                upper = (np.indices(es)[beta] >= half).ravel()
                copy = ends & upper
                original[copy] = np.roll(idx, half, axis=beta).ravel()[copy]
                self.copy_map[axis] = T
            self.copy.append(copy)
            self.original.append(original)

    # ------------------------------------------------------------------ the medium's side
    def check_stress(self, state: Any, comp: np.ndarray) -> None:
        """``ValueError`` when the medium's point stress depends on a constrained component.

        The strains the lattice evaluates the stress at are probed: on a lattice with coupled
        axes (d ≥ 2, the energy at the corners) the corner strains ``[C, d, r]`` and every
        slot of their stress; otherwise each axis' edge strains with the other axes at rest
        and that axis' slot.  Each set is probed as it is and moved by a seeded random 1 %
        (a dependence that vanishes at a symmetric state, e.g. a flat plate, still shows):
        component k of each slot is moved by 1e-3·max(1, |X[k]|) and the stress must not
        change by more than 1e-9·max(1, |Q|)."""
        sch, medium = self.sch, self.sch.medium
        d, r = sch.grid.d, self.r_dim
        samples: list[tuple[np.ndarray, np.ndarray | None, list[int]]] = []
        if sch.coupled:
            _, Xc = sch._corner_strains(state)
            X0 = sch.corners()["X0"] if sch.problem.reference is not None else None
            samples.append((Xc, X0, list(range(d))))
        else:
            for axis, x in enumerate(sch.edge_strains(state)):
                _, full = sch._axis_stress(x, axis)
                X0 = sch.edge_rest_strains(axis)
                samples.append((full.reshape(-1, d, r), None if X0 is None else X0.reshape(-1, d, r), [axis]))

        def stress(X: np.ndarray, X0: np.ndarray | None) -> np.ndarray:
            with np.errstate(all="ignore"):
                return medium.stress(X) if X0 is None else medium.stress_at(X, X0)

        rng = np.random.default_rng(20240611)
        for X, X0, slots in samples:
            moved_all = X.copy()
            for a in slots:
                size = np.maximum(1.0, np.abs(X[:, a, :]))
                moved_all[:, a, :] += 1e-2 * size * rng.standard_normal(X[:, a, :].shape)
            for probe in (X, moved_all):
                q0 = stress(probe, X0)[:, slots]
                if not np.all(np.isfinite(q0)):
                    continue  # outside the medium's domain: nothing to compare
                bound = 1e-9 * max(1.0, float(np.max(np.abs(q0), initial=0.0)))
                for a in slots:
                    for k in comp:
                        moved = probe.copy()
                        moved[:, a, k] += 1e-3 * max(1.0, float(np.max(np.abs(probe[:, a, k]), initial=0.0)))
                        dq = float(np.max(np.abs(stress(moved, X0)[:, slots] - q0), initial=0.0))
                        if not dq <= bound:
                            raise ValueError(
                                f"constrained_strains: the stress of medium {medium.name!r} depends on the "
                                f"constrained strain component {int(k)} (change {dq:.3e}); a constrained "
                                "component's stress is a reaction and must not be constitutive")

    # ------------------------------------------------------------------ rows
    def values(self, state: Any, active_only: bool = True) -> np.ndarray:
        """``X_e[k] − value_k`` on the constrained edges ``(ncon,)`` (multiplier order), or with
        ``active_only=False`` on every edge ``[E, c]`` (all axes concatenated)."""
        if not self.ncon:
            return np.zeros(0) if active_only else np.zeros((0, 0))
        vals = []
        sch = self.sch  # the logarithmic edge strains (also under a pole cell's chord-length strains X″,
        # whose θ″₃ = θ₃|p|/|v| vanishes with θ₃: the rows and B_c stay those of log G/h)
        logs = [sch.group.log(state.arrays[sch._key(a)]) / sch.h[a] for a in range(sch.grid.d)]
        for x, active in zip(logs, self.active, strict=True):
            xe = x.reshape(-1, self.r_dim)[:, self.comp] - self.value
            vals.append(xe[active].ravel() if active_only else xe)
        return np.concatenate(vals) if active_only else np.concatenate(vals, axis=0)

    def matrix(self, state: Any):
        """``B_c = ∂(X_e[k])/∂δ`` ``(ncon, nunk)`` (scipy CSR): the constrained rows of the exact
        strain rate of the drift Φ_i ← Φ_i exp(δ_i), δ on the unknowns."""
        import scipy.sparse as sp

        g, sch = self.g, self.sch
        c = self.comp.size
        rows, cols, vals = [], [], []
        start = 0
        for axis, active in enumerate(self.active):
            xi = g.log(state.arrays[sch._key(axis)]).reshape(-1, self.r_dim)[active]
            h = sch.h[axis]
            ne = xi.shape[0]
            row = start + np.arange(ne * c).reshape(ne, c)
            # a ghost end (glued axis) moves by Ad_{Γ⁻¹}δ of the node it stands for (Lattice, "Glued axes")
            for node, ghost, M in ((self.tails[axis][active], self.ghost_tails[axis][active], -g.dexp_inv(xi) / h),
                                   (self.heads[axis][active], self.ghost_heads[axis][active], g.dexp_inv(-xi) / h)):
                Mk = sch.from_ghosts(M[:, self.comp, :], ghost, axis)  # [ne, c, r]
                col = self.index[node]  # [ne, r]
                cc = np.broadcast_to(col[:, None, :], Mk.shape)
                rr = np.broadcast_to(row[:, :, None], Mk.shape)
                ok = cc >= 0
                rows.append(rr[ok])
                cols.append(cc[ok])
                vals.append(Mk[ok])
            start += ne * c
        if not rows:
            return sp.csr_matrix((self.ncon, self.nunk))
        vals = np.concatenate(vals)
        pattern = self.__dict__.get("_pattern")
        if pattern is None:  # the sparsity is fixed by the edges and the unknowns: sort it once
            rows, cols = np.concatenate(rows), np.concatenate(cols)
            order = np.lexsort((cols, rows))
            indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=self.ncon))])
            pattern = self._pattern = (order, cols[order], indptr)
        order, indices, indptr = pattern
        return sp.csr_matrix((vals[order], indices, indptr), shape=(self.ncon, self.nunk))

    def fixed_rate(self, state: Any, N: np.ndarray) -> np.ndarray:
        """``(ncon,)``: the rows' rate from the velocity ``N`` ``[*shape, r]`` of the node
        components that are not unknowns (a :class:`~cartan.problem.Driven` end's ξ; zero on
        clamped nodes and held components; N is read there only), the columns :meth:`matrix`
        leaves out: ``B_c N_full = matrix·N[unknown] + fixed_rate(N)``."""
        g, sch = self.g, self.sch
        Nf = np.asarray(N, dtype=float).reshape(-1, self.r_dim)
        fixed = np.where(self.index < 0, Nf, 0.0)
        out = []
        for axis, active in enumerate(self.active):
            xi = g.log(state.arrays[sch._key(axis)]).reshape(-1, self.r_dim)[active]
            h = sch.h[axis]
            rate = np.zeros((xi.shape[0], self.comp.size))
            for node, ghost, M in ((self.tails[axis][active], self.ghost_tails[axis][active], -g.dexp_inv(xi) / h),
                                   (self.heads[axis][active], self.ghost_heads[axis][active], g.dexp_inv(-xi) / h)):
                Mk = sch.from_ghosts(M[:, self.comp, :], ghost, axis)  # [ne, c, r]
                rate += np.einsum("ecr,er->ec", Mk, fixed[node])
            out.append(rate.ravel())
        return np.concatenate(out) if out else np.zeros(0)

    def fixed_force(self, state: Any, nu: np.ndarray) -> np.ndarray:
        """``[nnode, r]``: the nodal force ``B_cᵀν`` of the multipliers ``nu`` ``(ncon,)`` on the
        node components that are not unknowns (zero on the unknowns; the transpose of
        :meth:`fixed_rate`): the constraint force the supports balance (clamped and
        :class:`~cartan.problem.Driven` nodes, held components)."""
        g, sch = self.g, self.sch
        out = np.zeros(self.index.shape)
        start = 0
        for axis, active in enumerate(self.active):
            xi = g.log(state.arrays[sch._key(axis)]).reshape(-1, self.r_dim)[active]
            h = sch.h[axis]
            n = xi.shape[0] * self.comp.size
            lam = np.asarray(nu[start:start + n]).reshape(-1, self.comp.size)
            start += n
            for node, ghost, M in ((self.tails[axis][active], self.ghost_tails[axis][active], -g.dexp_inv(xi) / h),
                                   (self.heads[axis][active], self.ghost_heads[axis][active], g.dexp_inv(-xi) / h)):
                Mk = sch.from_ghosts(M[:, self.comp, :], ghost, axis)  # [ne, c, r]
                scatter_add(out, node, np.einsum("ecr,ec->er", Mk, lam))
        out[self.index >= 0] = 0.0
        return out

    # ------------------------------------------------------------------ multipliers
    def stress(self, nu: np.ndarray, edge_shapes: list[tuple[int, ...]]) -> list[np.ndarray]:
        """Per axis, the edge stresses ``[*edge_shape, r]`` whose constrained components are
        ``unit·ν`` (zero elsewhere) for the row multipliers ``nu`` ``(ncon,)``: μ = −ν/cell, the
        edge stresses whose reaction ``−cell·B_cᵀμ`` is ``B_cᵀν``."""
        out, start = [], 0
        c = self.comp.size
        for shape_e, active in zip(edge_shapes, self.active, strict=True):
            Q = np.zeros((int(np.prod(shape_e[:-1])), self.r_dim))
            n = int(active.sum()) * c
            Q[np.ix_(np.flatnonzero(active), self.comp)] = nu[start:start + n].reshape(-1, c) * self.unit
            start += n
            out.append(Q.reshape(shape_e))
        return out

    def edge_multipliers(self, nu: np.ndarray, edge_shapes: list[tuple[int, ...]]) -> np.ndarray:
        """The edge stresses of :meth:`stress` on every edge ``[E, c]`` (NaN on edges between
        fixed nodes).  The second copy of an edge across the ends of a glued axis (which holds
        no row, :meth:`_glued_copies`) shows its original's, seen from the copy:
        ``T⁻ᵀ μ`` (the same work on ``X'[comp] = T X[comp]``)."""
        rows = []
        for axis, (Q, active) in enumerate(zip(self.stress(nu, edge_shapes), self.active, strict=True)):
            q = Q.reshape(-1, self.r_dim)[:, self.comp].copy()
            q[~active] = np.nan
            copy = self.copy[axis] if self.copy else None
            if copy is not None and np.any(copy):
                orig = self.original[axis][copy]
                q[copy] = np.where(active[orig][:, None], q[orig] @ np.linalg.inv(self.copy_map[axis]), np.nan)
            rows.append(q)
        return np.concatenate(rows, axis=0)


class NodalStrainConstraints:
    """The constrained strain rows of a problem on the ``collocation`` scheme: one row per node,
    axis and held component of the stored nodal strains (paper §III, §III.E).

    The collocation scheme carries the strains X_α as state and drifts them by the
    compatibility equation of §III, ``∂_tX_α = ∂_αN + ad_{X_α}N`` (its exact Lie group
    integrator, §V), with ∂_α the scheme's difference operator D_α.  The rows

        c_{i,α,k}(X) = X_{α,i}[k] − value_k

    are linear in the state, and their rate along the drift Φ ← Φ exp(εδ) is linear in δ,

        B_c δ = [D_α δ + ad_{X_α} δ]_{i,k}        (exact: X(ε)′ at ε = 0),

    as is its rate along the drift with N fixed, ``Ḃ_c N = [ad_{D_αN + ad_{X_α}N} N]_{i,k}``
    (exact too: B_c depends on X through ad_X only).  The reaction ``B_cᵀν`` of the multipliers
    is the collocation's internal force of a stress whose held components are ``−ν/w_i`` (the
    scheme's force is ``−Lᵀ(wQ)/w`` with summation by parts, L = D + ad_X): ν is the fictitious
    stress of §IV.E times ``−w_i``.

    A row is kept when its stencil (the nodes D_α reads and the node itself) holds an unknown;
    a row whose columns are all fixed (between clamped nodes) keeps its value.  The interface
    is :class:`StrainConstraints`' (``ncon``, ``comp``, ``value``, :meth:`values`,
    :meth:`matrix`, :meth:`fixed_rate`, :meth:`fixed_force`) plus :meth:`rows_rate`, so
    ``rattle`` takes either.

    Rank.  Along an open axis a central D has one more row than independent tangential
    velocities (n rows, rank n − 1 of D restricted to the free nodes: its left null vector is
    the odd–even pattern of a collocated grid), so at a straight configuration the rows of the
    stretch component are dependent, and near one the multiplier systems are ill-conditioned
    (smallest singular value ≈ |κ|/4 at n = 11, κ the curvature in the plane of the motion).
    The rows held are therefore ``Tᵀc``: the nodal rows less their combinations that are
    dependent at the reference strains (the translation part of the medium's rest strain, the
    rotation part zero, X[comp] = value: straight and untwisted, or flat; :func:`_uncurved_reference`),
    found once by an SVD, T sparse (:func:`_complement`).  ``ncon`` counts the held rows,
    ``nrow`` the nodal ones; the combination left out (the stretch's odd–even ripple) is a
    discretization error, second order in h (docs/integrators.md, "rattle on the collocation
    scheme").  The multipliers ν are those of the held rows; ``Tν`` the nodal ones.

    The SVD takes the live components of every node as columns, whatever the supports: the
    combinations left out are the operator's own (the odd–even mode of each open line, the
    same with clamped, free and :class:`~cartan.problem.Held` ends or
    :class:`~cartan.problem.Symmetry` faces).  A dependence that only the supports add at the
    straight reference — between two ends that hold the translations, the weighted stretch
    Σ w(X₁ − 1), the length between them — is a real constraint on a slack (curved) shape and
    stays held (leaving it out would let the length drift: 2.6e-4 of uniform stretch in
    t = 0.4 on a clamped–clamped arc at n = 11); the multiplier system is then singular at a
    straight shape between such supports, as the lattice's.

    On a surface (d = 2, ``kirchhoff-love``: θ_α,3 held) the flat reference θ_u = e₁,
    θ_v = e₂ puts a rotation of the node itself in each row (row (i, u) reads ω₂, row (i, v)
    ω₁, through ``ad_{θ_α}``), so no combination is dependent and all 2·nnode rows are held
    (T is None).  The SVD is dense, O(nrow²·nnode): its singular values take 0.2 s at 9², 2.0 s
    at 17², 43 s at 33² nodes (one core; docs/media/kirchhoff-love.md, "rattle on the
    collocation scheme").

    Parameters
    ----------
    scheme : Collocation
        The scheme (its ``D``, ``grid``, ``group``).
    unknown : array of bool ``[*shape, r]``
        The node components that move (live, not clamped, not held by a
        :class:`~cartan.problem.Held` end or a :class:`~cartan.problem.Symmetry` face).
    state : State
        A state of the scheme at which the medium's stress is probed (the stress must not
        depend on a constrained component).
    check : bool
        Probe the medium's stress.

    Attributes
    ----------
    ncon : int
        Number of held rows (``nrow`` less the dependent combinations).
    nrow : int
        Number of nodal rows (active (node, axis) pairs × held components).
    T : scipy sparse ``(nrow, ncon)`` or None
        The held combinations of the nodal rows (None: all of them, independent).
    comp, value : ndarray ``(c,)``
        The constrained components and their values.
    active : bool array ``[nnode, d]``
        The (node, axis) pairs whose rows are held.
    """

    #: :meth:`rows_rate` is exact (rattle's force-level multipliers take it as it is)
    exact_rate = True

    def __init__(self, scheme: Any, unknown: np.ndarray, state: Any, check: bool = True):
        import scipy.sparse as sp

        medium = scheme.medium
        self.sch = scheme
        self.g = scheme.group
        self.r_dim = r = scheme.group.dim
        grid = scheme.grid
        d = grid.d
        nnode = int(np.prod(grid.shape))
        flat = np.asarray(unknown, dtype=bool).reshape(nnode, r)
        self.unknown_flat = flat.ravel()
        self.nunk = int(flat.sum())
        self.index = -np.ones((nnode, r), dtype=np.int64)
        self.index[flat] = np.arange(self.nunk)
        self.comp = np.zeros(0, dtype=np.int64)
        self.value = np.zeros(0)
        self.active = np.zeros((nnode, d), dtype=bool)
        self.ncon = self.nrow = 0
        self.T = None
        spec = _constrained_spec(medium, r)
        if spec is None:
            return
        comp, val = spec
        if check:
            self.check_stress(state, comp)
        self.comp, self.value = comp, val
        # per axis, D_α on the flattened nodes (C order): kron(I, D_α, I)
        self._D = []
        for axis, D in enumerate(scheme.D):
            mats = [sp.identity(int(m), format="csr") for m in grid.shape]
            mats[axis] = sp.csr_matrix(D.matrix())
            full = mats[0]
            for m in mats[1:]:
                full = sp.kron(full, m, format="csr")
            self._D.append(full.tocsr())
        live_node = flat.any(axis=1).astype(float)
        for axis, Dm in enumerate(self._D):
            reach = (abs(Dm) @ live_node) > 0.0
            self.active[:, axis] = reach | (live_node > 0.0)
        self.ncon = int(self.active.sum()) * comp.size
        c = comp.size
        # the rows' pattern (node, axis, comp) → multiplier index, and the D part of B_c (fixed)
        self._rowid = -np.ones((nnode, d, c), dtype=np.int64)
        self._rowid[self.active] = np.arange(self.ncon).reshape(-1, c)
        rows, cols, vals = [], [], []
        for axis, Dm in enumerate(self._D):
            coo = Dm.tocoo()
            keep = self.active[coo.row, axis]
            i, j, v = coo.row[keep], coo.col[keep], coo.data[keep]
            for kk, k in enumerate(comp):
                rows.append(self._rowid[i, axis, kk])
                cols.append(j * r + k)
                vals.append(v)
        self._Dpart = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                    shape=(self.ncon, nnode * r))
        # the ad part's pattern: row (i, α, k) with every component of node i
        ia = np.argwhere(self.active)  # [na, 2]: (node, axis)
        self._ad_rows = np.repeat(self._rowid[ia[:, 0], ia[:, 1]][:, :, None], r, axis=2)  # [na, c, r]
        self._ad_cols = np.broadcast_to((ia[:, 0] * r)[:, None, None] + np.arange(r), self._ad_rows.shape)
        self._ia = ia
        # the held combinations: the nodal rows less their dependent ones at the reference strains
        # (the medium's rest strains without curvature: straight, untwisted, flat; X[comp] = value:
        # the odd–even modes), on the live components of every node, supports or not ("Rank": a
        # dependence the supports add is physical and kept)
        self.nrow = self.ncon
        Xref = np.broadcast_to(_uncurved_reference(medium, self.g, d, r), (nnode, d, r)).copy()
        Xref[..., comp] = val
        live_cols = np.tile(np.asarray(scheme.live, dtype=bool).reshape(-1), nnode)
        _announce_dense_rank(self.nrow)
        Bref = self._full(Xref)[:, live_cols].toarray()
        # the singular values first (no vectors: a third of the time); the left singular vectors
        # only when some combination is dependent (all of them when B_ref has fewer columns)
        sv = np.linalg.svd(Bref, compute_uv=False)
        rank = int(np.sum(sv > 1e-10 * (sv[0] if sv.size else 0.0)))
        if rank < self.nrow:
            U = np.linalg.svd(Bref, full_matrices=Bref.shape[0] > Bref.shape[1])[0]
            self.T = _complement(U[:, rank:])  # (nrow, ncon) sparse: the independent combinations
            self.ncon = rank

    def check_stress(self, state: Any, comp: np.ndarray) -> None:
        """``ValueError`` when the medium's point stress at the nodal strains ``[*, d, r]`` depends
        on a constrained component (probed as they are and moved by a seeded random 1 %, each
        held component moved by 1e-3·max(1, |X[k]|); bound 1e-9·max(1, |Q|))."""
        medium, sch = self.sch.medium, self.sch
        X = np.asarray(sch.nodal_strains(state), dtype=float)
        X = X.reshape(-1, *X.shape[-2:])
        rest = sch.nodal_rest_strains()
        X0 = None if rest is None else np.asarray(rest, dtype=float).reshape(X.shape)

        def stress(Y: np.ndarray) -> np.ndarray:
            with np.errstate(all="ignore"):
                return medium.stress(Y) if X0 is None else medium.stress_at(Y, X0)

        rng = np.random.default_rng(20240611)
        moved_all = X + 1e-2 * np.maximum(1.0, np.abs(X)) * rng.standard_normal(X.shape)
        for probe in (X, moved_all):
            q0 = stress(probe)
            if not np.all(np.isfinite(q0)):
                continue
            bound = 1e-9 * max(1.0, float(np.max(np.abs(q0), initial=0.0)))
            for k in comp:
                moved = probe.copy()
                moved[..., k] += 1e-3 * max(1.0, float(np.max(np.abs(probe[..., k]), initial=0.0)))
                dq = float(np.max(np.abs(stress(moved) - q0), initial=0.0))
                if not dq <= bound:
                    raise ValueError(
                        f"constrained_strains: the stress of medium {medium.name!r} depends on the constrained "
                        f"strain component {int(k)} (change {dq:.3e}); a constrained component's stress is a "
                        "reaction and must not be constitutive")

    # ------------------------------------------------------------------ rows
    def _X(self, state: Any) -> np.ndarray:
        """The nodal strains ``[nnode, d, r]``."""
        return np.asarray(self.sch.nodal_strains(state), dtype=float).reshape(-1, self.sch.grid.d, self.r_dim)

    def nodal_values(self, state: Any) -> np.ndarray:
        """``X_{α,i}[k] − value_k`` on every row of the active (node, axis) pairs ``(nrow,)``
        (order: node, axis, component)."""
        if not self.ncon:
            return np.zeros(0)
        return (self._X(state)[..., self.comp] - self.value)[self.active].ravel()

    def values(self, state: Any, active_only: bool = True) -> np.ndarray:
        """The held rows ``(ncon,)``: ``Tᵀ(X_{α,i}[k] − value_k)`` (T the independent
        combinations, the identity when the nodal rows are independent), or with
        ``active_only=False`` the nodal rows on every (node, axis) ``[nnode·d, c]``."""
        if not self.ncon:
            return np.zeros(0) if active_only else np.zeros((0, 0))
        if not active_only:
            return (self._X(state)[..., self.comp] - self.value).reshape(-1, self.comp.size)
        c = self.nodal_values(state)
        return c if self.T is None else self.T.T @ c

    def _full(self, X: np.ndarray):
        """The nodal rows' ``B`` on every node component ``(nrow, nnode·r)`` at the strains X
        ``[nnode, d, r]`` (scipy CSR): ``[D_α δ + ad_{X_α} δ]_{i,k}``."""
        import scipy.sparse as sp

        ia = self._ia
        adx = self.g.ad(X[ia[:, 0], ia[:, 1]])[:, self.comp, :]  # [na, c, r]
        ad = sp.csr_matrix((adx.ravel(), (self._ad_rows.ravel(), self._ad_cols.ravel())),
                           shape=self._Dpart.shape)
        return (self._Dpart + ad).tocsr()

    def full_matrix(self, state: Any):
        """``B_c`` of the held rows on every node component ``(ncon, nnode·r)`` (scipy CSR):
        ``Tᵀ[D_α δ + ad_{X_α} δ]_{i,k}``."""
        import scipy.sparse as sp

        B = self._full(self._X(state))
        return B if self.T is None else sp.csr_matrix(self.T.T @ B)

    def matrix(self, state: Any):
        """``B_c`` ``(ncon, nunk)`` (scipy CSR): the rows' exact rate along the drift
        Φ_i ← Φ_i exp(δ_i), δ on the unknowns."""
        return self.full_matrix(state)[:, self.unknown_flat].tocsr()

    def fixed_rate(self, state: Any, N: np.ndarray) -> np.ndarray:
        """``(ncon,)``: the rows' rate from the velocity ``N`` ``[*shape, r]`` of the components
        that are not unknowns (zero on clamped nodes: N is read there only)."""
        Nf = np.asarray(N, dtype=float).reshape(-1)
        fixed = np.where(self.unknown_flat, 0.0, Nf)
        if not self.ncon or not fixed.any():
            return np.zeros(self.ncon)
        return self.full_matrix(state) @ fixed

    def fixed_force(self, state: Any, nu: np.ndarray) -> np.ndarray:
        """``[nnode, r]``: ``B_cᵀν`` on the components that are not unknowns (zero on the
        unknowns), ν ``(ncon,)`` the held rows' multipliers: the constraint force the supports
        balance (clamped nodes, held components), an impulse per unit time like ``wW`` (the
        rows' force on a support node is the weak form ``Lᵀ`` of the nodal multipliers ``Tν``,
        L = D_α + ad_{X_α}; :meth:`Rattle.support_reaction
        <cartan.integrators.constrained.Rattle.support_reaction>` subtracts it)."""
        out = np.zeros(self.index.shape)
        if self.ncon:
            out = (self.full_matrix(state).T @ np.asarray(nu, dtype=float)).reshape(self.index.shape)
        out[self.index >= 0] = 0.0
        return out

    def rows_rate(self, state: Any, N: np.ndarray) -> np.ndarray:
        """``Ḃ_c N`` ``(ncon,)``, exact: the rows' second derivative along the drift
        Φ ← Φ exp(εN), N ``[*shape, r]`` constant, ``[ad_{Ẋ_α} N]_{i,k}`` with
        ``Ẋ_α = D_αN + ad_{X_α}N`` (the compatibility equation, paper §III)."""
        if not self.ncon:
            return np.zeros(0)
        g, r = self.g, self.r_dim
        X = self._X(state)
        Nf = np.asarray(N, dtype=float).reshape(-1, r)
        out = np.zeros(X.shape[:2] + (self.comp.size,))
        for axis, Dm in enumerate(self._D):
            Xdot = Dm @ Nf + g.bracket(X[:, axis, :], Nf)
            out[:, axis, :] = g.bracket(Xdot, Nf)[:, self.comp]
        out = out[self.active].ravel()
        return out if self.T is None else self.T.T @ out

    def stress(self, nu: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """The nodal stresses ``[nnode, d, c]`` of the held components, ``−ν/w_i`` (NaN on the
        rows not held): the fictitious stress of §IV.E whose collocation force is ``B_cᵀν``."""
        out = np.full((*self.active.shape, self.comp.size), np.nan)
        w = np.asarray(weights, dtype=float).reshape(-1)
        nodal = np.asarray(nu, dtype=float) if self.T is None else self.T @ np.asarray(nu, dtype=float)
        out[self.active] = -nodal.reshape(-1, self.comp.size) / w[np.nonzero(self.active)[0]][:, None]
        return out


#: nodal rows above which the dense rank test is announced (≈ 10 s on one core), and the most it takes
#: (≈ 10 min: its cost grows as the rows cubed; docs/media/kirchhoff-love.md)
DENSE_RANK_NOTE_ROWS, DENSE_RANK_MAX_ROWS = 1500, 6000


def _announce_dense_rank(nrow: int) -> None:
    """A line on stderr before a long dense rank test of ``nrow`` nodal rows; ``ValueError`` above
    :data:`DENSE_RANK_MAX_ROWS`."""
    import sys

    if nrow > DENSE_RANK_MAX_ROWS:
        raise ValueError(f"integrator 'rattle' on the collocation scheme: {nrow} nodal constraint rows, above the "
                         f"{DENSE_RANK_MAX_ROWS} its dense rank test takes (a cost that grows as the rows cubed); "
                         "use scheme='lattice' or a coarser grid")
    if nrow > DENSE_RANK_NOTE_ROWS:
        print(f"cartan: rattle on the collocation scheme: the rank of {nrow} nodal constraint rows by a dense SVD "
              f"(about {43.0 * (nrow / 2178.0) ** 3:.0f} s on one core)", file=sys.stderr, flush=True)


def _uncurved_reference(medium: Any, group: Any, d: int, r: int) -> np.ndarray:
    """The reference strains ``(d, r)`` of :class:`NodalStrainConstraints`' rank test: the
    translation part of the medium's rest strain (the chart's metric: ``θ_α = e_α`` on a flat
    plate, the tangent of a rod), the rotation part (the curvatures) zero; zero on a group
    without translations."""
    ref = np.zeros((d, r))
    if getattr(group, "affine", False):
        k = int(group.space_dim)
        ref[:, :k] = np.asarray(medium.rest_strain(), dtype=float).reshape(d, r)[:, :k]
    return ref


def _complement(Y: np.ndarray):
    """``T`` ``(nrow, nrow − m)`` (scipy CSC) whose columns span the complement of the dependent
    combinations ``Y`` ``(nrow, m)`` (orthonormal): ``Tᵀc = 0`` exactly when c ∈ span Y.

    When the columns of Y have disjoint supports (the odd–even mode of each open line of nodes,
    nonzero at each of its rows), T is sparse: the rows off the supports as they are, and along
    each support s₀ < s₁ < … the chain ``(y[s_{t+1}] c[s_t] − y[s_t] c[s_{t+1}])/|(y[s_t],
    y[s_{t+1}])|`` (two nonzeros per column: the held rows stay banded).  Otherwise the dense
    orthonormal complement."""
    import scipy.sparse as sp

    nrow, m = Y.shape
    tol = 1e-8 * float(np.max(np.abs(Y), initial=0.0))
    support = np.abs(Y) > tol
    if np.all(support.sum(axis=1) <= 1):  # disjoint supports: the chains
        rows, cols, vals = [], [], []
        col = 0
        off = np.flatnonzero(~support.any(axis=1))
        rows.append(off)
        cols.append(np.arange(off.size))
        vals.append(np.ones(off.size))
        col = off.size
        for j in range(m):
            idx = np.flatnonzero(support[:, j])
            a, b = idx[:-1], idx[1:]
            ya, yb = Y[a, j], Y[b, j]
            norm = np.hypot(ya, yb)
            k = col + np.arange(a.size)
            rows += [a, b]
            cols += [k, k]
            vals += [yb / norm, -ya / norm]
            col += a.size
        if col == nrow - m:
            return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                 shape=(nrow, col))
    full = np.linalg.svd(Y, full_matrices=True)[0][:, m:]
    return sp.csc_matrix(full)
