"""``implicit-midpoint`` on the Nambu–Goto string: an indefinite (Minkowski) diagonal kinetic metric,
its Newton norms measured with |M| (cartan/integrators/implicit.py; docs/media/relativistic-rod.md).

The spinning loop of tests/test_relativistic_rod.py (tilt π/3, R₀ = 1, Δt = h/2 to t = 1): the
midpoint rule is symmetric and its discrete Lagrangian invariant under the Poincaré group, so the
energy, P⃗ and J⃗ change by the Newton residual only; the positions converge at order 2 against the
closed form.  Fast: the numpy path.  Slow: the compiled stage residual against it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_relativistic.string import RelativisticRod, loop_exact

import cartan

TILT = math.pi / 3


def _run(n: int, compiled: bool):
    rod = RelativisticRod()
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "loop", tilt=TILT))
    steps = math.ceil(1.0 / (0.5 * grid.spacing[0]))
    ds = cartan.simulate(problem, integrator="implicit-midpoint", dt=1.0 / steps, t_end=1.0, save_every=1,
                         progress=False, compiled=compiled)
    return problem, ds


def _lab(ds):
    return np.stack([ds.lab_x.values, ds.lab_y.values, ds.lab_z.values], axis=-1)


def test_spinning_loop_conserves_and_converges_at_order_two():
    """Energy 2πR₀μc² at every step to round-off (1e-14 relative); P⃗ = 0 and J⃗ = J⃗₀ to the Newton
    residual (tol 1e-10 relative on the velocities; at most 5.3e-13 and 2.0e-13 measured, bound
    1e-11); the
    error against the closed form r(t) falls at order 2 (1.93e-3 → 4.97e-4 at n = 32 → 64:
    1.96; the midpoint rule's (Δt/R₀)² and the lattice's (h/R₀)² dispersion), bound |p − 2| ≤ 0.2."""
    errors = []
    for n in (32, 64):
        problem, ds = _run(n, compiled=False)
        assert np.allclose(ds.energy.values, 2 * math.pi, rtol=1e-14, atol=0)
        P = np.stack([ds[f"momentum_{k}"].values for k in "xyz"], axis=-1)
        J = np.stack([ds[f"angular_momentum_{k}"].values for k in "xyz"], axis=-1)
        assert np.abs(P).max() <= 1e-11
        assert np.abs(J - J[0]).max() <= 1e-11
        x, _ = loop_exact(problem.grid.coordinates(0), float(ds.time[-1]), 1.0, tilt=TILT)
        errors.append(float(np.max(np.linalg.norm(_lab(ds)[-1] - x, axis=-1))))
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) <= 0.2, errors


@pytest.mark.slow
def test_compiled_stage_is_the_numpy_one():
    """The compiled stage residual and blocks against the numpy path: the Newton iterations stop at
    the same tolerance, so the states agree to that tolerance (1e-10 relative on the velocities),
    not to round-off; measured 1.9e-13 on the positions and 7.2e-13 relative on S, bound 1e-10."""
    _, a = _run(32, compiled=True)
    _, b = _run(32, compiled=False)
    assert np.abs(_lab(a) - _lab(b)).max() <= 1e-10
    assert np.abs(a.S.values - b.S.values).max() <= 1e-10 * np.abs(b.S.values).max()
