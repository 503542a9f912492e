"""The Jacobian and its factorisation on the sphere's glued chart (the vesicle flow's static step).

The flow's step (``cartan_kirchhoff_love.vesicle.helfrich_flow``, normal motion) solves a
``helfrich-membrane`` on the sphere's chart — longitude periodic, colatitude glued across the poles,
the lattice coupled at the corners, the adaptation held by strain constraints on every edge — under
a normal tether and a volume pressure.  Its Jacobian is the coloured central difference of the whole
force on the lattice's stencil (``cartan.statics._lattice_stencil``), and the saddle-point matrix
with the constraint multipliers is factorised in a nested-dissection order with every multiplier
after its edge's nodes (``cartan.statics._saddle_order``).  Checked here: the iterated greedy
colouring separates every stencil with fewer colours than the greedy colouring in node order; the
Jacobian does not depend on the colouring (to round-off) and equals a dense central difference of
the residual (8 × 4 nodes); the interleaved order is a permutation that puts every multiplier after
its unknowns, and the LU in that order solves the saddle-point system to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("cartan_kirchhoff_love")
import scipy.sparse as sp  # noqa: E402
from cartan_cosserat_surface.surface import VolumePressure  # noqa: E402
from cartan_kirchhoff_love.vesicle import NormalTether  # noqa: E402
from cartan_kirchhoff_love.vesicle_sphere import ellipsoid_problem  # noqa: E402

from cartan.problem import InitialState, Problem  # noqa: E402
from cartan.schemes.lattice import Lattice  # noqa: E402
from cartan.statics import (  # noqa: E402
    _distance2_colouring,
    _Equilibrium,
    _greedy_colouring,
    _lattice_stencil,
    _lu_solve,
    _saddle_order,
)


def _step(n: int, dt: float = 0.0125, pressure: float = 0.5) -> Problem:
    """The flow's static step from the prolate spheroid of v = 0.9 on 2n × n nodes (as
    ``helfrich_flow(motion="normal")`` builds it: no in-plane regularisation, a normal tether of
    stiffness 1/dt, a volume pressure)."""
    problem = ellipsoid_problem(n, 0.9, spacing="arc")
    med = problem.medium
    med = type(med)(**{**med.parameters(), "tension": 0.0, "area_modulus": 0.0, "shear_modulus": 0.0})
    Phi = np.asarray(problem.initial.Phi, dtype=float)
    start = InitialState(Phi=Phi, glue=problem.initial.glue)
    loads = [NormalTether(Phi[..., 1:, 0], Phi[..., 1:, 3], 1.0 / dt, 1e3), VolumePressure(pressure)]
    return Problem(med, problem.grid, start, reference=start, loads=loads)


def _conflict(src: np.ndarray, dst: np.ndarray, nnode: int):
    S = sp.csr_matrix((np.ones(src.size), (src, dst)), shape=(nnode, nnode))
    return S, (S @ S.T).tocsr()


def _perturbed(eq: _Equilibrium, seed: int = 3):
    """A state off the start (a drift of 1e-2 per component) and constraint multipliers of size 1e-2."""
    rng = np.random.default_rng(seed)
    st = eq.state0.copy()
    eq.sch.drift(st, 1.0, 1e-2 * rng.standard_normal((*eq.shape, eq.r_dim)))
    return st, 1e-2 * rng.standard_normal(eq.nmult)


@pytest.mark.parametrize("n", [8, 16])
def test_iterated_colouring_separates_the_stencils_with_fewer_colours(n):
    """Every node is reached at most once per colour (nodes of one colour have disjoint stencils),
    and the iterated greedy colouring needs no more colours than the greedy one in node order
    (measured: 16 against 17 at 16 × 8, 16 against 18 at 32 × 16)."""
    sch = Lattice(_step(n), track_frames=True)
    colour, src, dst = _lattice_stencil(sch)
    nnode = colour.size
    counts = np.zeros((colour.max() + 1, nnode), dtype=int)
    np.add.at(counts, (colour[src], dst), 1)
    assert counts.max() == 1
    assert set(np.unique(colour)) == set(range(colour.max() + 1))
    _, conflict = _conflict(src, dst, nnode)
    plain = _greedy_colouring(conflict, np.arange(nnode))
    assert colour.max() < plain.max()
    # the colouring is kept per stencil: a second lattice of the grid gets the same one, a copy
    again, _, _ = _lattice_stencil(Lattice(_step(n), track_frames=True))
    assert np.array_equal(again, colour) and again is not colour


def test_distance2_colouring_rejects_nothing_it_should_not():
    """On a 1D chain whose stencil is the node and its two neighbours the conflict graph is the
    square of the path, whose chromatic number is 3: the colouring takes 3 colours and separates
    the stencils."""
    nnode = 11
    src = np.concatenate([np.arange(nnode), np.arange(1, nnode), np.arange(nnode - 1)])
    dst = np.concatenate([np.arange(nnode), np.arange(nnode - 1), np.arange(1, nnode)])
    S, conflict = _conflict(src, dst, nnode)
    colour = _distance2_colouring(conflict)
    assert colour.max() + 1 == 3
    for c in range(3):
        assert (S @ (colour == c).astype(float)).max() == 1.0


def test_jacobian_does_not_depend_on_the_colouring():
    """The step's Jacobian (internal force with the constraint multipliers' geometric stiffness, the
    volume pressure on the stencil) with the iterated colouring equals the one with the greedy
    colouring in node order: each entry differences the same force of the same node, only the
    other nodes moved with it differ, and they are outside the entry's stencil — the same numbers
    (bitwise, measured), bound at the round-off of the force, 1e-12 of the row's largest entry."""
    eq = _Equilibrium(_step(8))
    st, mu = _perturbed(eq)
    J = eq.jacobian(st, mu, 1.0).toarray()
    _, conflict = _conflict(eq.src, eq.dst, eq.nnode)
    eq.colour = _greedy_colouring(conflict, np.arange(eq.nnode))
    J_plain = eq.jacobian(st, mu, 1.0).toarray()
    assert np.all(np.abs(J - J_plain) <= 1e-12 * np.abs(J).max(axis=1, keepdims=True))


