"""The implicit midpoint Lie-group integrator ``implicit-midpoint`` (symplectic, A-stable).

Method
------
A variational (Hamilton–Pontryagin) integrator for the Hamiltonian system of paper §V,
``Φ̇ = ΦN``, ``Ṡ = ad_NᵀS + W`` with ``W = D*Q + T`` (``Ṡ + ad*_N S = W``), built from the
discrete Lagrangian with the exponential map and the force at the midpoint of the step::

    L_d(Φ_k, Φ_{k+1}) = Δt Σ_i w_i [K(ξ_i/Δt) − U(Φ_{k+½})],  Φ_{k+1} = Φ_k exp(ξ),
                                                           Φ_{k+½} = Φ_k exp(ξ/2).

One step from ``(Φ_k, S_k)`` solves, node by node, for ``ξ = Δt N_{k+½} ∈ 𝔤``::

    R(ξ) = dexp⁻¹_ξᵀ μ − Δt B(ξ)ᵀ W_{k+½} − S_k = 0,          (stage equation)
    μ = ∂K/∂N(ξ/Δt),   B(ξ) = (I + Ad_{exp(ξ/2)})⁻¹,
    W_{k+½} = W(Φ_k exp(ξ/2), ξ/Δt, t_k + Δt/2),

then sets ``Φ_{k+1} = Φ_k exp(ξ)`` (the scheme's exact drift; on the lattice the edges are
conjugated, so temporal integrability is exact) and::

    S_{k+1} = dexp⁻¹_{−ξ}ᵀ μ + Δt (I − B(ξ))ᵀ W_{k+½}.

``B(ξ)`` and ``I − B(ξ) = (I + Ad_{exp(−ξ/2)})⁻¹`` are the left-trivialised derivatives of the
midpoint ``Φ_k exp(ξ/2)`` with respect to Φ_k and Φ_{k+1}; they share the midpoint force
between the two ends of the step (``½`` each on an abelian group).  Non-conservative loads
(damping, follower loads, velocity-dependent body forces) enter by the discrete
Lagrange–d'Alembert principle with the same weights.

Properties
----------
* **order 2**: the discrete Lagrangian is symmetric (``Φ_{k+½}`` is also
  ``Φ_{k+1} exp(−ξ/2)``), so the method is time-reversible, hence of even order;
* **symplectic** on T*G (a discrete Lagrangian method) and, for loads that are conservative,
  with bounded energy error and no drift (backward error analysis); on an abelian group (a
  vector space) it *is* the classical implicit midpoint rule, which conserves every quadratic
  invariant — the energy of a linear problem exactly;
* **momentum maps**: ``L_d`` is invariant under Φ → gΦ when the potential is (no loads,
  free ends), so the total spatial momentum ``Σ w Ad_{Φ⁻¹}ᵀS`` (linear and angular momentum
  of a rod) is conserved exactly for the solved ``ξ`` — in practice to the Newton
  tolerance, since ``J(Φ_{k+1}, S_{k+1}) = J(Φ_k, S_k + R(ξ))`` identically;
* **stays in G** (round-off) and **A-stable**: no stability limit on Δt for the linearised
  undamped system (``stability = inf``).  Unresolved modes (Δt·ω ≫ 1) are neither damped
  nor, for nonlinear problems, energy-bounded: they flip sign every step, and a
  large-amplitude motion can feed them by resonance until the energy grows.  The usable Δt is
  set by that, by accuracy and by the convergence of Newton's method — far above the
  explicit limit when the stiff modes are slaved to a slow motion (thin rods bending:
  ``cartan_verification.stiff``).

Coupled Lagrangians
-------------------
For a medium whose reduced Lagrangian couples velocity and strain
(:attr:`~cartan.medium.Medium.coupled_lagrangian`, on the schemes that step it:
:mod:`cartan.schemes._coupled`) the discrete Lagrangian is

    L_d(Φ_k, Φ_{k+1}) = Δt L(ξ/Δt, X(Φ_{k+½})),    L(N, X) = sup_p [Σ_i p_i·N_i − H_d(p, X)],

the Legendre transform of the scheme's discrete Hamiltonian H_d (the semi-discrete system the
other integrators run).  Its discrete Euler–Lagrange equations are the stage equation above
with two pieces evaluated differently (:meth:`ImplicitMidpoint._residual`; compiled, the operator
set's ``op_stage_momentum`` and ``op_state_force``, :mod:`cartan.integrators.newton`):

* ``μ = ∂L/∂N(ξ/Δt, X_{k+½})`` per unit weight: the momenta S whose discrete velocity
  ``N_d(S, X_{k+½})`` at the midpoint configuration is ξ/Δt on the live components
  (:meth:`cartan.schemes.base.Scheme.momentum`, started from the previous stage's μ);
* ``W_{k+½}``: the scheme's force at the midpoint configuration carrying the momenta μ, whose
  stress is then the Hamiltonian one ``∂H_d/∂X(μ, X_{k+½}) = −∂L/∂X`` (envelope theorem).

The gauge components of ξ are not unknowns: they are Δt times those the medium fixes in
:meth:`~cartan.schemes.base.Scheme.velocity` at the start of the step (r⁰ = ct for the temporal gauge
of the elastic relativistic string; exact when the gauge value is a constant).  The method
stays symmetric (order 2) and symplectic, and its momentum maps change by the Newton residual
only.  A ξ for which the Legendre map has no inverse (outside the medium's range: an acausal
velocity) counts as outside the domain of the residual (a halving).  The compiled residual and
blocks run such media on the sets whose coupled point kernels the medium declares (the lattice's
half edges, the collocation's nodes): μ by Newton's method per node on the set's discrete
velocity from the step's momentum S_k
(:func:`cartan.integrators.newton.im_coupled_momentum`), to the tolerance of the numpy path's
inversion (started there from the previous stage's μ), so the two agree to round-off.

Newton's method
---------------
Unknowns: ξ at the live components of every non-clamped node; the initial guess is the
previous step's ξ (scaled by the ratio of the steps), else ΔtN_k.  The Jacobian ``∂R/∂ξ``
is assembled by coloured central finite differences (:func:`cartan.statics._coloured_jacobian`
with the colouring and stencil of :func:`cartan.statics._colouring` and
:func:`cartan.statics._stencil_pairs`: ``2·3^d·r`` residual evaluations on the lattice, whose
force has a nearest-neighbour stencil; on a glued chart, the sphere's, the greedy colouring of
the lattice's own edges and corners, :func:`cartan.statics._lattice_stencil`; the dense
pattern for other schemes, up to
:data:`MAX_DENSE_UNKNOWNS` unknowns) and factorised by sparse LU.  The factorisation is kept
across steps (modified Newton).  An iteration that reduces ``‖R‖_*`` by less than the factor
``contraction`` discards it, so the next iteration uses a fresh Jacobian at the current
iterate; an iterate that does not decrease ``‖R‖_*`` at all is rejected (kept Jacobian) or
halved up to :data:`MAX_HALVINGS` times (fresh Jacobian).  The Jacobian is also discarded
when Δt changes and at every :meth:`ImplicitMidpoint.begin_block` (called by
:func:`cartan.simulate` at each save block, where a restart can resume, so that a restarted
run is bit-for-bit identical to the uninterrupted one).

Converged when ``‖R‖_* ≤ tol·‖N_{k+½}‖_M`` with the kinetic-energy norms
``‖N‖_M² = Σ w m N²`` and ``‖R‖_*² = Σ w R²/m`` (a relative velocity error), when ``‖R‖_*``
is at the round-off level of its terms, or when a Newton increment is at the round-off level
of the configuration (``‖δξ‖_∞ ≤`` :data:`XTOL`·max(1, L)).  After ``max_iter`` iterations
without convergence, or when no decrease is found, the step raises
:class:`cartan.statics.ConvergenceError` and leaves the state untouched;
:func:`cartan.simulate` turns it into its :class:`~cartan.simulate.InstabilityError` with
the last good state saved.

Cost per step: 2–5 residual evaluations (one force evaluation, one drift to the midpoint and
batched ``r × r`` algebra each) plus, when the Jacobian is refreshed, ``2·3^d·r`` residual
evaluations and a sparse LU of a banded matrix (lattice, d = 1).

Compiled residual
-----------------
When the scheme has a compiled operator set for the problem
(:meth:`~cartan.schemes.base.Scheme.compiled_operators`: any group with point kernels, any
medium that declares point kernels, the loads the operators run) and
:attr:`~cartan.schemes.base.Scheme.compiled_diagnostics` is set, every residual evaluation —
those of the finite-difference Jacobian included — is one compiled call
(:mod:`cartan.integrators.newton`: the drift of a work copy of the configuration to the
midpoint, the scheme's force there, the per-node algebra), and so are the norms of the
iteration, the substitutions of the sparse LU and the end of the step.  The numpy path
(:meth:`ImplicitMidpoint._residual`, ``Scheme.drift``, ``Scheme.force``) stays the reference: it
runs for every other problem, with the numpy backend, for a subclass that overrides
:meth:`~ImplicitMidpoint._residual` or :meth:`~Integrator.force`, and under
``cartan.simulate(..., compiled=False)``.  The two residuals agree to round-off (≤ 1e-12
relative); the Newton logic, its tolerances and the restart semantics are the same on both
paths, and a step agrees with the reference to the Newton tolerance.

Compiled blocks of steps
------------------------
With the compiled residual, :meth:`ImplicitMidpoint.compiled_advance` — which :func:`cartan.simulate`
calls for the steps between saves — runs whole blocks of steps in one compiled loop
(:func:`cartan.integrators.newton.implicit_loop`): the initial iterate, Newton's iteration with
its convergence, contraction and halving tests, the substitutions of the kept factorisation,
the end of each step, the midpoint powers and the bookkeeping of :meth:`step`.  Python runs
only when the loop needs a fresh Jacobian — it returns with the current iterate,
:meth:`_jacobian` builds it by finite differences of the compiled residual and factorises it
with ``scipy.sparse.linalg.splu`` there, and the loop continues the same step — and when a
step fails (the loop's reason becomes the :class:`~cartan.statics.ConvergenceError` of
:meth:`step`).  :meth:`step` stays the Python driver of the same iteration: the two perform the
same operations on the same compiled pieces, so they give the same iterates, counters and
states bit for bit (the dissipated and external energies to round-off: the loop sums the
midpoint powers with the scheme's compiled ``op_powers``), and the kept Jacobian and previous
ξ pass between them as between steps.

Driven ends (:class:`~cartan.problem.Driven`): ξ is Δtξ_d at a driven node, no unknown, so the
node moves by exp(Δtξ_d) exactly; the lattice's operator set with driven nodes serves the
compiled residual and blocks (``OperatorSet.loops``), whose starting iterates carry Δtξ_d there
(``op_drive``) and whose wrapped operators give the driven momentum ∂K/∂N(ξ_d) and the
supports' power at the midpoint.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..schemes.base import Scheme, State
from .base import Integrator

__all__ = ["ImplicitMidpoint"]

#: dense finite-difference Jacobians (schemes other than the lattice) up to this many unknowns
MAX_DENSE_UNKNOWNS = 3000
#: a Newton step with ‖δξ‖_∞ ≤ XTOL·max(1, L) (L the largest grid length) is at the round-off
#: level of the configuration: converged even when R (then round-off noise) does not decrease
XTOL = 1e-12
#: backtracking halvings with a fresh Jacobian before a step is declared failed
MAX_HALVINGS = 10

#: why Newton's method failed (the end of :class:`cartan.statics.ConvergenceError`'s message)
_NOT_FINITE = "the residual is not finite"
_SINGULAR_STEP = "the Jacobian is singular (non-finite Newton step)"
_NO_DECREASE = f"no decrease of the residual along the Newton step after {MAX_HALVINGS} halvings"


def _iteration_limit(max_iter: int) -> str:
    return f"the iteration limit max_iter = {max_iter} was reached"


def _check_option(name: str, value: Any, lo: float, hi: float, allowed: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ValueError(f"{name} must be a number in {allowed}, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and lo < v < hi):
        raise ValueError(f"{name} must be in {allowed}, got {value!r}")
    return v


class _Plan:
    """Unknown layout and Jacobian sparsity of one scheme (built once per scheme)."""

    def __init__(self, scheme: Scheme):
        from ..schemes.lattice import Lattice
        from ..statics import _colouring, _lattice_stencil, _stencil_pairs

        if scheme.grid.glued is not None and not isinstance(scheme, Lattice):
            raise ValueError("implicit-midpoint supports a glued axis (Grid.glued, the sphere's chart) on the "
                             "'lattice' scheme only")
        if not scheme.diagonal_metric:
            raise ValueError("implicit-midpoint needs a diagonal kinetic metric (Medium.kinetic_metric); "
                             "use lie-verlet or rkmk4 for this medium")
        shape = tuple(scheme.grid.shape)
        r = scheme.group.dim
        nnode = int(np.prod(shape))
        unknown = np.broadcast_to(scheme.live, (*shape, r)).copy()
        unknown[scheme._clamped] = False
        self.shape = shape
        self.unknown = unknown
        self.unknown_flat = unknown.reshape(nnode, r)
        self.nunk = int(unknown.sum())
        self.index = -np.ones((nnode, r), dtype=np.int64)
        self.index[self.unknown_flat] = np.arange(self.nunk)
        if isinstance(scheme, Lattice) and scheme.grid.glued is not None:  # edges across the poles
            self.colour, self.src, self.dst = _lattice_stencil(scheme)
        elif isinstance(scheme, Lattice):
            self.colour = _colouring(shape, tuple(scheme.grid.periodic))
            self.src, self.dst = _stencil_pairs(shape, tuple(scheme.grid.periodic),
                                                box=bool(getattr(scheme, "coupled", False)))
        else:
            if self.nunk > MAX_DENSE_UNKNOWNS:
                raise ValueError(
                    f"implicit-midpoint supports the 'lattice' scheme at any size (coloured sparse Jacobian) and "
                    f"other schemes up to {MAX_DENSE_UNKNOWNS} unknowns (dense Jacobian); scheme {scheme.name!r} "
                    f"has {self.nunk} unknowns here"
                )
            self.colour = np.arange(nnode)
            self.src, self.dst = (a.ravel() for a in np.meshgrid(np.arange(nnode), np.arange(nnode), indexing="ij"))
        w = scheme.weights[..., None]
        m = np.abs(scheme.mass)  # an indefinite metric (the Poincaré group's Minkowski one) measured by |M|
        inv = np.where(m > 0, 1.0 / np.where(m > 0, m, 1.0), 0.0)
        self.w_over_m = np.broadcast_to(w * inv, (*shape, r))[unknown]  # ‖R‖_*² = Σ w R²/|m|
        self.w_times_m = np.broadcast_to(w * m, (*shape, r))[unknown]  # ‖N‖_M² = Σ w |m| N²
        self.length = max(1.0, float(np.max(scheme.grid.length)))
        self.flat_unknown = np.flatnonzero(unknown)  # the unknowns in y.ravel() (the order of y[unknown])
        #: the compiled stage residual (:class:`cartan.integrators.newton.Stage`),
        #: built at the first step that may use it; None when the scheme has none
        self.compiled: Any = False
        #: the work arrays of the compiled blocks of steps
        #: (:class:`cartan.integrators.newton.Blocks`), built at the first block
        self.blocks: Any = None
        self.inv = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)  # 1/m, 0 on gauge


def _stage(scheme: Scheme):
    """The compiled stage residual of ``scheme`` over its operator set
    (:class:`cartan.integrators.newton.Stage`), or None: no operator set for the problem, a
    medium whose momentum is not the base ``m N``, or a group whose ``log_domain_norm`` the
    compiled domain test does not reproduce (:func:`cartan.integrators.newton.domain_rule`)."""
    from ..medium import Medium
    from .newton import Stage, domain_rule, newton_module

    if type(scheme.medium).momentum is not Medium.momentum and not getattr(scheme, "coupled_lagrangian", False):
        return None  # (a coupled Lagrangian's stage momenta: the operator set's im_coupled_momentum)
    operators = getattr(scheme, "compiled_operators", None)
    ops = operators() if operators is not None else None
    if ops is None or not ops.serves("implicit_loop"):  # (a set with driven ends serves some loops only)
        return None
    dom = domain_rule(scheme.group)
    if dom is None:
        return None
    return Stage(ops, newton_module(ops), scheme.mass, dom, scheme.group.injectivity_radius,
                 (*scheme.grid.shape, scheme.group.dim))


class ImplicitMidpoint(Integrator):
    """Symplectic implicit midpoint Lie-group integrator, solved by Newton's method (see module docstring).

    Parameters
    ----------
    tol : float, default 1e-10
        Relative Newton tolerance in (0, 1): ``‖R‖_* ≤ tol·‖N_{k+½}‖_M`` (a relative error of
        the midpoint velocity; see the module docstring for the round-off criteria).
    max_iter : int, default 25
        Newton iterations allowed per step (≥ 1); then :class:`cartan.statics.ConvergenceError`.
    fd_step : float, default 1e-6
        Central finite-difference step of the Jacobian along ξ (> 0), in the units of the
        Lie-algebra components (radians, lengths), like :func:`cartan.statics.solve_static`.
    contraction : float, default 0.25
        In (0, 1): a kept Jacobian is discarded when an iteration reduces ``‖R‖_*`` by less
        than this factor.
    reuse_jacobian : bool, default True
        Keep the factorised Jacobian across steps (modified Newton); False assembles it at
        the start of every step (full cost, fewest iterations).
    predictor : bool, default True
        Start Newton's method from the previous step's ξ (when the step continues the last
        one) instead of ΔtN_k, which at Δt·ω_max ≫ 1 carries the unresolved stiff oscillation.

    Attributes
    ----------
    nstep, nforce, wall_time
        The :class:`~cartan.integrators.base.Integrator` counters (``nforce`` includes the
        finite-difference Jacobians' force evaluations).
    newton_iterations : int
        Newton iterations (residual evaluations after the first of each step) in total.
    jacobians : int
        Jacobian assemblies (and sparse LU factorisations) in total.
    """

    name = "implicit-midpoint"
    order = 2
    symplectic = True
    explicit = False
    stability = np.inf
    advance_loop = "implicit_loop"  # (compiled_advance: the Newton blocks over the operator set)

    def __init__(self, tol: float = 1e-10, max_iter: int = 25, fd_step: float = 1e-6, contraction: float = 0.25,
                 reuse_jacobian: bool = True, predictor: bool = True):
        self.tol = _check_option("tol", tol, 0.0, 1.0, "(0, 1)")
        if isinstance(max_iter, bool) or not isinstance(max_iter, int | np.integer) or max_iter < 1:
            raise ValueError(f"max_iter must be an integer ≥ 1, got {max_iter!r}")
        self.max_iter = int(max_iter)
        self.fd_step = _check_option("fd_step", fd_step, 0.0, math.inf, "(0, inf)")
        self.contraction = _check_option("contraction", contraction, 0.0, 1.0, "(0, 1)")
        if not isinstance(reuse_jacobian, bool | np.bool_):
            raise ValueError(f"reuse_jacobian must be True or False, got {reuse_jacobian!r}")
        self.reuse_jacobian = bool(reuse_jacobian)
        if not isinstance(predictor, bool | np.bool_):
            raise ValueError(f"predictor must be True or False, got {predictor!r}")
        self.predictor = bool(predictor)
        self._plan: tuple[Scheme, _Plan] | None = None
        super().__init__()

    def options(self) -> dict[str, Any]:
        return {"tol": self.tol, "max_iter": self.max_iter, "fd_step": self.fd_step,
                "contraction": self.contraction, "reuse_jacobian": self.reuse_jacobian, "predictor": self.predictor}

    def reset(self) -> None:
        super().reset()
        self.newton_iterations = 0
        self.jacobians = 0
        self._cache: dict[str, Any] | None = None  # the last step: continuation key, Δt, ξ, Jacobian factor
        self._coupled_start: np.ndarray | None = None  # the last stage momenta μ (coupled Lagrangians)

    def begin_block(self) -> None:
        """Forget the previous step (kept Jacobian, previous ξ): the next step starts afresh,
        exactly as a run restarted here would (called by :func:`cartan.simulate` at the start
        of every save block)."""
        self._cache = None
        self._coupled_start = None

    def driven_reason(self, scheme: Scheme) -> str | None:
        """None: the step's ξ is Δtξ at a driven node (not an unknown of Newton's method), so
        the node moves by exp(Δtξ) exactly."""
        return None

    def step(self, scheme: Scheme, state: State, dt: float) -> None:
        """Advance ``state`` in place by one step of size ``dt``.

        As :meth:`Integrator.step`, except that the dissipated and external powers are
        integrated by the midpoint rule at ``(Φ_k exp(ξ/2), N_{k+½})`` — the quadrature of the
        method itself, so that the energy balance of a linear damped or forced problem closes
        to the Newton tolerance (the end-point trapezoidal rule does not, when Δt·γ/m ≫ 1).
        """
        self._check_driven(scheme)
        t0 = time.perf_counter()
        self._mid_powers = {"dissipated": 0.0, "external": 0.0}
        self._step(scheme, state, dt)
        state.t = state.t + dt
        for key, name in (("dissipated", "dissipated_energy"), ("external", "external_work")):
            state.scalars[name] = state.scalars.get(name, 0.0) + dt * self._mid_powers[key]
        state.scalars["nstep"] = state.scalars.get("nstep", 0) + 1
        self.nstep += 1
        self.wall_time += time.perf_counter() - t0

    def compiled_advance(self, scheme: Scheme, state: State, dt: float, nsteps: int,
                         kinetic_limit: float = math.inf) -> bool:
        """Advance ``state`` in place by up to ``nsteps`` steps of ``dt`` in compiled code.

        Whole blocks of steps — Newton's iteration, the end of each step and the bookkeeping of
        :meth:`step` — run in one numba loop
        (:func:`cartan.integrators.newton.implicit_loop`); Python runs only when
        the loop asks for a fresh Jacobian (:meth:`_jacobian` at the loop's current iterate,
        after which the same step continues) and when a step fails.  The steps are those of
        :meth:`step` — the same operations on the same compiled residual, norms and
        substitutions, so the same iterates, counters and results bit for bit, except the
        dissipated and external energies, whose midpoint powers are summed in compiled code
        (round-off) — and the kept Jacobian and previous ξ carry over between calls and to and
        from :meth:`step` as they do between steps (:meth:`begin_block` forgets them).

        Parameters
        ----------
        scheme : Scheme
            The scheme of ``state``.
        state : State
            Advanced in place; its arrays are updated in place (replaced first by writable
            C-contiguous float64 copies when they are not such arrays).
        dt : float
            The time step.
        nsteps : int
            Steps to take (≤ 0: none).
        kinetic_limit : float, default inf
            The per-step blow-up test of :func:`cartan.simulate`: the block stops after the
            first step whose momentum is not finite or whose kinetic energy ``½Σ w S²/m``
            exceeds this bound (the steps done are the increase of ``state.scalars["nstep"]``).

        Returns
        -------
        bool
            False, touching nothing, when the compiled residual does not apply (see
            :meth:`_compiled`: the numpy backend, ``scheme.compiled_diagnostics`` cleared, no
            operator set, another state layout, overridden :meth:`_residual` or
            :meth:`~Integrator.force`) or when a subclass overrides :meth:`step` or
            :meth:`_step`; the caller then runs :meth:`step`.  True when steps were taken.

        Raises
        ------
        cartan.statics.ConvergenceError
            When Newton's method fails in a step, with the message, iterations and history
            :meth:`step` gives; the state is left after the steps done before it (counted in
            ``state.scalars["nstep"]``).
        """
        if type(self).step is not ImplicitMidpoint.step or type(self)._step is not ImplicitMidpoint._step:
            return False
        plan = self._layout(scheme)
        kernel = self._compiled(scheme, state, plan)
        if kernel is None:
            return False
        nsteps = int(nsteps)
        if nsteps <= 0:
            return True
        from .newton import (
            DONE,
            FAIL_MAX_ITER,
            FAIL_NO_DECREASE,
            FAIL_NOT_FINITE,
            FAIL_SINGULAR,
            NEED_JACOBIAN,
            Blocks,
            LUSolve,
        )

        t_start = time.perf_counter()
        ops = kernel.ops
        C = ops.pack(state)  # the configuration and momentum the loop steps, written back at the end
        S = np.array(state.S, dtype=np.float64).reshape(kernel.n, kernel.r)
        kernel.bind_arrays(C, S)
        Cw = kernel._base[2]
        if plan.blocks is None or plan.blocks.stage is not kernel:
            plan.blocks = Blocks(kernel, plan.flat_unknown, plan.w_over_m, plan.w_times_m)
        blocks = plan.blocks
        dt = float(dt)
        nstep0 = state.scalars.get("nstep", 0)
        key = (id(state), state.t, nstep0)
        cache = self._cache if self._cache is not None and self._cache["key"] == key else None
        lu = cache["lu"] if cache is not None and self.reuse_jacobian and cache["dt"] == dt else None
        if lu is not None and not isinstance(lu, LUSolve):
            lu = LUSolve(lu, kernel.module.im_lu_solve)  # a factorisation of the numpy path
        blocks.start(None if cache is None else cache["xi"], 0.0 if cache is None else cache["dt"], self.max_iter)
        options = (self.tol, self.contraction, XTOL * plan.length, self.max_iter, MAX_HALVINGS, self.predictor,
                   self.reuse_jacobian)
        has_power = bool(scheme.has_external_power())

        t = state.t
        dissipated = state.scalars.get("dissipated_energy", 0.0)
        external = state.scalars.get("external_work", 0.0)
        total = 0
        resume = False
        reason = None
        try:
            while True:
                status, done, nforce, iters, t, dissipated, external, have_lu = blocks.run(
                    C, S, Cw, lu, resume, t, dt, nsteps - total, dissipated, external, kinetic_limit, has_power,
                    options)
                total += done
                self.nforce += nforce
                self.newton_iterations += iters
                if not have_lu:
                    lu = None
                if status != NEED_JACOBIAN:
                    break
                t_step = t

                def residual(x: np.ndarray, t_step: float = t_step) -> dict[str, np.ndarray] | None:
                    res = kernel(x, dt, t_step)
                    if res is not None:
                        self.nforce += 1
                    return res

                try:
                    lu = self._jacobian(residual, blocks.iterate(), plan, True)
                except (RuntimeError, FloatingPointError) as exc:
                    reason = f"the Jacobian is singular ({exc})"
                    break
                resume = True
            if reason is None and status != DONE:
                reason = {FAIL_NOT_FINITE: _NOT_FINITE, FAIL_MAX_ITER: _iteration_limit(self.max_iter),
                          FAIL_SINGULAR: _SINGULAR_STEP, FAIL_NO_DECREASE: _NO_DECREASE}[status]
        finally:
            if total > 0:  # the steps done, booked as step() books them
                ops.unpack(state, C)
                state.S = S.reshape(state.S.shape)
                state.t = t
                state.scalars["dissipated_energy"] = dissipated
                state.scalars["external_work"] = external
                state.scalars["nstep"] = nstep0 + total
                self.nstep += total
                self._cache = {"key": (id(state), t, nstep0 + total), "dt": dt, "xi": blocks.previous(),
                               "lu": lu if self.reuse_jacobian else None}
            self.wall_time += time.perf_counter() - t_start
        if reason is not None:
            it, rn, history = blocks.progress()
            raise self._failure(state, dt, it, rn, history, reason)
        return True

    # ------------------------------------------------------------------ pieces
    def _layout(self, scheme: Scheme) -> _Plan:
        if self._plan is None or self._plan[0] is not scheme:
            if not np.any(scheme.live):
                raise ValueError(
                    "implicit-midpoint needs a medium with inertia (some inertia() > 0); "
                    f"{scheme.medium.name or type(scheme.medium).__name__!r} has none"
                )
            self._plan = (scheme, _Plan(scheme))
            self._cache = None
        return self._plan[1]

    def _compiled(self, scheme: Scheme, state: State, plan: _Plan):
        """The compiled stage residual bound to ``state``, or None for the numpy reference
        (:meth:`_residual`): ``scheme.compiled_diagnostics`` cleared (``simulate(...,
        compiled=False)``), the numpy backend, no compiled operator set for the problem, another state
        layout, or a subclass overriding :meth:`_residual` or :meth:`force`."""
        if not getattr(scheme, "compiled_diagnostics", True):
            return None
        if type(self)._residual is not ImplicitMidpoint._residual or type(self).force is not Integrator.force:
            return None
        from .._backend import get_backend

        if get_backend() != "numba":
            return None
        if plan.compiled is False:
            plan.compiled = _stage(scheme)
        kernel = plan.compiled
        if kernel is None or not kernel.accepts(state):
            return None
        kernel.bind(state)
        return kernel

    def _residual(self, scheme: Scheme, state: State, xi: np.ndarray, dt: float) -> dict[str, np.ndarray] | None:
        """Stage residual R(ξ) and its pieces; None when ξ is outside the domain of dexp⁻¹
        (the numpy reference: :meth:`Scheme.drift`, :meth:`Scheme.force` and the batched group
        operations)."""
        g = scheme.group
        if np.any(g.log_domain_norm(xi) >= g.injectivity_radius):
            return None
        mid = state.copy()
        scheme.drift(mid, 0.5, xi)
        N = xi / dt
        if getattr(scheme, "coupled_lagrangian", False):
            # ℓ(N, X): μ = ∂L/∂N at the midpoint strains (the discrete Legendre map inverted there),
            # and the force with the Hamiltonian stress at (μ, X_{k+½}) (module docstring)
            start = self._coupled_start  # the last stage's μ: a close first iterate
            try:
                mu = scheme.momentum(mid, N, start=start)
            except ValueError:
                return None
            self._coupled_start = mu
            mid.S = mu
            W = self.force(scheme, mid, N, state.t + 0.5 * dt)
        else:
            W = self.force(scheme, mid, N, state.t + 0.5 * dt)
            mu = scheme.medium.momentum(N)
        lhs = np.swapaxes(np.eye(g.dim) + g.Ad(g.exp(0.5 * xi)), -1, -2)
        BW = np.linalg.solve(lhs, W[..., None])[..., 0]  # B(ξ)ᵀ W
        Dmu = np.einsum("...ji,...j->...i", g.dexp_inv(xi), mu)
        R = Dmu - dt * BW - state.S
        return {"R": R, "W": W, "BW": BW, "mu": mu, "Dmu": Dmu, "mid": mid}

    def _jacobian(self, residual, xi: np.ndarray, plan: _Plan, compiled: bool):
        """The factorised Jacobian ∂R/∂ξ at ξ by coloured central differences of ``residual``
        (``ξ ↦`` :meth:`_residual`'s dict); its ``solve`` in compiled code when ``compiled``."""
        import scipy.sparse.linalg as spla

        from ..statics import _coloured_jacobian

        def displaced(direction: np.ndarray, eps: float) -> np.ndarray:
            res = residual(xi + eps * direction)
            if res is None:
                raise FloatingPointError("finite-difference point outside the domain of exp")
            return res["R"]

        J = _coloured_jacobian(displaced, plan.colour, plan.src, plan.dst, plan.unknown_flat, plan.index,
                               plan.shape, self.fd_step)
        self.jacobians += 1
        with np.errstate(all="ignore"):
            lu = spla.splu(J.tocsc())
        if compiled:
            from .newton import LUSolve

            lu = LUSolve(lu, self._plan[1].compiled.module.im_lu_solve)
        return lu

    # ------------------------------------------------------------------ step
    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        plan = self._layout(scheme)
        g = scheme.group
        unk = plan.unknown
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        cache = self._cache if self._cache is not None and self._cache["key"] == key else None
        lu = cache["lu"] if cache is not None and self.reuse_jacobian and cache["dt"] == dt else None
        fresh = False

        kernel = self._compiled(scheme, state, plan)
        if kernel is None:
            def dnorm(y: np.ndarray) -> float:  # ‖y‖_* of a momentum density y [*shape, r]
                return float(np.sqrt(np.sum(plan.w_over_m * y[unk] ** 2)))

            def vnorm(v: np.ndarray) -> float:  # ‖v‖_M of a velocity v [*shape, r]
                return float(np.sqrt(np.sum(plan.w_times_m * v[unk] ** 2)))

            def residual(x: np.ndarray) -> dict[str, np.ndarray] | None:
                return self._residual(scheme, state, x, dt)
        else:
            def dnorm(y: np.ndarray) -> float:  # the same norms, summed in compiled code
                return kernel.norm(plan.w_over_m, plan.flat_unknown, y)

            def vnorm(v: np.ndarray) -> float:
                return kernel.norm(plan.w_times_m, plan.flat_unknown, v)

            def residual(x: np.ndarray) -> dict[str, np.ndarray] | None:
                res = kernel(x, dt)
                if res is not None:
                    self.nforce += 1  # one force evaluation, as Integrator.force counts it
                return res

        xi = np.zeros_like(state.S)
        if scheme.coupled_lagrangian:
            # the gauge components of ξ are Δt times those the medium fixes at the start of the step
            # (r⁰ = ct for the temporal gauge); only the live ones are unknowns
            held = ~unk
            xi[held] = dt * scheme.velocity(state)[held]
        driven = getattr(scheme, "_driven", None)
        if driven is not None:  # a driven end moves by exp(Δtξ): its ξ is no unknown
            xi[driven[0]] = dt * driven[1][driven[0]]
        res = None
        if cache is not None and self.predictor:
            # ξ_{k+½} ≈ ξ_{k−½}(Δt/Δt_prev): the midpoint velocities are smooth, whereas the step
            # momentum S_k carries the unresolved stiff oscillation when Δt·ω_max ≫ 1
            guess = xi.copy()
            guess[unk] = (dt / cache["dt"]) * cache["xi"][unk]
            res = residual(guess)
            if res is not None:
                xi = guess
        if res is None:
            # no previous step: the better of ξ = ΔtN_k and ξ = 0 (the former is poor, or even
            # beyond the injectivity radius of exp, when S_k carries a stiff oscillation)
            N_k = scheme.velocity(state) if kernel is None else kernel.velocity(state)
            xi[unk] = dt * N_k[unk]
            res = residual(xi)
            if np.any(xi):
                zero = np.where(unk, 0.0, xi)
                res0 = residual(zero)
                if res0 is not None and (res is None or dnorm(res0["R"]) < dnorm(res["R"])):
                    xi, res = zero, res0
        if res is None:  # (a coupled Lagrangian whose Legendre map has no inverse at either start)
            raise self._failure(state, dt, 0, math.inf, [math.inf], _NOT_FINITE)
        rn = dnorm(res["R"])
        history = [rn]
        it = 0
        while True:
            if not math.isfinite(rn):
                raise self._failure(state, dt, it, rn, history, _NOT_FINITE)
            # converged: a relative velocity error below tol, or R at the round-off level of its terms
            floor = 64 * np.finfo(float).eps * (dnorm(state.S) + dnorm(res["Dmu"]) + abs(dt) * dnorm(res["BW"]))
            if plan.nunk == 0 or rn <= max(self.tol * vnorm(xi) / abs(dt), floor):
                break
            if it >= self.max_iter:
                raise self._failure(state, dt, it, rn, history, _iteration_limit(self.max_iter))
            if lu is None:
                try:
                    lu = self._jacobian(residual, xi, plan, kernel is not None)
                except (RuntimeError, FloatingPointError) as exc:
                    raise self._failure(state, dt, it, rn, history, f"the Jacobian is singular ({exc})") from None
                fresh = True
            with np.errstate(all="ignore"):
                delta = lu.solve(-res["R"][unk])
            if not np.all(np.isfinite(delta)):
                raise self._failure(state, dt, it, rn, history, _SINGULAR_STEP)
            negligible = float(np.max(np.abs(delta))) <= XTOL * plan.length
            alpha = 1.0
            accepted = done = False
            for _ in range(MAX_HALVINGS + 1 if fresh else 1):
                trial = xi.copy()
                trial[unk] += alpha * delta
                res_t = residual(trial)
                rn_t = math.inf if res_t is None else dnorm(res_t["R"])
                it += 1
                if negligible and res_t is not None:
                    # a Newton step at the round-off level of ξ: what is left of R is round-off noise
                    accepted = done = True
                    break
                if rn_t < rn:
                    accepted = True
                    break
                if not fresh or it >= self.max_iter:
                    break
                alpha *= 0.5
            if accepted:
                slow = rn_t > self.contraction * rn
                xi, res, rn = trial, res_t, rn_t
                history.append(rn)
                fresh = False
                if done:
                    break
                if slow:
                    lu = None  # convergence slows: the next iteration uses a Jacobian at the new iterate
            elif not fresh:
                lu = None  # a kept Jacobian that no longer contracts: a fresh one at the current iterate
            elif it >= self.max_iter:
                raise self._failure(state, dt, it, rn, history, _iteration_limit(self.max_iter))
            else:
                raise self._failure(state, dt, it, rn, history, _NO_DECREASE)
        self.newton_iterations += it
        # the powers at the midpoint, for the energy bookkeeping of step()
        if scheme.has_external_power():
            mid = res["mid"] if kernel is None else kernel.drifted(state, xi, 0.5)  # (the kernel keeps none)
            self._mid_powers = scheme.powers(mid, xi / dt, state.t + 0.5 * dt)
        # advance: Φ ← Φ exp(ξ), S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (I − B)ᵀ W
        if kernel is None:
            S_new = np.einsum("...ji,...j->...i", g.dexp_inv(-xi), res["mu"]) + dt * (res["W"] - res["BW"])
            scheme.drift(state, 1.0, xi)
            state.S = S_new
        else:
            kernel.advance(state, xi, res, dt)
        scheme.constrain(state)
        self._cache = {"key": (id(state), state.t + dt, state.scalars.get("nstep", 0) + 1), "dt": dt, "xi": xi,
                       "lu": lu if self.reuse_jacobian else None}

    def _failure(self, state: State, dt: float, it: int, rn: float, history: list[float], reason: str):
        from ..statics import ConvergenceError

        self.newton_iterations += it
        self._cache = None
        tail = ", ".join(f"{x:.3e}" for x in history[-6:])
        return ConvergenceError(
            f"implicit-midpoint: Newton's method did not converge in the step from t = {state.t:.6g} with "
            f"Δt = {dt:.3g} after {it} iteration(s), residual ‖R‖ = {rn:.3e}: {reason} (last residuals: {tail}); "
            "reduce Δt or raise max_iter",
            it,
            rn,
            history,
        )
