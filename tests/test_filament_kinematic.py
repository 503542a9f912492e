"""The filament's kinematics: adapted frames in the Frenet and Bishop gauges
(``cartan_filament.gauges``) and the binormal flow through the ``kinematic`` integrator
(``cartan_filament.binormal``, ``cartan_filament.cases_kinematic``).

Tolerances follow from the discretisation: finite-difference frames are O(h²), the semi-discrete
binormal flow keeps the lattice constraint θ = (1, 0, 0) to O(dx²) per unit time, RKMK of order
p is O(Δt^p) on the translating ring (whose semi-discrete solution is exact).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from cartan_filament.binormal import (
    STABILITY_CONSTANT,
    _velocity_loop,
    binormal_dt_limit,
    binormal_velocity,
    binormal_velocity_numpy,
)
from cartan_filament.cases_kinematic import (
    RING_NORMAL,
    BishopFrenetHelix,
    VortexRing,
    ring_errors,
    ring_positions,
    run_binormal,
    vortex_ring_problem,
)
from cartan_filament.gauges import bishop_frames, frenet_frames, relative_angle
from cartan_verification.case import observed_orders, run_case

import cartan
from cartan.groups.se3 import SE3


def _orders(errors):
    return observed_orders(errors)


# ---------------------------------------------------------------------------- gauges
def test_frenet_refuses_zero_curvature_naming_the_node():
    x = np.linspace(0.0, 2 * np.pi, 41)  # y = sin x: inflection (κ = 0) at x = π, node 20
    r = np.stack([x, np.sin(x), np.zeros_like(x)], axis=-1)
    with pytest.raises(ValueError, match=r"node 20 \(arclength s = [0-9.]+\).*Bishop"):
        frenet_frames(r, x[1])
    line = np.stack([x, 2 * x, 0 * x], axis=-1)
    with pytest.raises(ValueError, match="curvature vanishes.*at node 0 "):
        frenet_frames(line, x[1])
    frames = bishop_frames(r, x[1])  # the Bishop frame exists through the inflection
    assert np.all(np.isfinite(frames.frames))
    E = frames.frames
    assert np.max(np.abs(np.swapaxes(E, -1, -2) @ E - np.eye(3))) < 1e-14
    assert np.max(np.abs(np.linalg.det(E) - 1.0)) < 1e-14


def test_gauges_validate_their_input():
    with pytest.raises(ValueError, match="positions must have shape"):
        frenet_frames(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="spacing"):
        bishop_frames(np.random.default_rng(0).normal(size=(6, 3)), spacing=0.0)
    with pytest.raises(ValueError, match=r"not regular at node 2 \(arclength s = 1\)"):
        bishop_frames(np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 0, 0], [2, 0, 0.0]]))
    with pytest.raises(ValueError, match="kappa_min"):
        frenet_frames(ring_positions(8), closed=True, kappa_min=-1.0)


def test_adapted_frames_have_the_tangent_as_e1_and_the_gauge_strains():
    case = BishopFrenetHelix()
    r, h, _ = case.helix(161)
    kappa, tau = case.curvature_torsion()
    F, B = frenet_frames(r, h), bishop_frames(r, h)
    rp = np.gradient(r, h, axis=0, edge_order=2)
    t = rp / np.linalg.norm(rp, axis=-1)[:, None]
    for frames in (F, B):
        assert np.max(np.abs(frames.frames[:, :, 0] - t)) < 1e-13
    XF, XB = F.edge_strains(), B.edge_strains()
    inner = slice(2, -2)  # away from the one-sided differences at the ends
    # Frenet: π = (τ, 0, κ), O(h²); θ = (1, 0, 0) to O(h²) (the chord leaves the node tangents)
    assert np.max(np.abs(XF[inner, 3:] - [tau, 0.0, kappa])) < 5 * h**2
    assert np.max(np.abs(XF[:, :3] - [1.0, 0.0, 0.0])) < 5 * h**2
    # Bishop: π₁ = 0 on every lattice edge to round-off, |π| = κ
    assert np.max(np.abs(XB[:, 3])) < 1e-13
    assert np.max(np.abs(np.linalg.norm(XB[inner, 3:], axis=-1) - kappa)) < 5 * h**2


def test_bishop_turns_from_frenet_by_minus_the_integrated_torsion():
    """The sign: φ = −∫τ ds (right-handed about e₁, from Frenet to Bishop), at O(h²)."""
    case = BishopFrenetHelix()
    errors = [run_case(case, level)[0] for level in (2, 3)]
    assert errors[-1] <= case.tolerance
    assert 1.8 <= _orders(errors)[-1] <= 2.3, errors
    prob, _ = case.problem(2)
    ds = case.solve(prob, {})
    wrong_sign = np.max(np.abs(ds["angle"].values + ds["angle_exact"].values)) / (ds.attrs["tau"] * ds.attrs["length"])
    assert wrong_sign > 1.0  # +∫τ ds is off by the whole turn
    # relative_angle is the rotation taking one frame to the other
    F = frenet_frames(case.helix(41)[0], case.helix(41)[1])
    c, s = math.cos(0.3), math.sin(0.3)
    turned = F.frames @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    assert np.allclose(relative_angle(F, turned), 0.3, atol=1e-14)


def test_closed_bishop_frame_spreads_its_closure_angle():
    r = ring_positions(64, amplitude=0.05)  # a non-planar closed curve: non-zero closure angle
    h = 2 * np.pi / 64
    raw = bishop_frames(r, h, closed=True, spread_closure=False)
    spread = bishop_frames(r, h, closed=True)
    alpha = raw.info["closure_angle"]
    assert abs(alpha) > 1e-3 and spread.info["closure_angle"] == alpha
    Xr, Xs = raw.edge_strains(), spread.edge_strains()
    assert np.max(np.abs(Xr[:-1, 3])) < 1e-13 and Xr[-1, 3] == pytest.approx(-alpha / h, rel=1e-2)
    # the edge's π₁ is the twist up to O(h²) (the log of the transport composed with the turn)
    assert np.max(np.abs(Xs[:, 3] - spread.info["twist"])) < h**2 * abs(spread.info["twist"])
    assert spread.info["twist"] == pytest.approx(-alpha / (64 * h))
    planar = bishop_frames(ring_positions(32, normal=RING_NORMAL), 2 * np.pi / 32, closed=True)
    assert abs(planar.info["closure_angle"]) < 1e-13
    # the ring's sampled frames are an orbit of a one-parameter subgroup: θ = (1, 0, 0) exactly
    X = planar.edge_strains()
    assert np.max(np.abs(X[:, :3] - [1.0, 0.0, 0.0])) < 1e-13
    assert np.max(np.abs(np.linalg.norm(X[:, 3:], axis=-1) - 1.0)) < 1e-13


# ---------------------------------------------------------------------------- the binormal velocity
def _nodal(Phi, dx):
    g = SE3()
    Xe = g.log(g.compose(g.inverse(Phi), np.roll(Phi, -1, axis=0))) / dx
    return Xe, 0.5 * (Xe + np.roll(Xe, 1, axis=0))


def test_velocity_forms_agree_and_validate():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(12, 1, 6))
    X[:, 0, 0] = 1.0 + 0.1 * rng.random(12)
    u = (0.3 * np.arange(12))[:, None]
    for periodic in (True, False):
        for gauge, code in (("bishop", 0), ("none", 1)):
            a = binormal_velocity_numpy(X, 0.3, periodic, gauge, 1.5)
            b = _velocity_loop(u, X, 0.0, periodic, code, 1.5)
            assert np.max(np.abs(a - b)) < 1e-13
            assert np.array_equal(binormal_velocity(0.3, periodic, gauge, 1.5)(0.0, u, X), a)
    assert np.allclose(binormal_velocity()(0.0, u, X), binormal_velocity(0.3)(0.0, u, X), rtol=1e-14, atol=1e-14)
    for kw, match in (({"dx": -1.0}, "dx"), ({"gauge": "frenet"}, "gauge"), ({"coefficient": 0.0}, "coefficient")):
        with pytest.raises(ValueError, match=match):
            binormal_velocity(**{"dx": 0.1, **kw})
    with pytest.raises(ValueError, match="order"):
        binormal_dt_limit(0.1, order=2)
    assert binormal_dt_limit(0.1) == pytest.approx(STABILITY_CONSTANT[4] * 0.01)


def test_velocity_keeps_the_adaptation_to_second_order():
    """One tiny step of Φ̇ = ΦN from a perturbed ring: ∂_tθ₂,₃, ∂_tθ₁ (length) and ∂_tπ₁
    (Bishop kept) of the lattice edges are O(dx²) — the discretisation error of the centred
    differences — and the spatial velocity is κb."""
    rates = []
    for n in (64, 128):
        dx = 2 * np.pi / n
        frames = bishop_frames(ring_positions(n, amplitude=0.05), dx, closed=True)
        Phi = frames.Phi
        Xe, Xn = _nodal(Phi, dx)
        N = binormal_velocity(dx)(0.0, None, Xn[:, None, :])
        eps = 1e-7
        Xd = (_nodal(SE3().compose(Phi, SE3().exp(eps * N)), dx)[0] - Xe) / eps
        rates.append([np.max(np.abs(Xd[:, 1:3])), np.max(np.abs(Xd[:, 0])), np.max(np.abs(Xd[:, 3]))])
        # V = κb in space: R V against the curvature binormal of the samples, t × r″/|r′|²
        r = frames.positions
        rp = (np.roll(r, -1, 0) - np.roll(r, 1, 0)) / (2 * dx)
        rpp = (np.roll(r, -1, 0) - 2 * r + np.roll(r, 1, 0)) / dx**2
        sp = np.linalg.norm(rp, axis=-1)[:, None]
        kb = np.cross(rp / sp, rpp) / sp**2
        v = np.einsum("nij,nj->ni", frames.frames, N[:, :3])
        assert np.max(np.abs(v - kb)) < 20 * dx**2
    rates = np.array(rates)
    assert np.all(rates[0] / rates[1] > 3.5), rates  # O(dx²)
    assert np.all(rates[1] < 0.02), rates


# ---------------------------------------------------------------------------- the vortex ring
def test_vortex_ring_translates_at_order_of_the_integrator():
    """Orders 1, 2 and 4 of RKMK on the exact semi-discrete translation (t ∈ [0, 2], R = 1)."""
    case = VortexRing()
    expected = {1: 1.0, 2: 2.0, 4: 4.0}
    for order, p in expected.items():
        errors = []
        for level in (1, 2):
            prob, settings = case.problem(level)
            settings["integrator_options"] = {"velocity": binormal_velocity(None), "order": order}
            ds = case.run(prob, settings, "kinematic")
            errors.append(case.error(ds, prob))
            parts = case.parts(ds)
        assert abs(_orders(errors)[-1] - p) <= 0.2, (order, errors)
        # radius, constraint and length depart no more than the translation
        assert max(parts["radius"], parts["constraint"], parts["length"]) <= 2 * errors[-1], parts
    assert errors[-1] < 1e-7  # order 4, Δt = 0.05


def test_ring_is_exact_in_the_gauge_without_frame_rotation():
    """With Ω₁ = 0 the ring's N is a constant translation: exp(ΔtN) is exact at any Δt."""
    prob, _ = vortex_ring_problem(16, 2.0, RING_NORMAL)
    ds = run_binormal(prob, dt=0.25, t_end=5.0, order=4, gauge="none")
    err = ring_errors(ds, 2.0, RING_NORMAL)
    assert max(err.values()) < 1e-12, err
    z = np.asarray(ds["position"].values).mean(axis=1) @ np.asarray(RING_NORMAL)
    assert z[-1] == pytest.approx(5.0 / 2.0, rel=1e-13)


