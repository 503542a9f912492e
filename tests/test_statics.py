"""Static equilibria by Newton's method on the group (cartan.solve_static)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from cartan_verification.references import ELASTICA_TABLE as ELASTICA
from cartan_verification.references import timoshenko_linear_tip

import cartan
from cartan.statics import ConvergenceError, solve_static

# Timoshenko cantilever (VERIFICATION.md §4): L = 3, r = 0.25, E = 1e6, G = 1e4, α_c = 27/28
L, RADIUS, E, G, F = 3.0, 0.25, 1e6, 1e4, 15.0
ALPHA_C = 27.0 / 28.0


def _cantilever(rod, n, length, load):
    grid = cartan.Grid(n, length=length)
    return cartan.Problem(
        rod,
        grid,
        rod.initial_state(grid, "straight"),
        {"start": cartan.Clamped(), "end": cartan.Free(load=load)},
    )


def _timoshenko(n):
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0, shear_coefficient=ALPHA_C)
    # the rod lies along e₁ = x; the dead tip force points along −z
    return solve_static(_cantilever(rod, n, L, [0.0, 0.0, -F, 0.0, 0.0, 0.0]))


def _elastica(alpha, n=101, stiff=1e6, load_steps=4, **kw):
    rod = cartan.medium(
        "cosserat-rod", stretch_shear=[stiff] * 3, bend_twist=[1.0, 1.0, 1.0], mass=1.0, rotational_inertia=[1.0] * 3
    )
    return solve_static(_cantilever(rod, n, 1.0, [0.0, 0.0, -alpha, 0.0, 0.0, 0.0]), load_steps=load_steps, **kw)


def test_timoshenko_cantilever_second_order_and_linear_theory():
    """Tip deflections at 51, 101, 201 nodes: observed order 2.00; the converged deflection is below
    the linear Timoshenko value FL/(α_cGA) + FL³/(3EI) = 0.0677703 by 3.2e-4 relative (the geometric
    nonlinearity; 3.88e-4 at n = 51, 3.39e-4 at 101, 3.27e-4 at 201)."""
    A = math.pi * RADIUS**2
    I = math.pi * RADIUS**4 / 4.0
    w_lin = timoshenko_linear_tip(L, F, E * I, ALPHA_C * G * A)
    tips = []
    for n in (51, 101, 201):
        ds = _timoshenko(n)
        x = ds["position"].isel(time=0, node=-1).values
        tips.append(-float(x[2]))
        assert ds.attrs["newton_iterations"] <= 10
    order = math.log2((tips[0] - tips[1]) / (tips[1] - tips[2]))
    assert 1.8 <= order <= 2.3, (tips, order)
    rich = tips[2] + (tips[2] - tips[1]) / 3.0
    rel = (rich - w_lin) / w_lin
    assert -4e-4 < rel < -2.5e-4, (tips, rich, w_lin, rel)


@pytest.mark.parametrize(
    ("alpha", "stiff", "steps"),
    [(1.0, 1e6, 4), (2.0, 1e6, 4), (10.0, 1e5, 10)],
)
def test_cantilever_elastica_tip(alpha, stiff, steps):
    """Inextensible, unshearable limit (stretch and shear stiffness 1e6 or 1e5 × B/L²), load stepping
    from the straight rod, n = 101.  Measured errors against the tabulated elastica: vertical
    −4.9e-6, −9.8e-6, 8.2e-5 and shortening 1.2e-6, −2.9e-6, −1.4e-5 for PL²/B = 1, 2, 10 (the
    10 case is dominated by the finite stretch stiffness, P/(EA) = 1e-4)."""
    ds = _elastica(alpha, stiff=stiff, load_steps=steps)
    x = ds["position"].isel(time=0, node=-1).values
    vertical, shortening = -float(x[2]), 1.0 - float(x[0])
    ref_v, ref_s = ELASTICA[alpha]
    assert abs(vertical - ref_v) < 1e-3, (vertical, ref_v)
    assert abs(shortening - ref_s) < 1e-3, (shortening, ref_s)
    assert ds["load_factor"].values[-1] == 1.0


def test_newton_converges_quadratically():
    """Above the round-off floor the residual falls as r_{k+1} ≤ C r_k² (history in the message)."""
    ds = _elastica(1.0, stiff=1e4, load_steps=1)
    hist = ds["newton_residual"].values
    floor = 1e-8 * hist[0]
    pairs = [(a, b) for a, b in zip(hist[:-1], hist[1:], strict=True) if b > floor]
    ratios = [b / a**2 for a, b in pairs[-2:]]
    msg = f"residual history {np.array2string(hist, precision=3)}; r_(k+1)/r_k² = {ratios}"
    assert len(pairs) >= 2, msg
    assert all(r < 1.0 for r in ratios), msg
    assert all(b / a < 1e-2 for a, b in pairs[-2:]), msg
    assert hist[-1] < 1e-9 * max(hist), msg


def test_dataset_layout():
    ds = _timoshenko(21)
    assert ds.sizes["time"] == 1
    for name in ("position", "frame", "X", "potential_energy", "newton_residual", "load_factor"):
        assert name in ds, name
    assert ds.attrs["newton_iterations"] == ds.sizes["newton_step"]
    # the clamped end stays put and the frames stay in SO(3)
    assert np.allclose(ds["position"].isel(time=0, node=0).values, 0.0)
    R = ds["frame"].isel(time=0).values
    assert np.allclose(np.einsum("nji,njk->nik", R, R), np.eye(3), atol=1e-12)
    # seeding from a previous equilibrium converges at once
    again = solve_static(_cantilever(
        cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0), 21, L, [0, 0, -F, 0, 0, 0]
    ), initial=ds)
    assert again.attrs["newton_iterations"] <= 1


@pytest.mark.parametrize("follower", [False, True])
def test_free_rod_under_unbalanced_load_raises(follower):
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0)
    grid = cartan.Grid(50, length=L)
    prob = cartan.Problem(
        rod,
        grid,
        rod.initial_state(grid, "straight"),
        {"end": cartan.Free(load=[0, 0, -F, 0, 0, 0], follower=follower)},
    )
    t0 = time.perf_counter()
    with pytest.raises(ConvergenceError, match=r"Newton iteration.*residual.*(singular|stagnates)") as info:
        solve_static(prob)
    assert time.perf_counter() - t0 < 5.0
    assert isinstance(info.value, RuntimeError)
    assert info.value.residual > 1.0


def test_iteration_limit_is_reported():
    with pytest.raises(ConvergenceError, match="max_iter = 1"):
        _elastica(2.0, stiff=1e4, load_steps=1, max_iter=1)


def test_options_are_validated():
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0)
    prob = _cantilever(rod, 11, L, [0, 0, -F, 0, 0, 0])
    with pytest.raises(ValueError, match="lattice"):
        solve_static(prob, scheme="collocation")
    with pytest.raises(ValueError, match="jacobian"):
        solve_static(prob, jacobian="exact")
    with pytest.raises(ValueError, match="load_steps"):
        solve_static(prob, load_steps=0)
