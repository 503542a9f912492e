"""Hook implementations of the ``cartan_cosserat_surface`` plugin (entry point ``cartan_cosserat_surface.plugin``)."""

from __future__ import annotations

import cartan
from cartan.plugins import register_cases, register_scenes


@cartan.hookimpl
def cartan_register_media(register):
    from .surface import CosseratSurface

    register("cosserat-surface", CosseratSurface)


@cartan.hookimpl
def cartan_register_scenes(register):
    register_scenes(register, __file__)


@cartan.hookimpl
def cartan_register_cases(register):
    register_cases(register, f"{__package__}.cases")
    register_cases(register, f"{__package__}.cases_shells")
    register_cases(register, f"{__package__}.cases_pressure")
    register_cases(register, f"{__package__}.cases_sphere")
