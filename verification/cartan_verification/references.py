"""Exact references of the rod cases, shared by the verification cases and the tests.

Static rods (VERIFICATION.md §4, cosserat-rod rows)
---------------------------------------------------
:func:`timoshenko_linear_tip`
    Linear Timoshenko cantilever under a tip force: w(L) = FL/(α_cGA) + FL³/(3EI).
:func:`cantilever_exact_tip`
    The geometrically exact (Simo–Reissner) cantilever with stretch, shear and bending under
    a dead tip force, by shooting on the planar boundary-value problem (adaptive Runge–Kutta
    to 1e-13, the root by Brent's method): the number the discretisations converge to.
:func:`cantilever_elastica`
    Inextensible, unshearable cantilever under a dead tip force perpendicular to the rod,
    Bisshopp & Drucker, Q. Appl. Math. 3 (1945) 272, in incomplete elliptic integrals.
:func:`euler_critical_load`, :func:`pinned_elastica`
    Euler's load π²B/L² and the post-buckled pinned–pinned elastica (Love, *A Treatise on
    the Mathematical Theory of Elasticity*, §263; Timoshenko & Gere, *Theory of Elastic
    Stability*, §2.7): P/P_cr = (2K(k)/π)², midspan deflection w/L = k/K(k), end shortening
    Δ/L = 2(1 − E(k)/K(k)), k = sin(θ₀/2) with θ₀ the end slope.

Dynamic rods
------------
:func:`rod_dispersion`
    Linear waves about any uniform stress-free rod state (straight or a ring): the frequencies
    and mode shapes of the linearised Cosserat rod at wave number k.  For a straight rod it
    is the Timoshenko beam (flexural and shear branches), the axial bar and the torsional
    rod; for a ring the coupled in-plane and out-of-plane ring modes.

Conventions are those of ``cosserat-rod``: e₁ along the rest tangent, SE(3) components
translation first.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "ELASTICA_TABLE",
    "cantilever_elastica",
    "cantilever_exact_tip",
    "euler_critical_load",
    "pinned_elastica",
    "rod_dispersion",
    "timoshenko_linear_tip",
]

#: Tabulated cantilever elastica (VERIFICATION.md §4): PL²/B → (tip vertical/L, shortening/L),
#: five digits; :func:`cantilever_elastica` computes them to round-off.
ELASTICA_TABLE: dict[float, tuple[float, float]] = {
    1.0: (0.30172, 0.05643),
    2.0: (0.49346, 0.16064),
    10.0: (0.81061, 0.55500),
}


def _positive(name: str, value: float, infinite: bool = False) -> float:
    value = float(value)
    if not ((math.isfinite(value) or (infinite and value == math.inf)) and value > 0):
        raise ValueError(f"{name} must be a {'' if infinite else 'finite '}number > 0, got {value!r}")
    return value


# ---------------------------------------------------------------------------- Timoshenko cantilever
def timoshenko_linear_tip(length: float, force: float, EI: float, shear_stiffness: float) -> float:
    """Tip deflection of the linear Timoshenko cantilever under a tip force.

    Parameters
    ----------
    length, force, EI : float
        Length L, tip force F and bending stiffness EI (all > 0).
    shear_stiffness : float
        α_c G A (> 0).

    Returns
    -------
    float
        w(L) = FL/(α_cGA) + FL³/(3EI).
    """
    L, F = _positive("length", length), _positive("force", force)
    return F * L / _positive("shear_stiffness", shear_stiffness) + F * L**3 / (3.0 * _positive("EI", EI))


def cantilever_exact_tip(length: float, force: float, EI: float, EA: float = math.inf,
                         shear_stiffness: float = math.inf, rtol: float = 1e-13) -> tuple[float, float]:
    """Tip displacement of the geometrically exact cantilever under a dead tip force.

    The rod lies along x, clamped at s = 0; the force F acts at s = L along −z.  With φ the
    rotation of the cross-section about y, the spatial internal force is the constant
    n = (0, 0, −F); its body components (sin φ F, 0, −cos φ F) give the strains
    θ₁ = 1 + sin φ F/EA, θ₃ = −cos φ F/(α_cGA), and

        x′ = cos φ θ₁ + sin φ θ₃,   z′ = −sin φ θ₁ + cos φ θ₃,   φ′ = m/EI,   m′ = −F x′,

    with x = z = φ = 0 at s = 0 and m(L) = 0 (the Simo–Reissner rod in the plane).  The root
    m(0) is found by Brent's method around the linear value FL, each shot integrated by
    DOP853 to ``rtol``.

    Parameters
    ----------
    length, force, EI : float
        L, F, EI (> 0).
    EA, shear_stiffness : float
        Stretch stiffness EA and shear stiffness α_cGA (> 0; ``inf``: inextensible, unshearable).
    rtol : float
        Relative tolerance of the integration (the result is accurate to about 10·rtol).

    Returns
    -------
    (float, float)
        (tip deflection −z(L), shortening L − x(L)).
    """
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    L, F, B = _positive("length", length), _positive("force", force), _positive("EI", EI)
    ea, ga = _positive("EA", EA, infinite=True), _positive("shear_stiffness", shear_stiffness, infinite=True)

    def rhs(_s, y):
        _, _, phi, m = y
        c, s = math.cos(phi), math.sin(phi)
        t1, t3 = 1.0 + s * F / ea, -c * F / ga
        dx = c * t1 + s * t3
        return [dx, -s * t1 + c * t3, m / B, -F * dx]

    def shoot(m0):
        sol = solve_ivp(rhs, (0.0, L), [0.0, 0.0, 0.0, m0], method="DOP853", rtol=rtol, atol=rtol * 1e-3)
        return sol.y[:, -1]

    m_lin = F * L
    m0 = brentq(lambda m: shoot(m)[3], 0.0, 1.5 * m_lin, xtol=1e-15 * m_lin, rtol=1e-15)
    x, z, _, _ = shoot(m0)
    return float(-z), float(L - x)


# ---------------------------------------------------------------------------- elastica
def cantilever_elastica(alpha: float) -> tuple[float, float]:
    """Inextensible cantilever elastica under a dead tip force perpendicular to the rod.

    With α = PL²/B and θ the tangent angle (θ(0) = 0, tip angle θ₀), Bθ″ = −P cos θ gives,
    in the modulus k = sin(π/4 + θ₀/2) and sin φ₁ = 1/(k√2),

        √α = K(k) − F(φ₁, k),
        tip vertical / L = [K − F(φ₁) − 2(E(k) − E(φ₁, k))] / √α,
        tip horizontal / L = 2k cos φ₁ / √α

    (Bisshopp & Drucker 1945); k is found by Brent's method.

    Parameters
    ----------
    alpha : float
        Load parameter PL²/B (> 0).

    Returns
    -------
    (float, float)
        (tip vertical deflection / L, shortening / L).
    """
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

    a = _positive("alpha", alpha)
    root = math.sqrt(a)

    def parts(k):
        m = k * k
        phi1 = math.asin(min(1.0, 1.0 / (k * math.sqrt(2.0))))
        return m, phi1, float(ellipk(m) - ellipkinc(phi1, m))

    k = brentq(lambda k: parts(k)[2] - root, 1.0 / math.sqrt(2.0) + 1e-15, 1.0 - 1e-15, xtol=1e-16, rtol=1e-15)
    m, phi1, length = parts(k)
    vertical = (length - 2.0 * float(ellipe(m) - ellipeinc(phi1, m))) / root
    horizontal = 2.0 * k * math.cos(phi1) / root
    return float(vertical), float(1.0 - horizontal)


def euler_critical_load(B: float, length: float) -> float:
    """Euler's buckling load of the pinned–pinned column, π²B/L²."""
    return math.pi**2 * _positive("B", B) / _positive("length", length) ** 2


