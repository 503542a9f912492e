"""``solve_static`` on free and closed filaments (the rigid-body gauge ``pins="rigid"``) and
prescribed end rotations (``cartan_filament.ends``), against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_filament.ends import rotation_matrix, turned_end
from cartan_verification.case import observed_orders
from test_filament import registered  # noqa: F401

import cartan
from cartan.problem import NodeForce
from cartan.statics import ConvergenceError, UnsupportedRigidMotion


def _ring(n: int, loads: list | None = None, **params):
    rod = cartan.medium("filament", **params)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "ring"), {}, loads or []), grid


def _diametral(n: int, P: float):
    """Two opposite forces P pressing the ring R = 1 at nodes 0 (x = R) and n/2 (x = −R)."""
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return [NodeForce(grid, force=[-P, 0, 0, 0, 0, 0], node=0), NodeForce(grid, force=[P, 0, 0, 0, 0, 0], node=n // 2)]


def test_closed_ring_diametral_compression():
    """A closed ring (R = 1, B = 1) pressed by two opposite forces P, solved by ``solve_static``
    with the rigid-body gauge (node 0 held in position and rotation): the diameter along the
    loads shortens by δ = (π/4 − 2/π)PR³/B and the one across grows by (2/π − 1/2)PR³/B
    (inextensible thin ring, Castigliano; Timoshenko, Strength of Materials I, §83; Roark,
    Table 9.2 case 1: 0.1488 and 0.1366 PR³/EI), to O(h²) on the periodic lattice; the gauge
    carries no load (the forces balance) and the constraints hold on every edge."""
    P = 1e-4  # the O(P) nonlinearity is 1e-4 of the result, below the O(h²) errors
    along, across = math.pi / 4 - 2 / math.pi, 2 / math.pi - 0.5
    errors = []
    for n in (16, 32, 64):
        prob, _ = _ring(n, _diametral(n, P), twist=0.7)
        ds = cartan.solve_static(prob, pins="rigid")
        x = ds["position"].isel(time=0).values
        short = (2.0 - (x[0, 0] - x[n // 2, 0])) / P
        grow = ((x[n // 4, 1] - x[3 * n // 4, 1]) - 2.0) / P
        errors.append(max(abs(short - along) / along, abs(grow - across) / across))
        assert ds.attrs["constraint_residual_max"] <= 1e-13
        assert float(np.max(np.abs(ds["reaction"].values))) <= 1e-14 * P / 1e-4  # round-off of the balance
    # measured 6.7e-2, 1.7e-2, 4.2e-3: order 2.00
    orders = observed_orders(errors)
    assert all(abs(p - 2.0) <= 0.1 for p in orders), (errors, orders)
    assert errors[-1] <= 5e-3


def test_overcurved_ring_relaxes_to_the_circle():
    """A closed ring of natural curvature κ₀ = 1.3 ≠ 1/R (inextensible: L = 2πR fixed) started
    from a perturbed polygon settles on a circle of radius L/2π: every edge carries the
    curvature 1/R, the internal force n = 0 and the moment B(1/R − κ₀)."""
    n, kappa0 = 24, 1.3
    prob, grid = _ring(n, rest_curvature=[0.0, kappa0], twist=0.8)
    Phi = np.array(prob.initial.Phi)
    u = grid.coordinates(0)
    Phi[:, 1:3, 0] *= (1.0 + 0.02 * np.cos(2 * u))[:, None]  # an oval start: not adapted, not closed-form
    Phi[:, 3, 0] += 0.01 * np.sin(3 * u)
    ds = cartan.solve_static(prob, initial=Phi, pins="rigid")
    X = ds["X"].isel(time=0).values  # edge strains (θ; π)
    r = ds["position"].isel(time=0).values
    radius = np.linalg.norm(r - r.mean(axis=0), axis=-1)
    # the lattice's edges are exact screw motions (X = log(Φᵢ⁻¹Φⱼ)/h): arcs of length h, nodes on the circle
    assert np.max(np.abs(radius - grid.length[0] / (2 * math.pi))) <= 1e-10
    assert np.max(np.abs(r - Phi[:, 1:, 0])) >= 1e-2  # it did move from the oval start
    kappa = np.hypot(X[:, 4], X[:, 5])
    assert np.max(np.abs(kappa - kappa[0])) <= 1e-10 and abs(kappa[0] - 1.0) <= 1e-12
    assert np.max(np.abs(ds["constraint_force"].isel(time=0).values)) <= 1e-10
    assert ds.attrs["constraint_residual_max"] <= 1e-13


def test_rigid_gauge_refuses_unbalanced_loads_and_clamped_bodies():
    """A free body under an unbalanced load has no equilibrium: the gauge would carry it, and the
    solve says so; ``"rigid"`` on a clamped body, or another text, is refused; without pins the
    free ring's Jacobian is singular and the message points to the gauge."""
    P = 1e-3
    prob, grid = _ring(16, _diametral(16, P)[:1])
    with pytest.raises(ValueError, match="unbalanced"):
        cartan.solve_static(prob, pins="rigid")
    with pytest.raises(ValueError, match="pins must be"):
        cartan.solve_static(prob, pins="free")
    prob, _ = _ring(16, _diametral(16, P))
    with (pytest.warns(UnsupportedRigidMotion, match="pins='rigid' for a free body"),
          pytest.raises(ConvergenceError, match="pins='rigid'")):
        cartan.solve_static(prob, adaptive_load=False, rigid_gauge=False)
    rod = cartan.medium("filament")
    line = cartan.Grid(5, length=1.0)
    clamped = cartan.Problem(rod, line, rod.initial_state(line, "straight"), {"start": cartan.Clamped()})
    with pytest.raises(ValueError, match="clamped"):
        cartan.solve_static(clamped, pins="rigid")
    periodic = cartan.Grid(8, length=1.0, periodic=True)  # a straight filament periodic up to a translation by L
    H = np.eye(4)
    H[1, 0] = 1.0
    init = cartan.problem.InitialState(Phi=rod.initial_state(periodic, "straight").Phi, holonomy=H)
    with pytest.raises(ValueError, match="holonomy"):
        cartan.solve_static(cartan.Problem(rod, periodic, init, {}), pins="rigid")


