"""Driven ends (:class:`cartan.Driven`) in implicit-midpoint's compiled Newton loop
(:func:`cartan.integrators.newton.implicit_loop` over the lattice's operator set with driven
nodes).

ξ = Δtξ_d at a driven node is no unknown of Newton's method: the loop's starting iterates carry
it (``op_drive``), the drift moves the node by exp(Δtξ_d), the wrapped operators give its momentum
∂K/∂N(ξ_d) and add the supports' power at the midpoint.  A Cosserat rod clamped at u = 0 and
driven at u = L, 50 steps in three blocks (1, 2, 47): ``compiled_advance`` takes the steps of the
Python driver over the same compiled residual bit for bit (the energies to round-off), and agrees
with the numpy reference (``compiled_diagnostics`` cleared) to round-off at a Newton tolerance at
round-off; the end frame is Φ(0)exp(tξ) to round-off.

Slow: the driven rod's Newton loop compiles on first use (45–90 s on a fresh cache).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_driven_compiled import SCREW, TWIST, _problem, _rel

import cartan
from cartan.integrators import ImplicitMidpoint
from cartan.schemes.lattice import Lattice

NSTEPS = 50
BLOCKS = (1, 2, NSTEPS - 3)
#: Newton's tolerance of the runs against the numpy reference: the floor of the convergence test
#: (64 ε times the residual's terms) decides, so both paths stop at round-off
TIGHT = 1e-13
#: compiled against numpy, relative to the largest value: the two residuals agree to round-off
#: (≤ 1e-12 relative, cartan.integrators.implicit) and both converge to round-off; 50 steps
TOL = 1e-12


class PythonDriver(ImplicitMidpoint):
    """``implicit-midpoint`` stepped by the Python driver only (``compiled_advance`` declines for a
    subclass that overrides ``step``)."""

    def step(self, scheme, state, dt):
        super().step(scheme, state, dt)


def _start(scheme):
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    return state


def test_the_driven_set_serves_the_newton_loop():
    """The driven rod's operator set serves implicit-midpoint's loop (no compilation here)."""
    ops = Lattice(_problem(TWIST)).compiled_operators()
    assert ops.data.any_driven and ops.serves("implicit_loop") and not ops.ok


DRIVEN = {
    "twist": (lambda: _problem(TWIST), 2e-3),
    # a general screw: Newton's ξ is Δtξ there, any ξ moves by exp(Δtξ)
    "screw": (lambda: _problem(SCREW, n=11), 2e-3),
    # damping dissipates at the midpoint as well
    "screw-damped": (lambda: _problem(SCREW, n=11, loads=[cartan.Damping([0.1] * 6)]), 4e-3),
}


@pytest.mark.slow  # (the driven rod's Newton loop compiles on first use: 45–90 s on a fresh cache)
@pytest.mark.parametrize("case", list(DRIVEN))
def test_blocks_move_a_driven_end_as_the_python_driver_and_numpy(case):
    make, dt = DRIVEN[case]
    # the compiled blocks against the Python driver over the same compiled residual: bit for bit
    ref_scheme, fast_scheme = Lattice(make()), Lattice(make())
    ref, fast = _start(ref_scheme), _start(fast_scheme)
    ri, fi = PythonDriver(), ImplicitMidpoint()
    for _ in range(NSTEPS):
        ri.step(ref_scheme, ref, dt)
    for size in BLOCKS:
        assert fi.compiled_advance(fast_scheme, fast, dt, size)
    assert ri._plan[1].compiled is not None  # the Python driver used the compiled residual
    assert np.array_equal(fast.S, ref.S)
    for key in ref.arrays:
        assert np.array_equal(fast.arrays[key], ref.arrays[key]), key
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"] == NSTEPS
    assert (fi.nstep, fi.nforce, fi.newton_iterations, fi.jacobians) == (
        ri.nstep, ri.nforce, ri.newton_iterations, ri.jacobians)
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= 1e-13 * max(abs(ref.scalars[key]), 1e-300), key
    assert ref.scalars["external_work"] != 0.0  # the supports work
    # the end frame: Φ(0)exp(tξ) to round-off, its momentum ∂K/∂N(ξ)
    xi = fast_scheme._driven[1][-1]
    exact = fast_scheme.problem.initial.Phi[-1] @ fast_scheme.group.exp(fast.t * xi)
    assert np.max(np.abs(fast_scheme.frames(fast)[-1] - exact)) < 1e-12
    mask, _, Sd = fast_scheme._driven
    assert np.array_equal(fast.S[mask], Sd[mask])
    # against the numpy reference, both converged to round-off
    np_scheme, tight_scheme = Lattice(make()), Lattice(make())
    np_scheme.compiled_diagnostics = False
    ref, fast = _start(np_scheme), _start(tight_scheme)
    ri, fi = ImplicitMidpoint(tol=TIGHT), ImplicitMidpoint(tol=TIGHT)
    assert not ri.compiled_advance(np_scheme, ref, dt, 1)  # declined: the numpy path
    for _ in range(NSTEPS):
        ri.step(np_scheme, ref, dt)
    for size in BLOCKS:
        assert fi.compiled_advance(tight_scheme, fast, dt, size)
    assert _rel(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert _rel(fast.arrays[key], ref.arrays[key]) <= TOL, key
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= TOL * max(abs(ref.scalars[key]), 1e-300), key
