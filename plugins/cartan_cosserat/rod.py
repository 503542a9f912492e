"""Cosserat rods on SE(3) and planar Cosserat rods on SE(2) (paper §VI.C, §VI.A).

A Cosserat rod is a Cartan medium with material dimension d = 1, configuration space the
frame bundle F(E³) ≅ SE(3) and symmetry group SE(3) (paper §VI.C, which takes over the
algebra of the Cosserat solid, §VI.A).  A configuration ``q = (r, E)`` is a centreline
point ``r`` and an orthonormal triad of directors ``E = (e₁ e₂ e₃)``, stored as the 4 × 4
matrix of Eq. "matrix rep of SE(3)", homogeneous coordinate first::

    q = Φ = [[1, 0ᵀ],
             [r, E ]]        (q_r = I₄, so Φ = q)

Fields (body frame, paper §VI.A)
--------------------------------
strain      X = Φ⁻¹∂_uΦ = {θ; π}   θ: stretch/shear (∂_u r = θᵢ eᵢ), π: bend/twist
velocity    N = Φ⁻¹∂_tΦ = {V; Ω}   V: centreline velocity, Ω: angular velocity
momentum    S = ∂K/∂N   = {P; L}
stress      Q = ∂U/∂X   = {F; M}   F: internal force, M: internal moment

components are ordered translation first, rotation second: ``X = (θ₁, θ₂, θ₃, π₁, π₂, π₃)``.

Director convention
-------------------
e₁ is the director along the rest tangent (the cross-section normal), e₂ and e₃ span the
cross-section.  The stress-free strain is ``θ₀ = (1, 0, 0)``, ``π₀ = κ₀`` (zero for a
naturally straight rod, or a given intrinsic curvature ``rest_curvature``): π₁ is the twist,
π₂ and π₃ the bending curvatures about e₂ and e₃.

Constitutive law (quadratic, uncoupled)
---------------------------------------
``U = ½(θ − θ₀)ᵀ𝕊(θ − θ₀) + ½(π − π₀)ᵀ𝔹(π − π₀)`` per unit reference length, with

* ``𝕊 = diag(EA, α_c GA, α_c GA)`` (stretch, shear along e₂, shear along e₃);
* ``𝔹 = diag(GJ, EI, EI)`` (twist, bending about e₂, bending about e₃);
* kinetic energy ``K = ½ρA|V|² + ½Ωᵀ𝕀Ω`` with ``𝕀 = diag(ρJ, ρI, ρI)``.

For the circular cross-section of radius a: ``A = πa²``, ``I = πa⁴/4``, ``J = 2I``.  The
shear correction coefficient α_c defaults to 27/28, the value PyElastica uses for a
circular cross-section (Kaneko's 1975 best fit for Poisson ratio 1/2); pass
``shear_coefficient`` for another choice (e.g. 4/3 or Cowper's 6(1+ν)/(7+6ν)).  The stress
is the exact gradient
``F = 𝕊(θ − θ₀)``, ``M = 𝔹(π − π₀)``.

Planar rods
-----------
:class:`PlanarCosseratRod` is the same medium restricted to motions in the e₁–e₂ plane with
bending about e₃, on SE(2) with components ``X = (θ₁, θ₂, π)``, ``N = (V₁, V₂, Ω)``: the
in-plane subset ``𝕊 = diag(EA, α_c GA)``, ``𝔹 = EI``, inertia ``(ρA, ρA, ρI)``.  An SE(3)
rod with planar data moves exactly like it: SE(3) components ``(0, 1, 5)`` are the SE(2)
components ``(0, 1, 2)`` (:data:`PLANAR_COMPONENTS`).  :meth:`CosseratRod.planar_reduction`
declares it as the rod's planar twin, so that ``cartan.simulate`` runs SE(3) problems whose
data all lie in the x–y plane on SE(2) (:mod:`cartan.reduction`).

Loads
-----
``make_load("gravity", g=...)`` gives :class:`Gravity`, the configurational potential
``U(q) = −ρA g·r`` per unit reference length (g the gravitational acceleration, e.g.
``(0, 0, −9.81)``), pulled back to a body force ``f = ρA Rᵀg``, ``m = 0`` by the core
(paper §IV.B).  Damping and uniform forces are the core's generic loads.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

import cartan
from cartan.medium import (
    Medium,
    QuadraticMedium,
    check_finite,
    check_keywords,
    check_positive,
    close_on_periodic_grid,
)
from cartan.problem import ConstantFieldPotential, InitialState
from cartan.spaces import FrameBundleE2

__all__ = [
    "DEFAULT_SHEAR_COEFFICIENT",
    "PLANAR_COMPONENTS",
    "CosseratRod",
    "FrameBundleE2",
    "Gravity",
    "PlanarCosseratRod",
]

#: default shear correction coefficient α_c of a circular cross-section (PyElastica's value)
DEFAULT_SHEAR_COEFFICIENT = 27.0 / 28.0

#: SE(3) components (θ₁, θ₂, π₃) that carry the planar rod's (θ₁, θ₂, π)
PLANAR_COMPONENTS = (0, 1, 5)

_MATERIAL_KEYS = ("E", "G", "poisson", "radius", "density", "shear_coefficient")


# ====================================================================== planar frame space


# ====================================================================== gravity
class Gravity(ConstantFieldPotential):
    """Uniform gravity as the configurational potential ``U(q) = −μ g·r`` (paper §IV.B).

    The core's :class:`~cartan.problem.ConstantFieldPotential` with field ``g`` and density
    ``μ``, validated with this rod's names.

    Parameters
    ----------
    g : array_like, shape ``(k,)``
        Gravitational acceleration in the spatial frame (k = 3 on SE(3), 2 on SE(2)),
        e.g. ``(0, 0, −9.81)``.
    mass : float
        Mass per unit reference length μ = ρA (> 0).

    Notes
    -----
    ``potential_gradient`` returns ∂U/∂q as a point-shaped ``[..., m, m]`` array whose only
    non-zero entries are the position slots ``[..., 1:, 0] = −μ g``; the core's pull-back
    gives the body force ``f = μ Rᵀg`` and no moment — the torque of gravity about a node is
    never written by hand.
    """

    def __init__(self, g: Any, mass: float):
        g = check_finite("g", g)
        if g.ndim != 1 or g.shape[0] not in (2, 3):
            raise ValueError(f"g must be a vector of 2 or 3 components, got shape {g.shape}")
        super().__init__(g, float(check_positive("mass", mass)))

    @property
    def g(self) -> np.ndarray:
        """Gravitational acceleration (the field f), shape ``(k,)``."""
        return self.field

    @property
    def mass(self) -> float:
        """Mass per unit reference length μ (the density)."""
        return self.density

    def bind(self, medium: Medium) -> None:
        k = medium.group.matrix_size - 1
        if self.g.shape != (k,):
            raise ValueError(f"g must have shape ({k},) for medium {medium.name!r}, got {self.g.shape}")
        super().bind(medium)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "gravity", "g": self.g.tolist(), "mass": self.mass}


# ====================================================================== shared base
def _frames_from(tangent: np.ndarray, normal_hint: np.ndarray) -> np.ndarray:
    """Right-handed director frames ``(e₁ e₂ e₃)`` as columns ``[n, 3, 3]``: e₁ ∥ tangent,
    e₃ the part of ``normal_hint`` orthogonal to e₁, e₂ = e₃ × e₁."""
    e1 = tangent / np.linalg.norm(tangent, axis=-1, keepdims=True)
    e3 = normal_hint - np.sum(normal_hint * e1, axis=-1, keepdims=True) * e1
    norm = np.linalg.norm(e3, axis=-1, keepdims=True)
    if np.any(norm < 1e-8):
        raise ValueError("the normal direction is parallel to the rod's tangent; give another 'normal'")
    e3 = e3 / norm
    e2 = np.cross(e3, e1)
    return np.stack([e1, e2, e3], axis=-1)


def _perpendicular(d: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to the unit vector ``d`` (e₃ when d lies in the e₁–e₂ plane)."""
    trial = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    v = trial - np.dot(trial, d) * d
    return v / np.linalg.norm(v)


