"""The ``helfrich-membrane`` medium: a fluid lipid membrane with the Helfrich energy, adapted to
its Gauss map (paper §VII.B).

(M, X, G) = (a 2D chart (u, v), E³, SE(3)), d = 2, the kinematics of ``kirchhoff-love``
(:mod:`cartan_kirchhoff_love.kirchhoff_love`): Φ = (r, R), strains X_α = Φ⁻¹∂_αΦ = {θ_α; π_α},
the frame adapted to the Gauss map by the constrained strains θ_u,3 = θ_v,3 = 0 (e₃ the unit
normal), held by the statics' Lagrange multipliers.  Write T_αi = θ_α,i and D_αi = d_α,i
(i = 1, 2; d_α = (π_α,2, −π_α,1), ∂_α e₃ = R d_α) for the 2 × 2 tangential blocks.

Geometry (all invariant under a rotation of the frame about e₃)
    * metric a = T Tᵀ (a_αβ = θ_α·θ_β on the constraint), area element J = √det a = |det T|
      (deformed area per unit chart area);
    * second fundamental form b_αβ = ∂_α r·∂_β e₃ = (T Dᵀ)_αβ (symmetrised: b̂ = sym b);
    * mean curvature H = ½ tr(a⁻¹b) = ½ tr(D T⁻¹), the mean of the principal curvatures;
      Gauss curvature K = det b̂ / det a.

Energy per unit chart area (the Helfrich energy; the integrand in brackets is per unit
*deformed* area)
    U = J [ ½κ_b (2H − c₀)² + κ_G K + σ ] + J₀ [ ½K_a (j − 1)² + μ (tr(a₀⁻¹a)/(2j) − 1) ],

j = J/J₀ the area stretch against the rest metric a₀ (J₀ = √det a₀; the medium's rest strain is
the unit metric of a chart by arc length, other rest metrics come from
``Problem(reference=Φ_ref)``).  κ_b is the bending modulus, κ_G the Gaussian modulus, c₀ the
spontaneous curvature, σ the surface tension (energy per unit deformed area).  The second
bracket is the in-plane regularisation of the Lagrangian lattice: a fluid membrane has no shear
stiffness, so its in-plane reparametrisations cost no energy and make Newton's matrix singular;
K_a is the area-stretch modulus (lipid bilayers are locally nearly area-incompressible) and μ a
small shear modulus of the neo-Hookean isochoric invariant tr(a₀⁻¹a)/(2j) − 1 ≥ 0 (zero for
any isotropic dilation of a₀, so it adds no tension under uniform stretching).  Willmore's
energy is the case κ_G = c₀ = σ = 0 (with the regularisation).

Conventions
    * Sign of H: b_αβ = ∂_α r·∂_β e₃, so H > 0 where the surface bends away from e₃: a sphere
      of radius R with the outward normal has H = +1/R (and K = 1/R²), a cylinder of radius R
      with the outward normal 2H = +1/R.  A sphere of radius R with the outward normal has zero
      bending energy for c₀ = 2/R; a cylinder for c₀ = 1/R.
    * The factor in front of (2H)² is ½κ_b: a cylinder of radius R has ½κ_b(1/R − c₀)² per unit
      area, a sphere ½κ_b(2/R − c₀)² + κ_G/R² (8πκ_b + 4πκ_G in all for c₀ = 0).  A
      Kirchhoff plate of bending stiffness D and Poisson ratio ν has, to second order in the
      deflection, κ_b = D and κ_G = −(1 − ν)D (see ``kirchhoff-love``).
    * Integrand per unit deformed area (J multiplies it); the σ-term is σ·(deformed area).

Stress Q = ∂U/∂X (T⁻ᵀ the inverse transpose, adj b̂ the adjugate, f = ½κ_b(2H − c₀)²,
f' = κ_b(2H − c₀), A₀ = a₀⁻¹):

    ∂U/∂T = (f + σ) J T⁻ᵀ − J f' (T⁻¹DT⁻¹)ᵀ + κ_G (adj b̂ D − det b̂ T⁻ᵀ)/J
            + K_a (j − 1) J T⁻ᵀ + μ J₀ (A₀T − ½ tr(A₀a) T⁻ᵀ)/j,
    ∂U/∂D = J f' T⁻ᵀ + κ_G adj b̂ T / J,

with Q_α = (∂U/∂T_α1, ∂U/∂T_α2, 0, −∂U/∂D_α2, ∂U/∂D_α1, 0): the stress does not depend on the
constrained θ_α,3 (their multipliers are the transverse shear forces) nor on the drill π_α,3
(the Levi-Civita connection form of the adapted frame, §VII.B; the rotation about e₃ is a
gauge held at zero by the statics).

The tension of the membrane (the isotropic in-plane stress conjugate to the area at fixed
shape) is σ + K_a(j − 1), written as the output ``surface_tension`` (j, the output
``area_stretch``, measured from the problem's reference as the energy measures it).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from numba import njit

import cartan
from cartan.medium import MediumKernels, check_finite, check_positive

from .kirchhoff_love import KirchhoffLove, checked_gauge

__all__ = ["HelfrichMembrane", "helfrich_energy", "helfrich_stress"]


# ====================================================================== point kernels
@njit(cache=True)
def _helfrich(X, X0, p, Q, want):  # pragma: no cover - compiled
    """Helfrich energy density per unit chart area at one point; writes Q = ∂U/∂X ``(2, 6)``
    when ``want``.  ``p = (κ_b, κ_G, c₀, σ, K_a, μ)``; X, X₀ ``(2, 6)`` (module docstring)."""
    kb, kg, c0, sig, ka, mu = p[0], p[1], p[2], p[3], p[4], p[5]
    # tangential blocks T (θ_α,1, θ_α,2) and D (π_α,2, −π_α,1)
    t00, t01, t10, t11 = X[0, 0], X[0, 1], X[1, 0], X[1, 1]
    d00, d01, d10, d11 = X[0, 4], -X[0, 3], X[1, 4], -X[1, 3]
    det = t00 * t11 - t01 * t10
    J = abs(det)
    # T⁻¹ = [[t11, −t01], [−t10, t00]] / det
    i00, i01, i10, i11 = t11 / det, -t01 / det, -t10 / det, t00 / det
    # 2H = tr(D T⁻¹)
    tau = d00 * i00 + d01 * i10 + d10 * i01 + d11 * i11
    # b = T Dᵀ, symmetrised
    b00 = t00 * d00 + t01 * d01
    b11 = t10 * d10 + t11 * d11
    b01 = 0.5 * (t00 * d10 + t01 * d11 + t10 * d00 + t11 * d01)
    detb = b00 * b11 - b01 * b01
    x = tau - c0
    f = 0.5 * kb * x * x
    # rest metric and the regularisation
    a0uu = X0[0, 0] * X0[0, 0] + X0[0, 1] * X0[0, 1]
    a0uv = X0[0, 0] * X0[1, 0] + X0[0, 1] * X0[1, 1]
    a0vv = X0[1, 0] * X0[1, 0] + X0[1, 1] * X0[1, 1]
    det0 = a0uu * a0vv - a0uv * a0uv
    J0 = np.sqrt(det0)
    A00, A01, A11 = a0vv / det0, -a0uv / det0, a0uu / det0
    auu = t00 * t00 + t01 * t01
    auv = t00 * t10 + t01 * t11
    avv = t10 * t10 + t11 * t11
    I1 = A00 * auu + 2.0 * A01 * auv + A11 * avv
    j = J / J0
    U = J * (f + sig) + kg * detb / J + J0 * (0.5 * ka * (j - 1.0) * (j - 1.0) + mu * (0.5 * I1 / j - 1.0))
    if want:
        fp = kb * x
        # coefficient of T⁻ᵀ in ∂U/∂T
        cT = (f + sig) * J - kg * detb / J + ka * (j - 1.0) * J - 0.5 * mu * J0 * I1 / j
        # M = T⁻¹ D T⁻¹
        m00 = (i00 * d00 + i01 * d10) * i00 + (i00 * d01 + i01 * d11) * i10
        m01 = (i00 * d00 + i01 * d10) * i01 + (i00 * d01 + i01 * d11) * i11
        m10 = (i10 * d00 + i11 * d10) * i00 + (i10 * d01 + i11 * d11) * i10
        m11 = (i10 * d00 + i11 * d10) * i01 + (i10 * d01 + i11 * d11) * i11
        # adj b̂ = [[b11, −b01], [−b01, b00]]
        g = kg / J
        s = mu * J0 / j
        # ∂U/∂T_αi = cT (T⁻ᵀ)_αi − J f' M_iα + g (adj b̂ D)_αi + s (A₀ T)_αi
        gt00 = cT * i00 - J * fp * m00 + g * (b11 * d00 - b01 * d10) + s * (A00 * t00 + A01 * t10)
        gt01 = cT * i10 - J * fp * m10 + g * (b11 * d01 - b01 * d11) + s * (A00 * t01 + A01 * t11)
        gt10 = cT * i01 - J * fp * m01 + g * (-b01 * d00 + b00 * d10) + s * (A01 * t00 + A11 * t10)
        gt11 = cT * i11 - J * fp * m11 + g * (-b01 * d01 + b00 * d11) + s * (A01 * t01 + A11 * t11)
        # ∂U/∂D_αi = J f' (T⁻ᵀ)_αi + g (adj b̂ T)_αi
        gd00 = J * fp * i00 + g * (b11 * t00 - b01 * t10)
        gd01 = J * fp * i10 + g * (b11 * t01 - b01 * t11)
        gd10 = J * fp * i01 + g * (-b01 * t00 + b00 * t10)
        gd11 = J * fp * i11 + g * (-b01 * t01 + b00 * t11)
        Q[0, 0], Q[0, 1], Q[0, 2] = gt00, gt01, 0.0
        Q[1, 0], Q[1, 1], Q[1, 2] = gt10, gt11, 0.0
        # D_α1 = π_α,2, D_α2 = −π_α,1
        Q[0, 3], Q[0, 4], Q[0, 5] = -gd01, gd00, 0.0
        Q[1, 3], Q[1, 4], Q[1, 5] = -gd11, gd10, 0.0
    return U


@njit(cache=True)
def helfrich_energy(X, X0, p):  # pragma: no cover - compiled
    """Helfrich energy density U(X; X₀) per unit chart area; ``p = (κ_b, κ_G, c₀, σ, K_a, μ)``;
    X, X₀ ``(2, 6)``."""
    Q = np.empty((1, 1))
    return _helfrich(X, X0, p, Q, False)


@njit(cache=True)
def helfrich_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """Writes Q = ∂U/∂X ``(2, 6)`` (see :func:`helfrich_energy`)."""
    _helfrich(X, X0, p, Q, True)


@njit(cache=True)
def _fields(X, X0, p, out):  # pragma: no cover - compiled
    """(H, K, Helfrich energy per unit deformed area, area stretch j, tension σ + K_a(j − 1)) at
    one point, ``out`` (5,)."""
    kb, kg, c0, sig, ka = p[0], p[1], p[2], p[3], p[4]
    t00, t01, t10, t11 = X[0, 0], X[0, 1], X[1, 0], X[1, 1]
    d00, d01, d10, d11 = X[0, 4], -X[0, 3], X[1, 4], -X[1, 3]
    det = t00 * t11 - t01 * t10
    tau = (d00 * t11 - d01 * t10 - d10 * t01 + d11 * t00) / det
    b00 = t00 * d00 + t01 * d01
    b11 = t10 * d10 + t11 * d11
    b01 = 0.5 * (t00 * d10 + t01 * d11 + t10 * d00 + t11 * d01)
    K = (b00 * b11 - b01 * b01) / (det * det)
    J0 = np.sqrt((X0[0, 0] * X0[0, 0] + X0[0, 1] * X0[0, 1]) * (X0[1, 0] * X0[1, 0] + X0[1, 1] * X0[1, 1])
                 - (X0[0, 0] * X0[1, 0] + X0[0, 1] * X0[1, 1]) ** 2)
    j = abs(det) / J0
    out[0] = 0.5 * tau
    out[1] = K
    out[2] = 0.5 * kb * (tau - c0) ** 2 + kg * K
    out[3] = j
    out[4] = sig + ka * (j - 1.0)


@njit(cache=True)
def _fields_batch(X, X0, p, out):  # pragma: no cover - compiled
    for i in range(X.shape[0]):
        _fields(X[i], X0[i], p, out[i])


# ====================================================================== medium
class HelfrichMembrane(KirchhoffLove):
    """Fluid membrane with the Helfrich energy on SE(3), d = 2, adapted to its Gauss map
    (paper §VII.B): θ_α,3 = 0 held by the statics' multipliers, as for ``kirchhoff-love``.

    Parameters
    ----------
    bending_modulus : float
        κ_b (> 0), default 1.
    gaussian_modulus : float
        κ_G (finite), default 0.  The local energy is positive semi-definite in the principal
        curvatures for −2κ_b ≤ κ_G ≤ 0; on a closed surface its integral is 2πχκ_G.
    spontaneous_curvature : float
        c₀ (finite), default 0, in the convention of 2H (a cylinder of radius R with the outward
        normal is stress-free in bending for c₀ = 1/R).
    tension : float
        Surface tension σ (≥ 0), energy per unit deformed area, default 0.
    area_modulus : float
        Area-stretch modulus K_a (≥ 0), default 10: a local area penalty ½K_a(j − 1)² per unit
        rest area.
    shear_modulus : float
        In-plane shear regularisation μ (≥ 0), default 0.01: μ(tr(a₀⁻¹a)/(2j) − 1) per unit rest
        area.  A fluid membrane has μ = 0; μ > 0 removes the lattice's zero-energy in-plane
        shear modes (μ = 0 leaves Newton's matrix singular unless every in-plane motion is
        held otherwise).
    density : float
        Mass per unit area (> 0), default 1 (kinetic metric; unused by the statics).
    thickness : float
        Membrane thickness δ (> 0), default 0.01, only in the rotary inertia ρδ²/12 of the
        kinetic metric.

    gauge, umbilic : str
        The initial frames' gauge about the normal and the rule at umbilics, as for
        ``kirchhoff-love`` (``"coordinate"``, ``"error"`` by default); the energy does not
        depend on the gauge.

    Notes
    -----
    ``X``, ``Q`` have shape ``[..., 2, 6]``, components ``(θ_α; π_α)``.  Energy, stress and
    conventions: see the module docstring.  The defaults are in units of κ_b and of a body of
    unit size ℓ: K_aℓ²/κ_b = 10 holds the area to 2 % under a load 10κ_b/ℓ³ on a simply
    supported unit plate; μℓ²/κ_b = 0.01 perturbs shapes by O(μℓ²/κ_b) (0.34 % on the tube of
    :mod:`cartan_kirchhoff_love.cases`, whose closed form includes μ).
    Initial states and loads are those of ``kirchhoff-love``.
    """

    name: ClassVar[str] = "helfrich-membrane"
    #: :meth:`outputs` measures the area stretch from the problem's reference (its nodal rest strains)
    outputs_read_reference: ClassVar[bool] = True
    output_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "normal_x": ("unit normal e3 (Gauss map), x component", "1"),
        "normal_y": ("unit normal e3 (Gauss map), y component", "1"),
        "normal_z": ("unit normal e3 (Gauss map), z component", "1"),
        "mean_curvature": ("mean curvature H = tr(a^-1 b)/2, positive where the surface bends away from e3",
                           "m-1"),
        "gauss_curvature": ("Gauss curvature K = det b / det a", "m-2"),
        "helfrich_energy_density": ("kappa_b/2 (2H - c0)^2 + kappa_G K, per unit deformed area", "J m-2"),
        "area_stretch": ("deformed area per unit rest area j = sqrt(det a / det a0)", "1"),
        "surface_tension": ("membrane tension sigma + K_a (j - 1)", "N m-1"),
    }

    def __init__(self, bending_modulus: float = 1.0, gaussian_modulus: float = 0.0,
                 spontaneous_curvature: float = 0.0, tension: float = 0.0, area_modulus: float = 10.0,
                 shear_modulus: float = 0.01, density: float = 1.0, thickness: float = 0.01,
                 gauge: str = "coordinate", umbilic: str = "error"):
        self.group = cartan.group("SE3")
        self.space = cartan.space("frame-E3")
        self.kb = float(check_positive("bending_modulus", bending_modulus, shape=()))
        self.kg = float(check_finite("gaussian_modulus", gaussian_modulus, ()))
        self.c0 = float(check_finite("spontaneous_curvature", spontaneous_curvature, ()))
        self.sigma = float(check_positive("tension", tension, allow_zero=True, shape=()))
        self.ka = float(check_positive("area_modulus", area_modulus, allow_zero=True, shape=()))
        self.mu = float(check_positive("shear_modulus", shear_modulus, allow_zero=True, shape=()))
        self.rho = float(check_positive("density", density, shape=()))
        self.h = float(check_positive("thickness", thickness, shape=()))
        self.k0 = np.zeros(2)  # no rest curvature: the Helfrich energy is absolute in the curvature
        self.gauge, self.umbilic = checked_gauge(gauge, umbilic)

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``HelfrichMembrane(**parameters())`` rebuilds it."""
        return {"bending_modulus": self.kb, "gaussian_modulus": self.kg, "spontaneous_curvature": self.c0,
                "tension": self.sigma, "area_modulus": self.ka, "shear_modulus": self.mu, "density": self.rho,
                "thickness": self.h, "gauge": self.gauge, "umbilic": self.umbilic}

    @property
    def kernel_params(self) -> np.ndarray:
        """p = (κ_b, κ_G, c₀, σ, K_a, μ) of the point kernels."""
        return np.array([self.kb, self.kg, self.c0, self.sigma, self.ka, self.mu])

    @property
    def bending_stiffness(self) -> float:
        """κ_b (the D of a Kirchhoff plate)."""
        return self.kb

    @property
    def area_density(self) -> float:
        """Mass per unit area."""
        return self.rho

    def inertia(self) -> np.ndarray:
        m, j = self.rho, self.rho * self.h ** 2 / 12.0
        return np.array([m, m, m, j, j, 0.0])

    def rest_strain(self) -> np.ndarray:
        """The unit metric of a chart by arc length, flat (the curvature of X₀ is not used)."""
        X0 = np.zeros((2, 6))
        X0[0, 0] = X0[1, 1] = 1.0
        return X0

    def point_kernels(self) -> MediumKernels:
        return MediumKernels(helfrich_energy, helfrich_stress, self.kernel_params)

    # ------------------------------------------------------------------ initial states
    initial_kinds: ClassVar[tuple[str, ...]] = (*KirchhoffLove.initial_kinds, "spheroid")

    def initial_state(self, grid, kind: str, **params: Any):
        """The initial states of ``kirchhoff-love`` and the closed ``"spheroid"`` on the sphere's
        chart (``Grid((N, n), (L_u, L_v), periodic=(True, False), glued=(None, 0))``, N even): a
        vesicle of area 4π (R₀ = 1) with ``reduced_volume`` v ∈ (0, 1) (default 0.9), ``shape``
        ``"prolate"`` (default) or ``"oblate"``, or a given ``aspect`` c/a; ``spacing`` ``"angle"``
        (default) or ``"arc"`` places the colatitude nodes
        (:func:`cartan_kirchhoff_love.vesicle_sphere.spheroid_frames`).  Its glue is the sphere's."""
        if kind != "spheroid":
            return super().initial_state(grid, kind, **params)
        from cartan.medium import check_keywords
        from cartan.problem import InitialState

        from .vesicle_sphere import spheroid_frames

        check_keywords(kind, _spheroid_keywords, params)
        sphere = super().initial_state(grid, "sphere")
        return InitialState(Phi=spheroid_frames(grid, sphere.Phi, **params), glue=sphere.glue)

    def with_tension(self, tension: float) -> HelfrichMembrane:
        """A copy of the medium whose σ is ``tension`` of either sign (finite): the Lagrange
        multiplier of a held total area (:func:`cartan_kirchhoff_love.vesicle.helfrich_flow`), which
        the constructor's σ ≥ 0 does not allow; ``parameters()`` of the copy report it as given."""
        out = type(self)(**{**self.parameters(), "tension": 0.0})
        out.sigma = float(check_finite("tension", tension, ()))
        return out

    # ------------------------------------------------------------------ outputs
    def fields(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """(H, K, Helfrich energy per unit deformed area, area stretch j, tension σ + K_a(j − 1))
        at strains X ``[..., 2, 6]`` (rest strain X0, default the medium's): ``[..., 5]``."""
        X = np.asarray(X, dtype=float)
        X0 = self.rest_strain() if X0 is None else np.asarray(X0, dtype=float)
        lead = X.shape[:-2]
        Xf = np.ascontiguousarray(X.reshape(-1, 2, 6))
        X0f = np.ascontiguousarray(np.broadcast_to(X0, X.shape).reshape(-1, 2, 6))
        out = np.empty((Xf.shape[0], 5))
        _fields_batch(Xf, X0f, self.kernel_params, out)
        return out.reshape(*lead, 5)

    def resultants(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """Not defined for a fluid membrane (no thickness-integrated moments): use :meth:`fields`."""
        raise NotImplementedError("helfrich-membrane: use fields() (H, K, energy density, area stretch, tension)")

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any,
                reference: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Normal, curvatures, Helfrich energy density, area stretch and tension at the nodes
        ``[*shape]`` each.

        The area stretch j = √(det a / det a⁰) and the tension σ + K_a(j − 1) are measured from the
        problem's stress-free reference (``reference["X0"]`` ``[*shape, 2, 6]``, the nodal rest
        strains, :attr:`outputs_read_reference`), else from the medium's :meth:`rest_strain` (the
        unit metric of a chart by arc length), as the energy's area term measures them: a sphere of
        radius R by longitude and colatitude at its own reference has j = 1 and the tension σ at
        every node (from the flat metric, j would be its chart area element R² sin θ).  H, K and the
        Helfrich energy density (per unit deformed area) do not depend on the reference.  All are
        scalars: no chart components to convert."""
        f = self.fields(X, None if reference is None else reference["X0"])
        names = ["mean_curvature", "gauss_curvature", "helfrich_energy_density", "area_stretch", "surface_tension"]
        out = {name: f[..., i] for i, name in enumerate(names)}
        out["normal_x"], out["normal_y"], out["normal_z"] = q[..., 1, 3], q[..., 2, 3], q[..., 3, 3]
        return out


def _spheroid_keywords(reduced_volume: float = 0.9, shape: str = "prolate", aspect: float | None = None,
                       spacing: str = "angle") -> None:
    """The keywords of the ``"spheroid"`` initial state (:meth:`HelfrichMembrane.initial_state`)."""
