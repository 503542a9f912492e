"""Verification of the pressure load of the ``cosserat-surface`` medium (registered by the plugin).

A closed circular cylinder under internal pressure
--------------------------------------------------
A cylinder of radius R on the arclength chart (u around, periodic, n nodes; v along the axis,
periodic with the holonomy a translation by L, so that the axial strain is zero: the plane
strain of a long tube), rest shape the ``"cylinder"`` initial state with the medium's constant
rest strain ``rest_curvature = (1/R, 0)``, under the :class:`~cartan_cosserat_surface.surface.Pressure`
p > 0 (outward).  The rigid motions are removed by springs on components that a uniform
inflation leaves unchanged (:class:`NodeSprings`: the tangential and axial positions of three
nodes), which therefore carry no force at the equilibrium.

**Exact homogeneous equilibrium of this medium.**  A uniform inflation R → R' = λR keeps the
director normal and the frames turning at 1/R per unit chart length: θ_u = (λ, 0, 0),
π_u = (0, 1/R, 0), θ_v = (0, 1, 0), π_v = 0.  The membrane strain is ε_uu = (λ² − 1)/2 (ε_vv =
ε_uv = 0), the bending measure κ_uu = θ_u1 π_u2 − 1/R = (λ − 1)/R, the transverse shear 0; with
the energy of :mod:`.surface` the hoop force and moment are n = Eh/(1 − ν²)·(λ² − 1)/2 and
m = D(λ − 1)/R, the body-frame hoop stress F₁ = nλ + m/R, and the radial balance of the
ring, F₁/R = pλ (the pressure per unit chart area is p|r_u × r_v| = pλ), gives

    p(λ) = Eh(λ² − 1)/(2(1 − ν²)R) + D(λ − 1)/(λR³)          (any λ > 0, exact),

increasing in λ (no limit point): :func:`inflation_pressure`, inverted by
:func:`inflation_stretch`.  Linearised, λ = 1 + w/R:

    w = (1 − ν²)pR²/(Eh) · 1/(1 + h²/(12R²)),

the membrane formula of the thin tube in plane strain, (1 − ν²)pR²/(Eh), stiffened by the
bending of the wall (D/R⁴ against Eh/((1 − ν²)R²), relative h²/(12R²)).

**The lattice.**  A uniformly inflated polygon of n nodes (frames rotated by φ = 2π/n from node
to node) has edge logarithms θ_u = (λ, 0, 0), π_u = (0, 1/R, 0) exactly — the orbit of a
constant twist — so its discrete energy is the continuum's, 2πRL·U(λ).  The central difference
of the positions gives |r_u| = R' sin φ/du, so the pressure's nodal forces are those of
p·sin φ/φ on the circle: their virtual work on a uniform inflation is p times the change of the
polygon's area (n/2)R'² sin φ.  By symmetry the uniform state is an equilibrium of the lattice,
and its stretch is **exactly** the continuum's at the pressure p·sin φ/φ:

    λ_lattice(p, n) = λ(p sin φ/φ),   φ = 2π/n,

an exact check of the lattice at any load (met to the solver's tolerance, 1e-13 measured), and
its error against the continuum is O(φ²) = O(du²): relative to w, (1 − sin φ/φ)·p/(w dp/dw)
→ φ²/6 in the linear range.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr
from cartan_verification.case import StaticCase

import cartan
from cartan.problem import InitialState, Problem

from .surface import NodeSprings, Pressure

__all__ = ["CylinderInflation", "NodeSprings", "all_cases", "closed_cylinder_problem", "inflation_pressure",
           "inflation_stretch", "mean_stretch", "polygon_factor"]


def inflation_pressure(medium, radius: float, stretch: float) -> float:
    """p(λ) = Eh(λ² − 1)/(2(1 − ν²)R) + D(λ − 1)/(λR³): the pressure holding a closed cylinder of
    ``medium`` (rest radius R) uniformly inflated to λR at zero axial strain (module docstring)."""
    E, nu, h, D = medium.E, medium.nu, medium.h, medium.bending_stiffness
    lam, R = float(stretch), float(radius)
    return E * h * (lam * lam - 1.0) / (2.0 * (1.0 - nu * nu) * R) + D * (lam - 1.0) / (lam * R ** 3)


def inflation_stretch(medium, radius: float, pressure: float) -> float:
    """The hoop stretch λ with :func:`inflation_pressure` (λ) = ``pressure`` (bisection to round-off)."""
    lo, hi = 1e-3, 1.0
    while inflation_pressure(medium, radius, hi) < pressure:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if inflation_pressure(medium, radius, mid) < pressure:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def polygon_factor(n: int) -> float:
    """sin φ/φ with φ = 2π/n: the lattice's pressure on a uniformly inflated n-gon relative to p."""
    phi = 2.0 * math.pi / n
    return math.sin(phi) / phi


