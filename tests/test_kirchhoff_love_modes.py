"""Free vibration of the simply supported square ``kirchhoff-love`` plate with ``rattle``.

The registered case ``plate-modes-kl`` (:mod:`cartan_kirchhoff_love.plate_modes`): the modes
(1, 1), (1, 2), (2, 2) on the odd-periodic plate against Rayleigh's ω² = Dk⁴/(ρh(1 + k²h²/12))
— λ = ωa²√(ρh/D) = π²(m² + n²) = 19.7392, 49.3480, 78.9568 without the rotary inertia — each
measurement against the lattice's own dispersion with Verlet's time error, the orders in Δx
(Δt tied) and in Δt, and the same mode on the (M + 1)² plate with the core's penalty supports.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_kirchhoff_love.plate_modes import (
    KIRCHHOFF_LAMBDA,
    MODES,
    SimplySupportedPlateModesKL,
    frequency_parameter,
    lattice_plate_frequency,
    mode_frequencies,
    plate_frequency,
    plate_modes_problem,
    plate_modes_settings,
)
from cartan_verification.case import observed_orders, run_levels

import cartan

CASE = cartan.registry("cases")["plate-modes-kl"]


def test_case_is_registered_as_a_dynamic_case():
    assert isinstance(CASE, SimplySupportedPlateModesKL) and not CASE.static
    assert CASE.default_integrators == ("rattle",) and CASE.expected_order() == 2.0
    assert tuple(CASE.modes) == MODES == ((1, 1), (1, 2), (2, 2))


def test_reference_values_and_the_rotary_inertia_correction():
    """Without rotary inertia λ = π²(m² + n²) = 19.7392, 49.3480, 78.9568 (the listed values);
    the medium's kinetic metric (ρh, ρh³/12) lowers them by √(1 + k²h²/12), k² = π²(m² + n²)/a²:
    19.5788, 48.3636, 76.4808 at h/a = 0.1, and the lattice's dispersion tends to it at O(Δ²)."""
    kl = cartan.medium("kirchhoff-love", E=1.0, poisson=0.3, thickness=0.1, density=1.0)
    listed = {(1, 1): 19.7392, (1, 2): 49.3480, (2, 2): 78.9568}
    model = {(1, 1): 19.5788, (1, 2): 48.3636, (2, 2): 76.4808}
    for mn in MODES:
        lam0 = frequency_parameter(kl, plate_frequency(kl, mn, rotary=False))
        assert lam0 == pytest.approx(KIRCHHOFF_LAMBDA[mn], rel=1e-14)
        assert round(lam0, 4) == listed[mn]
        lam = frequency_parameter(kl, plate_frequency(kl, mn))
        k2h2 = np.pi ** 2 * (mn[0] ** 2 + mn[1] ** 2) * kl.h ** 2
        assert lam == pytest.approx(lam0 / math.sqrt(1.0 + k2h2 / 12.0), rel=1e-14)
        assert round(lam, 4) == model[mn]
        errors = [lattice_plate_frequency(kl, mn, 1.0, 1.0 / M) / plate_frequency(kl, mn) - 1.0
                  for M in (128, 256, 512)]
        assert np.all(np.abs(observed_orders(np.abs(errors)) - 2.0) < 0.05), errors
    # a thinner plate approaches the listed λ: h/a = 0.001 is within 2e-5 of it
    thin = cartan.medium("kirchhoff-love", thickness=1e-3)
    for mn in MODES:
        assert abs(frequency_parameter(thin, plate_frequency(thin, mn)) / KIRCHHOFF_LAMBDA[mn] - 1.0) < 2e-5


def test_initial_state_and_settings():
    """The odd-periodic plate: 2M × 2M nodes of side 2a, w = 0 on the support lines, the frames'
    slopes t·cos on them; the supported plate (M + 1)², held by a penalty support; Δt = ½Δ/c."""
    p = plate_modes_problem(4)
    assert p.grid.shape == (8, 8) and p.grid.periodic == (True, True) and p.grid.length == (2.0, 2.0)
    z = p.initial.Phi[..., 3, 0]
    np.testing.assert_allclose(z[[0, 4], :], 0.0, atol=1e-18)
    np.testing.assert_allclose(z[:, [0, 4]], 0.0, atol=1e-18)
    s = plate_modes_settings(p)
    c = math.sqrt(1.0 / (1.0 - 0.09))
    assert s["dt"] <= 0.5 * 0.25 / c and s["dt"] > 0.45 * 0.25 / c
    q = plate_modes_problem(4, supports=100.0)
    assert q.grid.shape == (5, 5) and q.grid.periodic == (False, False) and len(q.loads) == 1
    assert plate_modes_settings(q, supports=100.0)["dt"] < s["dt"] / 9.0      # the springs: Δt/√(1 + P)


@pytest.mark.parametrize("kwargs, word", [
    ({"cells": 1}, "cells"), ({"cells": 4, "modes": [(1, 4)]}, "modes"), ({"cells": 4, "modes": [(0, 1)]}, "mode"),
    ({"cells": 4, "amplitude": -1.0}, "amplitude"), ({"cells": 4, "side": 0.0}, "side"),
    ({"cells": 4, "supports": 0.0}, "supports"),
])
def test_bad_parameters(kwargs, word):
    with pytest.raises(ValueError, match=word):
        plate_modes_problem(**kwargs)


