"""Limits of the ``relativistic-rod`` medium (docs/media/relativistic-rod.md §2, §6).

* Slow motion, v/c → 0: a Nambu–Goto standing wave, run through the core, against the linear
  taut string (tension μc², mass μ per lab length) with the same lab shape: the difference
  falls as (v/c)² (fitted slope), and at the quarter period it is the frequency shift
  ω = ck J₀(θ₀) of the Nambu–Goto wave, (π/8)(v/c)² to leading order.
* The boosted rod scene: a rod of rest length L₀ in inertial motion at βc along its axis,
  run in proper time: 4-momentum (γ, γβ)μcL₀, lab length L₀/γ at equal lab time, lab clocks
  γ times faster than proper time.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_relativistic.cases import NewtonianLimit
from cartan_relativistic.limit import (
    amplitude,
    lab_period,
    newtonian_string,
    standing_wave,
    tilt_curve,
    tilt_for_speed,
)

import cartan

EPS = np.finfo(float).eps


# ---------------------------------------------------------------------------- closed forms
def test_standing_wave_closed_form():
    """The Jacobi–Anger curve has the tangent angle θ₀ cos(ks) (its derivative, by central
    differences), the Virasoro constraints hold, and d'Alembert's string starts on its shape."""
    L, th = 2 * math.pi, math.asin(0.3)
    s = np.linspace(0.0, L, 41)
    a, da = tilt_curve(s, th, L)
    d = 1e-5
    fd = (tilt_curve(s + d, th, L)[0] - tilt_curve(s - d, th, L)[0]) / (2 * d)
    assert np.abs(fd - da).max() <= 1e-9  # central difference: O(d²) ≈ 1e-10 plus round-off/d ≈ 1e-11
    assert np.allclose(np.arctan2(da[:, 1], da[:, 0]), th * np.cos(2 * math.pi * s / L), atol=1e-15)
    assert tilt_curve(np.array([L]), th, L)[0][0, 0] == pytest.approx(lab_period(th, L), rel=1e-14)
    x, v = standing_wave(s, 0.7, th, L)
    xs = (standing_wave(s + d, 0.7, th, L)[0] - standing_wave(s - d, 0.7, th, L)[0]) / (2 * d)
    assert np.abs(np.sum(v * xs, axis=-1)).max() <= 1e-9  # ⟨ṙ, r′⟩ = 0
    assert np.abs(np.sum(xs * xs, axis=-1) + np.sum(v * v, axis=-1) - 1.0).max() <= 1e-9  # |x′|² + |v|² = 1
    assert newtonian_string(a[:, 0], 0.0, th, L) == pytest.approx(a[:, 1], abs=1e-14)
    # the largest speed of the motion is c sin θ₀, reached at the quarter period
    _, vq = standing_wave(np.linspace(0, L, 401), L / 4, th, L)
    assert np.linalg.norm(vq, axis=-1).max() == pytest.approx(0.3, rel=1e-12)


@pytest.mark.parametrize(("call", "match"), [(lambda: tilt_for_speed(0.0), "beta must be in"),
                                             (lambda: tilt_for_speed(0.9), "beta must be in"),
                                             (lambda: lab_period(0.0, 1.0), "theta0 must be in"),
                                             (lambda: amplitude(0.1, -1.0), "length must be"),
                                             (lambda: tilt_curve(np.zeros(2), math.nan, 1.0), "theta0 must be in")])
def test_limit_arguments_are_checked(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ---------------------------------------------------------------------------- v/c → 0 through the core
@pytest.fixture(scope="module")
def case():
    return NewtonianLimit()


@pytest.fixture(scope="module")
def rows(case):
    return case.measure()


def test_case_is_registered_as_a_limit(case):
    registered = cartan.registry("cases")[case.name]
    assert isinstance(registered, NewtonianLimit)
    assert case.expected_order() == 2.0 and case.space_order is None and case.time_order_of is None
    assert case.limit_levels() == {0: 5.0, 1: 10.0, 2: 20.0, 3: 40.0}


@pytest.mark.slow  # the periodic string with a translation holonomy compiles its own loop (≈ 40 s)
def test_nambu_goto_run_is_exact_at_courant_one(rows):
    """Courant number 1 on the lattice: d'Alembert's solution at the nodes, to round-off
    (positions of order L = 2π, relative to A ≥ 0.025: ≤ 32 steps × 2π ε / A ≈ 2e-12)."""
    for r in rows:
        assert r["exact"] <= 2e-12, r["exact"]


@pytest.mark.slow  # the periodic string with a translation holonomy compiles its own loop (≈ 40 s)
def test_difference_falls_as_v_over_c_squared(case, rows):
    """Expected exponent 2 (quartic term of the Nambu–Goto Lagrangian, docs §2); the next
    term is smaller by (v/c)² ≤ 0.04, so the fitted slope of the three finest levels lies
    within 2 ± 0.05."""
    from cartan.study import observed_order

    beta = np.array([r["beta"] for r in rows])
    err = np.array([r["error"] for r in rows])
    slope = observed_order(beta, err)
    assert abs(slope - 2.0) <= 0.05, (err, slope)
    assert np.all(np.abs(np.log2(err[:-1] / err[1:]) - 2.0) <= 0.05), err  # every pair, not only the fit
    assert err[-1] <= case.tolerance


@pytest.mark.slow  # the periodic string with a translation holonomy compiles its own loop (≈ 40 s)
def test_quarter_period_is_the_frequency_shift(rows):
    """At t = L/4c the Nambu–Goto string is straight (y = 0: a_y has odd harmonics only) while
    the taut string, faster by 1/J₀(θ₀), is at cos(π/(2J₀)) ≈ −(π/8)θ₀² of its fundamental's
    amplitude: the difference is (π/8)(v/c)²(1 + O((v/c)²)); the bound (v/c)² on the relative
    deviation is that O term with coefficient 1 (measured 0.74)."""
    for r in rows:
        b = r["beta"]
        assert r["quarter_time"] == pytest.approx(2 * math.pi / 4, rel=1e-14)
        assert abs(r["quarter"] / (math.pi / 8 * b * b) - 1.0) <= b * b, r


@pytest.mark.slow  # the periodic string with a translation holonomy compiles its own loop (≈ 80 s)
def test_the_difference_is_seen(case):
    """The error is not vacuous: a node moved across the string by 1e-3 A shows."""
    problem, settings = case.problem(3)
    ds = case.run(problem, settings, "lie-verlet")
    e0 = case.error(ds, problem)
    moved = ds.copy(deep=True)
    moved.lab_y.values[-1, 10] += 1e-3 * amplitude(case.tilt(problem), case.length)
    assert case.error(moved, problem) >= 1e-3 - e0 > e0
    assert case.tilt(problem) == pytest.approx(math.asin(0.025), rel=1e-12)


@pytest.mark.slow  # the periodic string with a translation holonomy compiles its own loop (≈ 40 s)
def test_limit_chart(case, rows, tmp_path):
    from matplotlib.figure import Figure

    fig = Figure()
    slope = case.draw(rows, fig)
    assert len(fig.axes) == 2 and abs(slope - 2.0) <= 0.05
    fig.savefig(tmp_path / "limit.png")
    assert (tmp_path / "limit.png").stat().st_size > 10_000


# ---------------------------------------------------------------------------- the boosted rod scene
@pytest.fixture(scope="module")
def boosted():
    sc = cartan.scene("relativistic-rod-boosted")
    return sc, sc.simulate(compiled=False, progress=False)


def test_boosted_rod_four_momentum(boosted):
    """P = (γ, γβ) μ c L₀ at every saved frame (P⁰ = γ E_rest / c): sums of 9 node terms of
    order γ, to a few ε."""
    sc, ds = boosted
    med, L0, beta = sc.problem.medium, sc.problem.grid.length[0], 0.8
    gamma = 1.0 / math.sqrt(1.0 - beta**2)
    E_rest = med.mu * med.c**2 * L0
    assert ds.sizes["time"] == 9
    assert np.allclose(ds.energy.values, gamma * E_rest, rtol=20 * EPS, atol=0)
    assert np.allclose(ds.momentum_x.values, gamma * beta * E_rest / med.c, rtol=20 * EPS, atol=0)
    assert np.abs(ds.momentum_y.values).max() == 0.0 and np.abs(ds.momentum_z.values).max() == 0.0
    assert np.allclose(ds.lorentz_factor.values, gamma, rtol=20 * EPS, atol=0)


def test_boosted_rod_contraction_and_dilation(boosted):
    """At equal lab time (the far end's, the near end carried along its lab worldline) the
    endpoints are L₀/γ apart; each node's lab clock advances γΔτ between frames (round-off of
    exp(ΔτN) compositions with entries ≈ γ: 1e-13)."""
    sc, ds = boosted
    L0, gamma = sc.problem.grid.length[0], 5.0 / 3.0
    t = ds.coordinate_time.values  # [frame, node]
    x = ds.lab_x.values
    tau = ds.time.values
    rate = np.diff(t, axis=0) / np.diff(tau)[:, None]
    assert np.allclose(rate, gamma, rtol=1e-13, atol=0)
    v = np.diff(x[:, 0]) / np.diff(t[:, 0])  # the near end's lab velocity
    assert np.allclose(v, 0.8, rtol=1e-13, atol=0)
    for k in range(len(tau)):
        near = x[k, 0] + v[min(k, len(v) - 1)] * (t[k, -1] - t[k, 0])
        assert x[k, -1] - near == pytest.approx(L0 / gamma, rel=1e-13)
    # not vacuous: the rest-frame length (no contraction) is far outside the tolerance
    assert abs(x[0, -1] - x[0, 0] - L0 / gamma) > 0.1


def test_boosted_straight_state_is_checked():
    rod = cartan.medium("relativistic-rod")
    grid = cartan.Grid(5, length=1.0)
    with pytest.raises(ValueError, match=r"boost must be in \(−1, 1\)"):
        rod.initial_state(grid, "straight", boost=-1.0)
    with pytest.raises(ValueError, match="takes no parameter"):
        rod.initial_state(grid, "straight", tilt=0.1)
    init = rod.initial_state(grid, "straight", boost=0.6)
    eta = math.atanh(0.6)
    lam = init.Phi[:, 1:, 1:]
    assert np.allclose(lam[:, 0, 0], math.cosh(eta), rtol=1e-15) and np.allclose(lam[:, 1, 0], math.sinh(eta))
    # the events are simultaneous in the rod's rest frame: r = B(η)(0, u, 0, 0)
    u = grid.coordinates(0)
    assert np.allclose(init.Phi[:, 1, 0], math.sinh(eta) * u) and np.allclose(init.Phi[:, 2, 0], math.cosh(eta) * u)


def test_boosted_rod_picture_is_lab_simultaneous(boosted, tmp_path):
    """The picture interpolates each worldline to common lab times: the drawn rod is L₀/γ long
    (linear interpolation of straight worldlines is exact)."""
    from cartan_relativistic.pictures import draw, lab_snapshots

    sc, ds = boosted
    times, xs, ys = lab_snapshots(ds.coordinate_time.values, ds.lab_x.values, ds.lab_y.values)
    assert times.size == ds.sizes["time"] and np.all(np.diff(times) > 0)
    assert np.allclose(xs[:, -1] - xs[:, 0], sc.problem.grid.length[0] * 0.6, rtol=1e-13, atol=0)
    assert np.abs(ys).max() == 0.0
    draw(ds, str(tmp_path / "rod.png"))
    assert (tmp_path / "rod.png").stat().st_size > 10_000
