"""The slow-motion (Newtonian) limit of the Nambu–Goto string (docs/media/relativistic-rod.md §2).

A Nambu–Goto string whose points move at speeds v ≪ c is, to leading order, the linear taut
string of tension T = μc² and mass μ per unit lab length: small transverse waves
``∂²_t y = c² ∂²_x y`` in the static gauge (x the lab coordinate along the string).  The
first correction is the quartic term of the Nambu–Goto Lagrangian, smaller by (v/c)².

This module holds the closed forms the verification case
(:class:`cartan_relativistic.cases.NewtonianLimit`) compares:

* the exact Nambu–Goto standing wave in conformal–temporal gauge, an infinite string along e₁
  periodic in σ with period L, released from rest:

  ``x(σ, t) = ½[a(σ − ct) + a(σ + ct)]``,  ``a′(s) = (cos θ(s), sin θ(s), 0)``,
  ``θ(s) = θ₀ cos(ks)``,  k = 2π/L,

  integrated term by term with the Jacobi–Anger expansion (Bessel functions J_m(θ₀)); a
  advances by ``X_L = L J₀(θ₀)`` along e₁ per period (the lab period of the string), and the
  largest speed of the motion is ``c sin θ₀``;
* the linear taut string with the same lab shape at rest, d'Alembert's solution
  ``y(x, t) = ½[y₀(x − ct) + y₀(x + ct)]``, y₀ the initial shape as a function of lab x
  (lab period X_L).

Its chart, ``python -m cartan_relativistic.limit OUT.png``, runs the case's levels through the
core and draws the difference against v/c with its fitted slope.
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np
from scipy.special import jv

__all__ = ["TERMS", "amplitude", "chart_main", "lab_period", "main", "newtonian_string", "standing_wave", "tilt_curve",
           "tilt_for_speed"]

#: Bessel terms kept in the Jacobi–Anger sums (J_m(θ₀) < 1e-30 beyond them for θ₀ ≤ 1)
TERMS = 24


def _check_tilt(theta0: float) -> float:
    theta0 = float(theta0)
    if not 0.0 < theta0 <= 1.0:
        raise ValueError(f"theta0 must be in (0, 1] (the largest tangent angle, radians), got {theta0!r}")
    return theta0


def _check_length(length: float) -> float:
    length = float(length)
    if not (math.isfinite(length) and length > 0.0):
        raise ValueError(f"length must be a finite number > 0, got {length!r}")
    return length


def tilt_for_speed(beta: float) -> float:
    """The amplitude θ₀ = asin β of the standing wave whose largest speed is βc, β ∈ (0, sin 1]."""
    beta = float(beta)
    if not 0.0 < beta <= math.sin(1.0):
        raise ValueError(f"beta must be in (0, sin 1] (largest speed in units of c), got {beta!r}")
    return math.asin(beta)


def lab_period(theta0: float, length: float) -> float:
    """Lab length of one period of the string, ``X_L = L J₀(θ₀)`` (L the period in σ)."""
    return _check_length(length) * float(jv(0, _check_tilt(theta0)))


def tilt_curve(s: np.ndarray, theta0: float, length: float) -> tuple[np.ndarray, np.ndarray]:
    """The unit-speed curve ``a(s)`` with tangent angle θ₀ cos(ks), a(0) = 0, and its tangent.

    Jacobi–Anger: ``cos(θ₀ cos φ) = J₀ + 2Σ_{m≥1} (−1)^m J_{2m} cos 2mφ`` and
    ``sin(θ₀ cos φ) = 2Σ_{m≥0} (−1)^m J_{2m+1} cos(2m+1)φ``, integrated term by term.

    Parameters
    ----------
    s : array, shape ``(n,)``
        Arc length (the conformal coordinate σ).
    theta0 : float
        Largest tangent angle, in (0, 1].
    length : float
        Period L in s.

    Returns
    -------
    (a, da) : arrays of shape ``(n, 3)``
        Positions and unit tangents.
    """
    theta0, length = _check_tilt(theta0), _check_length(length)
    s = np.asarray(s, dtype=float)
    k = 2.0 * math.pi / length
    ax = jv(0, theta0) * s
    ay = np.zeros_like(s)
    for m in range(1, TERMS):
        ax = ax + 2.0 * (-1) ** m * jv(2 * m, theta0) * np.sin(2 * m * k * s) / (2 * m * k)
    for m in range(TERMS):
        ay = ay + 2.0 * (-1) ** m * jv(2 * m + 1, theta0) * np.sin((2 * m + 1) * k * s) / ((2 * m + 1) * k)
    theta = theta0 * np.cos(k * s)
    a = np.stack([ax, ay, np.zeros_like(s)], axis=-1)
    da = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(s)], axis=-1)
    return a, da


def standing_wave(sigma: np.ndarray, t: float, theta0: float, length: float,
                  c: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact Nambu–Goto standing wave released from rest, conformal–temporal gauge.

    ``x(σ, t) = ½[a(σ − ct) + a(σ + ct)]``, ``∂_t x = ½c[−a′(σ − ct) + a′(σ + ct)]``
    (|a′| = 1: the Virasoro constraints hold, |∂_σx|² + |∂_t x|²/c² = 1).

    Parameters
    ----------
    sigma : array, shape ``(n,)``
        Conformal coordinate σ (energy per unit σ: μc²).
    t : float
        Lab time.
    theta0, length : float
        As in :func:`tilt_curve`.
    c : float
        Speed of light.

    Returns
    -------
    (x, v) : arrays of shape ``(n, 3)``
        Lab positions and velocities.
    """
    sigma = np.asarray(sigma, dtype=float)
    a1, d1 = tilt_curve(sigma - c * t, theta0, length)
    a2, d2 = tilt_curve(sigma + c * t, theta0, length)
    return 0.5 * (a1 + a2), 0.5 * c * (d2 - d1)


