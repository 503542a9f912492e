"""Hook implementations of the ``cosserat`` plugin (entry point ``cartan_cosserat.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"

#: scene name → TOML file shipped with the plugin
SCENES = {
    "rod-cantilever-gravity": SCENE_DIR / "rod-cantilever-gravity.toml",
    "rod-butterfly": SCENE_DIR / "rod-butterfly.toml",
    "rod-ring-relax": SCENE_DIR / "rod-ring-relax.toml",
}

#: static and continuation scenes (``mode = "static"`` / ``"continuation"``; run by ``cartan run``)
STATIC_SCENES = {
    "rod-timoshenko-static": SCENE_DIR / "rod-timoshenko-static.toml",
    "rod-euler-buckling": SCENE_DIR / "rod-euler-buckling.toml",
    "rod-elastica-continuation": SCENE_DIR / "rod-elastica-continuation.toml",
}


@cartan.hookimpl
def cartan_register_media(register):
    from .rod import CosseratRod, PlanarCosseratRod

    register("cosserat-rod", CosseratRod)
    register("planar-cosserat-rod", PlanarCosseratRod)


@cartan.hookimpl
def cartan_register_scenes(register):
    for name, path in {**SCENES, **STATIC_SCENES}.items():
        register(name, path)
