"""Principal against coordinate gauge: the same motion of a surface without umbilics.

The in-plane frame of the ``kirchhoff-love`` medium is a gauge (paper §VII.B): turning e₁, e₂
about e₃ changes neither the energy density at a point nor the motion of the surface.  The case
runs one motion twice with ``rattle``, its initial and reference frames built in the coordinate
gauge (e₁ ∥ ∂_u r) and in the principal gauge (e₁, e₂ along the principal directions, medium
parameter ``gauge="principal"``), and compares the node positions at the end.

The surface is a circular tube of radius R = 1 charted along helices: r(u, v) = (ρ sin θ,
v + τu, ρ cos θ − R), θ = u/R, τ = ½, periodic in u (holonomy: the translation by 2πRτ along the
axis) and in v (length 2πR/4), so that the coordinate e₁ ∥ ∂_u r = (cos θ, τ, −sin θ) is turned
by atan τ = 26.6° from the principal direction (the circumference, κ₁ = 1/R; κ₂ = 0 along the
axis: no umbilic).  The stress-free reference is the tube ρ = R, the initial state the oval
ρ = R(1 + ε cos 2θ), ε = 0.02, at rest; the run lasts t = 1 (Δt = ½Δ/c).  On the lattice the
edge strains mix frames of neighbouring nodes, and in the two gauges those differ by turns of
O(Δ∂φ): the lattice energies, hence the motions, differ by O(Δ²), while each run is its own
second-order approximation of the same continuum motion.  The error is the largest distance
between the two runs' node positions at the end, relative to the largest displacement.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import xarray as xr
from cartan_verification.case import Case

import cartan
from cartan.problem import Problem

__all__ = ["GaugeInvarianceKL", "helical_tube_problem"]


def helical_tube_problem(n: int, gauge: str = "principal", *, radius: float = 1.0, pitch: float = 0.5,
                         ovality: float = 0.02, **params: Any) -> Problem:
    """The oval tube of the module docstring on an ``n × n/4`` periodic lattice, charted along helices.

    Parameters
    ----------
    n : int
        Nodes around the circumference (a multiple of 4, ≥ 8); n/4 along the axis.
    gauge : {"coordinate", "principal"}
        The frames of the initial and reference states (the medium's ``gauge``).
    radius, pitch, ovality : float
        R (> 0), τ (the chart's axial advance per unit u), ε (|ε| < 1).
    **params
        Further keywords of the ``kirchhoff-love`` medium (default E = 1, ν = 0.3, h = 0.1, ρ = 1).

    Returns
    -------
    Problem
        Named ``"principal-gauge-kl"``, with the round tube as its stress-free reference.
    """
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 8 or n % 4:
        raise ValueError(f"n must be a multiple of 4, ≥ 8, got {n!r}")
    if not (np.isfinite(radius) and radius > 0.0):
        raise ValueError(f"radius must be a finite number > 0, got {radius!r}")
    if not (np.isfinite(ovality) and abs(ovality) < 1.0) or not np.isfinite(pitch):
        raise ValueError(f"ovality must be in (−1, 1) and pitch finite, got {ovality!r}, {pitch!r}")
    medium = cartan.medium("kirchhoff-love", gauge=gauge, **params)
    grid = cartan.Grid((n, n // 4), length=(2.0 * np.pi * radius, 0.5 * np.pi * radius), periodic=(True, True))

    def tube(eps: float):
        def position(u, v):
            theta = u / radius
            rho = radius * (1.0 + eps * np.cos(2.0 * theta))
            return np.stack([rho * np.sin(theta), v + pitch * u, rho * np.cos(theta) - radius], axis=-1)
        return position

    shift_u, shift_v = np.eye(4), np.eye(4)
    shift_u[2, 0], shift_v[2, 0] = 2.0 * np.pi * radius * pitch, grid.length[1]
    holonomy = {0: shift_u, 1: shift_v}

    def state(eps: float) -> cartan.InitialState:
        return cartan.InitialState(Phi=medium.initial_state(grid, "surface", position=tube(eps)).Phi,
                                   holonomy=holonomy)

    return Problem(medium, grid, state(ovality), reference=state(0.0), name="principal-gauge-kl")


class GaugeInvarianceKL(Case):
    """The oval helical tube run in the principal and in the coordinate gauge (module
    docstring): n = 24·2^level nodes around, n/4 along; the error is max |x_principal −
    x_coordinate| / max |x(t) − x(0)| at t = 1."""

    name = "principal-gauge-kl"
    medium = "kirchhoff-love"
    description = ("Principal against coordinate gauge: the same physical motion (positions) of an oval "
                   "Kirchhoff–Love tube (R = 1, ε = 0.02, h = 0.1) charted along helices (no umbilic; the "
                   "coordinate e₁ 26.6° off the principal directions), run with rattle from both gauges")
    reference = ("gauge invariance of the medium (paper §VII.B: a turn of e₁, e₂ about e₃ changes neither the "
                 "energy nor the motion): the two runs' positions agree up to the lattice's O(Δ²)")
    quantity = "node positions at t = 1 in the principal-gauge run against the coordinate-gauge run"
    norm = "max over nodes |x_p − x_c| / max over nodes |x_c(t) − x_c(0)|"
    space_order = 2.0
    refine = "space"
    default_integrators = ("rattle",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2)
    quick_levels = (0, 1)
    tolerance = 1e-4
    tolerance_reason = ("n = 24·2^level; the gauges' O(Δ²) difference is 1.14e-4, 2.66e-5, 6.67e-6 of the "
                        "displacement at n = 24, 48, 96 (measured; orders 2.09, 2.00; n = 16, 32, 64 gave 3.40e-4, "
                        "6.16e-5, 1.50e-5, orders 2.46, 2.04); the bound holds from n = 48 on")
    t_end = 1.0
    cfl = 0.5

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        problem = helical_tube_problem(24 * 2 ** level, "principal")
        m = problem.medium
        c = float(np.sqrt(m.E / (m.rho * (1.0 - m.nu ** 2))))
        steps = int(np.ceil(self.t_end / (self.cfl * problem.grid.spacing[0] / c)))
        return problem, {"dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps}

    def run(self, problem: Problem, settings: Mapping[str, Any], integrator: str, scheme: str = "lattice",
            compiled: bool = True) -> xr.Dataset:
        """The run of ``problem`` (principal gauge), with the node positions of the same run
        from the coordinate gauge as ``position_coordinate_gauge`` ``[time, nu, nv, 3]``."""
        ds = super().run(problem, settings, integrator, scheme, compiled)
        twin = helical_tube_problem(problem.grid.shape[0], "coordinate")
        other = super().run(twin, settings, integrator, scheme, compiled)
        ds["position_coordinate_gauge"] = (ds["position"].dims, np.asarray(other["position"].values))
        return ds

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        x_p = np.asarray(ds["position"].values)
        x_c = np.asarray(ds["position_coordinate_gauge"].values)
        moved = float(np.max(np.linalg.norm(x_c[-1] - x_c[0], axis=-1)))
        return float(np.max(np.linalg.norm(x_p[-1] - x_c[-1], axis=-1))) / moved
