"""The special Euclidean group SE(3) in the paper's affine convention, in closed form.

Conventions (paper, Appendix "Vector and matrix operations")
------------------------------------------------------------
* A group element is the 4 × 4 matrix ``g = (a; A) = [[1, 0ᵀ], [a, A]]``: the homogeneous
  coordinate comes **first**, the translation ``a`` fills rows 1..3 of column 0 and the
  rotation ``A`` the lower-right 3 × 3 block.  It acts on ``x ∈ R³`` by ``A x + a``.
* Algebra components ``ξ = (a1, a2)``: translation ``a1`` first, rotation ``a2`` second, and
  ``hat(ξ) = {a1; a2} = [[0, 0ᵀ], [a1, â2]]`` (the paper's basis ``b_i``).
* ``ad_ξ = [[â2, â1], [0, â2]]`` and ``Ad_g = [[A, âA], [0, A]]`` (6 × 6);
  ``[ξ, η] = (a2 × b1 + a1 × b2, a2 × b2)`` for ``η = (b1, b2)``.
* ``exp(ξ) = (J(a2) a1; exp(â2))`` with ``J`` the SO(3) left Jacobian.
* ``dexp(ξ) = Σ_k ad_ξᵏ/(k+1)! = [[J, Q], [0, J]]`` with ``J = J(a2)`` and Barfoot–Furgale's
  block (their ordering ``(ρ, φ)`` is the paper's ``(a1, a2)``; ``P = â1``, ``K = â2``)::

      Q = ½P + C (KP + PK + KPK) + D (K²P + PK² − 3KPK) + E (KPK² + K²PK),
      C = (θ − sin θ)/θ³,  D = (θ² + 2 cos θ − 2)/(2θ⁴),  E = (2θ − 3 sin θ + θ cos θ)/(2θ⁵),

  ``θ = |a2|``.  ``dexp⁻¹(ξ) = [[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]`` and ``𝓔(Δt, Y) = Δt·dexp(ΔtY)``.

Numerics
--------
``D = (½ − B)/θ²`` and ``E = (3C − B)/(2θ²)`` (``B = ½ sinc²(θ/2)``) for ``θ ≥ 0.1``; below,
every coefficient comes from its six-term Taylor series in ``θ²``.  The rotation parts reuse
the SO(3) kernels of :mod:`cartan.groups.so3`; ``log`` is the SO(3) quaternion logarithm
followed by ``a1 = J⁻¹(a2) a``.  Numpy reference path and numba kernels share the
``register_jitable`` arithmetic, so they evaluate identical formulas.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ._batch import kernel_table
from ._chunks import (
    _turn,
    _turn_coeffs_direct,
    _turn_coeffs_series,
    axial_times,
    count_moved,
    load_pair_block,
    store_block,
    store_scaled_pair_block,
    turn_coeffs_chunk,
)
from .base import SymmetryGroup
from .so3 import (
    SMALL_THETA2,
    TAYLOR_A,
    TAYLOR_B,
    TAYLOR_C,
    TAYLOR_CINV,
    _C_direct,
    _cinv_direct,
    _exp_coeffs_direct,
    cross3,
    cross_np,
    dexp_inv_coeff_np,
    hat_np,
    horner,
    log_np,
    matmul3_np,
    matvec3_np,
    poly_np,
    so3_dexp_inv_coeff,
    so3_log_point,
    so3_log_trace_series,
    so3_poly_point,
    so3_vee_point,
    vee_np,
)

__all__ = [
    "SE3",
    "se3_Ad_inv_apply_point",
    "se3_Ad_point",
    "se3_E_apply_point",
    "se3_E_point",
    "se3_act_point",
    "se3_axial_flow_chunk_point",
    "se3_axis_flow_point",
    "se3_ad_point",
    "se3_bracket_point",
    "se3_compose_point",
    "se3_dexp_coeffs",
    "se3_dexp_inv_T_pair_chunk_point",
    "se3_dexp_inv_T_pair_point",
    "se3_dexp_inv_apply_point",
    "se3_dexp_inv_point",
    "se3_dexp_point",
    "se3_exp_coeffs",
    "se3_exp_point",
    "se3_hat_point",
    "se3_inverse_point",
    "se3_log_chunk_point",
    "se3_log_point",
    "se3_frames_chunk_point",
    "se3_move_chunk_point",
    "se3_vee_point",
]

#: (θ² + 2 cos θ − 2)/(2θ⁴) = Σ (−1)ᵏ tᵏ/(2k+4)!, t = θ², highest power first
TAYLOR_D = (-1.0 / 87178291200.0, 1.0 / 479001600.0, -1.0 / 3628800.0, 1.0 / 40320.0,
            -1.0 / 720.0, 1.0 / 24.0)
#: (2θ − 3 sin θ + θ cos θ)/(2θ⁵) = Σ (−1)ᵏ (k+1) tᵏ/(2k+5)!
TAYLOR_E = (-6.0 / 1307674368000.0, 5.0 / 6227020800.0, -4.0 / 39916800.0, 3.0 / 362880.0,
            -2.0 / 5040.0, 1.0 / 120.0)


# ---------------------------------------------------------------------- shared arithmetic
@register_jitable(inline='always')
def _exp_coeffs3_direct(t2):
    a, b = _exp_coeffs_direct(t2)
    return a, b, _C_direct(t2)


@register_jitable(inline='always')
def _exp_coeffs3_series(t2):
    return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)


@register_jitable(inline='always')
def _dexp_coeffs_direct(t2):
    b = _exp_coeffs_direct(t2)[1]
    c = _C_direct(t2)
    return b, c, (0.5 - b) / t2, (3.0 * c - b) / (2.0 * t2)


@register_jitable(inline='always')
def _dexp_coeffs_series(t2):
    return horner(t2, TAYLOR_B), horner(t2, TAYLOR_C), horner(t2, TAYLOR_D), horner(t2, TAYLOR_E)


@register_jitable(inline='always')
def _V_apply(w0, w1, w2, b, c, v0, v1, v2):
    """``v + b (w × v) + c w × (w × v)`` (``J(w) v`` or ``J⁻¹(w) v``) by components."""
    u0, u1, u2 = cross3(w0, w1, w2, v0, v1, v2)
    z0, z1, z2 = cross3(w0, w1, w2, u0, u1, u2)
    return v0 + b * u0 + c * z0, v1 + b * u1 + c * z1, v2 + b * u2 + c * z2


@register_jitable(inline='always')
def _Q_apply(r0, r1, r2, p0, p1, p2, c, d, e, v0, v1, v2):
    """``Q v`` for translation ``r`` (``P = r̂``), rotation ``p`` (``K = p̂``) and coefficients
    ``(C, D, E)``: ``Q = ½P + C(KP + PK + KPK) + D(K²P + PK² − 3KPK) + E(KPK² + K²PK)``
    grouped as ``½u₁ + Cu₂ + Du₃ + K(y + Kz)`` with ``u_k = P Kᵏ⁻¹v``,
    ``y = Cu₁ + (C − 3D)u₂ + Eu₃``, ``z = Du₁ + Eu₂``: seven cross products."""
    b0, b1, b2 = cross3(p0, p1, p2, v0, v1, v2)
    k0, k1, k2 = cross3(p0, p1, p2, b0, b1, b2)
    u0, u1, u2 = cross3(r0, r1, r2, v0, v1, v2)
    w0, w1, w2 = cross3(r0, r1, r2, b0, b1, b2)
    x0, x1, x2 = cross3(r0, r1, r2, k0, k1, k2)
    c3 = c - 3.0 * d
    z = cross3(p0, p1, p2, d * u0 + e * w0, d * u1 + e * w1, d * u2 + e * w2)
    y0 = c * u0 + c3 * w0 + e * x0 + z[0]
    y1 = c * u1 + c3 * w1 + e * x1 + z[1]
    y2 = c * u2 + c3 * w2 + e * x2 + z[2]
    t = cross3(p0, p1, p2, y0, y1, y2)
    return (0.5 * u0 + c * w0 + d * x0 + t[0], 0.5 * u1 + c * w1 + d * x1 + t[1],
            0.5 * u2 + c * w2 + d * x2 + t[2])


@register_jitable(inline='always')
def _compose12(g10, g20, g30, g11, g12, g13, g21, g22, g23, g31, g32, g33,
               h10, h20, h30, h11, h12, h13, h21, h22, h23, h31, h32, h33):
    """:func:`se3_compose_point` on the 12 entries ``(a; A)`` of each factor (translation
    first, then the rotation row by row), the same operations in the same order: 12 scalars."""
    return (g11 * h10 + g12 * h20 + g13 * h30 + g10,
            g21 * h10 + g22 * h20 + g23 * h30 + g20,
            g31 * h10 + g32 * h20 + g33 * h30 + g30,
            g11 * h11 + g12 * h21 + g13 * h31, g11 * h12 + g12 * h22 + g13 * h32, g11 * h13 + g12 * h23 + g13 * h33,
            g21 * h11 + g22 * h21 + g23 * h31, g21 * h12 + g22 * h22 + g23 * h32, g21 * h13 + g22 * h23 + g23 * h33,
            g31 * h11 + g32 * h21 + g33 * h31, g31 * h12 + g32 * h22 + g33 * h32, g31 * h13 + g32 * h23 + g33 * h33)


@register_jitable(inline='always')
def _inv_compose12(t0, t1, t2, r00, r01, r02, r10, r11, r12, r20, r21, r22,
                   h10, h20, h30, h11, h12, h13, h21, h22, h23, h31, h32, h33):
    """``D⁻¹h = (Rᵀ(b − t); RᵀM)`` for ``D = (t; R)`` and ``h = (b; M)`` (12 entries each, in
    :func:`_compose12`'s order), without forming ``D⁻¹``: 12 scalars."""
    u0, u1, u2 = h10 - t0, h20 - t1, h30 - t2
    return (r00 * u0 + r10 * u1 + r20 * u2, r01 * u0 + r11 * u1 + r21 * u2, r02 * u0 + r12 * u1 + r22 * u2,
            r00 * h11 + r10 * h21 + r20 * h31, r00 * h12 + r10 * h22 + r20 * h32, r00 * h13 + r10 * h23 + r20 * h33,
            r01 * h11 + r11 * h21 + r21 * h31, r01 * h12 + r11 * h22 + r21 * h32, r01 * h13 + r11 * h23 + r21 * h33,
            r02 * h11 + r12 * h21 + r22 * h31, r02 * h12 + r12 * h22 + r22 * h32, r02 * h13 + r12 * h23 + r22 * h33)


_UNIT = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


# ---------------------------------------------------------------------- numba point kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def se3_exp_coeffs(t2):
    """``(A, B, C) = (sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³)`` for ``t2 = θ²``."""
    if t2 < SMALL_THETA2:
        return _exp_coeffs3_series(t2)
    return _exp_coeffs3_direct(t2)


@njit(cache=True, inline='always')
def se3_dexp_coeffs(t2):
    """``(B, C, D, E)``: the coefficients of ``J`` and of the ``Q`` block for ``t2 = θ²``."""
    if t2 < SMALL_THETA2:
        return _dexp_coeffs_series(t2)
    return _dexp_coeffs_direct(t2)


@njit(cache=True, inline='always')
def se3_hat_point(xi, out):
    """``out`` (4, 4) ← ``{a1; a2} = [[0, 0ᵀ], [a1, â2]]`` for ``xi`` (6,)."""
    out[0, 0] = 0.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[0, 3] = 0.0
    out[1, 0] = xi[0]
    out[2, 0] = xi[1]
    out[3, 0] = xi[2]
    out[1, 1] = 0.0
    out[1, 2] = -xi[5]
    out[1, 3] = xi[4]
    out[2, 1] = xi[5]
    out[2, 2] = 0.0
    out[2, 3] = -xi[3]
    out[3, 1] = -xi[4]
    out[3, 2] = xi[3]
    out[3, 3] = 0.0


@njit(cache=True, inline='always')
def se3_vee_point(A, out):
    """``out`` (6,) ← ``(A[1:, 0], vee(A[1:, 1:]))`` for ``A`` (4, 4)."""
    out[0] = A[1, 0]
    out[1] = A[2, 0]
    out[2] = A[3, 0]
    so3_vee_point(A[1:, 1:], out[3:])


@njit(cache=True, inline='always')
def se3_compose_point(g, h, out):
    """``out`` (4, 4) ← ``g h = (A_g a_h + a_g; A_g A_h)``; ``out`` must not alias the inputs."""
    out[0, 0] = 1.0
    for j in range(1, 4):
        out[0, j] = 0.0
    for i in range(1, 4):
        out[i, 0] = g[i, 1] * h[1, 0] + g[i, 2] * h[2, 0] + g[i, 3] * h[3, 0] + g[i, 0]
        for j in range(1, 4):
            out[i, j] = g[i, 1] * h[1, j] + g[i, 2] * h[2, j] + g[i, 3] * h[3, j]


@njit(cache=True, inline='always')
def se3_inverse_point(g, out):
    """``out`` (4, 4) ← ``g⁻¹ = (−Aᵀa; Aᵀ)``; ``out`` must not alias ``g``."""
    out[0, 0] = 1.0
    for j in range(1, 4):
        out[0, j] = 0.0
    for i in range(1, 4):
        out[i, 0] = -(g[1, i] * g[1, 0] + g[2, i] * g[2, 0] + g[3, i] * g[3, 0])
        for j in range(1, 4):
            out[i, j] = g[j, i]


@njit(cache=True, inline='always')
def se3_act_point(g, x, out):
    """``out`` (3,) ← ``A x + a`` for ``g = (a; A)`` (4, 4) and ``x`` (3,)."""
    for i in range(3):
        out[i] = g[i + 1, 1] * x[0] + g[i + 1, 2] * x[1] + g[i + 1, 3] * x[2] + g[i + 1, 0]


@njit(cache=True, inline='always')
def se3_exp_point(xi, out):
    """``out`` (4, 4) ← ``exp({a1; a2}) = (J(a2) a1; exp(â2))`` for ``xi`` (6,)."""
    w0, w1, w2 = xi[3], xi[4], xi[5]
    a, b, c = se3_exp_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
    so3_poly_point(w0, w1, w2, a, b, 1.0, out[1:, 1:])
    t = _V_apply(w0, w1, w2, b, c, xi[0], xi[1], xi[2])
    out[0, 0] = 1.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[0, 3] = 0.0
    out[1, 0] = t[0]
    out[2, 0] = t[1]
    out[3, 0] = t[2]


@njit(cache=True, inline='always')
def se3_log_point(g, out):
    """``out`` (6,) ← principal logarithm of ``g`` (4, 4): ``a2 = log A``, ``a1 = J⁻¹(a2) a``."""
    so3_log_point(g[1:, 1:], out[3:])
    w0, w1, w2 = out[3], out[4], out[5]
    c = so3_dexp_inv_coeff(w0 * w0 + w1 * w1 + w2 * w2)
    t = _V_apply(w0, w1, w2, -0.5, c, g[1, 0], g[2, 0], g[3, 0])
    out[0] = t[0]
    out[1] = t[1]
    out[2] = t[2]


@njit(cache=True, inline='always')
def se3_Ad_point(g, out):
    """``out`` (6, 6) ← ``Ad_g = [[A, âA], [0, A]]`` for ``g = (a; A)`` (4, 4)."""
    a0, a1, a2 = g[1, 0], g[2, 0], g[3, 0]
    for j in range(3):
        col = cross3(a0, a1, a2, g[1, j + 1], g[2, j + 1], g[3, j + 1])
        for i in range(3):
            out[i, j] = g[i + 1, j + 1]
            out[i + 3, j + 3] = g[i + 1, j + 1]
            out[i + 3, j] = 0.0
            out[i, j + 3] = col[i]


@njit(cache=True, inline='always')
def se3_ad_point(xi, out):
    """``out`` (6, 6) ← ``ad_ξ = [[â2, â1], [0, â2]]`` for ``xi`` (6,)."""
    for i in range(3):
        for j in range(3):
            out[i + 3, j] = 0.0
    out[0, 0] = 0.0
    out[0, 1] = -xi[5]
    out[0, 2] = xi[4]
    out[1, 0] = xi[5]
    out[1, 1] = 0.0
    out[1, 2] = -xi[3]
    out[2, 0] = -xi[4]
    out[2, 1] = xi[3]
    out[2, 2] = 0.0
    for i in range(3):
        for j in range(3):
            out[i + 3, j + 3] = out[i, j]
    out[0, 3] = 0.0
    out[0, 4] = -xi[2]
    out[0, 5] = xi[1]
    out[1, 3] = xi[2]
    out[1, 4] = 0.0
    out[1, 5] = -xi[0]
    out[2, 3] = -xi[1]
    out[2, 4] = xi[0]
    out[2, 5] = 0.0


@njit(cache=True, inline='always')
def se3_bracket_point(xi, eta, out):
    """``out`` (6,) ← ``[ξ, η] = (a2 × b1 + a1 × b2, a2 × b2)``."""
    u = cross3(xi[3], xi[4], xi[5], eta[0], eta[1], eta[2])
    v = cross3(xi[0], xi[1], xi[2], eta[3], eta[4], eta[5])
    w = cross3(xi[3], xi[4], xi[5], eta[3], eta[4], eta[5])
    out[0] = u[0] + v[0]
    out[1] = u[1] + v[1]
    out[2] = u[2] + v[2]
    out[3] = w[0]
    out[4] = w[1]
    out[5] = w[2]


@njit(cache=True, inline='always')
def _se3_dexp_fill(r0, r1, r2, w0, w1, w2, s, out):
    """``out`` (6, 6) ← ``s·dexp({r; w}) = s [[J, Q], [0, J]]``."""
    b, c, d, e = se3_dexp_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
    so3_poly_point(w0, w1, w2, b, c, s, out[:3, :3])
    for j in range(3):
        q = _Q_apply(r0, r1, r2, w0, w1, w2, c, d, e, _UNIT[j][0], _UNIT[j][1], _UNIT[j][2])
        for i in range(3):
            out[i + 3, j + 3] = out[i, j]
            out[i + 3, j] = 0.0
            out[i, j + 3] = s * q[i]


@njit(cache=True, inline='always')
def se3_dexp_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ) = [[J, Q], [0, J]]`` for ``xi`` (6,)."""
    _se3_dexp_fill(xi[0], xi[1], xi[2], xi[3], xi[4], xi[5], 1.0, out)


@njit(cache=True, inline='always')
def se3_E_point(dt, xi, out):
    """``out`` (6, 6) ← ``𝓔(Δt, ξ) = Δt·dexp(Δt ξ)`` for scalar ``dt``."""
    _se3_dexp_fill(dt * xi[0], dt * xi[1], dt * xi[2], dt * xi[3], dt * xi[4], dt * xi[5], dt, out)


@njit(cache=True, inline='always')
def se3_dexp_inv_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ)⁻¹ = [[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]`` for ``xi`` (6,)."""
    r0, r1, r2, w0, w1, w2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    cinv = so3_dexp_inv_coeff(t2)
    _, c, d, e = se3_dexp_coeffs(t2)
    Jinv = out[:3, :3]
    Q = out[3:, :3]  # scratch, zeroed at the end
    so3_poly_point(w0, w1, w2, -0.5, cinv, 1.0, Jinv)
    for j in range(3):
        q = _Q_apply(r0, r1, r2, w0, w1, w2, c, d, e, _UNIT[j][0], _UNIT[j][1], _UNIT[j][2])
        for i in range(3):
            Q[i, j] = q[i]
    for j in range(3):
        t0 = Q[0, 0] * Jinv[0, j] + Q[0, 1] * Jinv[1, j] + Q[0, 2] * Jinv[2, j]
        t1 = Q[1, 0] * Jinv[0, j] + Q[1, 1] * Jinv[1, j] + Q[1, 2] * Jinv[2, j]
        t2_ = Q[2, 0] * Jinv[0, j] + Q[2, 1] * Jinv[1, j] + Q[2, 2] * Jinv[2, j]
        for i in range(3):
            out[i, j + 3] = -(Jinv[i, 0] * t0 + Jinv[i, 1] * t1 + Jinv[i, 2] * t2_)
    for i in range(3):
        for j in range(3):
            out[i + 3, j + 3] = Jinv[i, j]
            out[i + 3, j] = 0.0


