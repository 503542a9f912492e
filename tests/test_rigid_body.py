"""The free rigid body reference problem: exact Jacobi solution and the three integrators.

Reference case (VERIFICATION.md §4): 𝕀 = diag(1, 2, 3), ω₀ = (1, 0, 0.5); the body angular
velocity has period 14.940779, energy and |M| are conserved.
"""

from __future__ import annotations

import numpy as np
import pytest

from cartan.groups.so3 import SO3
from cartan.rigid_body import kinetic_energy, period, rigid_body_exact, step_rigid_body

INERTIA = np.array([1.0, 2.0, 3.0])
OMEGA0 = np.array([1.0, 0.0, 0.5])
# Circulates around axis 1 (|M|² < 2E·I₂), around axis 3 (|M|² > 2E·I₂), and a case with
# negative components that exercises the sign and phase bookkeeping.
INITIAL = [OMEGA0, np.array([0.2, 0.5, 1.0]), np.array([-0.3, 0.7, -1.0]), np.array([1.0, -0.4, -0.2])]


@pytest.fixture(scope="module")
def group():
    return SO3()


def hat(v: np.ndarray) -> np.ndarray:
    """so(3) hat map ``[..., 3] → [..., 3, 3]``."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2)


def rotvec(axis_angle) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues), independent of the code under test."""
    v = np.asarray(axis_angle, dtype=float)
    th = np.linalg.norm(v)
    K = hat(v / th)
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * K @ K


def d_dt(f, t: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Fourth-order central difference of ``f`` at ``t``."""
    return (f(t - 2 * h) - 8 * f(t - h) + 8 * f(t + h) - f(t + 2 * h)) / (12 * h)


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle of rotations ``[..., 3, 3]`` (quaternion form, accurate at small angles)."""
    skew = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                           R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    return np.arctan2(np.linalg.norm(skew, axis=-1), 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0))


# ---------------------------------------------------------------------------- exact solution
def test_period_reference_value():
    assert round(period(INERTIA, OMEGA0), 6) == 14.940779


def test_period_is_a_period_of_omega():
    T = period(INERTIA, OMEGA0)
    t = np.linspace(0.0, 3.0, 7)
    W0, _ = rigid_body_exact(INERTIA, OMEGA0, t)
    W1, _ = rigid_body_exact(INERTIA, OMEGA0, t + T)
    np.testing.assert_allclose(W1, W0, rtol=0, atol=1e-13)


@pytest.mark.parametrize("omega0", INITIAL, ids=lambda w: str(tuple(w)))
def test_exact_solution_satisfies_equations_of_motion(omega0):
    t = np.linspace(-20.0, 40.0, 1201)
    W, R = rigid_body_exact(INERTIA, omega0, t)
    M = INERTIA * W
    np.testing.assert_allclose(W[np.argmin(np.abs(t))], omega0, rtol=0, atol=1e-14)
    # Residual of the 4th-order difference, h = 1e-3: truncation ~h⁴|f⁽⁵⁾| ≲ 1e-12 and
    # round-off ~(18/12)·δ/h with δ ≲ 1e-13 the pointwise error of ellipj: 1e-9 is generous
    # (measured ≲ 1e-11).  A wrong sign, amplitude or phase gives O(1).
    Mdot = INERTIA * d_dt(lambda s: rigid_body_exact(INERTIA, omega0, s)[0], t)
    assert np.max(np.abs(Mdot - np.cross(M, W))) < 1e-9
    Rdot = d_dt(lambda s: rigid_body_exact(INERTIA, omega0, s)[1], t)
    assert np.max(np.abs(Rdot - R @ hat(W))) < 1e-9


@pytest.mark.parametrize("omega0", INITIAL, ids=lambda w: str(tuple(w)))
def test_exact_solution_invariants(omega0, group):
    t = np.linspace(0.0, 200.0, 2001)
    W, R = rigid_body_exact(INERTIA, omega0, t)
    M = INERTIA * W
    E = kinetic_energy(INERTIA, M)
    G = np.linalg.norm(M, axis=-1)
    # Round-off level: a few ulps of ellipj per evaluation.
    assert np.max(np.abs(E / E[0] - 1.0)) < 1e-13
    assert np.max(np.abs(G / G[0] - 1.0)) < 1e-13
    m = np.einsum("nij,nj->ni", R, M)  # spatial angular momentum
    assert np.max(np.abs(m - m[0])) < 1e-13 * G[0]
    assert np.max(group.defect(R)) < 1e-13


def test_exact_solution_frame_covariance():
    """Permuted or rotated body axes describe the same motion (R ↦ R Qᵀ, Ω ↦ QΩ)."""
    t = np.linspace(0.0, 30.0, 61)
    R0 = rotvec([1.0, 2.0, 0.1])
    W, R = rigid_body_exact(INERTIA, OMEGA0, t, R0=R0)
    for Q in (np.eye(3)[[2, 0, 1]], rotvec([0.3, -0.5, 0.9])):
        J = Q @ np.diag(INERTIA) @ Q.T
        inertia = np.diag(J) if np.count_nonzero(J - np.diag(np.diag(J))) == 0 else J
        Wq, Rq = rigid_body_exact(inertia, Q @ OMEGA0, t, R0=R0 @ Q.T)
        np.testing.assert_allclose(Wq, W @ Q.T, rtol=0, atol=1e-13)
        np.testing.assert_allclose(Rq, R @ Q.T, rtol=0, atol=1e-12)


