"""Lagrangians that couple N and X on the collocation scheme's compiled operators
(:func:`cartan.schemes._collocation_ops.coupled_fragment`: pointwise N_i = ∂H/∂S(S_i, X_i) and
Q_i = ∂H/∂X(S_i, X_i) by the medium's coupled point kernels): the elastic relativistic string
(docs/media/relativistic-rod.md §3) through the generated loops of ``rkmk4`` and ``lie-euler``
against the numpy path (``simulate(..., compiled=False)``).

The fast test checks the declarations (the set's loops; the integrators without momentum decline
before any compile).  Slow: the loops compile on first use (30–90 s on a fresh cache); the same
formulas in the same order, the Legendre maps Newton's method converged to round-off on both paths,
so every saved field agrees to 1e-12 of its scale (round-off of 20 steps).
"""

from __future__ import annotations

import math

import pytest
from toys import rel_error

import cartan
from cartan.integrators.explicit import Overdamped
from cartan.schemes.collocation import Collocation

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")

#: compiled against numpy, relative to each field's scale: round-off of 20 steps
TOL = 1e-12


def _ring(n: int = 16) -> cartan.Problem:
    """A closed elastic string without clocks, spinning and breathing (tests/test_coupled_compiled.py)."""
    rod = cartan.medium("relativistic-rod", energy="elastic", clocks=False, stiffness=0.25)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "ring", radius=1.1, spin=0.3, radial_speed=0.1))


def test_the_coupled_set_serves_the_momentum_loops():
    scheme = Collocation(_ring())
    ops = scheme.compiled_operators()
    assert not ops.ok and "coupling N and X" in ops.reason
    assert ops.serves("euler_loop") and ops.serves("rkmk_loop") and ops.serves("implicit_loop")
    state = scheme.initial_state()
    assert Overdamped().run_compiled_loop(scheme, state, 0.01, 2) is False and state.t == 0.0


@pytest.mark.slow  # (each loop compiles on first use: 30–90 s on a fresh cache)
@pytest.mark.parametrize("integrator", ["rkmk4", "lie-euler"])
def test_the_ring_runs_compiled_and_agrees_with_the_numpy_path(integrator, generated_runs):
    kw = dict(scheme="collocation", integrator=integrator, dt=0.02, t_end=0.4, save_every=5, progress=False)
    fast = cartan.simulate(_ring(), **kw)
    assert generated_runs and all(generated_runs)
    ref = cartan.simulate(_ring(), compiled=False, **kw)
    assert rel_error(ref.position.values[-1], ref.position.values[0]) > 1e-3  # the ring moved
    for name in ("position", "frame", "N", "S", "X", "kinetic_energy", "potential_energy"):
        assert rel_error(fast[name].values, ref[name].values) <= TOL, name
