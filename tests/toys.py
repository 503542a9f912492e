"""Small media used by the core's tests (the core itself knows no medium)."""

from __future__ import annotations

import numpy as np

import cartan
from cartan.grid import Grid
from cartan.medium import QuadraticMedium as _Quadratic
from cartan.problem import InitialState, Problem


class QuadraticMedium(_Quadratic):
    """U = ½ Σ_k C_k (X_k − X0_k)², K = ½ Σ_k m_k N_k² on any group, d = 1."""

    name = "toy-quadratic"
    material_dim = 1

    def __init__(self, group="SE3", mass=None, stiffness=None, rest=None):
        self.group = cartan.group(group) if isinstance(group, str) else group
        r = self.group.dim
        self.space = None
        self.m = np.asarray(mass if mass is not None else np.linspace(1.0, 0.2, r), dtype=float)
        self.C = np.asarray(stiffness if stiffness is not None else np.linspace(10.0, 2.0, r), dtype=float)
        self.X0 = np.asarray(rest if rest is not None else np.eye(r)[0], dtype=float)
        self._set_energy(self.X0, self.C)

    def parameters(self):
        return {"group": self.group.name, "mass": self.m.tolist(), "stiffness": self.C.tolist(),
                "rest": self.X0.tolist()}

    def inertia(self):
        return self.m


def arc_problem(n=21, length=1.0, curvature=2.0, group="SE3", periodic=False, twist=0.0, velocity=None,
                **kw) -> Problem:
    """A rod bent into an arc (constant strain), optionally spinning."""
    medium = QuadraticMedium(group, **kw)
    G = medium.group
    grid = Grid(n, length, periodic=periodic)
    u = grid.coordinates(0)
    xi = np.zeros(G.dim)
    xi[0] = 1.0
    xi[-1] = curvature
    if G.dim >= 6:
        xi[3] = twist
    Phi = G.exp(u[:, None] * xi)
    N = None if velocity is None else np.broadcast_to(velocity, (n, G.dim)).copy()
    return Problem(medium, grid, InitialState(Phi=Phi, N=N))
