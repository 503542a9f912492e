"""Global functionals held by Lagrange multipliers in the statics (cartan.constraints.HeldFunctional,
solve_static(holds=...)): the bordered Newton system against the pins, and the multiplier as a force."""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.constraints import HeldFunctional


class TipCoordinate(HeldFunctional):
    """The spatial coordinate k of the last node: ∂r_k/∂v = R[k, :] along Φ ← Φ exp((v, ω))."""

    name = "tip"

    def __init__(self, k: int, target: float | None = None):
        super().__init__(target, scale=1.0)
        self.k = k

    def value(self, scheme, state):
        return float(scheme.frames(state)[-1, 1 + self.k, 0])

    def gradient(self, scheme, state):
        Phi = scheme.frames(state)
        out = np.zeros((*Phi.shape[:-2], scheme.group.dim))
        out[-1, :3] = Phi[-1, 1 + self.k, 1:]
        return out


class TipDistance(HeldFunctional):
    """|r_tip|² (a curved functional: its Hessian enters the Jacobian)."""

    name = "distance"

    def value(self, scheme, state):
        r = scheme.frames(state)[-1, 1:, 0]
        return float(r @ r)

    def gradient(self, scheme, state):
        Phi = scheme.frames(state)
        out = np.zeros((*Phi.shape[:-2], scheme.group.dim))
        out[-1, :3] = 2.0 * Phi[-1, 1:, 1:].T @ Phi[-1, 1:, 0]
        return out


def _cantilever(load):
    rod = cartan.medium("cosserat-rod", stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                        rotational_inertia=[1.0] * 3)
    grid = cartan.Grid(16, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=load)})


def test_held_coordinate_equals_the_pin():
    """Holding the tip's y by a HeldFunctional is the pin of that component: the same equilibrium
    (both solved to tol = 1e-10 of the load: positions agree to 1e-9) and μ = −reaction (the pin
    pushes with +reaction·e_y, the hold with −μ·e_y)."""
    problem = _cantilever([0.0, -0.5, 0.2, 0.0, 0.0, 0.3])
    pinned = cartan.solve_static(problem, pins={"end": [1]})
    held = cartan.solve_static(problem, holds=[TipCoordinate(1)])
    assert held.attrs["newton_iterations"] <= 8
    dx = np.max(np.abs(held.position.values - pinned.position.values))
    assert dx < 1e-9
    mu = float(held.held_multiplier.sel(held="tip"))
    reaction = float(pinned.reaction.values[0])
    assert abs(reaction) > 0.05   # the hold carries load (measured 0.098)
    assert abs(mu + reaction) < 1e-8 * abs(reaction)
    assert abs(float(held.held_value.sel(held="tip")) - float(held.held_target.sel(held="tip"))) < 1e-10


def test_curved_functional_multiplier_is_the_force():
    """A hold of |r_tip|² = 0.8² (a circle the tip must reach): at the solution the multiplier's
    reaction −2μ r_tip is a dead end force; the problem with that force added and no hold has the
    same equilibrium (to the solves' tolerance).  Newton's convergence stays quadratic with the
    hold's Hessian in the Jacobian (≤ 10 iterations from the straight rod)."""
    load = np.array([0.0, -0.5, 0.0, 0.0, 0.0, 0.0])
    problem = _cantilever(load)
    held = cartan.solve_static(problem, holds=[TipDistance(target=0.64)])
    assert held.attrs["newton_iterations"] <= 10
    r = held.position.values[-1, -1]
    assert abs(r @ r - 0.64) < 1e-10 * 0.64
    mu = float(held.held_multiplier.values[0])
    extra = np.concatenate([-2.0 * mu * r, np.zeros(3)])
    free = cartan.solve_static(_cantilever(load + extra), initial=held, tol=1e-12)
    assert free.attrs["newton_iterations"] <= 3
    assert np.max(np.abs(free.position.values - held.position.values)) < 1e-8


def test_bad_holds():
    problem = _cantilever([0.0, -0.5, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="holds\\[0\\] must be a cartan.constraints.HeldFunctional"):
        cartan.solve_static(problem, holds=[object()])
    with pytest.raises(ValueError, match="distinct names"):
        cartan.solve_static(problem, holds=[TipCoordinate(1), TipCoordinate(2)])
    with pytest.raises(ValueError, match="scale must be finite and > 0"):
        TipDistance(scale=0.0)
    with pytest.raises(ValueError, match="target must be finite"):
        TipDistance(target=float("nan"))
