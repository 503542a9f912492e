"""``kinematic`` in the generated RKMK loop (``rkmk_loop``, ``mode = 2``) over a scheme's operator set.

With a numba-compiled velocity ``f(t, u, X)`` the integrator's loop runs in a module generated
for (operators, loops, velocity); it must agree with the Python reference (``Kinematic.step``,
numpy) on every state array and energy accumulator to 1e-12 relative — the project's
compiled-vs-reference bound: the operations are the same, the compiled group logarithm and
exponential differ from numpy's in the last bits, and over the 30 steps here the observed
differences are a few 1e-15.  A plain Python velocity is declined.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest
from toys import CoupledQuartic, assert_close_states, rod_problem, wave

from cartan.grid import Grid
from cartan.integrators import Kinematic
from cartan.problem import Clamped, Damping, InitialState, Problem
from cartan.schemes.lattice import Lattice

TOL = 1e-12
BLOCKS = (1, 9, 20)





def _sheet() -> Problem:
    """The coupled quartic medium on SE(3), d = 2 (open × periodic), clamped on u = 0, damped."""
    med = CoupledQuartic("SE3", d=2)
    G = med.group
    grid = Grid((6, 5), (1.0, 0.8), periodic=(False, True))
    U, V = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    Phi = G.exp(U[..., None] * np.array([1.0, 0, 0, 0, 0.3, 0]) + V[..., None] * np.array([0, 1.0, 0, 0.5, 0, 0]))
    return Problem(med, grid, InitialState(Phi=Phi), {"u-start": Clamped()}, [Damping(0.2)])


def _both(scheme, integ, dt=0.01, blocks=BLOCKS):
    """The same steps by ``Integrator.step`` (numpy) and by the generated loop in ``blocks``."""
    start = scheme.initial_state()
    start.scalars["nstep"] = 0
    ref, fast = start.copy(), start.copy()
    ref_integ, fast_integ = integ(), integ()
    for _ in range(sum(blocks)):
        ref_integ.step(scheme, ref, dt)
    for size in blocks:
        assert fast_integ.run_compiled_loop(scheme, fast, dt, size)
    return (ref, ref_integ), (fast, fast_integ)


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2, 4])
def test_rod_se3_d1_agrees_with_the_reference(order):
    """A clamped SE(3) rod with a dead end load, damping and gravity (frames stepped)."""
    scheme = Lattice(rod_problem("dead"), track_frames=True)
    assert scheme.compiled_operators().ok
    (ref, ri), (fast, fi) = _both(scheme, lambda: Kinematic(velocity=wave, order=order))
    assert_close_states(fast, ref, TOL)
    assert fast.scalars["dissipated_energy"] != 0.0 and fast.scalars["external_work"] != 0.0
    assert fi.nstep == ri.nstep == sum(BLOCKS) and fi.nforce == ri.nforce == 0
    assert not np.array_equal(fast.arrays["G_u"], scheme.initial_state().arrays["G_u"])  # it moved


@pytest.mark.slow
@pytest.mark.parametrize("order", [1, 2, 4])
def test_sheet_d2_agrees_with_the_reference(order):
    scheme = Lattice(_sheet())
    (ref, _), (fast, _) = _both(scheme, lambda: Kinematic(velocity=wave, order=order))
    assert_close_states(fast, ref, TOL)
    assert fast.scalars["dissipated_energy"] != 0.0


def test_a_python_velocity_is_declined():
    scheme = Lattice(rod_problem("dead"))
    state = scheme.initial_state()
    before = {k: v.copy() for k, v in state.arrays.items()}
    integ = Kinematic(velocity=wave.py_func, order=2)
    assert integ.compiled_loop(scheme, state, 0.01) is None
    assert not integ.run_compiled_loop(scheme, state, 0.01, 5)
    assert state.t == 0.0 and all(np.array_equal(state.arrays[k], before[k]) for k in before)


@pytest.mark.slow
def test_closures_over_other_values_get_their_own_module():
    """Two closures of the same code over different amplitudes: each runs its own velocity."""
    def make(amplitude):
        @numba.njit
        def spin(t, u, X):
            N = np.zeros(X.shape[:-2] + (X.shape[-1],))
            N[..., 5] = amplitude
            return N
        return spin

    scheme = Lattice(rod_problem("dead"), track_frames=True)
    for amplitude in (0.5, 1.5):
        (ref, _), (fast, _) = _both(scheme, lambda a=amplitude: Kinematic(velocity=make(a), order=2),
                                    blocks=(5,))
        assert_close_states(fast, ref, TOL)