@njit(cache=True, inline='always')
def se3_axis_flow_point(k, t, s, acc, work):
    """The free flow along one basis axis: ``E = exp(t b_k)``, ``s ← Ad_Eᵀ s`` and ``acc ← acc E``
    for ``s`` (6,) and ``acc`` (4, 4) in place, without the matrices; ``work`` is unused.

    A translation (``k < 3``): ``E = (t e_k; I)``, so ``Ad_Eᵀ(P; L) = (P; L − t e_k × P)`` and
    ``acc`` moves by ``t`` times its rotation's column k.  A rotation about ``e_j``
    (``j = k − 3``): ``E = (0; R)`` with R turning the plane ``(e_p, e_q)``, ``p = j + 1``,
    ``q = j + 2`` (mod 3), by cosine ``1 − Bt²`` and sine ``At`` (:func:`se3_exp_coeffs`, the
    entries of :func:`se3_exp_point` at ``ξ = t b_k``), so ``Ad_Eᵀ(P; L) = (RᵀP; RᵀL)`` and the
    rotation of ``acc`` turns its columns p and q."""
    j = k if k < 3 else k - 3
    p = j + 1 if j < 2 else 0
    q = j + 2 if j < 1 else j - 1
    if k < 3:
        s[3 + p] += t * s[q]
        s[3 + q] -= t * s[p]
        for i in range(1, 4):
            acc[i, 0] += t * acc[i, 1 + j]
        return
    c, sn = _turn_coeffs_series(t) if t * t < SMALL_THETA2 else _turn_coeffs_direct(t)
    s[p], s[q] = _turn(c, sn, s[p], s[q])
    s[3 + p], s[3 + q] = _turn(c, sn, s[3 + p], s[3 + q])
    for i in range(1, 4):
        acc[i, 1 + p], acc[i, 1 + q] = _turn(c, sn, acc[i, 1 + p], acc[i, 1 + q])


