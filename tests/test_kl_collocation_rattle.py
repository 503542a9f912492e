"""``rattle`` on the ``collocation`` scheme for d = 2: the Kirchhoff–Love plate's held
θ_α,3 = 0 on the nodal strains (paper §III, §III.E, §VII.B;
:class:`cartan.constraints.NodalStrainConstraints`).

The plate is the simply supported square plate of ``plate-modes-kl`` with the core's hard
penalty supports (``plate_modes_problem(M, supports=100)``; the collocation scheme takes no
holonomy, so the odd-periodic plate of the lattice is not available), its initial frames turned
so that the collocation's own nodal strains hold θ_α,3 = 0 (the lattice's slopes leave them
O(A(kΔ)²) off at the edges, whose one-sided stencils differ from the lattice's).  Checked: all
2(M + 1)² nodal rows held (at the flat plate each row carries its own rotation, ``ad_{θ_α}``:
none is dependent); the rows and their rate against finite differences of the drift; the rows
at round-off along a run; the energy balance of second order in Δt; and (slow) the three
modes' frequencies converging to Rayleigh's as the grid is refined.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from toys import assert_rows_follow_the_drift

import cartan
from cartan.integrators import Rattle
from cartan.schemes.collocation import Collocation
from cartan.supports import PenaltySupport

pytest.importorskip("cartan_kirchhoff_love")
from cartan_kirchhoff_love.plate_modes import (  # noqa: E402
    mode_frequencies,
    plate_frequency,
    plate_modes_problem,
    plate_modes_settings,
)

#: the supports' penalty factor (the lattice's supported plate is 3.3e-4 off its exact supports at M = 8)
P = 100.0


def _theta3(problem: cartan.Problem, Phi0: np.ndarray, rv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """θ_α,3 ``[M + 1, M + 1, 2]`` of the collocation's nodal strains for the frames of rotation
    vectors ``rv`` ``[M + 1, M + 1, 3]`` at the positions of ``Phi0``, and those frames."""
    Phi = Phi0.copy()
    Phi[..., 1:, 1:] = Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(*rv.shape[:2], 3, 3)
    plain = cartan.Problem(problem.medium, problem.grid, cartan.InitialState(Phi=Phi))
    return Collocation(plain, "fd2").strain_from_frames(Phi)[..., :, 2], Phi


def _plate(cells: int) -> cartan.Problem:
    """``plate_modes_problem(cells, supports=P)`` with the slopes of its frames (rotation
    components 0, 1) solved so that the collocation's θ_α,3 vanish (three quasi-Newton
    iterations on the Jacobian at the lattice's slopes, found by finite differences of step
    1e-7 on nodes five apart: the stencils reach two nodes; θ_α,3 ≤ 1e-17 after them)."""
    base = plate_modes_problem(cells, supports=P)
    Phi0 = base.initial.Phi
    n = cells + 1
    rv = Rotation.from_matrix(Phi0[..., 1:, 1:].reshape(-1, 3, 3)).as_rotvec().reshape(n, n, 3)
    r0 = _theta3(base, Phi0, rv)[0]
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    J = np.zeros((n, n, 2, n, n, 2))
    eps = 1e-7
    for a in range(5):
        for b in range(5):
            sel = (ii % 5 == a) & (jj % 5 == b)
            for comp in range(2):
                moved = rv.copy()
                moved[..., comp][sel] += eps
                dr = (_theta3(base, Phi0, moved)[0] - r0) / eps
                for p, q in zip(*np.nonzero(sel), strict=True):
                    near = (np.abs(ii - p) <= 2) & (np.abs(jj - q) <= 2)
                    J[near, :, p, q, comp] = dr[near]
    J = J.reshape(2 * n * n, 2 * n * n)
    for _ in range(3):
        r0, Phi = _theta3(base, Phi0, rv)
        rv[..., :2] -= np.linalg.solve(J, r0.ravel()).reshape(n, n, 2)
    r0, Phi = _theta3(base, Phi0, rv)
    assert np.max(np.abs(r0)) < 1e-15
    plate = base.medium
    support = PenaltySupport(position_stiffness=np.full(3, P * plate.E * plate.h * cells**2),
                             director_stiffness=P * plate.bending_stiffness * cells**2).hold(Phi)
    return cartan.Problem(plate, base.grid, cartan.InitialState(Phi=Phi), loads=[support], name="plate-modes-kl")


@pytest.fixture(scope="module")
def plate8() -> cartan.Problem:
    return _plate(8)


def test_every_nodal_row_is_held(plate8):
    """2(M + 1)² nodal rows, none dependent at the flat reference (θ_u = e₁, θ_v = e₂: row
    (i, u) reads ω₂ of node i, row (i, v) its ω₁), so all are held (T is None); a rank test at
    X = 0 (the held components' values only) would see D_u w and D_v w alone and drop 82 of the
    162 rows at M = 8."""
    scheme = Collocation(plate8, "fd2")
    state = scheme.initial_state()
    integ = Rattle()
    integ.reset()
    con = integ._constraints(scheme, state)[0]
    assert con.nrow == 2 * 9**2
    assert con.ncon == con.nrow and con.T is None
    assert float(np.max(np.abs(con.values(state)))) < 1e-15  # the frames start on the rows


def test_rows_are_the_exact_rate_of_the_drift(plate8):
    """``B_c δ`` and ``Ḃ_c N`` against central differences of the scheme's exact drift of step
    ε = 1e-4 at a moving, bent state (three steps): truncation ∝ ε², measured 5.1e-9 and 4.9e-9
    relative (5.1e-7 and 4.9e-7 at ε = 1e-3); bound 1e-7."""
    scheme = Collocation(plate8, "fd2")
    state = scheme.initial_state()
    integ = Rattle()
    integ.reset()
    for _ in range(3):
        integ.step(scheme, state, 6e-3)
    assert_rows_follow_the_drift(scheme, state, 5, 1e-7, 1e-7)


def _run(problem: cartan.Problem, dt: float, t_end: float):
    return cartan.simulate(problem, scheme="collocation", integrator="rattle", dt=dt, t_end=t_end,
                           save_every=1, progress=False)


def test_rows_at_round_off_and_second_order_balance(plate8):
    """The rows at every step to the iteration's tolerance (≤ 1e-12 absolute, the rows' scale
    being the unit metric; measured ≤ 1e-13), and E − W (the supports' springs in E) closing at
    O(Δt²): max |ΔE| to t = 100Δt₀ is 5.7e-5, 1.4e-5, 3.6e-6 of E at Δt₀ = ½Δ/(c√(1 + P)), Δt₀/2,
    Δt₀/4 (orders 2.001, 2.000); asserted order 2 ± 0.3 for the first pair."""
    settings = plate_modes_settings(plate8, supports=P)
    dt0 = settings["dt"]
    errs = []
    for dt in (dt0, 0.5 * dt0):
        ds = _run(plate8, dt, 100 * dt0)
        assert float(ds["constraint_residual"].max()) < 1e-12
        balance = (ds["kinetic_energy"] + ds["potential_energy"] - ds["external_work"]).values
        errs.append(float(np.max(np.abs(balance - balance[0]))))
    order = math.log2(errs[0] / errs[1])
    assert 1.7 < order < 2.3, (errs, order)


@pytest.mark.slow
def test_frequencies_converge():
    """λ of (1, 1), (1, 2), (2, 2) at M = 8 and 16 (Δt = ½Δ/(c√(1 + P)), 1.1 quarter periods of
    (1, 1)) approach Rayleigh's ω: every error shrinks by more than 2.5 (order > 1.3; measured
    ratios 2.95, 3.16, 3.20) and is below 2.5 % at M = 16 (measured 0.60 %, 2.01 %, 2.24 %)."""
    errors = []
    for cells in (8, 16):
        problem = _plate(cells)
        ds = cartan.simulate(problem, scheme="collocation", integrator="rattle", progress=False,
                             **plate_modes_settings(problem, supports=P))
        assert float(ds["constraint_residual"].max()) < 1e-12
        errors.append({mode: omega / plate_frequency(problem.medium, mode) - 1
                       for mode, omega in mode_frequencies(ds, problem).items()})
    for mode in errors[0]:
        assert abs(errors[0][mode]) > 2.5 * abs(errors[1][mode]), errors
        assert abs(errors[1][mode]) < 2.5e-2, errors
