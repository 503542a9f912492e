"""Cosserat rods on a sphere for cartan (paper §VIII.A).

Registered through the ``cartan`` entry point ``sphere_rod = "cartan_sphere_rod.plugin"``:

* medium ``"sphere-rod"`` (:class:`~cartan_sphere_rod.rod.SphereRod`): configuration space the
  frame bundle F(S²_r) ≅ SO(3) of the sphere of radius r;
* scene ``"sphere-rod-relax"`` (TOML file in :mod:`cartan_sphere_rod.scenes`): an overdamped
  closed rod relaxing from a deformed state to a great circle (the paper's figure);
* :func:`~cartan_sphere_rod.plotting.plot_sphere_rod`: that figure from a run Dataset.
"""

from .rod import SphereRod

__all__ = ["SphereRod"]
