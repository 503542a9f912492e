"""The corner pass of the compiled lattice force with a shared rest strain.

When every corner of a coupled lattice has the same rest strain (no reference configuration),
``LatticeData.cuniform`` holds and the force's corner pass gives the medium's stress kernel that
one ``[d, r]`` array (``cX0u``) instead of a view of each corner's copy (``cX0[c]``), which saves
the view's reference counting (docs/performance.md, T9).  The kernel reads the same numbers
either way, so the force must be the same to the bit: no tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.schemes.lattice import Lattice

SE3 = cartan.group("SE3")


def _solid_box_ops():
    """The compiled operators, data and generated module of a perturbed periodic 3 × 4 × 3
    cosserat-solid box (the grid of the solid's compiled-vs-reference test)."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((3, 4, 3), length=(0.75, 1.0, 0.75), periodic=True)
    rng = np.random.default_rng(4)
    base = solid.initial_state(grid, "undeformed")
    Phi = SE3.compose(base.Phi, SE3.exp(0.05 * rng.standard_normal((*grid.shape, 6))))
    N = 0.05 * rng.standard_normal((*grid.shape, 6))
    problem = cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi, N=N, holonomy=base.holonomy))
    scheme = Lattice(problem)
    ops = scheme.compiled_operators()
    if getattr(ops, "reason", None):
        pytest.skip(f"no compiled operator set: {ops.reason}")
    return scheme, ops


def test_shared_rest_strain_is_detected_and_gives_the_same_force_to_the_bit():
    scheme, ops = _solid_box_ops()
    D = ops.data
    assert D.coupled and D.cuniform
    assert np.array_equal(D.cX0u, D.cX0[0]) and np.all(D.cX0 == D.cX0u)
    module = ops.generated()
    state = scheme.initial_state()
    n, r = ops.nodes, D.r
    S = np.ascontiguousarray(state.S, dtype=float).reshape(n, r).copy()
    Nv = np.empty((n, r))
    module.op_velocity(D, S, Nv)
    forces = []
    for data in (D, D._replace(cuniform=False)):  # one array, or each corner's view
        C = ops.pack(state)
        K = module.op_work(data)
        W = np.empty((n, r))
        module.op_force(data, C, 0.0, Nv, W, K)
        forces.append(W)
    assert np.any(forces[0] != 0.0)
    assert np.array_equal(forces[0], forces[1])


def test_distinct_rest_strains_are_not_shared():
    scheme, ops = _solid_box_ops()
    corners = scheme.corners()
    X0 = corners["X0"].copy()
    X0[1, 0, 0] += 1e-3  # one corner's rest strain differs: the data must keep every copy
    scheme._corners = dict(corners, X0=X0)
    from cartan.schemes._lattice_ops import lattice_operators

    D = lattice_operators(scheme, Lattice).data
    assert not D.cuniform
    assert np.array_equal(D.cX0, X0) and not np.any(D.cX0u)
