"""``rattle`` on a d = 2 lattice: the multiplier systems' kept symmetric-mode factors.

On a d ≥ 2 lattice the Python step factorises each configuration's ``B_c P B_cᵀ`` once, in
symmetric mode (``_splu_spd``), and the closing velocity projection's factors at Φₙ₊₁ are the
next step's predictor and chord factors (``_REUSE_FACTORS``).  The steps are those of the
general LU at every use to round-off.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as spla

import cartan.integrators.constrained as constrained
from cartan.integrators.constrained import Rattle
from cartan.problem import Damping
from cartan.schemes.lattice import Lattice

plate_modes = pytest.importorskip("cartan_kirchhoff_love.plate_modes")

#: steps compared (the first projects the sampled modes onto the constraints)
STEPS = 6


def _run(monkeypatch: pytest.MonkeyPatch, reuse: bool, damped: bool = False) -> tuple[Lattice, object, Rattle, int]:
    """STEPS Python steps of the odd-periodic plate (8 × 8 nodes, the modes (1, 1), (1, 2), (2, 2)
    at A = 10⁻⁴a) at its settings' Δt, with ``damped`` a linear damping (whose closing kick has
    its own multiplier matrix); returns the scheme, the state, the integrator and the number of
    sparse LU factorisations."""
    monkeypatch.setattr(constrained, "_REUSE_FACTORS", reuse)
    calls = [0]
    splu = spla.splu

    def counted(*args, **kwargs):
        calls[0] += 1
        return splu(*args, **kwargs)

    monkeypatch.setattr(spla, "splu", counted)
    problem = plate_modes.plate_modes_problem(4)
    dt = plate_modes.plate_modes_settings(problem)["dt"]
    if damped:
        problem = dataclasses.replace(problem, loads=[Damping([0.5, 0.5, 0.5, 0.01, 0.01, 0.01])])
    scheme = Lattice(problem)
    state = scheme.initial_state()
    integ = Rattle()
    for _ in range(STEPS):
        integ.step(scheme, state, dt)
    monkeypatch.setattr(spla, "splu", splu)
    return scheme, state, integ, calls[0]


def test_kept_factors_give_the_general_lu_steps(monkeypatch):
    """The plate's states after STEPS steps with the kept symmetric-mode factors and with the
    general LU at every use agree to round-off: the constraints hold to the iteration's 1e-13 in
    both, and S and the edge transforms differ by less than 2e-11 of their size.  That is the
    round-off of these solves (the multiplier systems' condition is ≈ 1e10): measured 2.7e-12 of
    max|S| (3.5e-5), and the general LU with another column ordering (``MMD_ATA``) differs from the
    default one by as much, 2.3e-12; the transforms by 3e-16.  The kept factors take one
    factorisation per step plus the start's projection (8), the general LU two per step (13)."""
    sch, fast, integ_f, n_fast = _run(monkeypatch, True)
    _, ref, integ_r, n_ref = _run(monkeypatch, False)
    for st, integ in ((fast, integ_f), (ref, integ_r)):
        assert integ.constraint_residual(sch, st) < 1e-13
    scale_S = float(np.max(np.abs(ref.S)))
    assert scale_S > 0.0  # the plate moves
    assert np.max(np.abs(fast.S - ref.S)) < 2e-11 * scale_S
    for key in ref.arrays:
        size = max(1.0, float(np.max(np.abs(ref.arrays[key]))))
        assert np.max(np.abs(fast.arrays[key] - ref.arrays[key])) < 2e-11 * size
    assert n_fast <= STEPS + 2 < 2 * STEPS <= n_ref


def test_kept_factors_under_damping(monkeypatch):
    """With a linear damping the closing kick's matrix B P_Γ Bᵀ (P_Γ = M⁺(I + ½ΔtΓM⁺)⁻¹/w) is
    factorised by the general LU and kept beside the step's symmetric one: the states agree
    with the general LU at every use as without damping (measured 4.8e-12 of max|S|), and the
    constraints hold to the iteration's 1e-13."""
    sch, fast, integ_f, _ = _run(monkeypatch, True, damped=True)
    _, ref, integ_r, _ = _run(monkeypatch, False, damped=True)
    for st, integ in ((fast, integ_f), (ref, integ_r)):
        assert integ.constraint_residual(sch, st) < 1e-13
    assert np.max(np.abs(fast.S - ref.S)) < 2e-11 * float(np.max(np.abs(ref.S)))


def test_symmetric_mode_factors_solve_the_plate_system():
    """``_splu_spd`` of the plate's ``B P Bᵀ`` (symmetric positive definite, condition ≈ 1e10)
    solves it with a backward error at round-off: |A x − b| ≤ 1e-13 |A||x| (the general LU's
    level), the same x as the general LU to the condition's 1e10·ε ≈ 1e-6 relative."""
    problem = plate_modes.plate_modes_problem(4)
    scheme = Lattice(problem)
    state = scheme.initial_state()
    integ = Rattle()
    held = integ._constraints(scheme, state)
    con, unknown, nodes, _ = held
    B = con.matrix(state)
    A = (B @ integ._metric(scheme, nodes, unknown, None) @ B.T).tocsc()
    b = np.random.default_rng(7).standard_normal(A.shape[0])
    x = constrained._splu_spd(A).solve(b)
    x_ref = spla.splu(A).solve(b)
    normA = float(abs(A).sum(axis=1).max())
    assert np.max(np.abs(A @ x - b)) < 1e-13 * normA * np.max(np.abs(x))
    assert np.max(np.abs(x - x_ref)) < 1e-5 * np.max(np.abs(x_ref))
