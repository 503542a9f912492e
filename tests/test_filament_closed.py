"""Closed filaments and the gauge parameter of the Kirchhoff filament (paper §III.E, §IV.E,
§VII.A): the circle as an equilibrium of a periodic lattice, Michell's instability of the twisted
ring, the ring pulled by diametral forces, a spinning ring in time (``rattle``), and the
``gauge`` parameter with its ``twist_angle`` output."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_verification.case import observed_orders, run_case

# the filament registered for these tests as for test_filament.py (its module fixture)
from test_filament import registered  # noqa: F401

import cartan
from cartan.statics import _Equilibrium


def _ring(n: int, **params):
    rod = cartan.medium("filament", **params)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return rod, grid


# ---------------------------------------------------------------------------- statics of the closed ring
def test_closed_ring_is_an_equilibrium():
    """The circle on a periodic lattice: every edge, the closing one included, carries
    θ = (1, 0, 0) and π = (0, 0, 1/R); with no load the forces and the constraint rows vanish
    at round-off with zero multipliers."""
    rod, grid = _ring(16)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "ring"), {})
    eq = _Equilibrium(prob, probe_lam=0.0)
    assert eq.ncon == 3 * 16  # one row per edge and component: the closing edge has its rows
    r = eq.residual(eq.state0, np.zeros(eq.nmult), 0.0)
    assert np.max(np.abs(r)) <= 1e-14
    X = eq.sch.edge_strains(eq.state0)[0]
    assert X.shape == (16, 6)
    np.testing.assert_allclose(np.abs(X), np.broadcast_to([1.0, 0.0, 0.0, 0.0, 0.0, 1.0], X.shape), atol=1e-14)


def test_twisted_ring_multipliers_and_michell():
    """A twist moment m₁ (natural twist): the circle stays an equilibrium, its multipliers are
    the binormal force n₃ = m₁/R on every edge, and it loses stability at m₁R/B → √3
    (Michell), with the lattice's critical value converging at second order."""
    from cartan_filament.cases import michell_ring

    out = [michell_ring(n) for n in (16, 32)]
    for o in out:
        assert o["equilibrium_residual"] <= 1e-13 and o["constraint_residual"] <= 1e-13
        assert abs(o["binormal_force"] - 1.0) <= 1e-12
        # K(t) is affine in the twist: the restricted block is singular at the computed t_c
        assert abs(o["eig_at_critical"]) <= 1e-9
    errors = [abs(o["critical"] - math.sqrt(3.0)) / math.sqrt(3.0) for o in out]
    assert abs(observed_orders(errors)[0] - 2.0) <= 0.2, errors
    assert errors[-1] <= 1.5e-2  # O(h²): 1.14e-2 at n = 32 (h = 0.196)
    # C enters the continuum criterion through m₁ only: a softer twist moves the lattice's critical
    # moment by a small part of its O(h²) error (4.9e-4 against 8.2e-2 at n = 16, measured)
    soft = michell_ring(16, twist=0.5)
    assert abs(soft["critical"] - out[0]["critical"]) <= 2e-2 * abs(out[0]["critical"] - math.sqrt(3.0))


