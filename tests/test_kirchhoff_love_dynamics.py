"""Dynamics of the ``kirchhoff-love`` plate with ``rattle``: the verified plate frequency.

The registered case ``plate-flexural-wave-kl`` (a standing flexural wave of a plate periodic in
u and v, :mod:`cartan_kirchhoff_love.cases`) at every level: the frequency against Rayleigh's
ω² = Dk⁴/(ρh(1 + k²h²/12)) at the observed order of the lattice's own dispersion, each
measurement against that discrete dispersion (with Verlet's time error), the constraints
θ_α,3 = 0 at every saved step, the energy against Verlet's modified energy, the time step and
the amplitude shown not to matter, and the rotary inertia ρh³/12 shown to lower the frequency
by the factor the formula gives.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_kirchhoff_love.cases import (
    PlateFlexuralWaveKL,
    flexural_frequency,
    flexural_wave_problem,
    lattice_flexural_frequency,
    quarter_period_frequency,
)
from cartan_kirchhoff_love.kirchhoff_love import KirchhoffLove, koiter_energy
from cartan_verification.case import observed_orders, run_levels

import cartan

CASE = cartan.registry("cases")["plate-flexural-wave-kl"]


@pytest.fixture(scope="module")
def levels():
    """Every level of the case (n = 8, 16, 32, 64; 372 rattle steps in all, ≈ 8 s):
    ``[(error, ds, problem, settings)]``."""
    return run_levels(CASE)


def _discrete(problem, settings) -> float:
    """The lattice's frequency with Verlet's time error: what ``rattle`` gives in the linear range."""
    k = 2.0 * math.pi * CASE.mode / problem.grid.length[0]
    return lattice_flexural_frequency(problem.medium, k, problem.grid.spacing[0], settings["dt"])


def _measure(problem, dt: float, t_end: float) -> float:
    ds = cartan.simulate(problem, integrator="rattle", dt=dt, t_end=t_end, save_every=1, progress=False)
    return quarter_period_frequency(ds, problem)


def test_case_is_registered_as_a_dynamic_case():
    assert isinstance(CASE, PlateFlexuralWaveKL) and not CASE.static
    assert CASE.default_integrators == ("rattle",) and CASE.expected_order() == 2.0


def test_dispersion_relation_is_the_medium_s():
    """The reference's ingredients are the medium's: the kinetic metric (ρh, ρh, ρh, ρh³/12,
    ρh³/12, 0) and, for cylindrical bending (κ_uu = κ, κ_vv = 0, the flat rest state), the
    energy density ½Dκ², D = Eh³/(12(1 − ν²)); Rayleigh's ω then has the factor 1 + k²h²/12."""
    E, nu, h, rho = 2.0, 0.25, 0.07, 3.0
    kl = cartan.medium("kirchhoff-love", E=E, poisson=nu, thickness=h, density=rho)
    np.testing.assert_allclose(kl.inertia(), [rho * h, rho * h, rho * h, rho * h**3 / 12, rho * h**3 / 12, 0.0],
                               rtol=1e-15)
    D = E * h**3 / (12 * (1 - nu**2))
    X0 = kl.rest_strain()
    for kappa in (1e-3, -2e-3):
        X = X0.copy()
        X[0, 4] = kappa          # b_uu = θ_u,1 π_u,2 − θ_u,2 π_u,1 = κ
        assert koiter_energy(X, X0, np.array([E, nu, h])) == pytest.approx(0.5 * D * kappa**2, rel=1e-13)
    k = 2 * math.pi / 0.8
    assert flexural_frequency(kl, k) == pytest.approx(math.sqrt(D * k**4 / (rho * h * (1 + k**2 * h**2 / 12))),
                                                      rel=1e-14)
    assert flexural_frequency(kl, k, rotary=False) == pytest.approx(k**2 * math.sqrt(D / (rho * h)), rel=1e-14)


