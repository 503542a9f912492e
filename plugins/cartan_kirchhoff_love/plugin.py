"""Hook implementations of the ``kirchhoff-love`` plugin (entry point ``cartan_kirchhoff_love.plugin``)."""

from __future__ import annotations

import cartan
from cartan.plugins import register_cases, register_scenes


@cartan.hookimpl
def cartan_register_media(register):
    from .helfrich import HelfrichMembrane
    from .kirchhoff_love import KirchhoffLove

    register("kirchhoff-love", KirchhoffLove)
    register("helfrich-membrane", HelfrichMembrane)


@cartan.hookimpl
def cartan_register_scenes(register):
    register_scenes(register, __file__)


@cartan.hookimpl
def cartan_register_cases(register):
    register_cases(register, f"{__package__}.cases")
