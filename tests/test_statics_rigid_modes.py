"""Rigid motions left free by the supports of a static problem (``cartan.rigid_modes``, issue 14).

A rigid motion ``Φ_i → exp(εξ)Φ_i`` leaves every strain unchanged; ``solve_static`` finds on its
first Jacobian the ξ that no support blocks and no load stiffens, warns
(:class:`~cartan.rigid_modes.UnsupportedRigidMotion`) naming them, and raises a ``ValueError``
when the loads have power along one (no equilibrium exists)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import cartan
from cartan.problem import NodeForce
from cartan.rigid_modes import UnsupportedRigidMotion, describe_motion
from cartan.statics import _Equilibrium, _rigid_motions, solve_static

TRANSLATIONS = ["translation along (1, 0, 0)", "translation along (0, 1, 0)", "translation along (0, 0, 1)"]
ROTATIONS_AT_0 = [f"rotation about {a} through (0, 0, 0)" for a in ("(1, 0, 0)", "(0, 1, 0)", "(0, 0, 1)")]


def _rod(boundaries=None, loads=(), n=11):
    rod = cartan.medium("cosserat-rod", stretch_shear=[1e3] * 3, bend_twist=[1.0] * 3, mass=1.0,
                        rotational_inertia=[1.0] * 3)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries or {}, list(loads))


def _ring(n=16, loads=()):
    rod = cartan.medium("filament")
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "ring"), {}, list(loads)), grid


def _names(ds):
    return ds.attrs["unsupported_rigid_motion_names"].split("; ")


def _free(problem, **kw):
    """The free rigid motions of ``problem`` at its start (λ = 1), as solve_static finds them."""
    eq = _Equilibrium(problem, **kw)
    J, low = eq.jacobian(eq.state0, np.zeros(eq.nmult), 1.0, None, low_rank=True)
    return _rigid_motions(eq, J, low, 1.0)


# ---------------------------------------------------------------------------- free directions found and named
def test_a_free_rod_and_a_free_ring_leave_every_rigid_motion_free():
    """No support at all: the six rigid motions of SE(3), named in words; the unloaded bodies are
    at equilibrium, so the solve returns the start and records them."""
    with pytest.warns(UnsupportedRigidMotion, match="6 rigid motion") as rec:
        ds = solve_static(_rod())
    assert len(rec) == 1  # warned once
    assert ds.attrs["unsupported_rigid_motions"] == 6
    assert _names(ds) == TRANSLATIONS + ROTATIONS_AT_0
    assert "pins=" in str(rec[0].message) and "Held" in str(rec[0].message)
    ring, _ = _ring()
    with pytest.warns(UnsupportedRigidMotion, match="6 rigid motion"):
        ds = solve_static(ring)
    assert _names(ds) == TRANSLATIONS + ROTATIONS_AT_0
    xi = np.asarray(ds.attrs["unsupported_rigid_motion_directions"]).reshape(6, 6)
    assert np.linalg.matrix_rank(xi) == 6


@pytest.mark.parametrize("how", ["held", "pins"])
def test_a_rod_pinned_in_translation_only_turns_about_the_pin(how):
    """A ball joint at node 0 (x = 0) by a Held end or by pins: the three rotations about axes
    through it stay free; with an axial dead tension at the other end the bending rotations are
    stiffened by the load (its moment arm), the twist about the rod's own axis is not."""
    kw = {"pins": {0: (0, 1, 2)}} if how == "pins" else {}
    ends = {"start": cartan.Held((0, 1, 2))} if how == "held" else {}
    with pytest.warns(UnsupportedRigidMotion, match="3 rigid motion"):
        ds = solve_static(_rod(ends), **kw)
    assert _names(ds) == ROTATIONS_AT_0
    tension = _rod({**ends, "end": cartan.Free(load=[1.0, 0, 0, 0, 0, 0])})
    free = _free(tension, **kw)
    assert free.names == [ROTATIONS_AT_0[0]] and not free.loaded
    # the loads' part resists the two bending rotations far above its bound (ratios > 1: resisted), the
    # internal part none (its ratios first, the loads' after them)
    internal, load = free.stiffness[:3], free.stiffness[3:]
    assert np.all(internal <= 1e-3) and np.all(load[:2] > 1e3) and load[2] <= 1e-3


