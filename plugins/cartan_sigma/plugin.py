"""Hook implementations of the ``sigma`` plugin (entry point ``cartan_sigma.plugin``)."""

from __future__ import annotations

import cartan
from cartan.plugins import register_scenes


@cartan.hookimpl
def cartan_register_media(register):
    from .model import SigmaModel

    register("sigma-model", SigmaModel)


@cartan.hookimpl
def cartan_register_scenes(register):
    register_scenes(register, __file__)
