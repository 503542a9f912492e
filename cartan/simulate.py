"""``cartan.simulate``: run a problem or scene, save frames, checkpoint, detect blow-up.

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
step, and it runs in sub-blocks that end at the steps 1, 2, 4, 8, … of the save block where
the guard runs its energy-balance test; so the guard sees the same states at the same steps
as with the Python loop, the failing step is named exactly, and the last good state is the
copy taken at the start of the save block, as before.  Each step depends only on the state,
so the result does not depend on the sub-blocks and a restart is bit for bit (with the same
path on both sides: the compiled and Python paths agree to round-off, not bit for bit).

The work around the steps uses compiled kernels too when the scheme has them
(``scheme.compiled_diagnostics``, cleared by ``compiled=False``): the CFL estimate
(:meth:`~cartan.schemes.base.Scheme.dt_max`, whose stiffness products use the lattice's
compiled force and drift) and the guard's energies (the compiled plan's quadratic energy);
saved frames always use the scheme's reference methods, with the frames rebuilt once per
frame (``docs/performance.md``, "Work around the steps").

Blow-up is detected cheaply inside each save block and fully at every save.  The tests:
non-finite momentum or configuration (every step); an energy-balance error
``|K + V + D − W − E₀|`` beyond ``max_energy_growth`` times the energy scale of the run *and*
beyond half the state's own ``|K| + |V| + |D| + |W|`` — energy the physics did not put there
(at steps 1, 2, 4, 8, … of each block and at every save); and, between those, the kinetic
energy against ``max_energy_growth`` times the energy scale.  The energy scale is the largest
``|K| + |V| + |D| + |W|`` (kinetic, potential, dissipated, external work) of the states
checked so far whose energy budget closed (balance error at most half that sum), so that
energy created by a blow-up never becomes the yardstick.  The run then stops with
:class:`InstabilityError`, after writing the frames up to the last good state, and that
state as a checkpoint, to the output file (or to a temporary file when there is none).
"""

from __future__ import annotations

import math
import os
import pathlib
import sys
import tempfile
import warnings
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from .integrators.base import Integrator
from .plugins import get_registry
from .problem import Problem
from .scene import Scene, load_scene, scene
from .schemes.base import Scheme, State

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = ["InstabilityError", "StabilityWarning", "simulate"]

DEFAULT_INTEGRATOR = "lie-verlet"
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
    if isinstance(obj, Problem):
        return obj, None
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


def _nsteps(t_end: float, dt: float) -> int:
    ratio = t_end / dt
    n = round(ratio)
    if abs(ratio - n) <= 1e-9 * max(1.0, ratio):
        return max(int(n), 0)
    return int(math.ceil(ratio))


def _round_down(x: float, digits: int = 2) -> float:
    """``x`` rounded down to ``digits`` significant digits (a tidy default time step)."""
    if not (x > 0 and math.isfinite(x)):
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
) -> tuple[int, str | None]:
    """Advance ``state`` in place by up to ``nsteps`` steps of ``dt``.

    Returns ``(steps done, None)``, or ``(steps done, reason)`` as soon as
    ``guard(state, steps done)`` reports a blow-up.  With ``compiled``, the steps go to
    the integrator's own ``compiled_advance(scheme, state, dt, n, kinetic_limit)`` when it has one
    (``implicit-midpoint``), else to ``scheme.compiled_advance``, when it accepts the
    combination (see the module docstring), in sub-blocks ending where the guard runs its
    energy test; otherwise,
    or for what it declines, to ``integrator.step`` one by one.  An implicit integrator's
    :class:`~cartan.statics.ConvergenceError` (its stage equations unsolved; the state is left
    at the last step done) is reported like a blow-up.  Integrators with a ``begin_block()``
    method (caches that change results, e.g. a kept Jacobian) are told that a block starts,
    where a restart could resume, so that restarts stay bit for bit.
    """
    from .statics import ConvergenceError

    k = 0
    begin = getattr(integrator, "begin_block", None)
    if begin is not None:
        begin()
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        fast = getattr(scheme, "compiled_advance", None) if compiled else None
        own = getattr(integrator, "compiled_advance", None) if compiled else None  # its own compiled blocks
        energy_checks = getattr(guard, "energy_checks", True)
        kinetic_limit = getattr(guard, "kinetic_limit", lambda: math.inf)
        while (own is not None or fast is not None) and k < nsteps:
            stop = min(nsteps, 1 << k.bit_length()) if energy_checks else nsteps
            before = state.scalars.get("nstep", 0)
            try:
                ran = (own(scheme, state, dt, stop - k, kinetic_limit()) if own is not None
                       else fast(integrator, state, dt, stop - k, kinetic_limit=kinetic_limit()))
            except ConvergenceError as exc:  # the step after those done failed
                return k + state.scalars.get("nstep", 0) - before + 1, str(exc)
            if not ran:
                break
            k += state.scalars.get("nstep", 0) - before
            reason = guard(state, k)
            if reason is not None:
                return k, reason
        for j in range(k, nsteps):
            try:
                integrator.step(scheme, state, dt)
            except ConvergenceError as exc:
                return j + 1, str(exc)
            reason = guard(state, j + 1)
            if reason is not None:
                return j + 1, reason
    return nsteps, None


