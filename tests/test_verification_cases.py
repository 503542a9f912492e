"""The registered verification cases (VERIFICATION.md §4) and the invariant checks (§1).

Every registered case runs at its two finest quick levels with each default integrator: the
error at the finest meets the case's tolerance and, where the case states an expected order,
the observed order log₂(e_coarse/e_fine) lies in [p − 0.2, p + 0.3].
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from cartan_verification import (
    Case,
    check_invariants,
    energy_balance,
    group_membership,
    momentum_drift,
    observed_orders,
    ring_closure,
    run_case,
    spatial_integrability,
    temporal_integrability,
)
from cartan_verification.plugin import all_cases

import cartan

CASES = cartan.registry("cases")
RUNS = [(name, integ) for name, case in sorted(CASES.items()) for integ in case.default_integrators]


# ---------------------------------------------------------------------------- registry and metadata
def test_every_case_is_registered_and_described():
    assert {c.name for c in all_cases()} == set(CASES)
    media = cartan.registry("media")
    for name, case in CASES.items():
        assert isinstance(case, Case) and case.name == name
        assert case.medium in media, name
        for field in ("description", "reference", "quantity", "norm", "tolerance_reason"):
            assert getattr(case, field).strip(), (name, field)
        assert 0 < case.tolerance < math.inf, name
        assert len(case.levels) >= 2 and set(case.quick()) <= set(case.levels)
        assert case.default_integrators and set(case.default_integrators) <= set(cartan.registry("integrators"))
        for integ in case.default_integrators:
            assert 0 < case.tolerance_for(integ) < math.inf
        if case.time_order_of is not None:
            for integ in case.default_integrators:
                assert case.expected_time_order(integ) is not None, (name, integ)
        with pytest.raises(AttributeError):
            case.tolerance = 1.0


def test_expected_order_precedence():
    cases = CASES
    assert cases["free-rigid-body"].expected_order("rkmk4") == 4.0
    assert cases["free-rigid-body"].expected_order() == 2.0
    assert cases["rod-axial-wave"].expected_order() == 2.0
    assert cases["rod-planar-se3-se2"].expected_order() is None
    limit = cases["sphere-rod-large-radius"]
    assert limit.expected_order() == 2.0 and limit.space_order is None
    assert limit.limit_levels() == {0: 10.0, 1: 20.0, 2: 40.0, 3: 80.0}


def test_problem_settings_are_simulate_arguments():
    for case in CASES.values():
        problem, settings = case.problem(case.levels[0])
        assert isinstance(problem, cartan.Problem)
        assert {"dt", "t_end", "save_every"} <= set(settings) <= {"dt", "t_end", "save_every", "integrator_options"}
        assert settings["dt"] > 0 and settings["t_end"] > 0


# ---------------------------------------------------------------------------- the cases converge
@pytest.mark.parametrize(("name", "integrator"), RUNS)
def test_case_meets_tolerance_and_order(name, integrator):
    case = CASES[name]
    errors = []
    with warnings.catch_warnings():
        if integrator == "lie-euler":  # unconditionally unstable for undamped motion (CFL 0), but
            warnings.simplefilter("ignore", cartan.StabilityWarning)  # resolved over this short run
        for level in case.quick():
            errors.append(run_case(case, level, integrator)[0])
    assert np.all(np.isfinite(errors))
    assert errors[-1] <= case.tolerance_for(integrator), (errors, case.tolerance_for(integrator))
    p = case.expected_order(integrator)
    if p is not None:
        observed = observed_orders(errors)[-1]
        assert p - 0.2 <= observed <= p + 0.3, (errors, observed, p)


@pytest.mark.parametrize(("name", "integrator"), RUNS)
def test_case_all_levels(name, integrator):
    """Every default level: the observed orders of the asymptotic (last two) pairs."""
    case = CASES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cartan.StabilityWarning)
        errors = [run_case(case, level, integrator)[0] for level in case.levels]
    assert errors[-1] <= case.tolerance_for(integrator)
    p = case.expected_order(integrator)
    if p is not None:
        assert np.all(np.abs(observed_orders(errors)[-2:] - p) <= 0.3), errors


def test_planar_case_detects_a_difference():
    """The SE(3) ≡ SE(2) error is not vacuous: a displaced node or an out-of-plane offset shows."""
    case = CASES["rod-planar-se3-se2"]
    err, ds = run_case(case, 0)
    assert err <= case.tolerance
    for k in (0, 2):
        moved = ds.copy(deep=True)
        moved.position.values[-1, 5, k] += 1e-6
        assert case.error(moved, case.problem(0)[0]) >= 1e-6


# ---------------------------------------------------------------------------- invariant checks
def _ring(n=10):
    rod = cartan.medium("cosserat-rod", E=1e4, poisson=0.5, radius=0.25, density=5000.0)
    grid = cartan.Grid(n, length=2.0, periodic=True)
    u = 2 * math.pi * np.arange(n) / n
    vel = np.stack([0.3 * np.cos(2 * u), 0.2 * np.sin(u), 0.4 * np.sin(2 * u), np.cos(u), 0.5 * np.sin(3 * u),
                    0.7 + 0 * u], axis=-1)
    init = rod.initial_state(grid, "ring", amplitude=0.2, mode=2, out_of_plane=0.15, velocity=vel,
                             rigid_velocity=[0, 0, 0, 0.5, 1.0, 2.0])
    return cartan.Problem(rod, grid, init)


def test_invariants_round_off_for_lattice_lie_verlet():
    ds = cartan.simulate(_ring(), integrator="lie-verlet", scheme="lattice", dt=2e-3, t_end=0.4, save_every=20,
                         progress=False)
    assert temporal_integrability(ds) <= 1e-12
    assert ring_closure(ds) <= 1e-12
    assert group_membership(ds) <= 1e-12
    assert spatial_integrability(ds) == 0.0  # d = 1: void
    assert 0 < energy_balance(ds) < 1e-3
    assert momentum_drift(ds) <= 1e-10  # free ring: Lie–Verlet conserves the momentum map
    report = check_invariants(ds)
    assert report["passed"] and all(v["passed"] in (True, None) for k, v in report.items() if k != "passed")


def test_invariants_large_for_forward_euler():
    with pytest.warns(cartan.StabilityWarning):
        ds = cartan.simulate(_ring(), integrator="forward-euler", scheme="lattice", dt=5e-4, t_end=0.1,
                             save_every=20, progress=False)
    assert group_membership(ds) > 1e-6
    assert ring_closure(ds) > 1e-6
    report = check_invariants(ds)
    assert not report["passed"] and report["group_membership"]["passed"] is False
    assert check_invariants(ds, tolerances={"group_membership": None, "ring_closure": None,
                                            "temporal_integrability": None, "energy_balance": None})["passed"]
    with pytest.raises(ValueError, match="unknown invariant"):
        check_invariants(ds, tolerances={"holonomy": 1.0})


def test_spatial_integrability_d2_and_dissipative_balance():
    m = cartan.medium("sigma-model", n=2, d=2)
    grid = cartan.Grid((12, 12), 1.0, periodic=True)
    problem = cartan.Problem(m, grid, m.initial_state(grid, "random-smooth", amplitude=1.0, velocity_amplitude=1.0))
    ds = cartan.simulate(problem, dt=0.004, t_end=0.04, save_every=5, progress=False)
    assert "spatial_residual" in ds
    assert spatial_integrability(ds) <= 1e-12
    assert ring_closure(ds) <= 1e-12
    # dissipative: E + D − E₀ closes to the integrator's order (second-order overdamped, small Δt)
    case = CASES["sphere-rod-latitude-order2"]
    _, ds1 = run_case(case, 2, save_every=8)
    _, ds2 = run_case(case, 3, save_every=16)
    b1, b2 = energy_balance(ds1), energy_balance(ds2)
    assert float(ds1.dissipated_energy[-1]) > 0 and b1 < 1e-2
    assert 1.6 <= math.log2(b1 / b2) <= 2.4, (b1, b2)
