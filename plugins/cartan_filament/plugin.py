"""Hook implementations of the ``filament`` plugin (entry point ``cartan_filament.plugin``)."""

from __future__ import annotations

import cartan
from cartan.plugins import register_cases, register_scenes


@cartan.hookimpl
def cartan_register_media(register):
    from .filament import Filament

    register("filament", Filament)


@cartan.hookimpl
def cartan_register_scenes(register):
    register_scenes(register, __file__)


@cartan.hookimpl
def cartan_register_cases(register):
    register_cases(register, "cartan_filament.cases")
    register_cases(register, "cartan_filament.cases_kinematic")
