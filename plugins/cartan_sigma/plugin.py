"""Hook implementations of the ``sigma`` plugin (entry point ``cartan_sigma.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"


@cartan.hookimpl
def cartan_register_media(register):
    from .model import SigmaModel

    register("sigma-model", SigmaModel)


@cartan.hookimpl
def cartan_register_scenes(register):
    for path in sorted(SCENE_DIR.glob("*.toml")):
        register(path.stem, path)