def closed_cylinder_problem(n: int, pressure: float, *, radius: float = 1.0, length: float = 1.0, n_axial: int = 3,
                            E: float = 1.0, poisson: float = 0.3, thickness: float = 0.05) -> Problem:
    """The closed cylinder under internal pressure on ``n × n_axial`` nodes (module docstring).

    Parameters
    ----------
    n : int
        Nodes around (a multiple of 4 ≥ 8).
    pressure : float
        p (> 0 inflates).
    radius, length : float
        R and the axial period L.
    n_axial : int
        Nodes along the (periodic) axis, ≥ 3.
    E, poisson, thickness : float
        The medium's parameters.

    Returns
    -------
    Problem
        Loads ``[Pressure, NodeSprings]``; the initial state the rest cylinder.
    """
    if n < 8 or n % 4:
        raise ValueError(f"n must be a multiple of 4, ≥ 8, got {n!r}")
    med = cartan.medium("cosserat-surface", E=E, poisson=poisson, thickness=thickness,
                        rest_curvature=(1.0 / radius, 0.0))
    grid = cartan.Grid((n, n_axial), length=(2.0 * math.pi * radius, length), periodic=(True, True))
    Phi = med.initial_state(grid, "cylinder").Phi
    H = np.eye(4)
    H[2, 0] = length  # Φ(v + L) = H Φ(v): a translation by L along the axis (y)
    # the tangential positions of the nodes at 0, π/2, π and the axial one at 0 (a uniform inflation keeps them)
    springs = [((0, 0), 0), ((0, 0), 1), ((n // 4, 0), 2), ((n // 2, 0), 0)]
    anchor = NodeSprings(Phi, springs, 1e3 * E * thickness / grid.spacing[0] ** 2)
    return Problem(med, grid, InitialState(Phi=Phi, holonomy={1: H}),
                   loads=[Pressure(pressure, grid, holonomy={1: H}), anchor], name="cylinder-pressure")


def mean_stretch(ds: xr.Dataset, problem: Problem) -> float:
    """Mean distance of the nodes from the cylinder's axis over the rest radius, λ = R'/R."""
    R = 1.0 / problem.medium.k0[0]
    x = ds["position"].values[-1]
    return float(np.mean(np.hypot(x[..., 0], x[..., 2] + R))) / R


class CylinderInflation(StaticCase):
    """A closed cylinder under internal pressure (module docstring): R = 1, L = 1, h = 0.05, E = 1,
    ν = 0.3, n = 8·2^level nodes around, 3 along the periodic axis; ``solve_static`` from rest.

    ``stretch`` sets the load: p = :func:`inflation_pressure` (λ) for the continuum hoop stretch λ;
    ``linear`` compares with the linear formula w = (1 − ν²)pR²/(Eh)/(1 + h²/(12R²)) (use λ − 1
    ≪ the lattice's error), otherwise with the exact homogeneous λ."""

    medium = "cosserat-surface"
    quantity = "radial displacement w = R' − R of the uniformly inflated cylinder"
    norm = "|w − w_ref| / w_ref"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    quick_levels = (1, 2)
    tolerance = 1e-2
    tolerance_reason = ("n = 8·2^level around; the lattice's error is that of the pressure p·sin φ/φ it applies "
                        "(φ = 2π/n), 1 − sin φ/φ → φ²/6: 2.55e-2, 6.41e-3 at n = 16, 32 linear, 2.26e-2, 5.68e-3 at "
                        "λ = 1.31 (measured); the bound holds from n = 32 on")

    def __init__(self, stretch: float, name: str, linear: bool):
        self.__dict__.update(stretch=float(stretch), name=name, linear=bool(linear))
        kind = "linear range" if linear else f"finite inflation λ = {stretch:g}"
        self.__dict__["description"] = (f"closed cylinder under internal pressure (follower, normal to the deformed "
                                        f"surface), zero axial strain, {kind}")
        self.__dict__["reference"] = (
            "w = (1 − ν²)pR²/(Eh)/(1 + h²/(12R²)), the linear plane-strain tube with the wall's bending" if linear
            else "the exact homogeneous equilibrium of this medium, p = Eh(λ² − 1)/(2(1 − ν²)R) + D(λ − 1)/(λR³) "
                 "(module docstring of cartan_cosserat_surface.cases_pressure)")

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        med = cartan.medium("cosserat-surface", thickness=0.05, rest_curvature=(1.0, 0.0))
        p = inflation_pressure(med, 1.0, self.stretch)
        return closed_cylinder_problem(8 * 2 ** level, p), {"tol": 1e-10}

    def error(self, ds, problem: Problem) -> float:
        med, R = problem.medium, 1.0 / problem.medium.k0[0]
        p = problem.loads[0].pressure
        w = (mean_stretch(ds, problem) - 1.0) * R
        if self.linear:
            ref = (1.0 - med.nu ** 2) * p * R ** 2 / (med.E * med.h) / (1.0 + med.h ** 2 / (12.0 * R ** 2))
        else:
            ref = (inflation_stretch(med, R, p) - 1.0) * R
        return abs(w / ref - 1.0)


#: the registered cases
CASES = [CylinderInflation(1.0 + 1e-7, "shell-cylinder-pressure", linear=True),
         CylinderInflation(1.3, "shell-cylinder-inflation", linear=False)]


def all_cases() -> list:
    """The cases this module registers."""
    return list(CASES)
