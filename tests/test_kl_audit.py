"""Further closed-form checks of the ``kirchhoff-love`` and ``helfrich-membrane`` media, beyond the
registered Navier plate (docs/media/kirchhoff-love.md, "Further checks"): the clamped square plate
(deflection, moments, first frequency), the simply supported 2:1 plate and the central point
force, a strip rolled up by an end moment (geometrically exact), and the Helfrich energy of a
sphere with spontaneous curvature."""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np
import pytest

import cartan

try:
    import cartan_kirchhoff_love.plugin as kl_plugin
except ModuleNotFoundError:  # not installed yet: the package beside the others
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "plugins"))
    import cartan_kirchhoff_love.plugin as kl_plugin

from cartan_kirchhoff_love import cases as C  # noqa: E402


@pytest.fixture(scope="module", autouse=True)
def registered():
    """The media registered (through their entry point when installed, else in-process)."""
    from cartan.plugins import reset_registry

    if "kirchhoff-love" not in cartan.registry("media"):
        reset_registry([("kirchhoff_love", kl_plugin)])
    yield


def _orders(errors: list[float]) -> np.ndarray:
    """log₂ of the ratios of successive errors (the resolution doubles)."""
    e = np.abs(np.asarray(errors, dtype=float))
    return np.log2(e[:-1] / e[1:])


# ---------------------------------------------------------------------------- clamped square plate
@pytest.fixture(scope="module")
def clamped():
    """Centre values of the quarter lattice at m = 5, 9, 17 (n = 9, 17, 33 on the whole plate)."""
    out = []
    for m in (5, 9, 17):
        problem = C.clamped_plate_problem(m)
        out.append(C.clamped_centre_values(cartan.solve_static(problem, tol=1e-10), problem))
    return out


def test_clamped_plate_deflection_second_order(clamped):
    errors = [v["deflection"] / C.CLAMPED_DEFLECTION - 1.0 for v in clamped]
    # measured −4.34e-2, −1.10e-2, −2.76e-3: the lattice's O(dx²), from below
    assert all(e < 0.0 for e in errors)
    assert np.allclose(_orders(errors), 2.0, atol=0.05)
    assert abs(errors[-1]) < 3e-3


def test_clamped_plate_moments(clamped):
    centre = [v["centre_moment"] / C.CLAMPED_CENTRE_MOMENT - 1.0 for v in clamped]
    edge = [v["edge_moment"] / C.CLAMPED_EDGE_MOMENT - 1.0 for v in clamped]
    # centre: O(dx²) (1.46e-2, 3.86e-3, 9.76e-4 measured); mid-edge: the nodal strain of a clamped
    # node is its half-cell's, Δ/2 inside the plate, where M' ≠ 0: O(dx) (0.417, 0.235, 0.126)
    assert np.allclose(_orders(centre), 2.0, atol=0.1)
    assert abs(centre[-1]) < 1.5e-3
    assert np.all((_orders(edge) > 0.75) & (_orders(edge) < 1.1))


def test_clamped_plate_first_frequency():
    lam = [C.clamped_plate_frequency(m, iterations=3)[-1] for m in (5, 9, 17)]
    errors = [x / C.CLAMPED_LAMBDA - 1.0 for x in lam]
    # measured 2.74e-2, 6.55e-3, 1.62e-3 (orders 2.07, 2.01); Leissa's λ has 5 digits (±1.4e-5),
    # the third inverse iteration is within 4e-6 of the lattice's λ (the fourth's change)
    assert all(e > 0.0 for e in errors)
    assert np.allclose(_orders(errors), 2.0, atol=0.1)
    assert errors[-1] < 2e-3


def test_clamped_frequency_bad_input():
    with pytest.raises(ValueError, match="iterations"):
        C.clamped_plate_frequency(5, iterations=0)
    with pytest.raises(ValueError, match="m must"):
        C.clamped_plate_problem(2)


