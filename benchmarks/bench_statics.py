"""Speed and accuracy of the static solver and of load continuation (PERFORMANCE.md T2).

Timoshenko cantilever (VERIFICATION.md §4: L = 3, radius 0.25, E = 1e6, G = 1e4, α_c = 27/28,
ρ = 5000, dead tip force 15 along −z; the ``rod-timoshenko-static`` scene at other resolutions):
``cartan.statics.solve_static`` from the straight rod on the ``lattice`` scheme.  The T2 target
is a tip deflection within 1e-4 of the geometrically exact answer in ≤ 1 s.

* ``time_solve`` — the whole Newton solve at n = 101 and 201 nodes;
* ``track_tip_error`` — the relative tip-deflection error against the geometrically exact
  reference, the Richardson extrapolation ``w₈₀₁ + (w₈₀₁ − w₄₀₁)/3`` of the lattice's
  second-order tip deflections (its own error is O(h⁴), below 1e-12 relative);
* ``track_newton_iterations`` — Newton iterations to the default tolerance.

Euler buckling (the ``rod-euler-buckling`` scene: a pinned–pinned planar column, n = 101,
followed by pseudo-arclength continuation through the first bifurcation onto the buckled
branch up to 1.5 P_cr):

* ``time_continuation`` — the whole path, as ``Scene.run`` does it;
* ``track_critical_load_error`` — the detected critical load against the Euler load π²B/L²
  (the lattice's error π²h²/12 = 8.2e-5 at n = 101).

``setup`` solves once, so that numba compilation (or loading its on-disk cache) never lands
inside a timing.
"""

from __future__ import annotations

import functools
import math

import cartan
from cartan.statics import solve_static

#: the Timoshenko cantilever of VERIFICATION.md §4
TIMOSHENKO = {"L": 3.0, "radius": 0.25, "E": 1e6, "G": 1e4, "density": 5000.0, "shear_coefficient": 27 / 28,
              "F": 15.0}


def timoshenko_problem(n: int) -> cartan.Problem:
    """The Timoshenko cantilever on ``n`` nodes (clamped at s = 0, dead tip force along −z)."""
    p = TIMOSHENKO
    rod = cartan.medium("cosserat-rod", E=p["E"], G=p["G"], radius=p["radius"], density=p["density"],
                        shear_coefficient=p["shear_coefficient"])
    grid = cartan.Grid(n, length=p["L"])
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, 0.0, -p["F"], 0.0, 0.0, 0.0])})


def timoshenko_tip(n: int) -> tuple[float, int]:
    """(tip deflection along −z, Newton iterations) of the static solve on ``n`` nodes."""
    ds = solve_static(timoshenko_problem(n))
    return -float(ds["position"].isel(time=0, node=-1, row=2)), int(ds.attrs["newton_iterations"])


@functools.cache
def timoshenko_reference() -> float:
    """The geometrically exact tip deflection: Richardson extrapolation of n = 401 and 801."""
    coarse, fine = timoshenko_tip(401)[0], timoshenko_tip(801)[0]
    return fine + (fine - coarse) / 3.0


class TimoshenkoStatic:
    """Newton solve of the Timoshenko cantilever on ``n`` nodes."""

    params = [101, 201]
    param_names = ["n"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 300.0

    def setup(self, n):
        self.problem = timoshenko_problem(n)
        solve_static(self.problem)  # compile or load every kernel

    def time_solve(self, n):
        solve_static(self.problem)

    def track_tip_error(self, n):
        """|w_n / w_exact − 1| of the tip deflection."""
        return abs(timoshenko_tip(n)[0] / timoshenko_reference() - 1.0)

    track_tip_error.unit = "relative"

    def track_newton_iterations(self, n):
        """Newton iterations from the straight rod."""
        return timoshenko_tip(n)[1]

    track_newton_iterations.unit = "iterations"


class EulerBuckling:
    """Continuation of the ``rod-euler-buckling`` scene through the first bifurcation."""

    number = 1
    repeat = (3, 5, 30.0)
    warmup_time = 0.0
    timeout = 300.0

    def setup(self):
        self.scene = cartan.scene("rod-euler-buckling")
        self.result = self.scene.run()  # compile or load every kernel

    def time_continuation(self):
        self.scene.run()

    def track_critical_load_error(self):
        """P_cr / (π²B/L²) − 1 (B = 1, L = 1): positive, π²h²/12 for the lattice."""
        return float(self.result["critical_load"][0]) / math.pi**2 - 1.0

    track_critical_load_error.unit = "relative"
