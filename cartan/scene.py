"""Scenes: a runnable problem plus its run settings, read from a TOML file or a dict.

A scene file names a registered medium and gives, in plain tables, everything
:func:`cartan.simulate` needs::

    name = "rod-butterfly"
    description = "free bent rod, no damping"
    medium = "cosserat-rod"
    [parameters]          # medium constructor keywords
    E = 1e4
    [grid]
    n = 41                # or shape = [..] for d >= 2
    length = 3.0
    periodic = false
    [boundaries]          # optional; ends "start"/"end" (d = 1) or "u-start", ...
    start = { kind = "clamped" }
    end = { kind = "free", load = [0, 0, -1, 0, 0, 0], follower = false }
    # a held end may carry a load too (d = 1): start = { kind = "held", components = [0, 1, 2],
    # load = [0, 0, 0, 0, 0, 1] } -- a node force at the end, its held components the reaction
    # a driven end turns (moves) with a constant body velocity: end = { kind = "driven",
    # velocity = [0, 0, 0, 0.5, 0, 0] } -- the end's frame is Phi(0) exp(t xi) (cartan.Driven)
    [[loads]]             # optional, repeated
    kind = "gravity"
    g = [0, 0, -9.81]
    [initial]             # -> medium.initial_state(grid, kind, **rest)
    kind = "arc"
    curvature = 1.0
    [run]
    integrator = "lie-verlet"   # plus optional [run.integrator_options]
    scheme = "lattice"          # plus optional [run.scheme_options]
    dt = 1e-4
    t_end = 1.0
    save_every = 100

Load kinds ``"damping"`` (``coefficients``), ``"uniform-force"`` (``components``,
``frame``) and ``"node-force"`` (:class:`~cartan.problem.NodeForce`: ``force``, ``at`` or ``node``, ``frame``)
are the core's; every other kind is built by ``medium.make_load(kind, **rest)``.

Modes
-----
``mode = "dynamic"`` (the default) runs :func:`cartan.simulate` with the ``[run]`` table.
A ``[flow]`` table (``mode = "flow"``, implied) runs the flow a plugin registered under its
``kind`` (registry ``"flows"``) with the table's other keys as keyword options, checked against
the flow's signature, its defaults' types and its optional ``check(problem, options)``.
``mode = "static"`` finds an equilibrium with :func:`cartan.statics.solve_static`, settings in
``[static]``::

    mode = "static"
    [static]
    tol = 1e-10             # residual tolerance (relative to the largest external nodal force)
    max_iterations = 50     # Newton iterations per load step
    load_steps = 1
    reuse = 1e-3            # optional: keep the factorised Jacobian while Newton contracts this much
    initial_guess = "previous.nc"   # optional: start from the last frame of a run file
    measure = { node = "end", component = "z" }   # optional: a displacement to report

``mode = "continuation"`` follows the equilibrium path in the load factor λ with
:func:`cartan.continuation.continuation`, settings in ``[continuation]``::

    mode = "continuation"
    [continuation]
    parameter = "end"       # the load λ scales: a loaded end, or "all" (every external load)
    lambda_max = 15.0       # follow λ from 0 to lambda_max
    ds = 0.05               # first arclength step; ds_min, ds_max bound it
    max_steps = 200         # path points allowed
    measure = { node = "middle", component = "y" }   # the displacement recorded along the path
    pins = { start = ["x", "y"], end = ["y"] }      # position components held (free ends only)
    branch_switch = true    # leave the path at the first bifurcation

On a lattice of d ≥ 2 the keys of ``pins`` name nodes per axis — ``start``, ``middle``,
``end`` or an index, comma-separated: ``pins = { "start,start" = ["x", "y", "z"], "end,middle" =
["z"] }`` (:func:`cartan.statics.pin_node`).  ``pins = "rigid"`` holds every component of the
first node instead: the rigid-body gauge of a body without clamps, a closed filament or a free
body under balanced loads (:func:`cartan.statics.rigid_gauge_pins`).

Static and continuation scenes have no ``[run]`` table; :meth:`Scene.run` runs any mode and
writes the result (CF attributes, ``history``, ``cartan_config``) atomically.

Every problem found while reading a scene — malformed TOML, a missing or unknown key, an
unknown medium, integrator, scheme or load kind, a parameter the medium rejects — raises
:class:`SceneError` with one line naming the file and the key, e.g.
``rod.toml: parameters: E must be > 0, got -1.0``.

Values and limits
-----------------
Scene files are regular files of at most :data:`MAX_SCENE_BYTES` (1 MiB), UTF-8 with or
without a byte-order mark, nested at most :data:`MAX_NESTING` levels deep.  A number is a
TOML number: a string that spells a number or a boolean (``"1e5"``, ``"inf"``, ``"false"``)
is an error wherever it appears (except ``name`` and ``description``), and a boolean is not
a number (``E = true`` is an error; a keyword takes ``true``/``false`` only where the
constructor declares a boolean default, or in ``[initial]`` and ``[[loads]]`` tables, which
the medium checks).  Numbers are finite, integers fit in 64 bits.  Grids are bounded by the
memory their state needs (:func:`cartan.limits.check_memory`, :envvar:`CARTAN_MAX_MEMORY`),
time-step counts by :func:`cartan.limits.step_limit` (:envvar:`CARTAN_MAX_STEPS`), and the work
of static and continuation solves by :data:`MAX_LOAD_STEPS`, :data:`MAX_ITERATIONS` and
:data:`MAX_PATH_POINTS`, flows by :data:`MAX_FLOW_STEPS`.
"""

from __future__ import annotations

import inspect
import math
import numbers
import os
import pathlib
import stat
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .grid import Grid
from .limits import (  # noqa: F401 - re-exported: the limits' home is cartan.limits
    DEFAULT_MAX_STEPS,
    MEMORY_ENV,
    STEPS_ENV,
    check_memory,
    format_bytes,
    memory_limit,
    state_bytes,
    step_limit,
)
from .plugins import get_registry
from .problem import Clamped, Damping, Driven, Free, Held, NodeForce, Problem, Symmetry, UniformForce

__all__ = [
    "MAX_ITERATIONS",
    "MAX_LOAD_STEPS",
    "MAX_NESTING",
    "MAX_PATH_POINTS",
    "MAX_SCENE_BYTES",
    "MODES",
    "Measure",
    "Scene",
    "SceneError",
    "check_memory",
    "format_bytes",
    "load_scene",
    "memory_limit",
    "read_scene_file",
    "scene",
    "state_bytes",
    "step_limit",
]

MODES = ("dynamic", "static", "continuation", "flow")
_TOP_KEYS = {
    "name", "description", "mode", "medium", "parameters", "grid", "boundaries", "loads", "initial", "run",
    "static", "continuation", "flow",
}
_GRID_KEYS = {"n", "shape", "length", "periodic", "glued"}
_RUN_KEYS = {
    "integrator",
    "scheme",
    "dt",
    "t_end",
    "save_every",
    "checkpoint_every",
    "integrator_options",
    "scheme_options",
}
_STATIC_KEYS = {"tol", "xtol", "max_iterations", "load_steps", "fd_step", "reuse", "initial_guess", "measure",
                "pins"}
_CONTINUATION_KEYS = {
    "parameter",
    "lambda_max",
    "lambda_scale",
    "stops",
    "ds",
    "ds_min",
    "ds_max",
    "max_steps",
    "tol",
    "max_iterations",
    "measure",
    "pins",
    "detect",
    "branch_switch",
    "switch_direction",
    "locate_tol",
    "fd_step",
}
#: continuation's first arclength step when ``[continuation]`` gives no ``ds``
DEFAULT_DS = 0.05
_AXIS_LABELS = ("x", "y", "z")


class SceneError(ValueError):
    """A scene file or dict is malformed or names something that does not exist.

    The message is a single line ``"<source>: <key>: <what is wrong>"``.
    """