@njit(cache=True, inline='always')
def se3_axial_flow_chunk_point(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes,
                               coef):
    """The free flow of ``lie-verlet`` at the nodes ``lo ≤ i < hi`` when every piece is axial (a
    diagonal kinetic metric): piece by piece, the times ``t = τ_p (P_p)_kk S_k`` of the piece's
    directions k (zero at clamped nodes and held components), then :func:`se3_axis_flow_point`
    along each, ``S`` ``(n, 6)`` in place and the motions ``Dn`` ``(n, 4, 4)`` (whose rows
    ``lo … hi − 1`` it sets: from the identity); returns whether a node moved (a time not zero).
    The plan's arrays are those of the lattice's ``_flow_plan``: ``tau [P]``, ``naxes [P]``,
    ``axes [P, r]``, ``coef [P, r]``.

    :func:`_axial_flow_chunk`, compiled once and cached: the nodes' momenta and motions as one
    row per entry (structure of arrays), each axis flow a branch-free pass over them with the
    rows of its axis as constants (the rotation's cosine and sine from the series of
    :func:`se3_exp_coeffs`, those turning by 0.1 rad or more again by its closed form), which
    LLVM vectorises.  The operations of :func:`se3_axis_flow_point` node by node, so its results
    to the bit, except that a node whose time is zero is turned by the identity (``1·x + 0·y``:
    the same value, but ``+0`` for ``−0``) instead of being skipped."""
    return _axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes, coef)


