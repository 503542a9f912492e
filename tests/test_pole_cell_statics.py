"""Statics with the lattice's pole cells (``solve_static(..., pole="cap")``, ``Lattice(pole="cap")``).

The cap's energy couples every glued edge of a pole (the pole row's N nodes), so the Jacobian's
stencil (``cartan.statics._lattice_stencil``) adds the whole pole row to the stencil of each of its
nodes; the chord-length strains X″ are functions of their own edge and add no other pair.  Checked
here, on the vesicle flow's static step (``tests/test_glued_jacobian.py``'s ``_step``: the sphere's
chart, a normal tether, a volume pressure, the adaptation held by strain constraints): the colouring
separates every stencil (its colours measured: 18, 24, 42 at 8 × 4, 16 × 8, 32 × 16 nodes against
18, 16, 16 with the corners — a pole row's N nodes conflict pairwise, so at least N colours); the
coloured Jacobian equals a dense central difference of the residual at 8 × 4; the surface measures
with the cap converge to the sphere's 4π at order 2; a bad ``pole`` is refused by name.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("cartan_kirchhoff_love")
from cartan_kirchhoff_love.vesicle import surface_measures  # noqa: E402
from cartan_kirchhoff_love.vesicle_sphere import ellipsoid_problem  # noqa: E402
from test_glued_jacobian import _assert_jacobian_matches_a_dense_difference, _step  # noqa: E402

import cartan  # noqa: E402
from cartan.schemes.lattice import Lattice  # noqa: E402
from cartan.statics import _Equilibrium, _lattice_stencil  # noqa: E402


@pytest.mark.parametrize("n", [4, 8])
def test_cap_stencil_holds_the_pole_rows_and_separates_them(n):
    """Every pole-row node reaches the whole row; nodes of one colour have disjoint stencils; at
    least 2n colours (the row's 2n nodes conflict pairwise)."""
    sch = Lattice(_step(n), track_frames=True, pole="cap")
    colour, src, dst = _lattice_stencil(sch)
    nu, nv = sch.grid.shape
    idx = np.arange(nu * nv).reshape(nu, nv)
    pairs = set(zip(src.tolist(), dst.tolist(), strict=True))
    for row in (idx[:, 0], idx[:, -1]):
        assert all((int(i), int(j)) in pairs for i in row for j in row)
    counts = np.zeros((colour.max() + 1, colour.size), dtype=int)
    np.add.at(counts, (colour[src], dst), 1)
    assert counts.max() == 1
    assert colour.max() + 1 >= nu


def test_cap_jacobian_matches_a_dense_difference_on_8_by_4():
    """The whole Jacobian with the cap (sparse part and the volume pressure's rank-6 rest) against
    central differences of the residual column by column, 8 × 4 nodes, row by row: the differences'
    truncation and round-off (h = 1e-6: h² ~ 1e-12, ε_mach/h ~ 1e-10 relative; measured 1.4e-10 of
    the row's largest entry)."""
    eq = _Equilibrium(_step(4), pole="cap")
    assert eq.sch.pole == "cap"
    _assert_jacobian_matches_a_dense_difference(eq)


def test_cap_area_converges_at_order_2_on_the_sphere():
    """The cap lattice's area (corners with chord-length strains plus W|det T_p| per pole cell) of the
    unit sphere tends to 4π at order 2 (errors measured −9.5e-2, −2.5e-2, −6.4e-3 at 8 × 4, 16 × 8,
    32 × 16); the observed order between the two finer ones is in [1.8, 2.2]; the volume is the
    corner quadrature's, the same with either pole."""
    err = []
    for n in (8, 16):
        pb = ellipsoid_problem(n, 1.0 - 1e-9, spacing="arc")
        m = surface_measures(pb, pole="cap")
        err.append(m["area"] / (4.0 * math.pi) - 1.0)
        assert m["volume"] == surface_measures(pb)["volume"]
    order = math.log2(err[0] / err[1])
    assert 1.8 <= order <= 2.2


def test_solve_static_rejects_a_bad_pole():
    with pytest.raises(ValueError, match="pole must be one of"):
        cartan.solve_static(_step(4), pole="disc")



def test_helfrich_flow_rejects_a_bad_pole():
    from cartan_kirchhoff_love.vesicle import helfrich_flow

    with pytest.raises(ValueError, match="pole must be one of 'corners', 'cap'"):
        helfrich_flow(ellipsoid_problem(4, 0.9), steps=1, pole="disc")
