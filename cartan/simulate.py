"""``cartan.simulate``: run a problem or scene, save frames, checkpoint, detect blow-up.

:func:`simulate` works in two phases.  :func:`_resolve_run` settles the run before any step:
every setting from the argument, else the restart file, else the scene's ``[run]`` table, else
the default; the scheme and integrator; the CFL estimate and Δt (half the estimate, rounded
down, when none is given; a :class:`StabilityWarning` above it); the step count, the output
file and the memory of the frames; it returns a :class:`_ResolvedRun`.  :func:`_execute_run`
runs it: the save loop below.  Δt reaches the step loop from ``cartan run --dt`` through four
functions::

    cartan run --dt    cartan.cli_run._run
      1  simulate(dt=...)
      2  _resolve_run(...)          → _ResolvedRun.dt (argument > checkpoint > scene > CFL estimate)
      3  _execute_run(run)          the save loop
      4  _advance(..., dt, ...)     → integrator.compiled_advance / scheme.compiled_advance /
                                      integrator.run_compiled_loop / integrator.step

This module does not import :mod:`cartan.scene` (nor does that module import this one): the
step and memory limits come from :mod:`cartan.limits`, and scene files, names and the scene
kept in a checkpoint are read through the run-level API, :mod:`cartan.api`.

The run loop advances the state between saves (:func:`_advance`), records a frame
(:func:`cartan.io.frame_record`), and every ``checkpoint_every`` saves writes the whole run
so far plus the exact state to the output file, so that ``simulate(..., restart=path)``
continues it and reproduces the uninterrupted run bit for bit.

Compiled loops
--------------
:func:`_advance` first offers the steps to the scheme's ``compiled_advance`` (the lattice
scheme runs qualifying problems — d = 1, quadratic media, data-like loads — in numba; see
``docs/performance.md``) and falls back to the Python loop of ``integrator.step`` when it
declines; ``simulate(..., compiled=False)`` forces the Python loop, the reference path.  The
compiled loop applies the per-step part of the blow-up test itself (finite momentum or
configuration, kinetic energy against the current bound) and stops after the first failing
step.  Until the run's energy scale is set (its first save block) it runs in sub-blocks that
end at the steps 1, 2, 4, 8, … of the save block where the guard runs its energy-balance test,
so that the guard sees the same states at the same steps as with the Python loop; after that
it takes each save block in one call (a call costs about a millisecond of Python around the
loop, which dominates short blocks of small problems) and the energy test runs at the save.
A block that fails — the loop stopped early, or the frame test failed — is run again from the
copy taken at its start in the sub-blocks, with the integrator's counters reset, so that the
failing step, its reason and the last good state are those of the sub-block tests.  Each
step depends only on the state, so the result does not depend on the sub-blocks and a restart
is bit for bit (with the same path on both sides: the compiled and Python paths agree to
round-off, not bit for bit).  The energy scale then grows with the saved states only, not with
the states between them.

The CFL estimate is computed once per content (:func:`_cfl_estimate`): a run whose problem,
scheme, integrator, options and initial state are those of one of the last few runs (a pilot
and its warm-up, a run repeated in a study) takes the estimate computed then.

The work around the steps uses compiled kernels too when the scheme has them and the problem
is large enough for them to pay for their compilation (``scheme.uses_compiled_diagnostics()``:
``scheme.compiled_diagnostics``, cleared by ``compiled=False``, and at least
``scheme.compiled_diagnostics_from`` unknowns): the CFL estimate
(:meth:`~cartan.schemes.base.Scheme.dt_max`, whose stiffness products use the lattice's
compiled force and drift) and the guard's energies (the compiled plan's quadratic energy);
saved frames always use the scheme's reference methods, with the frames rebuilt once per
frame (``docs/performance.md``, "Work around the steps").

Blow-up is detected cheaply inside each save block and fully at every save.  The tests:
non-finite momentum or configuration (every step); an energy-balance error
``|K + V + D − W − E₀|`` beyond ``max_energy_growth`` times the energy scale of the run *and*
beyond half the state's own ``|K| + |V| + |D| + |W|`` — energy the physics did not put there
(at steps 1, 2, 4, 8, … of each block and at every save; in compiled whole blocks at the save
only); and, between those, the kinetic
energy against ``max_energy_growth`` times the energy scale.  The energy scale is the largest
``|K| + |V| + |D| + |W|`` (kinetic, potential, dissipated, external work) of the states
checked so far whose energy budget closed (balance error at most half that sum), so that
energy created by a blow-up never becomes the yardstick; a run released from rest (initial
energy at round-off) takes the energy after its first step, which only the loads put there.  The run then stops with
:class:`InstabilityError`, after writing the frames up to the last good state, and that
state as a checkpoint, to the output file (or to a temporary file when there is none).
"""

from __future__ import annotations

import math
import numbers
import os
import pathlib
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from . import accumulators
from .integrators.base import Integrator
from .limits import DEFAULT_MAX_STEPS, STEPS_ENV, check_memory, state_bytes, step_limit
from .plugins import get_registry
from .problem import Problem
from .schemes.base import Scheme
from .state import State

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from .api import Scene

__all__ = ["InstabilityError", "StabilityWarning", "simulate"]

DEFAULT_INTEGRATOR = "lie-verlet"
#: the default integrator of a medium with constrained strains (it holds them with multipliers)
CONSTRAINED_INTEGRATOR = "rattle"
DEFAULT_SCHEME = "lattice"
DEFAULT_FRAMES = 100


class StabilityWarning(UserWarning):
    """The time step exceeds the integrator's CFL estimate: the run is likely to blow up."""


class InstabilityError(RuntimeError):
    """A run blew up (non-finite values or unbounded energy growth).

    Attributes
    ----------
    step : int
        Time-step index at which the blow-up was detected.
    time : float
        Time at detection.
    dt : float
        The time step.
    dt_max : float
        The integrator's CFL estimate for the run.
    path : pathlib.Path or None
        File holding the frames up to the last good state and that state as a checkpoint
        (``cartan.open(path)`` reads it; ``simulate(problem, dt=..., restart=path)``
        continues from it).
    """

    def __init__(
        self,
        message: str,
        *,
        step: int = -1,
        time: float = math.nan,
        dt: float = math.nan,
        dt_max: float = math.nan,
        path: pathlib.Path | None = None,
    ):
        super().__init__(message)
        self.step = step
        self.time = time
        self.dt = dt
        self.dt_max = dt_max
        self.path = path

    def __reduce__(self):  # picklable (e.g. across dask workers) with its attributes
        return (type(self), (str(self),), dict(self.__dict__))


# ---------------------------------------------------------------------------- resolution
def _resolve(kind: str, spec: Any, base: type) -> type | Any:
    """A registered name, a class (scipy's convention) or an instance → class or instance."""
    if isinstance(spec, str):
        return get_registry().get(kind, spec)
    if isinstance(spec, type) and issubclass(spec, base):
        return spec
    if isinstance(spec, base):
        return spec
    raise TypeError(f"{kind[:-1]} must be a registered name or a {base.__name__} subclass, got {spec!r}")


def _name_of(spec: Any) -> str:
    if isinstance(spec, str):
        return spec
    return getattr(spec, "name", "") or getattr(spec, "__name__", type(spec).__name__)