def _assert_jacobian_matches_a_dense_difference(eq) -> None:
    """The step's whole Jacobian (sparse part plus the low-rank rest) against central differences
    of its residual column by column (h = 1e-6), row by row to 1e-8 of the row's largest entry."""
    st, mu = _perturbed(eq)
    J, low = eq.jacobian(st, mu, 1.0, low_rank=True)
    K = J.toarray()
    if low is not None:
        K = K + low[0] @ low[1].T
    h = 1e-6
    D = np.zeros((eq.m, eq.nunk))
    for j in range(eq.nunk):
        d = np.zeros(eq.m)
        d[j] = h
        D[:, j] = (eq.residual(eq.update(st, mu, d)[0], mu, 1.0)
                   - eq.residual(eq.update(st, mu, -d)[0], mu, 1.0)) / (2 * h)
    scale = np.abs(D).max(axis=1, keepdims=True)
    assert np.all(np.abs(K[:, : eq.nunk] - D) <= 1e-8 * scale)


def test_jacobian_matches_a_dense_difference_on_8_by_4():
    """The whole Jacobian (the sparse part and the volume pressure's rank-6 rest U Vᵀ) against
    central differences of the residual column by column, 8 × 4 nodes: agreement to the
    differences' truncation and round-off (h = 1e-6: h² ~ 1e-12 and ε_mach/h ~ 1e-10 relative), row
    by row (the tangential tether, 1e3 times the normal one, would hide a bending entry in a global
    bound; measured 2e-10 of the row's largest entry, and without U Vᵀ 2.5e-3 absolute)."""
    _assert_jacobian_matches_a_dense_difference(_Equilibrium(_step(4)))


def test_saddle_order_puts_each_multiplier_after_its_unknowns_and_solves():
    """``_saddle_order`` is a permutation of the m rows, keeps the unknowns' order, puts every
    constraint multiplier after all the unknowns of its row; the LU in that order solves the
    step's saddle-point system J x = b with a backward error at round-off (1e-12 measured at
    32 × 16; bound 1e-9) and agrees with SuperLU's default ordering to the conditioning."""
    eq = _Equilibrium(_step(8))
    order = eq.lu_order
    assert np.array_equal(np.sort(order), np.arange(eq.m))
    B = eq._constraint_matrix(eq.state0).tocsr()
    place = np.empty(eq.m, dtype=np.int64)
    place[order] = np.arange(eq.m)
    unk = order[order < eq.nunk]
    assert np.all(np.diff(place[unk]) > 0)
    for i in range(eq.ncon):
        cols = B.indices[B.indptr[i]:B.indptr[i + 1]]
        assert place[eq.nunk + eq.npin + i] > place[cols].max()
    st, mu = _perturbed(eq)
    J = eq.jacobian(st, mu, 1.0).tocsc()
    b = np.random.default_rng(0).standard_normal(eq.m)
    x = _lu_solve(J, order)(b)
    assert np.linalg.norm(J @ x - b) <= 1e-9 * np.linalg.norm(b)
    x_ref = _lu_solve(J)(b)
    assert np.linalg.norm(x - x_ref) <= 1e-6 * np.linalg.norm(x_ref)


def test_saddle_order_without_constraints_and_with_pins():
    """No constraint rows: the unknowns in their order, then the pins' multipliers."""
    unknowns = np.array([2, 0, 1])
    order = _saddle_order(unknowns, sp.csr_matrix((0, 3)), 2)
    assert order.tolist() == [2, 0, 1, 3, 4]
    # a constraint row on unknowns 0 and 2 goes after 0 (the later of the two in the order)
    order = _saddle_order(unknowns, sp.csr_matrix(np.array([[1.0, 0.0, 1.0]])), 1)
    assert order.tolist() == [2, 0, 4, 1, 3]


@pytest.mark.parametrize("bad", [-0.1, 1.0, True, "0.1"])
def test_helfrich_flow_rejects_a_reuse_outside_0_1(bad):
    from cartan_kirchhoff_love.vesicle import helfrich_flow

    with pytest.raises(ValueError, match="reuse must be in"):
        helfrich_flow(ellipsoid_problem(4, 0.9), steps=1, reuse=bad)
