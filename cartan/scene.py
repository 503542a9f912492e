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

Load kinds ``"damping"`` (``coefficients``) and ``"uniform-force"`` (``components``,
``frame``) are the core's; every other kind is built by ``medium.make_load(kind, **rest)``.

Every problem found while reading a scene — malformed TOML, a missing or unknown key, an
unknown medium, integrator, scheme or load kind, a parameter the medium rejects — raises
:class:`SceneError` with one line naming the file and the key, e.g.
``rod.toml: parameters: E must be > 0, got -1.0``.
"""

from __future__ import annotations

import inspect
import math
import numbers
import pathlib
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .grid import Grid
from .plugins import get_registry
from .problem import Clamped, Damping, Free, Problem, UniformForce

__all__ = ["Scene", "SceneError", "load_scene", "scene"]

_TOP_KEYS = {"name", "description", "medium", "parameters", "grid", "boundaries", "loads", "initial", "run"}
_GRID_KEYS = {"n", "shape", "length", "periodic"}
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


class SceneError(ValueError):
    """A scene file or dict is malformed or names something that does not exist.

    The message is a single line ``"<source>: <key>: <what is wrong>"``.
    """


@dataclass
class Scene:
    """A runnable problem with its run settings (the ``[run]`` table of a scene).

    Attributes
    ----------
    problem : Problem
        Medium, grid, boundaries, loads and initial state.
    name, description : str
    integrator, scheme : str or None
        Registered names (None: the :func:`cartan.simulate` defaults).
    dt, t_end : float or None
    save_every, checkpoint_every : int or None
    integrator_options, scheme_options : dict
        Keyword arguments of the integrator and scheme constructors.
    source : dict
        The scene as parsed (TOML tables as dicts); recorded in the output and used to
        rebuild the problem on restart.
    path : pathlib.Path or None
        The file the scene was read from.
    """

    problem: Problem
    name: str = ""
    description: str = ""
    integrator: str | None = None
    scheme: str | None = None
    dt: float | None = None
    t_end: float | None = None
    save_every: int | None = None
    checkpoint_every: int | None = None
    integrator_options: dict[str, Any] = field(default_factory=dict)
    scheme_options: dict[str, Any] = field(default_factory=dict)
    source: dict[str, Any] = field(default_factory=dict)
    path: pathlib.Path | None = None

    def run_settings(self) -> dict[str, Any]:
        """The ``[run]`` settings as keyword arguments of :func:`cartan.simulate` (unset ones omitted)."""
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
        """``cartan.simulate(self, **kwargs)``: run the scene (keywords override ``[run]``)."""
        from .simulate import simulate

        return simulate(self, **kwargs)

    def __repr__(self) -> str:
        where = f", path={str(self.path)!r}" if self.path else ""
        return f"Scene(name={self.name!r}, medium={self.problem.medium.name!r}{where})"


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

    def integer(self, data: Mapping, key: str, where: str, minimum: int = 1) -> int | None:
        if key not in data:
            return None
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
            raise self.fail(_join(where, key), f"must be an integer ≥ {minimum}, got {value!r}")
        return int(value)

    def no_extra(self, data: Mapping, allowed: set[str], where: str) -> None:
        for key in data:
            if key not in allowed:
                raise self.fail(_join(where, key), f"unknown key; allowed: {', '.join(sorted(allowed))}")


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


_SINGULAR = {"media": "medium", "integrators": "integrator", "schemes": "scheme", "scenes": "scene"}


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
def _grid(reader: _Reader, data: Mapping) -> Grid:
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
    periodic = g.get("periodic", False)
    try:
        return Grid(shape, length=length, periodic=periodic)
    except (ValueError, TypeError) as exc:
        raise reader.fail("grid", _one_line(exc)) from None


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
        else:
            raise reader.fail(f"{key}.kind", f"unknown boundary kind {kind!r}; choose 'clamped' or 'free'")
    return out


def _loads(reader: _Reader, data: Mapping, medium) -> list:
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
            else:
                available = ["damping", "uniform-force", *getattr(medium, "load_kinds", ())]
                if getattr(medium, "load_kinds", ()) and kind not in available:
                    raise reader.fail(
                        f"{key}.kind", f"unknown load kind {kind!r}; available: {', '.join(available)}"
                    )
                load = medium.make_load(kind, **rest)
            load.bind(medium)
        except SceneError:
            raise
        except (ValueError, TypeError) as exc:
            raise reader.fail(f"{key} ({kind})", _one_line(exc)) from None
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
    try:
        return medium.initial_state(grid, kind, **rest)
    except (ValueError, TypeError) as exc:
        raise reader.fail(f"initial ({kind})", _one_line(exc)) from None


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
    try:
        cls(**out["integrator_options"])
    except (ValueError, TypeError) as exc:
        raise reader.fail("run.integrator_options", f"{integ_name}: {_one_line(exc)}") from None
    scheme_name = out["scheme"] or "lattice"
    cls = _lookup(reader, "schemes", scheme_name, "run.scheme")
    try:
        cls(problem, **out["scheme_options"])
    except (ValueError, TypeError) as exc:
        key = "run.scheme_options" if out["scheme_options"] else "run.scheme"
        raise reader.fail(key, f"{scheme_name}: {_one_line(exc)}") from None
    return out


def _problem_error_key(message: str) -> str:
    for prefix in ("initial", "boundaries", "loads", "grid"):
        if message.startswith(prefix):
            return prefix
    return "problem"


# ---------------------------------------------------------------------------- public
def _parse(path_or_dict: Any) -> tuple[dict, pathlib.Path | None, str]:
    if isinstance(path_or_dict, Mapping):
        data = dict(path_or_dict)
        name = data.get("name")
        return data, None, f"scene {name!r}" if isinstance(name, str) and name else "scene"
    if not isinstance(path_or_dict, str | pathlib.PurePath):
        raise SceneError(f"load_scene expects a path or a dict, got {type(path_or_dict).__name__}")
    path = pathlib.Path(path_or_dict)
    label = str(path)
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{label}: no such file") from None
    except OSError as exc:
        raise SceneError(f"{label}: cannot read: {exc.strerror or _one_line(exc)}") from None
    try:
        data = tomllib.loads(text.decode("utf-8"))
    except UnicodeDecodeError:
        raise SceneError(f"{label}: not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{label}: invalid TOML: {_one_line(exc)}") from None
    return data, path, label


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
        One line naming the file and the key for every problem found: malformed TOML,
        missing or unknown keys, unknown medium/integrator/scheme/load kind, a parameter the
        medium rejects (e.g. a negative stiffness).
    """
    data, path, label = _parse(path_or_dict)
    reader = _Reader(label)
    reader.no_extra(data, _TOP_KEYS, "")
    name = reader.string(data, "name", "", required=False, default=path.stem if path else "")
    description = reader.string(data, "description", "", required=False)
    medium_name = reader.string(data, "medium", "")
    cls = _lookup(reader, "media", medium_name, "medium")
    params = reader.table(data, "parameters", "")
    _check_keywords(reader, cls, params, "parameters", f"medium {medium_name!r}")
    try:
        medium = cls(**params)
    except (ValueError, TypeError) as exc:
        raise reader.fail("parameters", _one_line(exc)) from None
    grid = _grid(reader, data)
    boundaries = _boundaries(reader, data)
    loads = _loads(reader, data, medium)
    initial = _initial(reader, data, medium, grid)
    try:
        problem = Problem(
            medium=medium, grid=grid, initial=initial, boundaries=boundaries, loads=loads, name=name
        )
    except (ValueError, TypeError) as exc:
        msg = _one_line(exc)
        key = _problem_error_key(msg)
        raise reader.fail("" if msg.startswith(key) else key, msg) from None
    run = _run(reader, data, problem)
    return Scene(problem=problem, name=name, description=description, source=data, path=path, **run)


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
