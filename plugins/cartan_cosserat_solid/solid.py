"""Finite-rotation micropolar (Cosserat) solids on SE(3) (paper §VI.A).

(M, X, G) = (a box ⊂ R³, F(E³), SE(3)), d = 3.  A configuration ``q = (x, R)`` is a point
``x`` of the deformed body and an orthonormal triad ``R = (e₁ e₂ e₃)`` (the micro-rotation),
stored as the 4 × 4 matrix ``Φ = [[1, 0ᵀ], [x, R]]`` (homogeneous coordinate first, q_r = I₄).

Fields (body frame, paper §VI.A), components translation first
------------------------------------------------------------------
strain   X_α = Φ⁻¹∂_αΦ = {θ_α; π_α}   θ_α = Rᵀ∂_αx,  π̂_α = Rᵀ∂_αR       (α = u, v, w)
velocity N   = Φ⁻¹∂_tΦ = {V; Ω}
stress   Q^α = ∂U/∂X_α = {F^α; M^α}   F^α: force stress, M^α: couple stress on the face ⊥ α
balance  D_tP = D_αF^α + f,  D_tL = D_αM^α + θ_α × F^α + m

Convention
----------
The material axes u, v, w are the reference directions e₁, e₂, e₃ (the reference
placement is x = (u, v, w), R = I, so that the rest strain is θ₀_α = e_α, π₀_α = 0).  The
Cosserat strain and wryness tensors are the rows

    E_{αk} = θ_{α,k} − θ₀_{α,k},      K_{αk} = π_{α,k} − π₀_{α,k},

the first index the material (derivative) direction, the second the body-frame component.
Linearised about the reference (x = u + displacement, R = exp(φ̂)), E_{αk} → u_{k,α} +
e_{kαm}φ_m and K_{αk} → φ_{k,α}: Eringen's ε_kl = u_{l,k} + e_{lkm}φ_m and wryness φ_{l,k}
with (k, l) = (α, k).  The energy per unit reference volume is

    U = ½λ (tr E)² + ½(μ + κ) E:E + ½μ E:Eᵀ + ½α (tr K)² + ½β K:Kᵀ + ½γ K:K,

so that ``F^α_k = ∂U/∂E_{αk} = λ tr E δ_{αk} + (μ + κ) E_{αk} + μ E_{kα}`` (Eringen's
t_kl = λε_rr δ_kl + (μ+κ)ε_kl + μ ε_lk) and ``M^α_k = α tr K δ_{αk} + β K_{kα} + γ K_{αk}``
(m_kl = αφ_{r,r}δ_kl + βφ_{k,l} + γφ_{l,k}); the classical shear modulus is μ + κ/2.  U is
quadratic in the frame-indifferent strains, so the medium is a
:class:`~cartan.medium.QuadraticMedium` with a full, axis-coupled 18 × 18 stiffness (the numpy
reference path), and declares closed-form numba point kernels of the same energy for the
compiled loops.  The kinetic energy is
``K = ½ρ|V|² + ½ρj|Ω|²``.

Stress tensors in the spatial frame (outputs)
--------------------------------------------
Q^α is per unit reference area and in body components.  The nominal tensors
``P_{iα} = (R F^α)_i``, ``C_{iα} = (R M^α)_i`` (face normal the second index: the traction on a
face of outer reference normal N is P N) and the Cauchy tensors ``σ = P Fᵀ/J``, ``C Fᵀ/J``
(F_{iα} = (R θ_α)_i, J = det F; per unit current area) are recorded as tensors per node,
variables ``(time, u, v, w, row, axis)`` and ``(time, u, v, w, row, normal)``
(:data:`STRESS_OUTPUTS`); for small strains P_{iα} → t_{αi}, C_{iα} → m_{αi}, Eringen's
tensors transposed.

Charts
------
The energy above is per unit reference volume of an orthonormal chart (θ₀_α = e_α).  A
stress-free reference Φ_ref = (x_ref, R_ref) of a general chart (``Problem(..., reference=Φ_ref)``,
e.g. a disk charted by a square) has the rest strain θ₀_α = R_refᵀ∂_αx_ref: the rows of
Θ₀[α, k] = θ₀_αk, whose pull-back metric is g = Θ₀Θ₀ᵀ.  Since ∂_α = Σ_j Θ₀[α, j] ∂_j (∂_j the
derivative along the reference director j), the strains in the orthonormal frame of the
reference directors are Θ₀⁻¹E and Θ₀⁻¹K, and the reference volume is det Θ₀ per unit chart
volume, so the energy per unit chart volume is

    U_chart(X; X₀) = det Θ₀ · U(Θ₀⁻¹(X − X₀)),   Q[α] = det Θ₀ Σ_j (Θ₀⁻¹)_{jα} Q_phys[j],

(:meth:`CosseratSolid.potential_at`, the point kernels), which is U itself when Θ₀ = I; det Θ₀ > 0
(a right-handed chart) is required.  The rest of the solid reads the chart too (docs/design.md,
"Charts of a disk"):

* mass — the reference volume per unit chart volume is J = det Θ₀
  (:meth:`CosseratSolid.reference_volume`), so the lattice gives a node the mass ρJw and the
  micro-inertia ρjJw (w the chart's quadrature weight), and its body loads per unit reference
  volume the same weight;
* face loads — a traction (couple) per unit reference area on the face ⊥ α is integrated with
  the face's reference area element det Θ₀ |Θ₀⁻¹e_α| per unit chart area
  (:meth:`CosseratSolid.reference_area`; the area of the face spanned by θ₀_β × θ₀_γ);
* outputs (:meth:`CosseratSolid.outputs` with the reference) — the displacement x − x_ref and the
  micro-rotation log(R R_refᵀ) relative to the rest configuration, and the stresses of the
  physical strains in the orthonormal frame of the reference directors, Θ₀⁻¹X: the body tensors
  Q_phys[j] (row j the face ⊥ the reference director j, per unit reference area), the nominal
  P = R F_physᵀ R_refᵀ (per unit reference area, column J the face of reference normal e_J, so
  that the traction on a face of outer reference normal N is P N) and the Cauchy σ = P F_refᵀ/J_ref
  with F_ref = ∂x/∂x_ref = R (Θ₀⁻¹Θ)ᵀ R_refᵀ the deformation gradient from the rest
  configuration (per unit current area).  At nodes of the identity chart (X₀ = (e_α, 0) and
  R_ref = I exactly) they are the formulas above, to the bit.

Positive definiteness (Eringen, *Microcontinuum Field Theories I*, §5.3): with E split into its
deviatoric, spherical and skew parts, U = ½(λ + (2μ+κ)/3)(tr E)² + ½(2μ+κ)|dev sym E|² +
½κ|skw E|² + ½(α + (β+γ)/3)(tr K)² + ½(β+γ)|dev sym K|² + ½(γ−β)|skw K|², so U > 0 for every
non-zero strain iff 3λ + 2μ + κ > 0, 2μ + κ > 0, κ > 0, 3α + β + γ > 0, β + γ > 0, γ − β > 0.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numba import njit

import cartan
from cartan.medium import (
    MediumKernels,
    QuadraticMedium,
    check_finite,
    check_keywords,
    check_positive,
)
from cartan.problem import ConstantFieldPotential, InitialState, PotentialLoad
from cartan.supports import PenaltySupport, SymmetrySupport

__all__ = [
    "translation_holonomies",
    "CentreSupport",
    "disk_chart",
    "CosseratSolid",
    "STRESS_OUTPUTS",
    "stress_tensor",
    "Gravity",
    "eringen_stresses",
    "micropolar_stiffness",
    "rotation_vector",
    "torsion_stiffness_ratio",
]

_AXES = "uvw"

#: the stress tensors a solid can record (``output_stresses``): name → (extra dimensions of the node
#: variable, long name, units, which record set).  ``row`` (x, y, z: spatial component), ``axis``
#: (u, v, w: material axis) and ``col`` (d1, d2, d3: director) are the core's dimensions of the run
#: Dataset; ``normal`` (x, y, z: spatial direction of the face normal) is the solid's
#: (:attr:`CosseratSolid.output_coords`).  The second dimension is always the face's.
STRESS_OUTPUTS: dict[str, tuple[tuple[str, str], str, str, str]] = {
    "force_stress": (("axis", "col"), "force stress F^α_k (body frame; row α: the face ⊥ α, column k: the "
                     "component on the director d_k; per unit reference area)", "force/length^2", "body"),
    "couple_stress": (("axis", "col"), "couple stress M^α_k (body frame; row α: the face ⊥ α, column k: the "
                      "component on the director d_k; per unit reference area)", "force/length", "body"),
    "nominal_force_stress": (("row", "axis"), "nominal force stress P_iα = (R F^α)_i (row i: spatial component, "
                             "column α: the face ⊥ α; per unit reference area)", "force/length^2", "nominal"),
    "nominal_couple_stress": (("row", "axis"), "nominal couple stress C_iα = (R M^α)_i (row i: spatial component, "
                              "column α: the face ⊥ α; per unit reference area)", "force/length", "nominal"),
    "cauchy_force_stress": (("row", "normal"), "Cauchy force stress σ = P Fᵀ/J (row i: spatial component, column "
                            "j: the face with normal e_j; per unit current area)", "force/length^2", "cauchy"),
    "cauchy_couple_stress": (("row", "normal"), "Cauchy couple stress C Fᵀ/J (row i: spatial component, column j: "
                             "the face with normal e_j; per unit current area)", "force/length", "cauchy"),
}
_STRESS_SETS = ("body", "nominal", "cauchy")


@njit(cache=True)
def _orthonormal_energy(X, X0, p):  # pragma: no cover - compiled
    """U of an orthonormal chart (module docstring), ``p = (λ, μ, κ, α, β, γ)``; X, X0 ``(3, 6)``."""
    lam, mu, kap, al, be, ga = p[0], p[1], p[2], p[3], p[4], p[5]
    trE = 0.0
    trK = 0.0
    for a in range(3):
        trE += X[a, a] - X0[a, a]
        trK += X[a, 3 + a] - X0[a, 3 + a]
    EE = 0.0
    EEt = 0.0
    KK = 0.0
    KKt = 0.0
    for a in range(3):
        for k in range(3):
            e = X[a, k] - X0[a, k]
            c = X[a, 3 + k] - X0[a, 3 + k]
            EE += e * e
            EEt += e * (X[k, a] - X0[k, a])
            KK += c * c
            KKt += c * (X[k, 3 + a] - X0[k, 3 + a])
    return 0.5 * (lam * trE * trE + (mu + kap) * EE + mu * EEt + al * trK * trK + be * KKt + ga * KK)


@njit(cache=True)
def _identity_chart(X0):  # pragma: no cover - compiled
    """Whether θ₀_α = e_α (Θ₀ = I): the orthonormal chart, U itself."""
    for a in range(3):
        for k in range(3):
            if X0[a, k] != (1.0 if a == k else 0.0):
                return False
    return True


@njit(cache=True)
def _chart(X, X0, D, T):  # pragma: no cover - compiled
    """``D = Θ₀⁻¹(X − X₀)`` and ``T = Θ₀⁻¹`` (Θ₀ = X0[:, :3], module docstring "Charts");
    returns det Θ₀."""
    t = X0
    det = (t[0, 0] * (t[1, 1] * t[2, 2] - t[1, 2] * t[2, 1]) - t[0, 1] * (t[1, 0] * t[2, 2] - t[1, 2] * t[2, 0])
           + t[0, 2] * (t[1, 0] * t[2, 1] - t[1, 1] * t[2, 0]))
    inv = 1.0 / det
    T[0, 0] = (t[1, 1] * t[2, 2] - t[1, 2] * t[2, 1]) * inv
    T[0, 1] = (t[0, 2] * t[2, 1] - t[0, 1] * t[2, 2]) * inv
    T[0, 2] = (t[0, 1] * t[1, 2] - t[0, 2] * t[1, 1]) * inv
    T[1, 0] = (t[1, 2] * t[2, 0] - t[1, 0] * t[2, 2]) * inv
    T[1, 1] = (t[0, 0] * t[2, 2] - t[0, 2] * t[2, 0]) * inv
    T[1, 2] = (t[0, 2] * t[1, 0] - t[0, 0] * t[1, 2]) * inv
    T[2, 0] = (t[1, 0] * t[2, 1] - t[1, 1] * t[2, 0]) * inv
    T[2, 1] = (t[0, 1] * t[2, 0] - t[0, 0] * t[2, 1]) * inv
    T[2, 2] = (t[0, 0] * t[1, 1] - t[0, 1] * t[1, 0]) * inv
    for j in range(3):
        for k in range(6):
            s = 0.0
            for a in range(3):
                s += T[j, a] * (X[a, k] - X0[a, k])
            D[j, k] = s
    return det


@njit(cache=True)
def micropolar_energy_point(X, X0, p):  # pragma: no cover - compiled
    """U per unit chart volume at one point, ``det Θ₀ · U(Θ₀⁻¹(X − X₀))`` (module docstring,
    "Charts"; U itself for the orthonormal chart Θ₀ = I, the fast path), ``p = (λ, μ, κ, α, β, γ)``;
    X, X0 ``(3, 6)``.  The step loops never call it (only the potential energy of a saved frame
    does), so its helpers stay compiled once, out of line."""
    if _identity_chart(X0):
        return _orthonormal_energy(X, X0, p)
    D = np.empty((3, 6))
    T = np.empty((3, 3))
    det = _chart(X, X0, D, T)
    return det * _orthonormal_energy(D, np.zeros((3, 6)), p)


#: helpers of the general chart's stress, inlined into :func:`_chart_stress_rows`
_inline = njit(inline="always", error_model="numpy")


@_inline
def _combine(c0, c1, c2, r0, r1, r2):  # pragma: no cover - compiled
    """``c₀r₀ + c₁r₁ + c₂r₂`` of three 6-tuples, a 6-tuple."""
    return (c0 * r0[0] + c1 * r1[0] + c2 * r2[0], c0 * r0[1] + c1 * r1[1] + c2 * r2[1],
            c0 * r0[2] + c1 * r1[2] + c2 * r2[2], c0 * r0[3] + c1 * r1[3] + c2 * r2[3],
            c0 * r0[4] + c1 * r1[4] + c2 * r2[4], c0 * r0[5] + c1 * r1[5] + c2 * r2[5])


@_inline
def _scale(c, r):  # pragma: no cover - compiled
    """``c·r`` of a 6-tuple."""
    return (c * r[0], c * r[1], c * r[2], c * r[3], c * r[4], c * r[5])


@_inline
def _isotropic_stress(p, d0, d1, d2):  # pragma: no cover - compiled
    """The rows of ``∂U/∂D`` of the orthonormal chart's energy at the deviation D (rows d0, d1,
    d2, 6-tuples (E_α; K_α)), three 6-tuples: the formula of :func:`micropolar_stress_point`."""
    lam, mu, kap, al, be, ga = p[0], p[1], p[2], p[3], p[4], p[5]
    mk = mu + kap
    tE = lam * (d0[0] + d1[1] + d2[2])
    tK = al * (d0[3] + d1[4] + d2[5])
    return ((mk * d0[0] + mu * d0[0] + tE, mk * d0[1] + mu * d1[0], mk * d0[2] + mu * d2[0],
             ga * d0[3] + be * d0[3] + tK, ga * d0[4] + be * d1[3], ga * d0[5] + be * d2[3]),
            (mk * d1[0] + mu * d0[1], mk * d1[1] + mu * d1[1] + tE, mk * d1[2] + mu * d2[1],
             ga * d1[3] + be * d0[4], ga * d1[4] + be * d1[4] + tK, ga * d1[5] + be * d2[4]),
            (mk * d2[0] + mu * d0[2], mk * d2[1] + mu * d1[2], mk * d2[2] + mu * d2[2] + tE,
             ga * d2[3] + be * d0[5], ga * d2[4] + be * d1[5], ga * d2[5] + be * d2[5] + tK))


@njit(cache=True, error_model="numpy")
def _chart_stress_rows(p, t, r0, r1, r2):  # pragma: no cover - compiled
    """The rows of ``Q[α] = det Θ₀ Σ_j (Θ₀⁻¹)_{jα} Q_phys[j]``, Q_phys the stress of the orthonormal
    chart at D = Θ₀⁻¹(X − X₀) (module docstring, "Charts"), in scalars and tuples.

    Parameters: ``p`` the constants (a 6-tuple), ``t`` Θ₀ row by row (a 9-tuple), ``r0, r1, r2``
    the rows of X − X₀ (6-tuples); returns three 6-tuples.  Compiled once and called out of line
    from :func:`micropolar_stress_point`, with no array argument: inlined at every call site of
    the compiled loops this path, which the orthonormal chart never takes, costs ≈ 8 s more
    compile time per loop; a call with array arguments costs the kernel ≈ 40 ns per point even
    on the orthonormal path."""
    t00_, t01_, t02_, t10_, t11_, t12_, t20_, t21_, t22_ = t
    det = (t00_ * (t11_ * t22_ - t12_ * t21_) - t01_ * (t10_ * t22_ - t12_ * t20_)
           + t02_ * (t10_ * t21_ - t11_ * t20_))
    inv = 1.0 / det
    t00 = (t11_ * t22_ - t12_ * t21_) * inv  # T = Θ₀⁻¹
    t01 = (t02_ * t21_ - t01_ * t22_) * inv
    t02 = (t01_ * t12_ - t02_ * t11_) * inv
    t10 = (t12_ * t20_ - t10_ * t22_) * inv
    t11 = (t00_ * t22_ - t02_ * t20_) * inv
    t12 = (t02_ * t10_ - t00_ * t12_) * inv
    t20 = (t10_ * t21_ - t11_ * t20_) * inv
    t21 = (t01_ * t20_ - t00_ * t21_) * inv
    t22 = (t00_ * t11_ - t01_ * t10_) * inv
    q0, q1, q2 = _isotropic_stress(p, _combine(t00, t01, t02, r0, r1, r2), _combine(t10, t11, t12, r0, r1, r2),
                                   _combine(t20, t21, t22, r0, r1, r2))  # Q_phys of D = Θ₀⁻¹(X − X₀)
    return (_scale(det, _combine(t00, t10, t20, q0, q1, q2)),  # Q[α] = det Θ₀ Σ_j T_jα Q_phys[j]
            _scale(det, _combine(t01, t11, t21, q0, q1, q2)), _scale(det, _combine(t02, t12, t22, q0, q1, q2)))


@njit(cache=True)
def micropolar_stress_point(X, X0, p, Q):  # pragma: no cover - compiled
    """``Q = ∂U/∂X`` at one point (Q ``(3, 6)``, distinct from X and X0): F^α_k = λ trE δ_αk +
    (μ+κ)E_αk + μE_kα, M^α_k = α trK δ_αk + γK_αk + βK_kα in the orthonormal chart (the fast
    path), and ``Q[α] = det Θ₀ Σ_j (Θ₀⁻¹)_{jα} Q_phys[j]`` with Q_phys the stress at
    D = Θ₀⁻¹(X − X₀) in a general one (module docstring, "Charts"; :func:`_chart_stress_rows`).

    The orthonormal chart in straight-line scalar code (the deviation read first, then the test
    of the chart), no work array: the compiled loops inline this kernel at every corner, where
    the former loops over work arrays and calls of separately compiled helpers cost ≈ 95 ns per
    point, against ≈ 20–35 ns."""
    lam, mu, kap, al, be, ga = p[0], p[1], p[2], p[3], p[4], p[5]
    e00 = X[0, 0] - X0[0, 0]
    e01 = X[0, 1] - X0[0, 1]
    e02 = X[0, 2] - X0[0, 2]
    e10 = X[1, 0] - X0[1, 0]
    e11 = X[1, 1] - X0[1, 1]
    e12 = X[1, 2] - X0[1, 2]
    e20 = X[2, 0] - X0[2, 0]
    e21 = X[2, 1] - X0[2, 1]
    e22 = X[2, 2] - X0[2, 2]
    k00 = X[0, 3] - X0[0, 3]
    k01 = X[0, 4] - X0[0, 4]
    k02 = X[0, 5] - X0[0, 5]
    k10 = X[1, 3] - X0[1, 3]
    k11 = X[1, 4] - X0[1, 4]
    k12 = X[1, 5] - X0[1, 5]
    k20 = X[2, 3] - X0[2, 3]
    k21 = X[2, 4] - X0[2, 4]
    k22 = X[2, 5] - X0[2, 5]
    if not (X0[0, 0] == 1.0 and X0[1, 1] == 1.0 and X0[2, 2] == 1.0 and X0[0, 1] == 0.0 and X0[0, 2] == 0.0
            and X0[1, 0] == 0.0 and X0[1, 2] == 0.0 and X0[2, 0] == 0.0 and X0[2, 1] == 0.0):
        q0, q1, q2 = _chart_stress_rows(
            (lam, mu, kap, al, be, ga), (X0[0, 0], X0[0, 1], X0[0, 2], X0[1, 0], X0[1, 1], X0[1, 2], X0[2, 0],
                                         X0[2, 1], X0[2, 2]),
            (e00, e01, e02, k00, k01, k02), (e10, e11, e12, k10, k11, k12), (e20, e21, e22, k20, k21, k22))
        for k in range(6):
            Q[0, k] = q0[k]
            Q[1, k] = q1[k]
            Q[2, k] = q2[k]
        return
    mk = mu + kap
    tE = lam * (e00 + e11 + e22)
    tK = al * (k00 + k11 + k22)
    Q[0, 0] = mk * e00 + mu * e00 + tE
    Q[0, 1] = mk * e01 + mu * e10
    Q[0, 2] = mk * e02 + mu * e20
    Q[1, 0] = mk * e10 + mu * e01
    Q[1, 1] = mk * e11 + mu * e11 + tE
    Q[1, 2] = mk * e12 + mu * e21
    Q[2, 0] = mk * e20 + mu * e02
    Q[2, 1] = mk * e21 + mu * e12
    Q[2, 2] = mk * e22 + mu * e22 + tE
    Q[0, 3] = ga * k00 + be * k00 + tK
    Q[0, 4] = ga * k01 + be * k10
    Q[0, 5] = ga * k02 + be * k20
    Q[1, 3] = ga * k10 + be * k01
    Q[1, 4] = ga * k11 + be * k11 + tK
    Q[1, 5] = ga * k12 + be * k21
    Q[2, 3] = ga * k20 + be * k02
    Q[2, 4] = ga * k21 + be * k12
    Q[2, 5] = ga * k22 + be * k22 + tK


def micropolar_stiffness(lam: float, mu: float, kappa: float, alpha: float, beta: float,
                         gamma: float) -> np.ndarray:
    """The stiffness ``C = ∂²U/∂X∂X`` of the isotropic micropolar energy, shape ``(18, 18)``.

    Rows and columns are the flattened strain ``X[α, k]`` → ``6α + k`` (α = u, v, w; k = θ₁,
    θ₂, θ₃, π₁, π₂, π₃), so that ``U = ½ (X − X₀)ᵀ C (X − X₀)`` (module docstring).

    Parameters
    ----------
    lam, mu, kappa, alpha, beta, gamma : float
        The micropolar constants λ, μ, κ, α, β, γ.

    Returns
    -------
    numpy.ndarray, shape ``(18, 18)``
    """
    C = np.zeros((3, 6, 3, 6))
    for a in range(3):
        for k in range(3):
            for b in range(3):
                for m in range(3):
                    C[a, k, b, m] = (lam * (a == k) * (b == m) + (mu + kappa) * (a == b) * (k == m)
                                     + mu * (a == m) * (k == b))
                    C[a, 3 + k, b, 3 + m] = (alpha * (a == k) * (b == m) + gamma * (a == b) * (k == m)
                                             + beta * (a == m) * (k == b))
    return C.reshape(18, 18)


def eringen_stresses(grad_u: np.ndarray, phi: np.ndarray, grad_phi: np.ndarray, lam: float, mu: float,
                     kappa: float, alpha: float, beta: float, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """Eringen's linear micropolar stresses (the small-strain reference of the medium).

    ε_kl = u_{l,k} + e_{lkm}φ_m,  t_kl = λ ε_rr δ_kl + (μ+κ) ε_kl + μ ε_lk,
    m_kl = α φ_{r,r} δ_kl + β φ_{k,l} + γ φ_{l,k}.

    Parameters
    ----------
    grad_u : array, shape ``[..., 3, 3]``
        ``grad_u[..., k, l] = u_{l,k}``.
    phi : array, shape ``[..., 3]``
        Micro-rotation vector φ.
    grad_phi : array, shape ``[..., 3, 3]``
        ``grad_phi[..., k, l] = φ_{l,k}``.
    lam, mu, kappa, alpha, beta, gamma : float

    Returns
    -------
    (t, m) : arrays, shape ``[..., 3, 3]``
        Force stress t_kl and couple stress m_kl.
    """
    eps = np.asarray(grad_u, dtype=float) + np.einsum("lkm,...m->...kl", _levi_civita(), phi)
    eye = np.eye(3)
    t = (lam * np.trace(eps, axis1=-2, axis2=-1)[..., None, None] * eye + (mu + kappa) * eps
         + mu * np.swapaxes(eps, -1, -2))
    K = np.asarray(grad_phi, dtype=float)
    m = (alpha * np.trace(K, axis1=-2, axis2=-1)[..., None, None] * eye + beta * np.swapaxes(K, -1, -2)
         + gamma * K)
    return t, m


def _levi_civita() -> np.ndarray:
    e = np.zeros((3, 3, 3))
    e[0, 1, 2] = e[1, 2, 0] = e[2, 0, 1] = 1.0
    e[0, 2, 1] = e[2, 1, 0] = e[1, 0, 2] = -1.0
    return e


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """The rotation vector φ of rotations R (R = exp(φ̂), |φ| ≤ π), ``[..., 3, 3]`` → ``[..., 3]``."""
    return cartan.group("SO3").log(np.asarray(R, dtype=float))


def torsion_stiffness_ratio(radius: Any, lam: float, mu: float, kappa: float, alpha: float, beta: float,
                            gamma: float) -> np.ndarray:
    """Torsional stiffness of a micropolar circular cylinder over the classical G·J (Gauthier & Jahsman 1975).

    Free lateral surface, twist rate τ, u = τz(−y, x, 0), φ_z = τz and the radial micro-rotation
    φ_r = −τr/2 + A I₁(pr) with p² = 2κ/(α + β + γ) (the couple balance reduces to a modified
    Bessel equation of order 1); m_rr(a) = 0 gives
    A = (β + γ)τ / (2[(α + β + γ) p I₀(pa) − (β + γ) I₁(pa)/a]), and the torque over the
    section is

        M = G J τ + 2πκA a² I₂(pa)/p + 2παA a I₁(pa) + (β + γ) π a² τ,

    with G = μ + κ/2 and J = πa⁴/2 (derivation in ``docs/media/cosserat-solid.md``).

    Parameters
    ----------
    radius : float or array_like
        Cylinder radius a > 0 (any shape).
    lam, mu, kappa, alpha, beta, gamma : float
        The micropolar constants (κ > 0, α + β + γ > 0).

    Returns
    -------
    numpy.ndarray
        M / (G J τ), the shape of ``radius``; → 1 as a → ∞ (the classical limit).
    """
    from scipy.special import ive  # I_n(x)·e^(−x): A·I_n is formed without overflow

    a = check_positive("radius", radius)
    if not kappa > 0 or not alpha + beta + gamma > 0:
        raise ValueError("the torsion formula needs kappa > 0 and alpha + beta + gamma > 0")
    p = math.sqrt(2 * kappa / (alpha + beta + gamma))
    x = p * a
    # A·e^x per unit twist rate
    A = (beta + gamma) / (2 * ((alpha + beta + gamma) * p * ive(0, x) - (beta + gamma) * ive(1, x) / a))
    G, J = mu + 0.5 * kappa, math.pi * a**4 / 2
    M = (G * J + 2 * math.pi * kappa * A * a**2 * ive(2, x) / p + 2 * math.pi * alpha * A * a * ive(1, x)
         + (beta + gamma) * math.pi * a**2)
    return M / (G * J)


def _stress_sets(value: Any) -> tuple[str, ...]:
    """``output_stresses`` → the recorded sets, a sub-tuple of ``("body", "nominal", "cauchy")``."""
    if value is True or value is np.True_:
        return _STRESS_SETS
    if value is False or value is np.False_:
        return ()
    items = (value,) if isinstance(value, str) else value
    try:
        items = tuple(items)
    except TypeError:
        items = (None,)
    bad = [v for v in items if v not in _STRESS_SETS]
    if bad or not items:
        raise ValueError(f"output_stresses must be True, False or a subset of {list(_STRESS_SETS)}, "
                         f"got {value!r}")
    return tuple(k for k in _STRESS_SETS if k in items)


def stress_tensor(ds: Any, name: str) -> Any:
    """A recorded stress tensor of a solid's run: the variable ``ds[name]``, checked.

    Parameters
    ----------
    ds : xarray.Dataset
        A run or equilibrium of ``cosserat-solid`` (:func:`cartan.simulate`,
        :func:`cartan.solve_static`), or a file of one read by :func:`cartan.open`.
    name : str
        A key of :data:`STRESS_OUTPUTS`: ``"nominal_force_stress"`` (P, dimensions ``row`` =
        x, y, z and ``axis`` = u, v, w), ``"nominal_couple_stress"``, ``"cauchy_force_stress"``
        (σ, ``row`` and ``normal``, both x, y, z), ``"cauchy_couple_stress"``,
        ``"force_stress"`` and ``"couple_stress"`` (body frame, ``axis`` = u, v, w and ``col`` =
        d1, d2, d3).

    Returns
    -------
    xarray.DataArray
        Dimensions ``(time, u, v, w, *tensor dimensions)``, e.g. ``(time, u, v, w, row, axis)``,
        with their labels as coordinates and the attributes ``long_name`` and ``units``.

    Raises
    ------
    ValueError
        For an unknown ``name`` or a tensor the run did not record (``output_stresses``).
    """
    if name not in STRESS_OUTPUTS:
        raise ValueError(f"name must be one of {sorted(STRESS_OUTPUTS)}, got {name!r}")
    if name not in ds:
        raise ValueError(f"the dataset has no {name!r}: record it with output_stresses containing "
                         f"{STRESS_OUTPUTS[name][3]!r}")
    return ds[name]


# ====================================================================== gravity
class Gravity(ConstantFieldPotential):
    """Uniform gravity, the configurational potential ``U(q) = −ρ g·x`` per unit reference volume.

    The core's :class:`~cartan.problem.ConstantFieldPotential` with field ``g`` and density
    ρ; the core's pull-back gives the body force ``f = ρRᵀg`` and no body couple (paper §IV.B).

    Parameters
    ----------
    g : array_like, shape ``(3,)``
        Gravitational acceleration in the spatial frame, e.g. ``(0, 0, −9.81)``.
    density : float
        Mass density ρ > 0.
    """

    def __init__(self, g: Any, density: float):
        g = check_finite("g", g, (3,))
        super().__init__(g, float(check_positive("density", density)))

    @property
    def g(self) -> np.ndarray:
        """Gravitational acceleration, shape ``(3,)``."""
        return self.field

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "gravity", "g": self.g.tolist(), "density": self.density}


class CentreSupport(PotentialLoad):
    """Springs holding the position and the frame of one node, removing the rigid motions of a
    free body: ``U = ½k|x − x̄|² + ½k_R|R − R̄|²_F`` per unit reference volume at the node,
    zero elsewhere (x̄, R̄ the held values).  A support: not multiplied by the load parameter λ
    (:attr:`cartan.problem.Load.scaled` False).  Scene load kind ``"centre-support"``
    (:meth:`CosseratSolid.make_load`: ``stiffness``, ``rotation_stiffness``, optional ``node``).

    Parameters
    ----------
    Phi : array, shape ``(*shape, 4, 4)``, optional
        The configuration whose node ``node`` is held; None: the initial state of the problem
        the support is attached to.
    node : tuple of int, optional
        The held node's index (d entries); None: the centre node ``shape // 2`` of the problem.
    stiffness : float
        k > 0 (force per unit length per unit volume).
    rotation_stiffness : float
        k_R > 0 (per unit volume); |R − R̄|²_F = 4(1 − cos φ) + … for a rotation by φ.
    """

    scaled = False  # a support: acts at every load level

    def __init__(self, Phi: np.ndarray | None = None, node: tuple[int, ...] | None = None, stiffness: float = 1.0,
                 rotation_stiffness: float = 1.0):
        for name, value in (("stiffness", stiffness), ("rotation_stiffness", rotation_stiffness)):
            if not (isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)
                    and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0 (a finite number), got {value!r}")
        self.k, self.kr = float(stiffness), float(rotation_stiffness)
        self._given_node = None if node is None else tuple(int(i) for i in node)
        self._given_held = Phi is not None
        self.node: tuple[int, ...] | None = None
        if Phi is not None:
            self._hold(np.asarray(Phi, dtype=float), self._given_node)

    def _hold(self, Phi: np.ndarray, node: tuple[int, ...] | None) -> None:
        shape = Phi.shape[:-2]
        if node is None:
            node = tuple(n // 2 for n in shape)
        if len(node) != len(shape) or not all(0 <= i < n for i, n in zip(node, shape, strict=True)):
            raise ValueError(f"node must be an index into the node shape {shape}, got {node!r}")
        self.node = tuple(int(i) for i in node)
        self.mask = np.zeros(shape)
        self.mask[self.node] = 1.0
        self.held = Phi[self.node].copy()

    def attach(self, problem: Any) -> None:
        """Hold the problem's initial state at the node (when no ``Phi`` was given)."""
        if not self._given_held:
            self._hold(np.asarray(problem.initial.Phi, dtype=float), self._given_node)

    def _check_held(self) -> None:
        if self.node is None:
            raise ValueError("CentreSupport holds nothing yet: give Phi, or attach it to a Problem")

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        self._check_held()
        d = q - self.held
        return self.mask * 0.5 * (self.k * np.sum(d[..., 1:, 0] ** 2, axis=-1)
                                  + self.kr * np.sum(d[..., 1:, 1:] ** 2, axis=(-2, -1)))

    def potential_gradient(self, q: np.ndarray) -> np.ndarray:
        self._check_held()
        d = q - self.held
        grad = np.zeros(np.shape(q))
        grad[..., 1:, 0] = self.mask[..., None] * self.k * d[..., 1:, 0]
        grad[..., 1:, 1:] = self.mask[..., None, None] * self.kr * d[..., 1:, 1:]
        return grad

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "centre-support", "node": None if self.node is None else list(self.node),
                "stiffness": self.k, "rotation_stiffness": self.kr}