@register_jitable(inline='always')
def _shift_node(F, i0, t, j, p, q):
    """The flow along translation ``e_j`` (``p = j + 1``, ``q = j + 2`` mod 3) by ``t`` of column
    ``i0`` of the rows ``F`` of :func:`_axial_flow_chunk`: ``L_p += t P_q``, ``L_q −= t P_p``, and
    the motion's translation ``+= t`` times its rotation's column j (:func:`se3_axis_flow_point`)."""
    F[3 + p, i0] += t * F[q, i0]
    F[3 + q, i0] -= t * F[p, i0]
    F[6, i0] += t * F[9 + j, i0]
    F[7, i0] += t * F[12 + j, i0]
    F[8, i0] += t * F[15 + j, i0]


@register_jitable(inline='always')
def _turn_node(F, i0, cs, sn, p, q):
    """The plane (p, q) of both halves of S and of the motion's rotation turned by (cos, sin) =
    ``(cs, sn)`` in column ``i0`` of the rows ``F`` of :func:`_axial_flow_chunk`
    (:func:`se3_axis_flow_point`)."""
    for u in (0, 3, 9, 12, 15):
        F[u + p, i0], F[u + q, i0] = _turn(cs, sn, F[u + p, i0], F[u + q, i0])


@njit(cache=True, error_model='numpy')
def _axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes, coef):
    lo = max(lo, 0)
    nb = hi - lo
    # rows: S (0–5), the motion's translation (6–8) and rotation row by row (9–17), from the identity
    F = np.zeros((18, nb))
    T = np.empty((6, nb))
    CS = np.empty(nb)
    SN = np.empty(nb)
    for i0 in range(nb):
        i = lo + i0
        for k in range(6):
            F[k, i0] = S[i, k]
        F[9, i0] = 1.0
        F[13, i0] = 1.0
        F[17, i0] = 1.0
    moved = 0
    for p in range(npieces):
        axial_times(F, T, lo, nb, p, tau, naxes, axes, coef, any_clamped, clamped, any_held, held)
        for c in range(naxes[p]):
            k = axes[p, c]
            moved += count_moved(T, c, nb)
            if k == 0:
                for i0 in range(nb):
                    _shift_node(F, i0, T[c, i0], 0, 1, 2)
                continue
            if k == 1:
                for i0 in range(nb):
                    _shift_node(F, i0, T[c, i0], 1, 2, 0)
                continue
            if k == 2:
                for i0 in range(nb):
                    _shift_node(F, i0, T[c, i0], 2, 0, 1)
                continue
            turn_coeffs_chunk(T, c, nb, CS, SN)
            if k == 3:
                for i0 in range(nb):
                    _turn_node(F, i0, CS[i0], SN[i0], 1, 2)
            elif k == 4:
                for i0 in range(nb):
                    _turn_node(F, i0, CS[i0], SN[i0], 2, 0)
            else:
                for i0 in range(nb):
                    _turn_node(F, i0, CS[i0], SN[i0], 0, 1)
    for i0 in range(nb):
        i = lo + i0
        for k in range(6):
            S[i, k] = F[k, i0]
        Dn[i, 0, 0] = 1.0
        Dn[i, 0, 1] = 0.0
        Dn[i, 0, 2] = 0.0
        Dn[i, 0, 3] = 0.0
        for r in range(3):
            Dn[i, 1 + r, 0] = F[6 + r, i0]
            for b in range(3):
                Dn[i, 1 + r, 1 + b] = F[9 + 3 * r + b, i0]
    return moved > 0


@njit(cache=True, inline='always')
def se3_Ad_T_point(g, v, out):
    """``out`` (6,) ← ``Ad_gᵀ v = (Aᵀv_t; Aᵀ(v_r − a × v_t))`` for ``g = (a; A)`` (4, 4)."""
    out[0], out[1], out[2], out[3], out[4], out[5] = _Ad_T12(
        g[1, 0], g[2, 0], g[3, 0], g[1, 1], g[1, 2], g[1, 3], g[2, 1], g[2, 2], g[2, 3], g[3, 1], g[3, 2], g[3, 3],
        v[0], v[1], v[2], v[3], v[4], v[5])


@register_jitable(inline='always')
def _Ad_T12(a0, a1, a2, m00, m01, m02, m10, m11, m12, m20, m21, m22, v0, v1, v2, v3, v4, v5):
    """``Ad_gᵀ v = (Aᵀv_t; Aᵀ(v_r − a × v_t))`` for ``g = (a; A)`` given by its 12 entries
    (:func:`_compose12`'s order): :func:`se3_Ad_T_point` on scalars, 6 scalars.  With
    ``v = dexp(ξ)⁻ᵀq`` and ``g = exp ξ`` it is the head term ``dexp(−ξ)⁻ᵀq`` of an edge (as
    :func:`_ad_T_add12`, to round-off)."""
    u0, u1, u2 = cross3(a0, a1, a2, v0, v1, v2)
    w0, w1, w2 = v3 - u0, v4 - u1, v5 - u2
    return (m00 * v0 + m10 * v1 + m20 * v2, m01 * v0 + m11 * v1 + m21 * v2, m02 * v0 + m12 * v1 + m22 * v2,
            m00 * w0 + m10 * w1 + m20 * w2, m01 * w0 + m11 * w1 + m21 * w2, m02 * w0 + m12 * w1 + m22 * w2)


