"""The ``relativistic-rod`` medium: strings in Minkowski space on the Poincaré group (paper §VIII.C).

Configuration and group (paper §VIII.C)
---------------------------------------
``(M, 𝕏, G) = ([0, L₀] open or closed, F(M^{1,3}), M(1,3) = T(4) ⋊ SO(1,3))``; a configuration
is an event with an inertial frame, the 5 × 5 matrix ``Φ = [[1, 0ᵀ], [r, Λ]]`` with
``r = (ct, x, y, z)`` (homogeneous coordinate first, time coordinate next).  Algebra
components ``ξ = (y₀, y₁, y₂, y₃, c₁, c₂, c₃, d₁, d₂, d₃)``: translation first, then the
boost ``c`` and rotation ``d`` parts of so(1,3) (:mod:`cartan.groups.poincare`).

Dynamics that the core runs (docs/media/relativistic-rod.md, "Dynamics")
----------------------------------------------------------------------
The Nambu–Goto string (rest-frame energy per unit reference length ε(λ) = μc²λ, tension
T = ε′ = μc²) in the conformal gauge of its worldsheet, the Polyakov form of the action:

``K(N) = ½ μ ⟨y_N, y_N⟩_M``,   ``U(X) = ½ T ⟨φ, φ⟩_M``,   ``⟨a, b⟩_M = −a₀b₀ + a⃗·b⃗``,

with ``y_N = Λ⁻¹∂_t r`` and ``φ = Λ⁻¹∂_u r`` the translation parts of N and X.  The kinetic
metric ``M = μ diag(−1, 1, 1, 1, 0₆)`` is indefinite; the Lorentz part is gauge (zero rows:
the frame Λ is held constant and carries no physics, both energies being Lorentz
invariant).  The stress is ``Q = T η φ`` on the translation part, zero on the Lorentz part.
The Euler–Poincaré equations (paper §IV) reduce to the wave equation ``∂²_t r = c² ∂²_u r``
of every component of r, and the Virasoro constraints ``⟨∂_t r, ∂_u r⟩_M = 0`` and
``⟨∂_t r, ∂_t r⟩_M + c²⟨∂_u r, ∂_u r⟩_M = 0`` (preserved by the flow) make it the Nambu–Goto
string.  With ``r⁰ = ct`` at t = 0 and ``∂_t r⁰ = c`` the time component stays ``ct``
(temporal gauge): the core's time is the lab time and u is the energy coordinate, the energy
per unit u being μc².

An elastic string with ε(λ) ≠ μc²λ has no conformal gauge in which u stays a material
coordinate; ``energy="elastic"`` runs it in the temporal gauge r⁰ = ct, where its Lagrangian
ℓ(v⃗, x⃗′) couples N and X (:mod:`cartan_relativistic.elastic_rod`, docs §2–§3).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numba import njit

import cartan
from cartan.medium import KernelMedium, MediumKernels, check_finite, check_keywords, check_positive
from cartan.problem import InitialState

__all__ = [
    "ENERGIES",
    "RelativisticRod",
    "loop_exact",
    "nambu_goto_energy",
    "nambu_goto_stress",
]

#: energy laws ε(λ) the medium accepts: the Nambu–Goto string ε = μc²λ (conformal gauge, K − U) and
#: the elastic string ε = μc² + ½k(λ − 1)² (temporal gauge, a Lagrangian coupling N and X:
#: :class:`cartan_relativistic.elastic_rod.ElasticRelativisticRod`)
ENERGIES = ("nambu-goto", "elastic")

_ETA = np.array([-1.0, 1.0, 1.0, 1.0])


@njit(cache=True)
def nambu_goto_energy(X, X0, p):  # pragma: no cover - compiled
    """``U = ½ T ⟨φ, φ⟩_M`` with φ = X[0, :4] and T = p[0] (X0 unused: the string has no
    stress-free state)."""
    phi0 = X[0, 0]
    return 0.5 * p[0] * (-phi0 * phi0 + X[0, 1] * X[0, 1] + X[0, 2] * X[0, 2] + X[0, 3] * X[0, 3])


@njit(cache=True)
def nambu_goto_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """``Q = ∂U/∂X = T η φ`` on the translation part, zero on the Lorentz part."""
    T = p[0]
    Q[0, 0] = -T * X[0, 0]
    for k in range(1, 4):
        Q[0, k] = T * X[0, k]
    for k in range(4, 10):
        Q[0, k] = 0.0


@njit(cache=True)
def nambu_goto_proper_time_rate(N, p, out):  # pragma: no cover - compiled
    """dτ/dt = √(−⟨y_N, y_N⟩)/c at one node into ``out[0]`` (y_N = N[0:4], c = p[1]; the rate of the
    accumulator ``proper_time``, :meth:`RelativisticRod.accumulator_rates`, in its floating-point
    order): ⟨Λy, Λy⟩ = ⟨y, y⟩ for the node's Lorentz frame Λ, so the rate needs the velocity alone."""
    minus = N[0] * N[0] - N[1] * N[1] - N[2] * N[2] - N[3] * N[3]
    out[0] = math.sqrt(max(minus, 0.0)) / p[1]


