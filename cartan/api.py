"""The run-level public API, re-exported by :mod:`cartan`.

``cartan.simulate``, ``cartan.open``, ``cartan.load_scene``, ``cartan.scene``,
``cartan.medium`` and the problem-building classes (``Problem``, ``Grid``,
``InitialState``, ``Free``, ``Clamped``, ``Driven``, ``Held``, ``Symmetry``, ``Damping``, ``UniformForce``,
``NodeForce``, ``PotentialLoad``),
with the errors and warnings a run can raise (``InstabilityError``, ``StabilityWarning``,
``SceneError``).  Importing this module does not import xarray (that happens on the first
run or read).

This is the layer where scenes and runs meet: :mod:`cartan.scene` (reading scenes) and
:mod:`cartan.simulate` (running problems) import neither the other, and reach each other
through this module (``Scene.run`` runs :func:`simulate`; :func:`simulate` reads a scene file,
name or checkpointed scene with :func:`load_scene` and :func:`scene`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .continuation import continuation
from .grid import Grid
from .io import open_dataset
from .medium import Medium
from .problem import (
    Clamped,
    ConstantFieldPotential,
    Damping,
    Driven,
    Free,
    Held,
    InitialState,
    NodeForce,
    PotentialLoad,
    Problem,
    Symmetry,
    UniformForce,
)
from .scene import Scene, SceneError, load_scene, scene
from .simulate import InstabilityError, StabilityWarning, simulate
from .statics import ConvergenceError, solve_static

__all__ = [
    "Clamped",
    "ConstantFieldPotential",
    "ConvergenceError",
    "continuation",
    "Damping",
    "Driven",
    "Free",
    "Grid",
    "Held",
    "InitialState",
    "InstabilityError",
    "PotentialLoad",
    "Problem",
    "Scene",
    "SceneError",
    "StabilityWarning",
    "Symmetry",
    "NodeForce",
    "UniformForce",
    "load_scene",
    "medium",
    "open",
    "scene",
    "simulate",
    "solve_static",
]

#: ``cartan.open(path)``: read a run file (see :func:`cartan.io.open_dataset`).
open = open_dataset  # noqa: A001 - the public name is cartan.open


def medium(name: str, **params: Any) -> Medium:
    """Instance of the registered medium ``name`` with its parameters.

    Parameters
    ----------
    name : str
        Registered name, e.g. ``"cosserat-rod"`` (``cartan list media`` shows them all).
    **params
        Constructor keywords of the medium.

    Returns
    -------
    Medium

    Raises
    ------
    cartan.RegistryError
        If no medium of that name is registered.
    ValueError
        If a parameter is invalid (the medium names it).
    TypeError
        If a keyword is not a parameter of the medium.
    """
    from .plugins import get_registry

    cls = get_registry().get("media", name)
    try:
        with np.errstate(over="raise", invalid="raise", divide="raise"):
            return cls(**params)
    except TypeError as exc:
        raise TypeError(f"medium {name!r}: {exc}") from None
    except ArithmeticError as exc:  # a parameter so extreme that a derived quantity overflows
        from .scene import _out_of_range

        raise ValueError(f"medium {name!r}: {_out_of_range(params, exc)}") from None