@njit(cache=True, inline='always')
def se3_dexp_inv_T_point(xi, q, out):
    """``out`` (6,) ← ``dexp(ξ)⁻ᵀ q = (J⁻ᵀq_t; J⁻ᵀ(q_r − Qᵀ J⁻ᵀ q_t))`` without the matrix:
    ``J⁻ᵀ = I + ½K + cK²`` and ``Qᵀ(r, w) = −Q(r, −w)`` (the transpose of
    :func:`se3_dexp_inv_point`)."""
    r0, r1, r2, w0, w1, w2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    k = _pair_coeffs_series(t2) if t2 < SMALL_THETA2 else _pair_coeffs_direct(t2)
    out[0], out[1], out[2], out[3], out[4], out[5] = _dexp_inv_T12(r0, r1, r2, w0, w1, w2, k[0], k[1], k[2], k[3],
                                                                   q[0], q[1], q[2], q[3], q[4], q[5])


@njit(cache=True, inline='always')
def se3_dexp_inv_T_pair_point(xi, q, out, out_neg):
    """``out`` (6,) ← ``dexp(ξ)⁻ᵀ q`` (:func:`se3_dexp_inv_T_point`) and ``out_neg`` (6,) ←
    ``dexp(−ξ)⁻ᵀ q = dexp(ξ)⁻ᵀ q + ad_ξᵀ q`` (``dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ``), with
    ``ad_ξᵀ q = (q_t × w; q_t × r + q_r × w)``."""
    se3_dexp_inv_T_point(xi, q, out)
    out_neg[0], out_neg[1], out_neg[2], out_neg[3], out_neg[4], out_neg[5] = _ad_T_add12(
        xi[0], xi[1], xi[2], xi[3], xi[4], xi[5], q[0], q[1], q[2], q[3], q[4], q[5],
        out[0], out[1], out[2], out[3], out[4], out[5])


@register_jitable(inline='always')
def _pair_coeffs_series(t2):
    """``(c, C, D, E)``: the coefficient ``c`` of ``J⁻¹`` (:func:`so3_dexp_inv_coeff`) and those of
    the Q block (:func:`se3_dexp_coeffs`) from their series (θ² < ``SMALL_THETA2``)."""
    return horner(t2, TAYLOR_CINV), horner(t2, TAYLOR_C), horner(t2, TAYLOR_D), horner(t2, TAYLOR_E)


@register_jitable(inline='always')
def _pair_coeffs_direct(t2):
    """``(c, C, D, E)`` of :func:`_pair_coeffs_series` in closed form (θ² ≥ ``SMALL_THETA2``)."""
    _, c, d, e = _dexp_coeffs_direct(t2)
    return _cinv_direct(t2), c, d, e


@register_jitable(inline='always')
def _dexp_inv_T12(r0, r1, r2, w0, w1, w2, cinv, c, d, e, q0, q1, q2, q3, q4, q5):
    """``dexp(ξ)⁻ᵀ q = (a; J⁻ᵀ(q_r + Q(r, −w) a))``, ``a = J⁻ᵀq_t``, for ``ξ = (r; w)`` with the
    coefficients ``(c, C, D, E)`` of :func:`_pair_coeffs_series` (``Qᵀ(r, w) = −Q(r, −w)``;
    :func:`se3_dexp_inv_T_point` on scalars, branch-free): 6 scalars."""
    a0, a1, a2 = _V_apply(w0, w1, w2, 0.5, cinv, q0, q1, q2)
    b = _Q_apply(r0, r1, r2, -w0, -w1, -w2, c, d, e, a0, a1, a2)
    v0, v1, v2 = _V_apply(w0, w1, w2, 0.5, cinv, q3 + b[0], q4 + b[1], q5 + b[2])
    return a0, a1, a2, v0, v1, v2


@register_jitable(inline='always')
def _ad_T_add12(r0, r1, r2, w0, w1, w2, q0, q1, q2, q3, q4, q5, o0, o1, o2, o3, o4, o5):
    """``o + ad_ξᵀ q = o + (q_t × w; q_t × r + q_r × w)`` for ``ξ = (r; w)``: with
    ``o = dexp(ξ)⁻ᵀ q`` (:func:`_dexp_inv_T12`), ``dexp(−ξ)⁻ᵀ q`` (``dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ``),
    the head term of an edge: 6 scalars."""
    a0, a1, a2 = cross3(q0, q1, q2, w0, w1, w2)
    b0, b1, b2 = cross3(q0, q1, q2, r0, r1, r2)
    c0, c1, c2 = cross3(q3, q4, q5, w0, w1, w2)
    return o0 + a0, o1 + a1, o2 + a2, o3 + (b0 + c0), o4 + (b1 + c1), o5 + (b2 + c2)


#: edges per block of the edge passes (:func:`se3_log_chunk_point`,
#: :func:`se3_dexp_inv_T_pair_chunk_point`): their structure-of-arrays scratch (≤ 25 rows of
#: SOA_BLOCK numbers) stays in the L1 cache
SOA_BLOCK = 128


