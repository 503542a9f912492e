"""An under-resolved shape is named: the largest rotation between neighbouring frames, and the
blow-up message when Δt is within the CFL estimate (paper §VI.C: the edge strain log(Φ_i⁻¹Φ_j)/h
is undefined at a rotation of π)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from toys import arc_problem

from cartan.resolution import LIMIT, largest_edge_rotation, under_resolved
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice
from cartan.simulate import InstabilityError, simulate


@pytest.mark.parametrize("scheme_type", [Lattice, Collocation])
@pytest.mark.parametrize("n", [3, 8, 24])
def test_largest_edge_rotation_of_a_ring_is_two_pi_over_n(scheme_type, n):
    scheme = scheme_type(arc_problem(n=n, curvature=2 * np.pi, periodic=True))
    theta, axis = largest_edge_rotation(scheme, scheme.initial_state())
    # the frames are exact group elements: the angle is 2π/n to round-off
    assert abs(theta - 2 * np.pi / n) <= 1e-12 and axis == 0
    note = under_resolved(scheme, scheme.initial_state())
    assert (note is not None) == (2 * np.pi / n >= LIMIT)
    if note is not None:
        assert f"n = {n} nodes" in note and "refine the grid" in note


def test_planar_and_lorentz_groups():
    scheme = Lattice(arc_problem(n=3, curvature=2 * np.pi, periodic=True, group="SE2"))
    assert abs(largest_edge_rotation(scheme, scheme.initial_state())[0] - 2 * np.pi / 3) <= 1e-12
    boosted = Lattice(arc_problem(n=5, curvature=0.5, group="SO13"))  # boosts: not rotations
    assert largest_edge_rotation(boosted, boosted.initial_state()) is None


def _blow_up(n: int, factor: float) -> str:
    problem = arc_problem(n=n, curvature=2 * np.pi, periodic=True, velocity=np.array([0, 0, 0, 0, 0, 40.0]))
    scheme = Lattice(problem)
    from cartan.integrators.explicit import LieVerlet

    dt = factor * LieVerlet().dt_max(scheme, scheme.initial_state())
    with warnings.catch_warnings(), pytest.raises(InstabilityError) as info:
        warnings.simplefilter("ignore")
        simulate(problem, dt=dt, t_end=2000 * dt, save_every=50, progress=False, compiled=False)
    return str(info.value)


def test_blow_up_message_names_the_under_resolved_shape():
    # three nodes on a ring spinning fast about its axis: 2.09 rad between neighbours, within the CFL
    message = _blow_up(3, 0.5)
    assert "under-resolved" in message and "within the CFL estimate" in message


def test_blow_up_beyond_the_cfl_does_not_blame_the_resolution():
    message = _blow_up(24, 40.0)
    assert "exceeds the CFL estimate" in message and "under-resolved" not in message
