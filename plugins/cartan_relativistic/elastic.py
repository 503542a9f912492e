"""The elastic string's reduced Lagrangian, momentum and stress (docs/media/relativistic-rod.md §2).

Covariant reference formulas in numpy, point by point, for checking the derivation, and their
temporal-gauge forms (r = (ct, x⃗): ``temporal_*``, with the Hessian and the inverse Legendre
map) that :class:`cartan_relativistic.elastic_rod.ElasticRelativisticRod` runs through the
core's coupled-Lagrangian path.  With ṙ = ∂_t r, r′ = ∂_u r (4-vectors, r⁰ = ct),
A = −⟨ṙ, ṙ⟩, B = ⟨ṙ, r′⟩, C = ⟨r′, r′⟩ and the rest-frame stretch λ = √(C + B²/A):

    ℓ = −ε(λ) √A / c,
    S_y = ∂ℓ/∂ṙ = (ε/c) ηṙ/√A − (T/c)(B/√A) ηn,      Q_y = −∂ℓ/∂r′ = T (√A/c) ηn,

with T = ε′(λ) and n = (r′ + (B/A)ṙ)/λ the unit rest-frame tangent.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["ETA", "lagrangian", "momentum_stress", "newtonian_expansion", "quadratic_law", "stretch",
           "temporal_hessian", "temporal_lagrangian", "temporal_momentum", "temporal_stress", "temporal_velocity"]

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


# ---------------------------------------------------------------------------- temporal gauge
def quadratic_law(mu: float, k: float, c: float) -> tuple[Callable, Callable, Callable]:
    """``ε(λ) = μc² + ½k(λ − 1)²``, ``T = ε′(λ) = k(λ − 1)`` and ``ε″ = k``, elementwise."""
    return ((lambda lam: mu * c * c + 0.5 * k * (lam - 1.0) ** 2), (lambda lam: k * (lam - 1.0)),
            (lambda lam: np.full_like(lam, k)))


def _gauge_parts(v: np.ndarray, x: np.ndarray, c: float) -> tuple[np.ndarray, ...]:
    """a = √A = √(c² − v²), g = 1/a², b = B = v⃗·x⃗′, λ and ∂λ/∂v⃗ (docs §2, "Temporal gauge")."""
    a2 = c * c - np.sum(v * v, axis=-1)
    g = 1.0 / a2
    b = np.sum(v * x, axis=-1)
    lam = np.sqrt(np.sum(x * x, axis=-1) + b * b * g)
    dlam = (b * g)[..., None] * (x + (b * g)[..., None] * v) / lam[..., None]
    return np.sqrt(a2), g, b, lam, dlam


def temporal_lagrangian(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """ℓ(v⃗, x⃗′) = −ε(λ)√(c² − v²)/c in the temporal gauge r = (ct, x⃗), ``[..., 3]`` → ``[...]``."""
    a, _, _, lam, _ = _gauge_parts(v, x, c)
    return -law[0](lam) * a / c


def temporal_momentum(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """p⃗ = ∂ℓ/∂v⃗ = [ε v⃗/a − T a ∂λ/∂v⃗]/c, ``[..., 3]`` (the spatial part of S_y in §2)."""
    a, _, _, lam, dlam = _gauge_parts(v, x, c)
    return ((law[0](lam) / a)[..., None] * v - (law[1](lam) * a)[..., None] * dlam) / c


def temporal_stress(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """Q⃗ = −∂ℓ/∂x⃗′ = (T a/c) ∂λ/∂x⃗′ = (T a/c)(x⃗′ + (B/A) v⃗)/λ, ``[..., 3]`` (spatial part of Q_y)."""
    a, g, b, lam, _ = _gauge_parts(v, x, c)
    return (law[1](lam) * a / (c * lam))[..., None] * (x + (b * g)[..., None] * v)


def temporal_hessian(v: np.ndarray, x: np.ndarray, law: tuple, c: float) -> np.ndarray:
    """∂p⃗/∂v⃗ = ∂²ℓ/∂v⃗², ``[..., 3, 3]``: with q = λ², ∂²q = 2g x x + 4bg²(x v + v x) + 2b²g² I
    + 8b²g³ v v, ∂²λ = ∂²q/(2λ) − ∂λ ∂λ/λ, ∂a = −v/a, ∂²a = −I/a − v v/a³ and
    ∂²ℓ = −[ε″ a ∂λ∂λ + T(∂λ ∂a + ∂a ∂λ) + T a ∂²λ + ε ∂²a]/c."""
    a, g, b, lam, dlam = _gauge_parts(v, x, c)
    eye = np.eye(3)
    outer = np.einsum
    xx, vv, xv = outer("...i,...j->...ij", x, x), outer("...i,...j->...ij", v, v), outer("...i,...j->...ij", x, v)
    e = lambda s: s[..., None, None]  # noqa: E731 - scalar per point against a matrix
    Hq = 2 * e(g) * xx + 4 * e(b * g * g) * (xv + np.swapaxes(xv, -1, -2)) + 2 * e(b * b * g * g) * eye \
        + 8 * e(b * b * g**3) * vv
    Hlam = Hq / (2 * e(lam)) - outer("...i,...j->...ij", dlam, dlam) / e(lam)
    da = -v / a[..., None]
    Ha = -eye / e(a) - vv / e(a**3)
    T = law[1](lam)
    cross = outer("...i,...j->...ij", dlam, da)
    return -(e(law[2](lam) * a) * outer("...i,...j->...ij", dlam, dlam) + e(T) * (cross + np.swapaxes(cross, -1, -2))
             + e(T * a) * Hlam + e(law[0](lam)) * Ha) / c


def _newton(p: np.ndarray, x: np.ndarray, v: np.ndarray, law: tuple, c: float, iterations: int) -> np.ndarray | None:
    """Newton's method for p⃗(v⃗) = p⃗ from ``v`` (see :func:`temporal_velocity`); None if it fails."""
    done = False
    with np.errstate(invalid="ignore", divide="ignore"):
        for _ in range(iterations):
            R = temporal_momentum(v, x, law, c) - p
            J = temporal_hessian(v, x, law, c)
            if not (np.all(np.isfinite(R)) and np.all(np.isfinite(J))):
                return None
            try:
                dv = np.linalg.solve(J, R[..., None])[..., 0]
            except np.linalg.LinAlgError:
                return None
            alpha = np.ones((*v.shape[:-1], 1))
            for _ in range(60):  # stay inside the light cone
                out = np.linalg.norm(v - alpha * dv, axis=-1, keepdims=True) >= c
                if not np.any(out):
                    break
                alpha = np.where(out, 0.5 * alpha, alpha)
            v = v - alpha * dv
            if done:
                return v
            scale = np.maximum(np.linalg.norm(v, axis=-1), 1e-3 * c)
            done = bool(np.all(np.linalg.norm(dv, axis=-1) <= 1e-12 * scale) and np.all(alpha == 1.0))
    return None


