"""The symplectic ``implicit-midpoint`` on the core's coupled-Lagrangian path, the general elastic
law ε(λ) = μc² + W(λ), the proper time per node and the coupled-contract checker
(docs/media/relativistic-rod.md §2–§4, §6; cartan/integrators/implicit.py, "Coupled Lagrangians").

Fast tests run two implicit-midpoint steps on a 4-node free string (numpy path only: no
compiled code), the law's checks and closed forms, the checker, and the proper-time quadrature
on synthetic frames.  Slow: the time order of the rotating-ring case (implicit-midpoint 2,
rkmk4 4) with the proper time against t√(1 − v²/c²), the long-run energy of both integrators,
a quartic-law run (energy change at order 2, agreement with rkmk4), and ``check_medium`` on the elastic string.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr
from cartan_relativistic import elastic as E
from cartan_relativistic.clocks import add_proper_time, proper_time
from cartan_relativistic.elastic import ElasticLaw
from cartan_relativistic.elastic_rod import ElasticRelativisticRod

import cartan
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.schemes._coupled import hamiltonian
from cartan.schemes.lattice import Lattice
from cartan.testing import ConformanceError, check_coupled_contract

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")


def _free_string(n: int = 5, **kw):
    """An open string moving in 3-D: stretched, bent, with longitudinal and transverse velocity."""
    rod = cartan.medium("relativistic-rod", energy="elastic", **({"stiffness": 0.25} if not kw else kw))
    grid = cartan.Grid(n, length=1.0)
    u = grid.coordinates(0)
    x = np.stack([1.1 * u, 0.05 * np.sin(np.pi * u), 0.02 * u * u], -1)
    v = np.stack([0.2 * np.cos(np.pi * u), 0.3 * np.sin(2 * np.pi * u), 0.1 * u], -1)
    return cartan.Problem(rod, grid, rod.state_from(x, v))


# ---------------------------------------------------------------------------- implicit-midpoint
def _norm_M(scheme, state) -> float:
    """‖N‖_M = √(Σ w m N²), the norm of implicit-midpoint's convergence test."""
    N = scheme.velocity(state)
    return float(np.sqrt(np.sum(scheme.weights[:, None] * scheme.mass * N * N * scheme.live)))


def test_implicit_midpoint_steps_a_coupled_lagrangian_conserving_the_momenta():
    """Two steps on a free string with the quartic law.  The discrete Lagrangian
    Δt L(ξ/Δt, X(Φ_k exp(ξ/2))) is invariant under translations and rotations, so P⃗ and J⃗
    change only by the stage residual: ΔP⃗ = Σ w R, ΔJ⃗ = Σ w x⃗ × R, bounded by Cauchy–Schwarz
    by √(Σ w m)·‖R‖_* ≤ √(Σ w m)·tol·‖N‖_M per step (times max|x⃗| for J⃗).  r⁰ = ct holds
    exactly (the gauge components of ξ are cΔt); H_d changes by the order-2 local error only."""
    problem = _free_string(4, law=ElasticLaw.quartic(0.25, 0.5))
    scheme = Lattice(problem)
    state = scheme.initial_state()
    P0, H0 = scheme.total_momentum(state), hamiltonian(scheme, state)
    tol, dt, steps = 1e-12, 0.02, 2
    integ = ImplicitMidpoint(tol=tol)
    bound = steps * math.sqrt(float(np.sum(scheme.weights)) * 1.0) * tol * _norm_M(scheme, state)  # m = μ = 1
    for _ in range(steps):
        integ.step(scheme, state, dt)
    P = scheme.total_momentum(state)
    assert np.max(np.abs(P[1:4] - P0[1:4])) <= 1.5 * bound  # (the norm of N changes by O(Δt) over the steps)
    assert np.max(np.abs(P[7:10] - P0[7:10])) <= 1.5 * 1.2 * bound  # max |x⃗| ≤ 1.2
    assert np.allclose(scheme.frames(state)[:, 1, 0], state.t, rtol=0, atol=1e-14)  # r⁰ = ct, c = 1
    # H_d: local error O(Δt³) per step; the motion's energy is O(0.1), so 1e-5 is a loose bound
    # that a wrong force (an O(Δt) error) would break
    assert abs(hamiltonian(scheme, state) - H0) < 1e-5 * abs(H0)
    assert integ.newton_iterations > 0 and integ.jacobians >= 1