def test_separatrix_and_symmetric_top_are_rejected():
    with pytest.raises(ValueError, match="separatrix"):
        period(INERTIA, [0.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="separatrix"):
        rigid_body_exact(INERTIA, [1.0, 0.5, 1.0 / np.sqrt(3.0)], [0.0, 1.0])  # G² = 2E·I₂
    with pytest.raises(ValueError, match="distinct"):
        period([1.0, 2.0, 2.0], OMEGA0)


# ---------------------------------------------------------------------------- integrators
def final_error(group, method: str, dt: float, t_end: float = 6.0) -> float:
    """max(‖log(R_exactᵀR)‖, |M − M_exact|) at ``t_end``."""
    n = int(round(t_end / dt))
    t, R, M = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, dt, n, method, save_every=n)
    W_ex, R_ex = rigid_body_exact(INERTIA, OMEGA0, t[-1:])
    attitude = rotation_angle(R_ex[0].T @ R[-1])
    return max(attitude, np.linalg.norm(M[-1] - INERTIA * W_ex[0]))


def test_lie_verlet_second_order(group):
    # Symmetric method: e(h) = C h² + O(h⁴), so e(h)/e(h/2) = 4(1 + O(h²)); at h = 0.02
    # the correction is far below the ±10 % band [3.6, 4.4] (measured 3.9998).
    ratio = final_error(group, "lie-verlet", 0.02) / final_error(group, "lie-verlet", 0.01)
    assert 3.6 <= ratio <= 4.4


def test_rkmk4_fourth_order(group):
    # Not symmetric: e(h)/e(h/2) = 16(1 + O(h)); the O(h) term is ≈ +2 % at h = 0.1
    # (measured 16.34), inside the band [14, 18].  Errors (~1e-6) stay far above round-off.
    ratio = final_error(group, "rkmk4", 0.1) / final_error(group, "rkmk4", 0.05)
    assert 14.0 <= ratio <= 18.0


def test_forward_euler_first_order(group):
    ratio = final_error(group, "forward-euler", 0.01) / final_error(group, "forward-euler", 0.005)
    assert 1.8 <= ratio <= 2.2


def test_lie_verlet_energy_bounded_without_drift(group):
    dt, n = 0.05, 10_000  # t = 500, about 33 periods of Ω
    t, R, M = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, dt, n, "lie-verlet")
    E = kinetic_energy(INERTIA, M)
    dE = E / E[0] - 1.0
    amp = np.max(np.abs(dE))
    # Bounded: O(h²) with a modest constant (measured 2.2e-5 = 0.009 h²).
    assert amp < 0.04 * dt**2
    # No drift: the oscillation has the same envelope at the end as at the start (backward
    # error analysis: a modified energy is conserved up to exponentially small terms), and
    # the least-squares trend over the whole run is a tiny fraction of the amplitude.
    first, last = np.max(np.abs(dE[: n // 10])), np.max(np.abs(dE[-(n // 10):]))
    assert last <= 1.05 * first
    assert abs(np.polyfit(t, dE, 1)[0] * t[-1]) < 0.02 * amp
    # |M| is conserved exactly by the splitting (each sub-flow is a rotation of M).
    G = np.linalg.norm(M, axis=-1)
    assert np.max(np.abs(G / G[0] - 1.0)) < 1e-13


@pytest.mark.parametrize(("method", "dt", "n"), [("lie-verlet", 0.05, 10_000), ("rkmk4", 0.05, 2_000)])
def test_geometric_methods_stay_on_so3(group, method, dt, n):
    _, R, _ = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, dt, n, method, save_every=100)
    assert np.max(group.defect(R)) <= 1e-12


def test_forward_euler_leaves_so3(group):
    _, R, _ = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, 0.01, 200, "forward-euler",
                              save_every=100)
    # Each step multiplies RᵀR by (I + hΩ̂)ᵀ(I + hΩ̂) = I + h²Ω̂ᵀΩ̂: defect ≈ n h²|Ω|² ≈ 0.03.
    assert group.defect(R[-1]) > 1e-3


def test_save_cadence_and_validation(group):
    t, R, M = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, 0.1, 10, "rkmk4", save_every=5)
    assert t.shape == (3,) and R.shape == (3, 3, 3) and M.shape == (3, 3)
    np.testing.assert_allclose(t, [0.0, 0.5, 1.0])
    with pytest.raises(ValueError, match="method"):
        step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, 0.1, 10, "leapfrog")
    with pytest.raises(ValueError, match="principal"):
        Q = rotvec([0.1, 0.2, 0.3])
        step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, Q @ np.diag(INERTIA) @ Q.T, 0.1, 10)
