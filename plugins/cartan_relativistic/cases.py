"""Verification cases of the ``relativistic-rod`` medium (paper §VIII.C; docs/media/relativistic-rod.md).

Kinematics (the ``kinematic`` integrator with a prescribed N = {U; O}, U = (c, 0, 0, 0), in
proper time τ):

* :class:`BoostComposition` — constant proper acceleration along e₁: Λ(τ) is the composition
  of the steps' boosts, whose rapidities add to ατ/c, and r(τ) is hyperbolic motion.
* :class:`BoostedRod` — a rod at rest in a frame boosted by rapidity η: lab length L₀/γ and
  lab clocks running γ times faster than the rod's proper time.

Dynamics (``lie-verlet`` on the lattice, conformal–temporal gauge, c = 1):

* :class:`CollapsingLoop` — the circular Nambu–Goto loop released from rest,
  r(t) = R₀ cos(t/R₀), E = 2πR₀μ;
* :class:`BoostedLoop` — the same loop moving at βc along its axis: collapse time dilated by γ;
* :class:`SpinningLoop` — a Kibble–Turok loop x = ½[a(σ − t) + b(σ + t)] with a and b in
  planes at angle ψ: a loop with angular momentum, moving in three dimensions.
* :class:`BoostedSpinningLoop` — that loop moving at 0.6c in its own plane, against the
  Lorentz transform of the exact worldsheet re-sliced at equal lab time
  (:mod:`cartan_relativistic.lorentz`).

Fixed ends (``lie-verlet`` on the lattice's numpy path, :class:`cartan.Held` ends):

* :class:`FixedEndsStandingWave` — a string stretched between two fixed points oscillating in
  its finite-amplitude fundamental mode (θ₀ = 0.8: the midpoint reaches 0.72c), against the
  exact x⃗ = ½[a(σ − t) + a(σ + t)] with a′ even and 2L-periodic.

Limit (a parameter refinement, v/c halved with the level):

* :class:`NewtonianLimit` — a Nambu–Goto standing wave whose largest speed is v, against the
  linear taut string (tension μc², mass μ per lab length) with the same lab shape: the
  difference falls as (v/c)² (docs §2, "Newtonian limit").
* :class:`ElasticNewtonianLimit` — the elastic string (``energy="elastic"``, ``rkmk4`` on the
  core's coupled-Lagrangian path) against ``cosserat-rod`` as an extensible string with the
  same data, c = 10·2^level: the difference falls as c⁻².

Time order of the coupled-Lagrangian path:

* :class:`RotatingElasticRing` — the elastic ring turning rigidly at its discrete relative
  equilibrium (an exact solution of the semi-discrete system), ``implicit-midpoint`` (order 2,
  symplectic) and ``rkmk4`` (order 4).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from cartan_verification.case import Case
from numba import njit

import cartan

from .limit import amplitude, lab_period, newtonian_string, standing_wave, tilt_for_speed
from .string import loop_exact

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["BoostComposition", "BoostedLoop", "BoostedRod", "BoostedSpinningLoop", "CollapsingLoop",
           "ElasticNewtonianLimit", "FixedEndsStandingWave", "NewtonianLimit", "RotatingElasticRing",
           "SpinningLoop", "all_cases"]

#: proper acceleration α (c = 1) of :class:`BoostComposition`: rapidity ατ reaches 20 at τ = 20
ALPHA = 1.0
#: rapidity of :class:`BoostedRod` (γ = cosh 3 ≈ 10.07)
ETA = 3.0


@njit(cache=True)
def accelerated_observer(t, u, X):  # pragma: no cover - compiled
    """N = {U; O} with U = (1, 0, 0, 0) and O = [a; Ω] = [(α, 0, 0); 0]: proper acceleration α along e₁."""
    N = np.zeros(10)
    N[0] = 1.0
    N[4] = ALPHA
    return N


@njit(cache=True)
def inertial_observer(t, u, X):  # pragma: no cover - compiled
    """N = {U; O} with U = (1, 0, 0, 0) and O = 0: free fall (inertial motion) in proper time."""
    N = np.zeros(10)
    N[0] = 1.0
    return N


def _rapidity(Lam: np.ndarray) -> np.ndarray:
    """Rapidity of the Lorentz frames ``[..., 4, 4]`` along e₁, asinh Λ₁₀ (accurate at large rapidities)."""
    return np.arcsinh(Lam[..., 1, 0])


class BoostComposition(Case):
    """Constant proper acceleration α along e₁ (c = 1), run by ``kinematic`` in proper time τ.

    Each step composes Φ ← Φ exp(Δτ N) with N = {e₀; [αe₁; 0]}: the boosts of the steps
    compose along one axis, so their rapidities add, η = ατ exactly; the event is hyperbolic
    motion r = (sinh ατ, cosh ατ − 1, 0, 0)/α.  Integrated to rapidity 20 (γ ≈ 2.4·10⁸),
    where the Poincaré kernels must stay exact.
    """

    name = "relativistic-boost-composition"
    medium = "relativistic-rod"
    description = "boosts along one axis compose: rapidities add to ατ (up to 20); hyperbolic motion"
    reference = "η(τ) = ατ, r(τ) = (sinh ατ, cosh ατ − 1, 0, 0)/α (Rindler, Relativity, §3.8; hyperbolic motion)"
    quantity = "rapidity asinh Λ₁₀ and event r of every node over all saved frames"
    norm = "max over frames of |η − ατ|/max(ατ, 1) and ‖r − r_exact‖∞/‖r_exact‖∞"
    space_order = None
    time_order_of = {"kinematic": 4.0}
    roundoff = True
    refine = "time"
    default_integrators = ("kinematic",)
    default_schemes = ("lattice",)
    levels = (0, 1)
    tolerance = 1e-12
    tolerance_reason = ("constant N: every RKMK stage is exp(ΔτN) exactly, so the error is the round-off of "
                        "≤ 160 compositions of 5×5 matrices with entries up to 2.4e8 (≈ 160 ε relative)")

    t_end = 20.0

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        med = cartan.medium("relativistic-rod")
        grid = cartan.Grid(2, length=1.0)
        init = med.initial_state(grid, "straight")
        steps = 80 * 2**level
        return cartan.Problem(med, grid, init, name=self.name), {
            "dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps // 20,
            "integrator_options": {"velocity": accelerated_observer, "order": 4},
            "scheme_options": {"track_frames": True}}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        tau = ds.time.values[:, None]
        eta = _rapidity(ds.frame.values)  # Λ [time, node, 4, 4]
        e_eta = float(np.max(np.abs(eta - ALPHA * tau) / np.maximum(ALPHA * tau, 1.0)))
        u = problem.grid.coordinates(0)[None, :]
        exact = np.stack([np.sinh(ALPHA * tau) / ALPHA + 0 * u, (np.cosh(ALPHA * tau) - 1.0) / ALPHA + u,
                          0 * u + 0 * tau, 0 * u + 0 * tau], axis=-1)
        r = ds.position.values  # [time, node, 4]
        e_r = float(np.max(np.abs(r - exact) / np.max(np.abs(exact), axis=(-2, -1), keepdims=True)))
        return max(e_eta, e_r)


class BoostedRod(Case):
    """A rod of rest length L₀ at rest in a frame boosted by rapidity η along e₁ (c = 1).

    Φ₀(u) = B(η)·(u e₁; I) and N = {e₀; 0} (inertial motion, proper time τ): the events are
    r(τ, u) = B(η)(τ, u, 0, 0).  In the lab the rod moves at β = tanh η; its endpoints at equal
    lab time are L₀/γ apart (length contraction), and between two saved frames each node's
    lab time advances γ Δτ (time dilation).
    """

    name = "relativistic-boosted-rod"
    medium = "relativistic-rod"
    description = "rod at rest, boosted by rapidity 3: lab length L₀/γ, lab clock rate γ per unit proper time"
    reference = "Lorentz contraction L = L₀/γ and time dilation dt/dτ = γ, γ = cosh η (Rindler, Relativity, §2.7)"
    quantity = "lab length of the rod at equal lab time, and dt/dτ of every node, over all saved frames"
    norm = "max of |L − L₀/γ|/(L₀/γ) and |Δt/Δτ − γ|/γ"
    space_order = None
    time_order_of = {"kinematic": 4.0}
    roundoff = True
    refine = "time"
    default_integrators = ("kinematic",)
    default_schemes = ("lattice",)
    levels = (0, 1)
    tolerance = 1e-12
    tolerance_reason = "inertial motion is exp(ΔτN) exactly: round-off of a few compositions (entries ≈ γ ≈ 10)"

    length, t_end = 2.0, 4.0

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        med = cartan.medium("relativistic-rod")
        grid = cartan.Grid(9, length=self.length)
        init = med.initial_state(grid, "straight")
        B = med.group.exp(np.array([0.0, 0.0, 0.0, 0.0, ETA, 0.0, 0.0, 0.0, 0.0, 0.0]))
        Phi = np.einsum("ij,njk->nik", B, init.Phi)
        steps = 8 * 2**level
        return cartan.Problem(med, grid, cartan.InitialState(Phi=Phi, N=init.N), name=self.name), {
            "dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps // 4,
            "integrator_options": {"velocity": inertial_observer, "order": 4},
            "scheme_options": {"track_frames": True}}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        gamma = math.cosh(ETA)
        r = ds.position.values  # [time, node, 4]: (t, x, y, z)
        tau = ds.time.values
        dt_lab = np.diff(r[..., 0], axis=0)  # [time−1, node]
        rate = dt_lab / np.diff(tau)[:, None]
        e_clock = float(np.max(np.abs(rate - gamma) / gamma))
        v = np.diff(r[..., 1], axis=0) / dt_lab  # lab velocity of each node from its worldline
        errs = [e_clock]
        for k in range(r.shape[0]):
            t_star = r[k, -1, 0]  # the far end's lab time: carry the near end along its worldline
            vk = v[min(k, v.shape[0] - 1)]
            x0 = r[k, 0, 1] + vk[0] * (t_star - r[k, 0, 0])
            L = r[k, -1, 1] - x0
            errs.append(abs(L - self.length / gamma) / (self.length / gamma))
        return float(max(errs))


class CollapsingLoop(Case):
    """Circular Nambu–Goto loop released from rest, radius R₀ = 1, μ = c = 1.

    In conformal–temporal gauge the lattice is a chain of linear springs whose dispersion
    ω_h = (2/h) sin(h/2) gives an O(h²) error; Δt = h/2 keeps the leapfrog error O(h²) as well.
    Compared at t = 1.2 R₀ (before the collapse at πR₀/2).
    """

    name = "relativistic-loop-collapse"
    medium = "relativistic-rod"
    description = "circular Nambu–Goto loop from rest: r(t) = R₀ cos(t/R₀), E = 2πR₀μ"
    reference = ("x(σ, t) = R₀ cos(t/R₀)(cos σ/R₀, sin σ/R₀, 0) (Vilenkin & Shellard, Cosmic Strings and Other "
                 "Topological Defects, §6.2)")
    quantity = "lab positions of the nodes at t_end"
    norm = "max over nodes of ‖x − x_exact‖ at t_end, relative to R₀"
    space_order = 2.0
    time_order_of = None
    refine = "space"
    default_integrators = ("lie-verlet", "rkmk4")
    default_schemes = ("lattice", "collocation")
    levels = (0, 1, 2, 3)
    tolerance = 1e-3
    tolerance_reason = ("n = 16·2^level; at n = 128 the phase error of mode 1 is t[(h/R₀)²/24 + (Δt/R₀)²/24] "
                        "≈ 1.5e-4 R₀ (h = 2π/128, Δt = h/2) on the lattice; the collocated central difference "
                        "has the dispersion (kh)²/6, 4× the lattice's: ≈ 4e-4 R₀; margin ≈ 3")
    tolerances = {"lie-verlet/collocation": 1.5e-3, "rkmk4/collocation": 1.5e-3}
    radius, tilt, boost, t_end, cfl = 1.0, 0.0, 0.0, 1.2, 0.5

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        med = cartan.medium("relativistic-rod")
        gamma = 1.0 / math.sqrt(1.0 - self.boost**2)
        n = 16 * 2**level
        grid = cartan.Grid(n, length=2 * math.pi * gamma * self.radius, periodic=True)
        init = med.initial_state(grid, "loop", tilt=self.tilt, boost=self.boost)
        h = grid.spacing[0]
        steps = math.ceil(self.t_end / (self.cfl * h))
        return cartan.Problem(med, grid, init, name=self.name), {
            "dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        t = float(ds.time[-1])
        x, _ = loop_exact(problem.grid.coordinates(0), t, self.radius, 1.0, self.tilt, self.boost)
        lab = np.stack([ds.lab_x.values[-1], ds.lab_y.values[-1], ds.lab_z.values[-1]], axis=-1)
        return float(np.max(np.linalg.norm(lab - x, axis=-1)) / self.radius)


class BoostedLoop(CollapsingLoop):
    """The circular loop moving at β = 0.6 along its axis: collapse dilated, r(t) = R₀ cos(t/(γR₀))."""

    name = "relativistic-loop-boosted"
    description = "circular loop moving at 0.6c along its axis: r(t) = R₀ cos(t/(γR₀)), z = βt"
    reference = ("the rest-frame loop boosted along e₃: x = (R₀ cos(t/γR₀)(cos, sin)(σ/γR₀), βt), "
                 "E = γ·2πR₀μ (Lorentz transformation of the collapsing loop)")
    tolerance_reason = ("n = 16·2^level; O(h²) phase error of mode 1 with h = 2πγR₀/n, slower by γ than the loop at "
                        "rest; ≈ 1.5e-4 R₀ at n = 128, margin ≈ 3")
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    tolerances = {}
    boost = 0.6


class SpinningLoop(CollapsingLoop):
    """A Kibble–Turok loop, tilt ψ = π/3: rotating, never collapsing to a point."""

    name = "relativistic-loop-spinning"
    description = "Kibble–Turok loop x = ½[a(σ − t) + b(σ + t)], planes of a, b at π/3: spins in 3D"
    reference = ("x = ½[a(σ − t) + b(σ + t)], a, b unit-speed circles of radius R₀ in planes at angle ψ "
                 "(Kibble & Turok, Phys. Lett. B 116 (1982) 141)")
    tolerance_reason = ("n = 16·2^level; the two circles travel as modes ±1 with O(h²) lattice dispersion and "
                        "O(Δt²) leapfrog error, ≈ 1.5e-4 R₀ at n = 128, margin ≈ 3")
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    tolerances = {}
    tilt = math.pi / 3


class BoostedSpinningLoop(CollapsingLoop):
    """The Kibble–Turok loop (ψ = π/3, ρ = 1) moving at β = 0.6 along e₁, in the plane of a.

    Lorentz covariance with a worldsheet that is not planar: the initial data are the boosted
    exact solution in the lab's conformal–temporal gauge (the light-cone maps of
    :func:`cartan_relativistic.lorentz.boosted_kibble_turok`, σ̃ of period 2πγ, its sampling
    non-uniform in the rest frame's σ), and the run is compared with the boost of the exact
    rest-frame solution at equal lab time.  The lattice is the chain of the wave equation in σ̃:
    O(h²) dispersion and O(Δt²) leapfrog error at Δt = h/2; n = 32·2^level.
    """

    name = "relativistic-loop-boosted-spinning"
    description = "Kibble–Turok loop (ψ = π/3) moving at 0.6c in its plane: the run is the boost of the solution"
    reference = ("the rest-frame loop x = ½[a(σ − τ) + b(σ + τ)] (Kibble & Turok 1982) Lorentz-transformed by "
                 "β = 0.6 along e₁ and re-sliced at equal lab time through the light-cone maps "
                 "F₊ = γ(s + βb₁(s)), F₋ = γ(s − βa₁(s)) (docs §6, \"Further checks\")")
    quantity = "lab positions of the nodes at t = 1.5"
    norm = "max over nodes of ‖x − x_exact‖ at t_end, relative to ρ"
    tolerance = 8e-4
    tolerance_reason = ("n = 32·2^level; measured 2.06e-2, 5.69e-3, 1.44e-3, 3.56e-4 at n = 32 … 256 (orders 1.86, "
                        "1.98, 2.02: the O(h²) phase errors of modes that the boost compresses by up to "
                        "1/(γ(1 − β)) = 2 along σ̃); margin 2.2 at n = 256")
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    tolerances = {}
    beta, tilt, t_end, cfl = 0.6, math.pi / 3, 1.5, 0.5

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        from .lorentz import boosted_kibble_turok

        med = cartan.medium("relativistic-rod")
        gamma = 1.0 / math.sqrt(1.0 - self.beta**2)
        grid = cartan.Grid(32 * 2**level, length=2 * math.pi * gamma, periodic=True)
        x, v = boosted_kibble_turok(grid.coordinates(0), 0.0, self.beta, self.tilt)
        steps = round(self.t_end / (self.cfl * grid.spacing[0]))
        return cartan.Problem(med, grid, med.state_from(x, v), name=self.name), {
            "dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        from .lorentz import boosted_kibble_turok

        x, _ = boosted_kibble_turok(problem.grid.coordinates(0), float(ds.time[-1]), self.beta, self.tilt)
        lab = np.stack([ds.lab_x.values[-1], ds.lab_y.values[-1], ds.lab_z.values[-1]], axis=-1)
        return float(np.max(np.linalg.norm(lab - x, axis=-1)))


class FixedEndsStandingWave(Case):
    """A Nambu–Goto string between two fixed points in its finite-amplitude fundamental mode (c = μ = 1).

    σ ∈ [0, L], L = 1, both ends :func:`cartan_relativistic.fixed.fixed_end` (``cartan.Held``
    holding U⃗ and the frame: r⁰ free, Neumann), released from rest in the shape a(σ) with the
    tangent angle θ₀ cos(πσ/L), θ₀ = 0.8 (docs §3, "Fixed ends"): the exact solution
    :func:`cartan_relativistic.fixed.fixed_standing_wave`, ends at 0 and L J₀(θ₀) e₁, period
    2L/c.  The lattice is the chain of linear springs of the wave equation with the fixed nodes
    as its ends (the odd reflection of the periodic chain of 2(n − 1) cells), so the error is
    the O(h²) dispersion of the chain and of the leapfrog at Δt = h/2.  Compared at the saved
    frames t = L/4, L/2, 3L/4 (at t = L, 2L the modes' phase errors cancel to a higher order).
    """

    name = "relativistic-fixed-ends"
    medium = "relativistic-rod"
    description = "Nambu–Goto string between two fixed points (cartan.Held ends), finite-amplitude standing wave"
    reference = ("x(σ, t) = ½[a(σ − t) + a(σ + t)], a′ = (cos θ, sin θ, 0), θ = θ₀ cos(πσ/L): a′ even and 2L-periodic, "
                 "so x(0, t) = 0 and x(L, t) = L J₀(θ₀) e₁ (the wave-equation solution of the string with Dirichlet "
                 "ends: Zwiebach, A First Course in String Theory, ch. 6-7)")
    quantity = "lab positions of the nodes at t = L/4, L/2, 3L/4"
    norm = "max over those frames and the nodes of ‖x − x_exact‖, relative to L"
    space_order = 2.0
    time_order_of = None
    refine = "space"
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    tolerance = 3e-5
    tolerance_reason = ("n = 16·2^level + 1 nodes, Δt = h/2; measured 9.8e-6 at n = 129 (docs §6: the O(h²) phase "
                        "error of the chain and the leapfrog, 6.3e-4 at n = 17 falling by 4.00 per level); margin 3")
    theta0, t_end, cfl = 0.8, 0.75, 0.5

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        from .fixed import fixed_end

        med = cartan.medium("relativistic-rod")
        cells = 16 * 2**level
        grid = cartan.Grid(cells + 1, length=1.0)
        init = med.initial_state(grid, "standing", angle=self.theta0)
        steps = round(self.t_end / (self.cfl * grid.spacing[0]))
        return cartan.Problem(med, grid, init, boundaries={"start": fixed_end(), "end": fixed_end()},
                              name=self.name), {"dt": self.t_end / steps, "t_end": self.t_end,
                                                "save_every": steps // 3}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        from .fixed import fixed_standing_wave

        sigma = problem.grid.coordinates(0)
        lab = np.stack([ds.lab_x.values, ds.lab_y.values, ds.lab_z.values], axis=-1)
        worst = 0.0
        for k in range(1, len(ds.time)):
            x, _ = fixed_standing_wave(sigma, float(ds.time[k]), self.theta0, problem.grid.length[0])
            worst = max(worst, float(np.max(np.linalg.norm(lab[k] - x, axis=-1))))
        return worst / problem.grid.length[0]


class NewtonianLimit(Case):
    """Slow motion: a Nambu–Goto standing wave against the linear taut string, v/c → 0 (c = μ = 1).

    An infinite string along e₁, periodic in σ with period L = 2π (a translation holonomy of
    one lab period X_L = L J₀(θ₀)), released from rest with the tangent angle θ₀ cos(2πσ/L):
    its largest speed is v = c sin θ₀, and level ℓ sets v/c = 0.2·2^−ℓ.  The Newtonian
    counterpart is the linear taut string of tension μc² and mass μ per lab length released
    from rest with the same lab shape y₀(x) (closed form, d'Alembert,
    :func:`cartan_relativistic.limit.newtonian_string`; cartan has no medium that is exactly
    this string: the ``cosserat-rod`` carries frames with rotational inertia and shear, a
    dispersive Timoshenko string).

    The Nambu–Goto side runs through the core (``lie-verlet`` on the lattice) at Courant
    number 1, Δt = h/c: the lattice is the chain of linear springs of the wave equation
    (docs §3), on which the leapfrog at Courant number 1 reproduces d'Alembert's solution at
    the nodes exactly, so the run carries no discretisation error (checked against the exact
    standing wave, :func:`cartan_relativistic.limit.standing_wave`) and the difference is the
    physics alone.  Compared at t = L/(3c): the distance along e₂ between the two lab-frame
    curves at the Nambu–Goto nodes' lab abscissae, relative to the amplitude A.  The expected
    exponent is 2 (the quartic term of the Nambu–Goto Lagrangian in static gauge, docs §2).
    """

    name = "relativistic-newtonian-limit"
    medium = "relativistic-rod"
    description = "Nambu–Goto standing wave vs the linear taut string as v/c → 0: difference O((v/c)²)"
    reference = ("the linear taut string ∂²_t y = c² ∂²_x y (tension μc², mass μ per lab length) is the v/c → 0 "
                 "limit of the Nambu–Goto string; the quartic term of ℓ = −μc²√(1 + y′² − ẏ²/c²) is O((v/c)²) "
                 "(the Nambu–Goto action in static gauge; Vilenkin & Shellard, Cosmic Strings and Other Topological "
                 "Defects, ch. 6)")
    quantity = "transverse lab position of the Nambu–Goto nodes at t = L/(3c) against the taut string's y(x, t)"
    norm = "max over nodes of |y − y_Newton(x)| / A, A the amplitude"
    space_order = None
    time_order_of = None
    parameter_order = 2.0
    default_integrators = ("lie-verlet",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    tolerance = 3.8e-4
    tolerance_reason = ("v/c = 0.025 (level 3): the closed forms give the leading term C(v/c)², C = 0.547 at "
                        "t = L/(3c), i.e. 3.42e-4, and the Courant-1 run adds only round-off; margin 10 %")

    length, nodes, c = 2 * math.pi, 96, 1.0

    @staticmethod
    def speed(level: int) -> float:
        """The largest speed v/c of the level's standing wave, 0.2·2^−level."""
        return 0.2 / 2**level

    def limit_levels(self, levels=None) -> dict[int, float]:
        """Level → c/v (the limit parameter: the difference falls as (c/v)^−2)."""
        return {level: 1.0 / self.speed(level) for level in (self.levels if levels is None else levels)}

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        med = cartan.medium("relativistic-rod", c=self.c)
        grid = cartan.Grid(self.nodes, length=self.length, periodic=True)
        theta0 = tilt_for_speed(self.speed(level))
        x, v = standing_wave(grid.coordinates(0), 0.0, theta0, self.length, self.c)
        init = med.state_from(x, v)
        H = np.eye(5)
        H[2, 0] = lab_period(theta0, self.length)  # Φ(σ + L) = H Φ(σ): one lab period along e₁
        steps = self.nodes // 3  # t_end = L/(3c) = (n/3) h/c: Courant number 1
        t_end = self.length / (3 * self.c)
        return cartan.Problem(med, grid, cartan.InitialState(Phi=init.Phi, N=init.N, holonomy=H),
                              name=self.name), {"dt": t_end / steps, "t_end": t_end, "save_every": steps // 4}

    def tilt(self, problem: Problem) -> float:
        """θ₀ of a problem of this case, from its holonomy: J₀(θ₀) = X_L / L."""
        from scipy.optimize import brentq
        from scipy.special import jv

        ratio = float(problem.initial.holonomy[2, 0]) / self.length
        return float(brentq(lambda th: jv(0, th) - ratio, 1e-9, 1.0, xtol=1e-15, rtol=4 * np.finfo(float).eps))

    def difference(self, ds: xr.Dataset, problem: Problem, frame: int = -1) -> float:
        """max |y − y_Newton(x)|/A over the nodes at the saved ``frame``."""
        theta0 = self.tilt(problem)
        t = float(ds.time[frame])
        y = newtonian_string(ds.lab_x.values[frame], t, theta0, self.length, problem.medium.c)
        return float(np.max(np.abs(ds.lab_y.values[frame] - y)) / amplitude(theta0, self.length))

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return self.difference(ds, problem)

    def measure(self, levels=None) -> list[dict[str, Any]]:
        """Run ``levels`` (default the case's) and collect, per level: ``beta`` (v/c), ``error``
        (at t = L/3c), ``quarter`` (the same difference at t = L/4c), ``exact`` (largest
        distance of the run from the exact standing wave over the saved frames, relative to
        A) and the curves of the last frame (``x``, ``y``, ``y_newton``, ``amplitude``)."""
        rows = []
        for level in self.levels if levels is None else levels:
            problem, settings = self.problem(level)
            ds = self.run(problem, settings, self.default_integrators[0])
            theta0 = self.tilt(problem)
            A = amplitude(theta0, self.length)
            sigma = problem.grid.coordinates(0)
            exact = 0.0
            for k, t in enumerate(ds.time.values):
                x, _ = standing_wave(sigma, float(t), theta0, self.length, self.c)
                lab = np.stack([ds.lab_x.values[k], ds.lab_y.values[k], ds.lab_z.values[k]], axis=-1)
                exact = max(exact, float(np.max(np.abs(lab - x))) / A)
            quarter = int(np.argmin(np.abs(ds.time.values - self.length / (4 * self.c))))
            t_last = float(ds.time[-1])
            rows.append({
                "level": level, "beta": self.speed(level), "error": self.error(ds, problem),
                "quarter": self.difference(ds, problem, quarter), "quarter_time": float(ds.time[quarter]),
                "exact": exact, "amplitude": A, "lab_period": float(problem.initial.holonomy[2, 0]),
                "time": t_last, "x": ds.lab_x.values[-1].copy(), "y": ds.lab_y.values[-1].copy(),
                "y_newton": newtonian_string(ds.lab_x.values[-1], t_last, theta0, self.length, self.c)})
        return rows

    def draw(self, rows: list[dict[str, Any]], fig: Any) -> float:
        """The c → ∞ chart into a matplotlib figure: the difference against v/c with its fitted
        slope, and the differences scaled by A(v/c)² along the string.  Returns the slope."""
        from matplotlib.ticker import NullFormatter

        from cartan.study import observed_order

        beta = np.array([r["beta"] for r in rows])
        err = np.array([r["error"] for r in rows])
        quarter = np.array([r["quarter"] for r in rows])
        slope = observed_order(beta, err)
        a1, a2 = fig.subplots(1, 2)
        a1.loglog(beta, err, "o-", label=f"t = L/3c: fitted slope {slope:.3f}")
        a1.loglog(beta, quarter, "s-", label=f"t = L/4c: slope {observed_order(beta, quarter):.3f}")
        fine = np.geomspace(beta.min(), beta.max(), 20)
        a1.loglog(fine, math.pi / 8 * fine**2, "k--", lw=0.8, label="(π/8)(v/c)²: the frequency shift")
        a1.loglog(beta, [max(r["exact"], 1e-17) for r in rows], "x:", label="Nambu–Goto run vs exact (round-off)")
        a1.xaxis.set_minor_formatter(NullFormatter())
        a1.set_xticks(beta, [f"{b:g}" for b in beta])
        a1.set_xlabel("largest speed v/c")
        a1.set_ylabel("max |y_NG − y_Newton| / A")
        a1.set_title("Nambu–Goto string → linear taut string")
        a1.grid(True, which="both", alpha=0.3)
        a1.legend(fontsize=8)
        for r in rows:
            order = np.argsort(r["x"] % r["lab_period"])
            xs = (r["x"] % r["lab_period"])[order] / r["lab_period"]
            a2.plot(xs, ((r["y"] - r["y_newton"]) / (r["amplitude"] * r["beta"] ** 2))[order],
                    label=f"v/c = {r['beta']:g}")
        a2.set_xlabel("lab x / lab period")
        a2.set_ylabel("(y_NG − y_Newton) / (A (v/c)²)")
        a2.set_title("the difference at t = L/3c, scaled by (v/c)²: one curve")
        a2.grid(True, alpha=0.3)
        a2.legend(fontsize=8)
        return slope


class ElasticNewtonianLimit(Case):
    """The elastic string (ε = μc² + ½k(λ − 1)²) against ``cosserat-rod`` as c → ∞, same data.

    An open string (L = 1, μ = 1, k = 1, 17 nodes, free ends) released with the stretch
    1 + 0.1 cos(πu) and the velocity 0.3 cos(2πu) along e₁ (:mod:`cartan_relativistic.elastic_limit`),
    run to t = 1 by ``rkmk4`` with Δt = 0.025 on both sides: the relativistic string through the
    core's coupled-Lagrangian path (temporal gauge, docs §3), the Newtonian one as the
    ``cosserat-rod`` with 𝕊 = kI and 𝔹 = 0, whose frames stay unrotated on this motion along
    e₁.  Both lattices and both time discretisations coincide as c → ∞, so the difference is
    the relativistic correction alone; the expected exponent in c is −2 (the c⁻² bracket of ℓ,
    docs §2).  Levels: c = 10·2^level.
    """

    name = "relativistic-elastic-newtonian-limit"
    medium = "relativistic-rod"
    description = "elastic relativistic string vs cosserat-rod (extensible string) as c → ∞: difference O(c⁻²)"
    reference = ("ℓ = −ε(λ)√(c² − v²)/c with ε = μc² + W(λ) is −μc² + ½μv² − W(|x′|) + O(c⁻²) (docs §2, "
                 "'Newtonian limit'): the extensible string, which the cosserat-rod with 𝕊 = kI, 𝔹 = 0 is on a "
                 "motion along a line")
    quantity = "lab positions x of the nodes at t = 1 against those of the cosserat-rod run"
    norm = "max over nodes of |x_rel − x_Newton| / (aL), aL = 0.1 the stretch amplitude"
    space_order = None
    time_order_of = None
    parameter_order = 2.0
    default_integrators = ("rkmk4",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    tolerance = 5e-5
    tolerance_reason = ("c = 80 (level 3): the measured leading term C c⁻² with C ≈ 0.204 gives 3.2e-5 "
                        "(docs §6); margin 50 %")

    @staticmethod
    def light_speed(level: int) -> float:
        """c = 10·2^level."""
        return 10.0 * 2**level

    def limit_levels(self, levels=None) -> dict[int, float]:
        """Level → c (the limit parameter: the difference falls as c⁻²)."""
        return {level: self.light_speed(level) for level in (self.levels if levels is None else levels)}

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        from . import elastic_limit as E

        med = cartan.medium("relativistic-rod", energy="elastic", c=self.light_speed(level), mu=E.MU, stiffness=E.K)
        grid = cartan.Grid(E.NODES, length=E.LENGTH)
        x, v = E.string_data(grid)
        steps = int(round(E.T_END / E.DT))
        return (cartan.Problem(med, grid, med.state_from(x, v), name=self.name),
                {"dt": E.DT, "t_end": E.T_END, "save_every": steps})

    def _newtonian(self) -> np.ndarray:
        held = self.__dict__.get("_newton_positions")
        if held is None:
            from .elastic_limit import newtonian_run

            held = np.asarray(newtonian_run().position.values[-1], dtype=float)
            object.__setattr__(self, "_newton_positions", held)
        return held

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        from .elastic_limit import LENGTH, STRETCH

        lab = np.stack([ds.lab_x.values[-1], ds.lab_y.values[-1], ds.lab_z.values[-1]], axis=-1)
        return float(np.max(np.abs(lab - self._newtonian())) / (STRETCH * LENGTH))

    def measure(self, levels=None) -> list[dict[str, Any]]:
        """Per level: ``c``, ``error`` (:meth:`error`), ``drift`` (relative change of the discrete
        Hamiltonian H_d over the run: rkmk4's error), ``x``, ``dx`` (the final lab abscissae and
        their difference from the Newtonian run)."""
        rows = []
        for level in self.levels if levels is None else levels:
            problem, settings = self.problem(level)
            ds = self.run(problem, settings, self.default_integrators[0])
            H = ds.kinetic_energy.values + ds.potential_energy.values
            x = ds.lab_x.values[-1].copy()
            rows.append({"level": level, "c": self.light_speed(level), "error": self.error(ds, problem),
                         "drift": float(abs(H[-1] - H[0]) / abs(H[0])), "x": x,
                         "dx": x - self._newtonian()[:, 0]})
        return rows

    def draw(self, rows: list[dict[str, Any]], fig: Any) -> float:
        """The chart: the difference against c with its fitted slope, and the differences along
        the string scaled by c² (one curve).  Returns the fitted slope."""
        from cartan.study import observed_order

        c = np.array([r["c"] for r in rows])
        err = np.array([r["error"] for r in rows])
        slope = observed_order(1.0 / c, err)
        a1, a2 = fig.subplots(1, 2)
        a1.loglog(c, err, "o-", label=f"fitted slope −{slope:.3f}")
        a1.loglog(c, err[0] * (c[0] / c) ** 2, "k--", lw=0.8, label="c⁻²")
        a1.set_xlabel("speed of light c (k = μ = 1, L = 1)")
        a1.set_ylabel("max |x_rel − x_Newton| / (aL) at t = 1")
        a1.set_title("elastic relativistic string → cosserat-rod (extensible string)")
        a1.grid(True, which="both", alpha=0.3)
        a1.legend(fontsize=8)
        for r in rows:
            a2.plot(r["x"], r["dx"] * r["c"] ** 2, "o-", ms=3, label=f"c = {r['c']:g}")
        a2.set_xlabel("lab x at t = 1")
        a2.set_ylabel("(x_rel − x_Newton) · c²")
        a2.set_title("the difference scaled by c²: one curve")
        a2.grid(True, alpha=0.3)
        a2.legend(fontsize=8)
        return slope


class RotatingElasticRing(Case):
    """The elastic ring turning rigidly at its discrete relative equilibrium (docs §4, §6).

    12 nodes, μ = c = 1, k = 0.1, reference radius 1, lab radius R = 1.3, turning at the ω
    that balances the tension on the lattice (:func:`cartan_relativistic.rotating.equilibrium_spin`:
    ωR ≈ 0.2009c): the semi-discrete solution is the rigid rotation x⃗_i(t) = R_{e₃}(ωt)x⃗_i(0)
    exactly, so the error of a run is the time discretisation's alone.  Refined in time
    (Δt = 0.4/2^level to t = 8, about 0.2 turns), through the core's coupled-Lagrangian path:
    ``implicit-midpoint`` (symplectic, order 2) and ``rkmk4`` (order 4).
    """

    name = "relativistic-elastic-rotating-ring"
    medium = "relativistic-rod"
    description = "elastic ring turning rigidly at its discrete relative equilibrium: time order of the coupled path"
    reference = ("the rigid rotation x_i(t) = R(ωt) x_i(0), ω the root of the lattice's radial balance "
                 "W·r̂ + ω|p| = 0 (cartan_relativistic.rotating): an exact solution of the semi-discrete system")
    quantity = "lab positions of the nodes over all saved frames"
    norm = "max over frames and nodes of |x − R(ωt)x₀| / R"
    space_order = None
    time_order_of = {"implicit-midpoint": 2.0, "rkmk4": 4.0, "lie-euler": 1.0}
    refine = "time"
    default_integrators = ("implicit-midpoint", "rkmk4")
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    quick_levels = (2, 3)  # the tolerances are those of level 3
    tolerance = 4e-5
    tolerance_reason = ("implicit-midpoint at Δt = 0.05 (level 3): measured 1.69e-5 (docs §6; the phase error "
                        "of an order-2 method, ∝ Δt²); margin 2.4×.  rkmk4: measured 3.5e-10, margin 2.9×")
    tolerances = {"rkmk4": 1e-9}

    dt0, t_end = 0.4, 8.0

    def spin(self) -> float:
        held = self.__dict__.get("_spin")
        if held is None:
            from .rotating import equilibrium_spin

            held = equilibrium_spin()
            object.__setattr__(self, "_spin", held)
        return held

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        from .rotating import ring_problem

        steps = int(round(self.t_end / self.dt0)) * 2**level
        return (ring_problem(self.spin(), name=self.name),
                {"dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps // 4})

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        from .rotating import RADIUS, rigid_rotation

        lab = np.stack([ds.lab_x.values, ds.lab_y.values, ds.lab_z.values], axis=-1)
        exact = rigid_rotation(lab[0], self.spin(), ds.time.values)
        return float(np.max(np.abs(lab - exact)) / RADIUS)


def all_cases() -> list[Case]:
    """One instance of every relativistic-rod case."""
    return [BoostComposition(), BoostedRod(), CollapsingLoop(), BoostedLoop(), SpinningLoop(), BoostedSpinningLoop(),
            FixedEndsStandingWave(), NewtonianLimit(), ElasticNewtonianLimit(), RotatingElasticRing()]
