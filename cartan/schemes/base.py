"""The :class:`Scheme` contract: how a medium's fields live on a grid (ARCHITECTURE.md §3).

A scheme owns the storage of the configuration (strains X, structure field Φ) and
provides, generically over the group and the medium, the discrete operators the time
integrators need.  Integrators see only this interface:

``velocity(state)``
    N ``[*shape, r]`` from the momentum density S (gauge components and clamped ends zero,
    driven ends their prescribed velocity ξ);
``force(state, N, t)``
    W ``[*shape, r]``: the generalised force density D*_α Q^α + T, internal stresses, loads
    and boundary loads included, **excluding** the Lie–Poisson term ad*_N S, so that
    ``Ṡ = ad_Nᵀ S + W`` (paper §V, W = D*_u Q + T);
``drift(state, tau, N, exact=True)``
    advance the configuration along the flow Φ ← Φ exp(τN) with N frozen: exactly on the
    group (``exact=True``) or by the naive matrix update Φ ← Φ + τΦN̂ (``exact=False``, the
    paper's "forward Euler", which leaves the group);
``diagnostics(state)``
    energies, residuals and the output fields.

The momentum S is a *density* (per unit reference volume), like the paper's S; node masses
are the scheme's :attr:`Scheme.weights` (the grid's quadrature weights; on the lattice, the
nodes' reference volumes when the medium measures a general chart) times the medium's inertia.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from numba import njit

from .._backend import get_backend
from ..medium import Medium
from ..problem import Clamped, Driven, Problem, held_components
from ..state import State  # re-exported: its home is cartan.state

__all__ = ["Scheme", "State", "prefix_products"]


def prefix_products(first: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Prefix products ``P_0 = first, P_{k+1} = P_k steps_k`` along axis 0.

    ``first`` ``[..., m, m]``, ``steps`` ``[n−1, ..., m, m]`` → ``[n, ..., m, m]``; used to
    rebuild frames from a root frame and edge or midpoint increments (a spanning tree of the
    grid).  With the ``numba`` backend and float64 input the products run in one compiled
    pass, ``P_{k+1} = P_k steps_k`` in order (n matrix products, no temporaries);
    otherwise by doubling (Hillis–Steele scan: ⌈log₂ n⌉ batched numpy matrix products).  The
    two differ by round-off only: each P_k is a product of k + 1 matrices either way, with a
    relative error that grows like √k ulps for well-conditioned (e.g. orthogonal) factors.
    """
    first = np.asarray(first)
    steps = np.asarray(steps)
    if (
        first.dtype == np.float64
        and steps.dtype == np.float64
        and steps.shape[1:] == first.shape
        and first.ndim >= 2
        and get_backend() == "numba"
    ):
        m = first.shape[-1]
        batch = first.shape[:-2]
        acc = np.empty((steps.shape[0] + 1, *first.shape))
        acc[0] = first
        acc[1:] = steps
        _prefix_products_kernel(acc.reshape(acc.shape[0], -1, first.shape[-2], m))
        return acc.reshape((steps.shape[0] + 1, *batch, first.shape[-2], m))
    acc = np.concatenate([first[None], steps], axis=0)
    n = acc.shape[0]
    shift = 1
    while shift < n:
        acc[shift:] = acc[:-shift] @ acc[shift:]
        shift *= 2
    return acc


@njit(cache=True)
def _prefix_products_kernel(acc: np.ndarray) -> None:  # pragma: no cover - compiled
    """In place, ``acc [n, B, m, m]``: ``acc[k] ← acc[k − 1] acc[k]`` for k = 1 … n − 1."""
    n, nb, m, p = acc.shape
    tmp = np.empty((m, p))
    for k in range(1, n):
        for b in range(nb):
            for i in range(m):
                for j in range(p):
                    s = 0.0
                    for q in range(m):
                        s += acc[k - 1, b, i, q] * acc[k, b, q, j]
                    tmp[i, j] = s
            for i in range(m):
                for j in range(p):
                    acc[k, b, i, j] = tmp[i, j]


