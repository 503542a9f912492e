"""The O(n+1) nonlinear sigma model as a Cartan medium (paper §VIII.B).

A field ``n : W → Sⁿ ⊂ R^{n+1}`` on the base ``W = [0, T] × M`` (M a box of dimension
d = 1, 2, 3, each axis open or periodic) is written ``n = Φ n₀`` with a structure field
``Φ : W → SO(n+1)`` and the reference point ``n₀ = e_{n+1}`` (the last basis vector; the
space is :class:`cartan.spaces.Sphere`).  The configuration space is X = Sⁿ, the symmetry
group G = SO(n+1) of dimension r = n(n+1)/2, and the stabiliser SO(n) of n₀ is a gauge.

Reduced Lagrangian
------------------
With ``N = Φ⁻¹∂_tΦ`` and ``X_α = Φ⁻¹∂_αΦ``, ``∂_t n = Φ N̂ n₀`` and ``∂_α n = Φ X̂_α n₀``, so
``|∂_t n|² = ⟨N, 𝒜N⟩`` with the operator 𝒜 of §VIII.B defined by
``⟨Z, 𝒜Z⟩ = n₀ᵀẐᵀẐn₀``.  In cartan's so(n+1) basis (:mod:`cartan.groups.son`) the first n
generators rotate n₀ into an orthonormal frame of its tangent space and the remaining
n(n−1)/2 fix it, so ``𝒜 = diag(1, …, 1, 0, …, 0)`` with n ones (checked on construction).
The medium's Lagrangian density, with a stiffness K (the 1/g² of the field theory) and a
wave speed c, is

    ℓ(N, X) = ½ (K/c²) ⟨N, 𝒜N⟩ − ½ K Σ_α ⟨X_α, 𝒜X_α⟩,

i.e. ``½(K/c²)|∂_t n|² − ½K|∇n|²``; K = c = 1 is the paper's ``½(|∂_t n|² − |∇n|²)``
(wave maps).  Hence ``S = (K/c²) 𝒜N`` and ``Q^α = K 𝒜X_α`` (§VIII.B), and the balance law
``Ṡ + ad*_N S = ∂_αQ^α + ad*_{X_α}Q^α`` is the wave-map equation
``∂_t²n/c² − Δn = (|∇n|² − |∂_tn|²/c²) n``.

Gauge
-----
The gauge components of N (k ≥ n) carry no kinetic energy (``inertia()`` is 0 there) and
are held at zero by the schemes (temporal gauge): Φ is then parallel-transported in time.
The gauge components of X are the connection of the frame field; they do not enter the
continuum energy.  (The lattice's discrete energy ``Σ_e h^d U(log G_e / h)`` depends on the
relative gauge of neighbouring frames at O(h²); frames built by the initial-state helpers
below vary smoothly, so that term is a consistent discretisation error.)

Harmonic-map flow
-----------------
The dissipative flow ``γ ∂_t n = K(Δn + |∇n|²n)`` is the overdamped limit with a drag γ on
the moving components: a core :class:`~cartan.problem.Damping` load with coefficients
``γ𝒜`` (:meth:`SigmaModel.harmonic_map_damping`) run by the ``overdamped`` integrator.

Initial data (:meth:`SigmaModel.initial_state`)
-----------------------------------------------
``"great-circle"`` a field on the great circle through n₀ and a tangent ``direction``, with
angle profile φ and optional angular rate (a travelling wave ``n = f(u ∓ ct)`` on request);
``"uniform"``; ``"field"`` (given points, lifted with :meth:`Sphere.lift`); ``"random-smooth"``;
``"lump"`` (n = 2, d = 2: the Belavin–Polyakov lump, see :func:`lump_frames`).

Outputs
-------
:meth:`SigmaModel.energy_density` and :func:`energy_density` (also from a run's Dataset),
:func:`topological_charge` (n = 2, d = 2; Berg–Lüscher) and :func:`great_circle_angle`.
"""

from __future__ import annotations

import json
import math
import numbers
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from cartan.medium import QuadraticMedium, check_finite, check_keywords, check_positive
from cartan.problem import Damping, InitialState
from cartan.spaces import Sphere

__all__ = [
    "SigmaModel",
    "energy_density",
    "great_circle_angle",
    "lump_field",
    "lump_frames",
    "topological_charge",
]


# ====================================================================== validation helpers
def _int_param(name: str, value: Any, allowed: str, ok: Callable[[int], bool]) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not ok(int(value)):
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return int(value)


def _positive(name: str, value: Any) -> float:
    return float(check_positive(name, value, shape=()))


def _node_coordinates(grid) -> list[np.ndarray]:
    """Node coordinates as d arrays of shape ``grid.shape`` (``indexing="ij"``)."""
    return list(np.meshgrid(*[grid.coordinates(a) for a in range(grid.d)], indexing="ij"))


