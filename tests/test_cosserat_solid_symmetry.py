"""Symmetry planes of the micropolar solid: the octant of the uniaxially compressed block.

The homogeneous stretch is exact on the lattice, and the penalised symmetry planes move it by
an exactly known offset (module docstring of :mod:`cartan_cosserat_solid.cases`), so the octant
meets the closed form and the whole block to round-off: the tolerance 1e-10 is the case's
(round-off plus the Newton tolerance 1e-12 of the nodal load amplified by the 10⁴ penalty).
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_cosserat_solid.cases import UniaxialStressBlock, UniaxialStressOctant, uniaxial_stress

import cartan

OCTANT = UniaxialStressOctant()
TOL = OCTANT.tolerance


def _solve(case, level):
    problem, settings = case.problem(level)
    return problem, case.solve(problem, settings)


@pytest.fixture(scope="module")
def octants():
    return {level: _solve(OCTANT, level) for level in OCTANT.levels}


def test_octant_is_registered():
    case = cartan.registry("cases")["solid-uniaxial-stress-octant"]
    assert isinstance(case, UniaxialStressOctant) and case.kind == "convergence"


@pytest.mark.parametrize("level", OCTANT.levels)
def test_octant_meets_the_closed_form_at_round_off(octants, level):
    problem, ds = octants[level]
    assert problem.grid.shape == (2**level + 1,) * 3
    assert OCTANT.error(ds, problem) < TOL


def test_penalty_offset_is_real_and_exact(octants):
    """Without the offset δ = −2p/(k h_u) of the penalised plane u = 0 the error is far above round-off;
    with it the plane's nodes sit at δ exactly, while the lateral planes carry no force and stay put."""
    problem, ds = octants[1]
    c = problem.medium.constants
    s1, s2, E, _ = uniaxial_stress(OCTANT.load, c["lam"], c["mu"], c["kappa"])
    exact = OCTANT.exact_positions(problem, s1, s2)
    pos = ds["position"].values[-1]
    scale = OCTANT.load * OCTANT.length[0] / E
    delta = exact[0, 0, 0, 0]
    assert delta < 0 and abs(delta) > 1e4 * TOL * scale
    assert np.max(np.abs(pos[0, ..., 0] - delta)) < TOL * scale
    assert np.max(np.abs(pos[:, 0, :, 1])) < TOL * scale and np.max(np.abs(pos[:, :, 0, 2])) < TOL * scale


class _SoftOctant(UniaxialStressOctant):
    penalty = 1e2


def test_softer_planes_move_by_the_predicted_offset(octants):
    """The offset scales as 1/k: a 100× softer plane moves 100× more, still exactly."""
    soft = _SoftOctant()
    problem, ds = _solve(soft, 1)
    assert soft.error(ds, problem) < TOL
    ratio = ds["position"].values[-1][0, :, :, 0] / octants[1][1]["position"].values[-1][0, :, :, 0]
    assert np.max(np.abs(ratio - 100.0)) < 1e-6            # |δ| ≈ 1e-6: round-off 1e-15 relative to it is ~1e-9


@pytest.mark.parametrize("level", [1, 2])
def test_octant_agrees_with_the_eighth_of_the_whole_block(octants, level):
    """Octant level ℓ has the nodes of the whole block's level ℓ (n = 2^(ℓ+1) + 1) in the eighth
    u, v, w ≥ centre: positions (less δe₁, plus the centre), micro-rotations and stresses agree."""
    problem, ds = octants[level]
    whole_problem, whole = _solve(UniaxialStressBlock(), level)
    m = whole_problem.grid.shape[0] // 2
    eighth = (slice(m, None),) * 3
    c = problem.medium.constants
    s1, s2, E, _ = uniaxial_stress(OCTANT.load, c["lam"], c["mu"], c["kappa"])
    delta = OCTANT.exact_positions(problem, s1, s2)[0, 0, 0, 0]
    centre = 0.5 * np.asarray(whole_problem.grid.length)
    got = ds["position"].values[-1] - np.array([delta, 0.0, 0.0]) + centre
    ref = whole["position"].values[-1][eighth]
    assert got.shape == ref.shape
    assert np.max(np.abs(got - ref)) < TOL * OCTANT.load * OCTANT.length[0] / E
    fields = [f"microrotation_{x}" for x in "xyz"]
    fields += ["force_stress", "couple_stress"]
    for name in fields:
        scale = OCTANT.load if "stress" in name else OCTANT.load / E
        assert np.max(np.abs(ds[name].values[-1] - whole[name].values[-1][eighth])) < TOL * scale, name


def test_octant_scene_is_the_homogeneous_state():
    """The scene ``solid-compressed-octant-static`` (symmetry planes named in the scene file):
    the loaded face moves by −0.2/E plus the plane x = 0's offset −2·0.2/(k h) (k = 5e5, h = 1/4),
    the lateral faces by ν·0.2/E; exact on the lattice, so to the Newton tolerance."""
    ds = cartan.scene("solid-compressed-octant-static").run()
    _, _, E, nu = uniaxial_stress(0.2, 1.0, 1.0, 0.5)
    x = ds["position"].values[0]
    delta = -2.0 * 0.2 / (5e5 * 0.25)
    assert x[4, 2, 2, 0] - 1.0 == pytest.approx(-0.2 / E + delta, abs=1e-9)
    assert x[2, 4, 2, 1] - 1.0 == pytest.approx(nu * 0.2 / E, abs=1e-9)
    assert x[2, 2, 4, 2] - 1.0 == pytest.approx(nu * 0.2 / E, abs=1e-9)