def _make_guard(scheme: Scheme, integrator: Integrator, growth: float | None, e0: float, scale: list[float]):
    """Per-step blow-up test ``guard(state, k)``, k = steps done in the current save block.

    Every step: non-finite momentum (or configuration, for integrators without momentum).
    At k = 1, 2, 4, 8, …: the energy-balance test of :func:`_balance` on K and V (two
    energy evaluations, from the compiled plan's quadratic energy when the lattice has one and
    ``scheme.compiled_diagnostics`` is set: ``cartan.schemes._lattice_diagnostics.guard_energies``),
    which also raises the energy scale ``scale[0]`` and marks it established (``scale[1] ≥ 1``).
    At the other steps, once the scale is established: the kinetic energy ½Σ w S²/m against
    ``growth × scale[0]`` (one pass over S).
    """
    inv = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    w = scheme.weights[..., None]
    momentum = integrator.uses_momentum
    compiled_energies = bool(getattr(scheme, "compiled_diagnostics", False)) and growth is not None
    if compiled_energies:
        from .schemes._lattice_diagnostics import guard_energies

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


def _describe_dt(dt: float, dt_max: float) -> str:
    if dt_max == 0:
        return f"Δt = {dt:.3g} exceeds the CFL estimate 0 (no stable Δt for undamped motion)"
    if dt > dt_max:
        return f"Δt = {dt:.3g} exceeds the CFL estimate {dt_max:.3g}"
    if dt_max == math.inf:
        return f"Δt = {dt:.3g} (no stability limit)"
    return f"Δt = {dt:.3g} is within the CFL estimate {dt_max:.3g}"