def _as_scene(obj: Any) -> tuple[Problem, Scene | None]:
    """What to run: ``(problem, scene)`` from a Problem, a Scene, a scene file or dict, or a
    registered scene name.  Scenes are read by the run-level API (:mod:`cartan.api`), the layer
    that joins scenes and runs, so that this module and :mod:`cartan.scene` import neither
    the other."""
    if isinstance(obj, Problem):
        return obj, None
    from .api import Scene, load_scene, scene

    if isinstance(obj, Scene):
        return obj.problem, obj
    if isinstance(obj, pathlib.PurePath) or (isinstance(obj, str) and obj.endswith(".toml")):
        sc = load_scene(obj)
        return sc.problem, sc
    if isinstance(obj, str):
        sc = scene(obj)
        return sc.problem, sc
    if isinstance(obj, Mapping):
        sc = load_scene(obj)
        return sc.problem, sc
    raise TypeError(
        f"simulate needs a Problem, a Scene, a scene file or a registered scene name, got {obj!r}"
    )


def _first(*values: Any) -> Any:
    for v in values:
        if v is not None:
            return v
    return None


def _nsteps(t_end: float, dt: float, limit: int = DEFAULT_MAX_STEPS) -> int:
    """Steps of ``dt`` to reach ``t_end`` (``ceil(t_end/dt)``, or the nearest integer within
    round-off); a ValueError when they exceed ``limit`` (or overflow)."""
    ratio = t_end / dt
    if not ratio <= limit + 0.5:  # also inf and nan: t_end/dt overflows for dt → 0
        raise ValueError(
            f"t_end/dt = {t_end:g}/{dt:g} = {ratio:.3g} steps, above the limit of {limit} steps; give a larger dt "
            f"or a shorter t_end, or raise the limit (max_steps=, cartan run --max-steps, or the environment "
            f"variable {STEPS_ENV})"
        )
    n = round(ratio)
    if abs(ratio - n) <= 1e-9 * max(1.0, ratio):
        return max(int(n), 0)
    return int(math.ceil(ratio))