class _Rod(QuadraticMedium):
    """Shared machinery of :class:`CosseratRod` and :class:`PlanarCosseratRod`."""

    material_dim: ClassVar[int] = 1
    load_kinds: ClassVar[tuple[str, ...]] = ("gravity",)
    #: True for the SE(2) rod (2-vectors for positions, directions, g)
    _is_planar: ClassVar[bool] = False

    # per-class layout: names and shapes of the direct form
    _direct_shapes: ClassVar[dict[str, tuple]] = {}

    def __init__(self, **params: Any):
        given = {k: v for k, v in params.items() if v is not None}
        material = [k for k in given if k in _MATERIAL_KEYS]
        direct = [k for k in given if k in self._direct_shapes]
        if material and direct:
            raise ValueError(
                f"{self.name}: give either the material form ({', '.join(_MATERIAL_KEYS)}) or the "
                f"direct stiffness form ({', '.join(self._direct_shapes)}), not both "
                f"(got {sorted(material + direct)})"
            )
        if material:
            stiff, inertia = self._material(given)
        elif direct:
            stiff, inertia = self._direct(given)
        else:
            raise ValueError(
                f"{self.name}: give the material form (E, G or poisson, radius, density) or the direct "
                f"stiffness form ({', '.join(self._direct_shapes)})"
            )
        r = self.group.dim
        kappa_shape = (3,) if r == 6 else ()
        kappa = check_finite("rest_curvature", given.get("rest_curvature", np.zeros(kappa_shape)), kappa_shape)
        X0 = np.zeros((1, r))
        X0[0, 0] = 1.0
        X0[0, (3 if r == 6 else 2) :] = kappa
        self._stiff = np.asarray(stiff, dtype=float)
        self._inertia = np.asarray(inertia, dtype=float)
        self._set_energy(X0, self._stiff)
        self._params = {k: (np.asarray(v, dtype=float).tolist()) for k, v in given.items()}

    # ------------------------------------------------------------------ parameter forms
    def _material(self, p: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        for key in ("E", "radius", "density"):
            if key not in p:
                raise ValueError(
                    f"{self.name}: the material form needs {key!r} (E, G or poisson, radius, density)"
                )
        E = float(check_positive("E", p["E"], shape=()))
        a = float(check_positive("radius", p["radius"], shape=()))
        rho = float(check_positive("density", p["density"], shape=()))
        if ("G" in p) == ("poisson" in p):
            raise ValueError(f"{self.name}: give exactly one of 'G' (shear modulus) and 'poisson'")
        if "G" in p:
            G = float(check_positive("G", p["G"], shape=()))
        else:
            nu = float(check_finite("poisson", p["poisson"], ()))
            if not -1.0 < nu <= 0.5:
                raise ValueError(f"poisson must be in (−1, 0.5], got {p['poisson']!r}")
            G = E / (2.0 * (1.0 + nu))
        alpha = float(
            check_positive("shear_coefficient", p.get("shear_coefficient", DEFAULT_SHEAR_COEFFICIENT), shape=())
        )
        A = math.pi * a * a
        I = math.pi * a**4 / 4.0
        J = 2.0 * I
        stiff = np.array([E * A, alpha * G * A, alpha * G * A, G * J, E * I, E * I])
        inertia = np.array([rho * A, rho * A, rho * A, rho * J, rho * I, rho * I])
        return self._select(stiff, inertia)

    def _select(self, stiff: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return stiff, inertia

    def _direct(self, p: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
        missing = [k for k in self._direct_shapes if k not in p]
        if missing:
            raise ValueError(
                f"{self.name}: the direct stiffness form also needs {', '.join(map(repr, missing))}"
            )
        vals = {}
        for key, shape in self._direct_shapes.items():
            positive_only = key in ("mass", "rotational_inertia")
            vals[key] = check_positive(key, p[key], allow_zero=not positive_only, shape=shape)
        return self._assemble_direct(vals)

    def _assemble_direct(self, v: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    # ------------------------------------------------------------------ Medium contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords as given (JSON-serialisable); ``type(self)(**parameters())``
        rebuilds the medium."""
        return dict(self._params)

    def inertia(self) -> np.ndarray:
        """Kinetic metric ``(ρA, ρA, ρA, ρJ, ρI, ρI)`` (SE(3)) or ``(ρA, ρA, ρI)`` (SE(2)), shape ``(r,)``."""
        return self._inertia.copy()

    def stiffness_diagonal(self) -> np.ndarray:
        """Diagonal of (𝕊, 𝔹): ``(EA, α_cGA, α_cGA, GJ, EI, EI)`` or ``(EA, α_cGA, EI)``, shape ``(r,)``."""
        return self._stiff.copy()

    @property
    def linear_density(self) -> float:
        """Mass per unit reference length ρA."""
        return float(self._inertia[0])

    # ------------------------------------------------------------------ loads
    def make_load(self, kind: str, **params: Any):
        """``"gravity"``: :class:`Gravity` with ``g`` (k,) and mass ρA of this rod."""
        if kind == "gravity":
            unknown = set(params) - {"g"}
            if unknown or "g" not in params:
                raise ValueError(f"load 'gravity' takes exactly the parameter 'g', got {sorted(params)}")
            return Gravity(params["g"], self.linear_density)
        return super().make_load(kind, **params)

    # ------------------------------------------------------------------ initial states
    initial_kinds: ClassVar[tuple[str, ...]] = ("straight", "ring", "arc", "helix", "arrays")

    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial structure field and velocity on ``grid`` from a named shape.

        Parameters
        ----------
        grid : cartan.grid.Grid
            d = 1.
        kind : str
            ``"straight"``, ``"ring"``, ``"arc"``, ``"helix"`` (SE(3) only) or ``"arrays"``;
            see ``docs/media/cosserat-rod.md`` for each kind's parameters.
        **params
            Shape parameters, plus the velocity options common to every kind:
            ``velocity`` — body components N, shape ``(r,)`` or ``(n, r)``;
            ``rigid_velocity`` — a spatial twist ``(v, ω)`` (``(6,)`` on SE(3), ``(v₁, v₂, ω)``
            on SE(2)) of a rigid motion about ``center`` (default: the centroid of the nodes),
            converted to body components ``V = Rᵀ(v + ω × (r − c))``, ``Ω = Rᵀω``.  Both may be
            given; they add.

        Returns
        -------
        cartan.problem.InitialState
            ``Phi`` ``(n, m, m)`` and ``N`` ``(n, r)``.
        """
        if grid.d != 1:
            raise ValueError(f"{self.name} needs a grid with d = 1, got d = {grid.d}")
        velocity = params.pop("velocity", None)
        rigid = params.pop("rigid_velocity", None)
        center = params.pop("center", None)
        builders = {
            "straight": self._straight,
            "ring": self._ring,
            "arc": self._arc,
            "helix": self._helix,
            "arrays": self._arrays,
        }
        if kind not in builders or (kind == "helix" and self._is_planar):
            return super().initial_state(grid, kind, **params)
        periodic = grid.periodic[0]
        if kind == "ring" and not periodic:
            raise ValueError("initial kind 'ring' needs a periodic grid (a closed rod)")
        build = builders[kind]
        check_keywords(kind, build, params, ("velocity", "rigid_velocity", "center"))
        holonomy = None
        if periodic and kind in ("straight", "arc", "helix"):
            Phi, holonomy = close_on_periodic_grid(self.group, grid, lambda g: self._assemble(*build(g, **params)))
        else:
            pos, frames = build(grid, **params)
            Phi = self._assemble(pos, frames)
        N = self._velocities(grid, Phi, velocity, rigid, center)
        return InitialState(Phi=Phi, N=N, holonomy=holonomy)

    # geometry builders: positions (n, 3), frames (n, 3, 3) with directors as columns
    def _straight(self, grid, direction=None, normal=None, origin=None, stretch=1.0):
        s = grid.coordinates(0)
        d = self._vec3("direction", direction, (1.0, 0.0, 0.0))
        d = d / _norm_checked("direction", d)
        o = self._vec3("origin", origin, (0.0, 0.0, 0.0))
        lam = float(check_positive("stretch", stretch, shape=()))
        nrm = _perpendicular(d) if normal is None else self._vec3("normal", normal, None)
        pos = o + lam * s[:, None] * d
        frames = _frames_from(np.broadcast_to(d, pos.shape), np.broadcast_to(nrm, pos.shape))
        return pos, frames

    def _ring(self, grid, radius=None, origin=None, amplitude=0.0, mode=2, out_of_plane=0.0, phase=0.0):
        n, L = grid.shape[0], grid.length[0]
        R = L / (2 * math.pi) if radius is None else float(check_positive("radius", radius, shape=()))
        o = self._vec3("origin", origin, (0.0, 0.0, 0.0))
        eps = float(check_finite("amplitude", amplitude, ()))
        zeta = float(check_finite("out_of_plane", out_of_plane, ()))
        if self._is_planar and zeta != 0.0:
            raise ValueError("out_of_plane must be 0 for a planar rod")
        if int(mode) != mode or mode < 1:
            raise ValueError(f"mode must be an integer ≥ 1, got {mode!r}")
        m = int(mode)
        ph = float(check_finite("phase", phase, ()))
        phi = 2 * math.pi * np.arange(n) / n
        c, s = np.cos(phi), np.sin(phi)
        rho = R * (1.0 + eps * np.cos(m * phi + ph))
        drho = -R * eps * m * np.sin(m * phi + ph)
        z = R * zeta * np.sin(m * phi + ph)
        dz = R * zeta * m * np.cos(m * phi + ph)
        pos = o + np.stack([rho * c, rho * s, z], axis=-1)
        tangent = np.stack([drho * c - rho * s, drho * s + rho * c, dz], axis=-1)
        frames = _frames_from(tangent, np.broadcast_to([0.0, 0.0, 1.0], pos.shape))
        return pos, frames

    def _arc(self, grid, curvature=0.0, origin=None, angle=0.0, centered=False):
        s = grid.coordinates(0)
        k = float(check_finite("curvature", curvature, ()))
        a0 = float(check_finite("angle", angle, ()))
        o = self._vec3("origin", origin, (0.0, 0.0, 0.0))
        if centered:
            s = s - 0.5 * grid.length[0]
        ang = a0 + k * s
        if k == 0.0:
            x, y = s * math.cos(a0), s * math.sin(a0)
        else:
            x = (np.sin(ang) - math.sin(a0)) / k
            y = (math.cos(a0) - np.cos(ang)) / k
        pos = o + np.stack([x, y, np.zeros_like(s)], axis=-1)
        tangent = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(s)], axis=-1)
        frames = _frames_from(tangent, np.broadcast_to([0.0, 0.0, 1.0], pos.shape))
        return pos, frames

    def _helix(self, grid, radius=None, pitch=None, origin=None):
        if radius is None or pitch is None:
            raise ValueError("initial kind 'helix' needs 'radius' and 'pitch'")
        a = float(check_positive("radius", radius, shape=()))
        b = float(check_finite("pitch", pitch, ())) / (2 * math.pi)
        o = self._vec3("origin", origin, (0.0, 0.0, 0.0))
        c = math.hypot(a, b)
        t = grid.coordinates(0) / c
        pos = o + np.stack([a * np.cos(t), a * np.sin(t), b * t], axis=-1)
        T = np.stack([-a * np.sin(t), a * np.cos(t), np.full_like(t, b)], axis=-1) / c
        Nn = np.stack([-np.cos(t), -np.sin(t), np.zeros_like(t)], axis=-1)
        B = np.cross(T, Nn)
        return pos, np.stack([T, Nn, B], axis=-1)

    def _arrays(self, grid, positions=None, frames=None):
        n = grid.shape[0]
        k = 2 if self._is_planar else 3
        if positions is None or frames is None:
            raise ValueError("initial kind 'arrays' needs 'positions' and 'frames'")
        pos = check_finite("positions", positions, (n, k))
        E = check_finite("frames", frames, (n, k, k))
        defect = np.linalg.norm(np.swapaxes(E, -1, -2) @ E - np.eye(k), axis=(-2, -1))
        det = np.linalg.det(E)
        if np.any(defect > 1e-8) or np.any(np.abs(det - 1.0) > 1e-8):
            raise ValueError("frames must be proper rotations (orthonormal directors as columns, det = +1)")
        if k == 2:
            pos = np.concatenate([pos, np.zeros((n, 1))], axis=-1)
            E3 = np.zeros((n, 3, 3))
            E3[:, :2, :2] = E
            E3[:, 2, 2] = 1.0
            E = E3
        return pos, E

    def _vec3(self, name: str, value: Any, default: Any) -> np.ndarray:
        """A spatial vector parameter; planar rods accept 2 components (z = 0)."""
        if value is None:
            return np.array(default, dtype=float)
        k = 2 if self._is_planar else 3
        v = check_finite(name, value, (k,))
        return np.append(v, 0.0) if k == 2 else v

    # ------------------------------------------------------------------ assembly
    def _assemble(self, pos: np.ndarray, frames: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _velocities(self, grid, Phi, velocity, rigid, center) -> np.ndarray:
        n, r = grid.shape[0], self.group.dim
        N = np.zeros((n, r))
        if velocity is not None:
            v = check_finite("velocity", velocity)
            if v.shape not in ((r,), (n, r)):
                raise ValueError(f"velocity must have shape ({r},) or ({n}, {r}), got {v.shape}")
            N = N + v
        if rigid is not None:
            N = N + self._rigid_body_velocity(Phi, check_finite("rigid_velocity", rigid, (r,)), center)
        elif center is not None:
            raise ValueError("'center' is only used with 'rigid_velocity'")
        return N

    def _rigid_body_velocity(self, Phi: np.ndarray, twist: np.ndarray, center: Any) -> np.ndarray:
        raise NotImplementedError


def _norm_checked(name: str, v: np.ndarray) -> float:
    nv = float(np.linalg.norm(v))
    if nv == 0.0:
        raise ValueError(f"{name} must be a non-zero vector")
    return nv


# ====================================================================== SE(3) rod
class CosseratRod(_Rod):
    """Cosserat rod on SE(3), configuration space F(E³) (paper §VI.C).

    Give either the material form (``E``, ``G`` or ``poisson``, ``radius``, ``density``,
    optional ``shear_coefficient``; circular cross-section) or the direct stiffness form
    (``stretch_shear``, ``bend_twist``, ``mass``, ``rotational_inertia``).  Every value is
    validated: ``ValueError`` naming the parameter and its range.

    Parameters
    ----------
    E : float
        Young's modulus, > 0.
    G : float, optional
        Shear modulus, > 0 (give exactly one of ``G`` and ``poisson``).
    poisson : float, optional
        Poisson ratio ν ∈ (−1, 0.5]; ``G = E/(2(1 + ν))``.
    radius : float
        Cross-section radius a > 0: ``A = πa²``, ``I = πa⁴/4``, ``J = 2I``.
    density : float
        Mass density ρ > 0 (per unit volume).
    shear_coefficient : float, default 27/28
        α_c > 0 (PyElastica's value for a circular section).
    stretch_shear : array_like, shape ``(3,)``
        diag 𝕊 = (EA, α_cGA₂, α_cGA₃), ≥ 0 (zero decouples that strain).
    bend_twist : array_like, shape ``(3,)``
        diag 𝔹 = (GJ, EI₂, EI₃), ≥ 0.
    mass : float
        ρA > 0, mass per unit reference length.
    rotational_inertia : array_like, shape ``(3,)``
        diag 𝕀 = (ρJ, ρI₂, ρI₃) > 0, per unit reference length.
    rest_curvature : array_like, shape ``(3,)``, default 0
        Intrinsic π₀ = (twist, κ₂, κ₃).

    Notes
    -----
    Director convention: e₁ along the rest tangent, rest strain θ₀ = (1, 0, 0).
    ``X``, ``Q`` have shape ``[..., 1, 6]``; ``N``, ``S`` ``[..., 6]``, components
    ``(θ; π)``, ``(V; Ω)``, ``(P; L)``, ``(F; M)`` translation first (paper §VI.A).
    """

    name: ClassVar[str] = "cosserat-rod"
    _direct_shapes: ClassVar[dict[str, tuple]] = {
        "stretch_shear": (3,),
        "bend_twist": (3,),
        "mass": (),
        "rotational_inertia": (3,),
    }

    def __init__(
        self,
        *,
        E: float | None = None,
        G: float | None = None,
        poisson: float | None = None,
        radius: float | None = None,
        density: float | None = None,
        shear_coefficient: float | None = None,
        stretch_shear: Any = None,
        bend_twist: Any = None,
        mass: float | None = None,
        rotational_inertia: Any = None,
        rest_curvature: Any = None,
    ):
        self.group = cartan.group("SE3")
        self.space = cartan.space("frame-E3")
        super().__init__(
            E=E,
            G=G,
            poisson=poisson,
            radius=radius,
            density=density,
            shear_coefficient=shear_coefficient,
            stretch_shear=stretch_shear,
            bend_twist=bend_twist,
            mass=mass,
            rotational_inertia=rotational_inertia,
            rest_curvature=rest_curvature,
        )

    def _assemble_direct(self, v):
        m = float(v["mass"])
        return (
            np.concatenate([v["stretch_shear"], v["bend_twist"]]),
            np.concatenate([[m, m, m], v["rotational_inertia"]]),
        )

    def _assemble(self, pos, frames):
        n = pos.shape[0]
        Phi = np.zeros((n, 4, 4))
        Phi[:, 0, 0] = 1.0
        Phi[:, 1:, 0] = pos
        Phi[:, 1:, 1:] = frames
        return Phi

    def _rigid_body_velocity(self, Phi, twist, center):
        pos, R = Phi[:, 1:, 0], Phi[:, 1:, 1:]
        c = pos.mean(axis=0) if center is None else check_finite("center", center, (3,))
        v, w = twist[:3], twist[3:]
        vs = v + np.cross(w, pos - c)
        Rt = np.swapaxes(R, -1, -2)
        return np.concatenate([Rt @ vs[..., None], Rt @ np.broadcast_to(w, vs.shape)[..., None]], axis=-2)[
            ..., 0
        ]

    def planar(self) -> PlanarCosseratRod:
        """The planar rod with this rod's in-plane data (motion in e₁–e₂, bending about e₃).

        Raises
        ------
        ValueError
            When the rest curvature has out-of-plane components (π₀₁ or π₀₂ ≠ 0).
        """
        kappa = self._X0[0, 3:]
        if kappa[0] != 0.0 or kappa[1] != 0.0:
            raise ValueError("rest_curvature has out-of-plane components; the rod has no planar restriction")
        p = dict(self._params)
        p.pop("rest_curvature", None)
        extra = {"rest_curvature": float(kappa[2])} if kappa[2] != 0.0 else {}
        if "mass" in p:
            S, B, Ir = p["stretch_shear"], p["bend_twist"], p["rotational_inertia"]
            return PlanarCosseratRod(
                stretch_shear=S[:2], bending=B[2], mass=p["mass"], rotational_inertia=Ir[2], **extra
            )
        return PlanarCosseratRod(**p, **extra)

    def planar_reduction(self) -> PlanarCosseratRod | None:
        """The planar twin for :mod:`cartan.reduction`: :meth:`planar`, or None when the rest
        curvature has out-of-plane components (see :meth:`cartan.medium.Medium.planar_reduction`)."""
        try:
            return self.planar()
        except ValueError:
            return None

    def held_strain_twins(self) -> tuple:
        """The Kirchhoff filament (``filament``: θ = (1, 0, 0) held, paper §III.E, §VII.A) with
        this rod's 𝔹 = diag(GJ, EI₂, EI₃), π₀, ρA and inertia; none for a rod with a rest
        stretch or shear, a non-diagonal 𝔹, or constrained strains of its own (see
        :meth:`cartan.medium.Medium.held_strain_twins`)."""
        from cartan.medium import HeldStrainTwin

        X0, C = self.quadratic_energy()
        X0, C = np.asarray(X0, dtype=float).reshape(-1), np.asarray(C, dtype=float)
        B = C[3:, 3:]
        if self.constrained_strains() is not None or not np.array_equal(X0[:3], [1.0, 0.0, 0.0]) or \
                np.any(B != np.diag(np.diag(B))):
            return ()
        m = self.inertia()

        def parameters(_: dict[str, Any]) -> dict[str, Any]:
            return {"bending": [float(B[1, 1]), float(B[2, 2])], "twist": float(B[0, 0]),
                    "rest_curvature": [float(X0[4]), float(X0[5])], "rest_twist": float(X0[3]),
                    "mass": float(m[0]), "rotational_inertia": [float(v) for v in m[3:]]}

        return (HeldStrainTwin("filament", (0, 1, 2), (1.0, 0.0, 0.0), parameters, "stretch and shear"),)


# ====================================================================== SE(2) rod
class PlanarCosseratRod(_Rod):
    """Planar Cosserat rod on SE(2): motion in the e₁–e₂ plane, bending about e₃.

    Components ``X = (θ₁, θ₂, π)``, ``N = (V₁, V₂, Ω)``, ``Q = (F₁, F₂, M)``; the in-plane
    subset of :class:`CosseratRod`: ``𝕊 = diag(EA, α_cGA)``, ``𝔹 = EI``, inertia
    ``(ρA, ρA, ρI)``.  Configuration space: :class:`FrameBundleE2`.

    Parameters
    ----------
    E, G, poisson, radius, density, shear_coefficient
        The material form, as for :class:`CosseratRod`.
    stretch_shear : array_like, shape ``(2,)``
        Direct form: (EA, α_cGA), ≥ 0.
    bending : float
        Direct form: EI ≥ 0.
    mass : float
        Direct form: ρA > 0.
    rotational_inertia : float
        Direct form: ρI > 0.
    rest_curvature : float, default 0
        Intrinsic curvature κ₀ (about e₃).
    """

    name: ClassVar[str] = "planar-cosserat-rod"
    _is_planar: ClassVar[bool] = True
    initial_kinds: ClassVar[tuple[str, ...]] = ("straight", "ring", "arc", "arrays")
    _direct_shapes: ClassVar[dict[str, tuple]] = {
        "stretch_shear": (2,),
        "bending": (),
        "mass": (),
        "rotational_inertia": (),
    }

    def __init__(
        self,
        *,
        E: float | None = None,
        G: float | None = None,
        poisson: float | None = None,
        radius: float | None = None,
        density: float | None = None,
        shear_coefficient: float | None = None,
        stretch_shear: Any = None,
        bending: float | None = None,
        mass: float | None = None,
        rotational_inertia: float | None = None,
        rest_curvature: float | None = None,
    ):
        self.space = FrameBundleE2()
        self.group = self.space.group
        super().__init__(
            E=E,
            G=G,
            poisson=poisson,
            radius=radius,
            density=density,
            shear_coefficient=shear_coefficient,
            stretch_shear=stretch_shear,
            bending=bending,
            mass=mass,
            rotational_inertia=rotational_inertia,
            rest_curvature=rest_curvature,
        )

    def _select(self, stiff, inertia):
        idx = list(PLANAR_COMPONENTS)
        return stiff[idx], inertia[idx]

    def _assemble_direct(self, v):
        m = float(v["mass"])
        return (
            np.array([*v["stretch_shear"], float(v["bending"])]),
            np.array([m, m, float(v["rotational_inertia"])]),
        )

    def _straight(self, grid, direction=None, normal=None, origin=None, stretch=1.0):
        if normal is not None:
            raise ValueError("a planar rod takes no 'normal' (it is e₃)")
        return super()._straight(grid, direction=direction, origin=origin, stretch=stretch)

    def _assemble(self, pos, frames):
        if np.any(np.abs(pos[:, 2]) > 0.0) or np.any(np.abs(frames[:, 2, 2] - 1.0) > 1e-12):
            raise ValueError(
                "the initial shape of a planar rod must lie in the e₁–e₂ plane with e₃ normal to it"
            )
        n = pos.shape[0]
        Phi = np.zeros((n, 3, 3))
        Phi[:, 0, 0] = 1.0
        Phi[:, 1:, 0] = pos[:, :2]
        Phi[:, 1:, 1:] = frames[:, :2, :2]
        return Phi

    def held_strain_twins(self) -> tuple:
        """The planar elastica: θ = θ₀ held, the core's generic twin (no registered medium;
        :class:`cartan.advise.HeldStrainMedium`), see :meth:`cartan.medium.Medium.held_strain_twins`."""
        from cartan.medium import HeldStrainTwin

        if self.constrained_strains() is not None:
            return ()
        return (HeldStrainTwin(None, (0, 1), label="stretch and shear"),)

    def _rigid_body_velocity(self, Phi, twist, center):
        pos, R = Phi[:, 1:, 0], Phi[:, 1:, 1:]
        c = pos.mean(axis=0) if center is None else check_finite("center", center, (2,))
        v, w = twist[:2], float(twist[2])
        d = pos - c
        vs = v + w * np.stack([-d[:, 1], d[:, 0]], axis=-1)
        V = np.einsum("nji,nj->ni", R, vs)
        return np.concatenate([V, np.full((len(pos), 1), w)], axis=-1)
