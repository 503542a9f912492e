"""Registers the built-in schemes through the ``cartan`` entry points, like any plugin."""

from __future__ import annotations

from ..plugins import hookimpl


@hookimpl
def cartan_register_schemes(register):
    from .collocation import Collocation
    from .lattice import Lattice

    register("lattice", Lattice)
    register("collocation", Collocation)
