"""Axisymmetric vesicles: the shape equations of the Helfrich energy solved in 1D (reference).

The stationary shapes of a closed vesicle of sphere topology with held area A and volume V and
the energy E = κ_b/2 ∮(2H − c₀)² dA (κ_G contributes 2πχκ_G = 4πκ_G, a constant), c₀ = 0 here,
are critical points of F = E + σA − pV (σ the tension, p the pressure inside minus outside: the
multipliers of :func:`cartan_kirchhoff_love.vesicle.helfrich_flow`, whose σ is the medium's tension
and whose volume load has the potential −pV).  Among the axisymmetric ones (Seifert, Berndl &
Lipowsky, Phys. Rev. A 44, 1182 (1991); Jülicher & Seifert, Phys. Rev. E 49, 4728 (1994)) the
meridian is parametrised by its arc length s ∈ [0, L] from the upper pole: the tangent angle ψ(s),

    r' = cos ψ,   z' = −sin ψ,   κ₁ = ψ',   κ₂ = sin ψ / r,   2H = u = ψ' + sin ψ / r,

and F/2π = ∫₀ᴸ [κ_b r u²/2 + σ r − p r² sin ψ/2 + γ(r' − cos ψ)] ds, γ(s) the multiplier of
r' = cos ψ.  Its Euler–Lagrange equations (κ_b = 1) are

    ψ' = u − sin ψ / r,
    u' = −(p/2) r cos ψ + γ sin ψ / r,
    r' = cos ψ,
    γ' = u²/2 − u sin ψ / r + σ − p r sin ψ,

with the Hamiltonian r u ψ' + γ cos ψ − ℒ = 0 (the length L is free), which the regular pole
(r = 0, ψ = 0, γ = 0) sets.  At a pole sin ψ / r → ψ' = u/2, so ψ' = u/2, u' = 0, γ' = σ there.
The solver integrates them on t = s/L ∈ [0, 1] by collocation (:func:`scipy.integrate.solve_bvp`,
unknown parameters L, σ, p) together with the integrals a = ∫r ds (A = 2πa), w = ∫ r² sin ψ/2 ds
(V = 2πw), e = ∫ r u²/2 ds (E = 2πκ_b e), z, and the second moments of the surface ∫ r z ds,
∫ r z² ds, ∫ r³ ds; boundary conditions ψ = r = γ = a = w = e = z = moments = 0 at t = 0 and
ψ = π, r = 0, a = A/2π, w = V/2π at t = 1.  Units: R₀ = √(A/4π) = 1, so V = 4πv/3.

Outputs (:func:`solve_vesicle`): E/(8πκ_b), σ and p in units of κ_b/R₀² and κ_b/R₀³, the pole-to-
pole length over the equatorial diameter, and the ratio of the principal semi-axes of the
surface's second-moment tensor, √(λ_z/λ_x), λ_z = ∮(z − z̄)² dA, λ_x = ∮ x² dA = π∫ r³ ds — the
measure :func:`cartan_kirchhoff_love.vesicle_sphere.vesicle_shape` takes of a lattice.

Checks: the sphere (v → 1) has E/8πκ_b = 1; near it the ℓ = 2 deformation gives
E/8πκ_b − 1 = 2(1 − v) + O((1 − v)²) for both branches (the quadratic energy (κ_b/2)·24|u₂|² of a
Y₂ mode of amplitude u₂ against its volume deficit 1 − v = 3|u₂|²/4π; Seifert, Adv. Phys. 46, 13
(1997), §4), and at a stationary shape the multipliers satisfy the scaling identity of F:
under r → λr, E is invariant and A, V scale as λ², λ³, so 2σA − 3pV = 0 (the Helmholtz
virial, here 2σ·4π = 3p·4πv/3, i.e. p = 2σ/v) — a check independent of the solve.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AxisymmetricVesicle", "solve_vesicle", "spheroid_guess"]

#: ψ, u, r, γ, a, w, e, z, m_z, m_zz, m_rrr
_NY = 11


@dataclass
class AxisymmetricVesicle:
    """A stationary axisymmetric vesicle (R₀ = 1, κ_b = 1).

    Attributes
    ----------
    reduced_volume : float
        v = 3V/(4πR₀³).
    energy : float
        E/(8πκ_b).
    tension, pressure : float
        σ (κ_b/R₀²) and p (κ_b/R₀³), the multipliers of A and V in E + σA − pV.
    length : float
        Meridian length L (pole to pole, along the contour).
    extent_ratio : float
        Pole-to-pole distance over the equatorial diameter 2 max r.
    axis_ratio : float
        √(λ_z/λ_x) of the surface's second-moment tensor (> 1 prolate, < 1 oblate).
    s : ndarray ``(m,)``
        Arc length of the collocation mesh.
    psi, r, z : ndarray ``(m,)``
        The meridian on that mesh.
    residual : float
        The collocation's largest relative residual.
    sol : object
        The :func:`scipy.integrate.solve_bvp` result (``sol.sol(t)``, t = s/L, the dense output).
    """

    reduced_volume: float
    energy: float
    tension: float
    pressure: float
    length: float
    extent_ratio: float
    axis_ratio: float
    s: np.ndarray
    psi: np.ndarray
    r: np.ndarray
    z: np.ndarray
    residual: float
    sol: object

    def meridian(self, m: int = 400) -> tuple[np.ndarray, np.ndarray]:
        """(r, z) at m points equally spaced in arc length, z measured from the centroid z̄."""
        y = self.sol.sol(np.linspace(0.0, 1.0, int(m)))
        zbar = self.sol.y[8, -1] / self.sol.y[4, -1]
        return y[2], y[7] - zbar


def _rhs(t: np.ndarray, y: np.ndarray, par: np.ndarray) -> np.ndarray:
    L, sig, p = par
    psi, u, r, gam = y[0], y[1], y[2], y[3]
    sn, cs = np.sin(psi), np.cos(psi)
    pole = np.abs(r) < 1e-14
    rr = np.where(pole, 1.0, r)
    k2 = np.where(pole, 0.5 * u, sn / rr)       # sin ψ / r → ψ' = u/2 at a pole
    g = np.where(pole, 0.0, gam * sn / rr)      # γ sin ψ / r → 0 (γ = 0 at a regular pole)
    d = np.empty_like(y)
    d[0] = u - k2
    d[1] = -0.5 * p * r * cs + g
    d[2] = cs
    d[3] = 0.5 * u * u - u * k2 + sig - p * r * sn
    d[4] = r
    d[5] = 0.5 * r * r * sn
    d[6] = 0.5 * r * u * u
    d[7] = -sn
    d[8] = r * y[7]
    d[9] = r * y[7] ** 2
    d[10] = r ** 3
    return L * d


def spheroid_guess(reduced_volume: float, shape: str = "prolate", m: int = 201
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A starting guess (t ``(m,)``, y ``(11, m)``, (L, σ, p)) from the spheroid of reduced volume v
    (R₀ = 1), its meridian resampled at equal arc length; γ = 0 and σ = p = 0."""
    from scipy.integrate import cumulative_trapezoid

    from .vesicle_sphere import spheroid_aspect, spheroid_measures

    q = spheroid_aspect(reduced_volume, shape)
    A, _ = spheroid_measures(1.0, q)
    a = 1.0 / math.sqrt(A / (4.0 * math.pi))
    c = q * a
    th = np.linspace(0.0, math.pi, 20001)
    ds = np.hypot(a * np.cos(th), c * np.sin(th))
    s = cumulative_trapezoid(ds, th, initial=0.0)
    L = float(s[-1])
    t = np.linspace(0.0, 1.0, int(m))
    thm = np.interp(t * L, s, th)
    r, z = a * np.sin(thm), c * np.cos(thm)
    psi = np.arctan2(c * np.sin(thm), a * np.cos(thm))            # tangent (a cos θ, −c sin θ)
    dpsi = np.gradient(psi, t * L)
    with np.errstate(invalid="ignore", divide="ignore"):
        k2 = np.where(r > 1e-12, np.sin(psi) / np.where(r > 1e-12, r, 1.0), dpsi)
    y = np.zeros((_NY, t.size))
    y[0], y[1], y[2], y[7] = psi, dpsi + k2, r, z - z[0]
    y[4] = cumulative_trapezoid(r, t * L, initial=0.0)
    y[5] = cumulative_trapezoid(0.5 * r * r * np.sin(psi), t * L, initial=0.0)
    y[6] = cumulative_trapezoid(0.5 * r * y[1] ** 2, t * L, initial=0.0)
    y[8] = cumulative_trapezoid(r * y[7], t * L, initial=0.0)
    y[9] = cumulative_trapezoid(r * y[7] ** 2, t * L, initial=0.0)
    y[10] = cumulative_trapezoid(r ** 3, t * L, initial=0.0)
    return t, y, np.array([L, 0.0, 0.0])