def _cantilever(n: int = 11, **params):
    rod = cartan.medium("filament", **params)
    grid = cartan.Grid(n, length=1.0)
    return rod, grid, rod.initial_state(grid, "straight")


def test_end_twist_and_end_rotation():
    """The end of a clamped straight filament (L = 1) turned and held in rotation only (pins
    3, 4, 5; its position free): twisted by φ about its axis, the twist is φ/L on every edge
    and the torque Cφ/L; turned by α about d₃, the filament is the circular arc of curvature
    α/L with its tip at (L sin α/α, L(1 − cos α)/α) and the end moment Bα/L — exact on the
    lattice (uniform strains)."""
    C, B, phi, alpha = 0.7, 1.3, 2.0, 1.0
    rod, grid, init = _cantilever(twist=C, bending=B)
    ds = cartan.solve_static(cartan.Problem(rod, grid, turned_end(init, [phi, 0, 0]), {"start": cartan.Clamped()}),
                             pins={"end": (3, 4, 5)})
    X = ds["X"].isel(time=0).values
    assert np.max(np.abs(X[:, 3] - phi)) <= 1e-12 and np.max(np.abs(X[:, 4:])) <= 1e-12
    assert np.max(np.abs(ds["reaction"].values - [C * phi, 0, 0])) <= 1e-10
    ds = cartan.solve_static(cartan.Problem(rod, grid, turned_end(init, [0, 0, alpha]), {"start": cartan.Clamped()}),
                             pins={"end": (3, 4, 5)})
    tip = ds["position"].isel(time=0, node=-1).values
    assert np.max(np.abs(tip - [math.sin(alpha) / alpha, (1 - math.cos(alpha)) / alpha, 0.0])) <= 1e-12
    assert np.max(np.abs(ds["reaction"].values - [0, 0, B * alpha])) <= 1e-10
    with pytest.raises(ValueError, match="rotation"):
        turned_end(init, [1.0, 2.0])
    with pytest.raises(ValueError, match="end must be"):
        turned_end(init, [0, 0, 1], end="middle")


