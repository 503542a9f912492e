"""Spatial integrability in d = 2 (paper §III.C): the lattice keeps every plaquette holonomy
to round-off; collocation's continuum residual Δ_αβ is a discretisation error O(h²)."""

from __future__ import annotations

import numpy as np
import pytest
from toys import QuadraticMedium

import cartan
from cartan.integrators import LieVerlet
from cartan.schemes import Collocation, Lattice


def _problem(n):
    m = cartan.medium("sigma-model", n=2, d=2)
    grid = cartan.Grid((n, n), length=(1.0, 1.0), periodic=(True, True))
    return cartan.Problem(m, grid, m.initial_state(grid, "random-smooth"))


def test_lattice_plaquettes_stay_at_round_off_and_frames_rebuild_exactly():
    prob = _problem(16)
    tracked, rebuilt = Lattice(prob, track_frames=True), Lattice(prob, track_frames=False)
    a, b = tracked.initial_state(), rebuilt.initial_state()
    integ_a, integ_b = LieVerlet(), LieVerlet()
    dt = 0.2 * integ_a.dt_max(tracked, a)
    for _ in range(100):
        integ_a.step(tracked, a, dt)
        integ_b.step(rebuilt, b, dt)
        assert tracked.spatial_residual(a) <= 1e-12
    # frames rebuilt along a spanning tree equal the independently stepped frames
    assert np.max(np.abs(tracked.frames(a) - rebuilt.frames(b))) <= 1e-12


def test_collocation_continuum_residual_is_second_order():
    """Δ_αβ of smooth data with fd2 falls ≈ 4× when h halves (ratio in [3, 5]: second order
    with the O(h⁴) remainder still visible at n = 16)."""
    r = [Collocation(_problem(n)).spatial_residual(Collocation(_problem(n)).initial_state()) for n in (16, 32, 64)]
    assert 3.0 <= r[1] / r[2] <= 5.0, r
    assert r[0] > r[1] > r[2]


@pytest.mark.parametrize("scheme", ["lattice", "collocation"])
def test_output_records_the_spatial_residual(scheme):
    # the Python path: the d = 2 loops compile in make test-slow (tests/conftest.py)
    ds = cartan.simulate(_problem(8), scheme=scheme, dt=1e-3, t_end=0.004, save_every=2, compiled=False)
    assert ds.spatial_residual.dims == ("time",) and np.all(np.isfinite(ds.spatial_residual))
    assert ds.spatial_residual.attrs["long_name"].startswith("spatial integrability")


def test_holonomy_per_axis_is_validated():
    """``InitialState.holonomy`` for d ≥ 2 is ``{axis: H}`` over periodic axes (paper §III.C: a
    body periodic up to a motion); anything else is a ValueError naming it."""
    med = QuadraticMedium("SE2")
    med.material_dim = 2
    grid = cartan.Grid((4, 3), 1.0, periodic=(True, False))
    Phi = np.broadcast_to(np.eye(3), (4, 3, 3, 3)).copy()
    H = np.eye(3)
    H[1, 0] = 1.0
    assert cartan.Problem(med, grid, cartan.InitialState(Phi=Phi, holonomy={0: H})).initial.holonomy[0] is not None
    for bad, match in (({1: H}, "not periodic"), ({2: H}, "axis must be"), (H, "d = 1"),
                       ({0: 2 * np.eye(3)}, "not in SE2")):
        with pytest.raises(ValueError, match=match):
            cartan.Problem(med, grid, cartan.InitialState(Phi=Phi, holonomy=bad))
