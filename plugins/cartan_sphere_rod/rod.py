"""Cosserat rods on the sphere S²_r (paper §VIII.A, "Cosserat rods on 2-spheres").

A rod on a sphere is a Cartan medium with material dimension d = 1, configuration space the
frame bundle F(S²_r) of the sphere of radius r and symmetry group SO(3).  A configuration is
an orthonormal frame ``R = (e₁ e₂ e₃)`` (directors as columns): the centreline point is
``r·e₃`` and the directors e₁, e₂ span the tangent plane of the sphere there.  The core's
space ``cartan.space("frame-S2", radius=r)`` stores the frame itself (q_r = I₃, Φ = R).

Fields (body frame, so(3) components, hat map ``v ↦ [[0, −v₃, v₂], [v₃, 0, −v₁], [−v₂, v₁, 0]]``)
-----------------------------------------------------------------------------------------------
strain      X = R⁻¹∂_uR = (−θ₂/r, θ₁/r, π_n)     ∂_u(r e₃) = θ₁e₁ + θ₂e₂, π_n: rotation of (e₁, e₂) about e₃
velocity    N = R⁻¹∂_tR = (−V₂/r, V₁/r, Ω_n)     ∂_t(r e₃) = V₁e₁ + V₂e₂, Ω_n: spin about e₃
momentum    S = ∂K/∂N   = (−rP₂, rP₁, L_n)       P = ρ₀V, L_n = 𝕀_nΩ_n
stress      Q = ∂U/∂X   = (−rF₂, rF₁, M_n)       F = ∂U/∂θ (force), M_n = ∂U/∂π_n (moment)
load        T           = (−rf₂, rf₁, m_n)

so that ``∂_u e₁ = π_n e₂ − (θ₁/r) e₃``, ``∂_t e₁ = Ω_n e₂ − (V₁/r) e₃``: the e₃ terms are the
parallel transport on the sphere.

Director convention
-------------------
e₃ is the outward normal of the sphere (centreline ``r·e₃``), e₁ the director along the rest
tangent, e₂ = e₃ × e₁ the in-surface normal of the rod.  The stress-free state is
``θ = (θ₀, 0)``, ``π_n = 0`` — a great circle traversed along e₁ with stretch θ₀ (the paper
takes θ₀ = 1).

The paper prints ``X = (θ₂/r, −θ₁/r, π_n)``, ``N = (V₂/r, −V₁/r, Ω_n)``.  With its own hat map
(the one above) and ``ė_i = e_j Ω̂_ji`` that choice gives ``ṙ = −V₁e₁ − V₂e₂``, against
``ṙ = V₁e₁ + V₂e₂`` stated in the same paragraph; the two differ by the relabelling
``(e₁, e₂) → (−e₁, −e₂)``, a rotation by π about e₃.  cartan uses the components above, in
which e₁ is the rest tangent.  Every physical statement of §VIII.A holds unchanged: the kinetic
energy, the potential, and the balance laws (paper Eq. "cosserat rod on sphere dynamics")

    D_tP = D_uF + (1/r²) L×V + (1/r²) θ×M + f,     L̇ = ∂_uM + θ×F + m,

which is what ``Ṡ + N×S = ∂_uQ + X×Q + T`` reads in these components (``D = ∂ + π×`` or
``∂ + Ω×`` on vectors of the tangent plane, vectors ``(a₁, a₂, 0)`` and ``(0, 0, a_n)``).

Constitutive law
----------------
Per unit reference length,

    K = ½ρ₀|V|² + ½𝕀_nΩ_n²                      → inertia (ρ₀r², ρ₀r², 𝕀_n) in so(3) components,
    U = ½(θ₁ − θ₀, θ₂)𝕂(θ₁ − θ₀, θ₂)ᵀ + ½ℕ_nπ_n²  → U = ½(X − X₀)ᵀC(X − X₀),

with ``X₀ = (0, θ₀/r, 0)`` and ``C = [[r²𝕂₂₂, −r²𝕂₁₂, 0], [−r²𝕂₁₂, r²𝕂₁₁, 0], [0, 0, ℕ_n]]``.

As r → ∞ the 1/r² terms vanish and the medium is the planar Cosserat rod with
``stretch_shear = diag 𝕂``, ``bending = ℕ_n``, ``mass = ρ₀``, ``rotational_inertia = 𝕀_n``
(:meth:`SphereRod.planar_parameters`): SO(3) contracts to SE(2).

Loads
-----
``make_load("drag", gamma_T=γ_T, gamma_R=γ_R)`` is the paper's dissipation f = −γ_T V,
m = −γ_R Ω_n as the core's :class:`~cartan.problem.Damping` with coefficients
``(γ_T r², γ_T r², γ_R)``: T = (−rf₂, rf₁, m_n) = −(γ_T r² N₁, γ_T r² N₂, γ_R N₃), whose power
T·N = −γ_T|V|² − γ_RΩ_n² is the dissipation rate of the paper.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

import cartan
from cartan.grid import Grid
from cartan.medium import QuadraticMedium, check_finite, check_keywords, check_positive, close_on_periodic_grid
from cartan.problem import Damping, InitialState

__all__ = ["SphereRod"]

_Z = np.array([0.0, 0.0, 1.0])


def _integer(name: str, value: Any, minimum: int = 1, maximum: int | None = None) -> int:
    """``value`` as an int in [minimum, maximum] (a ``ValueError`` naming ``name`` otherwise)."""
    allowed = f"an integer ≥ {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]"
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    if (not math.isfinite(float(value)) or int(value) != value or value < minimum
            or (maximum is not None and value > maximum)):
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return int(value)


def _unit(name: str, value: Any) -> np.ndarray:
    v = check_finite(name, value, (3,))
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise ValueError(f"{name} must be a non-zero 3-vector")
    return v / n


def _rotation_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation taking e_z to the unit vector ``axis`` (the identity for e_z itself)."""
    c = float(axis[2])
    k = np.cross(_Z, axis)
    s = float(np.linalg.norm(k))
    if s < 1e-15:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return cartan.group("SO3").exp(k / s * math.atan2(s, c))


