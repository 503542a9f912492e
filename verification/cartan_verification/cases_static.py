"""Static verification cases of the Cosserat rods (VERIFICATION.md §4, cosserat-rod rows):
equilibria by Newton's method on the group (:func:`cartan.statics.solve_static`) and load
paths by pseudo-arclength continuation (:func:`cartan.continuation.continuation`).

Their "integrator" is ``"newton"`` and they are refined in space (:class:`StaticCase`); the
references are in :mod:`cartan_verification.references`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

import cartan

from .case import StaticCase
from .references import (
    cantilever_elastica,
    cantilever_exact_tip,
    euler_critical_load,
    pinned_elastica,
    timoshenko_linear_tip,
)

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["CantileverElastica", "EulerBuckling", "TimoshenkoCantilever"]


# ---------------------------------------------------------------------------- Timoshenko cantilever
class TimoshenkoCantilever(StaticCase):
    """Timoshenko cantilever (VERIFICATION.md §4): L = 3, radius 0.25, E = 1e6, G = 1e4,
    α_c = 27/28 (PyElastica's shear coefficient, the ``cosserat-rod`` default), ρ = 5000,
    dead tip force F = 15 along −z, clamped at s = 0; ``solve_static`` from the straight rod.

    Reference: the geometrically exact tip deflection of the Simo–Reissner rod (stretch, shear
    and bending), w = 0.0677484208 (:func:`~cartan_verification.references.cantilever_exact_tip`:
    shooting on the planar boundary-value problem, DOP853 to 1e-13 and Brent's method on the
    root moment).  It lies 3.23e-4 below the linear Timoshenko value
    FL/(α_cGA) + FL³/(3EI) = 0.0677703 (the geometric nonlinearity).  The lattice error is
    O(h²): n = 12·2^level + 1 nodes.
    """

    name = "rod-timoshenko-static"
    medium = "cosserat-rod"
    description = "Timoshenko cantilever under a tip force: geometrically exact tip deflection"
    reference = ("geometrically exact (Simo–Reissner) tip deflection 0.0677484 by shooting on the planar "
                 "boundary-value problem (DOP853, rtol 1e-13); the linear Timoshenko FL/(α_cGA) + FL³/(3EI) = "
                 "0.0677703 is 3.2e-4 above it; α_c = 27/28")
    quantity = "tip deflection −z(L) of the equilibrium"
    norm = "|w − w_exact| / w_exact"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    tolerance = 1e-4
    tolerance_reason = ("n = 12·2^level + 1; the O(h²) error is 1.8e-5 at n = 97 (measured), 7.0e-5 at n = 49; "
                        "the bound 1e-4 is the one asked at n ≤ 200")

    length, radius, E, G, density, force = 3.0, 0.25, 1e6, 1e4, 5000.0, 15.0
    shear_coefficient = 27.0 / 28.0

    def medium_obj(self):
        return cartan.medium("cosserat-rod", E=self.E, G=self.G, radius=self.radius, density=self.density,
                             shear_coefficient=self.shear_coefficient)

    def stiffnesses(self) -> dict[str, float]:
        """EA, α_cGA, EI of the rod."""
        A = math.pi * self.radius**2
        return {"EA": self.E * A, "shear_stiffness": self.shear_coefficient * self.G * A,
                "EI": self.E * math.pi * self.radius**4 / 4.0}

    def exact(self) -> float:
        """The geometrically exact tip deflection."""
        return _timoshenko_exact(self.length, self.force, **self.stiffnesses())

    def linear(self) -> float:
        """The linear Timoshenko tip deflection."""
        k = self.stiffnesses()
        return timoshenko_linear_tip(self.length, self.force, k["EI"], k["shear_stiffness"])

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = self.medium_obj()
        grid = cartan.Grid(12 * 2**level + 1, length=self.length)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, 0.0, -self.force, 0, 0, 0])},
                              name=self.name)
        return prob, {"tol": 1e-10}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        from cartan.statics import solve_static

        return solve_static(problem, **dict(settings))

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        tip = -float(ds["position"].isel(time=-1, node=-1).values[2])
        exact = self.exact()
        return abs(tip - exact) / exact


@functools.lru_cache(maxsize=8)
def _timoshenko_exact(length, force, EA, shear_stiffness, EI) -> float:
    return cantilever_exact_tip(length, force, EI, EA, shear_stiffness)[0]


# ---------------------------------------------------------------------------- planar rods for the elastica
def _planar_rod(stiff: float):
    """Planar rod with B = 1 and stretch and shear stiffness ``stiff`` × B/L² (L = 1)."""
    return cartan.medium("planar-cosserat-rod", stretch_shear=[stiff, stiff], bending=1.0, mass=1.0,
                         rotational_inertia=1.0)


# ---------------------------------------------------------------------------- Euler buckling
class EulerBuckling(StaticCase):
    """Euler buckling of a pinned–pinned column (VERIFICATION.md §4): planar rod, L = 1, B = 1,
    stretch and shear stiffness 1e7·B/L² (the inextensible, unshearable limit: the axial strain
    P/EA ≤ 1.5e-6 on the path), an axial dead load λ at the end; the ends are pinned by the
    continuation's Lagrange multipliers (start: x and y held, end: y held, rotations free).

    The path is followed by pseudo-arclength continuation from λ = 0 to 1.5 π²B/L²: the
    bifurcation is located on the straight branch (sign change of det K) and the path switches
    to the buckled branch.  References: P_cr = π²B/L² (Euler) and, at the last point
    (P/P_cr = 1.5), the pinned–pinned elastica (:func:`~cartan_verification.references.
    pinned_elastica`: Love §263) for the midspan deflection w/L = k/K(k) = 0.394288 and the end
    shortening Δ/L = 2(1 − E(k)/K(k)) = 0.636412.  The error is the largest of the three
    relative errors, each O(h²) (the critical load's is π²h²/12 to 0.2 %); n = 10·2^level + 1.
    """

    name = "rod-euler-buckling"
    medium = "planar-cosserat-rod"
    description = "pinned–pinned Euler buckling: P_cr = π²B/L² and the post-buckled elastica at P = 1.5 P_cr"
    reference = ("P_cr = π²B/L² (Euler); post-buckled pinned–pinned elastica P/P_cr = (2K(k)/π)², w/L = k/K(k), "
                 "Δ/L = 2(1 − E(k)/K(k)) (Love §263) at P/P_cr = 1.5: w/L = 0.394288, Δ/L = 0.636412")
    quantity = "critical load of the straight branch; midspan deflection and end shortening at P = 1.5π²B/L²"
    norm = "max of |P_cr/(π²B/L²) − 1|, |w/w_el − 1|, |Δ/Δ_el − 1|"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    tolerance = 1e-3
    tolerance_reason = ("n = 10·2^level + 1; at n = 81 the O(h²) errors are 1.29e-4 (P_cr: π²h²/12), 5.8e-5 "
                        "(w) and 2.6e-4 (Δ) (measured); P_cr is asked within 1e-3")

    stiff, load_ratio, ds0 = 1e7, 1.5, 0.05

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = _planar_rod(self.stiff)
        n = 10 * 2**level + 1
        grid = cartan.Grid(n, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Free(), "end": cartan.Free(load=[-1.0, 0.0, 0.0])}, name=self.name)
        return prob, {"lam_max": self.load_ratio * euler_critical_load(1.0, 1.0), "ds0": self.ds0,
                      "pins": {"start": (0, 1), "end": (1,)}}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        from cartan.continuation import continuation

        mid = problem.grid.shape[0] // 2
        return continuation(problem, monitor=functools.partial(_node_component, node=mid, row=1), **dict(settings))

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        """The three relative errors (``inf`` when no bifurcation was found or the path did not
        reach the buckled branch)."""
        p_euler = euler_critical_load(1.0, 1.0)
        kinds = [str(k) for k in ds["critical_kind"].values]
        if "bifurcation" not in kinds or int(ds["branch"].values[-1]) != 1:
            return {"critical_load": math.inf, "deflection": math.inf, "shortening": math.inf}
        p_cr = float(ds["critical_load"].values[kinds.index("bifurcation")])
        ratio = float(ds["load_factor"].values[-1]) / p_euler
        w_ref, s_ref = pinned_elastica(ratio)
        pos = ds["position"].isel(path=-1).values
        w = abs(float(ds["monitor"].values[-1]))
        shortening = 1.0 - (pos[-1, 0] - pos[0, 0])
        return {"critical_load": abs(p_cr / p_euler - 1.0), "deflection": abs(w / w_ref - 1.0),
                "shortening": float(abs(shortening / s_ref - 1.0))}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return float(max(self.parts(ds).values()))


def _node_component(d: xr.Dataset, node: int, row: int, sign: float = 1.0) -> float:
    """Position component ``row`` of ``node`` in a one-frame Dataset (a continuation monitor)."""
    return sign * float(d["position"].isel(time=0, node=node, row=row))


# ---------------------------------------------------------------------------- cantilever elastica
class CantileverElastica(StaticCase):
    """Cantilever elastica under a dead tip load (VERIFICATION.md §4): planar rod clamped at
    s = 0, L = 1, B = 1, stretch and shear stiffness 1e7·B/L² (inextensible, unshearable limit:
    P/EA ≤ 1e-6), tip force α·B/L² along −y followed by continuation from 0 to α = 10 with
    points placed on α = 1 and 2 (``stops``).

    Reference: the inextensible elastica in elliptic integrals (Bisshopp & Drucker 1945,
    :func:`~cartan_verification.references.cantilever_elastica`): tip vertical/L = 0.301721,
    0.493457, 0.810609 and shortening/L = 0.056433, 0.160642, 0.554996 for α = 1, 2, 10 (the
    tabulated five digits of VERIFICATION.md §4 to round-off).  The lattice error is O(h²);
    n = 10·2^level + 1.
    """

    name = "rod-cantilever-elastica"
    medium = "planar-cosserat-rod"
    description = "cantilever elastica under a tip dead load, PL²/B = 1, 2, 10"
    reference = ("inextensible elastica in elliptic integrals (Bisshopp & Drucker 1945): tip vertical/L = 0.301721, "
                 "0.493457, 0.810609, shortening/L = 0.056433, 0.160642, 0.554996 for PL²/B = 1, 2, 10")
    quantity = "tip vertical deflection and shortening at PL²/B = 1, 2, 10 on one continuation path"
    norm = "max over the three loads of |v − v_el| and |Δ − Δ_el|, in units of L"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    tolerance = 1e-4
    tolerance_reason = ("n = 10·2^level + 1; the O(h²) error is 2.5e-5 at n = 81 (α = 10, tip vertical; "
                        "measured), 1.0e-4 at n = 41; 1e-4 is the bound asked")

    stiff, loads, ds0 = 1e7, (1.0, 2.0, 10.0), 0.1

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = _planar_rod(self.stiff)
        grid = cartan.Grid(10 * 2**level + 1, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -1.0, 0.0])}, name=self.name)
        return prob, {"lam_max": max(self.loads), "ds0": self.ds0, "stops": list(self.loads[:-1]), "detect": False}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        from cartan.continuation import continuation

        return continuation(problem, monitor=functools.partial(_node_component, node=-1, row=1, sign=-1.0),
                            **dict(settings))

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        """``{"vertical α", "shortening α"}``: the signed errors at each load (in units of L)."""
        lam = ds["load_factor"].values
        out = {}
        for alpha in self.loads:
            i = int(np.argmin(np.abs(lam - alpha)))
            if abs(lam[i] - alpha) > 1e-9 * alpha:
                out[f"vertical {alpha:g}"] = out[f"shortening {alpha:g}"] = math.inf
                continue
            v_ref, s_ref = cantilever_elastica(alpha)
            out[f"vertical {alpha:g}"] = float(ds["monitor"].values[i]) - v_ref
            out[f"shortening {alpha:g}"] = 1.0 - float(ds["position"].isel(path=i, node=-1, row=0)) - s_ref
        return out

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return float(max(abs(v) for v in self.parts(ds).values()))