def _nodal(name: str, value: Any, grid, trailing: tuple = ()) -> np.ndarray:
    """A scalar, an array broadcastable to ``(*grid.shape, *trailing)``, or a callable of the
    node coordinates ``f(u)`` (d = 1), ``f(u, v)`` (d = 2), ``f(u, v, w)`` (d = 3)."""
    if callable(value):
        value = value(*_node_coordinates(grid))
    arr = check_finite(name, value)
    target = (*grid.shape, *trailing)
    try:
        return np.broadcast_to(arr, target).astype(float, copy=True)
    except ValueError:
        raise ValueError(f"{name} must broadcast to shape {target}, got shape {arr.shape}") from None


# ====================================================================== the medium
class SigmaModel(QuadraticMedium):
    """The O(n+1) nonlinear sigma model: wave maps and harmonic-map flow into Sⁿ (§VIII.B).

    Parameters
    ----------
    n : int, default 2
        Dimension of the target sphere Sⁿ (integer ≥ 2); the group is SO(n+1).
    d : int, default 1
        Dimension of the material base space (1, 2 or 3).
    stiffness : float, default 1
        K > 0, the energy of a unit gradient per unit volume (1/g² of the field theory).
    speed : float, default 1
        c > 0, the wave speed; the kinetic metric is K/c² on the moving components.

    Attributes
    ----------
    n, material_dim, speed : the parameters n, d, c
    stiffness_value : float
        K (``stiffness()`` is the Medium method returning the Hessian ∂Q/∂X).
    space : cartan.spaces.Sphere
        Sⁿ with ``q_r = n₀ = e_{n+1}``; ``group`` is its SO(n+1).

    Notes
    -----
    Components of N, X in so(n+1) follow :mod:`cartan.groups.son` (for n = 2: the SO3 hat
    map, ``X = (X₁, X₂, X₃)`` with ``∂_α n = Φ (X₂, −X₁, 0)`` for n₀ = e₃).  The first n
    components move n₀, the last n(n−1)/2 are gauge.  ``material_dim`` is set per instance
    (it is the parameter d).
    """

    name: ClassVar[str] = "sigma-model"
    #: U = ½K Σ_α |X_α|²_𝒜 is a sum over axes: the lattice scheme runs it for d ≥ 2
    separable_axes: ClassVar[bool] = True
    load_kinds: ClassVar[tuple[str, ...]] = ("drag",)
    initial_kinds: ClassVar[tuple[str, ...]] = ("great-circle", "uniform", "field", "random-smooth", "lump")

    def __init__(self, n: int = 2, d: int = 1, stiffness: float = 1.0, speed: float = 1.0):
        self.n = _int_param("n", n, "an integer ≥ 2 (the target sphere Sⁿ)", lambda v: v >= 2)
        self.material_dim = _int_param("d", d, "1, 2 or 3 (the material dimension)", lambda v: v in (1, 2, 3))
        self.stiffness_value = _positive("stiffness", stiffness)
        self.speed = _positive("speed", speed)
        self.space = Sphere(n=self.n)
        self.group = self.space.group
        self._A = self._projector()
        self._moving = self._A > 0
        # U = ½K Σ_α ⟨X_α, 𝒜X_α⟩ = ½K|∇n|²: quadratic with X₀ = 0 and C = K𝒜 on every axis
        self._set_energy(np.zeros((self.material_dim, self.group.dim)), self.stiffness_value * self._A)
        # per-frame outputs recorded by cartan.simulate (see outputs())
        self.output_fields = {"energy_density": ("energy density ½(K/c²)|∂ₜn|² + ½K|∇n|²", "energy")}
        if self.n == 2 and self.material_dim == 2:
            self.output_fields["topological_charge"] = (
                "Berg–Lüscher topological charge (an integer on periodic grids)", "1")

    def _projector(self) -> np.ndarray:
        """Diagonal of 𝒜 from ``⟨b_k, 𝒜 b_l⟩ = (b̂_k n₀)·(b̂_l n₀)``; checked to be a 0/1 diagonal."""
        g = self.group
        T = g.hat(np.eye(g.dim)) @ self.space.q_r  # (r, n+1): b̂_k n₀
        gram = T @ T.T
        A = np.diag(gram).copy()
        expected = np.zeros(g.dim)
        expected[: self.n] = 1.0
        if not (np.allclose(gram, np.diag(expected), atol=1e-14)):
            raise RuntimeError(f"the basis of {g.name} does not put the {self.n} generators moving n₀ first")
        return A

    # ------------------------------------------------------------------ parameters
    def parameters(self) -> dict[str, Any]:
        """``{"n", "d", "stiffness", "speed"}``; ``SigmaModel(**parameters())`` rebuilds the medium."""
        return {"n": self.n, "d": self.material_dim, "stiffness": self.stiffness_value, "speed": self.speed}

    @property
    def projector(self) -> np.ndarray:
        """Diagonal of 𝒜, shape ``(r,)``: 1 on the n components that move n₀, 0 on the gauge."""
        return self._A.copy()

    @property
    def density(self) -> float:
        """Kinetic metric K/c² on the moving components."""
        return self.stiffness_value / self.speed**2

    # ------------------------------------------------------------------ Medium contract
    def inertia(self) -> np.ndarray:
        """``(K/c²) 𝒜``, shape ``(r,)``: zeros mark the gauge components."""
        return self.density * self._A

    def wave_speed(self) -> float:
        """c."""
        return self.speed

    # ------------------------------------------------------------------ loads
    def harmonic_map_damping(self, gamma: float | None = None) -> Damping:
        """The drag of the harmonic-map flow: ``Damping(γ𝒜)``, default γ = K (unit diffusivity,
        ``∂_t n = Δn + |∇n|²n``).  Run it with the ``overdamped`` integrator."""
        gam = self.stiffness_value if gamma is None else _positive("gamma", gamma)
        return Damping(gam * self._A)

    def make_load(self, kind: str, **params: Any):
        """``"drag"``: :meth:`harmonic_map_damping` with the optional parameter ``gamma``."""
        if kind == "drag":
            unknown = set(params) - {"gamma"}
            if unknown:
                raise ValueError(f"load 'drag' takes only the parameter 'gamma', got {sorted(params)}")
            return self.harmonic_map_damping(params.get("gamma"))
        return super().make_load(kind, **params)

    # ------------------------------------------------------------------ fields and outputs
    def field(self, Phi: np.ndarray) -> np.ndarray:
        """``n = Φ n₀``: the last column of Φ, ``[..., n+1, n+1]`` → ``[..., n+1]``."""
        return np.asarray(Phi, dtype=float)[..., :, -1].copy()

    def body_velocity(self, Phi: np.ndarray, ndot: np.ndarray) -> np.ndarray:
        """Body velocity N ``[..., r]`` (gauge components zero) of a tangent field ``∂_t n``.

        ``∂_t n = Φ N̂ n₀`` and the ``b̂_k n₀`` (k < n) are orthonormal, so
        ``N_k = (b̂_k n₀)·(Φᵀ ∂_t n)``.  ``ndot`` must be tangent to the sphere at n = Φn₀.
        """
        Phi = np.asarray(Phi, dtype=float)
        ndot = np.asarray(ndot, dtype=float)
        nvec = Phi[..., :, -1]
        normal = np.einsum("...i,...i->...", nvec, ndot)
        scale = max(1.0, float(np.max(np.abs(ndot)))) if ndot.size else 1.0
        if np.any(np.abs(normal) > 1e-8 * scale):
            raise ValueError(
                f"velocity must be tangent to the sphere (∂_t n · n = 0); largest normal part "
                f"{float(np.max(np.abs(normal))):.3g}"
            )
        T = self.group.hat(np.eye(self.group.dim)) @ self.space.q_r  # (r, n+1)
        body = np.einsum("...ji,...j->...i", Phi, ndot)
        return np.einsum("ki,...i->...k", T, body) * self._A

    def energy_density(self, N: np.ndarray, X: np.ndarray, parts: bool = False):
        """Energy density ``½(K/c²)|∂_t n|² + ½K|∇n|²`` from nodal N ``[..., r]`` and X ``[..., d, r]``.

        Returns ``[...]`` (or the pair ``(kinetic, potential)`` when ``parts``).
        """
        k = self.kinetic(np.asarray(N, dtype=float))
        u = self.potential(X)
        return (k, u) if parts else k + u

    def outputs(self, q, X, N, grid) -> dict[str, Any]:
        """Energy density at the nodes and, for n = 2, d = 2, the Berg–Lüscher charge of the
        field q (periodic in both axes: an integer; otherwise the charge of the open lattice)."""
        out = {"energy_density": self.energy_density(N, X)}
        if "topological_charge" in self.output_fields:
            out["topological_charge"] = topological_charge(q, periodic=all(grid.periodic))
        return out

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial structure field Φ and velocity N on ``grid`` from a named kind.

        Every kind also accepts ``velocity``: a tangent field ``∂_t n`` at the nodes (a
        callable of the node coordinates or an array ``[*grid.shape, n+1]``), added to the
        kind's own velocity.

        ``"great-circle"``
            ``n = cos φ n₀ + sin φ e`` on the great circle through n₀ and the unit tangent
            ``direction`` e (default e₁), ``Φ = exp(φ ξ_e)`` with ``ξ_e = vee(e n₀ᵀ − n₀ eᵀ)``
            (smooth for any φ, windings included).  ``angle`` φ (callable of the node
            coordinates, array or scalar); ``rate`` ∂_tφ (default 0); ``travelling``
            ``"right"``/``"left"`` adds ``∂_tφ = ∓c ∂_uφ`` along ``axis`` (default 0), with
            ``slope`` ∂_uφ given (callable or array): then φ(u, t) = φ₀(u ∓ ct) solves the
            wave map exactly.  On a periodic axis a callable φ must close up to a multiple of
            2π (checked).
        ``"uniform"``
            ``point`` (unit vector, default n₀) at every node, lifted by the sphere's section.
        ``"field"``
            ``field`` ``[*grid.shape, n+1]`` (or a callable returning it): points of the
            sphere, lifted with :meth:`cartan.spaces.Sphere.lift` (``gauge`` optional).
        ``"random-smooth"``
            ``Φ = exp(ξ(u)) exp(η(u))``: ξ a random smooth moving-component field (a few
            Fourier modes per axis, ``modes`` = 2, ``amplitude`` = 0.5, ``seed`` = 0), η a random
            smooth gauge field (``gauge_amplitude``, default 0); velocity amplitude
            ``velocity_amplitude`` (default 0).  Periodic on every periodic axis.
        ``"lump"``
            n = 2, d = 2: :func:`lump_frames` with ``charge``, ``size``, ``center``, ``phase``,
            ``cutoff``.
        """
        if grid.d != self.material_dim:
            raise ValueError(f"{self.name} with d = {self.material_dim} needs a grid with d = {self.material_dim}, "
                             f"got d = {grid.d}")
        velocity = params.pop("velocity", None)
        builders = {
            "great-circle": self._great_circle,
            "uniform": self._uniform,
            "field": self._field,
            "random-smooth": self._random_smooth,
            "lump": self._lump,
        }
        if kind not in builders:
            return super().initial_state(grid, kind, **params)
        check_keywords(kind, builders[kind], params, ("velocity",))
        Phi, N = builders[kind](grid, **params)
        if velocity is not None:
            ndot = _nodal("velocity", velocity, grid, (self.n + 1,))
            N = N + self.body_velocity(Phi, ndot)
        return InitialState(Phi=Phi, N=N)

    def _tangent(self, direction: Any) -> np.ndarray:
        m = self.n + 1
        if direction is None:
            e = np.zeros(m)
            e[0] = 1.0
            return e
        e = check_finite("direction", direction, (m,))
        if abs(e[-1]) > 1e-12 * max(1.0, float(np.linalg.norm(e))):
            raise ValueError(f"direction must be tangent at n₀ = e_{m} (last component 0), got {e.tolist()}")
        norm = float(np.linalg.norm(e))
        if norm == 0.0:
            raise ValueError("direction must be a non-zero vector")
        return e / norm

    def _generator(self, e: np.ndarray) -> np.ndarray:
        """Components of ``e n₀ᵀ − n₀ eᵀ``: exp(φ ξ) n₀ = cos φ n₀ + sin φ e."""
        n0 = self.space.q_r
        return self.group.vee(np.outer(e, n0) - np.outer(n0, e))

    def _great_circle(self, grid, angle=0.0, rate=0.0, slope=None, travelling=None, axis=0, direction=None):
        axis = _int_param("axis", axis, f"an axis index in 0..{grid.d - 1}", lambda a: 0 <= a < grid.d)
        xi = self._generator(self._tangent(direction))
        phi = _nodal("angle", angle, grid)
        if callable(angle):
            for a in range(grid.d):
                if not grid.periodic[a]:
                    continue
                coords = _node_coordinates(grid)
                coords[a] = coords[a] + grid.length[a]
                jump = (check_finite("angle", angle(*coords)) - phi) / (2 * math.pi)
                if np.max(np.abs(jump - np.round(jump))) > 1e-8:
                    raise ValueError(
                        f"angle must satisfy φ(u + L) = φ(u) + 2πm on the periodic axis {a} "
                        f"(the field would not close)"
                    )
        dphi = _nodal("rate", rate, grid)
        if travelling is not None:
            signs = {"right": 1.0, "left": -1.0, 1: 1.0, -1: -1.0}
            if isinstance(travelling, bool) or travelling not in signs:
                raise ValueError(f"travelling must be 'right', 'left' or None, got {travelling!r}")
            if slope is None:
                raise ValueError("travelling needs slope = ∂φ/∂u along the axis (callable or array)")
            dphi = dphi - signs[travelling] * self.speed * _nodal("slope", slope, grid)
        elif slope is not None:
            raise ValueError("slope is used only with travelling='right' or 'left'")
        Phi = self.group.exp(phi[..., None] * xi)
        N = dphi[..., None] * xi
        return Phi, N

    def _uniform(self, grid, point=None):
        q = self.space.q_r if point is None else check_finite("point", point, (self.n + 1,))
        norm = float(np.linalg.norm(q))
        if not abs(norm - 1.0) <= 1e-8:
            raise ValueError(f"point must be a unit vector (a point of S^{self.n}), got |point| = {norm:.6g}")
        Phi = np.broadcast_to(self.space.lift(q / norm), (*grid.shape, self.n + 1, self.n + 1)).copy()
        return Phi, np.zeros((*grid.shape, self.group.dim))

    def _field(self, grid, field=None, gauge=None):
        if field is None:
            raise ValueError("initial kind 'field' needs field = points of the sphere [*grid.shape, n+1]")
        q = _nodal("field", field, grid, (self.n + 1,))
        g = None if gauge is None else _nodal("gauge", gauge, grid, (self.space.gauge_dim,))
        try:
            Phi = self.space.lift(q, gauge=g)
        except ValueError as exc:
            raise ValueError(f"field: {exc}") from None
        return Phi, np.zeros((*grid.shape, self.group.dim))

    def _random_smooth(self, grid, amplitude=0.5, modes=2, seed=0, gauge_amplitude=0.0, velocity_amplitude=0.0):
        amp = float(check_positive("amplitude", amplitude, allow_zero=True, shape=()))
        gamp = float(check_positive("gauge_amplitude", gauge_amplitude, allow_zero=True, shape=()))
        vamp = float(check_positive("velocity_amplitude", velocity_amplitude, allow_zero=True, shape=()))
        modes = _int_param("modes", modes, "an integer ≥ 1", lambda v: v >= 1)
        rng = np.random.default_rng(seed)
        r = self.group.dim
        coords = _node_coordinates(grid)

        def smooth(mask: np.ndarray, scale: float) -> np.ndarray:
            out = np.zeros((*grid.shape, r))
            ks = np.array(np.meshgrid(*[np.arange(modes + 1)] * grid.d, indexing="ij")).reshape(grid.d, -1).T
            for k in ks:
                arg = sum(2 * math.pi * k[a] * coords[a] / grid.length[a] for a in range(grid.d))
                c = rng.standard_normal((2, r)) * mask / (1.0 + float(np.sum(k**2)))
                out += np.cos(arg)[..., None] * c[0] + np.sin(arg)[..., None] * c[1]
            peak = float(np.max(np.linalg.norm(out, axis=-1)))
            return out * (scale / peak) if peak > 0 else out

        xi = smooth(self._A, amp)
        eta = smooth(1.0 - self._A, gamp)
        Phi = self.group.compose(self.group.exp(xi), self.group.exp(eta))
        N = smooth(self._A, vamp)
        return Phi, N

    def _lump(self, grid, charge=1, size=None, center=None, phase=0.0, cutoff=None):
        if self.n != 2:
            raise ValueError(f"initial kind 'lump' needs the O(3) model (n = 2), got n = {self.n}")
        Phi = lump_frames(grid, charge=charge, size=size, center=center, phase=phase, cutoff=cutoff)
        return Phi, np.zeros((*grid.shape, self.group.dim))


# ====================================================================== lumps (n = 2, d = 2)
def _smooth_step(t: np.ndarray) -> np.ndarray:
    """C^∞ step: 0 for t ≤ 0, 1 for t ≥ 1."""
    t = np.clip(t, 0.0, 1.0)
    with np.errstate(divide="ignore", over="ignore"):
        a = np.where(t > 0, np.exp(-1.0 / np.where(t > 0, t, 1.0)), 0.0)
        b = np.where(t < 1, np.exp(-1.0 / np.where(t < 1, 1.0 - t, 1.0)), 0.0)
    return a / (a + b)


def _lump_geometry(grid, charge, size, center, phase, cutoff):
    if grid.d != 2:
        raise ValueError(f"a lump lives on a grid with d = 2, got d = {grid.d}")
    Q = _int_param("charge", charge, "a non-zero integer", lambda v: v != 0)
    Lmin = min(grid.length)
    lam = 0.1 * Lmin if size is None else _positive("size", size)
    z0 = complex(*(0.5 * np.asarray(grid.length))) if center is None else complex(*check_finite("center", center, (2,)))
    alpha = float(check_finite("phase", phase, ()))
    if cutoff is None:
        r2 = 0.45 * Lmin
        r1 = 0.5 * r2
    else:
        r1, r2 = (float(v) for v in check_finite("cutoff", cutoff, (2,)))
        if not 0 < r1 < r2:
            raise ValueError(f"cutoff must be (r1, r2) with 0 < r1 < r2, got {cutoff!r}")
    if r2 > 0.5 * Lmin and any(grid.periodic):
        raise ValueError(f"cutoff radius r2 = {r2:g} must be ≤ half the box side {0.5 * Lmin:g} on a periodic grid")
    if not lam < r2:
        raise ValueError(f"size must be smaller than the cutoff radius r2 = {r2:g}, got {lam:g}")
    return Q, lam, z0, alpha, r1, r2


def _torus_offset(z: np.ndarray, z0: complex, grid) -> np.ndarray:
    """z − z0 reduced to the nearest periodic image on periodic axes."""
    dz = z - z0
    x, y = dz.real, dz.imag
    if grid.periodic[0]:
        x = x - grid.length[0] * np.round(x / grid.length[0])
    if grid.periodic[1]:
        y = y - grid.length[1] * np.round(y / grid.length[1])
    return x + 1j * y


def _spinor(grid, Q, lam, z0, alpha, r1, r2):
    """Normalised spinor (a, b) of the lump: W = a/b, n₁ + i n₂ = 2āb, n₃ = |a|² − |b|²."""
    X, Y = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    dz = _torus_offset(X + 1j * Y, z0, grid)
    chi = _smooth_step((r2 - np.abs(dz)) / (r2 - r1))
    base = (dz / lam) ** abs(Q)
    a = np.exp(1j * alpha) * (base if Q > 0 else np.conj(base))  # arg a = Q arg(z − z₀) + α
    b = chi.astype(complex)
    norm = np.sqrt(np.abs(a) ** 2 + np.abs(b) ** 2)
    return a / norm, b / norm, dz


def lump_field(grid, charge: int = 1, size: float | None = None, center: Any = None, phase: float = 0.0,
               cutoff: Any = None) -> np.ndarray:
    """The Belavin–Polyakov lump of charge Q as a field ``n`` ``[nx, ny, 3]`` (vacuum n₀ = e₃).

    In the stereographic coordinate from the vacuum, ``W = (n₁ − i n₂)/(1 − n₃)``, the lump is
    ``W = e^{iα}((z − z₀)/λ)^Q`` (``(z̄ − z̄₀)`` for Q < 0), z = u + iv; its Berg–Lüscher charge
    (:func:`topological_charge`) is Q.  It is cut off smoothly, ``W ← W/χ(r)`` with a C^∞
    χ = 1 for r ≤ r1 and 0 for r ≥ r2 (r = |z − z₀|, nearest periodic image): the exact lump
    inside r1, exactly the vacuum beyond r2, hence smooth and periodic when r2 ≤ half the box
    side.  ``size`` λ defaults to 0.1 of the smaller side, ``center`` z₀ to the box centre,
    ``phase`` α to 0 and ``cutoff`` (r1, r2) to (0.225, 0.45) × the smaller side.  The BP lump
    has energy 4π|Q|K; the cut-off tail (∝ λ²/r1² for |Q| = 1) adds to it.
    """
    a, b, _ = _spinor(grid, *_lump_geometry(grid, charge, size, center, phase, cutoff))
    ab = np.conj(a) * b
    return np.stack([2 * ab.real, 2 * ab.imag, np.abs(a) ** 2 - np.abs(b) ** 2], axis=-1)


def _theta1(u: np.ndarray, q: float) -> np.ndarray:
    """Jacobi θ₁(u | q) = 2 Σ (−1)^k q^{(k+½)²} sin((2k+1)u) for complex u (|Im u| ≲ π)."""
    nterms = int(math.ceil(math.sqrt(80.0 / max(-math.log(q), 1e-3)))) + 4
    out = np.zeros(np.shape(u), dtype=complex)
    for k in range(nterms):
        out += (-1) ** k * q ** ((k + 0.5) ** 2) * np.sin((2 * k + 1) * u)
    return 2.0 * out


def _unit_sin(u: np.ndarray) -> np.ndarray:
    """``sin u / |sin u|`` for complex u without overflow at large |Im u|."""
    u = np.asarray(u, dtype=complex)
    up = u.imag >= 0
    w = np.where(up, u, -u)  # sin(−u) = −sin u
    unit = np.exp(-1j * w.real) * 1j * (1 - np.exp(2j * w))  # sin w = (i/2) e^{−iw}(1 − e^{2iw})
    unit = unit / np.abs(unit)
    return np.where(up, unit, -unit)


def _vortex_phase(grid, z: np.ndarray, z0: complex, points: list[complex], p: int) -> np.ndarray:
    """Unit complex ``e^{iγ} = unit(F(z)) unit(z − z0)^{−2p} e^{−iJt}``: smooth at z0 (the winding
    2p of F there is divided out), winding −sign(p) at each of the 2|p| ``points``, and
    ``unit(z − z0)^{2p} e^{iγ}`` periodic on the periodic axes.

    Built from ``F(z) = f(π(z − z0)/ω₁)^{2p} Π_k f(π(z − z_k)/ω₁)^{−sign p}`` with f = θ₁ (nome
    e^{iπτ}, τ = ω₂/ω₁) on a torus or f = sin on a cylinder (ω₁ the period of the periodic axis):
    f(u + π) = −f(u) and the charges sum to zero, so F is periodic along ω₁; along ω₂ a torus
    multiplies F by exp(2πi Σ q_k z_k/ω₁), whose phase J the linear ramp e^{−iJt} removes (t the
    coordinate along ω₂ over its period)."""
    Lx, Ly = grid.length
    px, py = grid.periodic
    if px and py:
        if Lx >= Ly:
            omega, tau, ramp_axis, L2 = Lx, 1j * Ly / Lx, 1, Ly
        else:
            omega, tau, ramp_axis, L2 = -1j * Ly, 1j * Lx / Ly, 0, Lx
        nome = math.exp(-math.pi * tau.imag)

        def phase(u):
            t = _theta1(u, nome)
            return t / np.abs(t)
    elif px or py:
        omega, phase, ramp_axis = (Lx if px else -1j * Ly), _unit_sin, None
    else:
        return np.ones(z.shape, dtype=complex)
    dz = z - z0
    small = np.abs(dz) < 1e-12 * max(Lx, Ly)
    safe = np.where(small, 1.0, dz)
    # f(u)/(z − z0) → f'(0) π/ω₁ at z0, with f'(0) > 0
    ratio = np.where(small, abs(omega) / omega, phase(np.pi * safe / omega) * np.abs(safe) / safe)
    s = -int(np.sign(p))
    out = ratio ** (2 * p)
    for zk in points:
        out = out * phase(np.pi * (z - zk) / omega) ** s
    if ramp_axis is not None:
        total = 2 * p * z0 + s * sum(points)
        jump = 2 * math.pi * (total / omega).real
        jump = (jump + math.pi) % (2 * math.pi) - math.pi
        coord = z.imag if ramp_axis == 1 else z.real  # ω₂ = iLy (ω₁ = Lx) or ω₂ = Lx (ω₁ = −iLy)
        out = out * np.exp(-1j * jump * coord / L2)
    return out


def _vortex_points(grid, z0: complex, p: int, r2: float) -> list[complex]:
    """2|p| vortex positions in the vacuum (χ = 0): at plaquette centres on a torus, outside
    the box along the open axis on a cylinder (half beyond each end)."""
    Lx, Ly = grid.length
    px, py = grid.periodic
    m = abs(p)
    if px and py:
        hx, hy = grid.spacing
        pts: list[complex] = []
        for j in range(m):
            s = (j + 1) / (2 * m + 2)
            for sign in (1, -1):
                zk = z0 + sign * (0.5 * Lx + 1j * s * Ly)
                x = (math.floor((zk.real % Lx) / hx) + 0.5) * hx
                y = (math.floor((zk.imag % Ly) / hy) + 0.5) * hy
                pts.append(complex(x, y))
        corners = np.array([c + dx + 1j * dy for c in pts for dx in (-hx / 2, hx / 2) for dy in (-hy / 2, hy / 2)])
        if np.min(np.abs(_torus_offset(corners, z0, grid))) < r2 or len(set(pts)) != len(pts):
            raise ValueError(
                "the lump leaves no room for its gauge vortices: reduce the cutoff radius or refine the grid"
            )
        return pts
    # half beyond each end of the open axis: the frames wind |p| times around the periodic axis
    # beyond either end of the lump instead of 2|p| times on one side
    far = [(Ly if px else Lx) + 0.5 * (j // 2 + 1) * (Lx if px else Ly) if j % 2 == 0
           else -0.5 * (j // 2 + 1) * (Lx if px else Ly) for j in range(2 * m)]
    return [complex(z0.real, c) if px else complex(c, z0.imag) for c in far]


def lump_frames(grid, charge: int = 1, size: float | None = None, center: Any = None, phase: float = 0.0,
                cutoff: Any = None) -> np.ndarray:
    """Structure field Φ ``[nx, ny, 3, 3]`` of the lump of :func:`lump_field` (``Φ e₃ = n``).

    Φ is built from the spinor (a, b) of the field, ``Φ = R(U)·R₃(γ)`` with
    ``U = [[a, −b̄], [b, ā]] ∈ SU(2)`` and R(U) its rotation (``R e₃ = n``): smooth across the
    lump, including its centre where n = −n₀.  A field of degree Q ≠ 0 on a closed surface
    admits no smooth frame field (the pulled-back circle bundle has Euler number 2Q), so the
    gauge rotation R₃(γ) about e₃ moves the unavoidable frame vortices into the vacuum, where
    n = n₀ exactly and the gauge carries no energy: on a periodic box 2|Q| unit vortices sit at
    plaquette centres far from the lump (γ from Jacobi θ₁ functions, periodic); on a cylinder
    they sit outside the box, half beyond each end of the open axis (γ from sines); on an open
    box R(U) is already smooth everywhere and γ = 0.  Neighbouring frames then differ by small
    rotations everywhere except around the vacuum vortices (gauge rotations ≈ π/2 per edge,
    with zero energy).
    """
    Q, lam, z0, alpha, r1, r2 = _lump_geometry(grid, charge, size, center, phase, cutoff)
    a, b, dz = _spinor(grid, Q, lam, z0, alpha, r1, r2)
    # rotation of U = [[a, −b̄], [b, ā]]: R_ij = ½ tr(σ_i U σ_j U†)
    sig = np.array([[[0, 1], [1, 0]], [[0, -1j], [1j, 0]], [[1, 0], [0, -1]]], dtype=complex)
    U = np.empty((*a.shape, 2, 2), dtype=complex)
    U[..., 0, 0], U[..., 0, 1], U[..., 1, 0], U[..., 1, 1] = a, -np.conj(b), b, np.conj(a)
    R = 0.5 * np.einsum("iab,...bc,jcd,...ed->...ij", sig, U, sig, np.conj(U)).real
    # in the vacuum (b = 0) R = R₃(−2 arg a), arg a = Q arg(z − z₀) + α: winding −2Q about z₀.
    # γ = 2Q arg(z − z₀) + (smooth) cancels it there; its own winding −2Q at z₀ is balanced by
    # 2|Q| unit vortices in the vacuum.
    P = -Q
    z = z0 + dz  # nearest image of each node around z₀
    pts = _vortex_points(grid, z0, P, r2) if any(grid.periodic) else []
    e = _vortex_phase(grid, z, z0, pts, P)
    c, s = e.real, e.imag
    Rg = np.zeros((*z.shape, 3, 3))
    Rg[..., 0, 0], Rg[..., 0, 1], Rg[..., 1, 0], Rg[..., 1, 1], Rg[..., 2, 2] = c, -s, s, c, 1.0
    return R @ Rg


# ====================================================================== outputs
def topological_charge(field: Any, density: bool = False, periodic: bool = True):
    """Berg–Lüscher topological charge of an O(3) field on a 2D lattice.

    Each plaquette (i, j) is split into the triangles (n₀₀, n₁₀, n₁₁) and (n₀₀, n₁₁, n₀₁),
    and each contributes its signed spherical area
    ``σ = 2 atan2(n₁·(n₂×n₃), 1 + n₁·n₂ + n₂·n₃ + n₃·n₁) ∈ (−2π, 2π)`` (Berg & Lüscher 1981).
    On a periodic lattice ``Q = Σσ/4π`` is an integer to round-off for every configuration
    with no exceptional triangle (σ = ±2π), whatever the resolution.

    Parameters
    ----------
    field : array ``[..., nx, ny, 3]``
        Unit vectors (leading axes, e.g. time, are batch axes).
    density : bool
        Return the per-plaquette charge ``[..., nx, ny]`` (``[..., nx−1, ny−1]`` when not
        periodic) instead of the sum.
    periodic : bool
        Close the lattice on both axes (default); otherwise sum the interior plaquettes only
        (not an integer in general).
    """
    n = check_finite("field", field)
    if n.ndim < 3 or n.shape[-1] != 3:
        raise ValueError(f"field must have shape [..., nx, ny, 3], got {n.shape}")
    if periodic:
        n10 = np.roll(n, -1, axis=-3)
        n01 = np.roll(n, -1, axis=-2)
        n11 = np.roll(n10, -1, axis=-2)
        n00 = n
    else:
        n00, n10, n01, n11 = n[..., :-1, :-1, :], n[..., 1:, :-1, :], n[..., :-1, 1:, :], n[..., 1:, 1:, :]

    def area(a, b, c):
        num = np.einsum("...i,...i->...", a, np.cross(b, c))
        den = 1.0 + np.einsum("...i,...i->...", a, b) + np.einsum("...i,...i->...", b, c) \
            + np.einsum("...i,...i->...", c, a)
        return 2.0 * np.arctan2(num, den)

    q = (area(n00, n10, n11) + area(n00, n11, n01)) / (4 * math.pi)
    return q if density else np.sum(q, axis=(-2, -1))


def great_circle_angle(field: Any, direction: Any = None) -> np.ndarray:
    """Angle φ ∈ (−π, π] of points ``n = cos φ n₀ + sin φ e`` on the great circle through
    n₀ = e_{last} and the unit tangent ``direction`` e (default e₁): ``atan2(n·e, n·n₀)``."""
    n = check_finite("field", field)
    m = n.shape[-1]
    e = np.zeros(m)
    e[0] = 1.0
    if direction is not None:
        e = check_finite("direction", direction, (m,))
        e = e / np.linalg.norm(e)
    return np.arctan2(n @ e, n[..., -1])


def _medium_from(ds) -> SigmaModel:
    try:
        params = json.loads(ds.attrs["cartan_config"])["problem"]["parameters"]
        return SigmaModel(**params)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the dataset does not record a sigma-model run ({exc}); pass medium=") from None


def energy_density(source: Any, X: Any = None, medium: SigmaModel | None = None):
    """Energy density ``e = ½(K/c²)|∂_t n|² + ½K|∇n|²`` at the nodes.

    Parameters
    ----------
    source : xarray.Dataset or array
        A run's Dataset (``cartan.simulate`` output; the medium is rebuilt from its
        ``cartan_config`` unless given), or the nodal velocity N ``[..., r]``.
    X : array, optional
        With an array ``source``: nodal strains ``[..., d, r]``.
    medium : SigmaModel, optional

    Returns
    -------
    xarray.DataArray ``(time, *node dims)`` for a Dataset, else an array ``[...]``.

    Notes
    -----
    For a d = 1 run whose strains live on the edges (``lattice``), the edge energies are
    shared between the two end nodes, so that ``Σ w_i e_i`` (trapezoidal node weights) is the
    scheme's discrete energy exactly.  For d ≥ 2 the Dataset holds strains averaged onto the
    nodes and the density is evaluated there (O(h²) from the lattice's edge energy).
    """
    if X is not None or not hasattr(source, "data_vars"):
        if medium is None or X is None:
            raise ValueError("energy_density(N, X, medium=...) needs the strains X and the medium")
        return medium.energy_density(source, X)
    import xarray as xr

    ds = source
    med = medium if medium is not None else _medium_from(ds)
    kin = med.kinetic(ds["N"].values)
    Xv = ds["X"].values
    node_dims = [dim for dim in ds["N"].dims if dim not in ("time", "component")]
    if "edge" in ds["X"].dims:
        Ue = med.potential(Xv[..., None, :])  # (time, edge)
        if Ue.shape[-1] == ds.sizes["node"]:  # periodic: n edges, the last one closing the ring
            Un = 0.5 * (Ue + np.roll(Ue, 1, axis=-1))
        else:
            Un = np.empty((*Ue.shape[:-1], Ue.shape[-1] + 1))
            Un[..., 1:-1] = 0.5 * (Ue[..., 1:] + Ue[..., :-1])
            Un[..., 0], Un[..., -1] = Ue[..., 0], Ue[..., -1]
    elif Xv.ndim == kin.ndim + 1:  # d = 1 nodal strains (time, node, component)
        Un = med.potential(Xv[..., None, :])
    else:
        Un = med.potential(Xv)
    coords = {k: ds.coords[k] for k in ("time", *node_dims) if k in ds.coords}
    if "u" in ds.coords and "node" in node_dims:
        coords["u"] = ds.coords["u"]
    return xr.DataArray(kin + Un, dims=("time", *node_dims), coords=coords, name="energy_density",
                        attrs={"long_name": "energy density ½(K/c²)|∂ₜn|² + ½K|∇n|²", "units": "energy"})