def _frames(e3: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """Frames ``(e₁ e₂ e₃)`` as columns ``[n, 3, 3]``: e₃ normalised, e₁ the part of ``tangent``
    orthogonal to e₃, normalised, and e₂ = e₃ × e₁."""
    e3 = e3 / np.linalg.norm(e3, axis=-1, keepdims=True)
    e1 = tangent - np.sum(tangent * e3, axis=-1, keepdims=True) * e3
    norm = np.linalg.norm(e1, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError("the rod's tangent is normal to the sphere; give another 'direction'")
    e1 = e1 / norm
    return np.stack([e1, np.cross(e3, e1), e3], axis=-1)


class SphereRod(QuadraticMedium):
    """Cosserat rod on the sphere of radius r: (M, X, G) = ([0, L₀] or periodic, F(S²_r), SO(3)).

    Every value is validated on construction (``ValueError`` naming the parameter and its
    range).  Components, conventions and the energy are described in the module docstring
    and in ``docs/media/sphere-rod.md``.

    Parameters
    ----------
    radius : float, default 1
        Sphere radius r > 0.
    density : float, default 1
        ρ₀ > 0, mass per unit reference length.
    rotational_inertia : float, default 0.01
        𝕀_n > 0, moment of inertia of the directors about e₃ per unit reference length.
    stiffness : array_like, shape ``(2,)`` or ``(2, 2)``, default ``(1, 1)``
        𝕂 of the stretch θ₁ − θ₀ and shear θ₂: a diagonal (entries ≥ 0) or a symmetric
        positive semi-definite 2 × 2 matrix.
    bending : float, default 0.01
        ℕ_n ≥ 0, stiffness of the geodesic bending π_n.
    rest_stretch : float, default 1
        θ₀ > 0, the stretch of the stress-free state (the paper's θ₀ = 1).  A closed rod of
        reference length L₀ has a stress-free great circle when L₀θ₀ = 2πr.

    Notes
    -----
    Director convention: e₃ = outward normal, e₁ along the rest tangent, e₂ = e₃ × e₁; rest
    strain ``X₀ = (0, θ₀/r, 0)``.  ``X``, ``Q`` have shape ``[..., 1, 3]``, ``N``, ``S``
    ``[..., 3]``.  Use :meth:`strain_components`, :meth:`physical_strains`,
    :meth:`velocity_components` and :meth:`physical_velocities` to go between the so(3)
    components and (θ₁, θ₂, π_n), (V₁, V₂, Ω_n).
    """

    name: ClassVar[str] = "sphere-rod"
    material_dim: ClassVar[int] = 1
    load_kinds: ClassVar[tuple[str, ...]] = ("drag",)
    initial_kinds: ClassVar[tuple[str, ...]] = ("great-circle", "latitude", "arc", "perturbed", "arrays")

    def __init__(
        self,
        *,
        radius: float = 1.0,
        density: float = 1.0,
        rotational_inertia: float = 0.01,
        stiffness: Any = (1.0, 1.0),
        bending: float = 0.01,
        rest_stretch: float = 1.0,
    ):
        r = float(check_positive("radius", radius, shape=()))
        rho = float(check_positive("density", density, shape=()))
        inertia_n = float(check_positive("rotational_inertia", rotational_inertia, shape=()))
        K_given = check_finite("stiffness", stiffness)
        if K_given.shape == (2,):
            if np.any(K_given < 0):
                raise ValueError(f"stiffness must be ≥ 0 (diagonal of 𝕂), got {stiffness!r}")
            K = np.diag(K_given)
        elif K_given.shape == (2, 2):
            if not np.allclose(K_given, K_given.T, rtol=1e-12, atol=0.0):
                raise ValueError(f"stiffness must be a symmetric 2 × 2 matrix, got {stiffness!r}")
            K = 0.5 * (K_given + K_given.T)
            if np.min(np.linalg.eigvalsh(K)) < -1e-12 * max(1.0, float(np.abs(K).max())):
                raise ValueError(f"stiffness must be positive semi-definite (eigenvalues ≥ 0), got {stiffness!r}")
        else:
            raise ValueError(f"stiffness must have shape (2,) or (2, 2), got {K_given.shape}")
        Nn = float(check_positive("bending", bending, allow_zero=True, shape=()))
        theta0 = float(check_positive("rest_stretch", rest_stretch, shape=()))

        self.space = cartan.space("frame-S2", radius=r)
        self.group = self.space.group
        self.radius = r
        self.density = rho
        self.rotational_inertia = inertia_n
        self.stiffness_matrix = K
        self.bending = Nn
        self.rest_stretch = theta0
        self._inertia = np.array([rho * r * r, rho * r * r, inertia_n])
        r2 = r * r
        self._set_energy(
            [0.0, theta0 / r, 0.0],
            [[r2 * K[1, 1], -r2 * K[0, 1], 0.0], [-r2 * K[0, 1], r2 * K[0, 0], 0.0], [0.0, 0.0, Nn]],
        )
        self._params = {
            "radius": r,
            "density": rho,
            "rotational_inertia": inertia_n,
            "stiffness": K_given.tolist(),
            "bending": Nn,
            "rest_stretch": theta0,
        }

    # ------------------------------------------------------------------ Medium contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``SphereRod(**parameters())`` rebuilds the medium."""
        return {k: (list(v) if isinstance(v, list) else v) for k, v in self._params.items()}

    def inertia(self) -> np.ndarray:
        """Kinetic metric ``(ρ₀r², ρ₀r², 𝕀_n)`` in so(3) components, shape ``(3,)``.

        From N = (−V₂/r, V₁/r, Ω_n): ½ρ₀|V|² + ½𝕀_nΩ_n² = ½ρ₀r²(N₁² + N₂²) + ½𝕀_nN₃².
        """
        return self._inertia.copy()

    # ------------------------------------------------------------------ components
    def strain_components(self, theta1: Any, theta2: Any, pi_n: Any) -> np.ndarray:
        """so(3) components ``X = (−θ₂/r, θ₁/r, π_n)`` of physical strains, ``[..., 3]``."""
        t1, t2, p = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (theta1, theta2, pi_n)))
        return np.stack([-t2 / self.radius, t1 / self.radius, p], axis=-1)

    def physical_strains(self, X: Any) -> np.ndarray:
        """``(θ₁, θ₂, π_n) = (rX₂, −rX₁, X₃)``: stretch, shear, geodesic bending, ``[..., 3]``."""
        X = np.asarray(X, dtype=float)
        return np.stack([self.radius * X[..., 1], -self.radius * X[..., 0], X[..., 2]], axis=-1)

    def velocity_components(self, V1: Any, V2: Any, Omega_n: Any) -> np.ndarray:
        """so(3) components ``N = (−V₂/r, V₁/r, Ω_n)`` of physical velocities, ``[..., 3]``."""
        return self.strain_components(V1, V2, Omega_n)

    def physical_velocities(self, N: Any) -> np.ndarray:
        """``(V₁, V₂, Ω_n) = (rN₂, −rN₁, N₃)``, ``[..., 3]``."""
        return self.physical_strains(N)

    def physical_stress(self, X: Any) -> np.ndarray:
        """``(F₁, F₂, M_n) = (𝕂(θ₁ − θ₀, θ₂), ℕ_nπ_n)`` at strains ``X`` ``[..., 3]`` → ``[..., 3]``."""
        t = self.physical_strains(X)
        F = np.einsum("ij,...j->...i", self.stiffness_matrix, np.stack([t[..., 0] - self.rest_stretch, t[..., 1]], -1))
        return np.concatenate([F, (self.bending * t[..., 2])[..., None]], axis=-1)

    def centreline(self, Phi: Any) -> np.ndarray:
        """Centreline points ``r·e₃`` of frames ``[..., 3, 3]``, shape ``[..., 3]``."""
        return self.space.centreline(Phi)

    def planar_parameters(self) -> dict[str, Any]:
        """Keywords of the ``planar-cosserat-rod`` with this rod's data (its r → ∞ limit).

        ``stretch_shear = diag 𝕂``, ``bending = ℕ_n``, ``mass = ρ₀``, ``rotational_inertia = 𝕀_n``.

        Raises
        ------
        ValueError
            When 𝕂 has off-diagonal terms or θ₀ ≠ 1 (the planar rod has neither).
        """
        K = self.stiffness_matrix
        if K[0, 1] != 0.0:
            raise ValueError("stiffness couples stretch and shear; the planar rod has a diagonal stiffness")
        if self.rest_stretch != 1.0:
            raise ValueError("rest_stretch ≠ 1; the planar rod's stress-free stretch is 1")
        return {
            "stretch_shear": [float(K[0, 0]), float(K[1, 1])],
            "bending": self.bending,
            "mass": self.density,
            "rotational_inertia": self.rotational_inertia,
        }

    # ------------------------------------------------------------------ loads
    def make_load(self, kind: str, **params: Any):
        """``"drag"``: the paper's f = −γ_T V, m = −γ_R Ω_n as :class:`~cartan.problem.Damping`
        with coefficients ``(γ_T r², γ_T r², γ_R)`` (parameters ``gamma_T``, ``gamma_R`` ≥ 0)."""
        if kind == "drag":
            if set(params) != {"gamma_T", "gamma_R"}:
                raise ValueError(
                    f"load 'drag' takes exactly the parameters 'gamma_T' and 'gamma_R', got {sorted(params)}"
                )
            gT = float(check_positive("gamma_T", params["gamma_T"], allow_zero=True, shape=()))
            gR = float(check_positive("gamma_R", params["gamma_R"], allow_zero=True, shape=()))
            r2 = self.radius**2
            return Damping(np.array([gT * r2, gT * r2, gR]))
        return super().make_load(kind, **params)

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid: Grid, kind: str, **params: Any) -> InitialState:
        """Initial frames and velocity on ``grid`` from a named shape.

        Parameters
        ----------
        grid : cartan.grid.Grid
            d = 1.  ``"great-circle"``, ``"latitude"`` and ``"perturbed"`` are closed rods and
            need a periodic grid; ``"arc"`` is an open rod (on a periodic grid the closing edge
            carries the holonomy Φ(L)Φ(0)⁻¹).
        kind : str
            ``"great-circle"``: ``axis`` (normal of its plane, default e_z), ``winding`` (1),
            ``phase`` (longitude of node 0, 0).
            ``"latitude"``: circle of colatitude ``colatitude`` ∈ (0, π) about ``axis``, with
            ``winding`` and ``phase``; e₃ = position/r, e₁ the tangent (increasing longitude),
            e₂ = e₃ × e₁ (towards the pole of ``axis``).
            ``"arc"``: the orbit Φ(u) = Φ_s exp(s X̂) of constant strain X built from
            ``stretch`` (θ₀), ``shear`` (0) and ``curvature`` (π_n, 0: a great circle), with
            s = u, or u − L/2 when ``centered``; Φ_s has e₃ along ``point`` (default e_z) and
            e₁ along ``direction`` (default e_x) projected on the tangent plane.
            ``"perturbed"``: the great circle about ``axis`` with latitude
            ``amplitude·sin(mode·φ + phase)`` (radians) at longitude φ, and its directors
            rotated about e₃ by ``director_amplitude·sin(director_mode·φ + director_phase)``.
            ``"arrays"``: ``frames`` ``(n, 3, 3)`` (directors as columns), optional ``holonomy``.
        **params
            The shape's parameters, and optionally ``velocity`` (so(3) components N, ``(3,)``
            or ``(n, 3)``) and/or ``physical_velocity`` ((V₁, V₂, Ω_n), same shapes); they add.

        Returns
        -------
        cartan.problem.InitialState
        """
        if grid.d != 1:
            raise ValueError(f"{self.name} needs a grid with d = 1, got d = {grid.d}")
        velocity = params.pop("velocity", None)
        physical = params.pop("physical_velocity", None)
        builders = {
            "great-circle": self._great_circle,
            "latitude": self._latitude,
            "arc": self._arc,
            "perturbed": self._perturbed,
            "arrays": self._arrays,
        }
        if kind not in builders:
            return super().initial_state(grid, kind, **params)
        build = builders[kind]
        check_keywords(kind, build, params, ("velocity", "physical_velocity"))
        periodic = grid.periodic[0]
        if kind in ("great-circle", "latitude", "perturbed") and not periodic:
            raise ValueError(f"initial kind {kind!r} is a closed rod and needs a periodic grid")
        holonomy = None
        if kind == "arc" and periodic:
            Phi, holonomy = close_on_periodic_grid(self.group, grid, lambda g: build(g, **params))
        elif kind == "arrays":
            Phi, holonomy = build(grid, **params)
        else:
            Phi = build(grid, **params)
        N = self._velocities(grid.shape[0], velocity, physical)
        return InitialState(Phi=Phi, N=N, holonomy=holonomy)

    # geometry builders: frames (n, 3, 3), directors as columns
    def _longitudes(self, grid: Grid, winding: Any, phase: Any) -> np.ndarray:
        w = _integer("winding", winding)
        ph = float(check_finite("phase", phase, ()))
        n = grid.shape[0]
        return ph + 2.0 * math.pi * w * np.arange(n) / n

    def _latitude(self, grid, colatitude=None, axis=None, winding=1, phase=0.0):
        if colatitude is None:
            raise ValueError("initial kind 'latitude' needs 'colatitude' (radians, in (0, π))")
        beta = float(check_finite("colatitude", colatitude, ()))
        if not 0.0 < beta < math.pi:
            raise ValueError(f"colatitude must be in (0, π), got {colatitude!r}")
        A = _rotation_z_to(_Z if axis is None else _unit("axis", axis))
        phi = self._longitudes(grid, winding, phase)
        c, s = np.cos(phi), np.sin(phi)
        sb, cb = math.sin(beta), math.cos(beta)
        e3 = np.stack([sb * c, sb * s, np.full_like(c, cb)], axis=-1)
        e1 = np.stack([-s, c, np.zeros_like(c)], axis=-1)
        R = np.stack([e1, np.cross(e3, e1), e3], axis=-1)
        return A @ R

    def _great_circle(self, grid, axis=None, winding=1, phase=0.0):
        return self._latitude(grid, colatitude=math.pi / 2, axis=axis, winding=winding, phase=phase)

    def _arc(self, grid, stretch=None, shear=0.0, curvature=0.0, point=None, direction=None, centered=False):
        theta1 = self.rest_stretch if stretch is None else float(check_positive("stretch", stretch, shape=()))
        theta2 = float(check_finite("shear", shear, ()))
        kappa = float(check_finite("curvature", curvature, ()))
        e3 = _Z if point is None else _unit("point", point)
        d = np.array([1.0, 0.0, 0.0]) if direction is None else _unit("direction", direction)
        R0 = _frames(e3[None], d[None])[0]
        s = grid.coordinates(0)
        if centered:
            s = s - 0.5 * grid.length[0]
        X = self.strain_components(theta1, theta2, kappa)
        return R0 @ self.group.exp(s[:, None] * X)

    def _perturbed(self, grid, amplitude=0.3, mode=2, phase=0.0, director_amplitude=0.0, director_mode=None,
                   director_phase=0.0, axis=None, winding=1):
        a = float(check_finite("amplitude", amplitude, ()))
        if abs(a) >= math.pi / 2:
            raise ValueError(f"amplitude must be in (−π/2, π/2) (a latitude in radians), got {amplitude!r}")
        # more waves than nodes only aliases a lower mode (and sin(m φ) loses every digit)
        m = _integer("mode", mode, maximum=grid.shape[0])
        ph = float(check_finite("phase", phase, ()))
        b = float(check_finite("director_amplitude", director_amplitude, ()))
        md = m if director_mode is None else _integer("director_mode", director_mode, maximum=grid.shape[0])
        phd = float(check_finite("director_phase", director_phase, ()))
        A = _rotation_z_to(_Z if axis is None else _unit("axis", axis))
        phi = self._longitudes(grid, winding, 0.0)
        lam = a * np.sin(m * phi + ph)
        dlam = a * m * np.cos(m * phi + ph)
        c, s, cl, sl = np.cos(phi), np.sin(phi), np.cos(lam), np.sin(lam)
        e3 = np.stack([cl * c, cl * s, sl], axis=-1)
        tangent = np.stack([-sl * dlam * c - cl * s, -sl * dlam * s + cl * c, cl * dlam], axis=-1)
        R = _frames(e3, tangent)
        psi = b * np.sin(md * phi + phd)
        cp, sp = np.cos(psi), np.sin(psi)
        e1 = cp[:, None] * R[..., 0] + sp[:, None] * R[..., 1]
        e2 = -sp[:, None] * R[..., 0] + cp[:, None] * R[..., 1]
        R = np.stack([e1, e2, R[..., 2]], axis=-1)
        return A @ R

    def _arrays(self, grid, frames=None, holonomy=None):
        n = grid.shape[0]
        if frames is None:
            raise ValueError("initial kind 'arrays' needs 'frames' (n, 3, 3), directors as columns")
        R = check_finite("frames", frames, (n, 3, 3))
        if np.any(self.group.defect(R) > 1e-8):
            raise ValueError("frames must be proper rotations (orthonormal directors as columns, det = +1)")
        H = None
        if holonomy is not None:
            H = check_finite("holonomy", holonomy, (3, 3))
            if float(self.group.defect(H)) > 1e-8:
                raise ValueError("holonomy must be a proper rotation")
        return R, H

    def _velocities(self, n: int, velocity: Any, physical: Any) -> np.ndarray:
        N = np.zeros((n, 3))
        for name, value in (("velocity", velocity), ("physical_velocity", physical)):
            if value is None:
                continue
            v = check_finite(name, value)
            if v.shape not in ((3,), (n, 3)):
                raise ValueError(f"{name} must have shape (3,) or ({n}, 3), got {v.shape}")
            N = N + (v if name == "velocity" else self.velocity_components(v[..., 0], v[..., 1], v[..., 2]))
        return N