def test_clamped_plate_four_clamped_faces():
    """Four Clamped faces: the edge constraints θ_e,3 = 0 are rank-deficient by one (the alternating
    sums along the lines of u and of v between the clamps are the same combination); the statics'
    regularised constraint block (REG_CONSTRAINTS) solves it: the whole plate gives the quarter
    plate's centre deflection (−4.341e-2 at n = 9, measured on both to 1e-6) and holds the
    constraints to round-off."""
    n = 9
    medium = cartan.medium("kirchhoff-love", E=1.0, poisson=0.3, thickness=0.01)
    q = 1e-4 * 0.01 * medium.bending_stiffness / C.CLAMPED_DEFLECTION
    grid = cartan.Grid((n, n), length=(1.0, 1.0))
    bounds = {face: cartan.Clamped() for face in ("u-start", "u-end", "v-start", "v-end")}
    problem = cartan.Problem(medium, grid, medium.initial_state(grid, "flat"), bounds,
                             loads=[C.ConstantFieldPotential(np.array([0.0, 0.0, -q]), 1.0)])
    ds = cartan.solve_static(problem, tol=1e-10)
    w = -float(ds["position"].values[0][n // 2, n // 2, 2]) * medium.bending_stiffness / q
    assert abs(w / C.CLAMPED_DEFLECTION - 1.0 + 4.341234e-2) < 1e-6   # the quarter lattice's error at n = 9
    assert float(ds["constraint_residual"].max()) < 1e-14


# ---------------------------------------------------------------------------- Navier: 2:1 plate, point force
def test_navier_series_reference():
    ref = C.navier_series(1.0, 1.0)
    # Timoshenko & Woinowsky-Krieger Table 8 (ν = 0.3), and the registered case's coefficients
    assert ref["deflection"] == pytest.approx(C.DEFLECTION_COEFFICIENT, rel=2e-6)
    assert ref["moment_uu"] == pytest.approx(C.MOMENT_COEFFICIENT, rel=2e-6)
    assert ref["point"] == pytest.approx(0.01160, abs=5e-6)  # Timoshenko & Woinowsky-Krieger, four digits
    rect = C.navier_series(2.0, 1.0)
    # Table 8, b/a = 2: α = 0.01013, β = 0.1017, β₁ = 0.0464, to half a unit of their last digit
    assert rect["deflection"] == pytest.approx(0.01013, abs=5e-6)
    assert rect["moment_vv"] == pytest.approx(0.1017, abs=5e-5)
    assert rect["moment_uu"] == pytest.approx(0.0464, abs=5e-5)
    with pytest.raises(ValueError, match="a and b"):
        C.navier_series(0.0, 1.0)


def test_navier_rectangle_second_order():
    ref = C.navier_series(2.0, 1.0)
    errors = []
    for n in (9, 17):
        problem = C.rectangular_navier_problem(n, 2.0)
        ds = cartan.solve_static(problem, tol=1e-10)
        q = -float(problem.loads[0].field[2])
        D = problem.medium.bending_stiffness
        i, j = problem.grid.shape[0] // 2, n // 2
        errors.append([-float(ds["position"].values[0][i, j, 2]) * D / q / ref["deflection"] - 1.0,
                       -float(ds["bending_moment_uu"].values[0][i, j]) / q / ref["moment_uu"] - 1.0,
                       -float(ds["bending_moment_vv"].values[0][i, j]) / q / ref["moment_vv"] - 1.0])
    errors = np.array(errors)
    # measured at n = 9, 17: w −2.03e-2, −5.06e-3; M_uu −2.03e-2, −5.04e-3; M_vv −2.40e-2, −5.96e-3
    assert np.allclose(np.log2(errors[0] / errors[1]), 2.0, atol=0.05)
    assert np.all(np.abs(errors[1]) < 7e-3)


def test_navier_point_force():
    ref = C.navier_series(1.0, 1.0)["point"]
    errors = []
    for n in (9, 17, 33):
        problem = C.rectangular_navier_problem(n, 1.0, point=True)
        ds = cartan.solve_static(problem, tol=1e-10)
        size = -float(problem.loads[0].density[n // 2, n // 2, 2]) / (n - 1) ** 2
        w = -float(ds["position"].values[0][n // 2, n // 2, 2]) * problem.medium.bending_stiffness / size
        errors.append(w / ref - 1.0)
    # measured −2.78e-2, −8.55e-3, −2.53e-3: orders 1.70, 1.76 → 2, the O(dx² log dx) of a point force
    orders = _orders(errors)
    assert np.all((orders > 1.6) & (orders < 2.0))
    assert abs(errors[-1]) < 3e-3


# ---------------------------------------------------------------------------- strip rolled up by a moment
@pytest.mark.parametrize("turns", [0.5, 1.0])
def test_rolled_strip_is_the_koiter_arc(turns):
    for n in (5, 9):
        problem = C.rolled_strip_problem(n, turns)
        ds = cartan.solve_static(problem, tol=1e-10, load_steps=8)
        # circles are orbits of one-parameter subgroups: the lattice is exact at any n, to the
        # Newton tolerance (measured ≤ 2e-11)
        assert C.rolled_strip_error(ds, problem) < 1e-9
    # the inextensible elastica (curvature M/D) differs by the mid-surface's shortening O((κh)²)
    moment = float(problem.boundaries["u-end"].load[4])
    lam, p = C.koiter_arc(problem.medium, moment)
    k = moment / problem.medium.bending_stiffness
    u = problem.grid.coordinates(0)
    gap = np.max(np.hypot(lam / p * np.sin(p * u) - np.sin(k * u) / k,
                          lam / p * (1.0 - np.cos(p * u)) - (1.0 - np.cos(k * u)) / k))
    assert C.rolled_strip_error(ds, problem, inextensible=True) == pytest.approx(gap, abs=1e-9)
    assert 1.0 - lam == pytest.approx((k * problem.medium.h) ** 2 / 12.0, rel=1e-2)


def test_rolled_strip_bad_input():
    with pytest.raises(ValueError, match="turns"):
        C.rolled_strip_problem(5, math.inf)


# ---------------------------------------------------------------------------- Helfrich sphere
SPHERES = [  # (κ_b, κ_G, c₀, σ, R)
    (1.0, 0.0, 0.0, 0.0, 1.0), (1.0, -0.8, 0.0, 0.0, 1.0), (1.0, -0.8, 0.7, 0.0, 1.3), (2.0, -0.5, -0.6, 0.25, 0.8)]


def test_helfrich_sphere_energy():
    rel = []
    for kb, kg, c0, sigma, radius in SPHERES:
        row = []
        for n in (8, 16, 32):
            e, exact = C.helfrich_sphere_energy(n, radius, bending_modulus=kb, gaussian_modulus=kg,
                                                spontaneous_curvature=c0, tension=sigma)
            row.append(e / exact - 1.0)
        rel.append(row)
    rel = np.array(rel)
    # 8πκ_b + 4πκ_G (c₀ = 0) and ½κ_b(2/R − c₀)²·4πR² + 4πκ_G + 4πR²σ: the density is exact at every
    # node of a sphere, so E_h/E − 1 is the lattice area's error (6.45e-3, 1.61e-3, 4.02e-4), the same for
    # every set of moduli to round-off
    assert np.allclose(rel, rel[0], rtol=1e-9, atol=1e-12)
    assert np.allclose(_orders(rel[0]), 2.0, atol=0.01)
    # with c₀ = 2/R the bending term vanishes: only the Gauss–Bonnet term 4πκ_G is left
    e, exact = C.helfrich_sphere_energy(16, 1.3, gaussian_modulus=-0.8, spontaneous_curvature=2.0 / 1.3)
    assert exact == pytest.approx(-3.2 * math.pi, rel=1e-14)
    assert e / exact - 1.0 == pytest.approx(rel[0, 1], rel=1e-9)


# ---------------------------------------------------------------------------- clamped annulus (polar chart)
def test_clamped_annulus_second_order():
    errors = []
    for k in (4, 8):
        problem = C.annulus_problem(k + 1, 8 * k + 1)
        err, spread = C.annulus_error(cartan.solve_static(problem, tol=1e-10), problem)
        # the polar chart's rest strains are exact (circles and rays are one-parameter orbits):
        # the deflection is axisymmetric to round-off (measured ≤ 2.4e-13)
        assert spread < 1e-10
        errors.append(err)
    # measured 0.257, 0.0653, 0.0166 at nr = 5, 9, 17 (orders 1.98, 1.98): the clamped–clamped
    # beam's 4(Δ/(a − b))² of the lattice, the annulus being a strip of width a − b = 0.5
    assert np.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.05)
    assert errors[1] < 0.07


def test_annulus_bad_input():
    with pytest.raises(ValueError, match="nphi"):
        C.annulus_problem(5, 32)
    with pytest.raises(ValueError, match="inner and outer"):
        C.annulus_reference(np.array([0.7]), 1.0, 0.5)


def test_clamped_case_registered():
    """The registered ``plate-clamped-kl`` at its quick levels (n = 9, 17 on the whole plate)."""
    from cartan_verification.case import observed_orders, run_case

    case = cartan.registry("cases")["plate-clamped-kl"]
    errors = [run_case(case, level)[0] for level in case.quick()]
    assert abs(observed_orders(errors)[0] - 2.0) <= 0.1, errors
    assert errors[-1] <= case.tolerance


# ---------------------------------------------------------------------------- pressurised cylinder
def test_pressurised_cylinder_second_order():
    errors = []
    for n in (16, 32):
        problem, pins = C.pressurised_cylinder_problem(n, 0.01)
        ds = cartan.solve_static(problem, tol=1e-10, pins=pins)
        pos = np.asarray(ds["position"].values[0])
        radius = np.hypot(pos[..., 0], pos[..., 2] + 1.0)
        assert np.ptp(radius) < 1e-12                       # stays round (measured ≤ 3e-14)
        lam = C.cylinder_stretch(problem.medium, 0.01 * problem.medium.h, 1.0)
        errors.append(float(np.mean(radius)) / lam - 1.0)
        # relative to the displacement λ − 1: the inscribed polygon's (2π/n)²/6 (2.517e-2, 6.33e-3 measured)
        assert errors[-1] / (lam - 1.0) == pytest.approx(-(2.0 * np.pi / n) ** 2 / 6.0, rel=0.03)
    assert np.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.05)
