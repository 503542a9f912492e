"""The elastic string's Newtonian limit c → ∞ against ``cosserat-rod`` (docs §2, §6).

Same data on both sides: an open string of reference length L, rest mass μ per unit reference
length, axial stiffness k (ε(λ) = μc² + ½k(λ − 1)² against the ``cosserat-rod`` with
stretch–shear stiffness 𝕊 = k·I, no bending stiffness, mass μ), free ends, released with a
non-uniform stretch and a longitudinal velocity along e₁, both run by ``rkmk4`` on the lattice
with the same Δt.  The motion stays on the line of e₁, where the rod's frames are never torqued
(its strain θ = x⃗′ is parallel to its stress): the rod is then exactly the Newtonian
extensible string ½k(|x⃗′| − 1)², and its lattice the c → ∞ limit of the relativistic lattice
(docs §3), so the difference of the two runs is the relativistic correction alone, expected
O(c⁻²) (the c⁻² bracket of ℓ, docs §2).

``python -m cartan_relativistic.elastic_limit OUT.png`` draws the chart.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

import cartan

__all__ = ["main", "newtonian_run", "string_data"]

#: the case's data: reference length, nodes, μ, k, stretch amplitude, velocity amplitude, t_end, Δt
LENGTH, NODES, MU, K, STRETCH, SPEED, T_END, DT = 1.0, 17, 1.0, 1.0, 0.1, 0.3, 1.0, 0.025


def string_data(grid: cartan.Grid) -> tuple[np.ndarray, np.ndarray]:
    """Lab positions and velocities ``(n, 3)`` at t = 0: x = u + aL sin(πu/L)/π (stretch 1 + a
    cos(πu/L)) and v = V cos(2πu/L), along e₁."""
    u = grid.coordinates(0)
    x = np.zeros((u.size, 3))
    v = np.zeros((u.size, 3))
    x[:, 0] = u + STRETCH * LENGTH / math.pi * np.sin(math.pi * u / LENGTH)
    v[:, 0] = SPEED * np.cos(2 * math.pi * u / LENGTH)
    return x, v


def newtonian_run(compiled: bool = False) -> Any:
    """The ``cosserat-rod`` run with the case's data (𝕊 = kI, 𝔹 = 0, mass μ; frames I, ω = 0)."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[K, K, K], bend_twist=[0.0, 0.0, 0.0], mass=MU,
                        rotational_inertia=[1e-2, 1e-2, 1e-2])
    grid = cartan.Grid(NODES, length=LENGTH)
    x, v = string_data(grid)
    Phi = np.broadcast_to(np.eye(4), (NODES, 4, 4)).copy()
    Phi[:, 1:, 0] = x  # [[1, 0ᵀ], [x, R]]: homogeneous coordinate first
    N = np.zeros((NODES, 6))
    N[:, :3] = v
    problem = cartan.Problem(rod, grid, cartan.InitialState(Phi=Phi, N=N), name="newtonian-extensible-string")
    return cartan.simulate(problem, integrator="rkmk4", dt=DT, t_end=T_END, save_every=int(round(T_END / DT)),
                           progress=False, compiled=compiled)


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m cartan_relativistic.elastic_limit OUT.png`` (the c → ∞ chart)."""
    from .cases import ElasticNewtonianLimit
    from .limit import chart_main

    def report(rows, slope):
        return [*(f"c = {r['c']:g}: difference {r['error']:.3e}, energy drift {r['drift']:.1e}" for r in rows),
                f"fitted slope {slope:.3f}"]

    return chart_main("cartan_relativistic.elastic_limit", ElasticNewtonianLimit(), report, argv)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