@register_jitable(inline='always')
def _log_series12(b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """``log (b; R)`` by :func:`cartan.groups.so3.so3_log_trace_series` and the series of
    ``J⁻¹``'s coefficient ``c``, branch-free: ``(a1, a2, c, bad)`` as 8 scalars, ``bad`` where
    that is not :func:`se3_log_point`'s result to round-off (θ ≥ 0.1, or not the trace case)."""
    w0, w1, w2, bad = so3_log_trace_series(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    cinv = horner(t2, TAYLOR_CINV)
    t = _V_apply(w0, w1, w2, -0.5, cinv, b0, b1, b2)
    return t[0], t[1], t[2], w0, w1, w2, cinv, bad | (t2 >= SMALL_THETA2)


@njit(cache=True, inline='always')
def se3_log_chunk_point(G, lo, hi, XI):
    """``XI[e]`` (6,) ← ``log G[e]`` for ``lo ≤ e < hi``, ``G`` ``(E, 4, 4)``, ``XI`` ``(E, 6)``:
    :func:`_log_chunk`, a function compiled once and cached (not compiled again into every
    generated module that calls it: ≈ 2–3 s of compile time each; the same for the other
    passes below)."""
    _log_chunk(G, lo, hi, XI)


@njit(cache=True, error_model='numpy')
def _log_chunk(G, lo, hi, XI):
    """``XI[e]`` (6,) ← ``log G[e]`` (:func:`se3_log_point`) for ``lo ≤ e < hi``, ``G`` ``(E, 4, 4)``,
    ``XI`` ``(E, 6)``: the edge pass of the lattice's force, vectorised across edges.

    In blocks of :data:`SOA_BLOCK` edges: the entries are copied into one row per entry
    (structure of arrays), the logarithms taken by the branch-free series of
    :func:`_log_series12` in one loop that LLVM vectorises, written back, and the edges that
    series does not cover (a turn of 0.1 rad or more; a rotation whose trace is not its largest
    diagonal entry) taken again by :func:`se3_log_point`.  The results are
    :func:`se3_log_point`'s to round-off (``atan(x)/x`` from its series instead of ``atan2``)."""
    A = np.empty((12, SOA_BLOCK))
    L = np.empty((6, SOA_BLOCK))
    bad = np.empty(SOA_BLOCK, dtype=np.bool_)
    lo = max(lo, 0)
    for c0 in range(lo, hi, SOA_BLOCK):
        nb = min(hi - c0, SOA_BLOCK)
        for e0 in range(nb):
            e = c0 + e0
            A[0, e0] = G[e, 1, 0]
            A[1, e0] = G[e, 2, 0]
            A[2, e0] = G[e, 3, 0]
            A[3, e0] = G[e, 1, 1]
            A[4, e0] = G[e, 1, 2]
            A[5, e0] = G[e, 1, 3]
            A[6, e0] = G[e, 2, 1]
            A[7, e0] = G[e, 2, 2]
            A[8, e0] = G[e, 2, 3]
            A[9, e0] = G[e, 3, 1]
            A[10, e0] = G[e, 3, 2]
            A[11, e0] = G[e, 3, 3]
        nbad = 0
        for e0 in range(nb):
            v = _log_series12(A[0, e0], A[1, e0], A[2, e0], A[3, e0], A[4, e0], A[5, e0], A[6, e0], A[7, e0],
                              A[8, e0], A[9, e0], A[10, e0], A[11, e0])
            L[0, e0] = v[0]
            L[1, e0] = v[1]
            L[2, e0] = v[2]
            L[3, e0] = v[3]
            L[4, e0] = v[4]
            L[5, e0] = v[5]
            bad[e0] = v[7]
            nbad += v[7]
        store_block(L, c0, nb, 6, XI)
        if nbad:
            for e0 in range(nb):
                if bad[e0]:
                    se3_log_point(G[c0 + e0], XI[c0 + e0])


@njit(cache=True, inline='always')
def se3_dexp_inv_T_pair_chunk_point(XI, Q, scale, lo, hi, VT, VH):
    """``VT[e]`` ← ``s_e dexp(ξ_e)⁻ᵀ q_e`` and ``VH[e]`` ← ``s_e dexp(−ξ_e)⁻ᵀ q_e`` for
    ``lo ≤ e < hi``: :func:`_dexp_inv_T_pair_chunk`, compiled once and cached (see
    :func:`se3_log_chunk_point`)."""
    _dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH)


@njit(cache=True, error_model='numpy')
def _dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH):
    """``VT[e]`` ← ``s_e dexp(ξ_e)⁻ᵀ q_e`` and ``VH[e]`` ← ``s_e dexp(−ξ_e)⁻ᵀ q_e``
    (:func:`se3_dexp_inv_T_pair_point`) for ``lo ≤ e < hi``, with ``ξ_e = XI[e]``,
    ``q_e = Q[e]`` (all ``(E, 6)``) and ``s_e = scale[e]`` (``scale`` ``(E,)``, or empty: 1):
    both ends' terms of the lattice's edge stresses, vectorised across edges.

    In blocks of :data:`SOA_BLOCK` edges, as :func:`_log_chunk`: the coefficients ``c`` of
    ``J⁻¹`` and ``C``, ``D``, ``E`` of the Q block from their series (the branch of
    :func:`so3_dexp_inv_coeff` and :func:`se3_dexp_coeffs` below θ = 0.1) and, for the edges
    turning by 0.1 rad or more, from their closed forms, first; then one branch-free loop over
    the block that LLVM vectorises.  The same coefficients and operations as
    :func:`se3_dexp_inv_T_pair_point`: its results to the bit."""
    A = np.empty((12, SOA_BLOCK))
    B = np.empty((12, SOA_BLOCK))
    K = np.empty((4, SOA_BLOCK))  # the coefficients c of J⁻¹ and C, D, E of the Q block
    lo = max(lo, 0)
    scaled = scale.shape[0] > 0
    for c0 in range(lo, hi, SOA_BLOCK):
        nb = min(hi - c0, SOA_BLOCK)
        load_pair_block(XI, Q, c0, nb, 6, A)
        nbad = 0
        for e0 in range(nb):  # the series (θ < 0.1) everywhere, then the closed forms where θ ≥ 0.1
            t2 = A[3, e0] * A[3, e0] + A[4, e0] * A[4, e0] + A[5, e0] * A[5, e0]
            nbad += t2 >= SMALL_THETA2
            K[0, e0], K[1, e0], K[2, e0], K[3, e0] = _pair_coeffs_series(t2)
        if nbad:
            for e0 in range(nb):
                t2 = A[3, e0] * A[3, e0] + A[4, e0] * A[4, e0] + A[5, e0] * A[5, e0]
                if t2 >= SMALL_THETA2:
                    K[0, e0], K[1, e0], K[2, e0], K[3, e0] = _pair_coeffs_direct(t2)
        for e0 in range(nb):
            r0, r1, r2, w0, w1, w2 = A[0, e0], A[1, e0], A[2, e0], A[3, e0], A[4, e0], A[5, e0]
            q0, q1, q2, q3, q4, q5 = A[6, e0], A[7, e0], A[8, e0], A[9, e0], A[10, e0], A[11, e0]
            o = _dexp_inv_T12(r0, r1, r2, w0, w1, w2, K[0, e0], K[1, e0], K[2, e0], K[3, e0], q0, q1, q2, q3, q4, q5)
            h = _ad_T_add12(r0, r1, r2, w0, w1, w2, q0, q1, q2, q3, q4, q5, o[0], o[1], o[2], o[3], o[4], o[5])
            B[0, e0], B[1, e0], B[2, e0], B[3, e0], B[4, e0], B[5, e0] = o
            B[6, e0], B[7, e0], B[8, e0], B[9, e0], B[10, e0], B[11, e0] = h
        store_scaled_pair_block(B, scale, scaled, c0, nb, 6, VT, VH)


@njit(cache=True, inline='always')
def se3_move_chunk_point(Di, Dn, G, tail, head, lo, hi):
    """``G[e]`` ← ``Di[tail[e]] G[e] Dn[head[e]]`` for ``lo ≤ e < hi`` (``Di[i] = Dn[i]⁻¹``; all
    ``(·, 4, 4)``): the lattice's edge update by the nodes' motions, as two
    :func:`se3_compose_point` (the same operations: their results to the bit) in scalar code,
    :func:`_move_chunk`, compiled once and cached."""
    _move_chunk(Di, Dn, G, tail, head, lo, hi)


@njit(cache=True, error_model='numpy')
def _move_chunk(Di, Dn, G, tail, head, lo, hi):
    for e in range(max(lo, 0), hi):
        i, j = tail[e], head[e]
        t = _compose12(Di[i, 1, 0], Di[i, 2, 0], Di[i, 3, 0], Di[i, 1, 1], Di[i, 1, 2], Di[i, 1, 3],
                       Di[i, 2, 1], Di[i, 2, 2], Di[i, 2, 3], Di[i, 3, 1], Di[i, 3, 2], Di[i, 3, 3],
                       G[e, 1, 0], G[e, 2, 0], G[e, 3, 0], G[e, 1, 1], G[e, 1, 2], G[e, 1, 3],
                       G[e, 2, 1], G[e, 2, 2], G[e, 2, 3], G[e, 3, 1], G[e, 3, 2], G[e, 3, 3])
        o = _compose12(t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8], t[9], t[10], t[11],
                       Dn[j, 1, 0], Dn[j, 2, 0], Dn[j, 3, 0], Dn[j, 1, 1], Dn[j, 1, 2], Dn[j, 1, 3],
                       Dn[j, 2, 1], Dn[j, 2, 2], Dn[j, 2, 3], Dn[j, 3, 1], Dn[j, 3, 2], Dn[j, 3, 3])
        _store12(G, e, o)