def solve_vesicle(reduced_volume: float = 0.9, shape: str = "prolate", *, tol: float = 1e-10,
                  nodes: int = 201, max_nodes: int = 200000, guess: AxisymmetricVesicle | None = None
                  ) -> AxisymmetricVesicle:
    """The stationary axisymmetric vesicle of reduced volume v on the prolate or oblate branch
    (module docstring), by collocation of the shape equations from the spheroid of the same v
    (or from ``guess``, a neighbouring solution: continuation in v).

    Parameters
    ----------
    reduced_volume : float
        v ∈ (0, 1) (near 1 the ℓ = 2 shapes; the prolate branch is reached from the spheroid for
        v ≳ 0.65, the oblate for v ≳ 0.65 as well).
    shape : {"prolate", "oblate"}
        The branch's starting spheroid.
    tol : float
        :func:`scipy.integrate.solve_bvp` tolerance (relative collocation residual), > 0.
    nodes, max_nodes : int
        Initial and largest number of mesh nodes.
    guess : AxisymmetricVesicle, optional
        Start from this solution instead of the spheroid.

    Returns
    -------
    AxisymmetricVesicle

    Raises
    ------
    RuntimeError
        When the collocation does not converge.
    """
    from scipy.integrate import solve_bvp

    v = float(reduced_volume)
    if not 0.0 < v < 1.0:
        raise ValueError(f"reduced_volume must be in (0, 1), got {reduced_volume!r}")
    if shape not in ("prolate", "oblate"):
        raise ValueError(f"shape must be 'prolate' or 'oblate', got {shape!r}")
    if not (np.isfinite(tol) and tol > 0.0):
        raise ValueError(f"tol must be > 0, got {tol!r}")
    a_goal, w_goal = 2.0, 2.0 * v / 3.0          # A/2π = 2, V/2π = (4πv/3)/2π

    def bc(ya: np.ndarray, yb: np.ndarray, par: np.ndarray) -> np.ndarray:
        return np.array([ya[0], ya[2], ya[3], ya[4], ya[5], ya[6], ya[7], ya[8], ya[9], ya[10],
                         yb[0] - math.pi, yb[2], yb[4] - a_goal, yb[5] - w_goal])

    if guess is None:
        t, y, par = spheroid_guess(v, shape, nodes)
    else:
        t, y, par = guess.sol.x, guess.sol.y, np.asarray(guess.sol.p, dtype=float)
    sol = solve_bvp(_rhs, bc, t, y, p=par, tol=tol, max_nodes=int(max_nodes), bc_tol=1e-12)
    if not sol.success:
        raise RuntimeError(f"solve_vesicle: the shape equations did not converge at v = {v} ({shape}): {sol.message}")
    L, sig, p = (float(x) for x in sol.p)
    y = sol.y
    zbar = y[8, -1] / y[4, -1]
    lam_z = 2.0 * math.pi * (y[9, -1] - zbar * y[8, -1])      # ∮(z − z̄)² dA (the integrals are in s)
    lam_x = math.pi * y[10, -1]                               # ∮ x² dA
    zl = y[7]
    # the widest parallel: the largest r on the mesh, refined where r' = cos ψ changes sign
    k = int(np.argmax(y[2]))
    rmax = float(y[2, k])
    lo, hi = sol.x[max(k - 1, 0)], sol.x[min(k + 1, sol.x.size - 1)]
    if np.cos(sol.sol(lo)[0]) * np.cos(sol.sol(hi)[0]) < 0.0:
        from scipy.optimize import brentq

        rmax = float(sol.sol(brentq(lambda t: np.cos(sol.sol(t)[0]), lo, hi, xtol=1e-15))[2])
    return AxisymmetricVesicle(reduced_volume=v, energy=float(2.0 * math.pi * y[6, -1] / (8.0 * math.pi)),
                               tension=sig, pressure=p, length=L,
                               extent_ratio=float((zl.max() - zl.min()) / (2.0 * rmax)),
                               axis_ratio=float(math.sqrt(lam_z / lam_x)), s=L * sol.x, psi=y[0], r=y[2],
                               z=zl, residual=float(np.max(sol.rms_residuals)), sol=sol)