# ---------------------------------------------------------------------------- limits
#: largest scene file read, in bytes (1 MiB)
MAX_SCENE_BYTES = 1 << 20
#: deepest nesting of tables and arrays in a scene
MAX_NESTING = 32
#: largest ``[static] load_steps``
MAX_LOAD_STEPS = 10_000
#: largest ``max_iterations`` of ``[static]`` and ``[continuation]``
MAX_ITERATIONS = 10_000
#: largest ``[continuation] max_steps``
MAX_PATH_POINTS = 100_000
@dataclass(frozen=True)
class Measure:
    """A displacement recorded by static and continuation runs (``measure = {node, component}``).

    The value is one spatial component — or the length — of ``position − initial position``
    at one node, for media on affine groups.

    Attributes
    ----------
    node : int
        Flat node index (C order over the grid's axes).
    node_label : str
        The node as the scene gives it (``"end"``, ``"middle"``, ``"50"``, ``"[3, 4]"``).
    component : int or None
        Spatial axis (0 = x, 1 = y, 2 = z); None for the length of the displacement.
    component_label : str
        ``"x"``, ``"y"``, ``"z"`` or ``"magnitude"``.
    """

    node: int
    node_label: str
    component: int | None
    component_label: str

    def __call__(self, position: Any, initial: Any) -> float:
        """The displacement from flat node positions ``position`` and ``initial`` ``[nodes, k]``."""
        import numpy as np

        d = np.asarray(position, dtype=float)[self.node] - np.asarray(initial, dtype=float)[self.node]
        return float(np.linalg.norm(d)) if self.component is None else float(d[self.component])

    def describe(self) -> str:
        """E.g. ``"displacement z of node end"``."""
        what = "displacement magnitude" if self.component is None else f"displacement {self.component_label}"
        return f"{what} of node {self.node_label}"


@dataclass
class Scene:
    """A runnable problem with its run settings (the ``[run]``, ``[static]`` or ``[continuation]`` table).

    Attributes
    ----------
    problem : Problem
        Medium, grid, boundaries, loads and initial state.
    name, description : str
    mode : str
        ``"dynamic"`` (:func:`cartan.simulate`), ``"static"`` (:func:`cartan.statics.solve_static`)
        or ``"continuation"`` (:func:`cartan.continuation.continuation`).
    integrator, scheme : str or None
        Registered names (None: the :func:`cartan.simulate` defaults).
    dt, t_end : float or None
    save_every, checkpoint_every : int or None
    integrator_options, scheme_options : dict
        Keyword arguments of the integrator and scheme constructors.
    solver_options : dict
        Static and continuation modes: the keyword arguments of ``solve_static`` or
        ``continuation`` read from ``[static]`` / ``[continuation]`` (validated).
    measure : Measure or None
        The displacement reported by a static run and recorded along a continuation path.
    initial_guess : pathlib.Path or None
        Static mode: a run file whose last frame starts Newton's method.
    parameter : str
        Continuation mode: the load λ scales (a loaded end, or ``"all"``).
    flow : str or None
        Flow mode: the registered flow (registry ``"flows"``) the ``[flow]`` table names by
        ``kind``; its options are in ``solver_options``.
    source : dict
        The scene as parsed (TOML tables as dicts); recorded in the output and used to
        rebuild the problem on restart.
    path : pathlib.Path or None
        The file the scene was read from.
    """

    problem: Problem
    name: str = ""
    description: str = ""
    mode: str = "dynamic"
    integrator: str | None = None
    scheme: str | None = None
    dt: float | None = None
    t_end: float | None = None
    save_every: int | None = None
    checkpoint_every: int | None = None
    integrator_options: dict[str, Any] = field(default_factory=dict)
    scheme_options: dict[str, Any] = field(default_factory=dict)
    solver_options: dict[str, Any] = field(default_factory=dict)
    measure: Measure | None = None
    initial_guess: pathlib.Path | None = None
    parameter: str = "all"
    flow: str | None = None
    source: dict[str, Any] = field(default_factory=dict)
    path: pathlib.Path | None = None

    def run_settings(self) -> dict[str, Any]:
        """The ``[run]`` settings as keyword arguments of :func:`cartan.simulate` (unset ones omitted).

        Raises
        ------
        SceneError
            For static and continuation scenes, which :func:`cartan.simulate` does not run
            (use :meth:`run`).
        """
        if self.mode != "dynamic":
            raise SceneError(
                f"scene {self.name!r} has mode = {self.mode!r}: cartan.simulate runs dynamic scenes only; "
                "run it with Scene.run() or `cartan run`"
            )
        out = {
            "integrator": self.integrator,
            "scheme": self.scheme,
            "dt": self.dt,
            "t_end": self.t_end,
            "save_every": self.save_every,
            "checkpoint_every": self.checkpoint_every,
        }
        out = {k: v for k, v in out.items() if v is not None}
        if self.integrator_options:
            out["integrator_options"] = dict(self.integrator_options)
        if self.scheme_options:
            out["scheme_options"] = dict(self.scheme_options)
        return out

    def simulate(self, **kwargs: Any):
        """``cartan.simulate(self, **kwargs)``: run the scene (keywords override ``[run]``).

        Runs go through the run-level API (:mod:`cartan.api`): this module reads scenes and
        knows nothing of :mod:`cartan.simulate`, which knows nothing of it.
        """
        from .api import simulate

        return simulate(self, **kwargs)

    def run(self, output: str | pathlib.Path | None = None, *, command: str | None = None, **options: Any):
        """Run the scene by its mode and optionally write the result.

        Parameters
        ----------
        output : path, optional
            netCDF file written atomically (:func:`cartan.io.write_dataset`) after a
            successful run; nothing is written when the run fails.
        command : str, optional
            Text recorded in the ``history`` attribute (default: a description of this call).
        **options
            Dynamic mode only: keywords of :func:`cartan.simulate` (overriding ``[run]``).

        Returns
        -------
        xarray.Dataset
            Dynamic: the run (``time`` frames).  Static: the one-frame equilibrium of
            ``solve_static`` plus ``initial_position`` (affine groups).  Continuation: the path of
            ``continuation`` (``load_factor``, ``monitor`` — the measured displacement —,
            ``position`` along ``path``, critical points along ``critical``) plus
            ``initial_position``.  Flow: the registered flow's Dataset (the final fields, the
            history along ``step`` with the coordinate ``flow_time``); all with the CF attributes
            of a dynamic run (``Conventions``, ``title``, ``source``, ``history``,
            ``cartan_config`` holding the scene).

        Raises
        ------
        ValueError
            Run options given to a static or continuation scene; an ``output`` that cannot be
        written (a missing folder, not a regular file: :func:`cartan.io.check_output`).
        cartan.statics.ConvergenceError
            Newton's method or the path following failed.
        """
        if self.mode == "dynamic":
            from .api import simulate  # the run-level API, as in simulate()

            return simulate(self, output=output, command=command, **options)
        if options:
            raise ValueError(
                f"scene {self.name!r} has mode = {self.mode!r}: run options {', '.join(sorted(options))} apply to "
                f"dynamic scenes only; change the [{self.mode}] table instead"
            )
        from . import io

        if output is not None:
            io.check_output(output)  # before the work, not after it
        if self.mode == "static":
            ds = _solve_static(self, command)
        elif self.mode == "flow":
            ds = _run_flow(self, command)
        else:
            ds = _follow_path(self, command)
        if output is not None:
            io.write_dataset(ds, output)
        return ds

    def __repr__(self) -> str:
        where = f", path={str(self.path)!r}" if self.path else ""
        mode = f", mode={self.mode!r}" if self.mode != "dynamic" else ""
        return f"Scene(name={self.name!r}, medium={self.problem.medium.name!r}{mode}{where})"


# ---------------------------------------------------------------------------- helpers
def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