def test_frequency_converges_at_the_lattice_s_order(levels):
    """|ω/ω_R − 1| = 2.63e-2, 6.19e-3, 1.53e-3, 3.81e-4 at n = 8 … 64: each measurement is the
    lattice's own dispersion with Verlet's time error to 5e-6 (measured 1.2e-6: the wave's O(A²)
    nonlinearity, see below), so the observed orders are those of the discrete dispersion
    (2.086, 2.020, 2.002, its (kΔ)⁴ term lifting the coarse pair) to 0.01, and the asymptotic
    pairs lie in [1.95, 2.1]."""
    errors = np.array([e for e, *_ in levels])
    predicted = []
    for err, ds, problem, settings in levels:
        k = 2.0 * math.pi / problem.grid.length[0]
        omega_ref = flexural_frequency(problem.medium, k)
        omega = quarter_period_frequency(ds, problem)
        assert abs(omega / omega_ref - 1.0) == pytest.approx(err, rel=1e-12)
        discrete = _discrete(problem, settings)
        assert abs(omega / discrete - 1.0) < 5e-6, (problem.grid.shape, omega, discrete)
        predicted.append(discrete / omega_ref - 1.0)
        assert omega > omega_ref  # the lattice's dispersion is stiff: (1 − 2β)(kΔ)²/24 > 0
    orders = observed_orders(errors)
    np.testing.assert_allclose(orders, observed_orders(predicted), atol=0.01)
    assert np.all((orders[1:] > 1.95) & (orders[1:] < 2.1)), orders
    assert errors[-1] <= CASE.tolerance


def test_constraints_hold_at_every_step(levels):
    """θ_α,3 = 0 on every edge at every saved step (every step is saved), the initial state's
    included (its frames are turned by the chord angles): ≤ 1e-12."""
    for _, ds, _, _ in levels:
        res = ds["constraint_residual"].values
        assert res.shape == (ds.sizes["time"],) and float(res.max()) <= 1e-12
        assert float(np.abs(ds["X"].values[..., 2]).max()) <= 1e-12


def test_energy_is_verlet_s_modified_energy(levels):
    """No load, no damping: K + V = E₀ up to Verlet's bounded error.  On the wave's mode
    ``rattle`` is velocity Verlet, which conserves ½Mv² + ½Kx²(1 − (ω_hΔt)²/4) exactly, so the
    energy dips by (ω_hΔt)²/4 of E₀ at the zero crossing (the largest deviation over the
    quarter period): measured to 1e-4 of that at every level; a drift or a working constraint
    force would show as a difference of order one."""
    for _, ds, problem, settings in levels:
        assert float(np.abs(ds["external_work"].values).max()) == 0.0
        energy = ds["kinetic_energy"].values + ds["potential_energy"].values
        deviation = float(np.max(np.abs(energy / energy[0] - 1.0)))
        k = 2.0 * math.pi / problem.grid.length[0]
        omega_h = lattice_flexural_frequency(problem.medium, k, problem.grid.spacing[0])
        assert deviation == pytest.approx((omega_h * settings["dt"]) ** 2 / 4.0, rel=1e-2)
        assert np.all(energy <= energy[0] * (1.0 + 1e-9))  # the dip, not a growth


def test_time_error_is_below_the_space_error(levels):
    """Halving Δt at n = 16 moves the error by 3.8e-5 of ω, 0.6 % of the error (6.19e-3): Verlet's
    (ωΔt)²/24 times ¾, as the discrete prediction says (both runs to 5e-6)."""
    err, ds, problem, settings = levels[1]
    k = 2.0 * math.pi / problem.grid.length[0]
    omega_ref = flexural_frequency(problem.medium, k)
    omega_half = _measure(problem, 0.5 * settings["dt"], settings["t_end"])
    err_half = abs(omega_half / omega_ref - 1.0)
    assert abs(err - err_half) < 0.02 * err
    discrete = lattice_flexural_frequency(problem.medium, k, problem.grid.spacing[0], 0.5 * settings["dt"])
    assert abs(omega_half / discrete - 1.0) < 5e-6