@pytest.fixture(scope="module")
def perturbed_runs():
    out = {}
    for n in (32, 64):
        prob, frames = vortex_ring_problem(n, 1.0, RING_NORMAL, amplitude=0.05)
        dx = prob.grid.spacing[0]
        out[n] = (run_binormal(prob, dt=0.5 * dx * dx, t_end=1.0, order=4, save_every=20), frames)
    return out


def test_perturbed_ring_keeps_length_and_constraint_to_second_order(perturbed_runs):
    drift = {}
    for n, (ds, _frames) in perturbed_runs.items():
        X = np.asarray(ds["X"].values)
        P = np.asarray(ds["position"].values)
        length = np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=-1).sum(axis=1)
        drift[n] = (np.max(np.abs(length / length[0] - 1.0)),
                    np.max(np.abs(X[..., 1:3] - X[0, :, 1:3])),
                    np.max(np.abs(X[..., 3] - X[0, :, 3])))  # π₁ kept by the Bishop gauge Ω₁ = −½κ²
        assert np.all(np.isfinite(X))
    ratios = np.array(drift[32]) / np.array(drift[64])
    assert np.all(ratios > 3.0), (drift, ratios)  # O(dx²)
    # over t = 1 (208 steps) at n = 64: length 4.9e-5, θ₂,₃ 7.2e-3, π₁ 6.7e-3 (about 0.7 dx²)
    assert drift[64][0] < 1e-4 and drift[64][1] < 1e-2 and drift[64][2] < 1e-2, drift