def amplitude(theta0: float, length: float) -> float:
    """Transverse amplitude A = max |a_y| of the initial shape (at ks = π/2, a_y odd in s)."""
    a, _ = tilt_curve(np.array([length / 4.0]), theta0, length)
    return float(abs(a[0, 1]))


def _shape(x: np.ndarray, theta0: float, length: float) -> np.ndarray:
    """The initial shape as a function of lab x: y₀(x) = a_y(s(x)), s(x) solving a_x(s) = x by Newton."""
    s = x / jv(0, theta0)
    k = 2.0 * math.pi / length
    for _ in range(60):
        a, _ = tilt_curve(s, theta0, length)
        step = (a[..., 0] - x) / np.cos(theta0 * np.cos(k * s))  # da_x/ds = cos θ > 0: a_x is monotone
        s = s - step
        if np.max(np.abs(step)) <= 1e-15 * max(1.0, float(np.max(np.abs(x)))):
            break
    return tilt_curve(s, theta0, length)[0][..., 1]


def newtonian_string(x: np.ndarray, t: float, theta0: float, length: float, c: float = 1.0) -> np.ndarray:
    """The linear taut string (tension μc², mass μ per lab length: waves at c) released from
    rest with the lab shape of the Nambu–Goto string: ``y(x, t) = ½[y₀(x − ct) + y₀(x + ct)]``.

    Parameters
    ----------
    x : array, shape ``(n,)``
        Lab abscissae.
    t : float
        Lab time.
    theta0, length : float
        The Nambu–Goto string's data (:func:`tilt_curve`); y₀ has the lab period L J₀(θ₀).
    c : float
        Speed of light (the wave speed of the taut string, √(T/μ)).

    Returns
    -------
    array, shape ``(n,)``
        Transverse displacement y.
    """
    x = np.asarray(x, dtype=float)
    return 0.5 * (_shape(x - c * t, theta0, length) + _shape(x + c * t, theta0, length))


def chart_main(module: str, case: Any, report, argv: list[str] | None = None) -> int:
    """A limit chart's command line, ``python -m MODULE OUT.png``: measures ``case``'s levels,
    draws them (``case.draw(rows, fig)``) into OUT.png and prints ``report(rows, drawn)`` (the
    lines to print; ``drawn`` is what ``draw`` returned).  Returns the exit status."""
    from matplotlib.figure import Figure

    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print(f"usage: python -m {module} OUT.png", file=sys.stderr)
        return 2
    rows = case.measure(case.levels)
    fig = Figure(figsize=(10.5, 4.4), layout="constrained")
    drawn = case.draw(rows, fig)
    fig.savefig(argv[0], dpi=110)
    for line in report(rows, drawn):
        print(line)
    return 0


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m cartan_relativistic.limit OUT.png`` (the c → ∞ chart)."""
    from .cases import NewtonianLimit

    def report(rows, _):
        return [f"v/c = {r['beta']:.4f}: difference at t = L/3 {r['error']:.3e}, at t = L/4 {r['quarter']:.3e} "
                f"(π/8 (v/c)² = {math.pi / 8 * r['beta'] ** 2:.3e}), Nambu–Goto run vs exact {r['exact']:.1e}"
                for r in rows]

    return chart_main("cartan_relativistic.limit", NewtonianLimit(), report, argv)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
