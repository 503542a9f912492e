"""Verification cases of the ``cosserat-surface`` medium (registered by the plugin).

Simply supported square plate under a uniform load (Navier's series for the Mindlin plate)
--------------------------------------------------------------------------------------------
A square plate of side a, hard simple supports on all four edges (w = 0, the director held
along each edge, free to turn about it; in-plane displacements held), uniform dead load q.
The Mindlin (first-order shear) plate's centre deflection splits into the Kirchhoff part and
the shear part of the Marcus moment M = (M_xx + M_yy)/(1 + ν), both from Navier's double sine
series (Timoshenko & Woinowsky-Krieger §30; Wang, Reddy & Lee, *Shear deformable beams and
plates*, §2):

    w_c = 0.00406235·qa⁴/D + 0.0736714·qa²/(κGh).

The load is small (w_c = 10⁻⁶ h), so the geometrically exact shell is in its linear range (the
von Kármán coupling is O((w/h)²) = 10⁻¹²).  The supports are :class:`PenaltySupport` with
stiffnesses 10⁶ times the plate's own at the grid scale (κGh/dx², Eh/dx², D/dx²); the
deflection changes by 2.5·10⁻⁷ relative when they grow 100-fold (measured at n = 9), far below
the lattice's O(dx²) error.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from cartan_verification.case import StaticCase

import cartan
from cartan.problem import ConstantFieldPotential, Problem

from .surface import PenaltySupport

__all__ = ["NavierPlate", "all_cases", "navier_plate_problem", "navier_reference"]

#: Navier coefficients of the simply supported square Mindlin plate (centre deflection)
KIRCHHOFF_COEFFICIENT = 0.00406235
MARCUS_COEFFICIENT = 0.0736714


def navier_reference(medium, a: float, q: float) -> float:
    """Centre deflection ``0.00406235 qa⁴/D + 0.0736714 qa²/(κGh)`` of the plate ``medium``."""
    kGh = medium.ks * medium.shear_modulus * medium.h
    return q * (KIRCHHOFF_COEFFICIENT * a ** 4 / medium.bending_stiffness + MARCUS_COEFFICIENT * a ** 2 / kGh)


def navier_plate_problem(n: int, thickness_ratio: float, *, a: float = 1.0, E: float = 1.0, poisson: float = 0.3,
                         penalty: float = 1e6, deflection: float = 1e-6) -> tuple[Problem, float]:
    """The simply supported square plate on an ``n × n`` lattice.

    Parameters
    ----------
    n : int
        Nodes per side (≥ 3, odd for a centre node).
    thickness_ratio : float
        h/a.
    a, E, poisson : float
        Side, Young's modulus, Poisson ratio.
    penalty : float
        Support stiffness relative to the plate's at the grid scale.
    deflection : float
        Target centre deflection w_c/h (sets q).

    Returns
    -------
    (Problem, float)
        The problem and the reference centre deflection w_c.
    """
    if n < 3 or n % 2 == 0:
        raise ValueError(f"n must be an odd integer ≥ 3, got {n!r}")
    h = float(thickness_ratio) * a
    med = cartan.medium("cosserat-surface", E=E, poisson=poisson, thickness=h)
    q = deflection * h / navier_reference(med, a, 1.0)
    grid = cartan.Grid((n, n), length=(a, a))
    init = med.initial_state(grid, "flat")
    dx = a / (n - 1)
    kGh = med.ks * med.shear_modulus * h
    support = PenaltySupport(position_stiffness=penalty * np.array([E * h, E * h, kGh]) / dx ** 2,
                             director_stiffness=penalty * med.bending_stiffness / dx ** 2).hold(init.Phi)
    loads = [ConstantFieldPotential(np.array([0.0, 0.0, -q]), 1.0), support]
    return Problem(med, grid, init, loads=loads, name="plate-navier"), navier_reference(med, a, q)


class NavierPlate(StaticCase):
    """Simply supported square Mindlin plate under a uniform load (see the module docstring);
    n = 8·2^level + 1 nodes per side, ``solve_static`` from the flat plate."""

    medium = "cosserat-surface"
    reference = ("Navier series of the hard simply supported square Mindlin plate: w_c = 0.00406235 qa⁴/D + "
                 "0.0736714 qa²/(κGh) (Timoshenko & Woinowsky-Krieger §30; Wang, Reddy & Lee §2)")
    quantity = "centre deflection of the equilibrium"
    norm = "|w_c − w_ref| / w_ref"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    quick_levels = (0, 1)
    tolerance = 1e-2
    tolerance_reason = ("n = 8·2^level + 1; the O(dx²) error is 2.18e-2, 5.43e-3, 1.35e-3 at n = 9, 17, 33 for "
                        "h/a = 0.1 and 2.22e-2, 5.55e-3, 1.38e-3 for h/a = 0.001 (measured); the bound holds from "
                        "n = 17 on")

    def __init__(self, thickness_ratio: float, name: str):
        self.__dict__["thickness_ratio"] = float(thickness_ratio)
        self.__dict__["name"] = name
        self.__dict__["description"] = (f"simply supported square plate, uniform load, h/a = {thickness_ratio:g}: "
                                        "Mindlin centre deflection (no shear locking)")

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        prob, _ = navier_plate_problem(8 * 2 ** level + 1, self.thickness_ratio)
        return prob, {"tol": 1e-10}

    def solve(self, problem: Problem, settings: Mapping[str, Any]):
        return cartan.solve_static(problem, **dict(settings))

    def error(self, ds, problem: Problem) -> float:
        n = problem.grid.shape[0]
        w = -float(ds["position"].values[0][n // 2, n // 2, 2])
        a = problem.grid.length[0]
        q = -problem.loads[0].field[2]
        return abs(w / navier_reference(problem.medium, a, q) - 1.0)


#: the registered cases
CASES = [NavierPlate(0.1, "plate-navier-thick"), NavierPlate(0.001, "plate-navier-thin")]


def all_cases() -> list:
    """The cases this plugin registers."""
    return list(CASES)