def _real(name: str, value: Any, *, positive: bool = True) -> float:
    """``value`` as a float: a finite real number (not a bool or a string), > 0 by default."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:  # an int beyond the floats
        x = math.inf
    if not math.isfinite(x) or (positive and not x > 0):
        raise ValueError(f"{name} must be finite{' and > 0' if positive else ''}, got {value!r}")
    return x


def _count_of(name: str, value: Any) -> int | None:
    """None or an integer ≥ 1 (not a bool; an integral float such as 10.0 is accepted)."""
    if value is None:
        return None
    if (
        isinstance(value, bool | np.bool_)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or int(value) != value
        or value < 1
    ):
        raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}")
    return int(value)


def _check_arguments(
    dt: Any, t_end: Any, save_every: Any, checkpoint_every: Any, output: Any, restart: Any,
    integrator_options: Any, scheme_options: Any, progress: Any, max_energy_growth: Any, compiled: Any,
    command: Any,
) -> None:
    """ValueError naming the first argument of :func:`simulate` of the wrong type or range."""
    if dt is not None:
        _real("dt", dt)
    if t_end is not None:
        _real("t_end", t_end)
    _count_of("save_every", save_every)
    _count_of("checkpoint_every", checkpoint_every)
    for name, value in (("output", output), ("restart", restart)):
        if value is not None and not isinstance(value, str | os.PathLike):
            raise ValueError(f"{name} must be a path (str or os.PathLike), got {value!r}")
        if isinstance(value, str) and not value:
            raise ValueError(f"{name} must be a path, got ''")
    for name, value in (("integrator_options", integrator_options), ("scheme_options", scheme_options)):
        if value is not None and not isinstance(value, Mapping):
            raise ValueError(f"{name} must be a dict of keyword arguments, got {value!r}")
    if progress is not None and not isinstance(progress, bool | np.bool_):
        raise ValueError(f"progress must be True, False or None, got {progress!r}")
    if not isinstance(compiled, bool | np.bool_):
        raise ValueError(f"compiled must be True or False, got {compiled!r}")
    if max_energy_growth is not None:
        _real("max_energy_growth", max_energy_growth)
    if command is not None and not isinstance(command, str):
        raise ValueError(f"command must be a string, got {command!r}")


def _round_down(x: float, digits: int = 2) -> float:
    """``x`` rounded down to ``digits`` significant digits (a tidy default time step)."""
    if not (x > 0 and math.isfinite(x)) or x < 1e-300:  # 10**e would underflow
        return x
    e = math.floor(math.log10(x)) - digits + 1
    return math.floor(x / 10.0**e) * 10.0**e


def _show_progress(progress: bool | None) -> bool:
    if progress is not None:
        return bool(progress)
    if os.environ.get("CI"):
        return False
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


# ---------------------------------------------------------------------------- the loop
def _advance(
    integrator: Integrator,
    scheme: Scheme,
    state: State,
    dt: float,
    nsteps: int,
    guard: Callable[[State, int], str | None],
    compiled: bool = True,
    whole: bool = False,
) -> tuple[int, str | None]:
    """Advance ``state`` in place by up to ``nsteps`` steps of ``dt``.

    Returns ``(steps done, None)``, or ``(steps done, reason)`` as soon as
    ``guard(state, steps done)`` reports a blow-up.  With ``compiled``, the steps go to
    the integrator's own ``compiled_advance(scheme, state, dt, n, kinetic_limit)`` when it has one
    (``implicit-midpoint``), else to ``scheme.compiled_advance``, when it accepts the
    combination (see the module docstring), in sub-blocks ending where the guard runs its
    energy test — or, with ``whole``, in one call for the whole block, the guard not called:
    a compiled loop that stops early (its own per-step test failed) returns the reason
    ``"stopped early"``, and the caller runs the block again from its start in sub-blocks
    (:data:`_EARLY`); otherwise,
    or for what it declines, to ``integrator.step`` one by one.  An implicit integrator's
    :class:`~cartan.statics.ConvergenceError` (its stage equations unsolved; the state is left
    at the last step done) is reported like a blow-up.  Integrators with a ``begin_block()``
    method (caches that change results, e.g. a kept Jacobian) are told that a block starts,
    where a restart could resume, so that restarts stay bit for bit.  A medium that declares
    per-node accumulators (:mod:`cartan.accumulators`) takes the generated loops only when the
    scheme's operator set integrates them there (``OperatorSet.accumulates``); otherwise it is
    stepped one by one on this path, each step followed by the trapezoidal update of its
    accumulators.
    """
    from .statics import ConvergenceError

    k = 0
    # per-node accumulators: integrated in the generated loops of an operator set that takes them
    # (``OperatorSet.accumulates``; the other compiled paths know none), else stepped one by one below
    acc = bool(accumulators.declared(scheme.medium))
    begin = getattr(integrator, "begin_block", None)
    if begin is not None:
        begin()
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # the compiled paths, in order of preference: the integrator's own blocks, the scheme's
        # hand-written loops, the integrator's generated loop over the scheme's operators
        paths = []
        generic = getattr(integrator, "run_compiled_loop", None)
        takes = _accumulating_loops(scheme) if compiled and acc else ()
        if takes and integrator.advance_loop in takes:  # (e.g. implicit-midpoint's Newton blocks)
            paths.append(integrator.compiled_advance)
        if takes and generic is not None:
            paths.append(generic)
        if compiled and not acc:
            own = getattr(integrator, "compiled_advance", None)
            if own is not None:
                paths.append(own)
            fast = getattr(scheme, "compiled_advance", None)
            if fast is not None:
                paths.append(lambda s, st, h, n, lim: fast(integrator, st, h, n, kinetic_limit=lim))
            if generic is not None:
                paths.append(generic)
        energy_checks = getattr(guard, "energy_checks", True)
        kinetic_limit = getattr(guard, "kinetic_limit", lambda: math.inf)
        while paths and k < nsteps:
            stop = min(nsteps, 1 << k.bit_length()) if energy_checks and not whole else nsteps
            before = state.scalars.get("nstep", 0)
            try:
                ran = paths[0](scheme, state, dt, stop - k, kinetic_limit())
            except ConvergenceError as exc:  # the step after those done failed
                return k + state.scalars.get("nstep", 0) - before + 1, str(exc)
            if not ran:
                paths.pop(0)
                continue
            k += state.scalars.get("nstep", 0) - before
            if whole:  # the caller's frame test follows; a loop that stopped early is run again
                return k, None if k == nsteps else _EARLY
            reason = guard(state, k)
            if reason is not None:
                return k, reason
        rates = accumulators.rates(scheme, integrator, state) if acc and k < nsteps else None
        for j in range(k, nsteps):
            try:
                integrator.step(scheme, state, dt)
            except ConvergenceError as exc:
                return j + 1, str(exc)
            if rates is not None:  # trapezoidal rule over the step (cartan.accumulators)
                after = accumulators.rates(scheme, integrator, state)
                accumulators.add(state, dt, rates, after)
                rates = after
            reason = guard(state, j + 1)
            if reason is not None:
                return j + 1, reason
    return nsteps, None


def _accumulating_loops(scheme: Scheme) -> tuple[str, ...]:
    """The generated loops in which the scheme's compiled operator set integrates the medium's
    per-node accumulators (``OperatorSet.accumulates``; the integrator's ``run_compiled_loop``
    declines the loops that do not); empty: none."""
    from ._backend import get_backend

    operators = getattr(scheme, "compiled_operators", None)
    if operators is None or get_backend() != "numba":
        return ()
    ops = operators()
    return tuple(getattr(ops, "accumulates", ()))


#: the reason :func:`_advance` gives for a whole block whose compiled loop stopped early
_EARLY = "stopped early"
#: the save loop completes the frames' deferred diagnostics (:func:`cartan.io.complete_records`)
#: every this many frames, in one batched call, and at the assembly of the Dataset
_COMPLETE_EVERY = 32


def _make_guard(scheme: Scheme, integrator: Integrator, growth: float | None, e0: float, scale: list[float]):
    """Per-step blow-up test ``guard(state, k)``, k = steps done in the current save block.

    Every step: non-finite momentum (or configuration, for integrators without momentum).
    At k = 1, 2, 4, 8, …: the energy-balance test of :func:`_balance` on K and V (two
    energy evaluations; with ``scheme.compiled_diagnostics`` set, from the hand-written plan's
    quadratic energy when the lattice has one, ``cartan.schemes._lattice_diagnostics.guard_energies``,
    else, when the operator set's loops take the steps and ``scheme.uses_compiled_diagnostics()``,
    from the operator set,
    :func:`cartan.compiled.diagnostics.guard_energies`),
    which also raises the energy scale ``scale[0]`` and marks it established (``scale[1] ≥ 1``).
    At the other steps, once the scale is established: the kinetic energy ½Σ w S²/m against
    ``growth × scale[0]`` (one pass over S).
    """
    # ½Σ w S²/|m| (M's diagonal): the kinetic energy for diagonal metrics, a norm of S otherwise
    inv = np.abs(np.diag(scheme.inverse_metric))
    w = scheme.weights[..., None]
    momentum = integrator.uses_momentum
    compiled_energies = bool(getattr(scheme, "compiled_diagnostics", False)) and growth is not None
    if compiled_energies:
        from .compiled.diagnostics import guard_energies as generated_energies
        from .schemes._lattice_diagnostics import guard_energies as plan_energies

        # the plan's energies are numpy sums; the operator set's compile (large problems only)
        generated = not scheme.has_hand_written_loops() and scheme.uses_compiled_diagnostics()

        def guard_energies(scheme: Scheme, state: State) -> tuple[float, float] | None:
            fast = plan_energies(scheme, state)
            return fast if fast is not None or not generated else generated_energies(scheme, state)

    def kinetic_limit() -> float:
        """The bound the kinetic test applies now (inf while it is off): for compiled loops,
        which apply the per-step tests themselves between the guard's energy tests."""
        if growth is not None and momentum and scale[1] >= 1 and scale[0] > 0:
            return growth * scale[0]
        return math.inf

    def guard(state: State, k: int) -> str | None:
        if momentum:
            if not np.isfinite(np.sum(state.S)):
                return "non-finite momentum"
        elif not state.is_finite():
            return "non-finite configuration"
        if growth is None:
            return None
        if k & (k - 1) == 0:
            fast = guard_energies(scheme, state) if compiled_energies else None
            K, V = fast if fast is not None else (scheme.kinetic_energy(state), scheme.potential_energy(state))
            energies = {
                "kinetic_energy": float(K),
                "potential_energy": float(V),
                "dissipated_energy": float(state.scalars.get("dissipated_energy", 0.0)),
                "external_work": float(state.scalars.get("external_work", 0.0)),
            }
            if state.scalars.get("nstep") == 1:
                _scale_from_rest(scale, energies)
            reason = _balance(energies, e0, growth, scale[0])
            if reason is None:
                _raise_scale(scale, energies, e0)
            return reason
        if momentum and scale[1] >= 1 and scale[0] > 0:
            K = 0.5 * float(np.sum(w * state.S * state.S * inv))
            if not K <= growth * scale[0]:
                return (
                    f"kinetic energy {K:.3g} grew beyond {growth:g} × the energy scale "
                    f"{scale[0]:.3g} of the run"
                )
        return None

    guard.kinetic_limit = kinetic_limit
    guard.energy_checks = growth is not None
    return guard


def _balance(rec: Mapping[str, Any], e0: float, growth: float | None, scale: float) -> str | None:
    """Energy test: non-finite energies, or a balance error ``|K + V + D − W − E₀|`` beyond
    both ``growth × scale`` and half of ``|K| + |V| + |D| + |W|``."""
    for name in ("kinetic_energy", "potential_energy", "dissipated_energy", "external_work"):
        if not math.isfinite(rec[name]):
            return f"non-finite {name.replace('_', ' ')}"
    if growth is not None and scale > 0:
        err = _balance_error(rec, e0)
        if err > growth * scale and err > 0.5 * _magnitude(rec):
            return (
                f"energy balance error {err:.3g} grew beyond {growth:g} × the energy scale "
                f"{scale:.3g} of the run"
            )
    return None


