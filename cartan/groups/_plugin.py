"""Registers the built-in groups through the same entry-point mechanism as any plugin."""

from __future__ import annotations

from ..plugins import hookimpl
from . import _LAZY


@hookimpl
def cartan_register_groups(register):
    from .. import groups

    for name in _LAZY:
        register(name, getattr(groups, name))
