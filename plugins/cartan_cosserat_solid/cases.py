"""Verification cases of the micropolar solid (paper §VI.A), registered by this plugin.

They run on a periodic box (the ``lattice`` scheme with a translation holonomy per periodic
axis, ``InitialState.holonomy``), so that a plane wave or a uniform state is an exact solution
of the unbounded solid.

Exact references (linear micropolar elastodynamics, Eringen, *Microcontinuum Field Theories I*,
§5.11).  For fields depending on x₁ only, the longitudinal displacement u₁ and the longitudinal
micro-rotation φ₁ decouple from the transverse ones and from each other:

* u₁: t₁₁ = (λ + 2μ + κ)u₁,₁ and ρü₁ = t₁₁,₁, so ρω² = (λ + 2μ + κ)k², without dispersion;
* φ₁: ε₂₃ = −φ₁, ε₃₂ = φ₁ give t₂₃ − t₃₂ = −2κφ₁, m₁₁ = (α + β + γ)φ₁,₁, and
  ρjφ̈₁ = m₁₁,₁ + e₁ₖₗt_kl, so ρjω² = (α + β + γ)k² + 2κ: the optical branch, cut off at
  ρjω² = 2κ for k = 0.

At k = 0 a uniform micro-rotation R = exp(φe₁) at fixed positions has θ_α = Rᵀe_α, π_α = 0 and,
from the energy of :mod:`cartan_cosserat_solid.solid`, the exact (finite-rotation) potential
V(φ) = (2λ + 2μ + κ)(1 − cos φ)² + κ sin²φ; ρjφ̈ = −V′(φ), whose small-amplitude limit is the
cutoff ρjω² = 2κ.  On the lattice a uniform state is uniform on every edge, and the force is
exactly ad*_{X_α}Q^α (the odd part of dexp⁻¹): the semi-discrete motion is this ODE exactly,
so the only error is the integrator's.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

import cartan

try:  # the verification package is optional for users of the medium
    from cartan_verification.case import Case
except ImportError:  # pragma: no cover - registered only with cartan_verification installed
    Case = object  # type: ignore[assignment,misc]


if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["LongitudinalWave", "OpticalCutoff", "RotationWave", "ShearWave", "all_cases", "optical_potential",
           "shear_wave_branches", "uniform_rotation_exact"]


class _PeriodicBoxCase(Case):
    """A case on a periodic box: the lattice only (the collocation scheme takes no holonomy)."""

    def run(self, problem: Problem, settings: Any, integrator: str, scheme: str = "lattice",
            compiled: bool = True) -> xr.Dataset:
        if scheme != "lattice":
            raise ValueError(f"this case runs on a periodic box with translation holonomies: scheme must be "
                             f"'lattice', got {scheme!r}")
        return cartan.simulate(problem, integrator=integrator, scheme=scheme, compiled=compiled, progress=False,
                               **dict(settings))


class _PlaneWave(_PeriodicBoxCase):
    """A standing plane wave along x₁ in a periodic n × 3 × 3 box (fields independent of x₂,
    x₃: a plane wave of the unbounded solid), run for 5/4 of its period at Δt = ``cfl``·h/c.

    Subclasses give :meth:`_wave` → ``(solid, ω, k, c, P)`` (c the speed that sets Δt, P a
    coupled amplitude or None), :meth:`_displace` (the initial frames) and :meth:`_fields`
    (the observed fields, their exact values and scales at the final time)."""

    space_order = 2.0
    time_order_of = None
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    length, mode, amplitude, cfl, n0 = 2.0, 1, 1e-4, 0.25, 16

    def _wave(self):  # pragma: no cover - every subclass defines it
        raise NotImplementedError

    def _displace(self, Phi: np.ndarray, x: np.ndarray, k: float, P: float | None) -> None:  # pragma: no cover
        raise NotImplementedError

    def _fields(self, ds: xr.Dataset, x: np.ndarray, k: float, P: float | None, c: float) -> list:  # pragma: no cover
        raise NotImplementedError

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        solid, omega, k, speed, P = self._wave()
        n = self.n0 * 2**level
        h = self.length / n
        grid = cartan.Grid((n, 3, 3), length=(self.length, 3 * h, 3 * h), periodic=True)
        base = solid.initial_state(grid, "undeformed")
        Phi = base.Phi.copy()
        self._displace(Phi, grid.coordinates(0), k, P)
        t_end = 1.25 * 2 * math.pi / omega
        steps = math.ceil(t_end / (self.cfl * h / speed))
        problem = cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi, holonomy=base.holonomy), name=self.name)
        return problem, {"dt": t_end / steps, "t_end": t_end, "save_every": steps}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        _, omega, k, _, P = self._wave()
        x = problem.grid.coordinates(0)[:, None, None]
        c = math.cos(omega * float(ds.time[-1]))
        return float(max(np.max(np.abs(got - exact)) / scale for got, exact, scale in self._fields(ds, x, k, P, c)))


class LongitudinalWave(_PlaneWave):
    """Longitudinal standing wave u₁ = ε sin(kx₁) cos(ωt) in a periodic micropolar box,
    ρω² = (λ + 2μ + κ)k² (default solid, L = 2, mode 1, ε = 1e-4).

    The box is n × 3 × 3 nodes, periodic along every axis (fields independent of x₂, x₃: a plane
    wave of the unbounded solid).  On the lattice the motion is exactly a linear mass–spring chain
    (pure translations: the SE(3) logarithm is linear, and no rotation is excited), with
    ω_h = (2c/h) sin(kh/2): relative phase error (kh)²/24, plus Lie–Verlet's (ωΔt)²/24 with
    Δt = 0.25h/c refined with h.
    """

    name = "solid-longitudinal-wave"
    medium = "cosserat-solid"
    description = "longitudinal plane wave in a periodic micropolar box: ρω² = (λ + 2μ + κ)k²"
    reference = ("linear micropolar elastodynamics (Eringen, Microcontinuum Field Theories I, §5.11): "
                 "u₁ = ε sin(kx₁) cos(ωt), ρω² = (λ + 2μ + κ)k², no dispersion")
    quantity = "longitudinal displacement u₁ at the nodes after 5/4 periods (cos ωt = 0)"
    norm = "max abs over nodes at t_end = (5/4)·2π/ω, relative to the amplitude ε"
    levels = (0, 1, 2, 3)
    quick_levels = (0, 1)
    tolerance = 2.5e-2
    tolerance_reason = ("n = 16·2^level along x₁; measured 4.73e-2 (n = 16) and 1.18e-2 (n = 32), the predicted "
                        "(5π/2)[(kh)²/24 + (ωΔt)²/24] = 5.4e-2 and 1.3e-2 (O(h²) lattice dispersion + O(Δt²) "
                        "Lie–Verlet); 2× margin at the finest quick level")

    def _wave(self):
        solid = cartan.medium("cosserat-solid")
        c, k = solid.longitudinal_speed(), 2 * math.pi * self.mode / self.length
        return solid, c * k, k, c, None

    def _displace(self, Phi, x, k, P):
        Phi[..., 1, 0] += self.amplitude * np.sin(k * x)[:, None, None]

    def _fields(self, ds, x, k, P, c):
        return [(ds.displacement_x.values[-1], self.amplitude * np.sin(k * x) * c, self.amplitude)]


def optical_potential(phi: Any, lam: float, mu: float, kappa: float) -> np.ndarray:
    """V(φ) = (2λ + 2μ + κ)(1 − cos φ)² + κ sin²φ: the energy per unit volume of a uniform
    micro-rotation by φ about a fixed axis at fixed positions (module docstring)."""
    phi = np.asarray(phi, dtype=float)
    return (2 * lam + 2 * mu + kappa) * (1 - np.cos(phi)) ** 2 + kappa * np.sin(phi) ** 2


def uniform_rotation_exact(phi0: float, t: float, lam: float, mu: float, kappa: float, rho_j: float) -> float:
    """φ(t) of ρjφ̈ = −V′(φ), φ(0) = φ₀, φ̇(0) = 0 (:func:`optical_potential`), by an adaptive
    8th-order Runge–Kutta at rtol 1e-13 (scipy's DOP853)."""
    from scipy.integrate import solve_ivp

    A = 2 * lam + 2 * mu + kappa

    def rhs(_t, y):
        s, c = math.sin(y[0]), math.cos(y[0])
        return [y[1], -(2 * A * (1 - c) * s + 2 * kappa * s * c) / rho_j]

    sol = solve_ivp(rhs, (0.0, t), [phi0, 0.0], method="DOP853", rtol=1e-13, atol=1e-15)
    return float(sol.y[0, -1])


class OpticalCutoff(_PeriodicBoxCase):
    """Uniform micro-rotation oscillation (the optical branch at k = 0) in a periodic box:
    φ(0) = 0.5 about e₁, at rest, positions fixed; small-amplitude frequency ρjω² = 2κ.

    Default solid (κ = 0.5, ρj = 0.1: ω = √10), 3 × 3 × 3 nodes periodic, t_end = 5/4 of the
    linear period, Δt = T/(16·2^level).  The semi-discrete motion is the exact 1-DOF ODE of the
    module docstring, so the error is the integrator's: O(Δt²) for Lie–Verlet, O(Δt⁴) for RKMK4.
    """

    name = "solid-optical-cutoff"
    medium = "cosserat-solid"
    description = "uniform micro-rotation (optical branch, k = 0) in a periodic box: ρjω² = 2κ at small amplitude"
    reference = ("ρjφ̈ = −V′(φ), V = (2λ+2μ+κ)(1 − cos φ)² + κ sin²φ (the medium's energy at a uniform rotation; "
                 "small amplitude: Eringen's cutoff ρjω² = 2κ), integrated by DOP853 at rtol 1e-13")
    quantity = "micro-rotation angle φ (mean over the nodes) at t_end = (5/4)·2π/√(2κ/ρj)"
    norm = "|φ − φ_exact| / φ₀ at t_end"
    space_order = None
    time_order_of = {"lie-verlet": 2.0, "rkmk4": 4.0, "lie-euler": 1.0}
    default_integrators = ("lie-verlet", "rkmk4")
    default_schemes = ("lattice",)
    refine = "time"
    levels = (0, 1, 2, 3)
    quick_levels = (1, 2)
    tolerance = 1e-2
    tolerances = {"lie-verlet": 1e-2, "rkmk4": 1e-4}
    tolerance_reason = ("Δt = T/(16·2^level); measured at level 2 (Δt = T/64) 4.7e-3 (Lie–Verlet, observed order "
                        "2.02) and 3.4e-5 (RKMK4, observed order 4.02); tolerances ≈ 2–3× those")

    phi0 = 0.5

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        solid = cartan.medium("cosserat-solid")
        grid = cartan.Grid((3, 3, 3), length=(1.0, 1.0, 1.0), periodic=True)
        base = solid.initial_state(grid, "undeformed", rotation=(0.0, 0.0, 0.0))
        Phi = base.Phi.copy()
        Phi[..., 1:, 1:] = cartan.group("SO3").exp(np.array([self.phi0, 0.0, 0.0]))
        period = 2 * math.pi / math.sqrt(2 * solid.constants["kappa"] / (solid.rho * solid.j))
        steps = 16 * 2**level
        t_end = 1.25 * period
        problem = cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi, holonomy=base.holonomy), name=self.name)
        return problem, {"dt": t_end / (1.25 * steps), "t_end": t_end, "save_every": round(1.25 * steps)}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        solid = problem.medium
        c = solid.constants
        exact = uniform_rotation_exact(self.phi0, float(ds.time[-1]), c["lam"], c["mu"], c["kappa"],
                                       solid.rho * solid.j)
        phi = float(np.mean(ds.microrotation_x.values[-1]))
        return abs(phi - exact) / self.phi0