def _check_frame(rec: Mapping[str, Any], e0: float, growth: float | None, scale: float) -> str | None:
    """Full blow-up test on a saved frame: non-finite fields, then :func:`_balance`."""
    for name in ("X", "S", "N"):
        if name in rec and not np.all(np.isfinite(rec[name])):
            return {"X": "non-finite strain", "S": "non-finite momentum", "N": "non-finite velocity"}[name]
    return _balance(rec, e0, growth, scale)


def _balance_error(rec: Mapping[str, Any], e0: float) -> float:
    return abs(
        rec["kinetic_energy"] + rec["potential_energy"] + rec["dissipated_energy"] - rec["external_work"] - e0
    )


#: initial energy below this fraction of the first checked state's: the run starts from rest
_REST = 1e-8


def _scale_from_rest(scale: list[float], rec: Mapping[str, Any]) -> None:
    """At the run's first step: a run released from rest (initial ``|K| + |V|`` at round-off,
    below ``_REST`` times the energy after one step) takes the energy after one step as its
    scale.  What is there the loads put there in one step, and a first-order integrator's
    energy balance need not close at step 1 (explicit Euler under gravity: K = ½m(gΔt)², W = 0).
    Only step 1: later, energy that dwarfs the initial state's may be a blow-up's."""
    if scale[1] == 0:
        magnitude = _magnitude(rec)
        if scale[0] <= _REST * magnitude:
            scale[0] = magnitude
            scale[1] = 1


def _raise_scale(scale: list[float], rec: Mapping[str, Any], e0: float) -> None:
    """Raise the energy scale with a state whose energy budget closes (balance error at most
    half its energy): energy that blow-up created never becomes the yardstick."""
    if _balance_error(rec, e0) <= 0.5 * _magnitude(rec):
        scale[0] = max(scale[0], _magnitude(rec))
        scale[1] = max(scale[1], 1)


def _magnitude(rec: Mapping[str, Any]) -> float:
    return (
        abs(rec["kinetic_energy"])
        + abs(rec["potential_energy"])
        + abs(rec["dissipated_energy"])
        + abs(rec["external_work"])
    )


def _append(records: dict[str, list], rec: Mapping[str, Any]) -> None:
    for key, value in rec.items():
        records.setdefault(key, []).append(value)


def _truncate(records: Mapping[str, list], n: int) -> dict[str, list]:
    return {k: list(v[:n]) for k, v in records.items()}


def _resolution_note(scheme: Scheme, good: State, failed: State) -> str:
    """``"; <why the shape is under-resolved>"`` when the last good or the failed state turns
    neighbouring frames by more than :data:`cartan.resolution.LIMIT` (then no Δt helps), else
    ``""``."""
    from .resolution import under_resolved

    with np.errstate(all="ignore"):
        for st in (failed, good):
            note = under_resolved(scheme, st)
            if note is not None:
                return f"; {note}"
    return ""


def _default_dt(scheme: Scheme, integrator: Integrator, state: State, dt_max: float) -> float:
    """The time step of a run that gives none: half the CFL estimate ``dt_max``, rounded down
    to two significant digits.

    An integrator without a stability limit (``dt_max = inf``: ``implicit-midpoint``) that
    steps momenta takes the explicit time scale 1/ω_max of the linearised system
    (:meth:`~cartan.schemes.base.Scheme.dt_max`, ω_max² = λ_max(M⁻¹K)), the step
    ``lie-verlet`` takes by default: ω_max Δt = 1 resolves the fastest mode (the midpoint
    rule's phase error there ≈ (ω_maxΔt)²/12 ≈ 8 %, smaller on every slower mode).  A larger
    step is the user's to choose (``dt=``): it is stable, but it no longer resolves the
    fastest modes.

    Raises
    ------
    ValueError
        No Δt is stable (``dt_max = 0``), or the integrator has no stability limit and no
        inertial time scale (it prescribes the velocity: ``kinematic``; or the medium has no
        stiffness).
    """
    if 0 < dt_max < math.inf:
        return _round_down(0.5 * dt_max)
    if dt_max == math.inf and integrator.uses_momentum:
        scale = float(scheme.dt_max(state, rate=integrator.rate))  # 1/ω_max (1e150 without stiffness)
        if 0 < scale < 1e100:
            return _round_down(scale)
        raise ValueError(f"dt is required: {integrator.name!r} has no stability limit and the problem no "
                         f"stiffness that sets a time scale (1/ω_max = {scale:g})")
    if dt_max == math.inf:
        raise ValueError(f"dt is required: {integrator.name!r} has no stability limit and prescribes the "
                         f"velocity, so no time scale of the problem sets a default step")
    raise ValueError(f"dt is required: the CFL estimate of {integrator.name!r} is {dt_max:g} (no step is stable)")


def _describe_dt(dt: float, dt_max: float) -> str:
    if dt_max == 0:
        return f"Δt = {dt:.3g} exceeds the CFL estimate 0 (no stable Δt for undamped motion)"
    if dt > dt_max:
        return f"Δt = {dt:.3g} exceeds the CFL estimate {dt_max:.3g}"
    if dt_max == math.inf:
        return f"Δt = {dt:.3g} (no stability limit)"
    return f"Δt = {dt:.3g} is within the CFL estimate {dt_max:.3g}"


def _unstable_path(output: pathlib.Path | None) -> pathlib.Path:
    """Where a blow-up leaves the last good state: beside the output (``out.lastgood.nc``,
    :func:`cartan.io.lastgood_path`), which is never replaced by it; a temporary file without one."""
    from . import io

    if output is not None:
        return io.lastgood_path(output)
    fd, name = tempfile.mkstemp(prefix="cartan-unstable-", suffix=".nc")
    os.close(fd)
    return pathlib.Path(name)


def _frame_bytes(problem: Problem) -> float:
    """A lower estimate of the memory of one saved frame: strains, velocity, momentum (r each
    per node) and the configuration (m × m per node), float64."""
    g = problem.medium.group
    nodes = math.prod(problem.grid.shape)
    return 8.0 * nodes * (int(g.matrix_size) ** 2 + (2 + problem.grid.d) * int(g.dim))


def _checkpoint_scene_path(info: Mapping[str, Any], attrs: Mapping[str, Any] | None,
                           restart: pathlib.Path) -> str | None:
    """The scene file a checkpointed run came from: the checkpoint's ``scene_path``, else (a
    file written without it) the ``scene_path`` of the run file's ``cartan_config``; None for a
    run not started from a scene file.  A ``scene_path`` in the checkpoint that is neither None
    nor a path is a ValueError naming the field."""
    import json

    if "scene_path" in info:
        value = info["scene_path"]
        if value is not None and not (isinstance(value, str) and value):
            raise ValueError(
                f"restart file {str(restart)!r}: damaged checkpoint: scene_path must be a path or null, "
                f"got {value!r:.200}"
            )
        return value
    try:
        config = json.loads((attrs or {}).get("cartan_config", ""))
    except (TypeError, ValueError):
        return None
    value = config.get("scene_path") if isinstance(config, dict) else None
    return value if isinstance(value, str) and value else None