def _unstable_path(output: pathlib.Path | None) -> pathlib.Path:
    if output is not None:
        return output
    fd, name = tempfile.mkstemp(prefix="cartan-unstable-", suffix=".nc")
    os.close(fd)
    return pathlib.Path(name)


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
        Time step.  Default: half the integrator's CFL estimate, rounded down to two
        significant digits.  A Δt above the estimate gives a :class:`StabilityWarning`.
    t_end : float
        Final time (required unless a scene or the restart file gives it).  When Δt does not
        divide it, the run takes ``ceil(t_end/Δt)`` steps.
    save_every : int, optional
        Steps between saved frames (default: about 100 frames).  The initial and final
        states are always saved.
    output : path, optional
        netCDF file written (atomically) at every checkpoint and at the end, with the final
        state as a checkpoint so that the run can be continued.  With ``restart`` and no
        ``output``, the restart file is updated in place.
    restart : path, optional
        Continue the run saved in this file from its last checkpoint.  With the same
        settings the result is identical, bit for bit, to the uninterrupted run (only the
        ``history`` attribute and the force/wall-time counters in ``cartan_config``
        differ).  A larger ``t_end`` extends a finished run.
    checkpoint_every : int, optional
        Write the run so far and the exact state to ``output`` every this many saves.
    integrator_options, scheme_options : dict, optional
        Keyword arguments of the integrator and scheme constructors.
    progress : bool, optional
        Show a progress bar (tqdm).  Default: only when stderr is a terminal and the
        environment variable ``CI`` is not set.
    max_energy_growth : float or None
        Blow-up threshold (see the module docstring); None disables the energy tests
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

    Returns
    -------
    xarray.Dataset
        See :mod:`cartan.io` for the layout.

    Raises
    ------
    InstabilityError
        When the run blows up; the last good state is on disk (see the exception).
    ValueError
        Bad settings (naming them); :class:`~cartan.scene.SceneError` for bad scenes.
    """
    from . import io

    # -- what to run and with which settings: explicit > restart file > scene > defaults
    ck_state = ck_info = ck_records = ck_attrs = None
    if restart is not None:
        restart = pathlib.Path(restart)
        ck_state, ck_info, ck_records, ck_attrs = io.read_checkpoint(restart)
        if output is None:
            output = restart
    if problem_or_scene is None:
        if ck_info is None or not ck_info.get("scene"):
            raise ValueError(
                "simulate needs a problem or scene (only a restart of a scene run can rebuild it)"
            )
        problem_or_scene = ck_info["scene"]
    problem, sc = _as_scene(problem_or_scene)
    run_defaults = sc.run_settings() if sc is not None else {}
    ck_run = ck_info["run"] if ck_info else {}

    integ_spec = _first(
        integrator, ck_run.get("integrator"), run_defaults.get("integrator"), DEFAULT_INTEGRATOR
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

    problem_dict = problem.to_dict()
    if ck_info is not None:
        if io.to_json(problem_dict) != io.to_json(ck_info.get("problem")):
            raise ValueError(
                f"restart file {str(restart)!r} was written for a different problem "
                f"({ck_info.get('problem', {}).get('medium')!r}, {ck_info.get('problem', {}).get('grid')})"
            )
        expected = set(scheme_obj.initial_state().arrays)
        if set(ck_state.arrays) != expected:
            raise ValueError(
                f"restart file {str(restart)!r} holds a {sorted(ck_state.arrays)} state but scheme "
                f"{scheme_obj.name!r} with options {scheme_obj.options()} stores {sorted(expected)}"
            )
        state = ck_state
        integ_obj.nstep = int(ck_info["counters"]["nstep"])
        integ_obj.nforce = int(ck_info["counters"]["nforce"])
        integ_obj.wall_time = float(ck_info["counters"]["wall_time"])
    else:
        state = scheme_obj.initial_state()
        state.scalars.setdefault("nstep", 0)

    # -- time step, CFL estimate, schedule
    if ck_info is not None and ck_run.get("integrator") == integ_obj.name and same_scheme:
        dt_max = float(ck_run["dt_max"])
    else:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            dt_max = float(integ_obj.dt_max(scheme_obj, state))
    t_end = _first(t_end, ck_run.get("t_end"), run_defaults.get("t_end"))
    if t_end is None:
        raise ValueError("t_end is required (no scene or restart file gives it)")
    t_end = float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be finite and > 0, got {t_end!r}")
    dt = _first(dt, ck_run.get("dt"), run_defaults.get("dt"))
    if dt is None:
        if not (0 < dt_max < math.inf):
            raise ValueError(f"dt is required: the CFL estimate of {integ_obj.name!r} is {dt_max:g}")
        dt = _round_down(0.5 * dt_max)
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    if dt > dt_max:
        warnings.warn(
            f"{_describe_dt(dt, dt_max)} of {integ_obj.name!r} on {scheme_obj.name!r} "
            f"(grid spacing {min(problem.grid.spacing):.3g}); the run is likely to blow up",
            StabilityWarning,
            stacklevel=2,
        )
    if ck_info is not None and dt != ck_run.get("dt"):  # a new Δt counts the remaining time only
        total = int(ck_info["step"]) + _nsteps(max(t_end - ck_state.t, 0.0), dt)
    else:
        total = _nsteps(t_end, dt)
    save_every = _first(
        save_every, ck_run.get("save_every"), run_defaults.get("save_every"), max(1, total // DEFAULT_FRAMES)
    )
    checkpoint_every = _first(
        checkpoint_every, ck_run.get("checkpoint_every"), run_defaults.get("checkpoint_every")
    )
    for name, value in (("save_every", save_every), ("checkpoint_every", checkpoint_every)):
        if value is not None and (isinstance(value, bool) or int(value) != value or value < 1):
            raise ValueError(f"{name} must be an integer ≥ 1, got {value!r}")
    save_every = int(save_every)
    checkpoint_every = None if checkpoint_every is None else int(checkpoint_every)
    if checkpoint_every is not None and output is None:
        raise ValueError("checkpoint_every needs an output file (output=path)")
    output = None if output is None else pathlib.Path(output)
    # integrators that prescribe N (kinematic) have no energy budget to test; implicit ones
    # without a stability limit (stability = inf, uses_momentum) do
    no_budget = max_energy_growth is None or (integ_obj.stability == math.inf and not integ_obj.uses_momentum)
    growth = None if no_budget else float(max_energy_growth)

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
    scene_source = sc.source if sc is not None and sc.source.get("medium") else None

    def config() -> dict[str, Any]:
        return {
            "problem": problem_dict,
            "run": run_config,
            "counters": {
                "nstep": integ_obj.nstep,
                "nforce": integ_obj.nforce,
                "wall_time": integ_obj.wall_time,
            },
            "scene": scene_source,
            "scene_path": str(sc.path) if sc is not None and sc.path else None,
        }

    def dataset(recs: Mapping[str, list]) -> xr.Dataset:
        return io.build_dataset(scheme_obj, recs, config=config(), history=history)

    # -- frames so far, energy reference
    if ck_info is not None:
        records = {k: list(v) for k, v in ck_records.items()}
        step = int(ck_info["step"])
        nsaves = int(ck_info["nsaves"])
        e0 = float(ck_info["e0"])
        scale = [float(ck_info["scale"]), int(ck_info.get("scale_set", nsaves > 0))]
    else:
        records = {}
        rec = io.frame_record(scheme_obj, integ_obj, state)
        reason = _check_frame(rec, 0.0, None, 0.0)
        if reason is not None:
            raise ValueError(f"the initial state is not usable: {reason}")
        _append(records, rec)
        step = 0
        nsaves = 0
        e0 = rec["kinetic_energy"] + rec["potential_energy"]
        scale = [_magnitude(rec), 0]

    def checkpoint(st: State, nframes: int, at_step: int, at_saves: int) -> xr.Dataset:
        info = {
            "problem": problem_dict,
            "run": run_config,
            "counters": {
                "nstep": integ_obj.nstep,
                "nforce": integ_obj.nforce,
                "wall_time": integ_obj.wall_time,
            },
            "scene": scene_source,
            "step": at_step,
            "nsaves": at_saves,
            "nframes": nframes,
            "e0": e0,
            "scale": scale[0],
            "scale_set": scale[1],
        }
        return io.checkpoint_dataset(st, info)

    guard = _make_guard(scheme_obj, integ_obj, growth, e0, scale)
    bar = None
    if _show_progress(progress) and step < total:
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
            done, reason = _advance(integ_obj, scheme_obj, state, dt, n, guard, compiled=compiled)
            step += done
            if reason is None:
                rec = io.frame_record(scheme_obj, integ_obj, state)
                reason = _check_frame(rec, e0, growth, scale[0])
            if reason is not None:
                nframes, good_step, good_saves, good_scale = good_info
                scale[:] = good_scale
                kept = _truncate(records, nframes)
                try:
                    path = _unstable_path(output)
                    io.write_dataset(dataset(kept), path, checkpoint(good, nframes, good_step, good_saves))
                    where = f"saved to {path}"
                except OSError as exc:
                    path, where = None, f"could not be saved ({exc})"
                raise InstabilityError(
                    f"unstable at step {step} (t = {state.t:.6g}): {reason}; {_describe_dt(dt, dt_max)}; "
                    f"last good state (t = {good.t:.6g}) {where}",
                    step=step,
                    time=float(state.t),
                    dt=dt,
                    dt_max=dt_max,
                    path=path,
                )
            _append(records, rec)
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
