"""Long runs of the Cosserat rod (marked ``slow``; ``make test-slow``)."""

from __future__ import annotations

import numpy as np
import pytest

import cartan


@pytest.mark.slow
def test_butterfly_energy_bounded_without_trend_over_1e5_steps():
    """Lie–Verlet on the free bent rod (no damping): over 10⁵ steps the relative energy error
    stays bounded — an oscillation of O(Δt²) amplitude — with no secular trend.

    A symplectic integrator conserves a modified energy to O(Δt²) for exponentially long
    times, so the error in the last quarter of the run is no larger than in the first (up to
    the 30 % spread of the oscillation's maxima), and a linear fit over the whole run moves
    by less than 10 % of that amplitude.
    """
    rod = cartan.medium("cosserat-rod", E=1e4, poisson=0.5, radius=0.25, density=5000.0)
    grid = cartan.Grid(11, length=3.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=0.5, centered=True))
    dt = 4e-3
    ds = cartan.simulate(problem, integrator="lie-verlet", scheme="lattice", dt=dt, t_end=1e5 * dt, save_every=100)
    E = (ds.kinetic_energy + ds.potential_energy).values
    err = (E - E[0]) / E[0]
    assert int(ds.step[-1]) == 100_000
    amplitude = np.abs(err).max()
    assert amplitude < 1e-3
    q = len(err) // 4
    assert np.abs(err[-q:]).max() <= 1.3 * np.abs(err[:q]).max()
    t = ds.time.values
    slope = np.polyfit(t, err, 1)[0]
    assert abs(slope) * (t[-1] - t[0]) < 0.1 * amplitude