class _Reader:
    """Validating accessors that raise :class:`SceneError` naming the source and the key."""

    def __init__(self, label: str):
        self.label = label

    def fail(self, key: str, message: str) -> SceneError:
        parts = [p for p in (self.label, key) if p]
        return SceneError(": ".join([*parts, message]))

    def table(self, data: Mapping, key: str, where: str, required: bool = False) -> dict:
        if key not in data:
            if required:
                raise self.fail(_join(where, key), "missing table")
            return {}
        value = data[key]
        if not isinstance(value, Mapping):
            raise self.fail(_join(where, key), f"must be a table, got {type(value).__name__}")
        return dict(value)

    def string(self, data: Mapping, key: str, where: str, required: bool = True, default: str = "") -> str:
        if key not in data:
            if required:
                raise self.fail(_join(where, key), "missing key")
            return default
        value = data[key]
        if not isinstance(value, str) or (required and not value):
            raise self.fail(_join(where, key), f"must be a non-empty string, got {value!r}")
        return value

    def number(self, data: Mapping, key: str, where: str, *, positive: bool = True) -> float | None:
        if key not in data:
            return None
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
            raise self.fail(_join(where, key), f"must be a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(_join(where, key), f"must be > 0, got {value!r}")
        return float(value)

    def integer(
        self, data: Mapping, key: str, where: str, minimum: int = 1, maximum: int | None = None
    ) -> int | None:
        if key not in data:
            return None
        value = data[key]
        if (
            isinstance(value, bool)
            or not isinstance(value, numbers.Integral)
            or value < minimum
            or (maximum is not None and value > maximum)
        ):
            allowed = f"in {minimum}..{maximum}" if maximum is not None else f"≥ {minimum}"
            raise self.fail(_join(where, key), f"must be an integer {allowed}, got {value!r}")
        return int(value)

    def no_extra(self, data: Mapping, allowed: set[str], where: str) -> None:
        for key in data:
            if key not in allowed:
                raise self.fail(_join(where, key), f"unknown key; allowed: {', '.join(sorted(allowed))}")


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


#: top-level keys whose strings are free text (not checked for spelled-out numbers)
_FREE_TEXT = ("name", "description")
_BOOLEAN_WORDS = ("true", "false", "yes", "no", "on", "off")


def _spelled(text: str) -> str | None:
    """What a string spells when it reads as a number or a boolean (``"1e5"``, ``"false"``)."""
    word = text.strip().lower()
    if word in _BOOLEAN_WORDS:
        return "true or false"
    try:
        float(word)
    except ValueError:
        return None
    return "a number"


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _check_values(reader: _Reader, value: Any, key: str = "", depth: int = 0) -> None:
    """The value rules of every scene table (see the module docstring): bounded nesting,
    finite numbers, 64-bit integers, no booleans among numbers, no numbers or booleans
    spelled as strings."""
    if depth > MAX_NESTING:
        raise reader.fail(key, f"tables and arrays nested deeper than {MAX_NESTING} levels")
    if isinstance(value, Mapping):
        for k, v in value.items():
            if not (depth == 0 and k in _FREE_TEXT):
                _check_values(reader, v, _join(key, str(k)), depth + 1)
    elif isinstance(value, list | tuple):
        numeric = any(_is_number(v) for v in value)
        for i, v in enumerate(value):
            if numeric and isinstance(v, bool):
                raise reader.fail(f"{key}[{i}]", f"must be a number, got {v!r} (a boolean is not a number)")
            _check_values(reader, v, f"{key}[{i}]", depth + 1)
    elif isinstance(value, bool):
        return
    elif isinstance(value, numbers.Integral):
        if not -(2**63) <= value < 2**63:
            raise reader.fail(key, f"integer out of range (64 bits), got {value!r}")
    elif isinstance(value, numbers.Real):
        if not math.isfinite(value):
            raise reader.fail(key, f"must be a finite number, got {value!r}")
    elif isinstance(value, str):
        what = _spelled(value)
        if what is not None:
            raise reader.fail(key, f"must be {what}, not the string {value!r} (write it without quotes)")


def _declared_flags(target: Any) -> set[str] | None:
    """The keywords of ``target`` declared as booleans (a bool default or a ``bool``
    annotation); None when its signature cannot be read."""
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):
        return None
    return {
        p.name
        for p in sig.parameters.values()
        if isinstance(p.default, bool) or p.annotation in (bool, "bool", "bool | None")
    }


def _check_flags(reader: _Reader, target: Any, params: Mapping, key: str) -> None:
    """Booleans only for the keywords ``target`` declares as booleans: a boolean is not a number."""
    flags = _declared_flags(target)
    if flags is None:
        return
    for name, value in params.items():
        if name in flags:
            continue
        if isinstance(value, bool) or (isinstance(value, list) and any(isinstance(v, bool) for v in value)):
            raise reader.fail(
                _join(key, name), f"must be a number, got {value!r} (a boolean is not a number; "
                                  f"true/false are for the switches{' ' + ', '.join(sorted(flags)) if flags else ''})"
            )


def _numbers_in(value: Any) -> list[float]:
    if _is_number(value):
        return [float(value)] if math.isfinite(float(value)) else []
    if isinstance(value, list | tuple):
        return [x for v in value for x in _numbers_in(v)]
    return []


def _out_of_range(values: Mapping, exc: BaseException) -> str:
    """The message of an overflow while building from ``values``: the entry of the most extreme
    magnitude is named (the likely cause)."""
    reason = exc.args[-1] if exc.args and isinstance(exc.args[-1], str) else _one_line(exc)
    best: tuple[float, str, float] | None = None
    for name, value in values.items():
        for x in _numbers_in(value):
            size = abs(math.log10(abs(x))) if x else 0.0
            if best is None or size > best[0]:
                best = (size, str(name), x)
    if best is None:
        return f"a value is out of range: a quantity computed from it is not finite ({reason})"
    return f"{best[1]} = {best[2]:g} is out of range: a quantity computed from it is not finite"


def _building(reader: _Reader, key: str, values: Mapping, build: Any, *args: Any, **kwargs: Any) -> Any:
    """``build(*args, **kwargs)``; a ValueError or TypeError becomes a SceneError naming ``key``, a
    floating-point overflow or invalid operation one that names the most extreme of ``values``."""
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            return build(*args, **kwargs)
    except SceneError:
        raise
    except (ValueError, TypeError) as exc:
        raise reader.fail(key, _one_line(exc)) from None
    except ArithmeticError as exc:
        raise reader.fail(key, _out_of_range(values, exc)) from None


_SINGULAR = {"media": "medium", "integrators": "integrator", "schemes": "scheme", "scenes": "scene",
             "flows": "flow"}


def _lookup(reader: _Reader, kind: str, name: str, key: str) -> Any:
    table = get_registry().table(kind)
    if name not in table:
        known = ", ".join(sorted(table)) or "none"
        raise reader.fail(key, f"unknown {_SINGULAR.get(kind, kind)} {name!r}; registered {kind}: {known}")
    return table[name].obj


def _check_keywords(reader: _Reader, target: Any, params: Mapping, key: str, what: str) -> None:
    """Reject keywords that ``target``'s signature does not accept (unless it takes **kwargs)."""
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):  # builtins without signature: let the call decide
        return
    accepted = []
    for p in sig.parameters.values():
        if p.kind is inspect.Parameter.VAR_KEYWORD:
            return
        if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY):
            accepted.append(p.name)
    for name in params:
        if name not in accepted:
            raise reader.fail(
                _join(key, name), f"unknown parameter of {what}; accepted: {', '.join(accepted) or 'none'}"
            )


# ---------------------------------------------------------------------------- the parts
def _grid(reader: _Reader, data: Mapping, medium: Any) -> Grid:
    g = reader.table(data, "grid", "", required=True)
    reader.no_extra(g, _GRID_KEYS, "grid")
    if "n" in g and "shape" in g:
        raise reader.fail("grid", "give either n or shape, not both")
    if "n" in g:
        shape: Any = reader.integer(g, "n", "grid", minimum=2)
    elif "shape" in g:
        shape = g["shape"]
        if not isinstance(shape, list) or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in shape
        ):
            raise reader.fail("grid.shape", f"must be a list of integers, got {shape!r}")
    else:
        raise reader.fail("grid.n", "missing key (number of nodes; or shape = [...] for d ≥ 2)")
    length = g.get("length", 1.0)
    if not (_is_number(length) or (isinstance(length, list) and length and all(map(_is_number, length)))):
        raise reader.fail("grid.length", f"must be a number > 0 or a list of them (one per axis), got {length!r}")
    periodic = g.get("periodic", False)
    if not (
        isinstance(periodic, bool)
        or (isinstance(periodic, list) and periodic and all(isinstance(p, bool) for p in periodic))
    ):
        raise reader.fail(
            "grid.periodic", f"must be true or false (or a list of them, one per axis), got {periodic!r}"
        )
    glued = g.get("glued")  # per axis: the periodic axis its ends are glued across, or -1 (Grid's glued)
    if glued is not None and not (isinstance(glued, list) and all(isinstance(b, int) and not isinstance(b, bool)
                                                                  for b in glued)):
        raise reader.fail("grid.glued", f"must be a list of integers, one per axis (-1: not glued), got {glued!r}")
    grid = _building(reader, "grid", g, Grid, shape, length=length, periodic=periodic, glued=glued)
    nodes = math.prod(grid.shape)
    try:
        check_memory(f"a grid of {nodes} nodes", state_bytes(medium.group, nodes, grid.d), "use fewer nodes")
    except ValueError as exc:
        raise reader.fail("grid", str(exc)) from None
    return grid