#: CFL estimates of recent runs, by the content of what they depend on (:func:`_cfl_estimate`)
_CFL_MEMO: dict[bytes, float] = {}
#: the most estimates :data:`_CFL_MEMO` keeps
_CFL_MEMO_SIZE = 16
#: runs whose state is larger than this (bytes) are not memoised (their key would copy the state)
_CFL_MEMO_BYTES = 1 << 25
_CFL_LOCK = threading.Lock()


def _cfl_estimate(problem: Problem, scheme: Scheme, integrator: Integrator, state: State) -> float:
    """``integrator.dt_max(scheme, state)``, the CFL estimate, computed once per content.

    The estimate is a function of the problem, the scheme and integrator with their options,
    whether the scheme's compiled diagnostics are on, the backend and the state; a run of the
    same content as one of the last :data:`_CFL_MEMO_SIZE` (a pilot and its warm-up, a run
    repeated in a study) takes the number computed then, the same float.  The content is the
    pickle of those objects (a SHA-256 digest of it); what cannot be pickled, and a state larger
    than :data:`_CFL_MEMO_BYTES`, is estimated afresh.

    Returns
    -------
    float
        The estimate (0 when no Δt is stable, inf without a stability limit, possibly NaN).
    """
    import hashlib
    import pickle
    from io import BytesIO

    from ._backend import get_backend
    from .groups.base import SymmetryGroup

    class _Pickler(pickle.Pickler):
        def persistent_id(self, obj: Any) -> Any:  # a group by its kind (its lazy caches are no content)
            if not isinstance(obj, SymmetryGroup):
                return None
            return ("group", type(obj).__qualname__, repr(obj),
                    sorted((k, repr(v)) for k, v in vars(obj).items() if not k.startswith("_")))

    size = state.S.nbytes + sum(np.asarray(a).nbytes for a in state.arrays.values())
    if size > _CFL_MEMO_BYTES:  # a large run: no copy of its state for the key (estimated afresh)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return float(integrator.dt_max(scheme, state))
    buffer = BytesIO()
    try:
        _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(
            (problem, type(scheme).__qualname__, scheme.options(), bool(getattr(scheme, "compiled_diagnostics", False)),
             type(integrator).__qualname__, integrator.options(), get_backend(), state.t, state.S, state.arrays,
             state.scalars))
        key = hashlib.sha256(buffer.getvalue()).digest()
    except Exception:  # noqa: BLE001 - anything unpicklable (a closure, a compiled function) is estimated afresh
        key = None
    if key is not None:
        with _CFL_LOCK:
            if key in _CFL_MEMO:
                return _CFL_MEMO[key]
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        dt_max = float(integrator.dt_max(scheme, state))
    if key is not None:
        with _CFL_LOCK:  # runs on threads (a study's sweep) share the memo
            while len(_CFL_MEMO) >= _CFL_MEMO_SIZE:
                _CFL_MEMO.pop(next(iter(_CFL_MEMO)))
            _CFL_MEMO[key] = dt_max
    return dt_max


# ---------------------------------------------------------------------------- a resolved run
@dataclass
class _ResolvedRun:
    """A run whose settings are all settled: what :func:`_resolve_run` returns and
    :func:`_execute_run` carries out.

    Attributes
    ----------
    problem : Problem
    scheme : Scheme
    integrator : Integrator
        With its counters taken over from the checkpoint on a restart.
    state : State
        The state the loop starts from (advanced in place by it).
    dt, dt_max : float
        The time step and the integrator's CFL estimate.
    nsteps : int
        Steps from t = 0 to ``t_end`` (a restart continues from ``step``).
    save_every : int
    checkpoint_every : int or None
    output : pathlib.Path or None
        Checked to be writable.
    growth : float or None
        The blow-up threshold, None when the energy tests are off.
    compiled : bool
    progress : bool or None
    info : dict
        ``problem``, ``run``, ``scene`` and ``scene_path`` of ``cartan_config`` (the counters
        are added when a file is written).
    history : str
        The ``history`` attribute.
    records : dict of str → list
        The frames so far (the initial one, or those of the checkpoint).
    step, nsaves : int
        Steps done and frames saved so far.
    e0 : float
        The initial energy K + V.
    scale : list
        ``[energy scale, established]`` of the blow-up tests.
    """

    problem: Problem
    scheme: Scheme
    integrator: Integrator
    state: State
    dt: float
    dt_max: float
    nsteps: int
    save_every: int
    checkpoint_every: int | None
    output: pathlib.Path | None
    growth: float | None
    compiled: bool
    progress: bool | None
    info: dict[str, Any]
    history: str
    records: dict[str, list]
    step: int
    nsaves: int
    e0: float
    scale: list


