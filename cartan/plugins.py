"""Plugin system: pluggy hook specifications and the lazily built, cached registries.

Every registry entry — the built-in groups included — arrives through the entry-point
group ``cartan``.  A distribution declares::

    [project.entry-points.cartan]
    foo = "cartan_foo.plugin"

and the module ``cartan_foo.plugin`` implements any of the hooks below::

    import cartan

    @cartan.hookimpl
    def cartan_register_media(register):
        register("foo", FooMedium)

Registry names are kebab-case (groups keep their mathematical names, e.g. ``"SO3"``).  A
plugin that fails to import is reported with a :class:`PluginWarning` naming it and the
rest keeps working; registering one name twice in a registry is a :class:`RegistryError`.
"""

from __future__ import annotations

import importlib.metadata as md
import re
import threading
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import pluggy

PROJECT = "cartan"
ENTRY_POINT_GROUP = "cartan"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)

#: registry kind -> hook name
KINDS: dict[str, str] = {
    "groups": "cartan_register_groups",
    "spaces": "cartan_register_spaces",
    "media": "cartan_register_media",
    "schemes": "cartan_register_schemes",
    "integrators": "cartan_register_integrators",
    "cases": "cartan_register_cases",
    "scenes": "cartan_register_scenes",
    "flows": "cartan_register_flows",
    "commands": "cartan_register_commands",
}

Register = Callable[[str, Any], None]


class PluginWarning(UserWarning):
    """A plugin could not be loaded; the other plugins keep working."""


class RegistryError(ValueError):
    """A registry name is invalid, duplicated, or unknown."""


class HookSpecs:
    """Hook specifications.  Each hook receives ``register(name, obj)``."""

    @hookspec
    def cartan_register_groups(self, register: Register) -> None:
        """Register :class:`~cartan.groups.SymmetryGroup` subclasses (constructed by
        :func:`cartan.group` with keyword parameters, e.g. ``n`` for ``"SO"``)."""

    @hookspec
    def cartan_register_spaces(self, register: Register) -> None:
        """Register :class:`~cartan.spaces.HomogeneousSpace` subclasses."""

    @hookspec
    def cartan_register_media(self, register: Register) -> None:
        """Register ``Medium`` subclasses (the physics of paper §IV–VIII)."""

    @hookspec
    def cartan_register_schemes(self, register: Register) -> None:
        """Register discretisation ``Scheme`` classes."""

    @hookspec
    def cartan_register_integrators(self, register: Register) -> None:
        """Register ``Integrator`` classes."""

    @hookspec
    def cartan_register_cases(self, register: Register) -> None:
        """Register verification cases."""

    @hookspec
    def cartan_register_scenes(self, register: Register) -> None:
        """Register named runnable scenes (callables returning a problem, or scene dicts)."""

    @hookspec
    def cartan_register_flows(self, register: Register) -> None:
        """Register named flows a scene's ``[flow]`` table runs: ``register("helfrich", fn)`` with
        ``fn(problem, **options) -> xarray.Dataset`` (the options are ``fn``'s keyword parameters,
        checked by the scene reader against their defaults' types; an optional attribute
        ``fn.check(problem, options)`` raising ``ValueError`` checks ranges before the run)."""

    @hookspec
    def cartan_register_commands(self, register: Register) -> None:
        """Register extra ``click`` commands for the ``cartan`` CLI."""


@dataclass(frozen=True)
class Entry:
    """One registry entry and where it came from."""

    name: str
    obj: Any
    plugin: str
    distribution: str
    version: str


_SINGULAR = {"groups": "group", "spaces": "space", "media": "medium", "schemes": "scheme",
             "integrators": "integrator", "cases": "case", "scenes": "scene", "flows": "flow", "commands": "command"}

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9]*(-[A-Za-z0-9]+)*$")