#: boundary kinds built from one field of their table: (class, the field, other keys allowed)
_ONE_FIELD_ENDS = {
    "driven": (Driven, "velocity", ()),
    "held": (Held, "components", ("load", "follower")),  # the load: _held_loads
    "symmetry": (Symmetry, "normal", ()),
}


def _boundaries(reader: _Reader, data: Mapping) -> dict:
    b = reader.table(data, "boundaries", "")
    out = {}
    for end, spec in b.items():
        key = f"boundaries.{end}"
        if not isinstance(spec, Mapping):
            raise reader.fail(key, f'must be a table such as {{ kind = "clamped" }}, got {spec!r}')
        kind = reader.string(spec, "kind", key)
        if kind == "clamped":
            reader.no_extra(spec, {"kind"}, key)
            out[end] = Clamped()
        elif kind == "free":
            reader.no_extra(spec, {"kind", "load", "follower"}, key)
            follower = spec.get("follower", False)
            if not isinstance(follower, bool):
                raise reader.fail(f"{key}.follower", f"must be true or false, got {follower!r}")
            out[end] = Free(load=spec.get("load"), follower=follower)
        elif kind in _ONE_FIELD_ENDS:
            cls, name, extra = _ONE_FIELD_ENDS[kind]
            reader.no_extra(spec, {"kind", name, *extra}, key)
            try:
                out[end] = cls(**{name: spec.get(name)})
            except ValueError as exc:
                raise reader.fail(f"{key}.{name}", str(exc)) from None
        else:
            raise reader.fail(f"{key}.kind", f"unknown boundary kind {kind!r}; choose 'clamped', 'driven', 'free', "
                              "'held' or 'symmetry'")
    return out


def _held_loads(reader: _Reader, data: Mapping, medium, grid: Grid) -> list:
    """The loads of ``held`` ends (``load``, ``follower``): a :class:`~cartan.problem.NodeForce`
    on the end node per loaded end, with the meaning of a free end's ``load`` (P ∈ 𝔤*, r = the
    group's dimension components, a dead load fixed in the spatial frame, or with
    ``follower = true`` in the body frame).  The held components of P are the support's reaction
    and change nothing; the free ones load the end.  d = 1 only (the end is one node).  Each
    load carries ``held_end`` (the end's name), for :func:`_external_loads`."""
    out = []
    b = data.get("boundaries", {})
    for end, spec in (b.items() if isinstance(b, Mapping) else ()):
        if not isinstance(spec, Mapping) or spec.get("kind") != "held":
            continue
        key = f"boundaries.{end}"
        follower = spec.get("follower", False)
        if not isinstance(follower, bool):
            raise reader.fail(f"{key}.follower", f"must be true or false, got {follower!r}")
        if "load" not in spec:
            continue
        load, r = spec["load"], medium.group.dim
        if not (isinstance(load, list) and len(load) == r and all(_is_number(v) and math.isfinite(v) for v in load)):
            raise reader.fail(f"{key}.load", f"must be a list of {r} finite numbers (the load's components on "
                                             f"{medium.group.name}, as a free end's load), got {load!r}")
        if grid.d != 1:
            raise reader.fail(f"{key}.load", "a load on a held end is read on d = 1 grids (one end node); on a "
                                             "face of a d ≥ 2 grid give [[loads]] node-force tables on its nodes")
        if end not in ("start", "end"):
            continue  # not an end of this grid: the problem names it
        force = NodeForce(grid, [float(v) for v in load], node=0 if end == "start" else -1,
                          frame="body" if follower else "spatial")
        force.bind(medium)
        force.held_end = end
        out.append(force)
    return out


def _loads(reader: _Reader, data: Mapping, medium, grid: Grid | None = None) -> list:
    loads = data.get("loads", [])
    if isinstance(loads, Mapping):
        loads = [loads]
    if not isinstance(loads, list):
        raise reader.fail("loads", "must be an array of tables ([[loads]])")
    out = []
    for i, spec in enumerate(loads):
        key = f"loads[{i}]"
        if not isinstance(spec, Mapping):
            raise reader.fail(key, f"must be a table, got {spec!r}")
        kind = reader.string(spec, "kind", key)
        rest = {k: v for k, v in spec.items() if k != "kind"}
        try:
            if kind == "damping":
                reader.no_extra(rest, {"coefficients"}, key)
                if "coefficients" not in rest:
                    raise reader.fail(f"{key}.coefficients", "missing key")
                load = Damping(rest["coefficients"])
            elif kind == "uniform-force":
                reader.no_extra(rest, {"components", "frame"}, key)
                if "components" not in rest:
                    raise reader.fail(f"{key}.components", "missing key")
                load = UniformForce(rest["components"], frame=rest.get("frame", "body"))
            elif kind == "node-force":
                reader.no_extra(rest, {"force", "at", "node", "frame"}, key)
                if "force" not in rest:
                    raise reader.fail(f"{key}.force", "missing key")
                if grid is None:
                    raise reader.fail(key, "a node force needs the scene's grid")
                load = NodeForce(grid, **rest)
            else:
                available = ["damping", "uniform-force", "node-force", *getattr(medium, "load_kinds", ())]
                if getattr(medium, "load_kinds", ()) and kind not in available:
                    raise reader.fail(
                        f"{key}.kind", f"unknown load kind {kind!r}; available: {', '.join(available)}"
                    )
                with np.errstate(over="raise", invalid="raise", divide="raise"):
                    load = medium.make_load(kind, **rest)
            with np.errstate(over="raise", invalid="raise", divide="raise"):
                load.bind(medium)
        except SceneError:
            raise
        except (ValueError, TypeError) as exc:
            raise reader.fail(f"{key} ({kind})", _one_line(exc)) from None
        except ArithmeticError as exc:
            raise reader.fail(f"{key} ({kind})", _out_of_range(rest, exc)) from None
        out.append(load)
    return out


def _initial(reader: _Reader, data: Mapping, medium, grid: Grid):
    spec = reader.table(data, "initial", "", required=True)
    kind = reader.string(spec, "kind", "initial")
    rest = {k: v for k, v in spec.items() if k != "kind"}
    kinds = getattr(medium, "initial_kinds", ())
    if kinds and kind not in kinds:
        raise reader.fail(
            "initial.kind", f"unknown initial state kind {kind!r}; available: {', '.join(kinds)}"
        )
    return _building(reader, f"initial ({kind})", rest, medium.initial_state, grid, kind, **rest)


def _run(reader: _Reader, data: Mapping, problem: Problem) -> dict[str, Any]:
    run = reader.table(data, "run", "")
    reader.no_extra(run, _RUN_KEYS, "run")
    out: dict[str, Any] = {
        "dt": reader.number(run, "dt", "run"),
        "t_end": reader.number(run, "t_end", "run"),
        "save_every": reader.integer(run, "save_every", "run"),
        "checkpoint_every": reader.integer(run, "checkpoint_every", "run"),
        "integrator": reader.string(run, "integrator", "run", required=False, default="") or None,
        "scheme": reader.string(run, "scheme", "run", required=False, default="") or None,
        "integrator_options": reader.table(run, "integrator_options", "run"),
        "scheme_options": reader.table(run, "scheme_options", "run"),
    }
    # validate names and options now, so that a bad scene fails before anything runs
    integ_name = out["integrator"] or "lie-verlet"
    cls = _lookup(reader, "integrators", integ_name, "run.integrator")
    _check_flags(reader, cls, out["integrator_options"], "run.integrator_options")
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            cls(**out["integrator_options"])
    except (ValueError, TypeError) as exc:
        raise reader.fail("run.integrator_options", f"{integ_name}: {_one_line(exc)}") from None
    except ArithmeticError as exc:
        raise reader.fail("run.integrator_options", _out_of_range(out["integrator_options"], exc)) from None
    scheme_name = out["scheme"] or "lattice"
    cls = _lookup(reader, "schemes", scheme_name, "run.scheme")
    _check_flags(reader, cls, out["scheme_options"], "run.scheme_options")
    key = "run.scheme_options" if out["scheme_options"] else "run.scheme"
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            cls(problem, **out["scheme_options"])
    except (ValueError, TypeError) as exc:
        raise reader.fail(key, f"{scheme_name}: {_one_line(exc)}") from None
    except ArithmeticError as exc:
        raise reader.fail(key, _out_of_range(out["scheme_options"], exc)) from None
    return out