# ---------------------------------------------------------------------------- simulate
def simulate(
    problem_or_scene: Problem | Scene | str | os.PathLike | None,
    integrator: str | type[Integrator] | Integrator | None = None,
    scheme: str | type[Scheme] | None = None,
    dt: float | None = None,
    t_end: float | None = None,
    save_every: int | None = None,
    output: str | os.PathLike | None = None,
    restart: str | os.PathLike | None = None,
    checkpoint_every: int | None = None,
    integrator_options: Mapping[str, Any] | None = None,
    scheme_options: Mapping[str, Any] | None = None,
    progress: bool | None = None,
    max_energy_growth: float | None = 1e3,
    *,
    compiled: bool = True,
    command: str | None = None,
    max_steps: int | None = None,
    reduce: bool = True,
) -> xr.Dataset:
    """Run a problem and return its frames and diagnostics as an :class:`xarray.Dataset`.

    Parameters
    ----------
    problem_or_scene : Problem, Scene, path, str or None
        What to run: a :class:`~cartan.Problem`, a :class:`~cartan.scene.Scene`, a scene file
        (``*.toml``) or a registered scene name.  A scene supplies defaults for every run
        setting below from its ``[run]`` table.  None is allowed with ``restart`` when the
        run was started from a scene (it is rebuilt from the copy kept in the file).
    integrator : str, Integrator subclass or instance, optional
        Registered name (default ``"lie-verlet"``) or class, as in scipy.
    scheme : str or Scheme subclass, optional
        Registered name (default ``"lattice"``) or class.
    dt : float, optional
        Time step, a finite real number > 0.  Default: half the integrator's CFL estimate,
        rounded down to two significant digits; for an integrator without a stability limit
        (``implicit-midpoint``) the inertial time scale 1/ω_max (``_default_dt``).  A Δt above the estimate gives a
        :class:`StabilityWarning` (after every setting has been checked, just before the run).
    t_end : float
        Final time (required unless a scene or the restart file gives it).  When Δt does not
        divide it, the run takes ``ceil(t_end/Δt)`` steps: at least one (a ``t_end`` too short
        for a single step is an error), at most ``max_steps``.
    save_every : int, optional
        Steps between saved frames (default: about 100 frames).  The initial and final
        states are always saved.
    output : path, optional
        netCDF file written (atomically) at every checkpoint and at the end, with the final
        state as a checkpoint so that the run can be continued.  With ``restart`` and no
        ``output``, the restart file is updated in place.  Checked before the run
        (:func:`cartan.io.check_output`: its folder exists and is writable, and it is not
        anything but a regular file).
    restart : path, optional
        Continue the run saved in this file from its last checkpoint.  With the same
        settings the result is identical, bit for bit, to the uninterrupted run (only the
        ``history`` attribute and the force/wall-time counters in ``cartan_config``
        differ).  A larger ``t_end`` extends a finished run.  The scene the run came from
        (``scene`` and ``scene_path`` in ``cartan_config``) is kept when the restart is given
        the Problem, or None.
    checkpoint_every : int, optional
        Write the run so far and the exact state to ``output`` every this many saves.
    integrator_options, scheme_options : dict, optional
        Keyword arguments of the integrator and scheme constructors.
    progress : bool, optional
        Show a progress bar (tqdm).  Default: only when stderr is a terminal and the
        environment variable ``CI`` is not set.
    max_energy_growth : float or None
        Blow-up threshold, finite and > 0 (see the module docstring); None disables the energy tests
        (non-finite values are always detected).  Integrators that prescribe N
        (``kinematic``: no stability limit and no momentum) have no energy budget to test and
        get the non-finite test only.
    compiled : bool, default True
        Run the steps between saves in compiled code when the combination qualifies (the
        lattice and collocation schemes, d = 1–3, with a quadratic medium and data-like loads;
        ``implicit-midpoint``'s own compiled blocks; ``kinematic`` with a numba velocity;
        ``docs/performance.md``), else in Python.  False forces the Python loop, the reference
        path; the two agree to round-off.  A restart reproduces a run bit for bit when both
        parts use the same setting.
    command : str, optional
        Text recorded in the ``history`` attribute (default: a description of this call).
    max_steps : int, optional
        The most time steps the run may take (default: the environment variable
        ``CARTAN_MAX_STEPS``, else 10⁹; :func:`cartan.limits.step_limit`).  The frames kept in
        memory are bounded too (:func:`cartan.limits.check_memory`, ``CARTAN_MAX_MEMORY``).
    reduce : bool, default True
        Run the problem on an exact reduction when it admits one and it pays
        (:mod:`cartan.reduction`: an SE(3) problem whose data all lie in the x–y plane runs on
        the medium's SE(2) twin) and lift the frames back: the same Dataset, with the attribute
        ``cartan_reduction``.  False runs the problem as given.

    Returns
    -------
    xarray.Dataset
        See :mod:`cartan.io` for the layout.

    Raises
    ------
    InstabilityError
        When the run blows up; the last good state is on disk (see the exception), beside
        ``output`` (``out.lastgood.nc`` for ``out.nc``; ``output`` itself is not replaced).
    ValueError
        Bad settings (naming them and the allowed range), a damaged restart file, an output
        that cannot be written; :class:`~cartan.scene.SceneError` for bad scenes.
    """
    if not isinstance(reduce, bool | np.bool_):
        raise ValueError(f"reduce must be True or False, got {reduce!r}")
    run = _resolve_run(
        problem_or_scene, integrator, scheme, dt, t_end, save_every, output, restart, checkpoint_every,
        integrator_options, scheme_options, progress, max_energy_growth,
        compiled=compiled, command=command, max_steps=max_steps,
    )
    if reduce:
        from .reduction import run_reduced

        ds = run_reduced(run, restart=restart)
        if ds is not None:
            return ds
    return _execute_run(run)


