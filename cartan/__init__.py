"""cartan — geometric continuum mechanics of Cartan media.

Continua whose points live in a homogeneous space X acted on by a Lie group G (Kikuchi &
Adhikari, *Cartan media: geometric continuum mechanics in homogeneous spaces*).  The core
provides exact Lie-group kernels, homogeneous spaces and a plugin system; media, schemes,
integrators, verification cases and scenes arrive through the ``cartan`` entry points.

Public API
----------
``cartan.simulate(problem_or_scene, integrator=..., scheme=..., dt=..., t_end=...)`` → xarray.Dataset
``cartan.open(path)``, ``cartan.load_scene(path)``, ``cartan.scene(name)``, ``cartan.medium(name, **p)``
``cartan.Problem``, ``Grid``, ``InitialState``, ``Free``, ``Clamped``, loads; ``InstabilityError``
``cartan.group(name, **params)``     a registered :class:`~cartan.groups.SymmetryGroup`
``cartan.space(name, **params)``     a registered :class:`~cartan.spaces.HomogeneousSpace`
``cartan.registry(kind)``            ``{name: object}`` for ``"groups"``, ``"spaces"``, ...
``cartan.hookimpl``                  marker for plugin hook implementations
``cartan.use_backend(name)``         ``"numba"`` (default) or ``"numpy"`` reference kernels
``cartan.set_threads(k)``            threads of the compiled loops (default 1, or ``CARTAN_THREADS``)
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version
from typing import Any

from . import api as _api
from ._backend import get_backend, set_backend, use_backend
from ._threads import get_threads, set_threads, use_threads
from .api import *  # noqa: F403 - the run-level API; its __all__ is the single list of names
from .compiled.progress import install as _install_compile_progress
from .groups import SymmetryGroup
from .plugins import PluginWarning, RegistryError, hookimpl, registry
from .study import converge

try:
    __version__ = _version("cartan")
except PackageNotFoundError:  # pragma: no cover - running from an uninstalled checkout
    __version__ = "0+unknown"

__all__ = [
    "PluginWarning",
    "RegistryError",
    "SymmetryGroup",
    "__version__",
    "get_backend",
    "get_threads",
    "group",
    "hookimpl",
    "registry",
    "set_backend",
    "set_threads",
    "space",
    "use_backend",
    "use_threads",
    "converge",
    *_api.__all__,
]


def _construct(kind: str, name: str, params: dict[str, Any]) -> Any:
    from .plugins import get_registry

    cls = get_registry().get(kind, name)
    try:
        return cls(**params)
    except TypeError as exc:
        from .plugins import _SINGULAR

        raise TypeError(f"{_SINGULAR[kind]} {name!r}: {exc}") from None


def group(name: str, **params: Any) -> SymmetryGroup:
    """Instance of the registered group ``name``: ``group("SE3")``, ``group("SO", n=5)``."""
    return _construct("groups", name, params)


def space(name: str, **params: Any):
    """Instance of the registered homogeneous space ``name``: ``space("sphere", n=2)``."""
    return _construct("spaces", name, params)


_install_compile_progress()