def test_dispersive_limit_brackets_the_blow_up():
    """Below binormal_dt_limit(dx) the perturbed ring runs 1500 steps; 15 % above it blows up."""
    n = 32
    prob, _ = vortex_ring_problem(n, 1.0, RING_NORMAL, amplitude=0.01)
    dx = prob.grid.spacing[0]
    limit = binormal_dt_limit(dx)
    stable = run_binormal(prob, dt=0.95 * limit, t_end=1500 * 0.95 * limit, order=4, save_every=500)
    assert np.max(np.abs(np.asarray(stable["X"].values))) < 10.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            ds = run_binormal(prob, dt=1.15 * limit, t_end=1500 * 1.15 * limit, order=4, save_every=500)
            blown = not np.max(np.abs(np.asarray(ds["X"].values))) < 1e3
        except cartan.InstabilityError:
            blown = True
    assert blown


@pytest.mark.slow
def test_compiled_velocity_runs_in_the_generated_loop():
    """The numba closure takes the core's generated RKMK loop and agrees with the numpy form."""
    prob, _ = vortex_ring_problem(16, 1.0, RING_NORMAL, amplitude=0.05)
    ref = run_binormal(prob, dt=0.01, t_end=0.5, order=4, save_every=10)
    fast = run_binormal(prob, dt=0.01, t_end=0.5, order=4, save_every=10, compiled=True)
    assert np.max(np.abs(fast["position"].values - ref["position"].values)) < 1e-12