def disk_chart(xi: Any, eta: Any) -> tuple[np.ndarray, np.ndarray]:
    """The elliptical map of the square [−1, 1]² onto the unit disk,
    ``x = ξ√(1 − η²/2)``, ``y = η√(1 − ξ²/2)``.

    Smooth, it takes the sides ξ = ±1, η = ±1 onto the circle (x² + y² = 1 there) and has
    ``det J = (1 − (ξ² + η²)/2)/√((1 − ξ²/2)(1 − η²/2)) > 0`` except at the four corners of the
    square, where it vanishes (a right angle cannot open to a straight one smoothly otherwise).

    Parameters
    ----------
    xi, eta : array_like
        Chart coordinates in [−1, 1] (broadcast together).

    Returns
    -------
    (x, y) : arrays
        Points of the closed unit disk.
    """
    xi = np.asarray(xi, dtype=float)
    eta = np.asarray(eta, dtype=float)
    if np.any(np.abs(xi) > 1) or np.any(np.abs(eta) > 1):
        raise ValueError("xi and eta must lie in [-1, 1]")
    return xi * np.sqrt(1 - 0.5 * eta**2), eta * np.sqrt(1 - 0.5 * xi**2)


# ====================================================================== the medium
class CosseratSolid(QuadraticMedium):
    """Isotropic micropolar (Cosserat) solid on SE(3), d = 3 (paper §VI.A).

    Parameters
    ----------
    lam : float, default 1
        Lamé constant λ.
    mu : float, default 1
        Lamé constant μ (the classical shear modulus is μ + κ/2).
    kappa : float, default 0.5
        Cosserat coupling modulus κ > 0.
    alpha, beta, gamma : float, default 0.1, 0.05, 0.1
        Curvature (couple-stress) moduli α, β, γ.
    density : float, default 1
        Mass density ρ > 0 per unit reference volume.
    micro_inertia : float, default 0.1
        Micro-inertia j > 0 (a length squared): the rotational inertia is ρj.
    output_stresses : bool or str or sequence of str, default True
        The stress tensors recorded in every saved frame, each a 3 × 3 tensor per node (the
        displacement and the micro-rotation are always recorded): ``"body"`` — F^α_k, M^α_k
        (``force_stress``, ``couple_stress``, dimensions ``(axis, col)``); ``"nominal"`` — the
        spatial nominal tensors P_{iα} = (R F^α)_i, C_{iα} = (R M^α)_i (``nominal_force_stress``,
        ``nominal_couple_stress``, ``(row, axis)``); ``"cauchy"`` — σ = P Fᵀ/J and C Fᵀ/J
        (``cauchy_force_stress``, ``cauchy_couple_stress``, ``(row, normal)``).  True records all
        three (six tensors, 54 numbers per node), False none (:data:`STRESS_OUTPUTS`).

    Raises
    ------
    ValueError
        For non-finite constants, ρ ≤ 0 or j ≤ 0, or an energy that is not positive definite,
        naming the failing condition (3λ + 2μ + κ > 0, 2μ + κ > 0, κ > 0, 3α + β + γ > 0,
        β + γ > 0, γ − β > 0); for ``output_stresses`` not a bool or a subset of
        ``("body", "nominal", "cauchy")``.

    Notes
    -----
    ``X``, ``Q`` have shape ``[..., 3, 6]`` (axis α = u, v, w; components (θ; π)), ``N``,
    ``S`` ``[..., 6]``; rest strain ``X₀[α] = (e_α, 0)``.  The material coordinates (u, v, w)
    are the reference position: the displacement output is ``x − (u, v, w)`` (``x − x_ref``
    with a ``reference`` configuration, module docstring "Charts").
    """

    name: ClassVar[str] = "cosserat-solid"
    material_dim: ClassVar[int] = 3
    #: labels of the solid's own tensor dimension (``row``, ``axis`` and ``col`` are the core's)
    output_coords: ClassVar[dict[str, Any]] = {
        "normal": ("spatial direction of the face normal", ["x", "y", "z"])}
    load_kinds: ClassVar[tuple[str, ...]] = ("gravity", "symmetry", "simple-support", "centre-support")
    initial_kinds: ClassVar[tuple[str, ...]] = ("undeformed", "stretch", "deformation", "twist", "cylinder",
                                                "arrays")

    def __init__(self, lam: float = 1.0, mu: float = 1.0, kappa: float = 0.5, alpha: float = 0.1,
                 beta: float = 0.05, gamma: float = 0.1, density: float = 1.0, micro_inertia: float = 0.1,
                 output_stresses: bool | str | tuple[str, ...] = True):
        self.space = cartan.space("frame-E3")
        self.group = self.space.group
        c = {name: float(check_finite(name, value, ())) for name, value in
             (("lam", lam), ("mu", mu), ("kappa", kappa), ("alpha", alpha), ("beta", beta), ("gamma", gamma))}
        conditions = (
            ("3·lam + 2·mu + kappa > 0 (bulk modulus)", 3 * c["lam"] + 2 * c["mu"] + c["kappa"]),
            ("2·mu + kappa > 0 (shear modulus)", 2 * c["mu"] + c["kappa"]),
            ("kappa > 0 (Cosserat coupling)", c["kappa"]),
            ("3·alpha + beta + gamma > 0", 3 * c["alpha"] + c["beta"] + c["gamma"]),
            ("beta + gamma > 0", c["beta"] + c["gamma"]),
            ("gamma − beta > 0", c["gamma"] - c["beta"]),
        )
        for text, value in conditions:
            if not value > 0:
                raise ValueError(
                    f"the micropolar energy must be positive definite: {text} fails with "
                    + ", ".join(f"{k}={v!r}" for k, v in c.items()))
        self.rho = float(check_positive("density", density, shape=()))
        self.j = float(check_positive("micro_inertia", micro_inertia, shape=()))
        self.stress_outputs = _stress_sets(output_stresses)
        self.output_stresses: bool | list[str] = (
            len(self.stress_outputs) == len(_STRESS_SETS) if len(self.stress_outputs) in (0, len(_STRESS_SETS))
            else list(self.stress_outputs))
        self.constants = c
        X0 = np.zeros((3, 6))
        X0[:, :3] = np.eye(3)
        self._set_energy(X0, micropolar_stiffness(**c))
        fields = {f"displacement_{x}": (f"displacement x_{x} − {_AXES['xyz'.index(x)]} (x_{x} − x_ref,{x} with a "
                                        f"reference configuration)", "length") for x in "xyz"}
        fields |= {f"microrotation_{x}": (f"micro-rotation vector component {x} (log R; log(R R_refᵀ) with a "
                                          f"reference configuration)", "1") for x in "xyz"}
        for name, (dims, long_name, units, which) in STRESS_OUTPUTS.items():
            if which in self.stress_outputs:
                fields[name] = (long_name, units, dims)
        self.output_fields = fields

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``CosseratSolid(**parameters())`` rebuilds it."""
        return {**self.constants, "density": self.rho, "micro_inertia": self.j,
                "output_stresses": self.output_stresses}

    def potential_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """U per unit *chart* volume at a rest strain ``X0`` that varies over the body
        (``Problem(..., reference=Φ_ref)``), by the pull-back metric of the reference chart
        (module docstring, "Charts"): ``det Θ₀ · U(Θ₀⁻¹E, Θ₀⁻¹K)`` with ``Θ₀[α, k] = θ₀_αk``,
        evaluated by the point kernels (:func:`micropolar_energy_point`).

        Parameters
        ----------
        X, X0 : arrays, shape ``[..., 3, 6]`` (broadcast together); every det Θ₀ > 0

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        return self._kernel_batch("energy", X, X0)

    def stress_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """``Q = ∂U/∂X`` of :meth:`potential_at`, ``det Θ₀ · Θ₀⁻ᵀ Q_phys(Θ₀⁻¹(X − X₀))``
        (row α: ``Σ_j (Θ₀⁻¹)_{jα} Q_phys[j]``), shape ``[..., 3, 6]``."""
        return self._kernel_batch("stress", X, X0)

    def _kernel_batch(self, which: str, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        from cartan.compiled.kernels import medium_batch

        X = np.asarray(X, dtype=float)
        lead = np.broadcast_shapes(X.shape[:-2], np.shape(X0)[:-2])
        X0f = np.ascontiguousarray(np.broadcast_to(np.asarray(X0, dtype=float), (*lead, 3, 6))).reshape(-1, 3, 6)
        det = np.linalg.det(X0f[:, :, :3]) if X0f.shape[0] else np.ones(0)
        if np.any(~(det > 0)):
            raise ValueError(f"the rest strain's rows θ₀_α must form a right-handed basis (det Θ₀ > 0), got "
                             f"min det Θ₀ = {float(np.min(det)):.3g}")
        Xf = np.ascontiguousarray(np.broadcast_to(X, (*lead, 3, 6))).reshape(-1, 3, 6)
        kernels = self.point_kernels()
        module = medium_batch(kernels)
        if which == "energy":
            out = np.empty(Xf.shape[0])
            module.energy_batch(Xf, X0f, kernels.params, out)
            return out.reshape(lead)
        Q = np.empty_like(Xf)
        module.stress_batch(Xf, X0f, kernels.params, Q)
        return Q.reshape(*lead, 3, 6)

    def inertia(self) -> np.ndarray:
        """Kinetic metric ``(ρ, ρ, ρ, ρj, ρj, ρj)`` per unit reference volume, shape ``(6,)``
        (per unit chart volume it is J = :meth:`reference_volume` times this)."""
        return np.array([self.rho] * 3 + [self.rho * self.j] * 3)

    def reference_volume(self, X0: np.ndarray) -> np.ndarray:
        """The reference volume per unit chart volume, J = det Θ₀ (module docstring, "Charts").

        Parameters
        ----------
        X0 : array, shape ``[..., 3, 6]``
            Rest strains (rows θ₀_α; Θ₀ = X0[..., :3]).

        Returns
        -------
        numpy.ndarray, shape ``[...]``
            1 exactly for the identity chart.
        """
        return np.linalg.det(np.asarray(X0, dtype=float)[..., :3])

    def reference_area(self, X0: np.ndarray, axis: int) -> np.ndarray:
        """The reference area of the face ⊥ ``axis`` per unit chart area,
        ``|θ₀_β × θ₀_γ| = det Θ₀ |Θ₀⁻¹e_axis|`` (β, γ the other axes; Θ₀⁻¹e_α is the dual
        vector of θ₀_α), shape ``[...]`` for X0 ``[..., 3, 6]``; 1 for the identity chart."""
        if axis not in (0, 1, 2):
            raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
        T = np.asarray(X0, dtype=float)[..., :3]
        return np.linalg.det(T) * np.linalg.norm(np.linalg.inv(T)[..., :, axis], axis=-1)

    def point_kernels(self) -> MediumKernels:
        """Closed-form isotropic kernels (:func:`micropolar_energy_point`,
        :func:`micropolar_stress_point`, p = (λ, μ, κ, α, β, γ)): the energy of the 18 × 18
        stiffness in about 60 operations per point instead of the 2 × 324 of the generic
        quadratic kernels."""
        c = self.constants
        params = np.array([c["lam"], c["mu"], c["kappa"], c["alpha"], c["beta"], c["gamma"]])
        return MediumKernels(micropolar_energy_point, micropolar_stress_point, params)

    @property
    def shear_modulus(self) -> float:
        """The classical shear modulus μ + κ/2."""
        return self.constants["mu"] + 0.5 * self.constants["kappa"]

    def longitudinal_speed(self) -> float:
        """Long-wave speed of longitudinal waves, √((λ + 2μ + κ)/ρ)."""
        c = self.constants
        return math.sqrt((c["lam"] + 2 * c["mu"] + c["kappa"]) / self.rho)

    def strain_tensors(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cosserat strain E and wryness K, ``X [..., 3, 6]`` → two ``[..., 3, 3]`` (rows α)."""
        D = np.asarray(X, dtype=float) - self._X0
        return D[..., :3], D[..., 3:]

    def stress_tensors(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Force stress ``t[α, k] = F^α_k`` and couple stress ``m[α, k] = M^α_k`` at strains
        ``X [..., 3, 6]``, two ``[..., 3, 3]`` arrays (per unit reference area, body frame)."""
        Q = self.stress(X)
        return Q[..., :3], Q[..., 3:]

    @staticmethod
    def deformation_gradient(frames: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The deformation gradient ``F_{iα} = ∂_α x_i = (R θ_α)_i`` from the frames and strains.

        Parameters
        ----------
        frames : array, shape ``[..., 3, 3]``
            Micro-rotations R (directors as columns).
        X : array, shape ``[..., 3, 6]``
            Strains (rows α; θ_α the first three components).

        Returns
        -------
        numpy.ndarray, shape ``[..., 3, 3]``
            ``F[..., i, α]``.
        """
        return np.asarray(frames, dtype=float) @ np.swapaxes(np.asarray(X, dtype=float)[..., :3], -1, -2)

    def nominal_stress_tensors(self, frames: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The spatial nominal force and couple stresses, per unit reference area.

        ``P_{iα} = (R F^α)_i`` and ``C_{iα} = (R M^α)_i``: column α is the force (couple) per unit
        reference area on the face whose reference normal is e_α, in spatial components i, so
        that the traction on a face of outer reference normal N is ``P N`` (a first
        Piola–Kirchhoff tensor, not symmetric).  For small strains P_{iα} → t_{αi} and
        C_{iα} → m_{αi}: Eringen's tensors transposed (his first index is the face normal).

        Parameters
        ----------
        frames : array, shape ``[..., 3, 3]``
            Micro-rotations R.
        X : array, shape ``[..., 3, 6]``
            Strains.

        Returns
        -------
        (P, C) : arrays, shape ``[..., 3, 3]``
            Rows spatial x, y, z; columns the material axes u, v, w.
        """
        R = np.asarray(frames, dtype=float)
        Q = self.stress(X)
        return R @ np.swapaxes(Q[..., :3], -1, -2), R @ np.swapaxes(Q[..., 3:], -1, -2)

    def cauchy_stress_tensors(self, frames: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Cauchy force and couple stresses ``σ = P Fᵀ/J``, ``C Fᵀ/J`` (J = det F), per unit
        current area: the force (couple) on a face of current unit normal n is σ n (C Fᵀ n/J),
        by Nanson's formula n da = J F⁻ᵀN dA.  Not symmetric for a micropolar solid.

        Parameters
        ----------
        frames : array, shape ``[..., 3, 3]``
        X : array, shape ``[..., 3, 6]``

        Returns
        -------
        (sigma, couple) : arrays, shape ``[..., 3, 3]``
            Rows and columns spatial x, y, z (column j: the face with normal e_j).
        """
        P, C = self.nominal_stress_tensors(frames, X)
        F = self.deformation_gradient(frames, X)
        Ft_J = np.swapaxes(F, -1, -2) / np.linalg.det(F)[..., None, None]
        return P @ Ft_J, C @ Ft_J

    # ------------------------------------------------------------------ loads
    def make_load(self, kind: str, **params: Any):
        """``"gravity"``: :class:`Gravity` with ``g`` (3,) and this solid's density;
        ``"centre-support"``: :class:`CentreSupport` holding the initial state's ``node``
        (default the centre node) with ``stiffness`` and ``rotation_stiffness`` (per unit volume);
        ``"symmetry"`` (:class:`cartan.supports.SymmetrySupport`: ``edges`` (faces), ``normal``,
        ``position_stiffness``, ``director_stiffness``, per unit volume) and ``"simple-support"``
        (:class:`cartan.supports.PenaltySupport`) on the faces of the block (d = 3)."""
        if kind == "centre-support":
            unknown = sorted(set(params) - {"node", "stiffness", "rotation_stiffness"})
            if unknown or not {"stiffness", "rotation_stiffness"} <= set(params):
                raise ValueError(f"load 'centre-support' takes 'stiffness', 'rotation_stiffness' and optionally 'node' "
                                 f"(it holds the problem's initial state), got {sorted(params)}")
            return CentreSupport(**params)
        if kind == "gravity":
            if set(params) != {"g"}:
                raise ValueError(f"load 'gravity' takes exactly the parameter 'g', got {sorted(params)}")
            return Gravity(params["g"], self.rho)
        if kind in ("symmetry", "simple-support"):
            if "dim" in params:
                raise ValueError(f"load {kind!r}: 'dim' is the solid's, 3; do not give it")
            support = SymmetrySupport if kind == "symmetry" else PenaltySupport
            return support(**params, dim=3)
        return super().make_load(kind, **params)

    # ------------------------------------------------------------------ outputs
    #: :meth:`outputs` reads the problem's reference configuration (the core passes it)
    outputs_read_reference: ClassVar[bool] = True

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any,
                reference: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Displacement and micro-rotation vector (node fields of shape ``grid.shape``), and the
        stress tensors of ``output_stresses`` at the nodal strains (:data:`STRESS_OUTPUTS`; the
        frames R are the nodes'), of shape ``(*grid.shape, 3, 3)``.

        Parameters
        ----------
        q : array, shape ``(*grid.shape, 4, 4)``
            The configuration.
        X : array, shape ``(*grid.shape, 3, 6)``
            Nodal strains.
        N : array, shape ``(*grid.shape, 6)``
            Velocities (not read).
        grid : cartan.grid.Grid
        reference : dict, optional
            The problem's rest configuration at the nodes, ``{"q": (*shape, 4, 4), "X0":
            (*shape, 3, 6)}`` (the core passes it for a problem with a ``reference``).  Without
            it the material coordinates are the rest placement: displacement ``x − (u, v, w)``,
            micro-rotation log R, stresses of X.  With it (module docstring, "Charts"):
            displacement ``x − x_ref``, micro-rotation log(R R_refᵀ), and the stresses of the
            chart's physical strains Θ₀⁻¹X — nominal per unit reference area (columns: the
            reference normals e_x, e_y, e_z of the rest placement), Cauchy per unit current area.
        """
        R = q[..., 1:, 1:]
        if reference is None:
            coords = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(3)], indexing="ij"), axis=-1)
            disp = q[..., 1:, 0] - coords
            phi = rotation_vector(R)
        else:
            q_ref = np.asarray(reference["q"], dtype=float)
            disp = q[..., 1:, 0] - q_ref[..., 1:, 0]
            phi = rotation_vector(R @ np.swapaxes(q_ref[..., 1:, 1:], -1, -2))
        out = {f"displacement_{x}": disp[..., i] for i, x in enumerate("xyz")}
        out |= {f"microrotation_{x}": phi[..., i] for i, x in enumerate("xyz")}
        if not self.stress_outputs:
            return out
        if reference is None:
            body = self.stress_tensors(X) if "body" in self.stress_outputs else None
            nominal = self.nominal_stress_tensors(R, X) if "nominal" in self.stress_outputs else None
            cauchy = self.cauchy_stress_tensors(R, X) if "cauchy" in self.stress_outputs else None
        else:
            body, nominal, cauchy = self._chart_stresses(R, X, reference)
        if body is not None:
            out["force_stress"], out["couple_stress"] = body
        if nominal is not None:
            out["nominal_force_stress"], out["nominal_couple_stress"] = nominal
        if cauchy is not None:
            out["cauchy_force_stress"], out["cauchy_couple_stress"] = cauchy
        return out

    def _chart_stresses(self, R: np.ndarray, X: np.ndarray, reference: dict[str, np.ndarray]) -> tuple:
        """(body, nominal, cauchy) tensor pairs (None for a set not recorded) of the physical
        strains of a general chart (module docstring, "Charts"); the identity chart's nodes by
        the formulas without a chart, to the bit."""
        X = np.asarray(X, dtype=float)
        X0 = np.asarray(reference["X0"], dtype=float)
        R_ref = np.asarray(reference["q"], dtype=float)[..., 1:, 1:]
        T = np.linalg.inv(X0[..., :3])                        # Θ₀⁻¹
        Xp = T @ X                                            # Θ₀⁻¹X: θ-part Θ₀⁻¹Θ
        Q = self.stress(T @ (X - X0) + self._X0)              # Q_phys of D = Θ₀⁻¹(X − X₀)
        F = self.deformation_gradient(R, Xp)                  # R (Θ₀⁻¹Θ)ᵀ = F_ref R_ref
        P = R @ np.swapaxes(Q[..., :3], -1, -2)               # columns: the reference directors
        C = R @ np.swapaxes(Q[..., 3:], -1, -2)
        Ft_J = np.swapaxes(F, -1, -2) / np.linalg.det(F)[..., None, None]
        R_ref_t = np.swapaxes(R_ref, -1, -2)
        sets = {"body": (Q[..., :3], Q[..., 3:]), "nominal": (P @ R_ref_t, C @ R_ref_t),
                "cauchy": (P @ Ft_J, C @ Ft_J)}
        identity = np.all(X0 == self._X0, axis=(-2, -1)) & np.all(R_ref == np.eye(3), axis=(-2, -1))
        if identity.any():
            Xi, Ri = X[identity], R[identity]
            plain = {"body": self.stress_tensors(Xi), "nominal": self.nominal_stress_tensors(Ri, Xi),
                     "cauchy": self.cauchy_stress_tensors(Ri, Xi)}
            for key, pair in plain.items():
                for full, part in zip(sets[key], pair, strict=True):
                    full[identity] = part
        return tuple(sets[k] if k in self.stress_outputs else None for k in _STRESS_SETS)

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial structure field and velocity on a d = 3 grid.

        Parameters
        ----------
        grid : cartan.grid.Grid
            d = 3.  A periodic axis α makes the box periodic up to the translation by its
            period (the state's ``holonomy[α]``, Φ(u + L_α e_α) = H_α Φ(u)): the homogeneous
            kinds ``undeformed``, ``stretch`` and ``deformation`` only.
        kind : str
            ``"undeformed"`` — x = origin + Rp·(u, v, w), frames Rp (``origin`` (3,),
            ``rotation`` a rotation vector (3,) of the rigid placement Rp);
            ``"stretch"`` — homogeneous stretch x = origin + Rp·diag(s)·(u, v, w)
            (``stretch`` (3,) > 0, ``origin``, ``rotation``): uniform strain θ_α = s_α e_α;
            ``"deformation"`` — homogeneous deformation x = origin + F·(u, v, w) with frames
            ``exp(rotation)`` (``F`` (3, 3), det F > 0): uniform θ_α = Rᵀ F e_α;
            ``"twist"`` — uniform torsion about the line through ``axis_point`` (v, w) (default:
            the centre of the cross-section) along e₁: every cross-section u = const rotated
            rigidly, with its frames, by the angle ``rate``·u about e₁ (Saint-Venant's
            kinematics without warping: π_u = (rate, 0, 0));
            ``"cylinder"`` — a circular cylinder of ``radius`` a (default L_u/2) about the line
            through the centre of the section along w, the section (u, v) charted onto the disk by
            the elliptical map (:func:`disk_chart` of ξ = 2u/L_u − 1, η = 2v/L_v − 1), twisted
            by ``twist`` τ (rad per unit length): x = R_z(τw)(a x(ξ, η), a y(ξ, η), w), frames
            R_z(τw).  It comes with its stress-free ``reference`` (the untwisted cylinder, frames
            I: the chart of the energy, module docstring "Charts"), which a Problem takes; a
            periodic w axis gets the screw holonomy (L_w e_z, R_z(τL_w)) (the reference the
            translation L_w e_z): uniform torsion of an infinite cylinder;
            ``"arrays"`` — ``positions`` ``(*shape, 3)`` and ``frames`` ``(*shape, 3, 3)``.
        **params
            Shape parameters, plus ``velocity`` (body components N, ``(6,)`` or
            ``(*shape, 6)``) and ``rigid_velocity`` (a spatial twist (v, ω) of a rigid motion
            about ``center``, default the centroid: V = Rᵀ(v + ω × (x − c)), Ω = Rᵀω).

        Returns
        -------
        cartan.problem.InitialState
        """
        if grid.d != 3:
            raise ValueError(f"{self.name} needs a grid with d = 3, got d = {grid.d}")
        velocity = params.pop("velocity", None)
        rigid = params.pop("rigid_velocity", None)
        center = params.pop("center", None)
        builders = {"undeformed": self._undeformed, "stretch": self._stretch, "deformation": self._deformation,
                    "twist": self._twist, "cylinder": self._cylinder, "arrays": self._arrays}
        if kind not in builders:
            return super().initial_state(grid, kind, **params)
        build = builders[kind]
        check_keywords(kind, build, params, ("velocity", "rigid_velocity", "center"))
        built = build(grid, **params)
        if kind == "cylinder":
            pos, frames, holonomy, reference = built
        else:
            (pos, frames), reference = built, None
            holonomy = translation_holonomies(grid, pos, kind)
        Phi = np.zeros((*grid.shape, 4, 4))
        Phi[..., 0, 0] = 1.0
        Phi[..., 1:, 0] = pos
        Phi[..., 1:, 1:] = frames
        N = np.zeros((*grid.shape, 6))
        if velocity is not None:
            v = check_finite("velocity", velocity)
            if v.shape not in ((6,), (*grid.shape, 6)):
                raise ValueError(f"velocity must have shape (6,) or {(*grid.shape, 6)}, got {v.shape}")
            N = N + v
        if rigid is not None:
            twist = check_finite("rigid_velocity", rigid, (6,))
            c = pos.reshape(-1, 3).mean(axis=0) if center is None else check_finite("center", center, (3,))
            vs = twist[:3] + np.cross(twist[3:], pos - c)
            Rt = np.swapaxes(frames, -1, -2)
            N = N + np.concatenate([np.einsum("...ij,...j->...i", Rt, vs),
                                    np.einsum("...ij,j->...i", Rt, twist[3:])], axis=-1)
        elif center is not None:
            raise ValueError("'center' is only used with 'rigid_velocity'")
        return InitialState(Phi=Phi, N=N, holonomy=holonomy, reference=reference)

    @staticmethod
    def _coords(grid) -> np.ndarray:
        return np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(3)], indexing="ij"), axis=-1)

    @staticmethod
    def _rotation(rotation: Any) -> np.ndarray:
        return cartan.group("SO3").exp(check_finite("rotation", rotation, (3,)))

    def _undeformed(self, grid, origin=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)):
        return self._stretch(grid, stretch=(1.0, 1.0, 1.0), origin=origin, rotation=rotation)

    def _stretch(self, grid, stretch=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)):
        s = check_positive("stretch", stretch, shape=(3,))
        Rp = self._rotation(rotation)
        return self._homogeneous(grid, Rp @ np.diag(s), Rp, origin)

    def _deformation(self, grid, F=None, origin=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0)):
        if F is None:
            raise ValueError("initial kind 'deformation' needs 'F' (a 3 × 3 deformation gradient)")
        F = check_finite("F", F, (3, 3))
        if not np.linalg.det(F) > 0:
            raise ValueError(f"F must have det F > 0, got det F = {np.linalg.det(F):.3g}")
        return self._homogeneous(grid, F, self._rotation(rotation), origin)

    def _homogeneous(self, grid, F: np.ndarray, R: np.ndarray, origin: Any):
        o = check_finite("origin", origin, (3,))
        pos = o + np.einsum("ij,...j->...i", F, self._coords(grid))
        return pos, np.broadcast_to(R, (*grid.shape, 3, 3)).copy()

    def _twist(self, grid, rate=0.0, axis_point=None):
        tau = float(check_finite("rate", rate, ()))
        c = (np.array([0.5 * grid.length[1], 0.5 * grid.length[2]]) if axis_point is None
             else check_finite("axis_point", axis_point, (2,)))
        X = self._coords(grid)
        angle = tau * X[..., 0]
        R = cartan.group("SO3").exp(angle[..., None] * np.array([1.0, 0.0, 0.0]))
        arm = np.zeros_like(X)
        arm[..., 1:] = X[..., 1:] - c
        pos = np.einsum("...ij,...j->...i", R, arm)
        pos[..., 0] += X[..., 0]
        pos[..., 1:] += c
        return pos, R

    def _cylinder(self, grid, radius=None, twist=0.0):
        if grid.periodic[0] or grid.periodic[1]:
            raise ValueError("initial kind 'cylinder' charts the section (u, v) by a square: axes u and v must not be "
                             "periodic")
        a = 0.5 * grid.length[0] if radius is None else float(check_positive("radius", radius, shape=()))
        tau = float(check_finite("twist", twist, ()))
        X = self._coords(grid)
        xi, eta = disk_chart(2.0 * X[..., 0] / grid.length[0] - 1.0, 2.0 * X[..., 1] / grid.length[1] - 1.0)
        ref = np.stack([a * xi, a * eta, X[..., 2]], axis=-1)
        SO3 = cartan.group("SO3")
        R = SO3.exp((tau * X[..., 2])[..., None] * np.array([0.0, 0.0, 1.0]))
        pos = np.einsum("...ij,...j->...i", R, ref)
        Phi_ref = np.zeros((*grid.shape, 4, 4))
        Phi_ref[..., 0, 0] = 1.0
        Phi_ref[..., 1:, 0] = ref
        Phi_ref[..., 1:, 1:] = np.eye(3)
        holonomy = ref_holonomy = None
        if grid.periodic[2]:
            shift = np.eye(4)
            shift[3, 0] = grid.length[2]
            screw = shift.copy()
            screw[1:, 1:] = SO3.exp(np.array([0.0, 0.0, tau * grid.length[2]]))
            holonomy, ref_holonomy = {2: screw}, {2: shift}
        return pos, R, holonomy, InitialState(Phi=Phi_ref, holonomy=ref_holonomy)

    def _arrays(self, grid, positions=None, frames=None):
        if positions is None or frames is None:
            raise ValueError("initial kind 'arrays' needs 'positions' and 'frames'")
        pos = check_finite("positions", positions, (*grid.shape, 3))
        E = check_finite("frames", frames, (*grid.shape, 3, 3))
        defect = np.linalg.norm(np.swapaxes(E, -1, -2) @ E - np.eye(3), axis=(-2, -1))
        if np.any(defect > 1e-8) or np.any(np.abs(np.linalg.det(E) - 1.0) > 1e-8):
            raise ValueError("frames must be proper rotations (orthonormal directors as columns, det = +1)")
        return pos, E


def translation_holonomies(grid, positions: np.ndarray, kind: str = "undeformed") -> dict[int, np.ndarray] | None:
    """The holonomies of a homogeneously deformed box on a grid with periodic axes: along each
    periodic axis α the translation by ``A L_α e_α`` (A the homogeneous map), read off the
    positions as ``n_α (x(u + h_α e_α) − x(u))``.

    Parameters
    ----------
    grid : cartan.grid.Grid
    positions : array, shape ``(*grid.shape, 3)``
    kind : str
        The initial kind the positions come from (for the error message).

    Returns
    -------
    dict or None
        ``{axis: H}`` with H the 4 × 4 SE(3) translation; None when no axis is periodic.

    Raises
    ------
    ValueError
        for a periodic axis of fewer than 2 nodes, or a kind that is not homogeneous.
    """
    axes = [a for a in range(grid.d) if grid.periodic[a]]
    if not axes:
        return None
    if kind not in ("undeformed", "stretch", "deformation"):
        raise ValueError(f"a periodic axis needs a homogeneous initial kind (undeformed, stretch, deformation), "
                         f"got {kind!r}")
    out = {}
    for a in axes:
        if grid.shape[a] < 2:
            raise ValueError(f"periodic axis {grid.axis_names[a]!r} needs at least 2 nodes, got {grid.shape[a]}")
        step = np.take(positions, 1, axis=a) - np.take(positions, 0, axis=a)
        H = np.eye(4)
        H[1:, 0] = grid.shape[a] * step.reshape(-1, 3)[0]
        out[a] = H
    return out
