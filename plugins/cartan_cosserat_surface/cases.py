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

Buckling of a plate strip under in-plane compression (the wide column)
--------------------------------------------------------------------------------------------
A rectangular plate L × b loaded along u = L by a dead compressive edge force N per unit width
(:class:`cartan.Free` with ``load = (−1, 0, 0, 0, 0, 0)``, scaled by the continuation's λ = N),
the long edges v = 0, b free, and the loaded edges either

* ``"clamped-free"``: clamped along u = 0 (:class:`cartan.Clamped`), u = L free, or
* ``"pinned"``: both simply supported — w = 0 on both, x held on u = 0, the directors free (the
  soft support, M_uu = 0) — by the continuation's Lagrange pins (:func:`column_pins`; the
  medium's hard penalty supports are loads, which the continuation would scale by λ).

With ν = 0 the cylindrical mode w = w(u) is exact for the plate: the free edges carry no moment
M_vv = D(κ_vv + νκ_uu) = 0 and no twisting moment or shear, and no support restrains a Poisson
expansion, so the pre-buckled state is the uniform uniaxial one for any width.  The plate is
then a column of bending stiffness D = Eh³/12 per unit width with Euler's critical load

    N_E = π²D/(4L²) (clamped–free),   N_E = π²D/L² (pinned)
    (Timoshenko & Gere, *Theory of elastic stability*, §2.1–2.2).

The geometrically exact first-order-shear shell adds the compliance of the transverse shear
and of the stretch of the mid-surface.  For the energy of :mod:`.surface` on a ν = 0 strip in
cylindrical bending, U = ½Eh ε² + ½κ_sGh γ² + ½D(θ₁κ)² per unit width with
ε = ½(θ₁² + θ₃² − 1), γ = θ₃ (θ = Rᵀ∂_u r, κ the rotation rate, θ₁κ the bending measure of
§VI.B), the pre-buckled stretch λ₀ solves ½Eh(λ₀³ − λ₀) = −N, and the second variation of
U + N·x(L) about it (the spatial force is −N e_x everywhere, also in the pinned strip, whose
lateral reactions vanish), minimised over the shear (δγ = −N δφ/(κ_sGh − N/λ₀)), is
∫ Dλ₀²δφ′² − (Nλ₀ + N²/(κ_sGh − N/λ₀)) δφ²: it first vanishes, for δφ = sin(πu/(2L))
(clamped–free) or cos(πu/L) (pinned), at the root N_cr of

    N_E λ₀(N) = N + N²/(λ₀κ_sGh − N),

N_cr = N_E (1 − N_E/(Eh) − N_E/(κ_sGh) + …): Engesser's shear correction N_E/(1 + N_E/(κ_sGh))
to first order, and the shortening of the mid-surface.  At h/L = 0.1 (the registered cases) the
two corrections are −4.91·10⁻³ and −2.06·10⁻³ (clamped–free), −1.94·10⁻² and −8.26·10⁻³ (pinned)
relative, larger than the lattice's error from n = 17 on, so the reference is this root
(:func:`column_critical_load`), not N_E.  The lattice's error is that of the central second
difference of the mode, (k dx)²/12 with k = π/(2L) or π/L: O(dx²).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr
from cartan_verification.case import StaticCase

import cartan
from cartan.problem import ConstantFieldPotential, Problem

from .surface import PenaltySupport

__all__ = ["NavierPlate", "PlateColumnBuckling", "all_cases", "centre_node", "column_critical_load", "column_pins",
           "column_problem", "edge_middle", "navier_plate_problem", "navier_reference", "node_deflection"]

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

    def error(self, ds, problem: Problem) -> float:
        n = problem.grid.shape[0]
        w = -float(ds["position"].values[0][n // 2, n // 2, 2])
        a = problem.grid.length[0]
        q = -problem.loads[0].field[2]
        return abs(w / navier_reference(problem.medium, a, q) - 1.0)


# ---------------------------------------------------------------------------- buckling of a wide column
#: supports of the loaded edges: the factor c of N_E = π²D/(cL²)
COLUMN_ENDS = {"clamped-free": 4.0, "pinned": 1.0}


def _check_ends(ends: str) -> float:
    if ends not in COLUMN_ENDS:
        raise ValueError(f"ends must be one of {', '.join(map(repr, COLUMN_ENDS))}, got {ends!r}")
    return COLUMN_ENDS[ends]


def column_critical_load(medium, length: float, *, ends: str = "clamped-free", shear: bool = True,
                         stretch: bool = True) -> float:
    """First critical edge load per unit width of the plate strip (ν = 0), see the module docstring.

    Parameters
    ----------
    medium : CosseratSurface
        The plate (its ``poisson`` must be 0 for the cylindrical mode to be exact).
    length : float
        L, the distance between the loaded edges (> 0).
    ends : str
        ``"clamped-free"``: N_E = π²D/(4L²); ``"pinned"`` (both loaded edges simply supported,
        the director free): N_E = π²D/L².
    shear, stretch : bool
        Keep the transverse-shear compliance 1/(κ_sGh) and the stretch of the mid-surface
        (both: the root of ``N_E λ₀ = N + N²/(λ₀κ_sGh − N)``); both False: Euler's N_E;
        ``stretch=False``: Engesser's N_E/(1 + N_E/(κ_sGh)).

    Returns
    -------
    float
        N_cr (force per unit width).
    """
    from scipy.optimize import brentq

    c = _check_ends(ends)
    if medium.nu != 0.0:
        raise ValueError(f"poisson must be 0 for the cylindrical buckling mode of a free-edged strip, "
                         f"got {medium.nu!r}")
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"length must be a finite number > 0, got {length!r}")
    n_e = math.pi ** 2 * medium.bending_stiffness / (c * length ** 2)
    kgh = medium.ks * medium.shear_modulus * medium.h if shear else math.inf
    if not stretch:
        return n_e / (1.0 + n_e / kgh)
    eh = medium.E * medium.h

    def stretch_of(n: float) -> float:  # ½Eh(λ₀³ − λ₀) = −N on the stable (λ₀ > 1/√3) branch
        return brentq(lambda s: 0.5 * eh * (s ** 3 - s) + n, 1.0 / math.sqrt(3.0), 1.0, xtol=1e-15, rtol=1e-15)

    def gap(n: float) -> float:
        s = stretch_of(n)
        return n_e * s - n - (n * n / (s * kgh - n) if shear else 0.0)

    return brentq(gap, 1e-3 * n_e, n_e, xtol=1e-16 * n_e, rtol=1e-14)


def column_problem(n: int, *, ends: str = "clamped-free", length: float = 1.0, width: float = 0.25,
                   thickness: float = 0.1, E: float = 1.0, nv: int = 3, name: str = "plate-buckling") -> Problem:
    """The plate strip (ν = 0) under a unit dead compressive edge load along u = L.

    Parameters
    ----------
    n : int
        Nodes along the length (≥ 3).
    ends : str
        ``"clamped-free"``: edge ``u-start`` clamped; ``"pinned"``: ``u-start`` free, to be
        simply supported by the continuation's pins (:func:`column_pins`).
    length, width, thickness, E : float
        L, b, h and Young's modulus (> 0).
    nv : int
        Nodes across the width (≥ 2; the mode is uniform across it).
    name : str
        Problem name.

    Returns
    -------
    Problem
        Edge ``u-end`` free with the load (−1, 0, 0, 0, 0, 0) per unit width (λ = N in a
        continuation), ``v-start``/``v-end`` free.
    """
    _check_ends(ends)
    if int(n) != n or n < 3:
        raise ValueError(f"n must be an integer ≥ 3, got {n!r}")
    if int(nv) != nv or nv < 2:
        raise ValueError(f"nv must be an integer ≥ 2, got {nv!r}")
    med = cartan.medium("cosserat-surface", E=E, poisson=0.0, thickness=thickness)
    grid = cartan.Grid((int(n), int(nv)), length=(length, width))
    bounds = {"u-end": cartan.Free(load=[-1.0, 0.0, 0.0, 0.0, 0.0, 0.0])}
    if ends == "clamped-free":
        bounds["u-start"] = cartan.Clamped()
    return Problem(med, grid, med.initial_state(grid, "flat"), bounds, name=name)


def column_pins(shape: tuple[int, int]) -> dict[int, tuple[int, ...]]:
    """Continuation pins of the simply supported (``"pinned"``) strip on ``shape`` = (n, nv) nodes,
    keyed by flat node index.

    w = 0 on both loaded edges, x held on u = 0 (the reactions of the compression), y held at
    the node (0, 0): the rigid motions are removed and nothing else; the directors are free
    (the soft simple support: M_uu = 0 on the edges).
    """
    n, nv = shape
    pins: dict[int, tuple[int, ...]] = {j: (0, 2) for j in range(nv)}
    pins.update({(n - 1) * nv + j: (2,) for j in range(nv)})
    pins[0] = (0, 1, 2)
    return pins


def node_deflection(d: xr.Dataset, node: int = -1) -> float:
    """Transverse (z) position of the flat ``node`` in a one-frame Dataset (a continuation
    monitor; the strip starts in the plane z = 0, so this is its deflection)."""
    return float(d["position"].isel(time=0, node=node).values[2])


def edge_middle(problem: Problem) -> int:
    """Flat index of the middle node of the loaded edge u = L."""
    nu, nv = problem.grid.shape
    return (nu - 1) * nv + nv // 2


def centre_node(problem: Problem) -> int:
    """Flat index of the node (n // 2, nv // 2)."""
    nu, nv = problem.grid.shape
    return (nu // 2) * nv + nv // 2


class PlateColumnBuckling(StaticCase):
    """Critical load of the plate strip under in-plane compression (see the module docstring):
    L = 1, b = 0.25, h = 0.1, E = 1, ν = 0, n = 8·2^level + 1 nodes along L and 3 across; the
    straight path is followed by :func:`cartan.continuation.continuation` to 1.1 N_E and the
    bifurcation located by the sign change of det K.

    Parameters
    ----------
    ends : str
        ``"clamped-free"`` (:class:`cartan.Clamped` at u = 0) or ``"pinned"`` (both loaded
        edges simply supported by the continuation's pins, :func:`column_pins`).
    name : str
        Registered name.
    """

    medium = "cosserat-surface"
    quantity = "critical edge load per unit width (bifurcation of the straight path)"
    norm = "|N_cr,lattice / N_cr − 1|"
    space_order = 2.0
    levels = (0, 1, 2)
    quick_levels = (0, 1)

    length, width, thickness = 1.0, 0.25, 0.1

    def __init__(self, ends: str = "clamped-free", name: str = "plate-buckling-column"):
        c = _check_ends(ends)
        kind = "clamped–free" if ends == "clamped-free" else "simply supported (pinned) loaded edges, free sides"
        euler = "π²D/(4L²)" if c == 4.0 else "π²D/L²"
        self.__dict__.update(
            ends=ends, name=name,
            description=(f"plate strip, {kind} (ν = 0, h/L = 0.1), under in-plane compression: first critical "
                         f"load by continuation, against Euler's {euler} with the shear and stretch corrections"),
            reference=(f"N_cr: root of N_E λ₀ = N + N²/(λ₀κ_sGh − N), ½Eh(λ₀³ − λ₀) = −N, N_E = {euler} (Euler's "
                       "column, Timoshenko & Gere §2.1–2.2, with the first-order-shear shell's shear and "
                       "mid-surface stretch); N_cr = " + ("0.99305" if c == 4.0 else "0.97270") + " N_E at h/L = 0.1"),
            tolerance=1e-3 if c == 4.0 else 4e-3,
            tolerance_reason=("n = 8·2^level + 1; the error is the mode's (k dx)²/12 with k = π/(2L): 3.21e-3, "
                              "8.02e-4, 2.01e-4 at n = 9, 17, 33 (measured); the bound holds from n = 17 on"
                              if c == 4.0 else
                              "n = 8·2^level + 1; the error is the mode's (k dx)²/12 with k = π/L: 1.28e-2, "
                              "3.19e-3, 7.97e-4 at n = 9, 17, 33 (measured); the bound holds from n = 17 on"),
        )

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        prob = column_problem(8 * 2 ** level + 1, ends=self.ends, length=self.length, width=self.width,
                              thickness=self.thickness, name=self.name)
        n_e = column_critical_load(prob.medium, self.length, ends=self.ends, shear=False, stretch=False)
        settings = {"lam_max": 1.1 * n_e, "ds0": 0.3, "lam_scale": n_e, "branch_switch": False}
        if self.ends == "pinned":
            settings["pins"] = column_pins(prob.grid.shape)
        return prob, settings

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        from cartan.continuation import continuation

        node = edge_middle(problem) if self.ends == "clamped-free" else centre_node(problem)
        monitor = functools.partial(node_deflection, node=node)
        return continuation(problem, monitor=monitor, **dict(settings))

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        kinds = [str(k) for k in ds["critical_kind"].values]
        if "bifurcation" not in kinds:
            return math.inf
        n_cr = float(ds["critical_load"].values[kinds.index("bifurcation")])
        return abs(n_cr / column_critical_load(problem.medium, problem.grid.length[0], ends=self.ends) - 1.0)


#: the registered cases
CASES = [NavierPlate(0.1, "plate-navier-thick"), NavierPlate(0.001, "plate-navier-thin"),
         PlateColumnBuckling("clamped-free", "plate-buckling-column"),
         PlateColumnBuckling("pinned", "plate-buckling-wide-column")]


def all_cases() -> list:
    """The cases this plugin registers."""
    return list(CASES)
