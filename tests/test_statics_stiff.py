"""``solve_static`` on a stiff rod: the propped cantilever under an end moment with stretch and
shear stiffness GA = 1e9·EI/L² (docs/statics.md, "Stiff rods: the round-off floor and the
tension of a held end").

Both ends hold their positions, so the deflection stretches the rod: the arc length exceeds
the chord by ½∫w'², an axial tension N = (EA/L)·½∫w'² ds stiffens the bending, and the end
turns by less than the linear (Timoshenko) closed form ML(1 + φ)/(EI(4 + φ)): by 9.2 % at
EA = 1e9 although θ² ≈ 6e-8 (the parameter is EA·θ²·L²/EI ≈ 60, not θ²).  The reference is
the beam–string (moderate-rotation) solution: EI w'''' = N w'' with w(0) = w'(0) = 0,
w(L) = 0, EI w''(L) = M, and N from the compatibility equation above (shear left out:
φ = 12EI/(GA L²) = 1.2e-8).  The residual cannot reach tol·f = 1e-15 (its round-off floor is
EA·ε_mach·|X| ≈ 2e-7 per node); Newton ends on its increment test, and the lattice reaches the
reference at second order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import cartan
from cartan.problem import NodeForce

EI, M, L = 1.0, 1e-3, 1.0
EPS = float(np.finfo(float).eps)
NODES, WEIGHTS = np.polynomial.legendre.leggauss(40)  # ½∫w'²: w' is smooth (k ≤ 2), exact to round-off


def _slope(N: float):
    """w'(x) of the beam–string with axial tension N: w = A + Bx + C e^{k(x−L)} + D e^{−kx},
    k = √(N/EI) (the decaying exponentials keep the 4 × 4 system well conditioned)."""
    k = math.sqrt(N / EI)
    e = math.exp(-k * L)
    A = np.array([[1.0, 0.0, e, 1.0], [0.0, 1.0, k * e, -k], [1.0, L, 1.0, e], [0.0, 0.0, k * k, k * k * e]])
    _, b, c, d = np.linalg.solve(A, [0.0, 0.0, 0.0, M / EI])
    return lambda x: b + k * (c * math.exp(k * (x - L)) - d * math.exp(-k * x))


def _beam_string(EA: float) -> tuple[float, float]:
    """(θ(L), N): the end's angle and the tension of the propped cantilever held at both ends."""

    def gap(N: float) -> float:
        x = 0.5 * L * (NODES + 1.0)
        wp = np.array([_slope(N)(xi) for xi in x])
        return N - EA / L * 0.5 * L * float(np.dot(WEIGHTS, 0.5 * wp**2))

    N = brentq(gap, 1e-9, 1e3, xtol=1e-14, rtol=1e-12)
    return _slope(N)(L), N


def _solve(GA: float, n: int):
    rod = cartan.medium("cosserat-rod", stretch_shear=[GA] * 3, bend_twist=[EI] * 3, mass=1.0,
                        rotational_inertia=[1.0, 1.0, 1.0])
    grid = cartan.Grid(n, length=L)
    ends = {"start": cartan.Clamped(), "end": cartan.Held(components=(0, 1, 2))}
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries=ends,
                             loads=[NodeForce(grid, [0.0, 0.0, 0.0, 0.0, 0.0, M], node=-1)])
    ds = cartan.solve_static(problem, tol=1e-12)
    R = ds.frame.values[-1, -1]
    return ds, math.atan2(R[1, 0], R[0, 0])


def test_the_reference_is_the_linear_closed_form_at_small_EA_and_stiffer_at_large():
    """The beam–string reference tends to ML/(4EI) as EA → 0 (N ∝ EA: −1.39e-6 relative at
    EA = 1e4, the value of GA in tests/test_held_end_load.py) and lies 9.2 % below it at EA = 1e9
    (the tension's stiffening; measured −9.229e-2, N = 3.174).  At small EA, N = EA(ML/EI)²/240
    (the cubic deflection's ½∫w'² = (ML/4EI)²L/15)."""
    linear = M * L / (4.0 * EI)
    theta, N = _beam_string(1e4)
    assert -1e-5 < theta / linear - 1.0 < 0.0 and N == pytest.approx(1e4 * (M * L / EI) ** 2 / 240.0, rel=1e-3)
    theta, N = _beam_string(1e9)
    assert -0.10 < theta / linear - 1.0 < -0.085 and 3.0 < N < 3.3


def test_stiff_propped_cantilever_reaches_the_beam_string_angle_at_second_order():
    """GA = 1e9: measured errors against the beam–string angle −1.19e-2, −2.97e-3, −7.4e-4 at
    9, 17, 33 nodes (ratios 4.0, 4.0: the lattice's O(h²)); against the linear closed form
    they stay at −10.3 %, −9.5 %, −9.3 %.  Newton takes 5–6 iterations and ends on its
    increment test with ‖r‖_∞ ≈ 1.7–2.6e-7 ≈ (0.8–1.2)·EA·ε_mach, the residual's round-off floor
    (the stresses EA(X − X₀) of strains known to ε_mach·|X|, |X| ≈ 1), far above tol·f."""
    GA = 1e9
    phi = 12.0 * EI / (GA * L * L)
    closed = M * L * (1.0 + phi) / (EI * (4.0 + phi))
    reference, N = _beam_string(GA)
    errors, linear_errors = [], []
    for n in (9, 17, 33):
        ds, angle = _solve(GA, n)
        assert ds.attrs["newton_converged"] == 1
        assert ds.attrs["newton_converged_by"] == "increment"  # tol·f = 1e-15 is below the floor
        assert ds.attrs["newton_residual_tol"] == pytest.approx(1e-12 * M)
        assert ds.attrs["newton_residual_max"] <= 10.0 * GA * EPS  # the floor, with a margin of 10
        # the lattice's axial tension: EA times the mean stretch of the edges, against the reference
        stretch = float(np.mean(ds.X.values[-1, :, 0])) - 1.0
        assert GA * stretch == pytest.approx(N, rel=1e-2)  # O(h²) too: −3.1e-3, −7.3e-4, −1.8e-4
        errors.append(angle / reference - 1.0)
        linear_errors.append(angle / closed - 1.0)
    assert abs(errors[-1]) <= 1e-3
    for coarse, fine in zip(errors, errors[1:]):
        assert math.log2(coarse / fine) == pytest.approx(2.0, abs=0.1)
    # the gap to the linear closed form is the tension's, not the resolution's
    assert all(-0.11 < e < -0.09 for e in linear_errors)