def test_end_rotation_grown_to_a_full_circle():
    """The end rotation grown in eight steps of π/4 to α = 2π, each solve started from the last
    equilibrium with its end turned further: the arcs pass through every closed-form tip
    position, and at α = 2π the filament closes on itself (tip back at the clamp)."""
    rod, grid, init = _cantilever(n=17)
    ds, start = None, init
    for k in range(1, 9):
        alpha = k * math.pi / 4
        start = turned_end(start if ds is None else ds, [0, 0, math.pi / 4])
        ds = cartan.solve_static(cartan.Problem(rod, grid, start, {"start": cartan.Clamped()}), pins={"end": (3, 4, 5)})
        tip = ds["position"].isel(time=0, node=-1).values
        assert np.max(np.abs(tip - [math.sin(alpha) / alpha, (1 - math.cos(alpha)) / alpha, 0.0])) <= 1e-11, k
    E = ds["frame"].isel(time=0, node=-1).values
    assert np.max(np.abs(E - rotation_matrix([0, 0, 2 * math.pi]))) <= 1e-11  # the end frame back to the identity


def test_free_free_filament_under_end_moments():
    """The gauge serves an open free–free filament as well: opposite end moments ∓M bend it into
    the arc of curvature M/B on every edge (exact: uniform strains), node 0 carrying no load."""
    B, M = 1.5, 1.0
    rod, grid, init = _cantilever(bending=B)
    ends = {"start": cartan.Free(load=[0, 0, 0, 0, 0, -M]), "end": cartan.Free(load=[0, 0, 0, 0, 0, M])}
    ds = cartan.solve_static(cartan.Problem(rod, grid, init, ends), pins="rigid")
    X = ds["X"].isel(time=0).values
    assert np.max(np.abs(X[:, 5] - M / B)) <= 1e-12 and np.max(np.abs(X[:, 3:5])) <= 1e-12
    assert np.max(np.abs(ds["reaction"].values)) <= 1e-14


def test_rigid_gauge_in_scenes_and_continuation():
    """``pins = "rigid"`` in a static scene and in ``continuation``: the overcurved ring (no load)
    stays the circle, the gauge carries nothing; on a clamped body the scene refuses it by key."""
    from cartan.scene import SceneError, load_scene

    base = {"name": "ring-gauge", "medium": "filament", "parameters": {"rest_curvature": [0.0, 1.3], "twist": 0.8},
            "grid": {"n": 16, "length": 2 * math.pi, "periodic": True}, "initial": {"kind": "ring"}}
    ds = load_scene({**base, "mode": "static", "static": {"pins": "rigid"}}).run()
    X = ds["X"].isel(time=0).values
    assert np.max(np.abs(np.hypot(X[:, 4], X[:, 5]) - 1.0)) <= 1e-10
    prob, _ = _ring(16, _diametral(16, 1e-4), twist=0.7)  # the diametral pair, balanced, along λ
    path = cartan.continuation(prob, lam_max=1.0, ds0=0.5, pins="rigid", max_points=6, detect=False)
    x = path["position"].isel(path=-1).values
    assert float(path["load_factor"][-1]) == pytest.approx(1.0)
    assert abs((2.0 - (x[0, 0] - x[8, 0])) / 1e-4 - (math.pi / 4 - 2 / math.pi)) <= 0.1  # the n = 16 solve's 6.7 %
    clamped = {**base, "grid": {"n": 16, "length": 1.0}, "initial": {"kind": "straight"},
               "boundaries": {"start": {"kind": "clamped"}}, "mode": "static", "static": {"pins": "rigid"}}
    with pytest.raises(SceneError, match="static.pins"):
        load_scene(clamped)