def pinned_elastica(load_ratio: float) -> tuple[float, float]:
    """The post-buckled pinned–pinned elastica at P/P_cr = ``load_ratio`` (> 1).

    K(k) = (π/2)√(P/P_cr) fixes the modulus k = sin(θ₀/2) (θ₀ the end slope); then the
    midspan deflection is w/L = k/K(k) and the end shortening Δ/L = 2(1 − E(k)/K(k)).

    Returns
    -------
    (float, float)
        (midspan deflection / L, end shortening / L).
    """
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipk

    ratio = float(load_ratio)
    if not (math.isfinite(ratio) and ratio > 1.0):
        raise ValueError(f"load_ratio must be a finite number > 1 (above the critical load), got {load_ratio!r}")
    target = 0.5 * math.pi * math.sqrt(ratio)
    m = brentq(lambda m: float(ellipk(m)) - target, 0.0, 1.0 - 1e-16, xtol=1e-16, rtol=1e-15)
    K, E = float(ellipk(m)), float(ellipe(m))
    return math.sqrt(m) / K, 2.0 * (1.0 - E / K)


# ---------------------------------------------------------------------------- linear waves
def rod_dispersion(k: float, rest_strain, stiffness, inertia) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies and mode shapes of the linearised Cosserat rod about a uniform rest state.

    About a stress-free state Φ₀(s) = exp(s X₀) (X₀ ∈ se(3) constant: a straight rod, a ring
    or a helix) with N = 0, a perturbation Φ = Φ₀ exp(η) has the strain X₀ + η′ + ad_{X₀}η
    to first order, and the balance law 𝕄η̈ = ∂_sQ − ad_{X₀}ᵀQ with Q = ℂ(η′ + ad_{X₀}η).  For
    η = Re(η̂ e^{iks}) this is the Hermitian eigenproblem

        ω² 𝕄 η̂ = (ik + A)ᴴ ℂ (ik + A) η̂,    A = ad_{X₀},

    solved exactly (to round-off).  For a straight rod (X₀ = e₁) the branches are the
    Timoshenko beam's flexural and shear branches in each plane, the axial bar ω = √(EA/ρA)k
    and the torsional wave.

    Parameters
    ----------
    k : float
        Wave number (rad per unit reference length).
    rest_strain : array_like, shape ``(6,)``
        X₀ = (θ; π), e.g. ``(1, 0, 0, 0, 0, κ)`` for a ring of curvature κ in the e₁–e₂ plane.
    stiffness, inertia : array_like, shape ``(6,)``
        Diagonals of ℂ = diag(𝕊, 𝔹) and 𝕄 = diag(ρA, ρA, ρA, 𝕀).

    Returns
    -------
    omega : ndarray, shape ``(6,)``
        The frequencies ω ≥ 0, ascending.
    modes : ndarray, shape ``(6, 6)``, complex
        ``modes[:, j]`` the mode η̂ of ``omega[j]``, 𝕄-normalised.
    """
    from scipy.linalg import eigh

    from cartan.groups import SE3

    X0 = np.asarray(rest_strain, dtype=float)
    C = np.asarray(stiffness, dtype=float)
    M = np.asarray(inertia, dtype=float)
    for name, v in (("rest_strain", X0), ("stiffness", C), ("inertia", M)):
        if v.shape != (6,) or not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be 6 finite numbers, got shape {v.shape}")
    if np.any(C <= 0) or np.any(M <= 0):
        raise ValueError("stiffness and inertia must be > 0 (every diagonal entry)")
    A = SE3().ad(X0)
    B = 1j * float(k) * np.eye(6) + A
    K = B.conj().T @ (C[:, None] * B)
    K = 0.5 * (K + K.conj().T)
    w2, modes = eigh(K, np.diag(M))
    return np.sqrt(np.clip(w2, 0.0, None)), modes
