"""The planar reduction (``cartan.reduction``) of problems with ``cartan.Held`` ends.

A held end's in-plane components (V₁, V₂, Ω₃) are held as the SE(2) components (0, 1, 2); its
out-of-plane ones (V₃, Ω₁, Ω₂) are zero in a planar motion anyway, so an end holding only those
is free in the plane.  The reduced and the full runs agree to 1e-12 of each variable's scale
(tests/test_reduction.py: the SE(2) and SE(3) kernels differ by round-off, ≲ 1e-13 over a few
hundred steps).  Both run the numpy path (``compiled=False``): the point is the mapping.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_reduction import assert_same_run

import cartan
import cartan.reduction as reduction
from cartan.reduction import planar_obstacle, planar_reduction

ROD = {"E": 1e5, "poisson": 0.5, "radius": 0.05, "density": 1000.0}
RUN = {"dt": 1e-3, "t_end": 0.2, "save_every": 20, "progress": False, "compiled": False}


def pendulum(start, end) -> cartan.Problem:
    """A rod along x, held at s = 0 by ``start`` and at s = L by ``end``, swinging under gravity in
    the x–y plane with damping."""
    rod = cartan.medium("cosserat-rod", **ROD)
    grid = cartan.Grid(15, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": start, "end": end},
                          [rod.make_load("gravity", g=[0.0, -9.81, 0.0]),
                           cartan.Damping([2.0, 2.0, 2.0, 1e-3, 1e-3, 1e-3])], name="pendulum")


def test_held_ends_map_to_the_plane():
    pinned = pendulum(cartan.Held((0, 1, 2)), cartan.Held((2, 3, 4)))
    red = planar_reduction(pinned)
    assert red is not None and planar_obstacle(pinned) is None
    start, end = red.reduced.boundaries["start"], red.reduced.boundaries["end"]
    assert type(start) is cartan.Held and start.components == (0, 1)  # (V₁, V₂) held, Ω₃ free
    assert type(end) is cartan.Free and end.load is None  # out-of-plane components only: free in the plane
    rotating = planar_reduction(pendulum(cartan.Held((0, 1, 2, 3, 4)), cartan.Held((1, 2, 3, 4, 5))))
    assert rotating.reduced.boundaries["start"].components == (0, 1)
    assert rotating.reduced.boundaries["end"].components == (1, 2)  # V₂ and Ω₃: a sliding sleeve along x


@pytest.mark.parametrize("ends", [(cartan.Held((0, 1, 2)), cartan.Held((2, 3, 4))),
                                  (cartan.Held((0, 1, 2, 3, 4)), cartan.Free()),
                                  (cartan.Clamped(), cartan.Held((1, 2, 3, 4, 5)))],
                         ids=["pinned-outofplane", "pinned-planar", "clamped-sleeve"])
def test_held_reduced_equals_full(ends, monkeypatch):
    """A pinned pendulum (the pin holds the position, or the position and the out-of-plane
    rotations) and a rod clamped at s = 0 whose end slides along x (V₂, Ω₃ held): the reduced
    run's Dataset is the full run's to 1e-12."""
    problem = pendulum(*ends)
    full = cartan.simulate(problem, **RUN, reduce=False)
    monkeypatch.setattr(reduction, "reduction_pays", lambda run: True)
    reduced = cartan.simulate(problem, **RUN)
    assert_same_run(reduced, full)
    assert float(np.ptp(full.position.values[:, 7, 1])) > 1e-3  # the rod moved in the plane
    held = np.asarray(problem.boundaries["start"].components if isinstance(problem.boundaries["start"], cartan.Held)
                      else range(6))
    assert np.all(full.N.values[:, 0, held] == 0.0)
