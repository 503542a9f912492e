"""Fixed ends of the Nambu–Goto string (docs/media/relativistic-rod.md §3, "Fixed ends").

An end of the string held at a point of space, x⃗(σ_end, t) = x⃗_end, in the conformal–temporal
gauge of the medium: the end node's velocity is N = {(U₀, 0⃗); 0} with U₀ = ∂_t r⁰ free (the
time component obeys the wave equation with the natural, Neumann, condition ∂_σ r⁰ = 0 there,
which the Virasoro constraint ⟨ṙ, r′⟩ = 0 demands at a point with ẋ⃗ = 0).  The core's
:class:`cartan.Held` support with the components :data:`FIXED_END` holds exactly that; a
:class:`cartan.Clamped` end would hold r⁰ too (N = 0), which is not a solution.

Closed forms:

* :func:`fixed_standing_wave` — the exact finite-amplitude standing wave of a string stretched
  between two fixed points, released from rest (the periodic standing wave of
  :func:`cartan_relativistic.limit.standing_wave` with period 2L in σ, restricted to [0, L]:
  its nodes σ = 0 and σ = L stay fixed);
* :func:`plucked` — a string plucked into a triangle between two fixed points, at rest.
"""

from __future__ import annotations

import math

import numpy as np

import cartan

from .limit import lab_period, standing_wave

__all__ = ["FIXED_END", "fixed_end", "fixed_standing_wave", "plucked", "span"]

#: the components of N = (U₀, U⃗, a⃗, Ω⃗) a fixed end of the Nambu–Goto string holds at zero: the
#: spatial velocity U⃗ and the Lorentz part (the frame, gauge); U₀ = ∂_t r⁰ stays free
FIXED_END: tuple[int, ...] = tuple(range(1, 10))


def fixed_end() -> cartan.Held:
    """The support of an end of the Nambu–Goto string fixed in space: ``cartan.Held(components=FIXED_END)``."""
    return cartan.Held(components=FIXED_END)


def span(theta0: float, length: float) -> float:
    """Lab distance between the fixed ends of :func:`fixed_standing_wave`, ``L J₀(θ₀)``."""
    return 0.5 * lab_period(theta0, 2.0 * float(length))


def fixed_standing_wave(sigma: np.ndarray, t: float, theta0: float, length: float,
                        c: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact standing wave of a Nambu–Goto string with fixed ends, conformal–temporal gauge.

    ``x⃗(σ, t) = ½[a(σ − ct) + a(σ + ct)]``, ``a′(s) = (cos θ(s), sin θ(s), 0)``,
    ``θ(s) = θ₀ cos(πs/L)``: a′ is even and 2L-periodic, so a is odd with
    ``a(s + 2L) = a(s) + 2L J₀(θ₀) e₁``, and the ends stay at x⃗(0, t) = 0 and
    x⃗(L, t) = L J₀(θ₀) e₁ for all t (the reflection conditions).  Released from rest in the
    shape a(σ) (|∂_σx⃗| = 1: u is the arc length at t = 0); period 2L/c; the largest speed
    c sin θ₀ is reached by the midpoint when the string is straight (t = L/(2c)).

    Parameters
    ----------
    sigma : array, shape ``(n,)``
        Conformal coordinate σ ∈ [0, L] (the grid's u; energy μc² per unit σ).
    t : float
        Lab time.
    theta0 : float
        Tangent angle at the ends at t = 0, in (0, 1] (radians).
    length : float
        L > 0, the string's extent in σ (its energy is μc²L).
    c : float
        Speed of light.

    Returns
    -------
    (x, v) : arrays of shape ``(n, 3)``
        Lab positions and velocities ∂_t x⃗.
    """
    length = float(length)
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"length must be a finite number > 0, got {length!r}")
    return standing_wave(sigma, t, theta0, 2.0 * length, c)


def plucked(sigma: np.ndarray, length: float, height: float, at: float = 0.5) -> np.ndarray:
    """A string plucked into a triangle, at rest: lab positions ``(n, 3)`` in the x–y plane.

    Straight from (0, 0, 0) to the apex (a, H, 0) over σ ∈ [0, pL] and from there to the other
    fixed end (b, 0, 0) over [pL, L], each piece at unit speed (|∂_σx⃗| = 1: with ẋ⃗ = 0 the
    Virasoro constraints hold on each piece), a = √((pL)² − H²), b = a + √(((1 − p)L)² − H²).
    Its exact motion is d'Alembert's in σ: two kinks running at c and reflecting at the ends
    (the kink of the apex splits; the string is piecewise straight at every time).

    Parameters
    ----------
    sigma : array, shape ``(n,)``
        σ ∈ [0, L].
    length : float
        L > 0.
    height : float
        Apex height H, 0 < H < min(p, 1 − p) L.
    at : float
        p ∈ (0, 1): where along σ the string is plucked.

    Returns
    -------
    array, shape ``(n, 3)``
    """
    length, height, at = float(length), float(height), float(at)
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"length must be a finite number > 0, got {length!r}")
    if not (math.isfinite(at) and 0.0 < at < 1.0):
        raise ValueError(f"at must be in (0, 1) (where along the string it is plucked), got {at!r}")
    limit = min(at, 1.0 - at) * length
    if not (math.isfinite(height) and 0.0 < height < limit):
        raise ValueError(f"height must be in (0, {limit:g}) (the apex below the shorter side's length), "
                         f"got {height!r}")
    s = np.asarray(sigma, dtype=float)
    p = at * length
    c1, s1 = math.sqrt(p * p - height * height) / p, height / p
    c2, s2 = math.sqrt((length - p) ** 2 - height * height) / (length - p), height / (length - p)
    x = np.where(s <= p, c1 * s, c1 * p + c2 * (s - p))
    y = np.where(s <= p, s1 * s, height - s2 * (s - p))
    return np.stack([x, y, np.zeros_like(s)], axis=-1)
