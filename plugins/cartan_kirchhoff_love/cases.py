"""Verification cases of the ``kirchhoff-love`` medium (registered by the plugin), and the
cross-medium limit of the Cosserat surface (:func:`cosserat_limit`).

Simply supported square Kirchhoff plate under a uniform load (Navier's series)
--------------------------------------------------------------------------------
A square plate of side a, hard simple supports on all four edges (w = 0, the normal held
along each edge, free to turn about it; in-plane displacements held), uniform dead load q,
ν = 0.3.  Navier's double sine series of the Kirchhoff plate (Timoshenko & Woinowsky-Krieger,
*Theory of plates and shells*, §30, Table 8) gives the centre deflection and the centre
bending moment

    w_c = 0.00406235·qa⁴/D,        M_c = M_x = M_y = 0.0478864·qa²    (ν = 0.3).

The problem is the one of the ``cosserat-surface`` Navier cases
(:func:`cartan_cosserat_surface.cases.navier_plate_problem`: the same lattice, load and
:class:`~cartan_cosserat_surface.surface.PenaltySupport`) with the Kirchhoff–Love medium in
place of the Cosserat surface: the load is small (w_c ≈ 10⁻⁶h, the geometrically exact shell
in its linear range) and the supports are 10⁶ times as stiff as the plate at the grid scale.
The moment is read from the node fields: with b_αβ = ∂_α r·∂_β e₃ and e₃ = +z, a plate
sagging under the load has m^uu < 0, and the engineering moment is M_x = −m^uu.

The lattice's error is O(dx²) in both (measured below, and recorded by the tests).

Buckling of a plate strip under in-plane compression (the wide column)
-----------------------------------------------------------------------
The clamped–free strip of the ``cosserat-surface`` case ``plate-buckling-column`` (L = 1,
b = 0.25, h = 0.1, E = 1, ν = 0, :func:`cartan_cosserat_surface.cases.column_problem`) with the
Kirchhoff–Love medium, followed by :func:`cartan.continuation.continuation`.  Without transverse
shear the critical load is the root of N_E λ₀(N) = N, ½Eh(λ₀³ − λ₀) = −N (Euler's
N_E = π²D/(4L²) with the shortening of the mid-surface:
:func:`~cartan_cosserat_surface.cases.column_critical_load` with ``shear=False``), 2.06·10⁻³
below N_E at h/L = 0.1.  The lattice's error is the mode's (k dx)²/12, k = π/(2L): O(dx²).
This case exercises the constrained strains in the continuation (the pre-buckled path is flat,
the bifurcation is located by the sign change of det of the saddle-point Jacobian).

Cross-medium limit
------------------
:func:`cosserat_limit`: the same plate as a ``cosserat-surface`` whose transverse shear
stiffness κ_sGh is scaled by a ratio → ∞, against the ``kirchhoff-love`` plate on the same
lattice.  On the lattice the shear energy ½κ_sGh Σ θ_e,3² over the edges is the penalty form of
the Kirchhoff–Love constraint θ_e,3 = 0, so the difference is O(1/ratio) at any resolution.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr
from cartan_cosserat_surface.cases import PlateColumnBuckling, column_critical_load, navier_plate_problem
from cartan_verification.case import StaticCase

import cartan
from cartan.problem import Problem

__all__ = ["DEFLECTION_COEFFICIENT", "MOMENT_COEFFICIENT", "NavierPlateKL", "PlateColumnBucklingKL", "all_cases",
           "centre_values", "cosserat_limit", "kirchhoff_navier_problem", "kirchhoff_reference"]

#: Navier coefficients of the simply supported square Kirchhoff plate, ν = 0.3
DEFLECTION_COEFFICIENT = 0.00406235
MOMENT_COEFFICIENT = 0.0478864


def kirchhoff_reference(medium, a: float, q: float) -> tuple[float, float]:
    """(w_c, M_c) = (0.00406235 qa⁴/D, 0.0478864 qa²) of the plate ``medium`` (ν = 0.3)."""
    return DEFLECTION_COEFFICIENT * q * a ** 4 / medium.bending_stiffness, MOMENT_COEFFICIENT * q * a ** 2


def kirchhoff_navier_problem(n: int, thickness_ratio: float = 0.01, *, medium: Any = None,
                             **options: Any) -> Problem:
    """The simply supported square plate on an ``n × n`` lattice with a Kirchhoff–Love medium.

    Parameters
    ----------
    n : int
        Nodes per side (odd, ≥ 3).
    thickness_ratio : float
        h/a.
    medium : Medium, optional
        The medium to solve (default ``kirchhoff-love`` with E = 1, ν = 0.3, h = thickness_ratio·a):
        any surface medium of the same thickness (the cross-medium limit passes a Cosserat surface).
    **options
        ``a``, ``E``, ``poisson``, ``penalty``, ``deflection`` of
        :func:`cartan_cosserat_surface.cases.navier_plate_problem`.

    Returns
    -------
    Problem
        Named ``"plate-navier-kl"``; ``problem.loads[0]`` is the uniform load (0, 0, −q).
    """
    base, _ = navier_plate_problem(n, thickness_ratio, **options)
    if medium is None:
        medium = cartan.medium("kirchhoff-love", E=base.medium.E, poisson=base.medium.nu, thickness=base.medium.h)
    return Problem(medium, base.grid, base.initial, loads=base.loads, name="plate-navier-kl")


def centre_values(ds: xr.Dataset, problem: Problem) -> tuple[float, float]:
    """(w_c, M_c) of a static solution: the downward deflection of the centre node and the
    engineering moment M_x = −m^uu there (NaN when the medium has no ``bending_moment_uu``)."""
    n = problem.grid.shape[0]
    w = -float(ds["position"].values[0][n // 2, n // 2, 2])
    m = -float(ds["bending_moment_uu"].values[0][n // 2, n // 2]) if "bending_moment_uu" in ds else float("nan")
    return w, m


class NavierPlateKL(StaticCase):
    """Simply supported square Kirchhoff plate under a uniform load (see the module docstring):
    h/a = 0.01, n = 8·2^level + 1 nodes per side, ``solve_static`` from the flat plate; the
    error is the larger of the relative centre deflection and centre moment errors."""

    name = "plate-navier-kl"
    medium = "kirchhoff-love"
    description = ("Kirchhoff–Love plate, simply supported square, uniform load, ν = 0.3: centre deflection and "
                   "moment (transverse shear held at zero by the constraints)")
    reference = ("Navier series of the simply supported square Kirchhoff plate, ν = 0.3: w_c = 0.00406235 qa⁴/D, "
                 "M_c = 0.0478864 qa² (Timoshenko & Woinowsky-Krieger §30, Table 8)")
    quantity = "centre deflection and centre bending moment of the equilibrium"
    norm = "max(|w_c/w_ref − 1|, |M_c/M_ref − 1|)"
    space_order = 2.0
    levels = (0, 1, 2)
    quick_levels = (0, 1)
    tolerance = 1e-2
    tolerance_reason = ("n = 8·2^level + 1; the O(dx²) errors are, for w_c, 2.22e-2, 5.55e-3, 1.38e-3, 3.46e-4 "
                        "and, for M_c, 1.66e-2, 4.12e-3, 1.03e-3, 2.57e-4 at n = 9, 17, 33, 65 (measured); the "
                        "bound holds from n = 17 on")
    thickness_ratio = 0.01

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        return kirchhoff_navier_problem(8 * 2 ** level + 1, self.thickness_ratio), {"tol": 1e-10}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        return cartan.solve_static(problem, **dict(settings))

    def parts(self, ds: xr.Dataset, problem: Problem) -> dict[str, float]:
        """Relative errors of the centre deflection and moment, and the constraint residual."""
        q = -float(problem.loads[0].field[2])
        w_ref, m_ref = kirchhoff_reference(problem.medium, problem.grid.length[0], q)
        w, m = centre_values(ds, problem)
        return {"deflection": abs(w / w_ref - 1.0), "moment": abs(m / m_ref - 1.0),
                "constraint residual": float(ds.attrs["constraint_residual_max"])}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        parts = self.parts(ds, problem)
        return max(parts["deflection"], parts["moment"])


# ---------------------------------------------------------------------------- buckling of a wide column
class PlateColumnBucklingKL(PlateColumnBuckling):
    """Critical load of the clamped–free plate strip with the Kirchhoff–Love medium (see the
    module docstring): the problem of ``plate-buckling-column`` with the medium swapped, and the
    reference without the transverse-shear compliance."""

    medium = "kirchhoff-love"
    levels = (0, 1, 2)
    quick_levels = (0, 1)

    def __init__(self) -> None:
        super().__init__("clamped-free", "plate-buckling-column-kl")
        self.__dict__.update(
            description=("Kirchhoff–Love plate strip, clamped–free (ν = 0, h/L = 0.1), under in-plane compression: "
                         "first critical load by continuation with the constrained strains, against Euler's "
                         "π²D/(4L²) with the mid-surface shortening"),
            reference=("N_cr: root of N_E λ₀ = N, ½Eh(λ₀³ − λ₀) = −N, N_E = π²D/(4L²) (Euler's column, Timoshenko & "
                       "Gere §2.1; no transverse shear); N_cr = 0.99794 N_E at h/L = 0.1"),
            tolerance=1e-3,
            tolerance_reason=("n = 8·2^level + 1; the error is the mode's (k dx)²/12 with k = π/(2L): 3.21e-3, "
                              "8.02e-4, 2.00e-4 at n = 9, 17, 33 (measured); the bound holds from n = 17 on"),
        )

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        base, settings = super().problem(level, scheme)
        kl = cartan.medium("kirchhoff-love", E=base.medium.E, poisson=base.medium.nu, thickness=base.medium.h)
        return Problem(kl, base.grid, base.initial, base.boundaries, name=self.name), settings

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        kinds = [str(k) for k in ds["critical_kind"].values]
        if "bifurcation" not in kinds:
            return float("inf")
        n_cr = float(ds["critical_load"].values[kinds.index("bifurcation")])
        return abs(n_cr / column_critical_load(problem.medium, problem.grid.length[0], ends=self.ends,
                                               shear=False) - 1.0)


# ---------------------------------------------------------------------------- cross-medium limit
def cosserat_limit(ratios: Sequence[float] = (1e1, 1e2, 1e3, 1e4), n: int = 9,
                   thickness_ratio: float = 0.1) -> dict[str, Any]:
    """``cosserat-surface`` with the transverse shear stiffness κ_sGh scaled by ``ratio`` against
    ``kirchhoff-love`` on the same lattice: the simply supported Navier plate of
    :func:`kirchhoff_navier_problem` (same supports, load and grid; E = 1, ν = 0.3).

    Parameters
    ----------
    ratios : sequence of float
        κ_s/(5/6), each > 0.
    n : int
        Nodes per side (odd, ≥ 3).
    thickness_ratio : float
        h/a (0.1: the shear part of the Mindlin deflection is 5 % at ratio 1).

    Returns
    -------
    dict with ``"ratios"``, ``"errors"`` (max over the nodes of |z_surface − z_KL| / w_c,KL),
    ``"slope"`` (least-squares slope of log error against log ratio; −1 expected: the shear
    compliance is 1/(κ_sGh)) and ``"kirchhoff_deflection"`` (w_c of the Kirchhoff–Love lattice).
    """
    ratios = [float(r) for r in ratios]
    if len(ratios) < 2 or not all(np.isfinite(r) and r > 0 for r in ratios):
        raise ValueError(f"ratios must be at least two finite numbers > 0, got {ratios!r}")

    def heights(medium: Any = None) -> np.ndarray:
        prob = kirchhoff_navier_problem(n, thickness_ratio, medium=medium)
        ds = cartan.solve_static(prob, tol=1e-10)
        return np.asarray(ds["position"].values[0][..., 2])

    z_kl = heights()
    w_c = -float(z_kl[n // 2, n // 2])
    errors = []
    for r in ratios:
        shell = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=thickness_ratio,
                              shear_correction=r * 5.0 / 6.0)
        errors.append(float(np.max(np.abs(heights(shell) - z_kl))) / w_c)
    slope = float(np.polyfit(np.log(ratios), np.log(errors), 1)[0])
    return {"ratios": ratios, "errors": errors, "slope": slope, "kirchhoff_deflection": w_c}


#: the registered cases
CASES = [NavierPlateKL(), PlateColumnBucklingKL()]


def all_cases() -> list[StaticCase]:
    """The cases this plugin registers."""
    return list(CASES)