# ---------------------------------------------------------------------------- the law ε(λ)
@pytest.mark.parametrize(("law", "match"), [
    (ElasticLaw.quartic(0.1, 5.0), "slower than light"),
    (ElasticLaw(lambda lam: 0.5 * (lam - 1) ** 2, lambda lam: 2 * (lam - 1), lambda lam: 1 + 0 * lam),
     "W′ is not the derivative"),
    (ElasticLaw(lambda lam: 0.5 * (lam - 1) ** 2, lambda lam: lam - 1, lambda lam: 2 + 0 * lam),
     "W″ is not the derivative"),
    (ElasticLaw(lambda lam: -0.5 * (lam - 1) ** 2, lambda lam: -(lam - 1), lambda lam: -1 + 0 * lam),
     "ε″ = W″ > 0"),
    (ElasticLaw(lambda lam: -2.0 + 0 * lam, lambda lam: 0 * lam, lambda lam: 0 * lam), r"ε\(λ\) = μc² \+ W > 0"),
    ("no-such-law", "law must be a registered name"),
    ("quadratic", r"law 'quadratic' takes the parameters \(k"),
    ({"k": 0.1}, "needs its registered name"),
    (1.0, "law must be an ElasticLaw"),
])
def test_bad_laws_are_refused(law, match):
    with pytest.raises(ValueError, match=match):
        cartan.medium("relativistic-rod", energy="elastic", law=law, stretch_range=(0.7, 1.6))


def test_law_keywords_are_checked():
    with pytest.raises(ValueError, match="either stiffness"):
        cartan.medium("relativistic-rod", energy="elastic", stiffness=0.1, law=ElasticLaw.quartic(0.1, 0.2))
    with pytest.raises(ValueError, match="stretch_range must be"):
        cartan.medium("relativistic-rod", energy="elastic", stiffness=0.1, stretch_range=(1.5, 0.9))
    with pytest.raises(ValueError, match="law and stretch_range apply to energy='elastic'"):
        cartan.medium("relativistic-rod", law=ElasticLaw.quartic(0.1, 0.2))
    with pytest.raises(ValueError, match="must be a callable"):
        ElasticLaw(1.0, lambda lam: lam, lambda lam: lam)
    # the quadratic law is causal at λ = 1 for k < μc² but not at every stretch: λ = 2 needs k < μc²/5.5
    with pytest.raises(ValueError, match="violated at λ"):
        cartan.medium("relativistic-rod", energy="elastic", stiffness=0.5, stretch_range=(0.5, 2.0))
    rod = cartan.medium("relativistic-rod", energy="elastic", stiffness=0.15, stretch_range=(0.5, 2.0))
    assert rod.parameters()["stretch_range"] == (0.5, 2.0)


def test_wave_speeds_of_the_law_are_the_documented_ones():
    """c_L² = c²λ²ε″/(ε − λε′) and c_T² = c²λε′/ε (docs §2): at λ = 1 the quadratic law gives
    c_L² = k/μ, c_T² = 0; the quartic's c_L² at λ = 1.2 by the closed form."""
    c, mu, k, q = 2.0, 1.5, 0.3, 0.4
    cl2, ct2 = ElasticLaw.quadratic(k).speeds(np.array([1.0]), mu, c)
    assert abs(cl2[0] - k / mu) < 1e-15 and ct2[0] == 0.0
    lam = 1.2
    eps, T, K = mu * c * c + 0.5 * k * 0.04 + 0.25 * q * 0.2**4, k * 0.2 + q * 0.008, k + 3 * q * 0.04
    cl2, ct2 = ElasticLaw.quartic(k, q).speeds(np.array([lam]), mu, c)
    assert abs(cl2[0] - c * c * lam * lam * K / (eps - lam * T)) < 1e-14
    assert abs(ct2[0] - c * c * lam * T / eps) < 1e-15


