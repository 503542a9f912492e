"""A Nambu–Goto loop seen from a moving frame, in that frame's conformal–temporal gauge
(docs/media/relativistic-rod.md, "Further checks").

The Lorentz transform of a solution is a solution, but the transformed worldsheet is no longer
in the temporal gauge t = τ unless it is re-sliced: for x = ½[a(σ − τ) + b(σ + τ)] (|a′| = |b′| = 1)
boosted by β along e₁, t′ = γ(τ + βx₁) = ½[F₊(σ + τ) − F₋(σ − τ)] with the light-cone maps

    F₊(s) = γ(s + βb₁(s)),    F₋(s) = γ(s − βa₁(s))        (monotone: |a₁′|, |b₁′| ≤ 1),

so σ̃± = F±(σ±) are conformal light-cone coordinates of the lab and the movers

    Ã(F₋(s)) = (γ(a₁(s) − βs), a₂(s), a₃(s)),    B̃(F₊(s)) = (γ(b₁(s) + βs), b₂(s), b₃(s))

are unit-speed again (|dÃ/dσ̃|² = γ²[(a₁′ − β)² + (1 − β²)(1 − a₁′²)]/(γ(1 − βa₁′))² = 1): the
lab solution is x̃(σ̃, t) = ½[Ã(σ̃ − t) + B̃(σ̃ + t)], with σ̃ of period γ·(the rest period). The
loop moves at βc along e₁; its 4-momentum is Λ(β)P and its Lorentz charges Λ M Λᵀ.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cartan.medium import check_finite

__all__ = ["boosted_kibble_turok", "kibble_turok_movers"]

Mover = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def kibble_turok_movers(tilt: float) -> tuple[Mover, Mover]:
    """The movers of the Kibble–Turok loop of radius ρ = 1 (rest frame, centre at the origin).

    ``a(s) = (cos s, sin s, 0)`` and ``b(s) = (cos s, cos ψ sin s, sin ψ sin s)``, as in
    :func:`cartan_relativistic.string.loop_exact` with ρ = 1.

    Parameters
    ----------
    tilt : float
        Angle ψ between the planes of a and b.

    Returns
    -------
    (a, b) : callables ``s [n] -> (position [n, 3], tangent [n, 3])``
    """
    psi = float(check_finite("tilt", tilt, ()))
    cp, sp = math.cos(psi), math.sin(psi)

    def a(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        z = np.zeros_like(s)
        return np.stack([np.cos(s), np.sin(s), z], -1), np.stack([-np.sin(s), np.cos(s), z], -1)

    def b(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.stack([np.cos(s), cp * np.sin(s), sp * np.sin(s)], -1),
                np.stack([-np.sin(s), cp * np.cos(s), sp * np.cos(s)], -1))

    return a, b


def _invert(F: Callable[[np.ndarray], np.ndarray], dF: Callable[[np.ndarray], np.ndarray], y: np.ndarray,
            x0: np.ndarray) -> np.ndarray:
    """Solve F(x) = y for a monotone F by Newton's method (to 1e-15)."""
    x = x0.copy()
    for _ in range(100):
        dx = (F(x) - y) / dF(x)
        x -= dx
        if np.abs(dx).max() < 1e-15 * max(1.0, float(np.abs(x).max())):
            return x
    raise RuntimeError("light-cone map inversion did not converge")  # pragma: no cover - monotone maps


def boosted_kibble_turok(sigma: np.ndarray, t: float, beta: float, tilt: float = math.pi / 3
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Lab positions and velocities of the Kibble–Turok loop (ρ = 1, c = 1) moving at βc along e₁.

    Parameters
    ----------
    sigma : array, shape ``(n,)``
        The lab's conformal coordinate σ̃ (period 2πγ; energy μc² per unit σ̃).
    t : float
        Lab time.
    beta : float
        Speed of the loop along e₁, in (−1, 1).
    tilt : float
        Angle ψ between the planes of the movers (0: the circular loop released from rest).

    Returns
    -------
    (x, v) : arrays of shape ``(n, 3)``
        Positions and velocities ∂_t x at lab time t, in the lab's conformal–temporal gauge.

    Raises
    ------
    ValueError
        ``beta`` outside (−1, 1).
    """
    beta = float(check_finite("beta", beta, ()))
    if not -1.0 < beta < 1.0:
        raise ValueError(f"beta must be in (−1, 1) (a speed in units of c), got {beta!r}")
    sigma = np.asarray(check_finite("sigma", sigma), dtype=float)
    g = 1.0 / math.sqrt(1.0 - beta * beta)
    a, b = kibble_turok_movers(tilt)
    sp = _invert(lambda s: g * (s + beta * b(s)[0][:, 0]), lambda s: g * (1.0 + beta * b(s)[1][:, 0]),
                 sigma + t, (sigma + t) / g)
    sm = _invert(lambda s: g * (s - beta * a(s)[0][:, 0]), lambda s: g * (1.0 - beta * a(s)[1][:, 0]),
                 sigma - t, (sigma - t) / g)
    (A, dA), (B, dB) = a(sm), b(sp)
    At = np.column_stack([g * (A[:, 0] - beta * sm), A[:, 1], A[:, 2]])
    Bt = np.column_stack([g * (B[:, 0] + beta * sp), B[:, 1], B[:, 2]])
    dAt = np.column_stack([g * (dA[:, 0] - beta), dA[:, 1], dA[:, 2]]) / (g * (1.0 - beta * dA[:, 0]))[:, None]
    dBt = np.column_stack([g * (dB[:, 0] + beta), dB[:, 1], dB[:, 2]]) / (g * (1.0 + beta * dB[:, 0]))[:, None]
    return 0.5 * (At + Bt), 0.5 * (dBt - dAt)