def _problem_error_key(message: str) -> str:
    for prefix in ("initial", "boundaries", "loads", "grid"):
        if message.startswith(prefix):
            return prefix
    return "problem"


# ---------------------------------------------------------------------------- static and continuation
def _mode(reader: _Reader, data: Mapping) -> str:
    mode = data.get("mode", "flow" if "flow" in data else "dynamic")  # a [flow] table implies mode = "flow"
    if mode not in MODES:
        raise reader.fail("mode", f"unknown mode {mode!r}; allowed: {', '.join(repr(m) for m in MODES)}")
    for table in ("run", "static", "continuation", "flow"):
        wanted = "dynamic" if table == "run" else table
        if table in data and mode != wanted:
            raise reader.fail(
                table, f"a [{table}] table belongs to mode = {wanted!r} scenes, but this scene has mode = {mode!r}"
            )
    return mode


def _boolean(reader: _Reader, data: Mapping, key: str, where: str) -> bool | None:
    if key not in data:
        return None
    value = data[key]
    if not isinstance(value, bool):
        raise reader.fail(_join(where, key), f"must be true or false, got {value!r}")
    return value


def _affine_problem(reader: _Reader, problem: Problem, key: str) -> int:
    """The spatial dimension k of an affine group (positions), or a SceneError naming ``key``."""
    g = problem.medium.group
    if not getattr(g, "affine", False):
        raise reader.fail(
            key, f"needs a medium on an affine group (positions); medium {problem.medium.name!r} is on {g.name}"
        )
    return int(g.matrix_size) - 1


def _component(reader: _Reader, value: Any, k: int, key: str, magnitude: bool) -> int | None:
    """A spatial axis named ``"x"``/``"y"``/``"z"`` or by index; None for ``"magnitude"``."""
    names = list(_AXIS_LABELS[:k]) if k <= 3 else [f"x{i}" for i in range(k)]
    allowed = [*names, *(["magnitude"] if magnitude else [])]
    if magnitude and value == "magnitude":
        return None
    if isinstance(value, str) and value in names:
        return names.index(value)
    if isinstance(value, numbers.Integral) and not isinstance(value, bool) and 0 <= value < k:
        return int(value)
    raise reader.fail(
        key, f"unknown component {value!r}; allowed: {', '.join(repr(a) for a in allowed)} or an index 0..{k - 1}"
    )


