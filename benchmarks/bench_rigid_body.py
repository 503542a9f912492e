"""Accuracy history of the free rigid body reference problem (cartan.rigid_body).

Case: 𝕀 = diag(1, 2, 3), ω₀ = (1, 0, 0.5) (Ω-period 14.940779), errors against the exact
Jacobi elliptic solution at t = 6.
"""

from __future__ import annotations

import numpy as np

from cartan.groups.so3 import SO3
from cartan.rigid_body import kinetic_energy, rigid_body_exact, step_rigid_body

INERTIA = np.array([1.0, 2.0, 3.0])
OMEGA0 = np.array([1.0, 0.0, 0.5])
T_END = 6.0


def _final_error(method: str, dt: float) -> float:
    """max(‖log(R_exactᵀR)‖, |M − M_exact|) at T_END."""
    group = SO3()
    n = int(round(T_END / dt))
    t, R, M = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, dt, n, method, save_every=n)
    W_ex, R_ex = rigid_body_exact(INERTIA, OMEGA0, t[-1:])
    attitude = np.linalg.norm(group.log(R_ex[0].T @ R[-1]))
    return float(max(attitude, np.linalg.norm(M[-1] - INERTIA * W_ex[0])))


def _observed_order(method: str, dt: float) -> float:
    return float(np.log2(_final_error(method, dt) / _final_error(method, dt / 2)))


def track_lie_verlet_order():
    """Observed order of lie-verlet, log₂(e(0.02)/e(0.01)); expected 2."""
    return _observed_order("lie-verlet", 0.02)


track_lie_verlet_order.unit = "order"


def track_rkmk4_order():
    """Observed order of rkmk4, log₂(e(0.1)/e(0.05)); expected 4."""
    return _observed_order("rkmk4", 0.1)


track_rkmk4_order.unit = "order"


def track_energy_drift():
    """Relative energy drift of lie-verlet over 10⁴ steps of 0.05 (t = 500, ~33 periods).

    The least-squares trend of E/E(0) − 1 times the duration: a symplectic method has
    bounded oscillations (amplitude 2.2e-5 here) and no trend.
    """
    t, _, M = step_rigid_body(SO3(), np.eye(3), INERTIA * OMEGA0, INERTIA, 0.05, 10_000, "lie-verlet")
    dE = kinetic_energy(INERTIA, M) / kinetic_energy(INERTIA, M[0]) - 1.0
    return float(abs(np.polyfit(t, dE, 1)[0]) * t[-1])


track_energy_drift.unit = "relative"


def track_energy_error_amplitude():
    """max |E/E(0) − 1| of lie-verlet over the same 10⁴ steps; O(Δt²)."""
    _, _, M = step_rigid_body(SO3(), np.eye(3), INERTIA * OMEGA0, INERTIA, 0.05, 10_000, "lie-verlet")
    return float(np.max(np.abs(kinetic_energy(INERTIA, M) / kinetic_energy(INERTIA, M[0]) - 1.0)))


track_energy_error_amplitude.unit = "relative"