def test_amplitude_is_in_the_linear_range(levels):
    """Halving A (10⁻⁴L → 5·10⁻⁵L) at n = 16 moves ω by < 1e-5 relative (measured 9e-7), three
    orders below the lattice error, and the distance to the linear discrete prediction drops by
    ≈ 4: it is the wave's O(A²) nonlinearity."""
    err, ds, problem, settings = levels[1]
    omega = quarter_period_frequency(ds, problem)
    small = flexural_wave_problem(problem.grid.shape[0], amplitude=0.5 * CASE.amplitude)
    omega_small = _measure(small, settings["dt"], settings["t_end"])
    assert abs(omega_small / omega - 1.0) < 1e-5 < 1e-2 * err
    discrete = _discrete(problem, settings)
    ratio = (omega / discrete - 1.0) / (omega_small / discrete - 1.0)
    assert 3.0 < ratio < 5.0, ratio


class _RotaryInertia(KirchhoffLove):
    """The medium with its rotational kinetic entries scaled (a device of this test: the medium
    fixes them at ρh³/12)."""

    def __init__(self, scale: float, **params):
        super().__init__(**params)
        self.scale = scale

    def inertia(self) -> np.ndarray:
        out = super().inertia().copy()
        out[3:5] *= self.scale
        return out


def test_rotary_inertia_lowers_the_frequency_as_the_formula_says(levels):
    """With ρh³/12 the measured ω (n = 64) is Rayleigh's to 3.8e-4 and lies below the classical
    Kirchhoff k²√(D/ρh) by 1 − 1/√(1 + k²h²/12) = 1.60e-2 (to 5 %: the lattice error is 2 % of
    the shift).  Scaling the rotational inertia by 4 and by 1/4 (n = 16) moves ω down and up by
    the factor the formula gives (−4.5 % and +1.2 %): each run is the discrete dispersion with
    that inertia to 5e-6."""
    _, ds, problem, _ = levels[-1]
    k = 2.0 * math.pi / problem.grid.length[0]
    h = problem.medium.h
    omega = quarter_period_frequency(ds, problem)
    classical = flexural_frequency(problem.medium, k, rotary=False)
    shift = 1.0 - 1.0 / math.sqrt(1.0 + k**2 * h**2 / 12.0)
    assert omega < classical
    assert (1.0 - omega / classical) == pytest.approx(shift, rel=0.05)

    _, ds16, p16, s16 = levels[1]
    n, params = p16.grid.shape[0], p16.medium.parameters()
    measured = {1.0: quarter_period_frequency(ds16, p16)}
    for scale in (4.0, 0.25):
        prob = flexural_wave_problem(n, amplitude=CASE.amplitude, medium=_RotaryInertia(scale, **params))
        # the zig-zag of the frames (the Nyquist rotation the constraints leave free) has
        # ω = (2c/Δ)/√scale: Δt = ½Δ/c·min(1, √scale)
        dt = s16["dt"] * min(1.0, math.sqrt(scale))
        t_end = CASE.periods * 2.0 * math.pi / flexural_frequency(prob.medium, k)
        steps = math.ceil(t_end / dt)
        measured[scale] = _measure(prob, t_end / steps, t_end)
        discrete = lattice_flexural_frequency(prob.medium, k, prob.grid.spacing[0], t_end / steps)
        assert abs(measured[scale] / discrete - 1.0) < 5e-6, (scale, measured[scale], discrete)
        # the formula's ratio to the unscaled medium (0.955 and 1.012), to the difference of the
        # two lattice errors (1 − 2β)(kΔ)²/24, β = Jk²/(ρh + Jk²) from 0.008 to 0.116: ≤ 1.1e-3
        ratio = flexural_frequency(prob.medium, k) / flexural_frequency(p16.medium, k)
        assert measured[scale] / measured[1.0] == pytest.approx(ratio, abs=2e-3)
    assert measured[4.0] < measured[1.0] < measured[0.25]


def test_bad_wave_parameters():
    with pytest.raises(ValueError, match="mode"):
        flexural_wave_problem(8, mode=4)
    with pytest.raises(ValueError, match="amplitude"):
        flexural_wave_problem(8, amplitude=-1.0)
    with pytest.raises(ValueError, match="n must"):
        flexural_wave_problem(2)
    kl = cartan.medium("kirchhoff-love")
    with pytest.raises(ValueError, match="dt"):
        lattice_flexural_frequency(kl, 2 * math.pi, 0.125, dt=10.0)
