"""The ``lattice`` scheme: a discrete Lie-group lattice (ARCHITECTURE.md §3, scheme 1).

Nodes carry the momentum density S_i (and the frames Φ_i when a force needs them); each
edge e = (i → j) along axis α carries the group element ``G_e = exp(hX_e) = Φ_i⁻¹Φ_j``.

Drift
    The motion Φ_i ← Φ_i D_i of every node updates the edges by conjugation,
    ``G_e ← D_i⁻¹ G_e D_j`` — the exact discrete form of Ẋ = ∂N + [X, N] (paper §III.B).
    Temporal integrability, ring closure ∏G_e = I and plaquette holonomies are therefore
    preserved to round-off, whatever the time step.
Forces
    From the variation of the discrete potential ``V = Σ_e h U(X_e)`` with
    ``hX_e = log G_e``: under Φ_i → Φ_i exp(εη_i),
    ``δX_e = [dexp⁻¹_{−hX_e} η_j − dexp⁻¹_{hX_e} η_i]/h``, so the generalised force on node i
    is ``F_i = Σ_{e out of i} dexp⁻¹_{hX_e}ᵀ Q_e − Σ_{e into i} dexp⁻¹_{−hX_e}ᵀ Q_e`` with
    ``Q_e = ∂U/∂X(X_e)``; divided by the node weight it tends to ∂_uQ + ad*_X Q.  The
    semi-discrete system is Hamiltonian with the exact discrete energy V + Σ w_i K(N_i);
    second order in space.
Frames
    Φ is stepped at every node only when the problem needs it (potential loads, dead end
    loads); otherwise only the root node's frame is stepped and Φ is rebuilt from the edges
    at output times (paper §V, "model no more than a scene needs").  ``track_frames=True``
    forces stepping, e.g. to measure the integrability residual against independent frames.

Energies in d ≥ 2
    A potential additive over the axes (``medium.separable_axes = True``) is summed over the
    edges as above, each edge's strain with the other axes at rest.  Any other potential — one
    that couples the axes, like a shell's membrane energy — is evaluated at the **corners** of
    the lattice: at node i, every choice of one incident edge per axis (the edge before or
    after i along α, those that exist) gives a strain ``X_c = (X_{e_1}, …, X_{e_d})``, and
    ``V = Σ_i (w_i / #corners_i) Σ_c U(X_c)``, the analogue of full (2^d-point) quadrature,
    without the zero-energy modes of a one-point cell average.  The forces are its exact
    gradient: each corner's stress goes back to its d edges, and from the edges to the nodes
    through dexp⁻¹ as above.  For d = 1 both forms are the edge sum.
Rest strains
    A problem with a stress-free ``reference`` configuration Φ_ref has the rest strain
    ``X₀_e = log(Φ_ref,i⁻¹Φ_ref,j)/h`` on each edge (exactly stress-free on the lattice);
    otherwise the medium's constant ``rest_strain()``.
Charts
    The grid is a chart of the body; the energy is summed with the chart's quadrature weights
    (:attr:`chart_weights`, the grid's).  When the medium measures the reference volume of a
    general chart (:meth:`~cartan.medium.Medium.reference_volume` at the nodal rest strains,
    J_i), a node's mass, body loads and kinetic energy are those of its reference volume
    ``weights = w_i J_i``, and a face load (per unit reference area) is integrated with the
    face's reference area element (:meth:`~cartan.medium.Medium.reference_area`); media that
    return None (the default) keep ``weights = w_i`` and the chart's face areas.
Glued axes (closed surfaces over poles)
    On an axis α glued across a periodic axis β (:class:`~cartan.grid.Grid` ``glued``, the
    sphere's colatitude), each line along α has n + 1 edges: edge 0 comes from the ghost of its
    first node — the node of the line half way round β, seen in the frame Φ_j'Γ with Γ the
    state's constant ``glue`` — and edge n goes to the ghost of its last node, so
    ``G_e = Φ_i⁻¹Φ_j'Γ`` (or ``Γ⁻¹Φ_j'⁻¹Φ_i``).  Every physical edge across an end is stored
    twice, once per line, the two copies related by G' = ΓG⁻¹Γ and kept so by the drift,
    which moves a ghost by ``Γ⁻¹D_j'Γ``.  A node's corners take, along α, the two edges it is a
    genuine end of, so every node has the full set of corners (no pole row is special); the
    force a stored edge puts on a ghost end goes to the node it stands for through
    ``Ad_{Γ⁻¹}ᵀ`` (the ghost moves by Φ_j'Γ exp(Ad_{Γ⁻¹}η)).  The glued edges close loops as a
    periodic closing edge does: frames are rebuilt from the interior edges only, and the
    plaquettes across an end (ghost edges Γ⁻¹G Γ) enter the integrability residual.  Glued
    problems run on this numpy path (the compiled loops and operators decline them).
Poles (``pole="cap"``)
    On a coupled d = 2 SE(3) lattice with a glued axis and a reference, ``Lattice(problem,
    pole="cap")`` replaces the 2N corners per pole that use a glued edge by a pole cell whose
    energy is the medium's own density at a pole strain fitted to the pole's N glued edges, and
    gives every edge the chord-length strain X″ = (θ|p|/|v|, π) (:mod:`cartan.schemes._pole_cell`;
    the forces stay the exact gradient).  The default ``"corners"`` is the scheme above.

Compiled loops
    The generated loops (:meth:`cartan.integrators.base.Integrator.run_compiled_loop` over the
    operators of :mod:`cartan.schemes._lattice_ops`, :meth:`Lattice.compiled_operators`) run
    whole blocks of steps in numba for every group with point kernels and every medium that
    declares them, d = 1, 2, 3, with clamped, free (loaded) and held ends or faces
    (:class:`~cartan.problem.Held`, :class:`~cartan.problem.Symmetry`: the operators' ``held``
    mask, :meth:`_clamp_mask`), and driven ends (:class:`~cartan.problem.Driven`: the driven
    nodes' ξ and ∂K/∂N(ξ) in the operators' data, in the loops of ``lie-verlet``, ``lie-euler``,
    ``rkmk4``, ``overdamped``, ``rattle`` and ``implicit-midpoint`` only, serially).
    SE(3) rods (d = 1) with a quadratic potential and loads that
    are data (damping, body-frame uniform force, constant-field potentials, end loads,
    clamps) run ``lie-verlet`` and ``overdamped`` (order 1) in the hand-written
    structure-of-arrays loops of :meth:`Lattice.compiled_advance`
    (:mod:`cartan.schemes._lattice_compiled`), on threads when ``CARTAN_THREADS`` allows.
    Everything else stays on this module's numpy path, the reference both are tested against
    (``docs/performance.md``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..problem import Free, axis_glues, axis_holonomies, dead_to_body
from ..scatter import scatter_add
from .base import Scheme, State, prefix_products

__all__ = ["Lattice"]


class Lattice(Scheme):
    """Discrete Lie-group lattice, generic over the group and the medium."""

    name = "lattice"
    plan_module = "_lattice_compiled"
    diagnostics_module = "_lattice_diagnostics"
    order = 2
    strain_location = "edge"
    supports_coupled_lagrangian = True  # d = 1: cartan.schemes._coupled
    supports_driven_ends = True  # cartan.Driven: numpy path, and the generated loops (compiled_operators)
    gives_raw_force = True

    #: the treatment of a glued chart's poles (``"corners"`` or ``"cap"``: module docstring)
    pole = "corners"

    def __init__(self, problem, track_frames: bool | None = None, pole: str = "corners"):
        super().__init__(problem)
        if self._clamped.ndim > self.grid.d and self.coupled_lagrangian:
            raise ValueError("a Symmetry face or a Held end is not supported with a coupled Lagrangian "
                             "(Medium.coupled_lagrangian)")
        self.track = problem.needs_structure_field if track_frames is None else bool(track_frames)
        d = self.grid.d
        #: True when the potential is evaluated at the corners (d ≥ 2, axes coupled)
        self.coupled = d > 1 and not getattr(self.medium, "separable_axes", False)
        self.h = self.grid.spacing
        #: per glued axis, (Γ of the initial state, Γ of the reference): see "Glued axes"
        self._glue = axis_glues(problem.initial)
        self._glue_ref = axis_glues(problem.reference) if problem.reference is not None else {}
        if pole != "corners":
            from ._pole_cell import check_pole

            self.pole = check_pole(self, pole)
        #: the energy's quadrature weights (the grid's, per unit chart volume); :attr:`weights`
        #: are the nodes' reference volumes (mass, body loads), equal to them unless the medium
        #: measures a general chart (module docstring, "Charts")
        self.chart_weights = self.weights
        self._end_loads = []  # (index tuple, Free)
        for axis in range(d):
            if self.grid.periodic[axis] or self.grid.is_glued(axis):
                continue
            for side, idx in (("start", 0), ("end", -1)):
                b = problem.boundary(axis, side)
                if isinstance(b, Free) and b.load is not None:
                    sl = [slice(None)] * d
                    sl[axis] = idx
                    self._end_loads.append((tuple(sl), b))
        #: per loaded face: None, or its nodes' reference area per unit chart area over their
        #: reference volume per unit chart volume (a face load's density is P·factor/(h_α/2))
        self._end_factors: list[np.ndarray | None] = [None] * len(self._end_loads)
        self._chart_measures()

    def _chart_measures(self) -> None:
        """Node reference volumes and face-load factors of a general chart (module docstring)."""
        from ..medium import Medium

        # the nodal rest strains (a log per edge) only for media that measure their chart
        if self.problem.reference is None or type(self.medium).reference_volume is Medium.reference_volume:
            return
        X0 = self.nodal_rest_strains()
        J = self._reference_volumes(X0)
        if J is None:
            return
        if not np.all(J == 1.0):  # the chart's own measure (an orthonormal chart) keeps the weights to the bit
            self.weights = self.chart_weights * J
            for load in self.problem.loads:  # point loads take their node's volume (Load.measure)
                load.measure(self.weights)
        for k, (idx, _) in enumerate(self._end_loads):
            A = self.medium.reference_area(X0[idx], self._end_axis(idx))
            factor = (np.ones(J[idx].shape) if A is None else np.asarray(A, dtype=float)) / J[idx]
            self._end_factors[k] = None if np.all(factor == 1.0) else factor

    def end_load_density(self, k: int, P: np.ndarray) -> np.ndarray:
        """The force density of the loaded face ``k`` (of ``_end_loads``) under the load P per
        unit reference area (body components ``[*face, r]``): ``P/(h_α/2)`` on the chart's own
        measure, times the face's chart factor otherwise."""
        idx, _ = self._end_loads[k]
        half = 0.5 * self.h[self._end_axis(idx)]
        factor = self._end_factors[k]
        return P / half if factor is None else P * factor[..., None] / half

    def options(self) -> dict[str, Any]:
        if self.pole != "corners":
            return {"track_frames": self.track, "pole": self.pole}
        return {"track_frames": self.track}

    # ------------------------------------------------------------------ compiled loops
    def compiled_advance(self, integrator, state: State, dt: float, nsteps: int, *,
                         kinetic_limit: float = math.inf) -> bool:
        """Advance ``state`` in place by up to ``nsteps`` steps of ``integrator`` in compiled code.

        Returns False, leaving everything untouched, when the combination is not supported
        (the caller then offers the steps to the generated loops, then runs ``integrator.step``
        in Python): these loops take SE(3) rods (d = 1) with a quadratic potential
        (``quadratic_energy()``), damping, body-frame uniform forces, constant-field
        potentials, free and clamped ends, stepped by ``lie-verlet`` (every free-flow piece in
        closed form: no zero inertia) or ``overdamped`` of order 1 (``docs/performance.md``);
        the numpy backend always declines.  An integrator these loops never take (``rattle``,
        ``rkmk4``, …: :func:`cartan.schemes._lattice_compiled.may_run`, its type and name only) is
        declined at once, before the plan is built, at each of the run's save blocks.  With ``CARTAN_THREADS`` (or
        :func:`cartan.set_threads`) above 1 and a rod of at least ``cartan._threads.MIN_NODES``
        nodes the loops run on threads, with the same results.

        When it returns True the steps were taken exactly as ``integrator.step`` takes them
        (same formulas, agreement to round-off): ``state.t``, ``state.scalars`` (energy
        accumulators by the trapezoidal rule, ``"nstep"``) and the integrator's counters
        (``nstep``, ``nforce``, ``wall_time``) and caches are updated as the Python loop would.
        The loop stops early after the first step whose momentum (or, for integrators without
        momentum, configuration) is not finite, or whose kinetic energy ``½Σ w S²/m`` exceeds
        ``kinetic_limit``; the number of steps done is the increase of ``state.scalars["nstep"]``.
        """
        if self._glue or self._driven is not None:
            return False  # glued axes run on the numpy path, driven ends in the generated loops (module docstring)
        # (the plan module's may_run declines rattle, rkmk4, … before any plan is built)
        return self._run_compiled(self.plan_module, integrator, state, dt, nsteps, kinetic_limit)

    def compiled_operators(self):
        """The lattice's compiled operators (:mod:`cartan.schemes._lattice_ops`): any group
        with point kernels, any medium that declares point kernels, d = 1–3, damping,
        body-frame uniform forces, free (loaded) and clamped ends or faces, held components
        (:class:`~cartan.problem.Held` ends, :class:`~cartan.problem.Symmetry` faces: the
        operators' ``held`` mask, :meth:`_clamp_mask`) and :class:`~cartan.problem.Driven` ends
        (their nodes, ξ and ∂K/∂N(ξ) in the data; a set that serves the loops of ``lie-verlet``,
        ``lie-euler``, ``rkmk4``, ``overdamped``, ``rattle`` and ``implicit-midpoint`` only,
        :attr:`OperatorSet.loops`); a medium whose Lagrangian couples N and X with its coupled
        point kernels (the loops of ``lie-euler``, ``forward-euler`` and ``rkmk4`` only,
        :func:`cartan.schemes._lattice_ops.coupled_fragment`)."""
        ops = self.__dict__.get("_operators")
        if ops is None:
            if self._glue:
                from ..compiled.operators import OperatorSet

                ops = self._operators = OperatorSet.declined(
                    "a glued axis (a chart closed over poles) runs on the numpy path")
                return ops
            if any(f is not None for f in self._end_factors):
                from ..compiled.operators import OperatorSet

                ops = self._operators = OperatorSet.declined(
                    "face loads on a general chart (reference areas per node) run on the numpy path")
                return ops
            from ._lattice_ops import lattice_operators

            ops = self._operators = lattice_operators(self, Lattice)
        return ops

    # ------------------------------------------------------------------ layout helpers
    def _key(self, axis: int) -> str:
        keys = self.__dict__.get("_keys")
        if keys is None:  # (built once: read several times per step on the numpy path and per frame)
            keys = self._keys = tuple(f"G_{name}" for name in self.grid.axis_names)
        return keys[axis]

    def _ends(self, a: np.ndarray, axis: int, kind: str | None = None,
              glue: dict[int, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Node-shaped array ``a`` (node axes first) → (tail, head) values per edge.

        On a glued axis the ghost ends take the values of the opposite nodes, seen through the
        glue Γ (``glue``, default the initial state's) as ``kind`` says: ``"frame"`` Φ → ΦΓ,
        ``"inverse"`` Φ⁻¹ → Γ⁻¹Φ⁻¹, ``"conj"`` D → Γ⁻¹DΓ (node motions, edge elements), None
        unchanged (node numbers)."""
        if self.grid.is_glued(axis):
            G = (self._glue if glue is None else glue)[axis]
            beta = self.grid.glued[axis]
            half = self.grid.shape[beta] // 2
            n = a.shape[axis]
            first = np.roll(np.take(a, [0], axis=axis), half, axis=beta)
            last = np.roll(np.take(a, [n - 1], axis=axis), half, axis=beta)
            if kind is not None:
                Gi = self.group.inverse(G)
                first, last = ([f @ G if kind == "frame" else Gi @ f if kind == "inverse" else Gi @ f @ G]
                               for f in (first, last))
                first, last = first[0], last[0]
            return np.concatenate([first, a], axis=axis), np.concatenate([a, last], axis=axis)
        if self.grid.periodic[axis]:
            return a, np.roll(a, -1, axis=axis)
        n = a.shape[axis]
        return np.take(a, np.arange(n - 1), axis=axis), np.take(a, np.arange(1, n), axis=axis)

    def _scatter(self, F: np.ndarray, tail: np.ndarray, head: np.ndarray, axis: int) -> None:
        """F[tail nodes] += tail; F[head nodes] += head (edge-shaped contributions)."""
        if self.grid.is_glued(axis):
            r = F.shape[-1]
            flat = F.reshape(-1, r)
            t, hd = self.edge_nodes()
            gt, gh = self.ghost_ends()
            tail = self.from_ghosts(tail.reshape(-1, r), gt[axis], axis)
            head = self.from_ghosts(head.reshape(-1, r), gh[axis], axis)
            scatter_add(flat, t[axis], tail)
            scatter_add(flat, hd[axis], head)
            return
        if self.grid.periodic[axis]:
            F += tail
            F += np.roll(head, 1, axis=axis)
            return
        n = F.shape[axis]
        lo = [slice(None)] * F.ndim
        hi = [slice(None)] * F.ndim
        lo[axis] = slice(0, n - 1)
        hi[axis] = slice(1, n)
        F[tuple(lo)] += tail
        F[tuple(hi)] += head

    # ------------------------------------------------------------------ state
    def initial_state(self) -> State:
        g = self.group
        Phi = self.problem.initial.Phi
        arrays: dict[str, np.ndarray] = {}
        Phi_inv = g.inverse(Phi)
        holonomies = axis_holonomies(self.problem.initial, self.grid.d)
        for axis in range(self.grid.d):
            inv_tail, _ = self._ends(Phi_inv, axis, "inverse")
            _, head = self._ends(Phi, axis, "frame")
            if axis in holonomies:
                head = np.moveaxis(head.copy(), axis, 0)
                head[-1] = g.compose(holonomies[axis], head[-1])
                head = np.moveaxis(head, 0, axis)
            G = g.compose(inv_tail, head)
            arrays[self._key(axis)] = G
            xi = g.log(G)
            if np.any(g.log_domain_norm(xi) > 0.9 * g.injectivity_radius):
                raise ValueError(
                    "initial.Phi changes too fast between neighbouring nodes: an edge rotates by "
                    f"more than 0.9·{g.injectivity_radius:.3g}; refine the grid"
                )
        return self._new_state(arrays)

    # ------------------------------------------------------------------ strains and forces
    def constraint_rows(self, unknown: np.ndarray, state: State):
        """:meth:`Scheme.constraint_rows` on the edge strains, exact on the lattice: one row per
        edge and held component (:class:`cartan.constraints.StrainConstraints`)."""
        from ..constraints import StrainConstraints

        return StrainConstraints(self, unknown, state)

    def edge_strains(self, state: State) -> list[np.ndarray]:
        """Per axis, the edge strains ``X_e = log(G_e)/h`` ``[*edge_shape, r]`` (the chord-length
        strains X″ with ``pole="cap"``: :mod:`cartan.schemes._pole_cell`)."""
        return [self._edge_log(state.arrays[self._key(a)]) / self.h[a] for a in range(self.grid.d)]

    def _edge_log(self, G: np.ndarray) -> np.ndarray:
        """``hX`` ``[..., r]`` of edge elements ``G``: ``log G``, or with ``pole="cap"`` the
        chord-length strains hX″ (:func:`cartan.schemes._pole_cell.chord_strains`)."""
        if self.pole == "cap":
            from ._pole_cell import chord_strains

            return chord_strains(G, self.group)[0]
        return self.group.log(G)

    def strains(self, state: State) -> np.ndarray:
        if self.grid.d != 1:
            raise NotImplementedError("edge strains of d ≥ 2 lattices are returned per axis by edge_strains()")
        return self.edge_strains(state)[0][..., None, :]

    def nodal_strains(self, state: State) -> np.ndarray:
        """Edge strains averaged onto the nodes (one-sided at the ends of open axes)."""
        out = np.empty((*self.grid.shape, self.grid.d, self.group.dim))
        for axis, X in enumerate(self.edge_strains(state)):
            out[..., axis, :] = self._to_nodes(X, axis)
        return out

    def _to_nodes(self, X: np.ndarray, axis: int) -> np.ndarray:
        """Edge values along ``axis`` ``[*edge_shape, r]`` averaged onto the nodes (one-sided at
        the ends of an open axis)."""
        if self.grid.is_glued(axis):  # every node between two edges of its own chart
            n = X.shape[axis] - 1
            return 0.5 * (np.take(X, np.arange(n), axis=axis) + np.take(X, np.arange(1, n + 1), axis=axis))
        if self.grid.periodic[axis]:
            return 0.5 * (X + np.roll(X, 1, axis=axis))
        Xm = np.moveaxis(X, axis, 0)
        nodal = np.empty((Xm.shape[0] + 1, *Xm.shape[1:]))
        nodal[1:-1] = 0.5 * (Xm[1:] + Xm[:-1])
        nodal[0], nodal[-1] = Xm[0], Xm[-1]
        return np.moveaxis(nodal, 0, axis)

    def nodal_rest_strains(self) -> np.ndarray | None:
        """The rest strains of the ``reference`` averaged onto the nodes as :meth:`nodal_strains`
        averages the strains, ``[*shape, d, r]``; None without a reference configuration."""
        if self.problem.reference is None:
            return None
        out = np.empty((*self.grid.shape, self.grid.d, self.group.dim))
        for axis in range(self.grid.d):
            out[..., axis, :] = self._to_nodes(self.edge_rest_strains(axis)[..., axis, :], axis)
        return out

    def edge_rest_strains(self, axis: int) -> np.ndarray | None:
        """Rest strains of the edges along ``axis`` ``[*edge_shape, d, r]`` from the problem's
        ``reference`` (slot ``axis``: log(Φ_ref,i⁻¹Φ_ref,j)/h; the other slots the medium's
        rest strain), or None when the problem has no reference configuration."""
        ref = self.problem.reference
        if ref is None:
            return None
        cache = self.__dict__.setdefault("_edge_rest", {})
        if axis not in cache:
            g = self.group
            inv_tail, _ = self._ends(g.inverse(ref.Phi), axis, "inverse", self._glue_ref)
            _, head = self._ends(ref.Phi, axis, "frame", self._glue_ref)
            holonomies = axis_holonomies(ref, self.grid.d)
            if axis in holonomies:
                head = np.moveaxis(head.copy(), axis, 0)
                head[-1] = g.compose(holonomies[axis], head[-1])
                head = np.moveaxis(head, 0, axis)
            xi = self._edge_log(g.compose(inv_tail, head)) / self.h[axis]
            X0 = np.broadcast_to(self.medium.rest_strain(), (*xi.shape[:-1], self.grid.d, g.dim)).copy()
            X0[..., axis, :] = xi
            cache[axis] = X0
        return cache[axis]

    def _axis_stress(self, X: np.ndarray, axis: int) -> np.ndarray:
        full, X0 = self._axis_full(X, axis)
        if X0 is None:
            return self.medium.stress(full)[..., axis, :], full
        return self.medium.stress_at(full, X0)[..., axis, :], full

    def _axis_full(self, X: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray | None]:
        """``(full, X0)``: the edge strains ``X`` ``[*edge_shape, r]`` along ``axis`` in the slot
        ``axis`` of the edges' full strains ``[*edge_shape, d, r]`` (the other slots at rest), and
        the edges' rest strains (:meth:`edge_rest_strains`, None without a reference)."""
        d = self.grid.d
        X0 = self.edge_rest_strains(axis)
        if X0 is None:
            full = np.broadcast_to(self.medium.rest_strain(), (*X.shape[:-1], d, X.shape[-1])).copy()
        else:
            full = X0.copy()
        full[..., axis, :] = X
        return full, X0

    def edge_nodes(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per axis, the flat (C-order) nodes at the tail and at the head of each edge, in the
        order of that axis' edge array: ``(tails, heads)``, two lists of ``[E_α]`` int arrays."""
        held = self.__dict__.get("_edge_nodes")
        if held is None:
            numbers = np.arange(int(np.prod(self.grid.shape))).reshape(self.grid.shape)
            ends = [self._ends(numbers, a) for a in range(self.grid.d)]
            held = self._edge_nodes = ([t.ravel() for t, _ in ends], [hd.ravel() for _, hd in ends])
        return held

    def ghost_ends(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per axis, which edges' tail and head are ghosts (the ends of a glued axis, module
        docstring): ``(tail, head)``, two lists of ``[E_α]`` bool arrays (all False off glued axes)."""
        tails, heads = [], []
        for a in range(self.grid.d):
            es = self.grid.edge_shape(a)
            t, hd = np.zeros(es, dtype=bool), np.zeros(es, dtype=bool)
            if self.grid.is_glued(a):
                sl = [slice(None)] * self.grid.d
                sl[a] = 0
                t[tuple(sl)] = True
                sl[a] = -1
                hd[tuple(sl)] = True
            tails.append(t.ravel())
            heads.append(hd.ravel())
        return tails, heads

    def from_ghosts(self, F: np.ndarray, ghost: np.ndarray, axis: int) -> np.ndarray:
        """Edge-end forces ``F [E, r]`` with those on ghost ends (mask ``ghost [E]``) taken to the
        nodes they stand for, ``Ad_{Γ⁻¹}ᵀ F`` (module docstring, "Glued axes")."""
        if not np.any(ghost):
            return F
        A = self.group.Ad(self.group.inverse(self._glue[axis]))
        F = F.copy()
        F[ghost] = F[ghost] @ A
        return F

    def corners(self) -> dict[str, np.ndarray]:
        """The corners of a coupled lattice (see the module docstring), built once.

        Returns
        -------
        dict
            ``"node"`` ``[C]`` flat node of each corner, ``"edge"`` ``[C, d]`` the flat index
            of its edge along each axis (in that axis' edge array, C order), ``"weight"`` ``[C]``
            ``w_i/#corners_i``, ``"X0"`` ``[C, d, r]`` its rest strain; ``"tail"``, ``"head"``
            per axis, the flat end nodes of that axis' edges.
        """
        held = self.__dict__.get("_corners")
        if held is not None:
            return held
        d, r, shape = self.grid.d, self.group.dim, self.grid.shape
        n = int(np.prod(shape))
        tails, heads = self.edge_nodes()
        ghost_t, ghost_h = self.ghost_ends()
        after, before = [], []
        for t, hd, gt, gh in zip(tails, heads, ghost_t, ghost_h):
            ea = np.full(n, -1)
            eb = np.full(n, -1)
            ea[t[~gt]] = np.flatnonzero(~gt)  # a node's corners use the edges it is a genuine end of
            eb[hd[~gh]] = np.flatnonzero(~gh)
            after.append(ea)
            before.append(eb)
        count = np.ones(n)
        for a in range(d):
            count *= (after[a] >= 0).astype(float) + (before[a] >= 0)
        w = np.asarray(self.chart_weights, dtype=float).reshape(n)
        nodes, edges = [], []
        for combo in range(1 << d):
            idx = [after[a] if (combo >> a) & 1 else before[a] for a in range(d)]
            valid = np.all([i >= 0 for i in idx], axis=0)
            nodes.append(np.flatnonzero(valid))
            edges.append(np.stack([i[valid] for i in idx], axis=-1))
        node = np.concatenate(nodes)
        edge = np.concatenate(edges).astype(np.int64)
        X0 = np.broadcast_to(self.medium.rest_strain(), (node.size, d, r)).copy()
        for a in range(d):
            ref = self.edge_rest_strains(a)
            if ref is not None:
                X0[:, a, :] = ref.reshape(-1, d, r)[edge[:, a], a, :]
        weight = w[node] / count[node]
        if self.pole == "cap":  # the caps replace the corners that use a glued edge
            from ._pole_cell import cap

            a = cap(self).axis
            weight[(ghost_t[a] | ghost_h[a])[edge[:, a]]] = 0.0
        held = self._corners = {"node": node, "edge": edge, "weight": weight, "X0": X0,
                                "tail": tails, "head": heads, "ghost_tail": ghost_t, "ghost_head": ghost_h}
        return held

    def _corner_strains(self, state: State) -> tuple[list[np.ndarray], np.ndarray]:
        """Per axis the flat edge logarithms ``hX_e`` ``[E_α, r]``, and the corner strains ``[C, d, r]``."""
        c = self.corners()
        xis = [self._edge_log(state.arrays[self._key(a)]).reshape(-1, self.group.dim) for a in range(self.grid.d)]
        Xc = np.stack([xis[a][c["edge"][:, a]] / self.h[a] for a in range(self.grid.d)], axis=1)
        return xis, Xc

    def _corner_energy(self, Xc: np.ndarray) -> np.ndarray:
        X0 = self.corners()["X0"]
        return self.medium.potential_at(Xc, X0) if self.problem.reference is not None else self.medium.potential(Xc)

    def _corner_force(self, state: State) -> np.ndarray:
        if self.pole == "cap":
            from ._pole_cell import corner_force

            return corner_force(self, state)
        g, c = self.group, self.corners()
        xis, Xc = self._corner_strains(state)
        Q = (self.medium.stress_at(Xc, c["X0"]) if self.problem.reference is not None
             else self.medium.stress(Xc))
        F = np.zeros((int(np.prod(self.grid.shape)), g.dim))
        for a, xi in enumerate(xis):
            Qe = np.zeros_like(xi)
            scatter_add(Qe, c["edge"][:, a], (c["weight"] / self.h[a])[:, None] * Q[:, a, :])
            out = self.from_ghosts(np.einsum("...ji,...j->...i", g.dexp_inv(xi), Qe), c["ghost_tail"][a], a)
            inc = self.from_ghosts(np.einsum("...ji,...j->...i", g.dexp_inv(-xi), Qe), c["ghost_head"][a], a)
            scatter_add(F, c["tail"][a], out)
            scatter_add(F, c["head"][a], -inc)
        return F.reshape(*self.grid.shape, g.dim)

    def internal_force(self, state: State) -> np.ndarray:
        """Generalised internal force per node F_i (not divided by the weight) ``[*shape, r]``."""
        g = self.group
        if self.coupled:
            return self._corner_force(state)
        F = np.zeros((*self.grid.shape, g.dim))
        for axis in range(self.grid.d):
            xi = g.log(state.arrays[self._key(axis)])
            if self.coupled_lagrangian:  # ℓ(N, X) coupling N and X: the Hamiltonian stress (cartan.schemes._coupled)
                from ._coupled import coupled_stress

                Q = coupled_stress(self, state, xi / self.h[axis])
            else:
                Q, _ = self._axis_stress(xi / self.h[axis], axis)
            # V = cell·Σ_e U(X_e) and δX_e carries 1/h_α: the edge stress enters as (cell/h_α)·Q
            Q = Q * (float(np.prod(self.h)) / self.h[axis])
            out = np.einsum("...ji,...j->...i", g.dexp_inv(xi), Q)
            inc = np.einsum("...ji,...j->...i", g.dexp_inv(-xi), Q)
            self._scatter(F, out, -inc, axis)
        return F

    def force(self, state: State, N: np.ndarray, t: float, raw: bool = False) -> np.ndarray:
        """The force density W ``[*shape, r]`` (module docstring of :mod:`cartan.schemes.base`);
        ``raw``: not zeroed at the held nodes (for :meth:`~Scheme.support_reaction`)."""
        W = self.internal_force(state) / self.weights[..., None]
        Phi = self.frames(state) if self.problem.needs_structure_field else None
        for load in self.problem.loads:
            W += load.force(Phi, N, t)
        T = self.medium.body_force(Phi, N, t)
        if T is not None:
            W += T
        for k, (idx, b) in enumerate(self._end_loads):
            P = b.load if b.follower else dead_to_body(self.group, Phi[idx], b.load)
            # P is a load per unit face area (a point load for d = 1): the end node's share of the
            # face is weight/(h_α/2), so its force density is P/(h_α/2) (times the chart's factor)
            W[idx] += self.end_load_density(k, P)
        if not raw:
            W[self._clamped] = 0.0
        W[..., ~self.live] = 0.0
        return W

    def _boundary_power(self, state, N, Phi):
        p = 0.0
        for k, (idx, b) in enumerate(self._end_loads):
            P = b.load if b.follower else dead_to_body(self.group, Phi[idx], b.load)
            if self._end_factors[k] is None:
                face = self.weights[idx] / (0.5 * self.h[self._end_axis(idx)])
                p += float(np.sum(face[..., None] * P * N[idx]))
            else:
                p += float(np.sum(self.weights[idx][..., None] * self.end_load_density(k, P) * N[idx]))
        return p

    def end_load_entries(self) -> list[tuple[int, Any, int]]:
        """``(flat node, Free boundary, axis)`` for every node of every loaded free end (face),
        sorted by node, stably (a node loaded by two faces keeps the order of ``_end_loads``)."""
        numbers = np.arange(int(np.prod(self.grid.shape))).reshape(self.grid.shape)
        entries = [(int(i), b, self._end_axis(sl)) for sl, b in self._end_loads for i in np.ravel(numbers[sl])]
        entries.sort(key=lambda e: e[0])
        return entries

    @staticmethod
    def _end_axis(idx: tuple) -> int:
        """The axis whose end an end-load index selects (the one integer entry)."""
        return next(k for k, s in enumerate(idx) if not isinstance(s, slice))

    # ------------------------------------------------------------------ drift
    def drift(self, state: State, tau: float, N: np.ndarray, exact: bool = True) -> None:
        g = self.group
        arr = state.arrays
        if exact:
            D = g.exp(tau * N)
            Dinv = g.inverse(D)
            for axis in range(self.grid.d):
                key = self._key(axis)
                Dinv_tail, _ = self._ends(Dinv, axis, "conj")
                _, D_head = self._ends(D, axis, "conj")
                arr[key] = g.compose(g.compose(Dinv_tail, arr[key]), D_head)
            if "Phi" in arr:
                arr["Phi"] = g.compose(arr["Phi"], D)
            else:
                root = (0,) * self.grid.d
                arr["Phi_root"] = g.compose(arr["Phi_root"], D[root])
            return
        # naive matrix Euler: Φ ← Φ + τΦN̂, G ← G + τ(−N̂_i G + G N̂_j); leaves the group.
        Nh = g.hat(tau * N)
        for axis in range(self.grid.d):
            key = self._key(axis)
            N_tail, N_head = self._ends(Nh, axis, "conj")
            G = arr[key]
            arr[key] = G - N_tail @ G + G @ N_head
        if "Phi" in arr:
            arr["Phi"] = arr["Phi"] + arr["Phi"] @ Nh
        else:
            root = (0,) * self.grid.d
            arr["Phi_root"] = arr["Phi_root"] + arr["Phi_root"] @ Nh[root]

    # ------------------------------------------------------------------ output and diagnostics
    def frames(self, state: State) -> np.ndarray:
        if "Phi" in state.arrays:
            return state.arrays["Phi"]
        # Rebuild from the root frame along axis 0, then along each further axis from the
        # frames already built (a spanning tree of the lattice); exact because the drift keeps
        # every plaquette holonomy at its initial value.
        P = state.arrays["Phi_root"]
        for axis in range(self.grid.d):
            G = state.arrays[self._key(axis)]
            # the edges along this axis that start on the part built so far (index 0 on later axes)
            G = G[tuple(slice(None) if k <= axis else 0 for k in range(self.grid.d))]
            if self.grid.is_glued(axis):  # the interior edges; the glued ones close loops
                G = np.take(G, np.arange(1, G.shape[axis] - 1), axis=axis)
            elif self.grid.periodic[axis]:
                G = np.take(G, np.arange(G.shape[axis] - 1), axis=axis)
            steps = np.moveaxis(G, axis, 0)
            P = np.moveaxis(prefix_products(P, steps), 0, axis)
        return P

    def spatial_residual(self, state: State) -> float:
        """The plaquette holonomy residual (:meth:`plaquette_residual`)."""
        return self.plaquette_residual(state)

    def plaquette_residual(self, state: State) -> float:
        """Spatial integrability (paper §III.C): max over plaquettes and axis pairs of
        ‖log(G_α(i) G_β(i+e_α) G_α(i+e_β)⁻¹ G_β(i)⁻¹)‖; 0 for d = 1."""
        g = self.group
        res = 0.0
        for a in range(self.grid.d):
            for b in range(a + 1, self.grid.d):
                Ga, Gb = state.arrays[self._key(a)], state.arrays[self._key(b)]
                Ga_i, Ga_next = self._ends(Ga, b, "conj")  # G_α(i), G_α(i + e_β)
                Gb_i, Gb_next = self._ends(Gb, a, "conj")  # G_β(i), G_β(i + e_α)
                loop = g.compose(g.compose(Ga_i, Gb_next), g.inverse(g.compose(Gb_i, Ga_next)))
                res = max(res, float(np.max(np.abs(g.log(loop)))))
        return res

    def potential_energy(self, state: State) -> float:
        return self._potential_energy(state, None if self.coupled else self.edge_strains(state))

    def _potential_energy(self, state: State, edges: list[np.ndarray] | None) -> float:
        """:meth:`potential_energy` with the edge strains ``edges`` (:meth:`edge_strains` of
        ``state``; unused for a coupled lattice) given: a saved frame has them already."""
        V = 0.0
        cell = self.__dict__.get("_cell")
        if cell is None:
            cell = self._cell = float(np.prod(self.h))
        if self.coupled:
            xis, Xc = self._corner_strains(state)
            V += float(np.sum(self.corners()["weight"] * self._corner_energy(Xc)))
            if self.pole == "cap":
                from ._pole_cell import cap

                caps = cap(self)
                V += caps.energy_grad(xis[caps.axis], want=False)[0]
        for axis, X in enumerate(edges if not self.coupled else ()):
            full, X0 = self._axis_full(X, axis)  # (the energy only: no stress evaluated)
            V += cell * float(np.sum(self.medium.potential(full) if X0 is None
                                     else self.medium.potential_at(full, X0)))
        conservative = [load for load in self.problem.loads if load.conservative]
        if conservative:
            Phi = self.frames(state)
            for load in conservative:
                V += float(np.sum(self.weights * load.energy(Phi)))
        return V

    def integrability_residual(self, state: State) -> float:
        """max_e |X_e(stored) − log(Φ_i⁻¹Φ_j)/h| with Φ the stepped frames (or, when frames are
        rebuilt from the edges, the closure defect of periodic axes)."""
        if "Phi" not in state.arrays:
            return self.closure_residual(state)
        one = (..., None, slice(None), slice(None))  # (a batch of one state)
        edges = [state.arrays[self._key(axis)][one] for axis in range(self.grid.d)]
        return float(self.integrability_residuals(state.arrays["Phi"][one], edges)[0])

    def integrability_residuals(self, Phi: np.ndarray, edges: list[np.ndarray]) -> np.ndarray:
        """:meth:`integrability_residual` of a batch of tracked states at once, the same numbers.

        Parameters
        ----------
        Phi : numpy.ndarray, shape ``[*shape, *batch, m, m]``
            The stepped frames, the batch axes after the node axes.
        edges : list of numpy.ndarray
            Per axis α the stored edge elements ``[*edge_shape_α, *batch, m, m]``.

        Returns
        -------
        numpy.ndarray, shape ``[*batch]``
            Per state, ``max_e |X_e(stored) − log(Φ_i⁻¹Φ_j)/h|`` (the pointwise kernels and
            the exact maxima of :meth:`integrability_residual`: bit for bit its values).
        """
        g = self.group
        d = self.grid.d
        res = np.zeros(Phi.shape[d:-2])
        for axis in range(d):
            inv_tail, _ = self._ends(g.inverse(Phi), axis, "inverse")
            _, head = self._ends(Phi, axis, "frame")
            mismatch = g.log(g.compose(g.inverse(edges[axis]), g.compose(inv_tail, head)))
            worst = np.max(np.abs(mismatch), axis=(*range(d), mismatch.ndim - 1)) / self.h[axis]
            res = np.where(worst > res, worst, res)  # (as max(res, worst): a NaN is not taken)
        return res

    def closure_residual(self, state: State) -> float:
        """Closure ‖log(B_α⁻¹ ∏_e G_e)‖ around every periodic axis α and every line along it,
        with B_α = Φ₀⁻¹H_αΦ₀ the body holonomy at the line's first node (identity for a closed
        rod or shell); 0 when no axis is periodic."""
        g = self.group
        res = 0.0
        holonomies = axis_holonomies(self.problem.initial, self.grid.d)
        Phi = self.frames(state) if holonomies else None
        for axis in range(self.grid.d):
            if not self.grid.periodic[axis]:
                continue
            G = np.moveaxis(state.arrays[self._key(axis)], axis, 0)
            prod = G[0]
            for k in range(1, G.shape[0]):
                prod = prod @ G[k]
            if axis in holonomies:
                first = np.take(Phi, 0, axis=axis)
                B = g.compose(g.inverse(first), g.compose(holonomies[axis], first))
                prod = g.compose(g.inverse(B), prod)
            res = max(res, float(np.max(np.abs(g.log(prod)))))
        return res