def _measure(reader: _Reader, spec: Any, problem: Problem, key: str) -> Measure:
    import numpy as np

    if not isinstance(spec, Mapping):
        raise reader.fail(key, f'must be a table such as {{ node = "end", component = "z" }}, got {spec!r}')
    reader.no_extra(spec, {"node", "component"}, key)
    k = _affine_problem(reader, problem, key)
    shape = problem.grid.shape
    for part in ("node", "component"):
        if part not in spec:
            raise reader.fail(f"{key}.{part}", "missing key")
    node = spec["node"]
    ends = {"start": 0, "middle": shape[0] // 2, "end": shape[0] - 1}
    if isinstance(node, str):
        if len(shape) != 1 or node not in ends:
            allowed = "'start', 'middle', 'end' or an index" if len(shape) == 1 else f"a list of {len(shape)} indices"
            raise reader.fail(f"{key}.node", f"unknown node {node!r}; allowed: {allowed}")
        flat, label = ends[node], node
    else:
        idx = [node] if len(shape) == 1 and not isinstance(node, list) else node
        ok = (
            isinstance(idx, list)
            and len(idx) == len(shape)
            and all(isinstance(i, numbers.Integral) and not isinstance(i, bool) and -n <= i < n
                    for i, n in zip(idx, shape, strict=True))
        )
        if not ok:
            ranges = ", ".join(f"{-n}..{n - 1}" for n in shape)
            what = "'start', 'middle', 'end' or an index in" if len(shape) == 1 else "a list of indices in"
            raise reader.fail(f"{key}.node", f"must be {what} {ranges}, got {node!r}")
        flat = int(np.ravel_multi_index(tuple(int(i) % n for i, n in zip(idx, shape, strict=True)), shape))
        label = str(node)
    comp = _component(reader, spec["component"], k, f"{key}.component", magnitude=True)
    return Measure(node=flat, node_label=label, component=comp,
                   component_label="magnitude" if comp is None else str(spec["component"]))


def _static(reader: _Reader, data: Mapping, problem: Problem, path: pathlib.Path | None) -> dict[str, Any]:
    st = reader.table(data, "static", "")
    reader.no_extra(st, _STATIC_KEYS, "static")
    options = {
        "tol": reader.number(st, "tol", "static"),
        "xtol": reader.number(st, "xtol", "static"),
        "max_iter": reader.integer(st, "max_iterations", "static", maximum=MAX_ITERATIONS),
        "load_steps": reader.integer(st, "load_steps", "static", maximum=MAX_LOAD_STEPS),
        "fd_step": reader.number(st, "fd_step", "static"),
        "reuse": reader.number(st, "reuse", "static", positive=False),
    }
    if options["reuse"] is not None and not 0.0 <= options["reuse"] < 1.0:
        raise reader.fail("static.reuse", f"must be in [0, 1), got {options['reuse']!r}")
    out: dict[str, Any] = {"solver_options": {k: v for k, v in options.items() if v is not None}}
    if "measure" in st:
        out["measure"] = _measure(reader, st["measure"], problem, "static.measure")
    if "pins" in st:
        out["solver_options"]["pins"] = _pins(reader, st["pins"], problem, "static.pins")
    if "initial_guess" in st:
        out["initial_guess"] = _initial_guess(reader, st, problem, path)
    return out


def _initial_guess(reader: _Reader, st: Mapping, problem: Problem, path: pathlib.Path | None) -> pathlib.Path:
    """``[static] initial_guess``: a run file (relative to the scene file) with the grid's nodes."""
    key = "static.initial_guess"
    value = reader.string(st, "initial_guess", "static")
    guess = pathlib.Path(value)
    if not guess.is_absolute() and path is not None:
        guess = path.parent / guess
    _affine_problem(reader, problem, key)
    if not guess.is_file():
        raise reader.fail(key, f"no such file {str(guess)!r} (a run file whose last frame starts Newton's method)")
    from .io import open_dataset

    try:
        ds = open_dataset(guess)
    except (OSError, ValueError) as exc:
        raise reader.fail(key, f"{guess}: not a readable netCDF file ({_one_line(exc)})") from None
    if "position" not in ds or "frame" not in ds or "time" not in ds["position"].dims:
        raise reader.fail(key, f"{guess}: not a run file with position and frame along time")
    nodes = int(ds["position"].isel(time=-1).size // ds.sizes.get("row", 1))
    if nodes != problem.grid.size or ds.sizes.get("row") != problem.medium.group.matrix_size - 1:
        raise reader.fail(key, f"{guess}: holds {nodes} nodes in {ds.sizes.get('row')} dimensions, the scene "
                               f"{problem.grid.size} in {problem.medium.group.matrix_size - 1}")
    return guess


def _external_loads(problem: Problem) -> list[str]:
    """The external loads λ would scale: non-zero end loads and body loads (velocity-dependent
    loads such as damping vanish at rest and are left out)."""
    import numpy as np

    names = [f"boundaries.{end}" for end, b in problem.boundaries.items()
             if isinstance(b, Free) and b.load is not None and np.any(np.asarray(b.load) != 0)]
    # a held end's load (_held_loads) is named by its end, after the [[loads]] tables
    names += [f"boundaries.{load.held_end}" for load in problem.loads
              if getattr(load, "held_end", None) is not None and np.any(load.force_components != 0)]
    names += [f"loads[{i}]" for i, load in enumerate(problem.loads)
              if not (isinstance(load, Damping) or getattr(load, "velocity_dependent", False)
                      or getattr(load, "held_end", None) is not None)]
    return names


def _continuation(reader: _Reader, data: Mapping, problem: Problem) -> dict[str, Any]:
    w = "continuation"
    ct = reader.table(data, w, "", required=True)
    reader.no_extra(ct, _CONTINUATION_KEYS, w)
    if "lambda_max" not in ct:
        raise reader.fail(f"{w}.lambda_max", "missing key (the load factor at which the path ends)")
    lam_max = reader.number(ct, "lambda_max", w)
    ds0 = reader.number(ct, "ds", w) or DEFAULT_DS
    ds_min = reader.number(ct, "ds_min", w)
    ds_max = reader.number(ct, "ds_max", w)
    if ds_min is not None and ds_min > ds0:
        raise reader.fail(f"{w}.ds_min", f"must be ≤ ds = {ds0:g}, got {ds_min:g}")
    if ds_max is not None and ds_max < ds0:
        raise reader.fail(f"{w}.ds_max", f"must be ≥ ds = {ds0:g}, got {ds_max:g}")
    options: dict[str, Any] = {
        "lam_max": lam_max,
        "ds0": ds0,
        "ds_min": ds_min,
        "ds_max": ds_max,
        "lam_scale": reader.number(ct, "lambda_scale", w),
        "max_points": reader.integer(ct, "max_steps", w, minimum=2, maximum=MAX_PATH_POINTS),
        "tol": reader.number(ct, "tol", w),
        "max_iter": reader.integer(ct, "max_iterations", w, maximum=MAX_ITERATIONS),
        "locate_tol": reader.number(ct, "locate_tol", w),
        "fd_step": reader.number(ct, "fd_step", w),
        "detect": _boolean(reader, ct, "detect", w),
        "branch_switch": _boolean(reader, ct, "branch_switch", w),
    }
    if "switch_direction" in ct:
        sd = ct["switch_direction"]
        if isinstance(sd, bool) or sd not in (1, -1):
            raise reader.fail(f"{w}.switch_direction", f"must be 1 or -1, got {sd!r}")
        options["switch_direction"] = float(sd)
    if "stops" in ct:
        stops = ct["stops"]
        if not isinstance(stops, list) or not all(
            isinstance(x, numbers.Real) and not isinstance(x, bool) and 0 < x < lam_max for x in stops
        ):
            raise reader.fail(f"{w}.stops", f"must be a list of load factors in (0, lambda_max = {lam_max:g}), "
                                            f"got {stops!r}")
        options["stops"] = [float(x) for x in stops]
    if "pins" in ct:
        options["pins"] = _pins(reader, ct["pins"], problem)
    out: dict[str, Any] = {"solver_options": {k: v for k, v in options.items() if v is not None}}
    if "measure" in ct:
        out["measure"] = _measure(reader, ct["measure"], problem, f"{w}.measure")
    external = _external_loads(problem)
    if not external:
        raise reader.fail(w, "the scene has no external load for λ to scale (give an end load or a body load)")
    parameter = ct.get("parameter", "all")
    loaded_ends = [e.split(".", 1)[1] for e in external if e.startswith("boundaries.")]
    allowed = ["all", *loaded_ends]
    if not isinstance(parameter, str) or parameter not in allowed:
        raise reader.fail(f"{w}.parameter", f"unknown load {parameter!r}; allowed: "
                                            f"{', '.join(repr(a) for a in allowed)} (a loaded end or every load)")
    if parameter != "all" and len(external) > 1:
        others = ", ".join(e for e in external if e != f"boundaries.{parameter}")
        raise reader.fail(f"{w}.parameter", f"λ scales every external load together, but the scene also has "
                                            f"{others}; give parameter = \"all\" or remove them")
    out["parameter"] = parameter
    return out


def _pins(reader: _Reader, spec: Any, problem: Problem,
          key: str = "continuation.pins") -> dict[str, tuple[int, ...]] | str:
    if spec == "rigid":  # the rigid-body gauge of a body without clamps (cartan.statics.rigid_gauge_pins)
        try:
            from .statics import rigid_gauge_pins

            rigid_gauge_pins(problem, spec)
        except ValueError as err:
            raise reader.fail(key, str(err)) from None
        return spec
    if not isinstance(spec, Mapping):
        example = '{ start = ["x", "y"], end = ["y"] }' if problem.grid.d == 1 else \
            '{ "start,start" = ["x", "y", "z"], "end,middle" = ["z"] }'
        raise reader.fail(key, f"must be a table such as {example} or \"rigid\", got {spec!r}")
    k = _affine_problem(reader, problem, key)
    if problem.grid.d > 1:
        return _lattice_pins(reader, spec, problem, k, key)
    if problem.grid.periodic[0]:
        raise reader.fail(key, "pins hold the ends of an open rod (d = 1, not periodic)")
    out = {}
    for end, comps in spec.items():
        where = f"{key}.{end}"
        if end not in ("start", "end"):
            raise reader.fail(where, "unknown end; allowed: 'start', 'end'")
        if isinstance(problem.boundaries.get(end), Clamped):
            raise reader.fail(where, f"the {end} is clamped; pins hold free ends (give {{ kind = \"free\" }})")
        if not isinstance(comps, list) or not comps:
            raise reader.fail(where, f'must be a non-empty list of components such as ["x", "y"], got {comps!r}')
        idx = tuple(_component(reader, c, k, where, magnitude=False) for c in comps)
        if len(set(idx)) != len(idx):
            raise reader.fail(where, f"repeated component in {comps!r}")
        out[end] = idx
    return out



def _lattice_pins(reader: _Reader, spec: Mapping, problem: Problem, k: int, key: str) -> dict[str, tuple[int, ...]]:
    """``pins`` (of ``[continuation]`` or ``[static]``, named by ``key``) on a d ≥ 2 lattice:
    ``{ "A,B" = [components] }``, each node named per axis by ``start``, ``middle``, ``end`` or
    an index (:func:`cartan.statics.pin_node`); a node on a clamped face, a node named twice or a
    repeated component is refused."""
    from .statics import pin_node

    grid = problem.grid
    names = tuple(grid.axis_names)
    out: dict[str, tuple[int, ...]] = {}
    seen: dict[int, str] = {}
    for node, comps in spec.items():
        where = f"{key}.{node}"
        try:
            flat = pin_node(str(node), tuple(grid.shape), names)
        except ValueError as exc:
            raise reader.fail(where, str(exc).removeprefix("pins: ")) from None
        if flat in seen:
            raise reader.fail(where, f"the node of {seen[flat]!r} again (one entry per node)")
        seen[flat] = str(node)
        index = [int(i) for i in np.unravel_index(flat, tuple(grid.shape))]
        for axis, (i, n, name) in enumerate(zip(index, grid.shape, names, strict=True)):
            for side, at in (("start", 0), ("end", n - 1)):
                face = f"{name}-{side}"
                if i == at and not grid.periodic[axis] and isinstance(problem.boundaries.get(face), Clamped):
                    raise reader.fail(where, f"the node {tuple(index)} is on the clamped face {face}; pins hold "
                                             "free nodes")
        if not isinstance(comps, list) or not comps:
            raise reader.fail(where, f'must be a non-empty list of components such as ["x", "y"], got {comps!r}')
        idx = tuple(_component(reader, c, k, where, magnitude=False) for c in comps)
        if len(set(idx)) != len(idx):
            raise reader.fail(where, f"repeated component in {comps!r}")
        out[str(node)] = idx
    return out

# ---------------------------------------------------------------------------- flows
#: largest ``[flow] steps``
MAX_FLOW_STEPS = 10_000


def _flow_option(reader: _Reader, value: Any, default: Any, key: str) -> Any:
    """One ``[flow]`` option, typed by the flow's default: a bool, an integer, a finite number,
    a string, a list of strings or a table of numbers (a default of None accepts any of these)."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise reader.fail(key, f"must be true or false, got {value!r}")
    elif isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise reader.fail(key, f"must be an integer, got {value!r}")
    elif isinstance(default, float):
        if not _is_number(value):
            raise reader.fail(key, f"must be a finite number, got {value!r}")
        value = float(value)
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise reader.fail(key, f"must be a string, got {value!r}")
    elif isinstance(default, (tuple, list)):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise reader.fail(key, f"must be a list of strings, got {value!r}")
        value = tuple(value)
    elif isinstance(value, Mapping):
        if not all(_is_number(v) for v in value.values()):
            raise reader.fail(key, f"must be a table of numbers, got {value!r}")
        value = {k: float(v) for k, v in value.items()}
    return value


def _flow(reader: _Reader, data: Mapping, problem: Problem) -> dict[str, Any]:
    """``[flow]``: ``kind`` names a registered flow (registry ``"flows"``), the other keys are its
    keyword options, checked against the flow's signature (names), its defaults (types) and its
    ``check(problem, options)`` (ranges) before anything runs."""
    w = "flow"
    ft = reader.table(data, w, "", required=True)
    kind = reader.string(ft, "kind", w)
    fn = _lookup(reader, "flows", kind, f"{w}.kind")
    options = {k: v for k, v in ft.items() if k != "kind"}
    for reserved in ("problem", "progress"):
        if reserved in options:
            raise reader.fail(f"{w}.{reserved}", "not a scene option (the scene gives the problem; "
                                                 "`cartan run` the progress)")
    _check_keywords(reader, fn, options, w, f"flow {kind!r}")
    try:
        defaults = {p.name: p.default for p in inspect.signature(fn).parameters.values()}
    except (TypeError, ValueError):
        defaults = {}
    options = {k: _flow_option(reader, v, defaults.get(k), f"{w}.{k}") for k, v in options.items()}
    if "steps" in options and not 1 <= options["steps"] <= MAX_FLOW_STEPS:
        raise reader.fail(f"{w}.steps", f"must be an integer in [1, {MAX_FLOW_STEPS}], got {options['steps']!r}")
    check = getattr(fn, "check", None)
    if check is not None:
        try:
            check(problem, dict(options))
        except ValueError as exc:
            raise reader.fail(w, _one_line(exc)) from None
    return {"flow": kind, "solver_options": options}


def _run_flow(sc: Scene, command: str | None) -> Any:
    """The scene's registered flow on its problem, as a run file: the flow's Dataset with
    ``flow_time`` a coordinate of its ``step`` dimension and the attributes of the other runs."""
    import json

    fn = get_registry().get("flows", sc.flow)
    ds = fn(sc.problem, **sc.solver_options)
    if "flow_time" in ds and "flow_time" not in ds.coords:
        ds = ds.set_coords("flow_time")
    try:
        config = json.loads(ds.attrs.get("cartan_config", "{}"))
    except ValueError:
        config = {}
    config.setdefault("run", {})
    config["run"]["flow"] = {"kind": sc.flow, **{k: (list(v) if isinstance(v, tuple) else v)
                                                 for k, v in sc.solver_options.items()}}
    from . import io

    ds.attrs.setdefault("Conventions", io.CONVENTIONS)
    ds.attrs["title"] = f"cartan {sc.flow} flow: {sc.name or sc.problem.medium.name}"
    ds.attrs.setdefault("source", "cartan")
    ds.attrs["flow"] = sc.flow
    ds.attrs.setdefault("references", _REFERENCES)
    _finish(ds, sc, config, command)
    return ds


# ---------------------------------------------------------------------------- running static modes
_REFERENCES = "Kikuchi & Adhikari, Cartan media: geometric continuum mechanics in homogeneous spaces"


def _initial_positions(problem: Problem) -> Any:
    """Positions of the scene's initial state ``[*grid.shape, k]`` (affine groups), else None."""
    import numpy as np

    if not getattr(problem.medium.group, "affine", False):
        return None
    return np.array(np.asarray(problem.initial.Phi)[..., 1:, 0], dtype=float)


def _finish(ds: Any, sc: Scene, config: dict[str, Any], command: str | None) -> None:
    """Record the scene, the mode and the command in ``cartan_config`` and ``history``."""
    from . import io

    config["mode"] = sc.mode
    config["scene"] = sc.source if sc.source.get("medium") else None
    config["scene_path"] = str(sc.path) if sc.path else None
    if command is None:
        what = f"cartan.load_scene({str(sc.path)!r})" if sc.path else f"scene {sc.name!r}"
        command = f"Scene.run({what}, mode={sc.mode!r})"
    ds.attrs["history"] = io.history_line(command)
    ds.attrs["cartan_config"] = io.to_json(config)


def _label_pins(sc: Scene, ds: Any) -> None:
    """Label the reactions of the scene's pins (coordinate ``pin``: the node and the component)."""
    import numpy as np

    pins = sc.solver_options.get("pins")
    if "reaction" not in ds or not pins:
        return
    k = sc.problem.medium.group.matrix_size - 1
    axes = list(_AXIS_LABELS[:k]) if k <= 3 else [f"x{i}" for i in range(k)]
    if isinstance(pins, str):  # the rigid-body gauge: node 0, its translations then its rotations
        npin = ds["reaction"].shape[-1]
        labels = [f"0 {axes[c]}" if c < k else f"0 rotation {c - k}" for c in range(npin)]
    else:
        labels = [f"{node} {axes[c]}" for node, comps in pins.items() for c in comps]
    ds.coords["pin"] = ("pin", np.array(labels, dtype=object), {"long_name": "pinned node, component"})


def _solve_static(sc: Scene, command: str | None) -> Any:
    """``solve_static`` of the scene's problem with its ``[static]`` settings, annotated."""
    import json

    from . import io
    from .statics import solve_static

    initial = io.open_dataset(sc.initial_guess) if sc.initial_guess is not None else None
    ds = solve_static(sc.problem, initial=initial, **sc.solver_options)
    _label_pins(sc, ds)
    config = json.loads(ds.attrs["cartan_config"])
    config["run"]["initial_guess"] = str(sc.initial_guess) if sc.initial_guess is not None else None
    pos0 = _initial_positions(sc.problem)
    if pos0 is not None and "position" in ds:
        ds["initial_position"] = (
            ds["position"].dims[1:],
            pos0,
            {"long_name": "position in the scene's initial state (the reference of displacements)",
             "units": "length"},
        )
        if sc.measure is not None:
            k = pos0.shape[-1]
            value = sc.measure(ds["position"].values[0].reshape(-1, k), pos0.reshape(-1, k))
            ds.attrs["measure"] = sc.measure.describe()
            ds.attrs["measured_displacement"] = value
            config["run"]["measure"] = sc.measure.describe()
    _finish(ds, sc, config, command)
    return ds


def _parameter_comment(sc: Scene) -> str:
    import numpy as np

    if sc.parameter == "all":
        return "λ multiplies every external load of the scene (end loads and body loads)"
    b = sc.problem.boundaries[sc.parameter]
    kind = "follower" if b.follower else "dead"
    return f"λ multiplies the {kind} load {np.asarray(b.load).tolist()} at boundary {sc.parameter!r}"


def _follow_path(sc: Scene, command: str | None) -> Any:
    """``continuation`` of the scene's problem with its ``[continuation]`` settings, as a run file."""
    import numpy as np

    from . import io
    from .continuation import continuation

    problem = sc.problem
    pos0 = _initial_positions(problem)
    flat0 = None if pos0 is None else pos0.reshape(-1, pos0.shape[-1])
    measure = sc.measure
    monitor = None
    if measure is not None:

        def monitor(snapshot: Any) -> float:
            return measure(snapshot["position"].values[0], flat0)

    ds = continuation(problem, monitor=monitor, **sc.solver_options)
    _label_pins(sc, ds)
    if flat0 is not None:
        k = flat0.shape[1]
        labels = list(_AXIS_LABELS[:k]) if k <= 3 else [f"x{i}" for i in range(k)]
        ds.coords["row"] = ("row", np.array(labels, dtype=object), {"long_name": "spatial axis"})
        if problem.grid.d == 1:
            ds.coords["u"] = ("node", problem.grid.coordinates(0),
                              {"long_name": "material coordinate of the nodes", "units": "length"})
        if "position" in ds:
            ds["position"].attrs.update(long_name="position of the material point along the path", units="length")
        ds["initial_position"] = (("node", "row"), flat0, {
            "long_name": "position in the scene's initial state (the reference of displacements)",
            "units": "length"})
    if measure is not None:
        ds["monitor"].attrs.update(long_name=f"{measure.describe()} (position − initial position)",
                                   units="length")
    elif flat0 is not None:
        ds["monitor"].attrs.update(long_name="largest displacement of a node from its initial position",
                                   units="length")
    ds["load_factor"].attrs["comment"] = _parameter_comment(sc)
    for name, long_name, units in (
        ("newton_iterations", "corrector iterations of the path point", "1"),
        ("step", "arclength step Δs to the path point", "1"),
        ("branch", "branch index (0 before the branch switch, 1 after)", "1"),
        ("critical_load", "load factor λ of the critical point", "1"),
        ("critical_monitor", "monitored displacement at the critical point", ds["monitor"].attrs.get("units", "")),
        ("critical_eig", "eigenvalue of smallest magnitude of the symmetric Jacobian part at the critical point", ""),
        ("critical_kind", "kind of critical point (fold or bifurcation)", ""),
        ("critical_path_index", "index along path of the first point past the critical point", "1"),
        ("reaction", "reaction force at the pin (spatial component)", "force"),
    ):
        if name in ds:
            ds[name].attrs.update({"long_name": long_name, **({"units": units} if units else {})})
    wall = float(ds.attrs.get("wall_time", 0.0))
    iters = int(ds.attrs.get("newton_iterations", 0))
    options = dict(sc.solver_options)
    config: dict[str, Any] = {
        "problem": problem.to_dict(),
        "run": {
            "solver": "continuation",
            "scheme": "lattice",
            "parameter": sc.parameter,
            "measure": measure.describe() if measure is not None else None,
            **options,
        },
        "counters": {"newton_iterations": iters, "wall_time": wall},
    }
    title = ds.attrs.get("title") or f"{sc.name}: load continuation"
    ds.attrs = {
        "Conventions": io.CONVENTIONS,
        "title": title,
        "source": io.source_string(problem),
        "history": "",
        "references": _REFERENCES,
        "comment": "written by cartan; cartan_config holds the full run configuration as JSON",
        "units_convention": io.UNITS_CONVENTION,
        "cartan_config": "",
        "wall_time": wall,
        "newton_iterations": iters,
        **({"grid_shape": ds.attrs["grid_shape"]} if "grid_shape" in ds.attrs else {}),
    }
    _finish(ds, sc, config, command)
    return ds


# ---------------------------------------------------------------------------- public
def _parse(path_or_dict: Any) -> tuple[dict, pathlib.Path | None, str]:
    if isinstance(path_or_dict, Mapping):
        data = dict(path_or_dict)
        name = data.get("name")
        return data, None, f"scene {name!r}" if isinstance(name, str) and name else "scene"
    if not isinstance(path_or_dict, str | pathlib.PurePath):
        raise SceneError(f"load_scene expects a path or a dict, got {type(path_or_dict).__name__}")
    path = pathlib.Path(path_or_dict)
    return read_scene_file(path), path, str(path)


def read_scene_file(path: str | os.PathLike) -> dict[str, Any]:
    """The tables of a TOML scene file, read within the limits of the module docstring.

    Parameters
    ----------
    path : path-like
        A regular file of at most :data:`MAX_SCENE_BYTES`, UTF-8 (a byte-order mark is
        skipped).

    Returns
    -------
    dict
        The parsed TOML (not yet validated as a scene: :func:`load_scene` does that).

    Raises
    ------
    SceneError
        One line naming the file: missing, unreadable, not a regular file (a directory, a
        device, a pipe), too large, not UTF-8, invalid TOML, or nested too deeply.
    """
    label = str(path)
    try:
        # non-blocking, so that opening a pipe does not wait for a writer; regular files
        # read as usual
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise SceneError(f"{label}: no such file") from None
    except (OSError, ValueError) as exc:
        raise SceneError(f"{label}: cannot read: {getattr(exc, 'strerror', None) or _one_line(exc)}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            what = "a directory" if stat.S_ISDIR(info.st_mode) else "a device, pipe or socket"
            raise SceneError(f"{label}: not a regular file ({what}); a scene is a TOML file")
        chunks, size = [], 0
        while size <= MAX_SCENE_BYTES:
            chunk = os.read(fd, MAX_SCENE_BYTES + 1 - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise SceneError(f"{label}: cannot read: {exc.strerror or _one_line(exc)}") from None
    finally:
        os.close(fd)
    if size > MAX_SCENE_BYTES:
        raise SceneError(f"{label}: larger than {MAX_SCENE_BYTES} bytes (1 MiB), the limit for a scene file")
    try:
        text = b"".join(chunks).decode("utf-8-sig")
    except UnicodeDecodeError:
        raise SceneError(f"{label}: not a UTF-8 text file") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{label}: invalid TOML: {_one_line(exc)}") from None
    except RecursionError:
        raise SceneError(f"{label}: invalid TOML: nested deeper than {MAX_NESTING} levels") from None
    _check_values(_Reader(label), data)
    return data


def load_scene(path_or_dict: str | pathlib.Path | Mapping[str, Any]) -> Scene:
    """Read a scene from a TOML file or a dict of the same form.

    Parameters
    ----------
    path_or_dict : str, pathlib.Path or dict
        A scene file (see the module docstring for the schema) or its parsed tables.

    Returns
    -------
    Scene
        The problem and its run settings; ``Scene.simulate()`` runs it.

    Raises
    ------
    SceneError
        One line naming the file and the key for every problem found: a file that is not a
        regular file of at most 1 MiB, malformed or too deeply nested TOML, missing or unknown
        keys, a value against the rules of the module docstring (a number spelled as a string,
        a boolean for a number, a non-finite number), unknown medium/integrator/scheme/load
        kind, a parameter the medium rejects (e.g. a negative stiffness) or that makes a
        computation overflow, a grid above the memory limit, an unknown ``mode`` or a bad
        value in ``[static]`` / ``[continuation]`` / ``[flow]``.
    """
    data, path, label = _parse(path_or_dict)
    reader = _Reader(label)
    _check_values(reader, data)
    reader.no_extra(data, _TOP_KEYS, "")
    mode = _mode(reader, data)
    name = reader.string(data, "name", "", required=False, default=path.stem if path else "")
    description = reader.string(data, "description", "", required=False)
    medium_name = reader.string(data, "medium", "")
    cls = _lookup(reader, "media", medium_name, "medium")
    params = reader.table(data, "parameters", "")
    _check_keywords(reader, cls, params, "parameters", f"medium {medium_name!r}")
    _check_flags(reader, cls, params, "parameters")
    medium = _building(reader, "parameters", params, cls, **params)
    grid = _grid(reader, data, medium)
    boundaries = _boundaries(reader, data)
    loads = _loads(reader, data, medium, grid) + _held_loads(reader, data, medium, grid)
    initial = _initial(reader, data, medium, grid)
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            problem = Problem(
                medium=medium, grid=grid, initial=initial, boundaries=boundaries, loads=loads, name=name
            )
    except (ValueError, TypeError) as exc:
        msg = _one_line(exc)
        key = _problem_error_key(msg)
        raise reader.fail("" if msg.startswith(key) else key, msg) from None
    except ArithmeticError as exc:
        raise reader.fail("problem", _out_of_range(data.get("initial", {}), exc)) from None
    if mode == "dynamic":
        settings = _run(reader, data, problem)
    elif mode == "static":
        settings = _static(reader, data, problem, path)
    elif mode == "flow":
        settings = _flow(reader, data, problem)
    else:
        settings = _continuation(reader, data, problem)
    return Scene(problem=problem, name=name, description=description, mode=mode, source=data, path=path,
                 **settings)


def scene(name: str) -> Scene:
    """The registered scene ``name`` (registry ``"scenes"``), ready to run.

    A registered scene is a path to a TOML file, a dict of the same form, a
    :class:`Scene`, or a callable returning any of these or a :class:`~cartan.Problem`.

    Parameters
    ----------
    name : str
        Registered name (``cartan list scenes`` shows them all).

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        If no scene of that name is registered, or the scene itself is invalid.
    """
    obj = _lookup(_Reader(""), "scenes", name, "")
    if callable(obj) and not isinstance(obj, type):
        try:
            obj = obj()
        except (ValueError, TypeError) as exc:
            raise SceneError(f"scene {name!r}: {_one_line(exc)}") from None
    if isinstance(obj, Scene):
        return obj
    if isinstance(obj, Problem):
        return Scene(problem=obj, name=obj.name or name, source={"name": name})
    if isinstance(obj, Mapping):
        data = dict(obj)
        data.setdefault("name", name)
        return load_scene(data)
    if isinstance(obj, str | pathlib.PurePath):
        return load_scene(obj)
    raise SceneError(f"scene {name!r}: registered object {obj!r} is not a path, dict, Scene or Problem")