class Registry:
    """All registries, filled once from the plugin manager.  Use :func:`get_registry`."""

    def __init__(self, plugins: Iterable[tuple[str, ModuleType | object, str, str]]):
        self.manager = pluggy.PluginManager(PROJECT)
        self.manager.add_hookspecs(HookSpecs)
        self.origin: dict[str, tuple[str, str]] = {}
        for name, module, dist, version in plugins:
            self.manager.register(module, name=name)
            self.origin[name] = (dist, version)
        self.entries: dict[str, dict[str, Entry]] = {kind: {} for kind in KINDS}
        for kind, hook in KINDS.items():
            caller = getattr(self.manager.hook, hook)
            for impl in caller.get_hookimpls():
                try:
                    impl.function(register=self._registrar(kind, impl.plugin_name))
                except RegistryError:
                    raise
                except Exception as exc:  # noqa: BLE001 - a broken plugin must not break the rest
                    dist = self.origin.get(impl.plugin_name, ("unknown", ""))[0]
                    warnings.warn(
                        f"cartan plugin {impl.plugin_name!r} (from {dist}) failed in {hook} and its "
                        f"{kind} may be incomplete: {type(exc).__name__}: {exc}",
                        PluginWarning,
                        stacklevel=4,
                    )

    def _registrar(self, kind: str, plugin: str) -> Register:
        dist, version = self.origin.get(plugin, ("unknown", ""))

        def register(name: str, obj: Any) -> None:
            if not isinstance(name, str) or not _NAME.match(name):
                raise RegistryError(
                    f"plugin {plugin!r}: {kind} name {name!r} is not kebab-case "
                    "(letters, digits and single hyphens)"
                )
            table = self.entries[kind]
            if name in table:
                first = table[name]
                raise RegistryError(
                    f"{kind} name {name!r} is registered twice: by plugin {first.plugin!r} "
                    f"({first.distribution}) and by plugin {plugin!r} ({dist})"
                )
            table[name] = Entry(name, obj, plugin, dist, version)

        return register

    def get(self, kind: str, name: str) -> Any:
        table = self.table(kind)
        if name not in table:
            known = ", ".join(sorted(table)) or "none"
            raise RegistryError(f"unknown {_SINGULAR.get(kind, kind)} {name!r}; registered {kind}: {known}")
        return table[name].obj

    def table(self, kind: str) -> dict[str, Entry]:
        if kind not in self.entries:
            raise RegistryError(f"unknown registry {kind!r}; choose from {', '.join(KINDS)}")
        return self.entries[kind]


def register_scenes(register: Register, plugin_file: str) -> None:
    """Register the ``scenes/*.toml`` files beside a plugin's module under their file stems: the
    body of a plugin's ``cartan_register_scenes`` hook, ``register_scenes(register, __file__)``."""
    import pathlib

    for path in sorted((pathlib.Path(plugin_file).resolve().parent / "scenes").glob("*.toml")):
        register(path.stem, path)


def register_cases(register: Register, module: str, factory: str = "all_cases") -> None:
    """Register the verification cases ``module.factory()`` returns (the body of a plugin's
    ``cartan_register_cases`` hook).  Cases derive from an optional package (the verification
    package's ``Case``): when ``module`` cannot import one of its dependencies, the plugin
    registers no case and works otherwise; a missing ``module`` itself is an error."""
    import importlib

    try:
        cases = importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and (module == exc.name or module.startswith(exc.name + ".")):
            raise
        return
    for case in getattr(cases, factory)():
        register(case.name, case)


def _entry_point_plugins() -> list[tuple[str, object, str, str]]:
    found = []
    for ep in sorted(md.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: (e.dist.name if e.dist else "", e.name)):
        dist = ep.dist.name if ep.dist is not None else "unknown"
        version = ep.dist.version if ep.dist is not None else ""
        try:
            module = ep.load()
        except Exception as exc:  # noqa: BLE001 - any failure of a third-party import
            warnings.warn(
                f"cartan plugin {ep.name!r} ({ep.value}, from {dist}) failed to load and is "
                f"skipped: {type(exc).__name__}: {exc}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        found.append((f"{dist}:{ep.name}", module, dist, version))
    return found


_lock = threading.Lock()
_registry: Registry | None = None


def get_registry() -> Registry:
    """The process-wide registry, built on first use from the ``cartan`` entry points."""
    global _registry
    with _lock:
        if _registry is None:
            _registry = Registry(_entry_point_plugins())
        return _registry


def reset_registry(extra_plugins: Iterable[tuple[str, object]] = (), entry_points: bool = True) -> Registry:
    """Rebuild the registry, optionally with extra in-process plugin objects (for tests and
    interactive use): ``reset_registry([("myplugin", module_or_object)])``."""
    global _registry
    plugins = _entry_point_plugins() if entry_points else []
    plugins += [(name, obj, "local", "") for name, obj in extra_plugins]
    with _lock:
        _registry = Registry(plugins)
        return _registry


def registry(kind: str) -> dict[str, Any]:
    """``{name: object}`` of one registry: ``"groups"``, ``"spaces"``, ``"media"``,
    ``"schemes"``, ``"integrators"``, ``"cases"``, ``"scenes"``, ``"flows"`` or ``"commands"``."""
    return {name: e.obj for name, e in get_registry().table(kind).items()}