@register_jitable(inline='always')
def _store12(A, e, o):
    """``A[e]`` ← the SE(3) element of the 12 entries ``o`` (:func:`_compose12`'s order)."""
    A[e, 0, 0] = 1.0
    A[e, 0, 1] = 0.0
    A[e, 0, 2] = 0.0
    A[e, 0, 3] = 0.0
    A[e, 1, 0] = o[0]
    A[e, 2, 0] = o[1]
    A[e, 3, 0] = o[2]
    A[e, 1, 1] = o[3]
    A[e, 1, 2] = o[4]
    A[e, 1, 3] = o[5]
    A[e, 2, 1] = o[6]
    A[e, 2, 2] = o[7]
    A[e, 2, 3] = o[8]
    A[e, 3, 1] = o[9]
    A[e, 3, 2] = o[10]
    A[e, 3, 3] = o[11]


@njit(cache=True, inline='always')
def se3_frames_chunk_point(Dn, Di, Phi, lo, hi):
    """``Di[i]`` ← ``Dn[i]⁻¹`` (:func:`se3_inverse_point`) for ``lo ≤ i < hi``, and ``Phi[i]`` ←
    ``Phi[i] Dn[i]`` (:func:`se3_compose_point`) for the rows of ``Phi`` among them (``Phi``
    ``(f, 4, 4)``, f = n or 1): the nodes' part of the lattice's update by their motions, the same
    operations as those kernels in scalar code, :func:`_frames_chunk`, compiled once and cached."""
    _frames_chunk(Dn, Di, Phi, lo, hi)


@njit(cache=True, error_model='numpy')
def _frames_chunk(Dn, Di, Phi, lo, hi):
    lo = max(lo, 0)
    for i in range(lo, hi):
        se3_inverse_point(Dn[i], Di[i])
    for i in range(lo, min(hi, Phi.shape[0])):
        o = _compose12(Phi[i, 1, 0], Phi[i, 2, 0], Phi[i, 3, 0], Phi[i, 1, 1], Phi[i, 1, 2], Phi[i, 1, 3],
                       Phi[i, 2, 1], Phi[i, 2, 2], Phi[i, 2, 3], Phi[i, 3, 1], Phi[i, 3, 2], Phi[i, 3, 3],
                       Dn[i, 1, 0], Dn[i, 2, 0], Dn[i, 3, 0], Dn[i, 1, 1], Dn[i, 1, 2], Dn[i, 1, 3],
                       Dn[i, 2, 1], Dn[i, 2, 2], Dn[i, 2, 3], Dn[i, 3, 1], Dn[i, 3, 2], Dn[i, 3, 3])
        _store12(Phi, i, o)


@njit(cache=True, inline='always')
def se3_dexp_inv_apply_point(xi, v, out, work):
    """``out`` (6,) ← ``dexp(ξ)⁻¹ v = (J⁻¹(v_t − Q b); b)``, ``b = J⁻¹ v_r``, without the matrix
    (:func:`se3_dexp_inv_point`: ``[[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]``); ``work`` is unused."""
    r0, r1, r2, w0, w1, w2 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    cinv = so3_dexp_inv_coeff(t2)
    _, c, d, e = se3_dexp_coeffs(t2)
    b0, b1, b2 = _V_apply(w0, w1, w2, -0.5, cinv, v[3], v[4], v[5])
    q = _Q_apply(r0, r1, r2, w0, w1, w2, c, d, e, b0, b1, b2)
    a0, a1, a2 = _V_apply(w0, w1, w2, -0.5, cinv, v[0] - q[0], v[1] - q[1], v[2] - q[2])
    out[0], out[1], out[2], out[3], out[4], out[5] = a0, a1, a2, b0, b1, b2


@njit(cache=True, inline='always')
def se3_Ad_inv_apply_point(g, X, out, work):
    """``out[a]`` (6,) ← ``Ad_{g⁻¹} X[a] = (Aᵀ(x_t − a × x_r); Aᵀx_r)`` for every row
    ``X[a] = (x_t; x_r)`` of ``X`` ``(k, 6)`` and ``g = (a; A)`` (4, 4), without the matrix
    (the inverse of ``Ad_g = [[A, âA], [0, A]]``); ``work`` is unused."""
    for r in range(X.shape[0]):
        y0, y1, y2 = X[r, 3], X[r, 4], X[r, 5]
        c0, c1, c2 = cross3(g[1, 0], g[2, 0], g[3, 0], y0, y1, y2)
        u0, u1, u2 = X[r, 0] - c0, X[r, 1] - c1, X[r, 2] - c2
        for j in range(3):
            out[r, j] = g[1, j + 1] * u0 + g[2, j + 1] * u1 + g[3, j + 1] * u2
            out[r, j + 3] = g[1, j + 1] * y0 + g[2, j + 1] * y1 + g[3, j + 1] * y2


@njit(cache=True, inline='always')
def se3_E_apply_point(dt, xi, V, out, work):
    """``out[a]`` (6,) ← ``𝓔(Δt, ξ) V[a] = Δt (J v_t + Q v_r; J v_r)`` for every row
    ``V[a] = (v_t; v_r)`` of ``V`` ``(k, 6)``, ``J = J(w)`` and ``Q = Q(r, w)`` at
    ``(r; w) = Δt ξ`` (:func:`se3_E_point`), by cross products; ``work`` is unused."""
    r0, r1, r2 = dt * xi[0], dt * xi[1], dt * xi[2]
    w0, w1, w2 = dt * xi[3], dt * xi[4], dt * xi[5]
    b, c, d, e = se3_dexp_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
    for a in range(V.shape[0]):
        p0, p1, p2 = V[a, 3], V[a, 4], V[a, 5]
        j0, j1, j2 = _V_apply(w0, w1, w2, b, c, V[a, 0], V[a, 1], V[a, 2])
        q0, q1, q2 = _Q_apply(r0, r1, r2, w0, w1, w2, c, d, e, p0, p1, p2)
        k0, k1, k2 = _V_apply(w0, w1, w2, b, c, p0, p1, p2)
        out[a, 0], out[a, 1], out[a, 2] = dt * (j0 + q0), dt * (j1 + q1), dt * (j2 + q2)
        out[a, 3], out[a, 4], out[a, 5] = dt * k0, dt * k1, dt * k2


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        se3_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        se3_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        se3_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        se3_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        se3_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        se3_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        se3_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        se3_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        se3_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(xi, eta, out):
    for p in range(xi.shape[0]):
        se3_bracket_point(xi[p], eta[p], out[p])