def _resolve_run(
    problem_or_scene: Problem | Scene | str | os.PathLike | None,
    integrator: str | type[Integrator] | Integrator | None,
    scheme: str | type[Scheme] | None,
    dt: float | None,
    t_end: float | None,
    save_every: int | None,
    output: str | os.PathLike | None,
    restart: str | os.PathLike | None,
    checkpoint_every: int | None,
    integrator_options: Mapping[str, Any] | None,
    scheme_options: Mapping[str, Any] | None,
    progress: bool | None,
    max_energy_growth: float | None,
    *,
    compiled: bool,
    command: str | None,
    max_steps: int | None,
) -> _ResolvedRun:
    """Settle everything :func:`simulate` runs, before any step is taken.

    The arguments are those of :func:`simulate`.  Each setting comes from the argument, else
    the restart file, else the scene's ``[run]`` table, else the default; the scheme and
    integrator are built, a checkpoint is checked against them, the CFL estimate is computed
    (or taken from a checkpoint of the same integrator and scheme) and Δt defaults to half of
    it; the step count, the output file and the memory of the frames are checked; a Δt above
    the estimate gives a :class:`StabilityWarning` (pointing at the caller of
    :func:`simulate`); the initial frame is recorded (a fresh run) or the frames and energy
    reference of the checkpoint are taken over.

    Returns
    -------
    _ResolvedRun

    Raises
    ------
    ValueError, TypeError
        As :func:`simulate`, for bad settings; nothing has been run or written.
    """
    from . import io

    _check_arguments(dt, t_end, save_every, checkpoint_every, output, restart, integrator_options,
                     scheme_options, progress, max_energy_growth, compiled, command)
    limit = step_limit(max_steps)
    # -- what to run and with which settings: explicit > restart file > scene > defaults
    ck_state = ck_info = ck_records = ck_attrs = ck_scene_path = None
    if restart is not None:
        restart = pathlib.Path(restart)
        ck_state, ck_info, ck_records, ck_attrs = io.read_checkpoint(restart)
        io.check_run_info(ck_info, restart)
        ck_scene_path = _checkpoint_scene_path(ck_info, ck_attrs, restart)
        if output is None:
            output = restart
    if problem_or_scene is None:
        if ck_info is None or not ck_info.get("scene"):
            raise ValueError(
                "simulate needs a problem or scene (only a restart of a scene run can rebuild it)"
            )
        problem_or_scene = ck_info["scene"]
    problem, sc = _as_scene(problem_or_scene)
    held = problem.medium.constrained_strains() is not None
    run_defaults = sc.run_settings() if sc is not None else {}
    ck_run = ck_info["run"] if ck_info else {}

    integ_spec = _first(
        integrator, ck_run.get("integrator"), run_defaults.get("integrator"),
        CONSTRAINED_INTEGRATOR if held else DEFAULT_INTEGRATOR
    )
    scheme_spec = _first(scheme, ck_run.get("scheme"), run_defaults.get("scheme"), DEFAULT_SCHEME)
    same_integ = _name_of(integ_spec) == (
        ck_run.get("integrator") if ck_info else run_defaults.get("integrator")
    )
    same_scheme = _name_of(scheme_spec) == (ck_run.get("scheme") if ck_info else run_defaults.get("scheme"))
    base_iopts = (
        ck_run.get("integrator_options") if ck_info else run_defaults.get("integrator_options")
    ) or {}
    base_sopts = (ck_run.get("scheme_options") if ck_info else run_defaults.get("scheme_options")) or {}
    iopts = {**(base_iopts if same_integ else {}), **(integrator_options or {})}
    sopts = {**(base_sopts if same_scheme else {}), **(scheme_options or {})}

    scheme_cls = _resolve("schemes", scheme_spec, Scheme)
    if isinstance(scheme_cls, Scheme):
        raise TypeError("scheme must be a registered name or a Scheme subclass, not an instance")
    scheme_obj: Scheme = scheme_cls(problem, **sopts)
    scheme_obj.compiled_diagnostics = bool(compiled)  # the CFL estimate and the guard's energies
    integ = _resolve("integrators", integ_spec, Integrator)
    integ_obj: Integrator = integ(**iopts) if isinstance(integ, type) else integ
    if not isinstance(integ, type):
        integ_obj.reset()
    if held:  # the CFL estimate and the guard's energies on numpy: rattle's compiled loop (d = 1) takes the
        # steps, but compiling the operator set's diagnostics as well would cost tens of seconds per medium on a
        # fresh cache (kirchhoff-love, whose steps run in Python: 25–30 s) for work of milliseconds per save
        scheme_obj.compiled_diagnostics = False
    if held and not integ_obj.constrained:
        raise ValueError(
            f"medium {problem.medium.name!r} holds strain components fixed (constrained_strains) and integrator "
            f"{integ_obj.name!r} does not honour them: use integrator={CONSTRAINED_INTEGRATOR!r} (the default for "
            "such media)"
        )
    live = getattr(scheme_obj, "live", None)
    if integ_obj.uses_momentum and live is not None and not np.any(live):
        raise ValueError(
            f"medium {problem.medium.name!r} has no inertia (every component of its mass density is 0): "
            "its parameters are out of range"
        )

    problem_dict = problem.to_dict()
    problem_json = io.to_json(problem_dict)  # (now: a parameter that cannot be recorded fails before the run)
    if ck_info is not None:
        # (a medium reads the record of a file written by an earlier version, or says why it cannot)
        recorded = ck_info.get("problem")
        upgrade = getattr(problem.medium, "restart_record", None)
        if callable(upgrade) and isinstance(recorded, dict):
            recorded = upgrade(recorded, sorted(ck_state.arrays), str(restart))
        if problem_json != io.to_json(recorded):
            raise ValueError(
                f"restart file {str(restart)!r} was written for a different problem "
                f"({ck_info.get('problem', {}).get('medium')!r}, {ck_info.get('problem', {}).get('grid')})"
            )
        fresh = accumulators.start(scheme_obj, scheme_obj.initial_state())
        expected = set(fresh.arrays)
        if set(ck_state.arrays) != expected:
            raise ValueError(
                f"restart file {str(restart)!r} holds a {sorted(ck_state.arrays)} state but scheme "
                f"{scheme_obj.name!r} with options {scheme_obj.options()} stores {sorted(expected)}"
            )
        for name, a, b in [("S", ck_state.S, fresh.S),
                           *((k, ck_state.arrays[k], fresh.arrays[k]) for k in sorted(expected))]:
            if np.shape(a) != np.shape(b):
                raise ValueError(
                    f"restart file {str(restart)!r}: damaged checkpoint: {name} has shape {np.shape(a)}, the "
                    f"problem's state {np.shape(b)}"
                )
        state = ck_state
        integ_obj.set_counters(ck_info["counters"])
    else:
        state = accumulators.start(scheme_obj, scheme_obj.initial_state())  # (the medium's, if it declares any)
        state.scalars.setdefault("nstep", 0)

    # -- time step, CFL estimate, schedule
    if ck_info is not None and ck_run.get("integrator") == integ_obj.name and same_scheme:
        dt_max = float(ck_run["dt_max"])
    else:
        dt_max = _cfl_estimate(problem, scheme_obj, integ_obj, state)
    if math.isnan(dt_max):
        raise ValueError(
            f"the CFL estimate of {integ_obj.name!r} on {scheme_obj.name!r} is not a number: the medium's "
            f"parameters or the grid spacing ({min(problem.grid.spacing):.3g}) are out of range"
        )
    t_end = _first(t_end, ck_run.get("t_end"), run_defaults.get("t_end"))
    if t_end is None:
        raise ValueError("t_end is required (no scene or restart file gives it)")
    t_end = _real("t_end", t_end)
    dt = _first(dt, ck_run.get("dt"), run_defaults.get("dt"))
    if dt is None:
        dt = _default_dt(scheme_obj, integ_obj, state, dt_max)
    dt = _real("dt", dt)
    if ck_info is not None:
        t0, step0 = float(ck_state.t), int(ck_info["step"])
        if t_end < t0 - 1e-9 * max(dt, abs(t0)):
            raise ValueError(
                f"t_end = {t_end:g} is before the time t = {t0:g} of the checkpoint in {str(restart)!r}; "
                f"give t_end ≥ {t0:g}"
            )
        # a new Δt counts the remaining time only; the same Δt the steps from t = 0 (bit for bit).
        # Nothing left to run (t_end = t of a finished run) returns the run as it is.
        if dt != ck_run.get("dt"):
            total = step0 + _nsteps(max(t_end - t0, 0.0), dt, limit)
        else:
            total = max(_nsteps(t_end, dt, limit + step0), step0)
    else:
        total = _nsteps(t_end, dt, limit)
        if total < 1:
            raise ValueError(
                f"t_end = {t_end:g} is too short for dt = {dt:g}: the run would take no step (give t_end ≥ dt)"
            )
    save_every = _first(
        save_every, ck_run.get("save_every"), run_defaults.get("save_every"), max(1, total // DEFAULT_FRAMES)
    )
    checkpoint_every = _first(
        checkpoint_every, ck_run.get("checkpoint_every"), run_defaults.get("checkpoint_every")
    )
    save_every = _count_of("save_every", save_every)
    checkpoint_every = _count_of("checkpoint_every", checkpoint_every)
    if checkpoint_every is not None and output is None:
        raise ValueError("checkpoint_every needs an output file (output=path)")
    output = None if output is None else pathlib.Path(output)
    if output is not None:  # before the run, not after it
        io.check_output(output)
        io.check_output(io.lastgood_path(output))
    frames = (total - (int(ck_info["step"]) if ck_info is not None else 0)) // save_every + 2
    if ck_records is not None:
        frames += len(ck_records.get("time", ()))
    nodes = math.prod(problem.grid.shape)
    check_memory(
        f"keeping {frames} frames of {nodes} nodes in memory",
        frames * _frame_bytes(problem) + state_bytes(problem.medium.group, nodes, problem.grid.d),
        f"save fewer frames (a larger save_every than {save_every})",
    )
    # integrators that prescribe N (kinematic) have no energy budget to test; implicit ones
    # without a stability limit (stability = inf, uses_momentum) do
    no_budget = max_energy_growth is None or (integ_obj.stability == math.inf and not integ_obj.uses_momentum)
    growth = None if no_budget else float(max_energy_growth)
    if dt > dt_max:  # every setting is valid: the run will start
        warnings.warn(
            f"{_describe_dt(dt, dt_max)} of {integ_obj.name!r} on {scheme_obj.name!r} "
            f"(grid spacing {min(problem.grid.spacing):.3g}); the run is likely to blow up",
            StabilityWarning,
            stacklevel=3,  # the caller of simulate
        )

    run_config = {
        "integrator": integ_obj.name,
        "integrator_options": integ_obj.options(),
        "scheme": scheme_obj.name,
        "scheme_options": scheme_obj.options(),
        "dt": dt,
        "dt_max": dt_max,
        "t_end": t_end,
        "nsteps": total,
        "save_every": save_every,
        "checkpoint_every": checkpoint_every,
        "max_energy_growth": growth,
    }
    if command is None:
        what = f"scene {sc.name!r}" if sc is not None else f"problem {problem.name or problem.medium.name!r}"
        command = (
            f"cartan.simulate({what}, integrator={integ_obj.name!r}, scheme={scheme_obj.name!r}, "
            f"dt={dt!r}, t_end={t_end!r}, save_every={save_every}"
            + (f", restart={str(restart)!r}" if restart is not None else "")
            + ")"
        )
    history = io.history_line(command)
    if ck_attrs is not None and ck_attrs.get("history"):
        history = f"{ck_attrs['history']}\n{history}"
    # the scene the run came from, kept across restarts (a restart given the Problem, or the
    # scene rebuilt from the checkpoint, knows no file of its own)
    scene_source = sc.source if sc is not None and sc.source.get("medium") else None
    scene_path = str(sc.path) if sc is not None and sc.path else None
    if ck_info is not None:
        if scene_source is None:
            scene_source = ck_info.get("scene")
        if scene_path is None:
            scene_path = ck_scene_path

    # -- frames so far, energy reference
    if ck_info is not None:
        records = {k: list(v) for k, v in ck_records.items()}
        step = int(ck_info["step"])
        nsaves = int(ck_info["nsaves"])
        e0 = float(ck_info["e0"])
        scale = [float(ck_info["scale"]), int(ck_info.get("scale_set", nsaves > 0))]
    else:
        records = {}
        rec = io.frame_record(scheme_obj, integ_obj, state, defer=True)
        reason = _check_frame(rec, 0.0, None, 0.0)
        if reason is not None:
            raise ValueError(f"the initial state is not usable: {reason}")
        _append(records, rec)
        step = 0
        nsaves = 0
        e0 = rec["kinetic_energy"] + rec["potential_energy"]
        scale = [_magnitude(rec), 0]

    return _ResolvedRun(
        problem=problem,
        scheme=scheme_obj,
        integrator=integ_obj,
        state=state,
        dt=dt,
        dt_max=dt_max,
        nsteps=total,
        save_every=save_every,
        checkpoint_every=checkpoint_every,
        output=output,
        growth=growth,
        compiled=bool(compiled),
        progress=progress,
        info={"problem": problem_dict, "run": run_config, "scene": scene_source, "scene_path": scene_path},
        history=history,
        records=records,
        step=step,
        nsaves=nsaves,
        e0=e0,
        scale=scale,
    )


def _execute_run(run: _ResolvedRun) -> xr.Dataset:
    """Run what :func:`_resolve_run` settled: the save loop (see the module docstring).

    Parameters
    ----------
    run : _ResolvedRun
        Executed once: its state, frames and energy scale are updated in place.

    Returns
    -------
    xarray.Dataset
        The frames and diagnostics; also written to ``run.output`` when there is one.

    Raises
    ------
    InstabilityError
        When the run blows up (the last good state is on disk, see the exception).
    """
    from . import io

    problem, scheme_obj, integ_obj, state = run.problem, run.scheme, run.integrator, run.state
    dt, dt_max, total, save_every = run.dt, run.dt_max, run.nsteps, run.save_every
    checkpoint_every, output, growth, e0 = run.checkpoint_every, run.output, run.growth, run.e0
    records, scale, step, nsaves = run.records, run.scale, run.step, run.nsaves

    def config() -> dict[str, Any]:
        return {
            "problem": run.info["problem"],
            "run": run.info["run"],
            "counters": integ_obj.counters(),
            "scene": run.info["scene"],
            "scene_path": run.info["scene_path"],
        }

    def dataset(recs: Mapping[str, list]) -> xr.Dataset:
        return io.build_dataset(scheme_obj, recs, config=config(), history=run.history)

    def checkpoint(st: State, nframes: int, at_step: int, at_saves: int) -> xr.Dataset:
        info = {
            **config(),
            "step": at_step,
            "nsaves": at_saves,
            "nframes": nframes,
            "e0": e0,
            "scale": scale[0],
            "scale_set": scale[1],
        }
        return io.checkpoint_dataset(st, info)

    guard = _make_guard(scheme_obj, integ_obj, growth, e0, scale)
    completed = 0  # the frames before this one have their deferred diagnostics (cartan.io.complete_records)
    bar = None
    if _show_progress(run.progress) and step < total:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=total,
            initial=step,
            unit="step",
            file=sys.stderr,
            dynamic_ncols=True,
            desc=problem.name or problem.medium.name,
            leave=False,
        )
    try:
        while step < total:
            n = min(save_every - step % save_every, total - step)
            good = state.copy()
            good_info = (len(records["time"]), step, nsaves, list(scale))
            # once the energy scale is set, a compiled loop takes the whole block in one call (it tests every
            # step for non-finite values and the kinetic bound itself) and the energy test runs at the save; a
            # block that fails is run again from its start in sub-blocks, so that the failing step, the reason
            # and the counters are those of the sub-block tests (each step depends only on the state)
            whole = run.compiled and scale[1] >= 1
            counters = integ_obj.counters() if whole else None
            done, reason = _advance(integ_obj, scheme_obj, state, dt, n, guard, compiled=run.compiled, whole=whole)
            if reason is None:
                rec = io.frame_record(scheme_obj, integ_obj, state, defer=True)
                reason = _check_frame(rec, e0, growth, scale[0])
            if reason is not None and whole:
                state = good.copy()
                integ_obj.set_counters(counters)
                done, reason = _advance(integ_obj, scheme_obj, state, dt, n, guard, compiled=run.compiled)
                if reason is None:
                    rec = io.frame_record(scheme_obj, integ_obj, state, defer=True)
                    reason = _check_frame(rec, e0, growth, scale[0])
            step += done
            if reason is not None:
                nframes, good_step, good_saves, good_scale = good_info
                scale[:] = good_scale
                kept = _truncate(records, nframes)
                try:
                    path = _unstable_path(output)
                    io.write_dataset(dataset(kept), path, checkpoint(good, nframes, good_step, good_saves))
                    where = f"saved to {path}"
                    if output is not None:
                        where += (f" ({output} is left as it was)" if output.exists()
                                  else f" (nothing was written to {output})")
                except (OSError, ValueError) as exc:
                    path, where = None, f"could not be saved ({' '.join(str(exc).split())})"
                note = _resolution_note(scheme_obj, good, state) if dt <= dt_max else ""
                raise InstabilityError(
                    f"unstable at step {step} (t = {state.t:.6g}): {reason}; {_describe_dt(dt, dt_max)}{note}; "
                    f"last good state (t = {good.t:.6g}) {where}",
                    step=step,
                    time=float(state.t),
                    dt=dt,
                    dt_max=dt_max,
                    path=path,
                )
            _append(records, rec)
            if len(records["time"]) - completed >= _COMPLETE_EVERY:  # (what frames keep for it stays bounded)
                io.complete_records(scheme_obj, records, start=completed)
                completed = len(records["time"])
            nsaves += 1
            _raise_scale(scale, rec, e0)
            if bar is not None:
                bar.update(done)
            if checkpoint_every is not None and nsaves % checkpoint_every == 0 and step < total:
                io.write_dataset(
                    dataset(records), output, checkpoint(state, len(records["time"]), step, nsaves)
                )
    finally:
        if bar is not None:
            bar.close()

    ds = dataset(records)
    if output is not None:
        io.write_dataset(ds, output, checkpoint(state, len(records["time"]), step, nsaves))
    return ds
