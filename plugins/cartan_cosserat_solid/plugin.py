"""Hook implementations of the ``cartan_cosserat_solid`` plugin (entry point ``cartan_cosserat_solid.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"


@cartan.hookimpl
def cartan_register_media(register):
    from .solid import CosseratSolid

    register("cosserat-solid", CosseratSolid)


@cartan.hookimpl
def cartan_register_scenes(register):
    for path in sorted(SCENE_DIR.glob("*.toml")):
        register(path.stem, path)


@cartan.hookimpl
def cartan_register_cases(register):
    try:
        import cartan_verification  # noqa: F401 - the cases derive from its Case
    except ImportError:  # pragma: no cover - the medium works without the verification package
        return
    from .cases import LongitudinalWave, OpticalCutoff, RotationWave, ShearWave

    for case in (LongitudinalWave(), RotationWave(), ShearWave(), OpticalCutoff()):
        register(case.name, case)