# ---------------------------------------------------------------------------- runs (slow)
@pytest.fixture(scope="module")
def levels():
    """The case's levels M = 4, 8, 16 (25 + 49 + 98 rattle steps on up to 32² nodes):
    ``[(error, ds, problem, settings)]``.  Level 3 (M = 32, 196 Python rattle steps on 64²
    nodes, ≈ 40 ms each) runs in `cartan verify` (docs/verification/kirchhoff-love)."""
    return run_levels(CASE, CASE.levels[:3])


def _predicted(problem, settings, mn) -> float:
    return lattice_plate_frequency(problem.medium, mn, 1.0, problem.grid.spacing[0], settings["dt"])


@pytest.mark.slow
def test_frequencies_converge_at_the_lattice_s_order(levels):
    """Every mode at every level is the lattice's dispersion with Verlet's time error to 1e-5
    (measured ≤ 3e-6: the O(A²) nonlinearity of three superposed modes); the case's error (the
    (1, 2) mode: 7.69e-2, 1.22e-2, 2.71e-3; 6.58e-4 at M = 32) has the predicted observed orders
    (2.65, 2.17; 2.04 at M = 32) to 0.02, the asymptotic pair in [1.9, 2.2]."""
    errors, predicted = [], []
    for err, ds, problem, settings in levels:
        omegas = mode_frequencies(ds, problem)
        pred = {}
        for mn, omega in omegas.items():
            pred[mn] = _predicted(problem, settings, mn)
            assert abs(omega / pred[mn] - 1.0) < 1e-5, (problem.grid.shape, mn, omega, pred[mn])
        errors.append(err)
        predicted.append(max(abs(pred[mn] / plate_frequency(problem.medium, mn) - 1.0) for mn in MODES))
    orders = observed_orders(errors)
    np.testing.assert_allclose(orders, observed_orders(predicted), atol=0.02)
    assert np.all((orders[1:] > 1.9) & (orders[1:] < 2.2)), orders
    assert errors[-1] <= CASE.tolerance


@pytest.mark.slow
def test_constraints_hold(levels):
    """θ_α,3 = 0 on every edge after the first step to 1e-12 (the sampled initial state holds it
    to O(A²) ≈ 1e-9, projected by rattle's first step)."""
    for _, ds, _, _ in levels:
        res = ds["constraint_residual"].values
        assert float(res[0]) < 1e-8 and float(res[1:].max()) <= 1e-12


@pytest.mark.slow
def test_time_order_at_fixed_spacing():
    """M = 8, Δt = ½Δ/c halved twice: each run's (1, 2) frequency follows Verlet's
    (2/Δt) arcsin(ω_hΔt/2) (to 1e-5), and the time error ω(Δt) − ω(0) is O(Δt²): the
    successive differences ω(Δt) − ω(Δt/2), ω(Δt/2) − ω(Δt/4) (2.43e-4, 6.07e-5 of ω_h,
    measured; the O(A²) offset of ≈ 2e-6 cancels in them) have the observed order 2.00 ± 0.05."""
    problem, settings = CASE.problem(1)
    omegas = []
    for f in (1, 2, 4):
        ds = cartan.simulate(problem, integrator="rattle", dt=settings["dt"] / f, t_end=settings["t_end"],
                             save_every=1, progress=False)
        omega = mode_frequencies(ds, problem)[(1, 2)]
        assert abs(omega / _predicted(problem, {"dt": settings["dt"] / f}, (1, 2)) - 1.0) < 1e-5
        omegas.append(omega)
    differences = -np.diff(omegas)
    order = observed_orders(differences)[0]
    assert abs(order - 2.0) < 0.05, (omegas, order)


@pytest.mark.slow
def test_true_edge_supports_give_the_same_frequency():
    """The (1, 2) mode on the 9 × 9 plate with the core's hard penalty supports (P = 100, 400):
    its frequency differs from the odd-periodic lattice's (the discrete dispersion, which that
    lattice meets to 1e-6) by −3.31e-4 and −8.61e-5 (measured): O(1/P), the springs' compliance
    (ratio 3.84 ≈ 4), and the extrapolation P → ∞ leaves 5e-6, below 1e-3 of the lattice's own
    error (1.19e-2): the supported lattice and the odd-periodic one are the same plate."""
    diffs = {}
    for P in (100.0, 400.0):
        problem = plate_modes_problem(8, modes=[(1, 2)], supports=P)
        settings = plate_modes_settings(problem, modes=[(1, 2)], supports=P)
        ds = cartan.simulate(problem, integrator="rattle", progress=False, **settings)
        omega = mode_frequencies(ds, problem, [(1, 2)])[(1, 2)]
        diffs[P] = omega / _predicted(problem, settings, (1, 2)) - 1.0
        assert float(ds["constraint_residual"].values[1:].max()) <= 1e-12
    ratio = diffs[100.0] / diffs[400.0]
    assert 3.5 < ratio < 4.5, diffs
    lattice_error = lattice_plate_frequency(problem.medium, (1, 2), 1.0, 0.125) / plate_frequency(
        problem.medium, (1, 2)) - 1.0
    assert abs((4.0 * diffs[400.0] - diffs[100.0]) / 3.0) < 1e-3 * lattice_error, diffs
