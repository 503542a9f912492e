"""Cosserat media for cartan: the Cosserat rod on SE(3) and the planar rod on SE(2).

Registered through the ``cartan`` entry point ``cosserat = "cartan_cosserat.plugin"``:

* media ``"cosserat-rod"`` (:class:`~cartan_cosserat.rod.CosseratRod`, paper §VI.C) and
  ``"planar-cosserat-rod"`` (:class:`~cartan_cosserat.rod.PlanarCosseratRod`);
* scenes ``"rod-cantilever-gravity"``, ``"rod-butterfly"``, ``"rod-ring-relax"`` (dynamic) and
  ``"rod-timoshenko-static"``, ``"rod-euler-buckling"``, ``"rod-elastica-continuation"`` (static and
  continuation runs) — TOML files in :mod:`cartan_cosserat.scenes`.
"""

from .rod import (
    DEFAULT_SHEAR_COEFFICIENT,
    PLANAR_COMPONENTS,
    CosseratRod,
    FrameBundleE2,
    Gravity,
    PlanarCosseratRod,
)

__all__ = [
    "DEFAULT_SHEAR_COEFFICIENT",
    "PLANAR_COMPONENTS",
    "CosseratRod",
    "FrameBundleE2",
    "Gravity",
    "PlanarCosseratRod",
]
