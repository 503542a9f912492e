"""The O(n+1) nonlinear sigma model for cartan (paper §VIII.B).

Registered through the ``cartan`` entry point ``sigma = "cartan_sigma.plugin"``: medium
``"sigma-model"`` (:class:`~cartan_sigma.model.SigmaModel`), wave maps and harmonic-map flow
of a field n: M → Sⁿ with G = SO(n+1), plus its outputs (energy density, the Berg–Lüscher
topological charge of O(3) fields on 2D lattices).
"""

from .model import (
    SigmaModel,
    energy_density,
    great_circle_angle,
    lump_field,
    lump_frames,
    topological_charge,
)

__all__ = [
    "SigmaModel",
    "energy_density",
    "great_circle_angle",
    "lump_field",
    "lump_frames",
    "topological_charge",
]
