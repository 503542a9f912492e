"""Hook implementations of the ``sphere_rod`` plugin (entry point ``cartan_sphere_rod.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"

#: scene name → TOML file shipped with the plugin
SCENES = {
    "sphere-rod-relax": SCENE_DIR / "sphere-rod-relax.toml",
}


@cartan.hookimpl
def cartan_register_media(register):
    from .rod import SphereRod

    register("sphere-rod", SphereRod)


@cartan.hookimpl
def cartan_register_scenes(register):
    for name, path in SCENES.items():
        register(name, path)