def loop_exact(sigma: np.ndarray, t: float, radius: float, c: float = 1.0, tilt: float = 0.0,
               boost: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact Nambu–Goto loop in conformal–temporal gauge: lab positions and velocities.

    ``x(σ, t) = ½[a(σ − ct) + b(σ + ct)]`` with ``a(s) = ρ(cos(s/ρ), sin(s/ρ), 0)`` and
    ``b(s) = ρ(cos(s/ρ), cos ψ sin(s/ρ), sin ψ sin(s/ρ))`` (|a′| = |b′| = 1: the Virasoro
    constraints hold), ρ = γR.  ψ = 0 is the circular loop released from rest,
    ``x = R cos(ct/R)(cos(σ/R), sin(σ/R), 0)``.  A boost β ≠ 0 (needs ψ = 0) moves the
    loop along e₃ at speed βc: its rest-frame solution boosted, rescaled by γ so that the
    gauge stays conformal and temporal, ``x = (R cos(ct/(γR)) (cos, sin)(σ/(γR)), βct)``.

    Parameters
    ----------
    sigma : array, shape ``(n,)``
        Conformal coordinate σ (the grid's u).
    t : float
        Lab time.
    radius : float
        Rest-frame radius R at t = 0.
    c : float
        Speed of light.
    tilt : float
        Angle ψ between the planes of a and b.
    boost : float
        β ∈ (−1, 1).

    Returns
    -------
    (x, v) : arrays of shape ``(n, 3)``
        Positions and velocities ∂_t x.
    """
    sigma = np.asarray(sigma, dtype=float)
    gamma = 1.0 / math.sqrt(1.0 - boost * boost)
    rho = gamma * radius
    sm, sp = (sigma - c * t) / rho, (sigma + c * t) / rho
    ca, sa, cb, sb = np.cos(sm), np.sin(sm), np.cos(sp), np.sin(sp)
    cp, spsi = math.cos(tilt), math.sin(tilt)
    a = rho * np.stack([ca, sa, np.zeros_like(sa)], axis=-1)
    b = rho * np.stack([cb, cp * sb, spsi * sb], axis=-1)
    da = np.stack([-sa, ca, np.zeros_like(sa)], axis=-1)
    db = np.stack([-sb, cp * cb, spsi * cb], axis=-1)
    x = 0.5 * (a + b)
    v = 0.5 * c * (-da + db)
    if boost != 0.0:
        x = x / gamma
        v = v / gamma
        x[:, 2] += boost * c * t
        v[:, 2] += boost * c
    return x, v


class RelativisticRod(KernelMedium):
    """A Nambu–Goto string in Minkowski space on the Poincaré group (paper §VIII.C).

    Parameters
    ----------
    c : float, default 1
        Speed of light, > 0.
    mu : float, default 1
        Rest mass per unit rest length μ, > 0; the tension is T = μc².
    energy : str, default ``"nambu-goto"``
        The rest-frame energy law ε(λ): ``"nambu-goto"`` (ε = μc²λ, this class) or ``"elastic"``
        (ε = μc² + ½k(λ − 1)²: the constructor returns an
        :class:`~cartan_relativistic.elastic_rod.ElasticRelativisticRod`).
    stiffness : float, optional
        k > 0 of the elastic law (``energy="elastic"`` only).
    law, stretch_range : optional
        A general elastic law ε(λ) = μc² + W(λ) and the stretches it is checked over
        (``energy="elastic"`` only: :class:`cartan_relativistic.elastic_rod.ElasticRelativisticRod`).
    clocks : bool, optional
        Accumulate each node's proper time τ in the run (the output ``proper_time``
        ``(time, node)``, continued exactly by restarts; :mod:`cartan.accumulators`).  Default:
        off for the Nambu–Goto string, on for the elastic string; the compiled loops integrate
        it for both (the rate is a Lorentz invariant of the node's velocity,
        :func:`nambu_goto_proper_time_rate`; docs §4, "Proper time per node").

    Notes
    -----
    ``X``, ``Q`` ``[..., 1, 10]`` and ``N``, ``S`` ``[..., 10]`` in the Poincaré basis,
    translation ``(y₀, y⃗)`` first.  Kinetic metric ``μ diag(−1, 1, 1, 1, 0₆)`` (indefinite;
    :meth:`inertia` returns its diagonal, negative in the time slot), potential
    ``U = ½ T ⟨φ, φ⟩_M``.
    """

    name: ClassVar[str] = "relativistic-rod"
    material_dim: ClassVar[int] = 1
    initial_kinds: ClassVar[tuple[str, ...]] = ("loop", "plucked", "standing", "straight")
    output_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "energy": ("total energy E = c P⁰ (lab frame)", "J"),
        "momentum_x": ("total momentum P¹ (lab frame)", "kg m s-1"),
        "momentum_y": ("total momentum P² (lab frame)", "kg m s-1"),
        "momentum_z": ("total momentum P³ (lab frame)", "kg m s-1"),
        "angular_momentum_x": ("total angular momentum J₁ = Σ (y p_z − z p_y) about the origin", "kg m2 s-1"),
        "angular_momentum_y": ("total angular momentum J₂ = Σ (z p_x − x p_z) about the origin", "kg m2 s-1"),
        "angular_momentum_z": ("total angular momentum J₃ = Σ (x p_y − y p_x) about the origin", "kg m2 s-1"),
        "coordinate_time": ("lab (coordinate) time r⁰/c of each node", "s"),
        "lab_x": ("lab position x of each node", "m"),
        "lab_y": ("lab position y of each node", "m"),
        "lab_z": ("lab position z of each node", "m"),
        "lorentz_factor": ("γ = dt/dτ of each node (proper-time rate 1/γ)", "1"),
        "virasoro_residual": ("max over nodes of |⟨ṙ, r′⟩| and |⟨ṙ, ṙ⟩ + c²⟨r′, r′⟩| relative to c²", "1"),
    }

    def __new__(cls, c: float = 1.0, mu: float = 1.0, energy: str = "nambu-goto", stiffness: float | None = None,
                law: Any = None, stretch_range: Any = None, clocks: bool | None = None):
        # (the keywords of __init__, so that the signature of the class names them: a scene's
        # ``clocks = true`` is then read as the switch it is)
        if cls is RelativisticRod and isinstance(energy, str) and energy == "elastic":
            from .elastic_rod import ElasticRelativisticRod

            return super().__new__(ElasticRelativisticRod)
        return super().__new__(cls)

    def __init__(self, c: float = 1.0, mu: float = 1.0, energy: str = "nambu-goto", stiffness: float | None = None,
                 law: Any = None, stretch_range: Any = None, clocks: bool | None = None):
        self.group = cartan.group("Poincare")
        self.space = cartan.space("frame-M13")
        self.c = float(check_positive("c", c, shape=()))
        self.mu = float(check_positive("mu", mu, shape=()))
        if not isinstance(energy, str) or energy not in ENERGIES:
            raise ValueError(f"energy must be one of {ENERGIES}, got {energy!r}")
        if energy == "nambu-goto" and (law is not None or stretch_range is not None):
            raise ValueError("law and stretch_range apply to energy='elastic' (ε(λ) = μc² + W(λ)); the Nambu–Goto "
                             "string's ε = μc²λ is fixed")
        if energy == "nambu-goto" and stiffness is not None:
            raise ValueError("stiffness applies to energy='elastic' (ε(λ) = μc² + ½k(λ − 1)²); the Nambu–Goto "
                             "string has none")
        self.energy = energy
        self.tension = self.mu * self.c**2
        self.clocks = self._check_clocks(clocks, default=False)

    @staticmethod
    def _check_clocks(clocks: Any, default: bool) -> bool:
        if clocks is None:
            return default
        if not isinstance(clocks, (bool, np.bool_)):
            raise ValueError(f"clocks must be True or False (accumulate each node's proper time in the run), "
                             f"got {clocks!r}")
        return bool(clocks)

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        out: dict[str, Any] = {"c": self.c, "mu": self.mu, "energy": self.energy}
        if self.clocks:
            out["clocks"] = True
        return out

    # ------------------------------------------------------------------ proper time in the run
    def accumulators(self) -> dict[str, tuple[str, str]]:
        """``{"proper_time": ...}`` with ``clocks=True`` (:mod:`cartan.accumulators`): each node's
        proper time τ, accumulated over every step (docs §4, "Proper time per node")."""
        if not self.clocks:
            return {}
        return {"proper_time": ("proper time τ = ∫ dτ of each node since t = 0 (accumulated in the run, "
                                "trapezoidal rule per step)", "s")}

    def accumulator_rates(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """``dτ/dt = √(−⟨ṙ, ṙ⟩)/c`` per node, ``[*grid.shape]``, ṙ = Λ y_N the node's 4-velocity in
        the run's time t: 1/γ in the conformal–temporal gauge (ṙ⁰ = c), 1 for a run in proper time
        (``kinematic``, U = (c, 0, 0, 0)).  Λ is a Lorentz transformation, ⟨Λy, Λy⟩ = ⟨y, y⟩, so the
        rate is computed from y_N = N[..., 0:4] alone (``q`` unused), in the floating-point order of
        the compiled rate (:func:`nambu_goto_proper_time_rate`): the two paths agree bit for bit."""
        y = np.asarray(N, dtype=float)
        minus = y[..., 0] * y[..., 0] - y[..., 1] * y[..., 1] - y[..., 2] * y[..., 2] - y[..., 3] * y[..., 3]
        return {"proper_time": np.sqrt(np.maximum(minus, 0.0)) / self.c}

    def kinetic_metric(self) -> np.ndarray:
        """``M = μ diag(−1, 1, 1, 1, 0₆)``, shape ``(10, 10)`` (K = ½μ⟨y_N, y_N⟩_M)."""
        return np.diag(self.inertia())

    def inertia(self) -> np.ndarray:
        """Diagonal of the kinetic metric, ``μ(−1, 1, 1, 1, 0₆)``, shape ``(10,)``."""
        return np.concatenate([self.mu * _ETA, np.zeros(6)])

    def rest_strain(self) -> np.ndarray:
        """Strain of a straight string along e₁ at rest, ``φ = (0, 1, 0, 0)``, shape ``(1, 10)``
        (not stress-free: the string is always under tension T)."""
        X0 = np.zeros((1, 10))
        X0[0, 1] = 1.0
        return X0

    def point_kernels(self) -> MediumKernels:
        """The Nambu–Goto point kernels (parameters (T, c)); with ``clocks=True`` also the rate of the
        proper time (:func:`nambu_goto_proper_time_rate`), which runs the clocks in the compiled loops."""
        if not self.clocks:
            return MediumKernels(nambu_goto_energy, nambu_goto_stress, np.array([self.tension]))
        return MediumKernels(nambu_goto_energy, nambu_goto_stress, np.array([self.tension, self.c]),
                             accumulator_rate=nambu_goto_proper_time_rate)

    def check_support(self, support: Any, end: str) -> None:
        """Refuse an end of the Nambu–Goto string that holds the time component U₀ = ∂_t r⁰.

        A :class:`cartan.Clamped` end (N = 0), or a :class:`cartan.Held` end whose components
        include 0, holds the end's event r = (ct, x⃗) instead of its position x⃗: r⁰ stops while
        the rest of the string runs on in the temporal gauge r⁰ = ct, which breaks the Virasoro
        constraints (residual ≈ 1, docs/media/relativistic-rod.md §3 "Fixed ends") and the
        energy balance.  The fixed end is ``cartan.Held(components=(1, …, 9))``
        (:func:`cartan_relativistic.fixed.fixed_end`).  The elastic string (``energy="elastic"``,
        temporal gauge with the run's time the lab time) accepts every support.

        Raises
        ------
        ValueError
            For such an end of the Nambu–Goto string, naming ``boundaries[end]``.
        """
        if self.energy != "nambu-goto":
            return
        holds_time = isinstance(support, cartan.Clamped) or (
            isinstance(support, cartan.Held) and 0 in support.components)
        if holds_time:
            raise ValueError(
                f"boundaries[{end!r}]: a {support.kind} end of the Nambu–Goto string (relativistic-rod, "
                "energy='nambu-goto') holds the time component U₀ = ∂_t r⁰ (component 0), which is not a solution "
                "(Virasoro residual ≈ 1, energy not conserved); an end fixed in space is "
                "cartan.Held(components=(1, 2, 3, 4, 5, 6, 7, 8, 9)) = cartan_relativistic.fixed.fixed_end() "
                "(scene: { kind = \"held\", components = [1, 2, 3, 4, 5, 6, 7, 8, 9] })")

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial Φ and N of a string in conformal–temporal gauge (r⁰ = 0, ∂_t r⁰ = c).

        ``"loop"`` (periodic grid): :func:`loop_exact` at t = 0 with ``radius`` R =
        L/(2πγ) (fixed by the grid: the energy is μc²L), ``tilt`` ψ (default 0: the circular
        loop released from rest) and ``boost`` β (default 0) along e₃, ``center`` (3,).

        ``"straight"``: a straight segment along e₁ at rest, |∂_u x| = 1 (the rest strain),
        with ``origin`` (3,); its free ends are not a solution of the constraints (the ends of a
        free Nambu–Goto string move at c), so it is for fixed ends
        (:func:`cartan_relativistic.fixed.fixed_end`: at rest, an equilibrium) or kinematics.  ``boost``
        β ∈ (−1, 1) (default 0) gives the same rod seen from a frame moving at −βc along e₁:
        Φ = B(η)·Φ_rest with B(η) the boost of rapidity η = atanh β (the frame Λ = B(η) is the
        rod's rest frame, the events r = B(η)(0, u, 0, 0) are simultaneous in it, not in the
        lab) and N = {U; 0}, U = (c, 0, 0, 0): the rod in inertial motion at βc along its axis,
        for the ``kinematic`` integrator in proper time (lab length L₀/γ, energy γμc²L₀).

        ``"standing"`` (open grid, for fixed ends, :func:`cartan_relativistic.fixed.fixed_end`):
        the exact standing wave of :func:`cartan_relativistic.fixed.fixed_standing_wave` at
        t = 0, released from rest with the tangent angle ``angle`` θ₀ cos(πu/L) (θ₀ ∈ (0, 1],
        default 0.8), its ends at ``origin`` and origin + L J₀(θ₀) e₁.

        ``"plucked"`` (open grid, for fixed ends): the triangle of
        :func:`cartan_relativistic.fixed.plucked` at rest, apex ``height`` H (default 0.2 L) at
        u = ``at``·L (default 0.5), from ``origin``.

        Parameters
        ----------
        grid : cartan.Grid
            d = 1.
        kind : str
        **params
            As above.

        Returns
        -------
        cartan.InitialState
            ``Phi`` ``(n, 5, 5)`` with Λ = I, ``N`` ``(n, 10)``.
        """
        if grid.d != 1:
            raise ValueError(f"{self.name} needs a grid with d = 1, got d = {grid.d}")
        if kind in ("standing", "plucked"):
            if grid.periodic[0]:
                raise ValueError(f"initial kind {kind!r} needs an open grid (a string between two fixed ends)")
            build = self._standing if kind == "standing" else self._plucked
            check_keywords(kind, build, params)
            x, v = build(grid, **params)
        elif kind == "loop":
            check_keywords(kind, self._loop, params)
            x, v = self._loop(grid, **params)
        elif kind == "straight":
            boost = params.pop("boost", 0.0)
            check_keywords(kind, self._straight, params, extra=("boost",))
            beta = float(check_finite("boost", boost, ()))
            if not -1.0 < beta < 1.0:
                raise ValueError(f"boost must be in (−1, 1) (a speed in units of c), got {boost!r}")
            x, v = self._straight(grid, **params)
            init = self.state_from(x, v)
            if beta == 0.0:
                return init
            xi = np.zeros(10)
            xi[4] = math.atanh(beta)  # the boost B(η) along e₁, rapidity η = atanh β
            Phi = np.einsum("ij,njk->nik", self.group.exp(xi), init.Phi)
            return InitialState(Phi=Phi, N=init.N)
        else:
            return super().initial_state(grid, kind, **params)
        return self.state_from(x, v)

    def state_from(self, x: np.ndarray, v: np.ndarray, t: float = 0.0) -> InitialState:
        """Φ = (r; I) with r = (ct, x) and N = (c, v, 0₆) from lab positions and velocities ``(n, 3)``."""
        x = check_finite("positions", x)
        v = check_finite("velocities", v, x.shape)
        n = x.shape[0]
        Phi = np.zeros((n, 5, 5))
        Phi[:, 0, 0] = 1.0
        Phi[:, 1, 0] = self.c * t
        Phi[:, 2:, 0] = x
        Phi[:, 1:, 1:] = np.eye(4)
        N = np.zeros((n, 10))
        N[:, 0] = self.c
        N[:, 1:4] = v
        return InitialState(Phi=Phi, N=N)

    def _loop(self, grid, tilt=0.0, boost=0.0, center=None):
        if not grid.periodic[0]:
            raise ValueError("initial kind 'loop' needs a periodic grid (a closed string)")
        psi = float(check_finite("tilt", tilt, ()))
        beta = float(check_finite("boost", boost, ()))
        if not -1.0 < beta < 1.0:
            raise ValueError(f"boost must be in (−1, 1) (a speed in units of c), got {boost!r}")
        if beta != 0.0 and psi != 0.0:
            raise ValueError("boost needs tilt = 0 (only the planar loop stays in temporal gauge when boosted)")
        o = np.zeros(3) if center is None else check_finite("center", center, (3,))
        gamma = 1.0 / math.sqrt(1.0 - beta * beta)
        R = grid.length[0] / (2 * math.pi * gamma)
        x, v = loop_exact(grid.coordinates(0), 0.0, R, self.c, psi, beta)
        return x + o, v

    def _standing(self, grid, angle=0.8, origin=None):
        from .fixed import fixed_standing_wave

        theta0 = float(check_finite("angle", angle, ()))
        if not 0.0 < theta0 <= 1.0:
            raise ValueError(f"angle must be in (0, 1] (the tangent angle at the ends, radians), got {angle!r}")
        o = np.zeros(3) if origin is None else check_finite("origin", origin, (3,))
        x, v = fixed_standing_wave(grid.coordinates(0), 0.0, theta0, grid.length[0], self.c)
        return x + o, v

    def _plucked(self, grid, height=None, at=0.5, origin=None):
        from .fixed import plucked

        L = grid.length[0]
        H = 0.2 * L if height is None else float(check_finite("height", height, ()))
        o = np.zeros(3) if origin is None else check_finite("origin", origin, (3,))
        x = plucked(grid.coordinates(0), L, H, float(check_finite("at", at, ())))
        return x + o, np.zeros_like(x)

    def _straight(self, grid, origin=None):
        o = np.zeros(3) if origin is None else check_finite("origin", origin, (3,))
        u = grid.coordinates(0)
        x = o + np.stack([u, np.zeros_like(u), np.zeros_like(u)], axis=-1)
        return x, np.zeros_like(x)

    # ------------------------------------------------------------------ outputs
    def lab_events(self, q: np.ndarray, N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Events r ``[..., 4]`` and ∂_t r = Λ y_N ``[..., 4]`` in the lab frame."""
        q = np.asarray(q, dtype=float)
        r = q[..., 1:, 0]
        rdot = np.einsum("...ij,...j->...i", q[..., 1:, 1:], np.asarray(N, dtype=float)[..., :4])
        return r, rdot

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """Lab positions and times per node, γ, and the Poincaré charges (energy, momentum,
        angular momentum: the conserved quantities of the Polyakov action, docs "Outputs")."""
        c, mu = self.c, self.mu
        r, rdot = self.lab_events(q, N)
        w = grid.node_weights()
        P = mu * np.tensordot(w, rdot, axes=1)  # contravariant 4-momentum Σ w μ ∂_t r
        x, p = r[..., 1:], mu * rdot[..., 1:]
        J = np.tensordot(w, np.cross(x, p), axes=1)
        rprime = np.einsum("...ij,...j->...i", q[..., 1:, 1:], np.asarray(X, dtype=float)[..., 0, :4])
        eta = _ETA
        dot = np.abs(np.einsum("...i,i,...i->...", rdot, eta, rprime))
        con = np.abs(np.einsum("...i,i,...i->...", rdot, eta, rdot) + c * c * np.einsum(
            "...i,i,...i->...", rprime, eta, rprime))
        speed2 = np.sum(rdot[..., 1:] ** 2, axis=-1) * (c / np.maximum(rdot[..., 0], 1e-300)) ** 2
        gamma = 1.0 / np.sqrt(np.maximum(1.0 - speed2 / c**2, 1e-300))
        return {
            "energy": c * P[0],
            "momentum_x": P[1], "momentum_y": P[2], "momentum_z": P[3],
            "angular_momentum_x": J[0], "angular_momentum_y": J[1], "angular_momentum_z": J[2],
            "coordinate_time": r[..., 0] / c,
            "lab_x": x[..., 0], "lab_y": x[..., 1], "lab_z": x[..., 2],
            "lorentz_factor": gamma,
            "virasoro_residual": float(max(np.max(dot) * c, np.max(con)) / c**2),
        }

    # ------------------------------------------------------------------ pictures
    @classmethod
    def draw(cls, ds: Any, fig: Any) -> bool:
        """The lab-frame picture of a run for ``cartan plot`` (:meth:`cartan.medium.Medium.draw`):
        the string at equal lab times and the worldlines of a few material points
        (:func:`cartan_relativistic.pictures.draw_figure`); False for a result without the
        lab-frame outputs over two frames or more, which gets the generic picture."""
        from .pictures import draw_figure

        return draw_figure(ds, fig)