class Scheme(abc.ABC):
    """Discretisation of a :class:`~cartan.Problem` on its grid (generic over group and medium).

    Subclasses set ``name`` and implement the abstract methods; the constructor receives
    the problem and scheme options (validated, ``ValueError`` naming the option).
    """

    name: ClassVar[str] = ""
    #: spatial order of accuracy (``math.inf`` for spectral differentiation)
    order: ClassVar[float] = 2
    #: where :meth:`strains` lives: ``"edge"`` (between nodes) or ``"node"``
    strain_location: ClassVar[str] = "node"
    #: whether work outside the step loop (the CFL estimate :meth:`dt_max`, the blow-up
    #: guard's energies in :func:`cartan.simulate`) may use compiled kernels when the scheme
    #: has them; ``cartan.simulate(..., compiled=False)`` clears it on its scheme
    compiled_diagnostics: bool = True
    #: the smallest problem (nodes × algebra dimension) whose diagnostics use compiled kernels
    #: (:meth:`uses_compiled_diagnostics`; docs/performance.md, "Work around the steps"): the
    #: CFL estimate of an SE(3) rod costs the same in numpy and compiled at 10⁴ nodes
    #: (0.26–0.68 s against 0.23–0.29 s), and below that the compiled kernels save milliseconds
    #: per run but compile for ≈ 76 s on a fresh cache
    compiled_diagnostics_from: int = 60_000
    #: whether the scheme steps media whose Lagrangian couples N and X
    #: (:attr:`cartan.medium.Medium.coupled_lagrangian`, :mod:`cartan.schemes._coupled`); the others refuse them
    supports_coupled_lagrangian: ClassVar[bool] = False
    #: the module that discretises such a Lagrangian on this scheme: its ``coupled_velocity(scheme,
    #: state)``, ``initial_momentum(scheme, state, N, start=None)`` and ``kinetic_part(scheme, state)``
    #: give :meth:`velocity`, :meth:`momentum` and :meth:`kinetic_energy` (the lattice's half edges,
    #: :mod:`cartan.schemes._coupled`; the collocation's nodes, :mod:`cartan.schemes._collocation_coupled`)
    coupled_module: ClassVar[str] = "cartan.schemes._coupled"
    #: whether the scheme moves :class:`~cartan.problem.Driven` ends
    supports_driven_ends: ClassVar[bool] = False
    #: whether the scheme's ``force`` takes ``raw=True`` (the force density before the held
    #: nodes' is zeroed: :meth:`support_reaction`)
    gives_raw_force: ClassVar[bool] = False

    def __init__(self, problem: Problem, **options: Any):
        if options:
            raise ValueError(f"scheme {self.name!r} takes no option(s) {sorted(options)}")
        if getattr(problem.medium, "coupled_lagrangian", False) and not (
                self.supports_coupled_lagrangian and problem.grid.d == 1):
            raise ValueError(f"medium {problem.medium.name!r} has a Lagrangian that couples N and X; scheme "
                             f"{self.name!r} does not step such media (the 'lattice' and the 'collocation' do, "
                             "for d = 1)")
        self.problem = problem
        self.medium = problem.medium
        self.group = problem.medium.group
        self.grid = problem.grid
        self.mass = self.medium.inertia()  # (r,), the diagonal of the kinetic metric
        self.live = ~np.asarray(self.medium.gauge_mask(), dtype=bool)
        #: N = M⁺S: the inverse kinetic metric on the live block (r, r); diagonal for most media
        self.inverse_metric = self.medium.inverse_metric()
        self.diagonal_metric = not np.any(self.inverse_metric - np.diag(np.diag(self.inverse_metric)))
        self.weights = self.grid.node_weights()  # [*shape]
        self._clamped = self._clamp_mask()
        #: the driven nodes ``(*shape)`` bool and their velocity ξ and momentum ∂K/∂N(ξ)
        #: ``(*shape, r)`` (zero elsewhere), or None without :class:`~cartan.problem.Driven` ends
        self._driven = self._driven_velocity()

    def _driven_velocity(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """``(mask, N, S)`` of the problem's :class:`~cartan.problem.Driven` ends (see
        ``_driven``), or None.

        Raises
        ------
        ValueError
            A driven end on a scheme without them (:attr:`supports_driven_ends`) or with a
            medium whose Lagrangian couples N and X.
        """
        ends = [(axis, side, b) for axis in range(self.grid.d)
                if not (self.grid.periodic[axis] or self.grid.is_glued(axis)) for side in ("start", "end")
                if isinstance(b := self.problem.boundary(axis, side), Driven)]
        if not ends:
            return None
        if not self.supports_driven_ends:
            raise ValueError(f"scheme {self.name!r} does not move Driven ends; use scheme='lattice' or 'collocation'")
        if self.coupled_lagrangian:
            raise ValueError(f"a Driven end is not supported with a Lagrangian that couples N and X (medium "
                             f"{self.medium.name!r}, Medium.coupled_lagrangian)")
        mask = np.zeros(self.grid.shape, dtype=bool)
        N = np.zeros((*self.grid.shape, self.group.dim))
        for axis, side, b in ends:
            sl = [slice(None)] * self.grid.d
            sl[axis] = 0 if side == "start" else -1
            if np.any(mask[tuple(sl)] & np.any(N[tuple(sl)] != b.velocity, axis=-1)):
                raise ValueError(f"boundaries: two Driven ends meet at a corner with different velocities (the "
                                 f"{self.grid.axis_names[axis]}-{side} face); give them the same velocity")
            mask[tuple(sl)] = True
            N[tuple(sl)] = b.velocity
        S = np.where(mask[..., None], self.medium.momentum(N), 0.0)
        S[..., ~self.live] = 0.0
        return mask, N, S

    def uses_compiled_diagnostics(self) -> bool:
        """Whether the CFL estimate (:meth:`stiffness_probe`) and the blow-up guard's energies
        run on compiled kernels: :attr:`compiled_diagnostics` is set and the problem has at
        least :attr:`compiled_diagnostics_from` unknowns (nodes × dim 𝔤)."""
        return bool(self.compiled_diagnostics) and not self.coupled_lagrangian and (
            int(np.prod(self.grid.shape)) * self.group.dim >= self.compiled_diagnostics_from)

    # ------------------------------------------------------------------ contract
    @abc.abstractmethod
    def initial_state(self) -> State:
        """State at t = 0 from ``problem.initial``."""

    @abc.abstractmethod
    def force(self, state: State, N: np.ndarray, t: float) -> np.ndarray:
        """Generalised force density W ``[*shape, r]`` (see module docstring)."""

    @abc.abstractmethod
    def drift(self, state: State, tau: float, N: np.ndarray, exact: bool = True) -> None:
        """Advance the configuration in place along Φ ← Φ exp(τN) (see module docstring)."""

    @abc.abstractmethod
    def frames(self, state: State) -> np.ndarray:
        """Structure field Φ ``[*shape, m, m]`` (reconstructed when not stepped)."""

    @abc.abstractmethod
    def strains(self, state: State) -> np.ndarray:
        """Strain field as stored by the scheme, ``[*edge-or-node shape, d, r]`` (output)."""

    @abc.abstractmethod
    def nodal_strains(self, state: State) -> np.ndarray:
        """Strain field at the nodes ``[*shape, d, r]`` (for prescribed velocities N(t, u, X))."""

    @abc.abstractmethod
    def potential_energy(self, state: State) -> float:
        """Discrete internal potential energy plus conservative-load energies."""

    @abc.abstractmethod
    def integrability_residual(self, state: State) -> float:
        """Temporal integrability residual: stored X against X recomputed from Φ."""

    def constraint_rows(self, unknown: np.ndarray, state: State) -> Any:
        """The medium's constrained strain rows on this scheme (``rattle``'s rows, paper §III.E,
        §IV.E): an object with ``ncon``, ``values(state)`` (c ``[ncon]``), ``matrix(state)``
        (B_c, sparse ``(ncon, nunk)``: the rows' rate along the drift of the unknowns),
        ``fixed_rate`` and ``fixed_force`` (the held nodes' part), as
        :class:`cartan.constraints.StrainConstraints`; ``rows_rate(state, N)`` (Ḃ_c N) and
        ``exact_rate = True`` when the scheme gives that rate in closed form.

        Parameters
        ----------
        unknown : array of bool ``[*shape, r]``
            The node components that move (live, not clamped).
        state : State

        Raises
        ------
        ValueError
            Here: the scheme holds no strain rows (a scheme that does overrides this).
        """
        raise ValueError(f"integrator 'rattle' holds the constrained strains on the scheme's rows (the lattice's "
                         f"edge strains, the collocation's nodal strains); scheme {self.name!r} has none: "
                         "use scheme='lattice' or scheme='collocation'")

    # ------------------------------------------------------------------ shared
    def _run_compiled(self, module: str, integrator: Any, state: State, dt: float, nsteps: int,
                      kinetic_limit: float) -> bool:
        """The body of a scheme's ``compiled_advance``: build its compiled plan once
        (``cartan.schemes.<module>.build_plan(self)``, None when the problem does not qualify)
        and run ``<module>.advance``; False when the numpy backend is selected or the problem
        does not qualify (nothing touched), and at once, before any plan is built, when the
        module's optional ``may_run(integrator)`` says its loops never take that integrator."""
        import importlib

        plans = importlib.import_module(f"{__package__}.{module}")
        may_run = getattr(plans, "may_run", None)
        if may_run is not None and not may_run(integrator):
            return False
        plan = None if self.coupled_lagrangian else self.compiled_plan(module)
        if plan is None:
            return False
        return plans.advance(self, plan, integrator, state, dt, nsteps, kinetic_limit)

    def compiled_operators(self):
        """The scheme's compiled operator set for its problem
        (:class:`cartan.compiled.operators.OperatorSet`), or None when the scheme has none.

        The integrators' generated loops (:meth:`cartan.integrators.base.Integrator.run_compiled_loop`)
        call these operators; a declined set says why in ``reason``.  Built once per scheme.
        """
        return None

    def compiled_plan(self, module: str) -> tuple | None:
        """The compiled plan of this scheme's problem, built once by
        ``cartan.schemes.<module>.build_plan(self)`` and kept on the scheme; None with the
        numpy backend or when the problem does not qualify."""
        if get_backend() != "numba":
            return None
        plan = self.__dict__.get("_compiled_plan", False)
        if plan is False:
            import importlib

            plan = self._compiled_plan = importlib.import_module(f"{__package__}.{module}").build_plan(self)
        return plan

    #: the module of the scheme's hand-written compiled loops (``compiled_advance``), if any
    plan_module: ClassVar[str | None] = None
    #: the module of the diagnostics on that plan (``compiled_stiffness_probe(scheme, state,
    #: eps)``, None where the plan does not cover the problem), imported by name, if any
    diagnostics_module: ClassVar[str | None] = None

    def has_hand_written_loops(self) -> bool:
        """Whether the scheme's hand-written compiled loops cover this problem (the lattice's
        SE(3) rods: ``lie-verlet`` and ``overdamped`` of order 1 take their steps there, the
        other integrators the generated loops); then the diagnostics around the steps use
        their plan, and no operator-set module is compiled for them."""
        return self.plan_module is not None and self.compiled_plan(self.plan_module) is not None

    def _reference_volumes(self, rest: np.ndarray) -> np.ndarray | None:
        """J ``[*shape]``, the nodes' reference volume per unit chart volume
        (:meth:`~cartan.medium.Medium.reference_volume` at the nodal rest strains ``rest``), or None
        for a medium that does not measure its chart.  Where J ≡ 1 (an orthonormal chart) the
        callers keep the chart's weights to the bit.

        Raises
        ------
        ValueError
            J not finite and > 0 at every node.
        """
        if type(self.medium).reference_volume is Medium.reference_volume:
            return None
        J = self.medium.reference_volume(rest)
        if J is None:
            return None
        J = np.asarray(J, dtype=float)
        if J.shape != tuple(self.grid.shape) or not np.all(np.isfinite(J) & (J > 0)):
            raise ValueError(f"medium {self.medium.name!r}: reference_volume must be finite and > 0 at every node, "
                             f"shape {tuple(self.grid.shape)}")
        return J

    def _clamp_mask(self) -> np.ndarray:
        """The held nodes and components: the clamped and driven nodes ``(*shape)`` bool, or,
        with :class:`~cartan.problem.Symmetry` faces or :class:`~cartan.problem.Held` ends, the
        held body components ``(*shape, r)`` bool (:func:`~cartan.problem.held_components`, all
        r at the clamped and driven nodes).  Either indexes the ``(*shape, r)`` velocities,
        momenta and forces that are zeroed there (paper §IV.D: N = 0 on the held components,
        whose force is the support's reaction); :meth:`held_nodes` gives the wholly held nodes.

        Raises
        ------
        ValueError
            From :func:`~cartan.problem.held_components`: a held set that is not a subalgebra,
            a kinetic metric coupling held and free components, a symmetry face off SE(3).
        """
        mask = np.zeros(self.grid.shape, dtype=bool)
        for axis in range(self.grid.d):
            if self.grid.periodic[axis]:
                continue
            for side, idx in (("start", 0), ("end", -1)):
                if isinstance(self.problem.boundary(axis, side), Clamped | Driven):
                    sl = [slice(None)] * self.grid.d
                    sl[axis] = idx
                    mask[tuple(sl)] = True
        held = held_components(self.problem)
        if held is None:
            return mask
        held[mask] = True
        return held

    def _new_state(self, arrays: dict[str, np.ndarray]) -> State:
        """State at t = 0 with the scheme's configuration ``arrays``: adds the frames (all of
        them when ``self.track`` is set, else the root node's), S₀ = ∂K/∂N(N₀), constraints."""
        Phi = self.problem.initial.Phi
        if getattr(self, "track", True):
            arrays["Phi"] = Phi.copy()
        else:
            arrays["Phi_root"] = Phi[(0,) * self.grid.d].copy()
        S = self.medium.momentum(self.problem.initial.N)
        state = State(0.0, np.ascontiguousarray(S, dtype=float), arrays)
        if self.coupled_lagrangian:  # S₀ such that N(S₀, X) = N₀ (the discrete Legendre map)
            state.S = self._coupled().initial_momentum(self, state, self.problem.initial.N)
        self.constrain(state)
        return state

    @property
    def coupled_lagrangian(self) -> bool:
        """Whether the medium's Lagrangian couples N and X (:mod:`cartan.schemes._coupled`)."""
        return bool(getattr(self.medium, "coupled_lagrangian", False))

    def _coupled(self) -> Any:
        """The module :attr:`coupled_module` (imported on first use)."""
        import importlib

        return importlib.import_module(self.coupled_module)

    def momentum(self, state: State, N: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
        """The node momenta S ``[*shape, r]`` whose velocity (:meth:`velocity`) at ``state``'s
        configuration is ``N``: ∂K/∂N, or the inverse of the discrete Legendre map of
        :mod:`cartan.schemes._coupled` for a coupled Lagrangian (``start``: a nearby solution
        as its first iterate; the root is the same).

        Raises
        ------
        ValueError
            Where the Legendre map has no inverse (a coupled Lagrangian outside its range).
        """
        if self.coupled_lagrangian:
            return self._coupled().initial_momentum(self, state, N, start=start)
        return self.medium.momentum(N)

    def velocity(self, state: State) -> np.ndarray:
        """N = ∂K*/∂S with gauge components and clamped nodes held at zero (N = ∂H_d/∂S, the
        discrete Legendre map of :mod:`cartan.schemes._coupled`, for a coupled Lagrangian)."""
        if self.coupled_lagrangian:
            N = self._coupled().coupled_velocity(self, state)
        else:
            N = self.medium.velocity(state.S)
        if self._clamped.any():
            N[self._clamped] = 0.0
        if self._driven is not None:
            mask, Nd, _ = self._driven
            N[mask] = Nd[mask]
        return N

    def constrain(self, state: State) -> None:
        """Zero the momentum of clamped nodes and gauge components, set that of driven nodes to
        ∂K/∂N(ξ) (after a kick)."""
        state.S[..., ~self.live] = 0.0
        if self._clamped.any():
            state.S[self._clamped] = 0.0
        if self._driven is not None:
            mask, _, Sd = self._driven
            state.S[mask] = Sd[mask]

    def kinetic_energy(self, state: State) -> float:
        if self.coupled_lagrangian:  # H_d − Σ w U(X): the kinetic part of the discrete Hamiltonian
            return self._coupled().kinetic_part(self, state)
        N = self.velocity(state)
        return float(np.sum(self.weights * self.medium.kinetic(N)))

    def powers(self, state: State, N: np.ndarray, t: float) -> dict[str, float]:
        """Instantaneous dissipated power and external (non-potential) power."""
        dissipated = 0.0
        external = 0.0
        Phi = self.frames(state) if self.problem.needs_structure_field else None
        for load in self.problem.loads:
            if load.conservative:
                continue
            p = float(np.sum(self.weights * np.einsum("...k,...k->...", load.force(Phi, N, t), N)))
            if load.dissipative:
                dissipated -= p
            else:
                external += p
        T = self.medium.body_force(Phi, N, t)
        if T is not None:
            external += float(np.sum(self.weights * np.einsum("...k,...k->...", T, N)))
        external += self._boundary_power(state, N, Phi)
        if self._driven is not None:
            external += self._driven_power(state, N, t)
        return {"dissipated": dissipated, "external": external}

    def _driven_power(self, state: State, N: np.ndarray, t: float) -> float:
        """The power R·ξ of the driven ends' reactions (:meth:`support_reaction`); kept for the
        state it was computed at (an integrator books the powers at the end of a step and again
        at the start of the next, on the same state: one force evaluation for both)."""
        key = (id(state), id(state.S), state.t, state.scalars.get("nstep", 0), t)
        cached = self.__dict__.get("_driven_power_at")
        if cached is not None and cached[0] == key:
            return cached[1]
        mask, Nd, _ = self._driven
        p = float(np.sum(self.support_reaction(state, N, t)[mask] * Nd[mask]))
        self._driven_power_at = (key, p)
        return p

    def held_nodes(self) -> np.ndarray:
        """The nodes held in every component, ``[*shape]`` bool: clamped and driven ends (the
        clamp mask holds both; a :class:`~cartan.problem.Held` end holds only some components)."""
        return self._clamped if self._clamped.ndim == self.grid.d else self._clamped.all(axis=-1)

    def support_reaction(self, state: State, N: np.ndarray | None = None, t: float | None = None) -> np.ndarray:
        """The generalised force the supports exert on their wholly held nodes (clamped and
        driven ends), body components, ``[*shape, r]``; zero at the other nodes.

        At such a node the momentum S is prescribed (zero, or ∂K/∂N(ξ) at a driven end, constant
        in the body frame), so its balance ``w Ṡ = w(ad_NᵀS + W) + R`` (paper §V) gives the
        reaction ``R = −w(W + ad_NᵀS)``, with W the force density of the rest of the body, the
        loads and the boundary loads on the node (:meth:`force` before it is zeroed there) and w
        the node's weight.  Its power at a driven end is ``R·ξ = −w W·ξ`` (⟨ad_ξᵀS, ξ⟩ = 0),
        the work booked as ``external_work``.

        Parameters
        ----------
        state : State
        N : numpy.ndarray, shape ``[*shape, r]``, optional
            The velocity (default :meth:`velocity` of ``state``).
        t : float, optional
            The time of the forces (default ``state.t``).

        Raises
        ------
        ValueError
            On a scheme whose :meth:`force` does not give the force before the held nodes'
            (:attr:`gives_raw_force` False).
        """
        if not self.gives_raw_force:
            raise ValueError(f"scheme {self.name!r} does not give the supports' reactions; use scheme='lattice'")
        N = self.velocity(state) if N is None else N
        W = self.force(state, N, state.t if t is None else t, raw=True)
        R = -self.weights[..., None] * (W + np.einsum("...ji,...j->...i", self.group.ad(N), state.S))
        R[~self.held_nodes()] = 0.0
        R[..., ~self.live] = 0.0
        return R

    def _boundary_power(self, state: State, N: np.ndarray, Phi: np.ndarray | None) -> float:
        return 0.0

    def spatial_residual(self, state: State) -> float:
        """Spatial integrability residual (paper §III.C) for d ≥ 2; 0 for d = 1.

        Schemes report their own measure: the lattice the plaquette holonomies, collocation
        the continuum residual Δ_αβ = ∂_βX_α − ∂_αX_β − [X_α, X_β].
        """
        return 0.0

    def has_external_power(self) -> bool:
        """True when loads, boundary loads or the medium's body force can do work (the
        integrator then books their power every step)."""
        return bool(self.problem.loads) or bool(getattr(self, "_end_loads", ())) or self._driven is not None or (
            type(self.medium).body_force is not Medium.body_force
        )

    def total_momentum(self, state: State) -> np.ndarray:
        """Total momentum in the spatial frame, ``Σ_i w_i Ad_{Φ_i}⁻ᵀ S_i`` ``(r,)`` — the
        momentum map of the left action, conserved by free media."""
        return self.total_momentum_of(state, self.frames(state))

    def total_momentum_of(self, state: State, Phi: np.ndarray) -> np.ndarray:
        """:meth:`total_momentum` with the frames Φ ``[*shape, m, m]`` of ``state`` given."""
        Adinv = self.group.Ad(self.group.inverse(Phi))
        spatial = np.einsum("...ji,...j->...i", Adinv, state.S)
        return np.tensordot(self.weights, spatial, axes=self.weights.ndim)

    def stiffness_probe(self, state: State, eps: float = 1e-7) -> Callable[[np.ndarray], np.ndarray]:
        """The action ``v ↦ K v`` of the stiffness (the force Jacobian) at ``state``.

        ``K v = −[W(Φ exp(εv)) − W(Φ exp(−εv))]/(2ε)`` with W = :meth:`force` at N = 0:
        central differences along the exact drift, in the left-trivialised directions (for
        conservative forces K is the Hessian of the discrete potential).  Used by :meth:`dt_max`.

        Parameters
        ----------
        state : State
            The linearisation point (not modified).
        eps : float
            Difference step (> 0).

        Returns
        -------
        callable
            ``probe(v)`` for v ``[*shape, r]`` → K v ``[*shape, r]`` (a new array).  When
            :meth:`uses_compiled_diagnostics` and the lattice scheme has a hand-written
            compiled plan for the problem (an SE(3) rod, ``docs/performance.md``), the passes of
            its loops; else,
            when the scheme's compiled operator set (:meth:`compiled_operators`) covers the
            problem and the state, its compiled operators
            (:func:`cartan.compiled.diagnostics.compiled_stiffness_probe`); otherwise
            :meth:`drift` and :meth:`force`.  All evaluate the same formulas (round-off apart).
        """
        if self.uses_compiled_diagnostics():
            import importlib

            from ..compiled.diagnostics import compiled_stiffness_probe as generated_probe

            # a hand-written plan first where the scheme has one (its kernels are compiled with
            # the loops that take the steps), then the operator set
            probes = []
            if self.diagnostics_module is not None:
                probes.append(importlib.import_module(f"{__package__}.{self.diagnostics_module}").compiled_stiffness_probe)
            if not self.has_hand_written_loops():
                probes.append(generated_probe)
            for compiled_probe in probes:
                probe = compiled_probe(self, state, eps)
                if probe is not None:
                    return probe
        zero = np.zeros((*self.grid.shape, self.group.dim))

        def probe(v: np.ndarray) -> np.ndarray:
            plus, minus = state.copy(), state.copy()
            self.drift(plus, eps, v)
            self.drift(minus, -eps, v)
            return -(self.force(plus, zero, state.t) - self.force(minus, zero, state.t)) / (2 * eps)

        return probe

    def dt_max(self, state: State, rate: str = "inertial", iterations: int = 40, eps: float = 1e-7) -> float:
        """Largest eigen-frequency based time-step estimate of the linearised semi-discrete
        system at ``state`` (power iteration on the force Jacobian; generic over schemes).

        ``rate="inertial"``: returns 1/ω_max with ω_max² = λ_max(M⁻¹K) (multiply by the
        integrator's stability constant, 2 for leapfrog).  ``rate="overdamped"``: returns
        1/λ_max(Γ⁻¹K) for the drag matrix Γ given by the problem's damping loads.

        The power iteration starts from a fixed pseudo-random vector (seed 0) and stops after
        ``iterations`` products with M⁻¹K (or Γ⁻¹K), or as soon as two successive Rayleigh
        quotients agree to 1e-3; typical rods stop after 17 or 18 products at any n, and the
        estimate lies within 1 % above the exact 1/ω_max (the Rayleigh quotient approaches
        λ_max from below).  Each product is one call of :meth:`stiffness_probe` (two force
        evaluations), compiled when the scheme has a compiled plan or operator set for the problem.

        Parameters
        ----------
        state : State
            Linearisation point (not modified).
        rate : {"inertial", "overdamped"}
        iterations : int
            Largest number of power iterations (≥ 1).
        eps : float
            Difference step of :meth:`stiffness_probe` (> 0).

        Returns
        -------
        float
            1/ω_max (inertial) or 1/λ_max (overdamped); 1e150 (1e300) when K vanishes.

        Raises
        ------
        ValueError
            For a ``rate``, ``iterations`` or ``eps`` outside the ranges above.
        """
        if rate not in ("inertial", "overdamped"):
            raise ValueError(f"rate must be 'inertial' or 'overdamped', got {rate!r}")
        if isinstance(iterations, bool) or int(iterations) != iterations or iterations < 1:
            raise ValueError(f"iterations must be an integer ≥ 1, got {iterations!r}")
        if not (np.isfinite(eps) and eps > 0):
            raise ValueError(f"eps must be finite and > 0, got {eps!r}")
        shape = (*self.grid.shape, self.group.dim)
        if rate == "inertial" and not self.diagonal_metric:
            inv = self.inverse_metric  # applied as a matrix below
        elif rate == "inertial":
            inv = np.where(self.live, 1.0 / np.where(self.live, self.mass, 1.0), 0.0)
        else:
            gam = self.drag()
            inv = np.where(gam > 0, 1.0 / np.where(gam > 0, gam, 1.0), 0.0)
        rng = np.random.default_rng(0)
        v = rng.standard_normal(shape) * (self.live if inv.ndim == 2 else (inv > 0))
        v[self._clamped] = 0.0
        lam = 0.0
        probe = self.stiffness_probe(state, eps)
        for _ in range(int(iterations)):
            nv = np.linalg.norm(v)
            if nv == 0:
                break
            v /= nv
            w = probe(v) @ inv.T if inv.ndim == 2 else inv * probe(v)
            w[self._clamped] = 0.0
            lam_new = float(np.vdot(v, w))
            v = w
            if lam and abs(lam_new - lam) < 1e-3 * abs(lam):
                lam = lam_new
                break
            lam = lam_new
        lam = max(abs(lam), 1e-300)
        return 1.0 / np.sqrt(lam) if rate == "inertial" else 1.0 / lam

    def drag(self) -> np.ndarray:
        """Drag coefficients Γ ``(r,)`` from the problem's :class:`~cartan.problem.Damping` loads."""
        from ..problem import Damping

        gam = np.zeros(self.group.dim)
        for load in self.problem.loads:
            if isinstance(load, Damping):
                gam = gam + load.coefficients
        return gam

    def options(self) -> dict[str, Any]:
        return {}