def temporal_velocity(p: np.ndarray, x: np.ndarray, law: tuple, c: float, iterations: int = 40) -> np.ndarray:
    """The inverse Legendre map v⃗(p⃗, x⃗′) ``[..., 3]``: Newton per point on p⃗(v⃗) = p⃗.

    The Jacobian is the closed-form Hessian (:func:`temporal_hessian`), the start the
    Newtonian v⃗ = c²p⃗/ε(|x⃗′|) pulled inside the light cone, and a step that would leave the
    light cone is halved until it does not.  Once every correction is below 10⁻¹² of
    max(|v⃗|, 10⁻³c) one more step is taken (quadratic convergence: the result is at round-off).
    When that fails (fast motion along the string, where ℓ is far from quadratic in v⃗), the
    momentum is reached by continuation from p⃗ = 0 in 32 stages.

    Raises
    ------
    ValueError
        When Newton's method does not converge (no subluminal velocity has that momentum, or
        the Hessian of ℓ is singular there).
    """
    p = np.asarray(p, dtype=float)
    x = np.asarray(x, dtype=float)
    v = p * (c * c / law[0](np.linalg.norm(x, axis=-1)))[..., None]
    speed = np.linalg.norm(v, axis=-1, keepdims=True)
    v = np.where(speed >= 0.9 * c, v * (0.9 * c / np.maximum(speed, 1e-300)), v)
    out = _newton(p, x, v, law, c, iterations)
    if out is not None:
        return out
    v = np.zeros_like(p)
    for s in np.linspace(0.0, 1.0, 33)[1:]:
        v = _newton(s * p, x, v, law, c, iterations)
        if v is None:
            raise ValueError("the momentum has no subluminal velocity, or the Hessian of ℓ is singular there "
                             "(Newton's method for v(p, x′) did not converge)")
    return v