class RotationWave(_PlaneWave):
    """Longitudinal micro-rotation standing wave φ₁ = ε sin(kx₁) cos(ωt) in a periodic box:
    the dispersive optical branch ρjω² = (α + β + γ)k² + 2κ (default solid, L = 2, mode 1, ε = 1e-4).

    Positions stay fixed (φ₁ does not couple to u₁ in the linear theory; the finite-rotation
    coupling is O(ε²)).  On the lattice a rotation about e₁ varying along x₁ is exact on every
    edge, and the semi-discrete motion is the chain ρjφ̈_i = (α+β+γ)(φ_{i+1} − 2φ_i + φ_{i−1})/h²
    − V′(φ_i) with ρjω_h² = (α+β+γ)(2/h)² sin²(kh/2) + 2κ: an O(h²) phase error, plus
    Lie–Verlet's O(Δt²) with Δt = 0.25h/c (c the fastest wave speed) refined with h.
    """

    name = "solid-rotation-wave"
    medium = "cosserat-solid"
    description = ("longitudinal micro-rotation wave in a periodic micropolar box: ρjω² = (α+β+γ)k² + 2κ "
                   "(the optical branch)")
    reference = ("linear micropolar elastodynamics (Eringen, Microcontinuum Field Theories I, §5.11): "
                 "φ₁ = ε sin(kx₁) cos(ωt), ρjω² = (α + β + γ)k² + 2κ")
    quantity = "longitudinal micro-rotation φ₁ at the nodes after 5/4 periods (cos ωt = 0)"
    norm = "max abs over nodes at t_end = (5/4)·2π/ω, relative to the amplitude ε"
    levels = (0, 1, 2, 3)
    quick_levels = (0, 1)
    tolerance = 2e-2
    tolerance_reason = ("n = 16·2^level along x₁; measured 3.27e-2, 8.19e-3, 2.05e-3, 5.12e-4 at n = 16 … 128 "
                        "(observed order 2.00: O(h²) lattice dispersion + O(Δt²) Lie–Verlet); 2.4× margin at the "
                        "finest quick level")

    def _wave(self):
        solid = cartan.medium("cosserat-solid")
        c = solid.constants
        k = 2 * math.pi * self.mode / self.length
        omega = math.sqrt(((c["alpha"] + c["beta"] + c["gamma"]) * k**2 + 2 * c["kappa"]) / (solid.rho * solid.j))
        return solid, omega, k, solid.wave_speed(), None

    def _displace(self, Phi, x, k, P):
        phi = self.amplitude * np.sin(k * x)
        Phi[..., 1:, 1:] = cartan.group("SO3").exp(phi[:, None] * np.array([1.0, 0.0, 0.0]))[:, None, None]

    def _fields(self, ds, x, k, P, c):
        return [(ds.microrotation_x.values[-1], self.amplitude * np.sin(k * x) * c, self.amplitude)]