def test_closed_ring_pulled_by_diametral_forces():
    """The ring pulled apart by two opposite forces P (continuation, node 0 held in position and
    rotation, the opposite node loaded and held out of plane): the diameter along the load
    grows by (π/4 − 2/π)PR³/B and the one across it shrinks by (2/π − 1/2)PR³/B (thin
    inextensible ring), to O(h²); the constraints hold on every edge, the closing one too."""
    P = 1e-4
    along, across = math.pi / 4 - 2 / math.pi, 2 / math.pi - 0.5
    errors = []
    for n in (16, 32):
        rod, grid = _ring(n, twist=0.7)
        load = cartan.problem.NodeForce(grid, force=[-P, 0.0, 0.0, 0.0, 0.0, 0.0], node=n // 2)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "ring"), {}, [load])
        ds = cartan.continuation(prob, 1.0, 1.0, pins={0: (0, 1, 2, 3, 4, 5), n // 2: (2,)}, detect=False)
        assert float(np.max(ds["constraint_residual"].values)) <= 1e-13
        d = ds["position"].isel(path=-1).values - ds["position"].isel(path=0).values
        grow, shrink = -d[n // 2, 0] / P, -2.0 * d[n // 4, 1] / P
        errors.append(max(abs(grow - along) / along, abs(shrink - across) / across))
    # O(h²): 6.8e-2 and 1.7e-2 (measured); the O(P) nonlinearity is 1e-4 of it
    assert abs(observed_orders(errors)[0] - 2.0) <= 0.2, errors
    assert errors[-1] <= 2e-2


# ---------------------------------------------------------------------------- the closed ring in time
def test_spinning_ring_rattle():
    """A closed ring spinning about its axis (ω = 1.5, rattle on the periodic lattice) is a
    relative equilibrium: the constraints hold on every edge at round-off, the radius and the
    plane are kept to round-off, the energy is conserved and the ring turns by ωt."""
    rod, grid = _ring(12, twist=0.8, mass=2.0)
    w = 1.5
    init = rod.initial_state(grid, "ring", rigid_velocity=[0.0, 0.0, 0.0, 0.0, 0.0, w], center=[0.0, 0.0, 0.0])
    # compiled=False: the Python step (a fast test compiles nothing on an empty numba cache)
    ds = cartan.simulate(cartan.Problem(rod, grid, init, {}), dt=1e-2, t_end=0.1, save_every=5, progress=False,
                         compiled=False)
    assert float(ds["constraint_residual"].max()) <= 1e-13
    pos = ds["position"].values
    assert np.max(np.abs(np.linalg.norm(pos[..., :2], axis=-1) - 1.0)) <= 1e-12
    assert np.max(np.abs(pos[..., 2])) <= 1e-12
    energy = (ds["kinetic_energy"] + ds["potential_energy"]).values
    assert np.ptp(energy) <= 1e-12 * energy[0]
    # the angle turned: RATTLE's O(Δt²) phase error (1.1e-5 measured at Δt = 1e-2)
    t = float(ds["time"][-1])
    assert abs(math.atan2(pos[-1, 0, 1], pos[-1, 0, 0]) - w * t) <= 1e-4


# ---------------------------------------------------------------------------- the gauge parameter
@pytest.mark.parametrize("bad", ["Frenet", "none", 1])
def test_gauge_parameter_checked(bad):
    with pytest.raises(ValueError, match="gauge must be one of 'material', 'bishop', 'frenet'"):
        cartan.medium("filament", gauge=bad)


def test_gauge_round_trip_and_default_unchanged():
    plain = cartan.medium("filament")
    assert "gauge" not in plain.parameters() and not plain.output_fields
    grid = cartan.Grid(9, length=1.0)
    for gauge in ("bishop", "frenet"):
        rod = cartan.medium("filament", gauge=gauge)
        assert cartan.medium("filament", **rod.parameters()).gauge == gauge
        assert set(rod.output_fields) == {"twist_angle"}
    # the straight initial state in the Bishop gauge: the frames are transported, i.e. unchanged
    a = plain.initial_state(grid, "straight").Phi
    b = cartan.medium("filament", gauge="bishop").initial_state(grid, "straight").Phi
    np.testing.assert_allclose(a, b, atol=1e-15)


def test_frenet_gauge_refuses_a_straight_piece():
    rod = cartan.medium("filament", gauge="frenet")
    with pytest.raises(ValueError, match=r"at node 0 \(arclength s = 0\).*gauge = 'bishop'"):
        rod.initial_state(cartan.Grid(11, length=1.0), "straight")
    # the output refuses it too, naming the node where the current centreline is straight
    X = np.zeros((5, 1, 6))
    X[:, 0, 0] = 1.0
    X[:, 0, 5] = [1.0, 1.0, 0.0, 1.0, 1.0]
    q = np.broadcast_to(np.eye(4), (5, 4, 4))
    with pytest.raises(ValueError, match="at node 2"):
        rod.outputs(q, X, np.zeros((5, 6)), cartan.Grid(5, length=1.0))


def test_twist_angle_of_a_twisted_ring():
    """A closed ring whose material frame turns k times about the tangent (frames given as
    ``arrays``): the twist angle relative to the Bishop frame is ks (φ′ = π₁, unwrapped), the one
    relative to the Frenet frame is ks plus the constant angle of the frames at s = 0; the Bishop
    and Frenet initial frames of the ring are its (inward normal, axis) frames."""
    n, k = 24, 2.0
    rod, grid = _ring(n, gauge="bishop")
    s = grid.coordinates(0)
    base = rod.initial_state(grid, "ring").Phi  # Bishop = Frenet frames of the circle
    E = base[:, 1:, 1:]
    np.testing.assert_allclose(E[:, :, 1], -base[:, 1:, 0], atol=1e-14)  # d₂ the inward normal
    c, sn = np.cos(k * s), np.sin(k * s)
    frames = E.copy()
    frames[:, :, 1] = c[:, None] * E[:, :, 1] + sn[:, None] * E[:, :, 2]
    frames[:, :, 2] = -sn[:, None] * E[:, :, 1] + c[:, None] * E[:, :, 2]
    Phi = base.copy()
    Phi[:, 1:, 1:] = frames
    prob = cartan.Problem(cartan.medium("filament"), grid, cartan.problem.InitialState(Phi=Phi), {})
    eq = _Equilibrium(prob, probe_lam=0.0)
    X = eq.sch.nodal_strains(eq.state0)
    # π₁ the same on every edge, k to O(h²) (the edge's rotation composes the turn and the twist)
    assert np.ptp(X[:, 0, 3]) <= 1e-13 and abs(X[0, 0, 3] - k) <= 0.2 * (k * grid.spacing[0]) ** 2
    bishop = rod.outputs(Phi, X, np.zeros((n, 6)), grid)["twist_angle"]
    np.testing.assert_allclose(bishop, k * s, atol=1e-12)
    frenet = cartan.medium("filament", gauge="frenet").outputs(Phi, X, np.zeros((n, 6)), grid)["twist_angle"]
    np.testing.assert_allclose(np.unwrap(frenet), k * s, atol=1e-12)


def test_twist_angle_recorded_by_solve_static():
    """A clamped helix-shaped filament (natural curvature 0.8, twist 0.4) relaxes to its rest
    helix; recorded with gauge "frenet" the twist angle is 0 (the material frame is the Frenet
    frame), with gauge "bishop" it grows as τs = 0.4s to O(h²)."""
    a, b = 1.0, 0.5
    L = 2 * math.pi * math.hypot(a, b)
    grid = cartan.Grid(21, length=L)
    out = {}
    for gauge in ("frenet", "bishop"):
        rod = cartan.medium("filament", gauge=gauge, rest_curvature=[0.0, 0.8], rest_twist=0.4)
        init = rod.initial_state(grid, "helix", radius=a, pitch=2 * math.pi * b)
        ds = cartan.solve_static(cartan.Problem(rod, grid, init, {"start": cartan.Clamped()}), max_iter=30)
        out[gauge] = ds["twist_angle"].isel(time=0).values
    s = grid.coordinates(0)
    assert np.max(np.abs(out["frenet"])) <= 1e-10
    # O(h²) (h = 0.35): 0.6 % of 0.4L measured at n = 41
    assert np.max(np.abs(out["bishop"] - 0.4 * s)) <= 0.03 * 0.4 * L


# ---------------------------------------------------------------------------- the plectoneme scene
def test_plectoneme_scene_reads():
    """The scene builds: both ends clamped, the arc's edges meet θ = (1, 0, 0) exactly, the Bishop
    frames carry no twist (π₁ = 0), so the stored twist energy is ½C(π₁⁰)²L."""
    sc = cartan.scene("filament-plectoneme")
    prob = sc.problem
    assert prob.medium.gauge == "bishop" and set(prob.boundaries) == {"start", "end"}
    eq = _Equilibrium(prob, probe_lam=0.0)
    X = eq.sch.edge_strains(eq.state0)[0]
    assert np.max(np.abs(X[:, :3] - [1.0, 0.0, 0.0])) <= 1e-13
    assert np.max(np.abs(X[:, 3])) <= 1e-13
    pi0 = prob.medium.rest_curvature_twist()[0]
    assert abs(eq.sch.potential_energy(eq.state0) - (0.5 * pi0**2 + 0.5 * 1.5**2) * 2.0) <= 1e-9


# ---------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_plectoneme_scene_buckles_out_of_plane():
    """The first 1.5 time units of the scene (compiles the rattle loop with a node force): the
    twisted arc leaves its plane, the constraints hold at round-off, the energy balance holds."""
    sc = cartan.scene("filament-plectoneme")
    ds = sc.simulate(t_end=1.5, progress=False)
    z = np.abs(ds["position"].values[..., 2]).max(axis=-1)
    assert z[0] == 0.0 and z[-1] >= 0.1  # 0.26 measured at t = 1.5
    assert float(ds["constraint_residual"].max()) <= 1e-12
    balance = (ds["kinetic_energy"] + ds["potential_energy"] + ds["dissipated_energy"] - ds["external_work"]).values
    assert np.max(np.abs(balance - balance[0])) <= 5e-3 * balance[0]  # 1.8e-3 measured (Δt = 2e-3)
    assert "twist_angle" in ds and ds["twist_angle"].dims == ("time", "node")


@pytest.mark.slow
def test_michell_case_all_levels():
    from cartan_filament.cases import MichellRing

    case = MichellRing()
    errors = [run_case(case, level)[0] for level in case.levels]
    assert errors[-1] <= case.tolerance
    assert np.all(np.abs(observed_orders(errors) - 2.0) <= 0.1), errors


@pytest.mark.slow
@pytest.mark.parametrize("gauge", ["bishop", "frenet"])
def test_conformance_with_gauge(gauge):
    """The medium contract with the gauge's output field (``twist_angle``) declared and recorded."""
    from cartan.testing import check_medium

    check_medium("filament", {"gauge": gauge})
