"""Hook implementations of the ``sigma`` plugin (entry point ``cartan_sigma.plugin``)."""

from __future__ import annotations

import cartan


@cartan.hookimpl
def cartan_register_media(register):
    from .model import SigmaModel

    register("sigma-model", SigmaModel)