def shear_wave_branches(k: float, lam: float, mu: float, kappa: float, alpha: float, beta: float, gamma: float,
                        rho: float, rho_j: float) -> tuple[float, float]:
    """The two transverse frequencies (acoustic, optical) at wavenumber k > 0.

    A transverse wave u₂(x₁) couples to the micro-rotation φ₃(x₁):
    ρü₂ = (μ+κ)u₂″ − κφ₃′, ρjφ̈₃ = γφ₃″ + κu₂′ − 2κφ₃, so that
    [(μ + κ)k² − ρω²][γk² + 2κ − ρjω²] = κ²k² (λ, α, β do not enter).

    Returns
    -------
    (ω_acoustic, ω_optical) : floats
    """
    a = rho * rho_j
    b = -(rho * (gamma * k**2 + 2 * kappa) + rho_j * (mu + kappa) * k**2)
    c = (mu + kappa) * k**2 * (gamma * k**2 + 2 * kappa) - kappa**2 * k**2
    disc = math.sqrt(b * b - 4 * a * c)
    return math.sqrt((-b - disc) / (2 * a)), math.sqrt((-b + disc) / (2 * a))


class ShearWave(_PlaneWave):
    """Transverse standing wave on the acoustic branch, u₂ = ε sin(kx₁) cos(ωt) with the micro-rotation
    φ₃ = P cos(kx₁) cos(ωt) it drags along, P = ((μ+κ)k² − ρω²)ε/(κk) (default solid, L = 2,
    mode 1, ε = 1e-4): the coupled micropolar dispersion [(μ+κ)k² − ρω²][γk² + 2κ − ρjω²] = κ²k².

    Unlike the longitudinal waves, translations and rotations mix on every u-edge; the lattice
    dispersion is O(h²) off the continuum one, and Lie–Verlet adds O(Δt²) with Δt = 0.25h/c.
    """

    name = "solid-shear-wave"
    medium = "cosserat-solid"
    description = ("transverse (shear) plane wave in a periodic micropolar box, coupled to the micro-rotation: "
                   "[(μ+κ)k² − ρω²][γk² + 2κ − ρjω²] = κ²k²")
    reference = ("linear micropolar elastodynamics (Eringen, Microcontinuum Field Theories I, §5.11): the acoustic "
                 "root of [(μ+κ)k² − ρω²][γk² + 2κ − ρjω²] = κ²k², eigenvector (u₂, φ₃) = (ε sin kx₁, P cos kx₁)")
    quantity = "transverse displacement u₂ and micro-rotation φ₃ at the nodes after 5/4 periods"
    norm = "max over nodes of |u₂ − exact|/ε and |φ₃ − exact|/|P| at t_end = (5/4)·2π/ω"
    levels = (0, 1, 2)
    quick_levels = (0, 1)
    # Δt ∝ h at a fixed CFL number: at a fixed Δt the lattice's (slow) and leapfrog's (fast)
    # dispersion errors cancel partly as h falls, and the fitted order drifts above 2 (2.47)
    refine = "both"
    tolerance = 2e-4
    tolerance_reason = ("n = 32·2^level along x₁ (n = 16 is pre-asymptotic for the coupled branch: measured "
                        "2.80e-3, 4.47e-4, 9.58e-5, 2.29e-5 at n = 16 … 128, observed orders 2.65, 2.22, 2.06, "
                        "O(h²) once the wave is resolved); 2× margin at n = 64")

    n0 = 32

    def _wave(self):
        solid = cartan.medium("cosserat-solid")
        c = solid.constants
        k = 2 * math.pi * self.mode / self.length
        omega, _ = shear_wave_branches(k, **c, rho=solid.rho, rho_j=solid.rho * solid.j)
        P = -(solid.rho * omega**2 - (c["mu"] + c["kappa"]) * k**2) * self.amplitude / (c["kappa"] * k)
        return solid, omega, k, solid.wave_speed(), P

    def _displace(self, Phi, x, k, P):
        Phi[..., 2, 0] += (self.amplitude * np.sin(k * x))[:, None, None]
        R = cartan.group("SO3").exp((P * np.cos(k * x))[:, None] * np.array([0.0, 0.0, 1.0]))
        Phi[..., 1:, 1:] = R[:, None, None]

    def _fields(self, ds, x, k, P, c):
        return [(ds.displacement_y.values[-1], self.amplitude * np.sin(k * x) * c, self.amplitude),
                (ds.microrotation_z.values[-1], P * np.cos(k * x) * c, abs(P))]


def all_cases() -> list:
    """The cases this plugin registers (none without the verification package)."""
    if Case is object:  # pragma: no cover - the verification package is not installed
        return []
    return [LongitudinalWave(), RotationWave(), ShearWave(), OpticalCutoff()]
