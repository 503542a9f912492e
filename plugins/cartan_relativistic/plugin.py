"""Hook implementations of the ``cartan_relativistic`` plugin (entry point ``cartan_relativistic.plugin``)."""

from __future__ import annotations

import pathlib

import cartan

SCENE_DIR = pathlib.Path(__file__).resolve().parent / "scenes"


@cartan.hookimpl
def cartan_register_media(register):
    from .string import RelativisticRod

    register("relativistic-rod", RelativisticRod)


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
    from .cases import all_cases

    for case in all_cases():
        register(case.name, case)