def test_quartic_law_legendre_map_and_stress_are_derivatives():
    """ℓ(v⃗, x⃗′) with the quartic law: p⃗ = ∂ℓ/∂v⃗, Q⃗ = −∂ℓ/∂x⃗′ and the Hessian by central
    differences (h = 1e-6: error ≈ 1e-12), v⃗(p⃗) returns v⃗; the medium's contract checked by
    :func:`cartan.testing.check_coupled_contract` (Legendre maps inverse, ∂H/∂S, ∂H/∂X);
    its potential is W(|x⃗′|)."""
    rng = np.random.default_rng(5)
    c = 1.5
    law = ElasticLaw.quartic(0.2, 0.3).functions(1.0, c)
    d = rng.normal(size=(20, 3))
    x = (1.0 + 0.3 * rng.random((20, 1))) * d / np.linalg.norm(d, axis=1, keepdims=True)
    v = 0.4 * c * rng.uniform(-1, 1, size=(20, 3)) / math.sqrt(3)
    h, eye = 1e-6, np.eye(3)
    dl = np.stack([(E.temporal_lagrangian(v + h * eye[k], x, law, c) - E.temporal_lagrangian(v - h * eye[k], x, law, c))
                   / (2 * h) for k in range(3)], -1)
    dx = np.stack([(E.temporal_lagrangian(v, x + h * eye[k], law, c) - E.temporal_lagrangian(v, x - h * eye[k], law, c))
                   / (2 * h) for k in range(3)], -1)
    p = E.temporal_momentum(v, x, law, c)
    assert np.allclose(p, dl, rtol=0, atol=1e-8)
    assert np.allclose(E.temporal_stress(v, x, law, c), -dx, rtol=0, atol=1e-8)
    Hv = np.stack([(E.temporal_momentum(v + h * eye[k], x, law, c) - E.temporal_momentum(v - h * eye[k], x, law, c))
                   / (2 * h) for k in range(3)], -1)
    assert np.allclose(E.temporal_hessian(v, x, law, c), Hv, rtol=0, atol=1e-8)
    assert np.allclose(E.temporal_velocity(p, x, law, c), v, rtol=0, atol=1e-13)
    rod = cartan.medium("relativistic-rod", energy="elastic", c=c, law=ElasticLaw.quartic(0.2, 0.3),
                        stretch_range=(0.8, 1.4))
    report = check_coupled_contract(rod)
    assert not report.failed and len(report.passed) == 5
    X = np.zeros((4, 1, 10))
    X[:, 0, 1] = [0.8, 1.0, 1.2, 1.4]
    assert np.allclose(rod.potential(X), 0.1 * (X[:, 0, 1] - 1) ** 2 + 0.075 * (X[:, 0, 1] - 1) ** 4, rtol=0,
                       atol=1e-16)


@pytest.mark.slow
def test_quartic_string_conserves_energy_and_agrees_with_rkmk4():
    """A free string with the quartic law (9 nodes) to t = 0.16 by implicit-midpoint at Δt = 0.02
    and 0.01: P⃗ within the Newton-residual bound (fast test), the change of H_d falls as Δt²
    (H_d − H̃ = O(Δt²) for the modified Hamiltonian H̃ the method conserves; accepted ratio
    3–5 per halving), and rkmk4 on the same steps agrees with it to the midpoint's O(Δt²) global
    error."""
    law = ElasticLaw.quartic(0.25, 0.5)
    problem = _free_string(9, law=law)
    scheme = Lattice(problem)
    start = scheme.initial_state()
    P0, H0 = scheme.total_momentum(start), hamiltonian(scheme, start)
    tol, changes = 1e-12, []
    for dt, steps in ((0.02, 8), (0.01, 16)):
        state, twin = start.copy(), start.copy()
        bound = steps * tol * _norm_M(scheme, state)
        integ = ImplicitMidpoint(tol=tol)
        rk = cartan.registry("integrators")["rkmk4"]()
        for _ in range(steps):
            integ.step(scheme, state, dt)
            rk.step(scheme, twin, dt)
        assert np.max(np.abs(scheme.total_momentum(state)[1:4] - P0[1:4])) < 1.5 * bound
        changes.append(abs(hamiltonian(scheme, state) - H0))
        # the two differ by the midpoint's global error C·Δt²·t, C = O(1) here
        assert np.max(np.abs(scheme.frames(state) - scheme.frames(twin))) < 1e-4
    assert 3.0 < changes[0] / changes[1] < 5.0, changes