def test_a_planar_rod_with_one_held_translation():
    """SE(2): node 0's x held by a pin leaves the translation along y and the rotation about the
    pinned point (the origin) free; named in the plane."""
    rod = cartan.medium("planar-cosserat-rod", stretch_shear=[1e3, 1e3], bending=1.0, mass=1.0,
                        rotational_inertia=1.0)
    grid = cartan.Grid(9, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {})
    with pytest.warns(UnsupportedRigidMotion, match="2 rigid motion"):
        ds = solve_static(prob, pins={0: (0,)})
    assert _names(ds) == ["translation along (0, 1)", "rotation about the point (0, 0)"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solve_static(prob, pins={0: (0, 1, 2)})  # every component of node 0: silent


def test_describe_motion_names_screws_and_points():
    se3, se2, so3 = cartan.group("SE3"), cartan.group("SE2"), cartan.group("SO3")
    p = np.array([0.0, 2.0, 0.0])
    w = np.array([0.0, 0.0, 1.0])
    assert describe_motion(se3, np.concatenate([-np.cross(w, p), w])) == "rotation about (0, 0, 1) through (0, 2, 0)"
    assert describe_motion(se3, np.concatenate([-np.cross(w, p) + 0.5 * w, w])).startswith("screw about (0, 0, 1)")
    assert describe_motion(se2, [2.0, 0.0, 0.0]) == "translation along (1, 0)"
    assert describe_motion(se2, [1.0, -3.0, 1.0]) == "rotation about the point (3, 1)"  # W p + v = 0
    assert describe_motion(so3, [0.0, 2.0, 0.0]) == "rotation about (0, 1, 0)"
    poincare = cartan.group("Poincare")
    assert describe_motion(poincare, np.eye(poincare.dim)[0]).startswith("Poincare Lie-algebra direction ξ = (1, 0")


# ---------------------------------------------------------------------------- loads with power: no equilibrium
def test_an_unbalanced_load_on_a_free_direction_is_refused():
    """A free rod under a dead end force, or a ring under one of two opposite forces: the
    resultant has power along a free translation, so no equilibrium exists (ValueError naming
    it); the balanced pair only warns."""
    with pytest.raises(ValueError, match=r"power along translation along \(0, 0, -1\)"):
        solve_static(_rod({"end": cartan.Free(load=[0.0, 0.0, -1.0, 0.0, 0.0, 0.0])}))
    with pytest.raises(ValueError, match=r"power along rotation about \(0, 0, 1\)"):  # an end couple
        solve_static(_rod({"start": cartan.Held((0, 1, 2)), "end": cartan.Free(load=[0, 0, 0, 0, 0, 1.0])}))
    n = 16
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    pair = [NodeForce(grid, force=[-1e-3, 0, 0, 0, 0, 0], node=0), NodeForce(grid, force=[1e-3, 0, 0, 0, 0, 0],
                                                                              node=n // 2)]
    with pytest.raises(ValueError, match=r"power along translation along \(-1, 0, 0\)"):
        solve_static(_ring(n, pair[:1])[0])
    free = _free(_ring(n, pair)[0])
    # the dead pair along x stiffens the rotations about y and z (its moment arm), not the one about x
    assert free.names == TRANSLATIONS + [ROTATIONS_AT_0[0]] and not free.loaded


# ---------------------------------------------------------------------------- well-posed problems: silent
def test_supported_problems_are_silent():
    """A cantilever, a ring under the rigid-body gauge, a rod on an elastic foundation (a load that
    stiffens every rigid motion) and a rod pinned at both ends with one end's twist held."""
    from test_statics import _rod_on_foundation

    cases = [
        (_rod({"start": cartan.Clamped(), "end": cartan.Free(load=[0, 0, -1.0, 0, 0, 0])}), {}),
        (_ring(16, [])[0], {"pins": "rigid"}),
        (_rod_on_foundation(), {}),
        (_rod({"start": cartan.Held((0, 1, 2, 3, 4)), "end": cartan.Free(load=[0, 1.0, 0, 0, 0, 0])}),
         {"pins": {-1: (1, 2)}}),
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnsupportedRigidMotion)
        for prob, kw in cases:
            ds = solve_static(prob, **kw)
            assert ds.attrs["unsupported_rigid_motions"] == 0
            assert "unsupported_rigid_motion_names" not in ds.attrs


# ---------------------------------------------------------------------------- the gauge rows (rigid_gauge)
def test_the_gauge_gives_the_pinned_equilibrium_without_its_rigid_motion():
    """A free ring pressed by a balanced diametral pair: with the default gauge rows the solve
    converges (without them the LU meets the zero pivot of the free translations), to the
    equilibrium of the rigid-body gauge (node 0 pinned) up to a rigid motion: the same strains
    to round-off and the Newton tolerance, the gauge rows' multipliers (the loads' power along the
    free motions) zero, and no mean rigid motion left."""
    from cartan.statics import ConvergenceError

    n, P = 16, 1e-4
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    pair = [NodeForce(grid, force=[-P, 0, 0, 0, 0, 0], node=0), NodeForce(grid, force=[P, 0, 0, 0, 0, 0],
                                                                           node=n // 2)]
    prob, _ = _ring(n, pair)
    with pytest.warns(UnsupportedRigidMotion, match="held at their mean"):
        gauged = solve_static(prob)
    pinned = solve_static(prob, pins="rigid")
    X_g, X_p = (ds["X"].isel(time=0).values for ds in (gauged, pinned))
    assert np.max(np.abs(X_g - X_p)) <= 1e-9 * P / 1e-4  # Newton tolerances of both solves (1e-10·f)
    names = [str(h) for h in gauged["held"].values]
    assert names == [f"rigid_motion_{k}" for k in range(4)]
    assert np.max(np.abs(gauged["held_value"].values)) <= 1e-10 * 2 * math.pi  # C_k = 0 to tol·s
    assert np.max(np.abs(gauged["held_multiplier"].values)) <= 1e-12  # no power along the free motions
    # the pinned solution is the gauged one moved rigidly: every node by the same g = Φ_p Φ_g⁻¹
    pos_g, pos_p = gauged["position"].isel(time=0).values, pinned["position"].isel(time=0).values
    fr_g, fr_p = gauged["frame"].isel(time=0).values, pinned["frame"].isel(time=0).values
    R = fr_p[0] @ fr_g[0].T
    t = pos_p[0] - R @ pos_g[0]
    assert np.max(np.abs(pos_g @ R.T + t - pos_p)) <= 1e-9
    assert np.max(np.abs(np.einsum("ij,njk->nik", R, fr_g) - fr_p)) <= 1e-9
    with pytest.warns(UnsupportedRigidMotion, match="singular along them"), pytest.raises(ConvergenceError):
        solve_static(prob, rigid_gauge=False, adaptive_load=False)
    with pytest.raises(ValueError, match="rigid_gauge must be True or False"):
        solve_static(prob, rigid_gauge="yes")


def test_a_soft_support_resists_against_its_own_size():
    """The whole Scordelis–Lo roof holds its axial translation by a spring of 1e-8 Et/L² on the
    diaphragms, 2e-17 of the diaphragm penalty beside it: the loads' part of the Jacobian is
    measured row by row (against its own size), so the spring resists and the roof is silent;
    without the spring the axial translation is free and named."""
    from test_cosserat_surface_shells import whole_roof

    from cartan.problem import Problem
    from cartan.supports import PenaltySupport

    prob, _ = whole_roof(9)
    free = _free(prob)
    assert free.count == 0 and np.max(free.stiffness) > 1e3  # the spring: 1.3e4 times its bound at n = 17
    spring = prob.loads[1]
    stiff = spring.k.copy()
    stiff[1] = 0.0
    bare = PenaltySupport(list(spring.edges), stiff, 0.0).hold(prob.initial.Phi)
    free = _free(Problem(prob.medium, prob.grid, prob.initial, loads=[prob.loads[0], bare]))
    assert free.names == ["translation along (0, 1, 0)"] and not free.loaded
