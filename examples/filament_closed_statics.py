"""Statics of a closed filament and of a filament with a prescribed end rotation.

Left: a ring (R = 1, B = 1, n = 64) pressed by two opposite forces P = 0.5, 2, 5 B/R²,
``solve_static(..., pins="rigid")`` (node 0 held: the rigid-body gauge). Right: a clamped
filament (L = 1, n = 33) whose end rotation about d₃ grows from π/4 to 2π in eight solves,
each started from the last with its end turned further (``cartan_filament.ends.turned_end``):
circular arcs closing into a ring.

Run: ``python examples/filament_closed_statics.py [out.png]``
(default ``docs/media/filament/filament-closed-statics.png``).
"""

from __future__ import annotations

import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from cartan_filament.ends import turned_end  # noqa: E402

import cartan  # noqa: E402
from cartan.problem import NodeForce  # noqa: E402


def main(out: str = "docs/media/filament/filament-closed-statics.png") -> None:
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.8))
    n = 64
    rod = cartan.medium("filament", twist=0.7)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    ring = rod.initial_state(grid, "ring")
    for P in (0.0, 0.5, 2.0, 5.0):
        loads = [NodeForce(grid, force=[-P, 0, 0, 0, 0, 0], node=0),
                 NodeForce(grid, force=[P, 0, 0, 0, 0, 0], node=n // 2)]
        ds = cartan.solve_static(cartan.Problem(rod, grid, ring, {}, loads), pins="rigid")
        x = ds["position"].isel(time=0).values
        x = x - x.mean(axis=0)
        left.plot([*x[:, 0], x[0, 0]], [*x[:, 1], x[0, 1]], label=f"P = {P:g} B/R²")
        print(f"P = {P}: diameter along the loads {x[0, 0] - x[n // 2, 0]:.4f}, across "
              f"{x[n // 4, 1] - x[3 * n // 4, 1]:.4f}, gauge reaction {abs(ds['reaction'].values).max():.1e}")
    left.set_title("closed ring, diametral compression (pins='rigid')")
    left.set_aspect("equal")
    left.set_xlim(-2.1, 1.2)
    left.legend(fontsize=8, loc="center left")
    rod = cartan.medium("filament")
    line = cartan.Grid(33, length=1.0)
    start, ds = rod.initial_state(line, "straight"), None
    for k in range(1, 9):
        start = turned_end(start if ds is None else ds, [0.0, 0.0, math.pi / 4])
        ds = cartan.solve_static(cartan.Problem(rod, line, start, {"start": cartan.Clamped()}), pins={"end": (3, 4, 5)})
        x = ds["position"].isel(time=0).values
        right.plot(x[:, 0], x[:, 1], label=f"α = {k}π/4")
    right.set_title("end rotation α about d₃, grown in eight solves")
    right.set_aspect("equal")
    right.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print("wrote", out)


if __name__ == "__main__":
    main(*sys.argv[1:])
