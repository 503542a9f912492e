"""Hook implementations of the ``cartan_cosserat_surface`` plugin (entry point ``cartan_cosserat_surface.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"


@cartan.hookimpl
def cartan_register_media(register):
    from .surface import CosseratSurface

    register("cosserat-surface", CosseratSurface)


@cartan.hookimpl
def cartan_register_scenes(register):
    for path in sorted(SCENE_DIR.glob("*.toml")):
        register(path.stem, path)


@cartan.hookimpl
def cartan_register_cases(register):
    from .cases import CASES

    for case in CASES:
        register(case.name, case)