# ---------------------------------------------------------------------------- proper time
def _frames(t: np.ndarray, gamma: np.ndarray) -> xr.Dataset:
    return xr.Dataset({"coordinate_time": (("time", "node"), np.repeat(t[:, None], gamma.shape[1], 1)),
                       "lorentz_factor": (("time", "node"), gamma)}, coords={"time": t})


def test_proper_time_quadrature():
    """Constant γ: τ = t/γ exactly; 1/γ linear in t: Simpson and the trapezoid are exact; 1/γ
    quadratic: Simpson exact, the trapezoid off by its O(Δt²) error."""
    t = np.linspace(0.0, 2.0, 9)
    const = _frames(t, np.full((9, 3), 1.25))
    assert np.allclose(proper_time(const), t[:, None] / 1.25, rtol=0, atol=1e-15)
    lin = _frames(t, 1.0 / (1.0 - 0.1 * t[:, None] * np.ones((1, 2))))
    exact = t - 0.05 * t * t
    for method in ("simpson", "trapezoid"):
        assert np.allclose(proper_time(lin, method), exact[:, None], rtol=0, atol=1e-14)
    quad = _frames(t, 1.0 / (1.0 - 0.1 * t[:, None] ** 2))
    exact = t - 0.1 * t**3 / 3
    assert np.allclose(proper_time(quad), exact[:, None], rtol=0, atol=1e-14)
    trap = proper_time(quad, "trapezoid")
    # the trapezoid's error on a quadratic is exactly (Δt²/12)·|f″|·t, f″ = −0.2, Δt = 0.25
    assert np.allclose(np.abs(trap - exact[:, None]), (0.25**2 / 12) * 0.2 * t[:, None], rtol=1e-9, atol=1e-15)
    ds = add_proper_time(const)
    assert "proper_time" in ds and ds.proper_time.dims == ("time", "node")
    with pytest.raises(ValueError, match="method must be one of"):
        proper_time(const, "euler")
    with pytest.raises(ValueError, match="missing"):
        proper_time(const.drop_vars("lorentz_factor"))


# ---------------------------------------------------------------------------- the checker
class _WrongStress(ElasticRelativisticRod):
    """The elastic string with a stress 1 % too large: not ∂H/∂X."""

    def stress_with(self, S, X):
        return 1.01 * super().stress_with(S, X)


def test_coupled_contract_checker_finds_a_wrong_stress_and_refuses_other_media():
    rep = check_coupled_contract(_WrongStress(stiffness=0.25), raise_on_failure=False)
    assert any("stress_with = ∂H/∂X" in f for f in rep.failed) and len(rep.passed) == 4
    with pytest.raises(ConformanceError):
        check_coupled_contract(_WrongStress(stiffness=0.25))
    with pytest.raises(ValueError, match="does not declare coupled_lagrangian"):
        check_coupled_contract("relativistic-rod")


# ---------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_rotating_ring_time_order_and_proper_time():
    """The rigidly rotating ring (a relative equilibrium of the semi-discrete system): the
    position error of implicit-midpoint falls at order 2 (measured 1.998, 2.000; accepted
    1.9–2.1), J₃ stays to the Newton tolerance and P⃗ to round-off; every node's proper time is
    t√(1 − v²/c²) to the integrator's error (measured 3.8e-6 at Δt = 0.1)."""
    from cartan_relativistic.cases import RotatingElasticRing

    from cartan.study import observed_order

    case = RotatingElasticRing()
    v = case.spin() * 1.3
    errs, dts = [], []
    for level in (0, 1, 2):
        problem, settings = case.problem(level)
        ds = case.run(problem, settings, "implicit-midpoint")
        errs.append(case.error(ds, problem))
        dts.append(settings["dt"])
        M = ds.total_momentum.values
        assert np.max(np.abs(M[:, 1:4])) < 1e-14
        assert np.ptp(M[:, 9]) < 1e-8 * abs(M[0, 9])
    assert abs(observed_order(np.array(dts), np.array(errs)) - 2.0) < 0.1
    assert errs[-1] < 2 * case.tolerance * 4  # level 2: Δt twice the tolerance's level 3
    tau = proper_time(ds)
    exact = ds.time.values[:, None] * math.sqrt(1 - v * v)
    # the scene relativistic-elastic-ring-rotating turns at this equilibrium spin
    sc = cartan.scene("relativistic-elastic-ring-rotating")
    speed = np.linalg.norm(sc.problem.initial.N[:, 1:4], axis=1)
    assert np.allclose(speed, v, rtol=1e-15, atol=0)
    # the proper-time error is the integrator's (γ varies only with the numerical breathing)
    assert np.max(np.abs(tau - exact)) < 1e-5


