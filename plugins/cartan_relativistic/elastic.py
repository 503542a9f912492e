"""The elastic string's reduced Lagrangian, momentum and stress (docs/media/relativistic-rod.md §2).

Reference formulas in numpy, point by point, for checking the derivation (the core cannot run
them: ℓ couples N and X non-quadratically).  With ṙ = ∂_t r, r′ = ∂_u r (4-vectors, r⁰ = ct),
A = −⟨ṙ, ṙ⟩, B = ⟨ṙ, r′⟩, C = ⟨r′, r′⟩ and the rest-frame stretch λ = √(C + B²/A):

    ℓ = −ε(λ) √A / c,
    S_y = ∂ℓ/∂ṙ = (ε/c) ηṙ/√A − (T/c)(B/√A) ηn,      Q_y = −∂ℓ/∂r′ = T (√A/c) ηn,

with T = ε′(λ) and n = (r′ + (B/A)ṙ)/λ the unit rest-frame tangent.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["ETA", "lagrangian", "momentum_stress", "newtonian_expansion", "stretch"]

#: Minkowski metric η = diag(−1, 1, 1, 1)
ETA = np.array([-1.0, 1.0, 1.0, 1.0])


def _mink(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(ETA * a * b, axis=-1)


def stretch(rdot: np.ndarray, rprime: np.ndarray) -> np.ndarray:
    """Rest-frame stretch λ = √(⟨r′, r′⟩ + ⟨ṙ, r′⟩²/(−⟨ṙ, ṙ⟩)), ``[..., 4]`` → ``[...]``."""
    A = -_mink(rdot, rdot)
    B = _mink(rdot, rprime)
    return np.sqrt(_mink(rprime, rprime) + B * B / A)


def lagrangian(rdot: np.ndarray, rprime: np.ndarray, eps: Callable, c: float) -> np.ndarray:
    """ℓ = −ε(λ)√A/c per unit reference length and unit time, ``[..., 4]`` → ``[...]``."""
    A = -_mink(rdot, rdot)
    return -eps(stretch(rdot, rprime)) * np.sqrt(A) / c


def momentum_stress(rdot: np.ndarray, rprime: np.ndarray, eps: Callable, deps: Callable,
                    c: float) -> tuple[np.ndarray, np.ndarray]:
    """``(S_y, Q_y)``, each ``[..., 4]`` (covariant components, ηṙ lowered), from the closed forms above."""
    A = -_mink(rdot, rdot)
    B = _mink(rdot, rprime)
    lam = stretch(rdot, rprime)
    n = (rprime + (B / A)[..., None] * rdot) / lam[..., None]
    sA = np.sqrt(A)[..., None]
    T = deps(lam)[..., None]
    S = (eps(lam)[..., None] / c) * ETA * rdot / sA - (T / c) * (B[..., None] / sA) * ETA * n
    Q = T * (sA / c) * ETA * n
    return S, Q


def newtonian_expansion(v: np.ndarray, xprime: np.ndarray, m: float, W: Callable, dW: Callable,
                        c: float) -> tuple[np.ndarray, np.ndarray]:
    """The c⁰ and c⁻² terms of ℓ + mc² for ε = mc² + W(λ), lab time (r = (ct, x⃗)).

    Returns
    -------
    (l0, l2) : arrays ``[...]``
        ``l0 = ½m|v|² − W(|x′|)`` and ``l2 = c⁻²[⅛m v⁴ + ½W v² − ½W′(|x′|)|x′|(v·x̂′)²]``.
    """
    v2 = np.sum(v * v, axis=-1)
    L = np.linalg.norm(xprime, axis=-1)
    vt = np.sum(v * xprime, axis=-1) / L
    l0 = 0.5 * m * v2 - W(L)
    l2 = (m * v2 * v2 / 8.0 + 0.5 * W(L) * v2 - 0.5 * dW(L) * L * vt * vt) / c**2
    return l0, l2
