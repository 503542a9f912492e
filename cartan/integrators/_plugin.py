"""Registers the built-in integrators through the ``cartan`` entry points, like any plugin."""

from __future__ import annotations

from ..plugins import hookimpl


@hookimpl
def cartan_register_integrators(register):
    from . import constrained, explicit, implicit

    for cls in (explicit.ForwardEuler, explicit.LieEuler, explicit.LieVerlet, explicit.RKMK4,
                explicit.Overdamped, explicit.Kinematic, implicit.ImplicitMidpoint, constrained.Rattle):
        register(cls.name, cls)