@pytest.mark.slow
def test_long_run_energy_bounded_for_implicit_midpoint_drifting_for_rkmk4():
    """The breathing ring (8 nodes, Δt = 0.2, t = 100): implicit-midpoint's H_d error oscillates
    with no trend (measured: amplitude 1.16e-4 = 2.0e-4 H_d, fitted drift over the run 0.5 % of
    it; accepted < 5 %), rkmk4's drifts linearly (the fitted drift −8.0e-8 is its whole error,
    accepted > 50 %); J₃ to the Newton tolerance (1.2e-8) against rkmk4's order-4 drift (1.8e-7)."""
    from cartan_relativistic.rotating import energy_drift

    T = 100.0
    runs = energy_drift(T, 0.2, 8)
    im, rk = runs["implicit-midpoint"], runs["rkmk4"]
    b_im = np.polyfit(im["t"], im["dH"], 1)[0]
    b_rk = np.polyfit(rk["t"], rk["dH"], 1)[0]
    assert abs(b_im) * T < 0.05 * np.max(np.abs(im["dH"]))
    assert abs(b_rk) * T > 0.5 * np.max(np.abs(rk["dH"]))
    assert np.max(np.abs(im["dJ"])) < np.max(np.abs(rk["dJ"]))
    # P⃗: rkmk4 to round-off; implicit-midpoint to the Newton tolerance, 500 steps of at most
    # √(Σ w m)·tol·‖N‖_M = √(2π)·1e-10·1.0 (measured 1.1e-11)
    assert np.max(rk["dP"]) < 1e-14
    assert np.max(im["dP"]) < 500 * math.sqrt(2 * math.pi) * 1e-10


@pytest.mark.slow
def test_check_medium_passes_on_the_elastic_string():
    """The conformance kit on the coupled medium: contract, coupled-contract checks and the runs
    (rkmk4, lie-euler, implicit-midpoint, kinematic, overdamped on the lattice and the
    collocation; lie-verlet and rattle refuse it: skipped with their reasons)."""
    from cartan.testing import check_medium

    rep = check_medium("relativistic-rod", {"energy": "elastic", "stiffness": 0.25})
    assert any("coupled contract" in p for p in rep.passed)
    assert any("lattice × implicit-midpoint" in p for p in rep.passed)
    assert any("collocation × implicit-midpoint" in p for p in rep.passed)


# ---------------------------------------------------------------------------- restarts
@pytest.mark.parametrize("integrator", ["rkmk4", "implicit-midpoint"])
def test_elastic_string_restarts_bit_for_bit(tmp_path, integrator):
    """A run to t₁ continued from its checkpoint to t₂ is the uninterrupted run to t₂ bit for bit:
    the inverse Legendre map of a point depends on (S, X) alone (no warm start from an earlier
    call), and implicit-midpoint's stage momenta start afresh at every save block, as a restart
    does (numpy path: the coupled Lagrangian has no compiled loop)."""
    from cartan.api import simulate

    problem = _free_string(4, law=ElasticLaw.quartic(0.25, 0.5))
    dt, save = 0.02, 2
    whole = simulate(problem, integrator=integrator, dt=dt, t_end=4 * save * dt, save_every=save,
                     output=tmp_path / "whole.nc", compiled=False)
    simulate(_free_string(4, law=ElasticLaw.quartic(0.25, 0.5)), integrator=integrator, dt=dt,
             t_end=2 * save * dt, save_every=save, output=tmp_path / "part.nc", compiled=False)
    continued = simulate(_free_string(4, law=ElasticLaw.quartic(0.25, 0.5)), integrator=integrator,
                         restart=tmp_path / "part.nc", t_end=4 * save * dt, output=tmp_path / "cont.nc",
                         compiled=False)
    for name in ("position", "frame", "S", "N", "energy"):
        assert np.array_equal(whole[name].values[-1], continued[name].values[-1]), name
    assert np.array_equal(whole["time"].values[-1], continued["time"].values[-1])