def test_vortex_ring_scene_translates_and_restarts_exactly(tmp_path):
    """The registered scene (a named velocity factory in the scene file): the ring moves along
    its normal at 1/R (RKMK4 at Δt = 0.02: error O(Δt⁴), measured 1e-9 here), and a restart
    from the middle continues it bit for bit (the named velocity is rebuilt from the file)."""
    from click.testing import CliRunner

    from cartan.cli import main

    whole, half = tmp_path / "whole.nc", tmp_path / "half.nc"
    run = CliRunner().invoke(main, ["run", "--scene", "filament-vortex-ring", "--t-end", "0.4", "-o", str(whole)])
    assert run.exit_code == 0, run.output
    run = CliRunner().invoke(main, ["run", "--scene", "filament-vortex-ring", "--t-end", "0.2", "-o", str(half)])
    assert run.exit_code == 0, run.output
    run = CliRunner().invoke(main, ["run", "--restart", str(half), "--t-end", "0.4"])
    assert run.exit_code == 0, run.output
    a, b = cartan.api.open(whole), cartan.api.open(half)
    np.testing.assert_array_equal(a.position.values, b.position.values)
    centre = a.position.values[-1].mean(axis=0)
    assert abs(centre[2] - 0.4) < 1e-6 and float(np.hypot(centre[0], centre[1])) < 1e-12
    radius = np.linalg.norm(a.position.values[-1] - centre, axis=-1)
    assert float(np.max(np.abs(radius - 1.0))) < 1e-6