@njit(cache=True)
def _dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        se3_dexp_point(xi[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        se3_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _E_batch(dt, xi, out):
    for p in range(xi.shape[0]):
        se3_E_point(dt[p], xi[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def _exp_coeffs3_np(t2):
    small = t2 < SMALL_THETA2
    safe = np.where(small, 1.0, t2)
    series = _exp_coeffs3_series(t2)
    direct = _exp_coeffs3_direct(safe)
    return tuple(np.where(small, s, d) for s, d in zip(series, direct, strict=True))


def _dexp_coeffs_np(t2):
    small = t2 < SMALL_THETA2
    safe = np.where(small, 1.0, t2)
    series = _dexp_coeffs_series(t2)
    direct = _dexp_coeffs_direct(safe)
    return tuple(np.where(small, s, d) for s, d in zip(series, direct, strict=True))


def _Q_np(r, w, c, d, e) -> np.ndarray:
    """``Q`` block ``[..., 3, 3]`` for translation ``r`` and rotation ``w`` ``[..., 3]``."""
    r0, r1, r2, w0, w1, w2 = r[..., 0], r[..., 1], r[..., 2], w[..., 0], w[..., 1], w[..., 2]
    cols = [np.stack(np.broadcast_arrays(*_Q_apply(r0, r1, r2, w0, w1, w2, c, d, e, *u)), axis=-1)
            for u in _UNIT]
    return np.stack(cols, axis=-1)


def _blocks(tl, tr, br) -> np.ndarray:
    """The 6 × 6 matrix ``[[tl, tr], [0, br]]`` from broadcast ``[..., 3, 3]`` blocks."""
    tl, tr, br = np.broadcast_arrays(tl, tr, br)
    out = np.zeros((*tl.shape[:-2], 6, 6))
    out[..., :3, :3] = tl
    out[..., :3, 3:] = tr
    out[..., 3:, 3:] = br
    return out


def _affine(t, R) -> np.ndarray:
    """``(t; R)`` as ``[..., 4, 4]`` from ``t`` ``[..., 3]`` and ``R`` ``[..., 3, 3]``."""
    lead = np.broadcast_shapes(t.shape[:-1], R.shape[:-2])
    out = np.zeros((*lead, 4, 4))
    out[..., 0, 0] = 1.0
    out[..., 1:, 0] = t
    out[..., 1:, 1:] = R
    return out


def _dexp_np(r, w, s) -> np.ndarray:
    w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
    b, c, d, e = _dexp_coeffs_np(w0 * w0 + w1 * w1 + w2 * w2)
    J = poly_np(w0, w1, w2, b, c, s)
    Q = _Q_np(r, w, c, d, e)
    s = np.asarray(s)[..., None, None]
    return _blocks(J, s * Q, J)


# ---------------------------------------------------------------------- the group
class SE3(SymmetryGroup):
    """Rigid motions of R³ as ``g = (a; A) = [[1, 0ᵀ], [a, A]]``; algebra se(3) ≅ R⁶.

    Algebra components ``ξ = (a1, a2)`` ``[..., 6]`` — translation first, rotation second —
    map to ``{a1; a2} = [[0, 0ᵀ], [a1, â2]]`` (paper, Appendix "Vector and matrix
    operations").  :meth:`log_domain_norm` is the rotation angle ``|a2|``.  All operations
    are closed-form; see the module docstring.
    """

    name = "SE3"
    dim = 6
    matrix_size = 4
    affine = True
    _kernels = kernel_table(globals())
    _point_prefix = "se3"

    def basis(self) -> np.ndarray:
        """Generators ``b_i = {(δ_i1, δ_i2, δ_i3); (δ_i4, δ_i5, δ_i6)}``, shape ``(6, 4, 4)``."""
        return self._hat(np.eye(6))

    def defect(self, g) -> np.ndarray:
        """Distance from SE(3): ``‖AᵀA − I‖_F + ‖g[0, :] − (1, 0, 0, 0)‖``.

        Parameters
        ----------
        g : array_like, shape ``[..., 4, 4]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        g = self._element(g)
        A = g[..., 1:, 1:]
        rot = np.linalg.norm(np.swapaxes(A, -1, -2) @ A - np.eye(3), axis=(-2, -1))
        return rot + np.linalg.norm(g[..., 0, :] - np.array([1.0, 0.0, 0.0, 0.0]), axis=-1)

    def log_domain_norm(self, xi) -> np.ndarray:
        """Rotation angle ``|a2|`` of ``xi`` ``[..., 6]`` → ``[...]``."""
        xi = self._algebra(xi)
        return np.linalg.norm(xi[..., 3:], axis=-1)

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 4, 4))
        out[..., 1:, 0] = xi[..., :3]
        out[..., 1:, 1:] = hat_np(xi[..., 3:])
        return out

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return np.concatenate([A[..., 1:, 0], vee_np(A[..., 1:, 1:])], axis=-1)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        Ag = g[..., 1:, 1:]
        return _affine(matvec3_np(Ag, h[..., 1:, 0]) + g[..., 1:, 0], matmul3_np(Ag, h[..., 1:, 1:]))

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        At = np.swapaxes(g[..., 1:, 1:], -1, -2)
        return _affine(-matvec3_np(At, g[..., 1:, 0]), At)

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return matvec3_np(g[..., 1:, 1:], x) + g[..., 1:, 0]

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        w0, w1, w2 = xi[..., 3], xi[..., 4], xi[..., 5]
        a, b, c = _exp_coeffs3_np(w0 * w0 + w1 * w1 + w2 * w2)
        R = poly_np(w0, w1, w2, a, b, 1.0)
        t = np.stack(_V_apply(w0, w1, w2, b, c, xi[..., 0], xi[..., 1], xi[..., 2]), axis=-1)
        return _affine(t, R)

    def _log(self, g: np.ndarray) -> np.ndarray:
        w = log_np(g[..., 1:, 1:])
        w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
        c = dexp_inv_coeff_np(w0 * w0 + w1 * w1 + w2 * w2)
        v = np.stack(_V_apply(w0, w1, w2, -0.5, c, g[..., 1, 0], g[..., 2, 0], g[..., 3, 0]), axis=-1)
        return np.concatenate([v, w], axis=-1)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        A = g[..., 1:, 1:]
        a = g[..., 1:, 0]
        aA = np.stack([cross_np(a, A[..., :, j]) for j in range(3)], axis=-1)
        return _blocks(A, aA, A)

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        K = hat_np(xi[..., 3:])
        return _blocks(K, hat_np(xi[..., :3]), K)

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        top = cross_np(xi[..., 3:], eta[..., :3]) + cross_np(xi[..., :3], eta[..., 3:])
        return np.concatenate(np.broadcast_arrays(top, cross_np(xi[..., 3:], eta[..., 3:])), axis=-1)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return _dexp_np(xi[..., :3], xi[..., 3:], 1.0)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        w = xi[..., 3:]
        w0, w1, w2 = w[..., 0], w[..., 1], w[..., 2]
        t2 = w0 * w0 + w1 * w1 + w2 * w2
        cinv = dexp_inv_coeff_np(t2)
        _, c, d, e = _dexp_coeffs_np(t2)
        Jinv = poly_np(w0, w1, w2, -0.5, cinv, 1.0)
        Q = _Q_np(xi[..., :3], w, c, d, e)
        return _blocks(Jinv, -matmul3_np(Jinv, matmul3_np(Q, Jinv)), Jinv)

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        Ys = dt[..., None] * Y
        return _dexp_np(Ys[..., :3], Ys[..., 3:], dt)
