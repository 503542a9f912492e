"""The ``collocation`` scheme: the paper's own formulation (ARCHITECTURE.md §3, scheme 2).

The strains X_α, the velocity N and the momentum density S live on the same nodes, and the
material derivative ∂_α is a linear difference operator along each axis: central finite
differences of second (``"fd2"``) or fourth (``"fd4"``) order, or the Fourier spectral
derivative (``"fourier"``, periodic axes only).

Drift (paper §V, "Geometric integrators for dynamical motion")
    For a velocity field N frozen over the sub-step τ, the strains follow the paper's Lie
    group integrator, Eq. (X LGI)::

        X_α⁺ = Ad_{exp(−τN)} X_α + 𝓔(τ, −N) ∂_αN,

    the exact solution of Ẋ_α = ∂_αN − ad_N X_α with N constant in time; the frames (when
    stepped) follow Φ⁺ = Φ exp(τN).  With τ = 1 and a per-node algebra element σ this is
    exactly the strain of Φ exp(σ(u)) (the drift the RKMK integrators use).  The naive
    update (``exact=False``, the paper's forward Euler) is X⁺ = X + τ(∂_αN − ad_N X_α),
    Φ⁺ = Φ + τΦN̂.
Forces (paper §IV, balance law; §V, W = D*_u Q + T)
    ``W = Σ_α (∂_α Q^α − ad_{X_α}ᵀ Q^α) + T`` with Q^α = ∂U/∂X_α evaluated at the nodes
    (``ad*_X = −ad_Xᵀ``).  The stress is a function of all the nodal strains, so media whose
    potential couples the axes (``separable_axes = False``) are handled directly.
Open axes and boundary conditions (paper §IV.D, n_α Q^α = P on ∂M)
    The central stencils are closed at the ends by diagonal-norm *summation-by-parts*
    (SBP) rows — boundary rows of order p/2, quadrature weights H (trapezoidal for fd2) —
    and the natural condition enters as a penalty (simultaneous-approximation term) at the
    end node, ``W_end += (P − n_α Q^α_end)/H_end``, with P in body components (a dead load
    is rotated by the frame there, :func:`~cartan.problem.dead_to_body`) and P = 0 for an
    unloaded free end; for d ≥ 2, P is a traction per unit reference area.  Summation by
    parts makes the semi-discrete energy balance exact, ``d/dt Σ H (K + U) = Σ_ends P·N``,
    which is what keeps the explicit time stepping stable.  (Closing with one-sided stencils
    of the interior order and replacing the end stress by n_α P before differencing is
    stable for fd2 but not for fd4: the semi-discrete wave operator then has eigenvalues
    with Re λ ≈ 0.05 c/h.)  At a clamped end N = 0 and W = 0.  At a
    :class:`~cartan.problem.Held` end or a :class:`~cartan.problem.Symmetry` face the held
    body components get N = 0, S = 0 and W = 0 (the clamp mask ``(*shape, r)`` of
    :meth:`~cartan.schemes.base.Scheme._clamp_mask`) and the free ones the penalty of an
    unloaded free end (P = 0), on the numpy path and the compiled one.  Solutions converge with
    order 2 (fd2) and about 3 (fd4, boundary rows of order 2) on open axes — except for an
    odd–even part of the positions between two ends that hold the translations (an arch under
    ``rattle``: the collocated grid's odd–even mode, which the central stencils do not see at
    interior nodes, excited at O(h) there, with fd2 and fd4 alike; ``docs/schemes.md``, "Between
    two supports").
Driven ends (:class:`~cartan.problem.Driven`)
    A clamp that moves with its body velocity ξ: at its nodes N = ξ and S = ∂K/∂N(ξ) at every
    step (:meth:`~cartan.schemes.base.Scheme.velocity`, ``constrain``) and the force is not
    applied, so the drift moves their frames by exp(τξ) (Φ(t) = Φ(0)exp(tξ) to round-off: the
    frames are stepped by default) and their strains by the same Lie group integrator, with ξ in
    ∂_αN.  The raw force there is the weak form of a clamped end's (:meth:`_clamped_traction`),
    so the reaction ``R = −w(W + ad_ξᵀS)`` is the one whose power R·ξ closes the semi-discrete
    energy balance ``d/dt Σ w(K + U) = Σ_driven R·ξ`` exactly (summation by parts).  The
    compiled operators do the same for ``lie-verlet``, ``lie-euler``, ``rkmk4``, ``overdamped``
    and ``implicit-midpoint`` (``rattle`` runs its Python step here).
Charts
    The grid is a chart of the body; the energy is summed with the quadrature weights
    (:attr:`~Collocation.chart_weights`).  When the medium measures the reference volume of a
    general chart (:meth:`~cartan.medium.Medium.reference_volume` J_i at the nodal rest strains
    of the ``reference``), a node's mass, body loads and kinetic energy are those of its
    reference volume, ``weights = w_i J_i``, as on the lattice, and the internal force (a
    density per unit chart volume, ∂_αQ^α − ad*…) is divided by J_i, so that the semi-discrete
    energy balance Σ w_i J_i S·Ṅ = −Σ w_i U̇ still holds.  A free face's load P enters its
    penalty per unit chart area (the lattice integrates it with the face's reference area).
Frames
    Stepped at every node when a force needs them (``problem.needs_structure_field``), when
    an end is :class:`~cartan.problem.Driven` (unless ``track_frames=False``) or when
    ``track_frames=True``.  Otherwise only the root node's frame is stepped and the
    field is rebuilt at output times by the trapezoidal Magnus step
    ``Φ_{i+1} = Φ_i exp(h (X_i + X_{i+1})/2)`` along each axis in turn (second order in h,
    whatever the derivative operator).
Initial strains
    ``X_α(0) = Φ₀⁻¹ ∂_αΦ₀`` by :meth:`Collocation.strain_from_frames`: the same interior
    stencils, closed on open axes by one-sided stencils of the full order p, so X(0) is
    O(hᵖ) accurate at every node and the integrability residual starts at round-off.

Compiled loops
    :meth:`Collocation.compiled_operators` gives the integrators' generated loops
    (:meth:`cartan.integrators.base.Integrator.run_compiled_loop`) the scheme's operators
    (:mod:`cartan.schemes._collocation_ops`) for any group and medium with point kernels: d = 1,
    2, 3, ``fd2``, ``fd4`` and ``fourier``, open and periodic axes, the loads that are data
    (damping, body-frame uniform force, constant-field potentials, node forces, end loads,
    clamps, held ends, symmetry faces and driven ends), and media whose Lagrangian couples N and
    X with coupled point kernels (``lie-euler``, ``forward-euler``, ``rkmk4``).  The CFL
    estimate (:meth:`~cartan.schemes.base.Scheme.dt_max`) and the blow-up guard's energies run
    on the same operators (:mod:`cartan.compiled.diagnostics`; with driven ends too, not with a
    coupled Lagrangian).  Everything else stays on this module's numpy path,
    the reference the compiled loops are tested against (``docs/schemes.md``).

What is exact and what is not
    Unlike the ``lattice`` scheme, the stored strains are independent unknowns: temporal
    integrability (stored X = Φ⁻¹∂_uΦ) holds only to the accuracy of the difference
    operator, and the residual grows by O(Δt·hᵖ) per step (a rate O(hᵖ) in time: the
    discrete ∂_u has no exact product rule).  On the boundary rows of an open axis the rate is
    O(h^{p/2}), the SBP rows' order, (D − D_strain)N to first order; where the solution is not
    smooth it does not fall with h (the clamped–free corners of a plate, N ~ r^0.758:
    ``docs/schemes.md``, "Open axes and corners").  Group membership of Φ is exact (round-off)
    for the geometric integrators, and a spatially constant N is integrated exactly.  On
    periodic axes the central and spectral operators are skew-symmetric, so the
    semi-discrete energy Σ_i w_i (K(N_i) + U(X_i)) is an exact invariant of the
    semi-discrete system (on open axes: with the SBP weights, up to the boundary power) and
    ``lie-verlet`` keeps its error O(Δt²).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..problem import Clamped, Driven, Free, Held, Symmetry, dead_to_body
from .base import Scheme, State, prefix_products

__all__ = ["Collocation", "DerivativeOperator"]

DERIVATIVES = ("fd2", "fd4", "fourier")
_Row = tuple[int, tuple[int, ...], np.ndarray]  # (node, offsets, coefficients)

# Finite-difference rows: (offsets relative to the node, coefficients × h).
_INTERIOR = {
    "fd2": ((-1, 1), (-0.5, 0.5)),
    "fd4": ((-2, -1, 1, 2), (1 / 12, -8 / 12, 8 / 12, -1 / 12)),
}
# Rows at the start of an open axis, one per boundary node; the rows at the end are their
# mirror images (offsets and coefficients negated).
#
# "one-sided": closures of the same order as the interior (accurate, but not stable in time:
# with them the semi-discrete wave operator has eigenvalues with Re λ ≈ 0.05 c/h for fd4).
# Used to compute strains from frames.
_ONE_SIDED = {
    "fd2": [((0, 1, 2), (-1.5, 2.0, -0.5))],
    "fd4": [
        ((0, 1, 2, 3, 4), (-25 / 12, 48 / 12, -36 / 12, 16 / 12, -3 / 12)),
        ((-1, 0, 1, 2, 3), (-3 / 12, -10 / 12, 18 / 12, -6 / 12, 1 / 12)),
    ],
}
# "sbp": diagonal-norm summation-by-parts closures (Kreiss & Scherer 1974; Strand 1994;
# Mattsson & Nordström 2004), H D + (H D)ᵀ = diag(−1, 0, …, 0, 1) with the norm H below;
# boundary rows of order p/2.  Used for the dynamics.
_SBP = {
    "fd2": [((0, 1), (-1.0, 1.0))],
    "fd4": [
        ((0, 1, 2, 3), (-24 / 17, 59 / 34, -4 / 17, -3 / 34)),
        ((-1, 1), (-1 / 2, 1 / 2)),
        ((-2, -1, 1, 2), (4 / 43, -59 / 86, 59 / 86, -4 / 43)),
        ((-3, -1, 1, 2), (3 / 98, -59 / 98, 32 / 49, -4 / 49)),
    ],
}
_SBP_NORM = {"fd2": (0.5,), "fd4": (17 / 48, 59 / 48, 43 / 48, 49 / 48)}
_MIN_NODES = {"fd2": (3, 3), "fd4": (5, 8), "fourier": (3, 0)}  # (periodic, open)


def _load_of(b: Free | Held | Symmetry) -> np.ndarray | None:
    """The applied load P of an end: a :class:`~cartan.problem.Free` end's ``load``; None (no
    load) at a held end or a symmetry face."""
    return b.load if isinstance(b, Free) else None


class DerivativeOperator:
    """First derivative along one grid axis: central finite differences or Fourier.

    Parameters
    ----------
    kind : {"fd2", "fd4", "fourier"}
    n : int
        Number of nodes along the axis.
    h : float
        Node spacing.
    periodic : bool
        Periodic axes wrap the central stencils around (or use the FFT).
    closure : {"sbp", "one-sided"}
        Rows at the ends of an open axis.  ``"one-sided"``: one-sided stencils of the
        interior order p (the most accurate derivative of given data).  ``"sbp"``: the
        diagonal-norm summation-by-parts closure, ``H D + (H D)ᵀ = diag(−1, 0, …, 0, 1)``
        with the norm ``H`` of :meth:`norm` (boundary rows of order p/2); the discrete
        integration by parts it provides is what makes the time evolution stable.

    Notes
    -----
    The operator acts along a chosen array axis of any array, so the same object
    differentiates scalar, algebra-valued (``[..., r]``) and matrix-valued (``[..., m, m]``)
    fields.  :meth:`rows` exposes the stencils, so that the strains of a frame field can be
    computed by the same weights in local logarithmic coordinates
    (:meth:`Collocation.strain_from_frames`).
    """

    def __init__(self, kind: str, n: int, h: float, periodic: bool, closure: str = "sbp"):
        if kind not in DERIVATIVES:
            raise ValueError(f"derivative must be one of {DERIVATIVES}, got {kind!r}")
        if closure not in ("sbp", "one-sided"):
            raise ValueError(f"closure must be 'sbp' or 'one-sided', got {closure!r}")
        if kind == "fourier" and not periodic:
            raise ValueError("derivative='fourier' needs periodic axes; use 'fd2' or 'fd4' on open axes")
        need = _MIN_NODES[kind][0 if periodic else 1]
        if n < need:
            raise ValueError(
                f"derivative={kind!r} needs at least {need} nodes on a {'periodic' if periodic else 'open'} "
                f"axis, got {n}"
            )
        self.kind, self.n, self.h = kind, int(n), float(h)
        self.periodic, self.closure = bool(periodic), closure
        if kind == "fourier":
            k = 2.0 * np.pi * np.fft.rfftfreq(n, d=h)
            if n % 2 == 0:
                k[-1] = 0.0  # the Nyquist mode has no real derivative: drop it (keeps D skew)
            self._ik = 1j * k

    @property
    def order(self) -> float:
        """Interior order of accuracy (``math.inf`` for the spectral operator)."""
        return {"fd2": 2, "fd4": 4}.get(self.kind, math.inf)

    def _start_rows(self):
        return (_SBP if self.closure == "sbp" else _ONE_SIDED)[self.kind]

    @property
    def halfwidth(self) -> int:
        """Number of boundary rows at each end of an open axis (0 when periodic)."""
        if self.periodic:
            return 0
        return len(self._start_rows())

    def rows(self) -> tuple[tuple[tuple[int, ...], np.ndarray], list[_Row]]:
        """The finite-difference stencils, scaled by 1/h.

        Returns
        -------
        interior : (offsets, coefficients)
            The central stencil (every node of a periodic axis).
        boundary : list of (node, offsets, coefficients)
            The closure rows of an open axis, ``node`` a non-negative index (empty when
            periodic).
        """
        if self.kind == "fourier":
            raise ValueError("the Fourier derivative has no finite stencil")
        off, c = _INTERIOR[self.kind]
        interior = (off, np.asarray(c) / self.h)
        boundary = []
        if not self.periodic:
            for i, (o, cc) in enumerate(self._start_rows()):
                boundary.append((i, o, np.asarray(cc) / self.h))
                boundary.append((self.n - 1 - i, tuple(-x for x in o), -np.asarray(cc) / self.h))
        return interior, boundary

    def norm(self) -> np.ndarray:
        """Quadrature weights along the axis ``(n,)``: h on periodic axes; on open axes the
        SBP norm H (trapezoidal for fd2; (17, 59, 43, 49)/48·h at the ends for fd4)."""
        w = np.full(self.n, self.h)
        if not self.periodic:
            ends = np.asarray(_SBP_NORM[self.kind]) * self.h
            w[: len(ends)] = ends
            w[self.n - len(ends):] = ends[::-1]
        return w

    def __call__(self, a: np.ndarray, axis: int = 0) -> np.ndarray:
        """∂a along ``axis`` of ``a`` (same shape)."""
        A = np.moveaxis(np.asarray(a, dtype=float), axis, 0)
        if self.kind == "fourier":
            spec = np.fft.rfft(A, axis=0)
            spec *= self._ik.reshape((-1,) + (1,) * (A.ndim - 1))
            out = np.fft.irfft(spec, n=self.n, axis=0)
            return np.moveaxis(out, 0, axis)
        (off, c), boundary = self.rows()
        n = self.n
        if self.periodic:
            out = sum(ck * np.roll(A, -o, axis=0) for o, ck in zip(off, c, strict=True))
        else:
            b = self.halfwidth
            out = np.empty_like(A)
            out[b : n - b] = sum(ck * A[b + o : n - b + o] for o, ck in zip(off, c, strict=True))
            for i, o_row, c_row in boundary:
                out[i] = sum(ck * A[i + o] for o, ck in zip(o_row, c_row, strict=True))
        return np.moveaxis(out, 0, axis)

    def matrix(self) -> np.ndarray:
        """The operator as a dense ``(n, n)`` matrix (for analysis and tests)."""
        return self(np.eye(self.n), axis=0)


class Collocation(Scheme):
    """Nodal strains stepped with the paper's Lie group integrator (module docstring).

    Parameters
    ----------
    problem : Problem
    derivative : {"fd2", "fd4", "fourier"}
        Difference operator for ∂_α on every axis.  ``"fourier"`` is allowed only when every
        axis is periodic.
    track_frames : bool, optional
        Step Φ at every node (default: only when a force needs it or an end is
        :class:`~cartan.problem.Driven`).  Needed to measure the temporal integrability residual.

    Attributes
    ----------
    D : list of DerivativeOperator
        Per axis, the operator of the dynamics (SBP closures on open axes).
    D_strain : list of DerivativeOperator
        Per axis, the operator of :meth:`strain_from_frames` (one-sided closures of full
        order on open axes; the same as ``D`` on periodic axes).
    order : float
        Interior order p of the derivative (``math.inf`` for Fourier).

    Raises
    ------
    ValueError
        For an unknown ``derivative``, ``"fourier"`` on an open axis, or too few nodes for
        the stencil (fd2: 3; fd4: 5 periodic, 8 open).
    """

    name = "collocation"
    order = 2
    #: ``force(raw=True)`` adds the clamped and driven ends' natural-condition term
    #: (:meth:`_clamped_traction`), so that :meth:`~cartan.schemes.base.Scheme.support_reaction` is
    #: the support's reaction
    gives_raw_force = True
    #: :class:`~cartan.problem.Driven` ends move (module docstring, "Driven ends"), in the compiled
    #: operators too
    supports_driven_ends = True
    #: media whose Lagrangian couples N and X, d = 1: :mod:`cartan.schemes._collocation_coupled` (compiled
    #: with the medium's coupled point kernels for lie-euler, forward-euler and rkmk4)
    supports_coupled_lagrangian = True
    coupled_module = "cartan.schemes._collocation_coupled"

    def __init__(self, problem, derivative: str = "fd2", track_frames: bool | None = None):
        super().__init__(problem)
        if self.coupled_lagrangian:  # what the pointwise discretisation does not cover
            self._coupled().check_problem(self)
        if problem.grid.glued is not None:
            raise ValueError("the collocation scheme does not support a glued axis (Grid.glued, the sphere's "
                             "chart); use the lattice scheme")
        if problem.initial.holonomy is not None:
            raise ValueError(
                "the collocation scheme supports closed periodic axes only (no initial.holonomy); "
                "use the lattice scheme for a periodic axis with a non-trivial holonomy"
            )
        if not isinstance(derivative, str) or derivative not in DERIVATIVES:
            raise ValueError(f"derivative must be one of {DERIVATIVES}, got {derivative!r}")
        self.derivative = derivative
        # a driven end's frame is stepped, Φ(0)exp(tξ) to round-off, when the frames are (the default
        # with Driven ends); rebuilt from the root node it would be second order only
        self.track = (problem.needs_structure_field or self._driven is not None) if track_frames is None \
            else bool(track_frames)
        grid = self.grid
        d = grid.d
        self.h = grid.spacing
        axes = list(zip(grid.shape, self.h, grid.periodic, strict=True))
        self.D = [DerivativeOperator(derivative, n, h, p, closure="sbp") for n, h, p in axes]
        self.D_strain = [D if D.periodic else DerivativeOperator(derivative, n, h, p, closure="one-sided")
                         for D, (n, h, p) in zip(self.D, axes, strict=True)]
        self.order = self.D[0].order
        # quadrature weights: tensor product of the per-axis norms (the SBP norm H on open
        # axes, so that Σ w (K + U) is the energy the semi-discrete system conserves)
        norms = [D.norm() for D in self.D]
        w = np.ones(grid.shape)
        for axis, wa in enumerate(norms):
            shape = [1] * d
            shape[axis] = grid.shape[axis]
            w = w * wa.reshape(shape)
        self.weights = w
        # natural boundary conditions n_α Q^α = P: (axis, node index, n_α, H_α at the end,
        # boundary, face weight) for every end that is not clamped: free ends (P their load),
        # held ends and symmetry faces (P = 0 on their free components; the held ones are
        # zeroed with the clamp mask); the face weight integrates a traction over the other
        # axes (1 for d = 1).
        self._free_ends: list[tuple[int, tuple, float, float, Free | Held | Symmetry, np.ndarray]] = []
        kinds = (Free, Clamped, Held, Symmetry, Driven)
        other = sorted({type(b).__name__ for b in problem.boundaries.values() if type(b) not in kinds})
        if other:
            raise ValueError(f"boundaries: the collocation scheme takes Free, Clamped, Held, Symmetry and Driven "
                             f"boundaries, got {other}")
        for axis in range(d):
            if grid.periodic[axis]:
                continue
            for side, idx, sign in (("start", 0, -1.0), ("end", -1, 1.0)):
                b = problem.boundary(axis, side)
                if isinstance(b, Clamped | Driven):
                    continue
                sl = [slice(None)] * d
                sl[axis] = idx
                H_end = float(norms[axis][idx])
                face = w[tuple(sl)] / H_end
                self._free_ends.append((axis, tuple(sl), sign, H_end, b, face))
        # loaded ends, the attribute the integrators look for to book external work
        self._end_loads = [e for e in self._free_ends if _load_of(e[4]) is not None]
        # the rest strain field of a stress-free reference configuration (None: the medium's)
        self.rest = None
        if problem.reference is not None:
            if problem.reference.holonomy is not None:
                raise ValueError("the collocation scheme takes a reference configuration without a holonomy")
            self.rest = self.strain_from_frames(problem.reference.Phi)
        self._chart_measures()

    def _chart_measures(self) -> None:
        """Reference volumes of a general chart (module docstring, "Charts"): when the medium
        measures them (:meth:`~cartan.medium.Medium.reference_volume` J at the nodal rest
        strains :attr:`rest`), :attr:`weights` become ``w_i J_i`` (mass, body loads, kinetic
        energy) and the internal force, a density per unit chart volume, is divided by J;
        :attr:`chart_weights` (the quadrature weights w) keep weighing the energy."""

        #: the energy's quadrature weights (per unit chart volume); :attr:`weights` are the nodes'
        #: reference volumes, equal to them unless the medium measures a general chart
        self.chart_weights = self.weights
        #: 1/J per node on a general chart, else None
        self._inv_volume: np.ndarray | None = None
        J = None if self.rest is None else self._reference_volumes(self.rest)
        if J is None or np.all(J == 1.0):  # the chart's own measure keeps the weights to the bit
            return
        self.weights = self.chart_weights * J
        self._inv_volume = 1.0 / J
        for load in self.problem.loads:
            load.measure(self.weights)

    def options(self) -> dict[str, Any]:
        return {"derivative": self.derivative, "track_frames": self.track}

    # ------------------------------------------------------------------ compiled loops
    def compiled_operators(self):
        """The collocation's compiled operators (:mod:`cartan.schemes._collocation_ops`), built
        once and kept on the scheme: any group with point kernels, any medium that declares
        point kernels (axis-coupled energies and a reference configuration included), d = 1–3,
        ``fd2``, ``fd4``, ``fourier``, open and periodic axes, damping, body-frame uniform
        forces, constant-field potentials, free (loaded) and clamped ends or faces,
        :class:`~cartan.problem.Held` ends and :class:`~cartan.problem.Symmetry` faces (the
        held components of the clamp mask zeroed as on the numpy path, their free components
        under the natural condition P = 0), :class:`~cartan.problem.Driven` ends (N = ξ and
        S = ∂K/∂N(ξ) at their nodes, the supports' power R·ξ with the weak-form raw force of
        :meth:`_clamped_traction`; a set for the loops of ``lie-verlet``, ``lie-euler``,
        ``rkmk4``, ``overdamped`` and ``implicit-midpoint`` and the compiled diagnostics only), any
        kinetic metric, and media whose Lagrangian couples N and X with
        coupled point kernels (pointwise, :mod:`cartan.schemes._collocation_coupled`; a set for the
        loops of ``lie-euler``, ``forward-euler`` and ``rkmk4`` only); a declined
        :class:`~cartan.compiled.operators.OperatorSet` says why otherwise."""
        ops = self.__dict__.get("_operators")
        if ops is None:
            from ._collocation_ops import collocation_operators

            ops = self._operators = collocation_operators(self, Collocation)
        return ops

    # ------------------------------------------------------------------ strains from frames
    def strain_from_frames(self, Phi: np.ndarray, check: bool = False) -> np.ndarray:
        """Nodal strains ``X_α = Φ⁻¹∂_αΦ`` of a frame field, O(hᵖ) at every node.

        Uses :attr:`D_strain`: on open axes the finite-difference stencils are closed by
        one-sided stencils of the interior order p.  Finite differences act in the local
        logarithmic chart of each node: with the stencil ``(o_k, c_k)`` of node i,
        ``X_i = Σ_k c_k log(Φ_i⁻¹Φ_{i+o_k})`` — the stencil applied to the smooth curve
        s ↦ log(Φ(u_i)⁻¹Φ(u_i + s)), whose derivative at s = 0 is X(u_i).  The result lies
        in 𝔤 exactly and is equivariant under rigid motions on either side (Φ → gΦ and
        Φ → Φg for constant g) to round-off.  The spectral operator is global, so it acts
        on the matrix entries instead and the result is projected to the algebra by
        ``vee``: ``X = vee(Φ⁻¹ D Φ)`` (spectrally accurate for smooth periodic frames).

        Parameters
        ----------
        Phi : array ``[*shape, m, m]``
        check : bool
            Raise ``ValueError`` when a stencil spans more than 0.9 of the group's
            injectivity radius (the grid does not resolve the frame field).

        Returns
        -------
        numpy.ndarray ``[*shape, d, r]``
        """
        g = self.group
        Phi = np.asarray(Phi, dtype=float)
        Phi_inv = g.inverse(Phi)
        out = np.empty((*self.grid.shape, self.grid.d, g.dim))
        worst = 0.0
        for axis, D in enumerate(self.D_strain):
            if D.kind == "fourier":
                out[..., axis, :] = g.vee(Phi_inv @ D(Phi, axis=axis))
                if check:
                    nxt = np.roll(Phi, -1, axis=axis)
                    worst = max(worst, float(np.max(g.log_domain_norm(g.log(g.compose(Phi_inv, nxt))))))
                continue
            P = np.moveaxis(Phi, axis, 0)
            Pi = np.moveaxis(Phi_inv, axis, 0)
            X = np.zeros((*P.shape[:-2], g.dim))
            (off, c), boundary = D.rows()
            n = D.n
            # every stencil term as a pair (node i, node i + o, coefficient): one compose and
            # one log for all of them, summed into node i in the order of the terms (the
            # interior stencil's terms, then the closure rows')
            nodes = np.arange(n)
            if D.periodic:
                target = np.tile(nodes, len(off))
                source = np.concatenate([np.roll(nodes, -o) for o in off])
                coef = np.repeat(c, n)
            else:
                b = D.halfwidth
                inner = nodes[b:n - b]
                terms = [(inner, inner + o, np.full(inner.size, ck)) for o, ck in zip(off, c, strict=True)]
                terms += [(np.array([i]), np.array([i + o]), np.array([ck])) for i, o_row, c_row in boundary
                          for o, ck in zip(o_row, c_row, strict=True) if o != 0]
                target, source, coef = (np.concatenate(parts) for parts in zip(*terms, strict=True))
            xi = g.log(g.compose(Pi[target], P[source]))
            np.add.at(X, target, coef.reshape(-1, *(1,) * (xi.ndim - 1)) * xi)
            if check and xi.size:
                worst = max(worst, float(np.max(g.log_domain_norm(xi))))
            out[..., axis, :] = np.moveaxis(X, 0, axis)
        if check and worst > 0.9 * g.injectivity_radius:
            raise ValueError(
                "initial.Phi changes too fast along the grid: a difference stencil spans a relative "
                f"rotation of {worst:.3g} > 0.9·{g.injectivity_radius:.3g}; refine the grid"
            )
        return out

    # ------------------------------------------------------------------ constrained strains
    def constraint_rows(self, unknown: np.ndarray, state: State):
        """:meth:`Scheme.constraint_rows` on the nodal strains: one row per node, axis and held
        component, ``c = X_{α,i}[k] − value_k``, with ``B_c δ = [D_α δ + ad_{X_α} δ]_k`` of the
        compatibility equation (paper §III), less the combinations dependent at the straight
        (or flat) reference (the odd–even mode of each open line of a filament; none on a
        Kirchhoff–Love surface, d = 2; found with every live component free:
        :class:`cartan.constraints.NodalStrainConstraints`, "Rank").  Clamped, free and
        :class:`~cartan.problem.Held` ends and :class:`~cartan.problem.Symmetry` faces: the held
        components are columns left out of ``B_c``, as a clamped node's."""
        from ..constraints import NodalStrainConstraints

        return NodalStrainConstraints(self, unknown, state)

    # ------------------------------------------------------------------ state
    def initial_state(self) -> State:
        """X₀ = Φ₀⁻¹∂Φ₀ by :meth:`strain_from_frames`, S₀ = ∂K/∂N(N₀), frames as configured."""
        Phi = self.problem.initial.Phi
        return self._new_state({"X": self.strain_from_frames(Phi, check=True)})

    def strains(self, state: State) -> np.ndarray:
        """The stored nodal strains ``[*shape, d, r]``."""
        return state.arrays["X"]

    def nodal_strains(self, state: State) -> np.ndarray:
        """The stored nodal strains ``[*shape, d, r]`` (the scheme's unknowns)."""
        return state.arrays["X"]

    def nodal_rest_strains(self) -> np.ndarray | None:
        """The rest strains of the ``reference`` at the nodes ``[*shape, d, r]``, or None."""
        return self.rest

    # ------------------------------------------------------------------ forces
    def _end_load(self, Phi: np.ndarray | None, b: Free | Held | Symmetry, idx: tuple) -> np.ndarray:
        """Body components of the load P of a free end (dead loads rotated by Φ there); zero
        at a held end or a symmetry face (the natural condition on their free components)."""
        shape = (*self.weights[idx].shape, self.group.dim)
        if _load_of(b) is None:
            return np.zeros(shape)
        if b.follower:
            return np.broadcast_to(b.load, shape)
        return dead_to_body(self.group, Phi[idx], b.load)

    def internal_force(self, state: State, Phi: np.ndarray | None = None) -> np.ndarray:
        """``D*_α Q^α = Σ_α ∂_αQ^α − ad_{X_α}ᵀ Q^α`` plus the boundary terms ``[*shape, r]``.

        At a free end of axis α the natural condition n_α Q^α = P enters as the
        simultaneous-approximation term ``(P − n_α Q^α)/H_end`` (H_end the end weight of
        the axis); ``Phi`` is needed only for dead end loads.
        """
        g = self.group
        X = state.arrays["X"]
        if self.coupled_lagrangian:  # ℓ(N, X): the Hamiltonian stress ∂H/∂X(S_i, X_i) (_collocation_coupled)
            Q = self.medium.stress_with(state.S, X)
        else:
            Q = self.medium.stress(X) if self.rest is None else self.medium.stress_at(X, self.rest)
        W = np.zeros((*self.grid.shape, g.dim))
        for axis, D in enumerate(self.D):
            Qa = Q[..., axis, :]
            W += D(Qa, axis=axis)
            W -= np.einsum("...ji,...j->...i", g.ad(X[..., axis, :]), Qa)
        for axis, idx, sign, H_end, b, _ in self._free_ends:
            W[idx] += (self._end_load(Phi, b, idx) - sign * Q[idx][..., axis, :]) / H_end
        if self._inv_volume is not None:  # per unit reference volume on a general chart
            W *= self._inv_volume[..., None]
        return W

    def force(self, state: State, N: np.ndarray, t: float, raw: bool = False) -> np.ndarray:
        """The force density W ``[*shape, r]`` (:meth:`internal_force` plus the loads and the
        medium's body force), zero at the clamped nodes and held components.

        ``raw``: not zeroed there, and at the clamped and driven ends with the natural condition's term
        ``−n_α Q^α/H_end`` of an unloaded end (:meth:`_clamped_traction`), so that ``wW`` is the
        force of the body and the loads on the held components, ``−Lᵀ(wQ)`` plus the loads (the
        supports balance it: :meth:`support_reaction`)."""
        Phi = self.frames(state) if self.problem.needs_structure_field else None
        W = self.internal_force(state, Phi)
        if raw:
            W += self._clamped_traction(state)
        for load in self.problem.loads:
            W += load.force(Phi, N, t)
        T = self.medium.body_force(Phi, N, t)
        if T is not None:
            W += T
        if not raw:
            W[self._clamped] = 0.0
        W[..., ~self.live] = 0.0
        return W

    def _clamped_traction(self, state: State) -> np.ndarray:
        """``[*shape, r]``: ``−n_α Q^α/H_end`` at the nodes of the clamped and driven ends (per unit reference
        volume on a general chart), zero elsewhere.

        With it the clamped nodes' force is the weak form of a free end's, ``wW = −Lᵀ(wQ)`` plus
        the loads (L = D_α + ad_{X_α}, summation by parts: ``H D + (H D)ᵀ = diag(−1, 0, …, 0,
        1)``), i.e. minus the derivative of the energy Σ w U(X) along the clamped node's drift —
        the force the body exerts on it.  Without it the strong-form density ``D_αQ^α − ad_Xᵀ Q``
        at the node, times its weight O(h), misses the end's stress: the traction the clamp
        transmits (paper §IV.D, ``n_α Q^α = P`` with P the support's load)."""
        W = np.zeros((*self.grid.shape, self.group.dim))
        ends = []
        for axis, D in enumerate(self.D):
            if self.grid.periodic[axis]:
                continue
            for side, idx, sign in (("start", 0, -1.0), ("end", -1, 1.0)):
                if isinstance(self.problem.boundary(axis, side), Clamped | Driven):
                    sl = [slice(None)] * self.grid.d
                    sl[axis] = idx
                    ends.append((axis, tuple(sl), sign, float(D.norm()[idx])))
        if not ends:
            return W
        X = state.arrays["X"]
        for axis, idx, sign, H_end in ends:  # the stress at the end's nodes only
            if self.coupled_lagrangian:  # ℓ(N, X): the Hamiltonian stress (_collocation_coupled)
                Q = self.medium.stress_with(state.S[idx], X[idx])
            else:
                Q = self.medium.stress(X[idx]) if self.rest is None else self.medium.stress_at(X[idx], self.rest[idx])
            W[idx] -= sign * Q[..., axis, :] / H_end
        if self._inv_volume is not None:
            W *= self._inv_volume[..., None]
        return W

    def _boundary_power(self, state, N, Phi):
        p = 0.0
        for _, idx, _, _, b, face in self._end_loads:
            P = self._end_load(Phi, b, idx)
            p += float(np.sum(face * np.einsum("...k,...k->...", P, N[idx])))
        return p

    # ------------------------------------------------------------------ drift
    def drift(self, state: State, tau: float, N: np.ndarray, exact: bool = True) -> None:
        g = self.group
        arr = state.arrays
        X = arr["X"]
        N = np.asarray(N, dtype=float)
        if exact:
            # paper §V: X⁺ = Ad_{exp(−τN)} X + 𝓔(τ, −N) ∂N, Φ⁺ = Φ exp(τN)
            expN = g.exp(tau * N)
            Ad = g.Ad(g.inverse(expN))
            E = g.E(tau, -N)
            Xn = np.empty_like(X)
            for axis, D in enumerate(self.D):
                Xn[..., axis, :] = (np.einsum("...ij,...j->...i", Ad, X[..., axis, :])
                                    + np.einsum("...ij,...j->...i", E, D(N, axis=axis)))
            arr["X"] = Xn
            if "Phi" in arr:
                arr["Phi"] = g.compose(arr["Phi"], expN)
            else:
                root = (0,) * self.grid.d
                arr["Phi_root"] = g.compose(arr["Phi_root"], expN[root])
            return
        # naive Euler: X ← X + τ(∂N − ad_N X), Φ ← Φ + τΦN̂ (leaves the group)
        Xn = np.empty_like(X)
        for axis, D in enumerate(self.D):
            Xa = X[..., axis, :]
            Xn[..., axis, :] = Xa + tau * (D(N, axis=axis) - g.bracket(N, Xa))
        arr["X"] = Xn
        Nh = g.hat(tau * N)
        if "Phi" in arr:
            arr["Phi"] = arr["Phi"] + arr["Phi"] @ Nh
        else:
            root = (0,) * self.grid.d
            arr["Phi_root"] = arr["Phi_root"] + arr["Phi_root"] @ Nh[root]

    # ------------------------------------------------------------------ output and diagnostics
    def frames(self, state: State) -> np.ndarray:
        """Φ ``[*shape, m, m]``: the stepped frames, or the trapezoidal reconstruction
        ``Φ_{i+1} = Φ_i exp(h(X_i + X_{i+1})/2)`` from the root node, axis by axis
        (second order in h whatever the derivative operator)."""
        if "Phi" in state.arrays:
            return state.arrays["Phi"]
        g = self.group
        X = state.arrays["X"]
        d = self.grid.d
        P = state.arrays["Phi_root"]
        for axis in range(d):
            # strains along this axis on the sub-grid whose later indices are 0
            sl = tuple([slice(None)] * (axis + 1) + [0] * (d - axis - 1))
            Xa = np.moveaxis(X[sl][..., axis, :], axis, 0)
            steps = g.exp(0.5 * self.h[axis] * (Xa[:-1] + Xa[1:]))
            P = np.moveaxis(prefix_products(P, steps), 0, axis)
        return P

    def potential_energy(self, state: State) -> float:
        """``Σ_i w_i U(X_i)`` plus conservative-load energies; w the scheme's quadrature
        weights (:attr:`chart_weights`: trapezoidal, except the SBP norm on open fd4 axes), the
        loads' energies (per unit reference volume) weighed by :attr:`weights`."""
        X = state.arrays["X"]
        U = self.medium.potential(X) if self.rest is None else self.medium.potential_at(X, self.rest)
        V = float(np.sum(self.chart_weights * U))
        conservative = [load for load in self.problem.loads if load.conservative]
        if conservative:
            Phi = self.frames(state)
            for load in conservative:
                V += float(np.sum(self.weights * load.energy(Phi)))
        return V

    def integrability_residual(self, state: State) -> float:
        """Temporal integrability residual (VERIFICATION.md §1).

        With stepped frames: ``max_i |X_i(stored) − X_i(Φ)|`` with X(Φ) from
        :meth:`strain_from_frames`.  It is round-off at t = 0 (the initial strains are
        computed that way) and grows by O(Δt·hᵖ) per step — a rate O(hᵖ) per unit time,
        independent of Δt — because the discrete ∂ has no exact product rule (near open
        ends the rate is set by the order p/2 of the boundary rows of the dynamics).  The
        growth is the quantity of interest; ``lattice`` keeps it at round-off.  Without
        stepped frames Φ is rebuilt from X, so the only check left is the ring closure of
        periodic axes (:meth:`closure_residual`).
        """
        if "Phi" not in state.arrays:
            return self.closure_residual(state)
        Xr = self.strain_from_frames(state.arrays["Phi"])
        return float(np.max(np.abs(state.arrays["X"] - Xr)))

    def spatial_residual(self, state: State) -> float:
        """Continuum spatial integrability residual (paper §III.C), max over nodes and axis pairs
        of |Δ_αβ| with Δ_αβ = D_βX_α − D_αX_β − [X_α, X_β] by the scheme's difference operators:
        O(hᵖ) for smooth fields, and the paper's law ∂_tΔ = [Δ, N] keeps it near its initial value."""
        X = state.arrays["X"]
        g = self.group
        res = 0.0
        for a in range(self.grid.d):
            for b in range(a + 1, self.grid.d):
                delta = self.D[b](X[..., a, :], axis=b) - self.D[a](X[..., b, :], axis=a) - g.bracket(
                    X[..., a, :], X[..., b, :])
                res = max(res, float(np.max(np.abs(delta))))
        return res

    def closure_residual(self, state: State) -> float:
        """``‖log ∏ exp(h(X_i + X_{i+1})/2)‖`` around every periodic axis (0 when none is).

        The trapezoidal holonomy of the nodal strains: O(h²) for a smooth closed
        configuration (not zero: the reconstruction is second order)."""
        g = self.group
        X = state.arrays["X"]
        res = 0.0
        for axis in range(self.grid.d):
            if not self.grid.periodic[axis]:
                continue
            Xa = np.moveaxis(X[..., axis, :], axis, 0)
            G = g.exp(0.5 * self.h[axis] * (Xa + np.roll(Xa, -1, axis=0)))
            prod = G[0]
            for k in range(1, G.shape[0]):
                prod = prod @ G[k]
            res = max(res, float(np.max(np.abs(g.log(prod)))))
        return res

