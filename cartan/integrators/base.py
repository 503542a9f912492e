"""The :class:`Integrator` base: the written contract for time integrators.

An integrator advances a :class:`~cartan.schemes.base.State` by one step through the
:class:`~cartan.schemes.base.Scheme` interface only (``velocity``, ``force``, ``drift``,
``constrain``), so every integrator runs on every scheme and knows nothing of the medium.

Implementers
------------
* set the class attributes ``name`` (kebab-case), ``order``, ``geometric`` (Φ stays in G),
  ``symplectic``, ``explicit``, and ``stability`` — the largest stable ``Δt·ω_max`` for
  the undamped linear oscillator (2 for leapfrog, 2√2 for RK4, 0 when no Δt is stable), or
  for ``rate = "overdamped"`` the largest ``Δt·λ_max`` of the linear gradient flow;
* implement :meth:`_step`, which advances ``state`` in place by ``dt`` (time included) and
  calls :meth:`force` (never ``scheme.force`` directly) so the counters stay right;
* keep ``_step`` deterministic: a restart from a checkpoint reproduces the run bit for bit;
* return None from :meth:`Integrator.driven_reason` when the steps move the nodes of a
  :class:`~cartan.problem.Driven` end (the scheme's ``velocity`` gives ξ there, ``constrain``
  sets their momentum) by exactly exp(Δtξ) per step; the default refuses driven ends;
* optionally, define ``compiled_advance(scheme, state, dt, nsteps, kinetic_limit) -> bool``
  to take whole blocks of steps in compiled code (:func:`cartan.simulate` offers it the steps
  between saves before the scheme's own ``compiled_advance``): False, touching nothing, when
  it declines; otherwise the steps taken exactly as :meth:`step` takes them, stopping after
  a step whose kinetic energy ``½Σ w S²/m`` exceeds ``kinetic_limit`` or is not finite
  (``implicit-midpoint`` does; the explicit integrators leave it to the schemes).

The base class keeps the counters (``nstep``, ``nforce``, ``wall_time``), advances
``state.t``, and integrates the dissipated and external powers (trapezoidal rule) into
``state.scalars`` so that the energy balance of a run closes to the integrator's order.
"""

from __future__ import annotations

import abc
import time
from typing import Any, ClassVar

import numpy as np

from ..schemes.base import Scheme, State

__all__ = ["Integrator"]


