"""The problems ``cartan advise`` builds keep the stress-free reference configuration.

A rod with a curved rest shape (``Problem.reference``) released at that shape is at rest: its
potential energy is zero to round-off.  The held-strain twin (``held_strain_twin``) and the
planar limit of a rod on a sphere (``plane_limit_problem``, and the rod on the sphere of twice
the radius that the Richardson estimate runs) must keep that rest shape; built without it they
would start bent away from a straight rest shape, with a bending energy of order B κ² L, and
the advice would compare the scene with a different motion.  These tests build problems and
evaluate energies on numpy (nothing compiled).
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.advise import _sphere_variant, held_strain_twin, plane_limit_problem
from cartan.schemes.lattice import Lattice

#: relative round-off of a zero energy at a stress-free state (the rest strain is recomputed from
#: the reference frames with the group's log and exp: a few ulps per edge, squared in the energy)
ROUNDOFF = 1e-20


def _energy(problem: cartan.Problem) -> float:
    sch = Lattice(problem)
    return float(sch.potential_energy(sch.initial_state()))


def _rod(**extra):
    return cartan.medium("cosserat-rod", stretch_shear=[1e4, 1e4, 1e4], bend_twist=[0.8, 1.0, 1.0], mass=1.0,
                         rotational_inertia=[0.01, 0.01, 0.01], **extra)


def test_held_strain_twin_keeps_a_curved_rest_shape():
    """A rod whose rest shape is an arc of unit stretch (θ_ref = (1, 0, 0), the values the filament
    holds): the twin carries the reference, so that the arc is stress-free on the twin too."""
    rod, grid = _rod(), cartan.Grid(11, length=1.0)
    arc = rod.initial_state(grid, "arc", curvature=2.0)
    problem = cartan.Problem(rod, grid, arc, {"start": cartan.Clamped()}, reference=arc.Phi)
    assert _energy(problem) <= ROUNDOFF
    held, _ = held_strain_twin(problem)
    assert held.reference is not None
    np.testing.assert_array_equal(held.reference.Phi, problem.reference.Phi)
    assert _energy(held) <= ROUNDOFF
    straight = cartan.Problem(held.medium, grid, arc, {"start": cartan.Clamped()})  # the twin without it
    assert _energy(straight) > 0.1  # ½ B κ² L = ½ · 1 · 4 · 1 = 2 (the lattice's chord: within 10 %)


def test_held_strain_twin_refuses_a_stretched_rest_shape():
    """A rest shape stretched by 10 %: the filament holds θ₁ = 1, so it is no twin of this rod."""
    rod, grid = _rod(), cartan.Grid(11, length=1.0)
    arc = rod.initial_state(grid, "arc", curvature=2.0)
    ref = np.array(arc.Phi, copy=True)
    ref[:, 1:, 0] *= 1.1
    problem = cartan.Problem(rod, grid, arc, {"start": cartan.Clamped()}, reference=ref)
    with pytest.raises(ValueError, match="reference"):
        held_strain_twin(problem)


@pytest.mark.parametrize("variant", ["plane", "double radius"])
def test_sphere_rod_variants_keep_a_curved_rest_shape(variant):
    """A rod on a sphere at rest in its curved rest shape (an arc of curvature 1 on the sphere):
    the planar limit and the rod on the sphere of radius 2r start stress-free as well, with the
    same physical rest strains."""
    grid = cartan.Grid(21, length=2.0)
    rod = cartan.medium("sphere-rod", radius=40.0, stiffness=[20.0, 10.0], bending=1.0, density=1.0,
                        rotational_inertia=0.05)
    arc = rod.initial_state(grid, "arc", curvature=1.0, centered=True)
    problem = cartan.Problem(rod, grid, arc, {"start": cartan.Clamped(), "end": cartan.Free()},
                             [rod.make_load("drag", gamma_T=2.0, gamma_R=0.5)], reference=arc.Phi)
    assert _energy(problem) <= ROUNDOFF
    other = plane_limit_problem(problem) if variant == "plane" else _sphere_variant(problem, 2.0 * rod.radius)
    assert other.reference is not None
    assert _energy(other) <= ROUNDOFF
    bare = cartan.Problem(other.medium, grid, other.initial, other.boundaries, other.loads)  # without it
    assert _energy(bare) > 0.5  # ½ B κ² L = 1 (straight rest shape)