class Integrator(abc.ABC):
    """Base class of time integrators (see module docstring for the contract)."""

    name: ClassVar[str] = ""
    order: ClassVar[int] = 1
    geometric: ClassVar[bool] = True
    symplectic: ClassVar[bool] = False
    explicit: ClassVar[bool] = True
    stability: ClassVar[float] = 0.0
    rate: ClassVar[str] = "inertial"
    #: False for integrators that prescribe N (kinematic, overdamped): S is not evolved.
    uses_momentum: ClassVar[bool] = True
    #: True for integrators that hold the medium's constrained strains
    #: (:meth:`~cartan.medium.Medium.constrained_strains`) with multipliers (``rattle``)
    constrained: ClassVar[bool] = False
    #: the generated loop that :meth:`compiled_advance` runs over the scheme's operator set, if it
    #: runs one (``implicit-midpoint``: ``"implicit_loop"``): ``simulate`` offers it a run with
    #: per-node accumulators when the set integrates them in that loop (``OperatorSet.accumulates``)
    advance_loop: ClassVar[str | None] = None

    def __init__(self, **options: Any):
        if options:
            raise ValueError(f"integrator {self.name!r} takes no option(s) {sorted(options)}")
        self.reset()

    def reset(self) -> None:
        """Zero the counters."""
        self.nstep = 0
        self.nforce = 0
        self.wall_time = 0.0

    def counters(self) -> dict[str, int | float]:
        """The counters ``{"nstep", "nforce", "wall_time"}`` (what a checkpoint records)."""
        return {"nstep": int(self.nstep), "nforce": int(self.nforce), "wall_time": float(self.wall_time)}

    def set_counters(self, counters: dict[str, Any]) -> None:
        """Continue counting from ``counters`` (as :meth:`counters` returned them: a restart)."""
        self.nstep = int(counters["nstep"])
        self.nforce = int(counters["nforce"])
        self.wall_time = float(counters["wall_time"])

    def options(self) -> dict[str, Any]:
        return {}

    # ------------------------------------------------------------------ contract
    @abc.abstractmethod
    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        """Advance ``state`` in place by ``dt`` (configuration and momentum; not ``t``)."""

    # ------------------------------------------------------------------ shared
    def velocity(self, scheme: Scheme, state: State) -> np.ndarray:
        """N used for the energy bookkeeping (the state's own velocity by default)."""
        return scheme.velocity(state)

    def force(self, scheme: Scheme, state: State, N: np.ndarray, t: float) -> np.ndarray:
        """Counted call of ``scheme.force``."""
        self.nforce += 1
        return scheme.force(state, N, t)

    def driven_reason(self, scheme: Scheme) -> str | None:
        """Why this integrator's steps do not move the scheme's :class:`~cartan.problem.Driven`
        ends by exactly exp(Δtξ) per step, or None when they do (default: a reason; the
        integrators that do say so)."""
        return "its steps do not move a node with a prescribed velocity by exp(Δtξ)"

    def _check_driven(self, scheme: Scheme) -> None:
        """ValueError naming the integrator when the scheme has driven ends it cannot move
        exactly (:meth:`driven_reason`); checked once per scheme."""
        if getattr(scheme, "_driven", None) is None or getattr(self, "_driven_checked", None) is scheme:
            return
        reason = self.driven_reason(scheme)
        if reason is not None:
            raise ValueError(f"integrator {self.name!r} does not take Driven ends: {reason}; use 'lie-verlet', "
                             "'lie-euler', 'rkmk4', 'implicit-midpoint' or 'overdamped'")
        self._driven_checked = scheme

    def step(self, scheme: Scheme, state: State, dt: float) -> None:
        """Advance ``state`` in place by one step of size ``dt``."""
        self._check_driven(scheme)
        t0 = time.perf_counter()
        p0 = self._powers(scheme, state)
        self._step(scheme, state, dt)
        state.t = state.t + dt
        state.scalars["nstep"] = state.scalars.get("nstep", 0) + 1  # (before p1: a velocity cached
        p1 = self._powers(scheme, state)  # for the powers at the end is the next step's start)
        for key in ("dissipated", "external"):
            name = "dissipated_energy" if key == "dissipated" else "external_work"
            state.scalars[name] = state.scalars.get(name, 0.0) + 0.5 * dt * (p0[key] + p1[key])
        self.nstep += 1
        self.wall_time += time.perf_counter() - t0

    def _powers(self, scheme: Scheme, state: State) -> dict[str, float]:
        if not scheme.has_external_power():
            return {"dissipated": 0.0, "external": 0.0}
        return scheme.powers(state, self.velocity(scheme, state), state.t)

    def dt_max(self, scheme: Scheme, state: State) -> float:
        """CFL estimate: the largest stable Δt for the linearised system at ``state``
        (0 when no Δt is stable; inf when the integrator has no stability limit)."""
        if self.stability == np.inf:
            return np.inf
        return self.stability * scheme.dt_max(state, rate=self.rate)

    # ------------------------------------------------------------------ compiled loops
    def compiled_loop(self, scheme: Scheme, state: State, dt: float) -> tuple[str, tuple] | None:
        """The generated loop that takes this integrator's steps, or None (default: none).

        Returns ``(name, args)``: a loop of :mod:`cartan.integrators.loops` and the
        integrator's own arguments, which the loop receives between ``(D, C, S)`` and
        ``(t, dt, nsteps, dissipated, external, check, limit)``.
        """
        return None

    def compiled_module(self, ops: Any) -> Any:
        """The generated module that holds this integrator's loop for the operator set ``ops``
        (default: the set's own module, :meth:`cartan.compiled.operators.OperatorSet.generated`);
        an integrator with problem-specific kernels (``kinematic``) generates its own."""
        return ops.generated()

    def compiled_loop_done(self, state: State, args: tuple) -> None:  # noqa: B027 - an optional hook
        """Called after a generated loop ran with ``args`` (e.g. to keep a force for the
        next block); the default does nothing."""

    def run_compiled_loop(self, scheme: Scheme, state: State, dt: float, nsteps: int,
                          kinetic_limit: float = float("inf")) -> bool:
        """Take up to ``nsteps`` steps in the generated loop of (this integrator, the scheme's
        operator set, the group's and the medium's point kernels).

        Returns False, touching nothing, when the integrator has no loop, the scheme no
        operator set for the problem (``scheme.compiled_operators()``), or the numpy backend is
        selected; otherwise True after the steps were taken as :meth:`step` takes them
        (round-off apart), with ``state.t``, ``state.scalars`` and the counters updated, and
        stopping after a step that is not finite or whose kinetic energy exceeds
        ``kinetic_limit``.  The first run of a combination on a machine compiles its module and
        says so on stderr; later runs load it from the cache (:mod:`cartan.compiled.codegen`).
        """
        import contextlib

        from .._backend import get_backend
        from .._threads import loop_threads, numba_threads
        from ..compiled.codegen import first_call

        if get_backend() != "numba" or (getattr(scheme, "coupled_lagrangian", False) and not self.uses_momentum):
            return False  # (a Lagrangian coupling N and X enters through the momentum: cartan.schemes._coupled)
        self._check_driven(scheme)
        operators = getattr(scheme, "compiled_operators", None)
        ops = operators() if operators is not None else None
        if ops is None or not (ops.ok or ops.loops) or not ops.accepts(state):
            return False
        spec = self.compiled_loop(scheme, state, float(dt))
        if spec is None or not ops.serves(spec[0]):  # (a set with driven ends serves some loops only)
            return False
        if ops.accumulates and not (self.uses_momentum and spec[0] in ops.accumulates):
            return False  # (per-node accumulators: integrated in these loops only, cartan.accumulators)
        name, args = spec
        # the threaded build (cartan._threads) of the operator set's own module, on a large
        # enough grid with threads requested; an integrator with a module of its own runs serially
        threads = 1
        default_module = type(self).compiled_module is Integrator.compiled_module
        if ops.threaded and default_module:
            threads = loop_threads(ops.nodes, count=False)
        t_start = time.perf_counter()
        config = ops.pack(state)
        S = np.ascontiguousarray(state.S, dtype=float).reshape(ops.nodes, -1).copy()
        check = 1 if self.uses_momentum else 2
        call = (ops.data, config, S, *args, float(state.t), float(dt), int(nsteps),
                float(state.scalars.get("dissipated_energy", 0.0)), float(state.scalars.get("external_work", 0.0)),
                check, float(kinetic_limit))
        # the loop of the operator set's own module, once it ran in this process for this set: the
        # same function without the module's lookup and the first-call guard (per call of a run)
        ran = self.__dict__.get("_ran_loop")
        if default_module and threads == 1 and ran is not None and ran[0] is ops and ran[1] == name:
            done, nforce, t, diss, ext = ran[2](*call)
        else:
            module = ops.generated(threaded=True) if threads > 1 else self.compiled_module(ops)
            what = f"the {self.name} loop for {ops.label}" + (" (threaded build)" if threads > 1 else "")
            loop = getattr(module, name)
            with first_call(module, name, what), numba_threads(threads) if threads > 1 else contextlib.nullcontext():
                done, nforce, t, diss, ext = loop(*call)
            self._ran_loop = (ops, name, loop) if default_module and threads == 1 else None
        ops.unpack(state, config)
        if self.uses_momentum:  # (the others leave S as it is; Overdamped zeroes it in compiled_loop_done)
            state.S = S.reshape(state.S.shape)
        state.t = t
        state.scalars["dissipated_energy"] = diss
        state.scalars["external_work"] = ext
        state.scalars["nstep"] = state.scalars.get("nstep", 0) + done
        self.compiled_loop_done(state, args)
        self.nstep += done
        self.nforce += nforce
        self.wall_time += time.perf_counter() - t_start
        return True

    def __repr__(self) -> str:
        opts = ", ".join(f"{k}={v!r}" for k, v in self.options().items())
        return f"{type(self).__name__}({opts})"
