"""The Poincaré group M(1,3) = T(4) ⋊ SO⁺(1,3) in closed form.

Conventions (paper, section "Relativistic Cosserat rods")
----------------------------------------------------------
* Elements ``(t; Λ) = [[1, 0ᵀ], [t, Λ]]`` (``5 × 5``, homogeneous coordinate first) with
  ``Λ ∈ SO⁺(1,3)`` (:mod:`cartan.groups.so13`); the action on R⁴ is ``x ↦ Λx + t``.
* Algebra elements ``{y; Z} = [[0, 0ᵀ], [y, Z]]`` with components
  ``ξ = (y₀, y₁, y₂, y₃, c₁, c₂, c₃, d₁, d₂, d₃)``: translation first, then the so(1,3)
  components ``(c; d)`` of ``Z = [[0, cᵀ], [c, d̂]]``.
* Bracket ``[{y₁; Z₁}, {y₂; Z₂}] = {Z₁y₂ − Z₂y₁; [Z₁, Z₂]}``, hence
  ``ad_{y;Z} = [[Z, −N(y)], [0, ad_Z]]`` with ``N(y) ζ = Z_ζ y`` (``4 × 6``), and
  ``Ad_{(t;Λ)} = [[Λ, −N(t) Ad_Λ], [0, Ad_Λ]]``.

Closed forms
------------
``exp{y; Z} = (V y; exp Z)`` with ``V = Σ_k Zᵏ/(k+1)! = ∫₀¹ e^{sZ} ds``.  In the spinor
picture (``x ↔ X = x^μ σ_μ``, ``e^{sZ} x ↔ e^{sL} X e^{sL†}``, ``L = −i w·σ/2``,
``e^{sL} = α(s) I + β(s) L`` with ``α = cos(sθ/2)``, ``β = sin(sθ/2)/(θ/2)``)

    ``V X = I₁ X + conj(I₂) L X + I₂ X L† + I₄ L X L†``,

``I₁ = ∫|α|²``, ``I₂ = ∫α β̄``, ``I₄ = ∫|β|²``.  With ``θ = b + ia`` (so ``Z`` has eigenvalues
``±a``, ``±ib``), ``u = a²``, ``v = −b²`` and the entire functions ``G(μ) = sinh√μ/√μ``,
``Ch(μ) = cosh √μ``, ``H(μ) = (cosh √μ − 1)/μ``:

    ``I₁ = ½(G(u) + G(v))``,  ``I₄ = 2 G[u, v]``,  ``Re I₂ = Ch[u, v]``,
    ``Im I₂ = −ab H[u, v]``,

where ``F[u, v] = (F(u) − F(v))/(u − v)`` is a divided difference.  ``u − v = |θ²|``: when
``|θ²| < 1`` the divided differences are summed from the Taylor series of ``F``
(``F[u, v] = Σ_k f_k Σ_{j<k} uʲ v^{k−1−j}``), so null and near-null generators
(``u = v = 0``, ``Z`` nilpotent) keep full accuracy; ``G`` and ``H`` use their series for
small arguments too (``H(μ) = ½ G(μ/4)²``).  ``a²`` and ``b²`` are computed from ``θ² = w·w``
without cancellation.

``log(t; Λ) = {V⁻¹ t; log Λ}`` (a ``4 × 4`` solve; ``V`` is invertible for ``|Re θ| < 2π``),
principal for ``|Re θ| < π`` as for :class:`~cartan.groups.so13.SO13`; the
:meth:`Poincare.log_domain_norm` is the Euclidean norm of the Lorentz part ``(c; d)``.

``dexp{y; Z} = [[V, Q], [0, J]]`` with ``J`` the closed-form :mod:`~cartan.groups.so13`
Jacobian and ``V`` the closed form above; the coupling block ``Q`` is the ``(1, 3)`` block of
``expm([[Z, −N(y), 0], [0, ad_Z, I₆], [0, 0, 0]])`` (``16 × 16``, a reduced Van Loan
exponential); ``dexp⁻¹ = [[V⁻¹, −V⁻¹ Q J⁻¹], [0, J⁻¹]]``; ``𝓔(Δt, Y) = Δt·dexp(ΔtY)``.

Kernels
-------
numba kernels (:attr:`Poincare._kernels`): hat, vee, compose, inverse, act, exp, log, Ad, ad,
bracket.  ``dexp``, ``dexp_inv`` and ``E`` use the numpy path on both backends (the ``Q``
block needs a matrix exponential).  The generated loops also bind the fused one-axis free flow
:func:`poincare_axis_flow_point` (lattice ``lie-verlet``: a shift, a boost or a turn in one
plane, every axis in closed form) and the fused products :func:`poincare_coad_exp_point`,
:func:`poincare_dexp_inv_apply_point`, :func:`poincare_E_apply_point` and
:func:`poincare_Ad_inv_apply_point` (``lie-euler``, the RKMK stages, collocation); these, exp
and 𝓔 take a pure translation ``{y; 0}`` (exp = ``(y; I)``, ad² = 0) in line.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numba import njit
from numba.extending import register_jitable

from ..compiled.linalg import solve_augmented
from ._batch import kernel_table
from ._generic_kernels import vanloan_E_point
from .base import SymmetryGroup
from .so13 import (
    Ad_np,
    _exp_spinor,
    _fill_complex_op,
    _lorentz_entries,
    _phi_entries,
    _stack,
    _theta2,
    ad_np,
    bracket_np,
    dexp_inv_np,
    dexp_np,
    exp_coeffs_np,
    hat_np,
    horner,
    inverse_np,
    log_np,
    lorentz_defect,
    so13_Ad_point,
    so13_exp_coeffs,
    so13_hat_point,
    so13_log_point,
    so13_vee_point,
    vee_np,
)

__all__ = [
    "Poincare",
    "poincare_Ad_T_point",
    "poincare_Ad_inv_apply_point",
    "poincare_Ad_point",
    "poincare_E_apply_point",
    "poincare_E_point",
    "poincare_V_coeffs",
    "poincare_act_point",
    "poincare_ad_point",
    "poincare_axis_flow_point",
    "poincare_bracket_point",
    "poincare_coad_exp_point",
    "poincare_compose_point",
    "poincare_dexp_inv_T_pair_chunk_point",
    "poincare_dexp_inv_T_pair_point",
    "poincare_dexp_inv_apply_point",
    "poincare_dexp_inv_point",
    "poincare_exp_point",
    "poincare_frames_chunk_point",
    "poincare_hat_point",
    "poincare_inverse_point",
    "poincare_log_chunk_point",
    "poincare_log_point",
    "poincare_move_chunk_point",
    "poincare_vee_point",
]

#: Below this value of |θ²| = a² + b² the divided differences are summed from series.
DD_SERIES_RADIUS = 1.0
#: Below this argument G(μ) = sinh√μ/√μ (and sin√t/√t) is summed from its series.
G_SERIES_RADIUS = 1.0


def _coeffs(f, n: int) -> tuple[float, ...]:
    return tuple(1.0 / math.factorial(f(k)) for k in range(n))


#: Taylor coefficients (lowest power first) of G, Ch, H in μ.
COEF_G = _coeffs(lambda k: 2 * k + 1, 13)
COEF_CH = _coeffs(lambda k: 2 * k, 14)
COEF_H = _coeffs(lambda k: 2 * k + 2, 13)
#: G(μ) and G(−t) = sin√t/√t, highest power first for Horner.
TAYLOR_SINHC = tuple(reversed(COEF_G[:10]))
TAYLOR_SINC = tuple(reversed([(-1.0) ** k * c for k, c in enumerate(COEF_G[:10])]))


# ---------------------------------------------------------------------- shared arithmetic
@register_jitable
def _dd_series(u, v, coeffs):
    """``F[u, v] = Σ_{k≥1} f_k h_{k−1}(u, v)``, ``h_n = Σ_{j≤n} uʲ v^{n−j}``, ``f`` lowest first."""
    h = 1.0 + 0.0 * (u + v)
    vp = 1.0 + 0.0 * v
    acc = coeffs[1] * h
    for k in range(2, len(coeffs)):
        vp = vp * v
        h = u * h + vp
        acc = acc + coeffs[k] * h
    return acc


@register_jitable
def _sinhc_direct(t):
    r = np.sqrt(t)
    return np.sinh(r) / r


@register_jitable
def _sinc_direct(t):
    r = np.sqrt(t)
    return np.sin(r) / r


@register_jitable
def _I_from(ab, gu, gv, dd_g, dd_ch, dd_h):
    """``(I₁, I₂, I₄)`` from ``G(u)``, ``G(−b²)`` and the divided differences at ``(u, −b²)``."""
    return 0.5 * (gu + gv), dd_ch - 1j * (ab * dd_h), 2.0 * dd_g


@register_jitable
def _dd_direct(u, b2, gu, gv, gu4, gv4):
    """Direct divided differences ``(G, Ch, H)[u, −b²]`` for ``u + b² ≥ 1``."""
    m = u + b2
    return ((gu - gv) / m, (np.cosh(np.sqrt(u)) - np.cos(np.sqrt(b2))) / m,
            0.5 * (gu4 * gu4 - gv4 * gv4) / m)


@register_jitable
def _V_entries(c1, c2, c3, d1, d2, d3, I1, I2, I4):
    """Row-major entries of ``V = I₁ Id + 2Φ(conj(I₂) L, I) + I₄ Φ(L, L)``."""
    h = -0.5j
    l1, l2, l3 = h * (d1 + 1j * c1), h * (d2 + 1j * c2), h * (d3 + 1j * c3)
    k = I2.conjugate()
    p = _phi_entries(0.0j, k * l1, k * l2, k * l3, 1.0 + 0.0j, 0.0j, 0.0j, 0.0j)
    q = _phi_entries(0.0j, l1, l2, l3, 0.0j, l1, l2, l3)
    return (
        I1 + 2.0 * p[0] + I4 * q[0], 2.0 * p[1] + I4 * q[1], 2.0 * p[2] + I4 * q[2],
        2.0 * p[3] + I4 * q[3],
        2.0 * p[4] + I4 * q[4], I1 + 2.0 * p[5] + I4 * q[5], 2.0 * p[6] + I4 * q[6],
        2.0 * p[7] + I4 * q[7],
        2.0 * p[8] + I4 * q[8], 2.0 * p[9] + I4 * q[9], I1 + 2.0 * p[10] + I4 * q[10],
        2.0 * p[11] + I4 * q[11],
        2.0 * p[12] + I4 * q[12], 2.0 * p[13] + I4 * q[13], 2.0 * p[14] + I4 * q[14],
        I1 + 2.0 * p[15] + I4 * q[15],
    )


@register_jitable
def _Zt(c1, c2, c3, d1, d2, d3, t0, t1, t2, t3):
    """``Z t`` for ``Z = [c; d]``: ``(c·t⃗, c t₀ + d × t⃗)``."""
    return (c1 * t1 + c2 * t2 + c3 * t3, c1 * t0 + d2 * t3 - d3 * t2, c2 * t0 + d3 * t1 - d1 * t3,
            c3 * t0 + d1 * t2 - d2 * t1)


# ---------------------------------------------------------------------- numba point kernels
@njit(cache=True)
def _sinhc(t):
    if t < G_SERIES_RADIUS:
        return horner(t, TAYLOR_SINHC)
    return _sinhc_direct(t)


@njit(cache=True)
def _sinc(t):
    if t < G_SERIES_RADIUS:
        return horner(t, TAYLOR_SINC)
    return _sinc_direct(t)


@njit(cache=True)
def _eig_squares(x):
    """``(a², b², ab)`` for ``θ² = x = (b + ia)²`` without cancellation."""
    p = x.real
    q = x.imag
    m = math.hypot(p, q)
    if p >= 0.0:
        b2 = 0.5 * (m + p)
        u = q * q / (4.0 * b2) if b2 > 0.0 else 0.0
    else:
        u = 0.5 * (m - p)
        b2 = q * q / (4.0 * u)
    return u, b2, 0.5 * q


@njit(cache=True)
def poincare_V_coeffs(x):
    """``(I₁, I₂, I₄)`` of ``V`` as functions of the complex ``x = θ²``."""
    u, b2, ab = _eig_squares(x)
    gu = _sinhc(u)
    gv = _sinc(b2)
    gu4 = _sinhc(0.25 * u)
    gv4 = _sinc(0.25 * b2)
    if u + b2 < DD_SERIES_RADIUS:
        dd_g = _dd_series(u, -b2, COEF_G)
        dd_ch = _dd_series(u, -b2, COEF_CH)
        dd_h = _dd_series(u, -b2, COEF_H)
    else:
        dd_g, dd_ch, dd_h = _dd_direct(u, b2, gu, gv, gu4, gv4)
    return _I_from(ab, gu, gv, dd_g, dd_ch, dd_h)


@njit(cache=True)
def _V_point(c1, c2, c3, d1, d2, d3):
    I1, I2, I4 = poincare_V_coeffs(_theta2(c1, c2, c3, d1, d2, d3))
    return _V_entries(c1, c2, c3, d1, d2, d3, I1, I2, I4)


@njit(cache=True)
def poincare_hat_point(xi, out):
    """``out`` (5, 5) ← ``{y; Z}`` for ``xi`` (10,)."""
    for j in range(5):
        out[0, j] = 0.0
    for i in range(4):
        out[i + 1, 0] = xi[i]
    so13_hat_point(xi[4:], out[1:, 1:])


@njit(cache=True)
def poincare_vee_point(A, out):
    """``out`` (10,) ← components of ``A`` (5, 5): ``A[1:, 0]`` and the so(1,3) part."""
    for i in range(4):
        out[i] = A[i + 1, 0]
    so13_vee_point(A[1:, 1:], out[4:])


@njit(cache=True)
def poincare_compose_point(g, h, out):
    """``out`` (5, 5) ← ``g h`` ``= (t_g + Λ_g t_h; Λ_g Λ_h)``; no aliasing."""
    _compose5(g, h, out)


@register_jitable(inline='always')
def _compose5(g, h, out):
    """:func:`poincare_compose_point`'s arithmetic, inlined into the passes below."""
    out[0, 0] = 1.0
    for j in range(1, 5):
        out[0, j] = 0.0
    for i in range(1, 5):  # (no accumulator across iterations: numba's IR inlining keeps it out of scope)
        out[i, 0] = g[i, 0] + g[i, 1] * h[1, 0] + g[i, 2] * h[2, 0] + g[i, 3] * h[3, 0] + g[i, 4] * h[4, 0]
        for j in range(1, 5):
            out[i, j] = g[i, 1] * h[1, j] + g[i, 2] * h[2, j] + g[i, 3] * h[3, j] + g[i, 4] * h[4, j]


@njit(cache=True)
def poincare_inverse_point(g, out):
    """``out`` (5, 5) ← ``(−Λ⁻¹t; Λ⁻¹)`` with ``Λ⁻¹ = ηΛᵀη``; no aliasing."""
    _inverse5(g, out)


@register_jitable(inline='always')
def _inverse5(g, out):
    """:func:`poincare_inverse_point`'s arithmetic, inlined into the passes below."""
    out[0, 0] = 1.0
    for j in range(1, 5):
        out[0, j] = 0.0
    for i in range(4):
        si = -1.0 if i == 0 else 1.0
        for j in range(4):
            sj = -1.0 if j == 0 else 1.0
            out[i + 1, j + 1] = si * sj * g[j + 1, i + 1]
    for i in range(1, 5):
        out[i, 0] = -(0.0 + out[i, 1] * g[1, 0] + out[i, 2] * g[2, 0] + out[i, 3] * g[3, 0] + out[i, 4] * g[4, 0])


@njit(cache=True)
def poincare_act_point(g, x, out):
    """``out`` (4,) ← ``Λ x + t``."""
    for i in range(4):
        out[i] = g[i + 1, 0] + g[i + 1, 1] * x[0] + g[i + 1, 2] * x[1] + g[i + 1, 3] * x[2] \
            + g[i + 1, 4] * x[3]


@register_jitable(inline='always')
def _lorentz_zero(xi):
    """Whether the Lorentz part ``(c; d)`` of ``xi`` (10,) is exactly zero (ξ a pure translation)."""
    return ((xi[4] == 0.0) & (xi[5] == 0.0) & (xi[6] == 0.0) & (xi[7] == 0.0) & (xi[8] == 0.0)
            & (xi[9] == 0.0))


@register_jitable(inline='always')
def _translation_element(y0, y1, y2, y3, out):
    """``out`` (5, 5) ← the pure translation ``(y; I)``."""
    for a in range(5):
        for b in range(5):
            out[a, b] = 1.0 if a == b else 0.0
    out[1, 0], out[2, 0], out[3, 0], out[4, 0] = y0, y1, y2, y3


@register_jitable(inline='always')
def _translation_N(y0, y1, y2, y3, z):
    """``N(y) ζ = Z_ζ y`` (4,) for ``ζ = (c; d)`` the entries 4..9 of ``z`` (10,),
    ``N(y) = [[y⃗ᵀ, 0], [y₀ I, −ŷ⃗]]``."""
    c1, c2, c3, d1, d2, d3 = z[4], z[5], z[6], z[7], z[8], z[9]
    return (y1 * c1 + y2 * c2 + y3 * c3, y0 * c1 + y3 * d2 - y2 * d3,
            y0 * c2 - y3 * d1 + y1 * d3, y0 * c3 + y2 * d1 - y1 * d2)


@njit(cache=True)
def poincare_exp_point(xi, out):
    """``out`` (5, 5) ← ``exp{y; Z} = (V y; exp Z)`` for ``xi`` (10,); a pure translation
    (Z = 0 exactly: V = I, exp Z = I) directly."""
    if _lorentz_zero(xi):
        _translation_element(xi[0], xi[1], xi[2], xi[3], out)
        return
    c1, c2, c3, d1, d2, d3 = xi[4], xi[5], xi[6], xi[7], xi[8], xi[9]
    x = _theta2(c1, c2, c3, d1, d2, d3)
    co, sh = so13_exp_coeffs(x)
    L = _lorentz_entries(*_exp_spinor(c1, c2, c3, d1, d2, d3, co, sh))
    I1, I2, I4 = poincare_V_coeffs(x)
    V = _V_entries(c1, c2, c3, d1, d2, d3, I1, I2, I4)
    out[0, 0] = 1.0
    for i in range(4):
        out[0, i + 1] = 0.0
        out[i + 1, 0] = V[4 * i] * xi[0] + V[4 * i + 1] * xi[1] + V[4 * i + 2] * xi[2] \
            + V[4 * i + 3] * xi[3]
        for j in range(4):
            out[i + 1, j + 1] = L[4 * i + j]


@njit(cache=True)
def _solve4(V, t, out):
    """``out`` (4,) ← ``V⁻¹ t`` (``V`` a tuple; :func:`cartan.compiled.linalg.solve_augmented`);
    NaN where V is singular."""
    M = np.empty((4, 5))
    for i in range(4):
        for j in range(4):
            M[i, j] = V[4 * i + j]
        M[i, 4] = t[i]
    if not solve_augmented(M, out):
        for i in range(4):
            out[i] = np.nan


@register_jitable(inline='always')
def _pure_translation(g):
    """Whether the Lorentz block of ``g`` (5, 5) is exactly the identity (straight-line and
    without short-circuits, so that numba's IR inlining takes it into the passes' loops cleanly)."""
    return ((g[1, 1] == 1.0) & (g[2, 2] == 1.0) & (g[3, 3] == 1.0) & (g[4, 4] == 1.0)
            & (g[1, 2] == 0.0) & (g[1, 3] == 0.0) & (g[1, 4] == 0.0) & (g[2, 1] == 0.0)
            & (g[2, 3] == 0.0) & (g[2, 4] == 0.0) & (g[3, 1] == 0.0) & (g[3, 2] == 0.0)
            & (g[3, 4] == 0.0) & (g[4, 1] == 0.0) & (g[4, 2] == 0.0) & (g[4, 3] == 0.0))


@njit(cache=True)
def poincare_log_point(g, out):
    """``out`` (10,) ← principal ``{V⁻¹t; log Λ}`` of ``g`` (5, 5); a pure translation
    (Λ = I exactly: V = I) directly."""
    if _pure_translation(g):
        for k in range(4):
            out[k] = g[k + 1, 0]
        for k in range(4, 10):
            out[k] = 0.0
        return
    so13_log_point(g[1:, 1:], out[4:])
    V = _V_point(out[4], out[5], out[6], out[7], out[8], out[9])
    _solve4(V, g[1:, 0], out[:4])


@njit(cache=True)
def poincare_Ad_point(g, out):
    """``out`` (10, 10) ← ``[[Λ, −N(t) Ad_Λ], [0, Ad_Λ]]``."""
    so13_Ad_point(g[1:, 1:], out[4:, 4:])
    t0, t1, t2, t3 = g[1, 0], g[2, 0], g[3, 0], g[4, 0]
    for i in range(4):
        for j in range(4):
            out[i, j] = g[i + 1, j + 1]
    for i in range(6):
        for j in range(4):
            out[i + 4, j] = 0.0
    for j in range(6):
        z = _Zt(out[4, j + 4], out[5, j + 4], out[6, j + 4], out[7, j + 4], out[8, j + 4],
                out[9, j + 4], t0, t1, t2, t3)
        for i in range(4):
            out[i, j + 4] = -z[i]


@njit(cache=True)
def poincare_ad_point(xi, out):
    """``out`` (10, 10) ← ``[[Z, −N(y)], [0, ad_Z]]``."""
    y0, y1, y2, y3 = xi[0], xi[1], xi[2], xi[3]
    c1, c2, c3, d1, d2, d3 = xi[4], xi[5], xi[6], xi[7], xi[8], xi[9]
    so13_hat_point(xi[4:], out[:4, :4])
    for i in range(6):
        for j in range(4):
            out[i + 4, j] = 0.0
    hr = (0.0, -d3, d2, d3, 0.0, -d1, -d2, d1, 0.0)
    hi = (0.0, -c3, c2, c3, 0.0, -c1, -c2, c1, 0.0)
    _fill_complex_op(hr, hi, 1.0, out[4:, 4:])
    # −N(y): N(y) = [[y⃗ᵀ, 0], [y₀ I, −ŷ⃗]]
    ny = (y1, y2, y3, 0.0, 0.0, 0.0,
          y0, 0.0, 0.0, 0.0, y3, -y2,
          0.0, y0, 0.0, -y3, 0.0, y1,
          0.0, 0.0, y0, y2, -y1, 0.0)
    for i in range(4):
        for j in range(6):
            out[i, j + 4] = -ny[6 * i + j]


@njit(cache=True)
def poincare_bracket_point(u, v, out):
    """``out`` (10,) ← ``{Z_u y_v − Z_v y_u; [Z_u, Z_v]}``."""
    a = _Zt(u[4], u[5], u[6], u[7], u[8], u[9], v[0], v[1], v[2], v[3])
    b = _Zt(v[4], v[5], v[6], v[7], v[8], v[9], u[0], u[1], u[2], u[3])
    for i in range(4):
        out[i] = a[i] - b[i]
    a1, a2, a3, b1, b2, b3 = u[4], u[5], u[6], u[7], u[8], u[9]
    e1, e2, e3, f1, f2, f3 = v[4], v[5], v[6], v[7], v[8], v[9]
    out[4] = (b2 * e3 - b3 * e2) + (a2 * f3 - a3 * f2)
    out[5] = (b3 * e1 - b1 * e3) + (a3 * f1 - a1 * f3)
    out[6] = (b1 * e2 - b2 * e1) + (a1 * f2 - a2 * f1)
    out[7] = (b2 * f3 - b3 * f2) - (a2 * e3 - a3 * e2)
    out[8] = (b3 * f1 - b1 * f3) - (a3 * e1 - a1 * e3)
    out[9] = (b1 * f2 - b2 * f1) - (a1 * e2 - a2 * e1)


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        poincare_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        poincare_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        poincare_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        poincare_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        poincare_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        poincare_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        poincare_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        poincare_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        poincare_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(u, v, out):
    for p in range(u.shape[0]):
        poincare_bracket_point(u[p], v[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def _eig_squares_np(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p, q = x.real, x.imag
    m = np.hypot(p, q)
    pos = p >= 0.0
    big = np.where(pos, 0.5 * (m + p), 0.5 * (m - p))
    other = q * q / (4.0 * np.where(big > 0.0, big, 1.0))
    u = np.where(pos, other, big)
    b2 = np.where(pos, big, other)
    return u, b2, 0.5 * q


def _g_np(t: np.ndarray, series, direct) -> np.ndarray:
    small = t < G_SERIES_RADIUS
    return np.where(small, horner(t, series), direct(np.where(small, 1.0, t)))


def V_coeffs_np(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised :func:`poincare_V_coeffs`."""
    u, b2, ab = _eig_squares_np(x)
    gu = _g_np(u, TAYLOR_SINHC, _sinhc_direct)
    gv = _g_np(b2, TAYLOR_SINC, _sinc_direct)
    gu4 = _g_np(0.25 * u, TAYLOR_SINHC, _sinhc_direct)
    gv4 = _g_np(0.25 * b2, TAYLOR_SINC, _sinc_direct)
    small = u + b2 < DD_SERIES_RADIUS
    series = (_dd_series(u, -b2, COEF_G), _dd_series(u, -b2, COEF_CH), _dd_series(u, -b2, COEF_H))
    # the direct branch is evaluated on a safe argument (u + b² = 1) where the series is used
    direct = _dd_direct(np.where(small, 1.0, u), np.where(small, 0.0, b2), gu, gv, gu4, gv4)
    dd = tuple(np.where(small, s, d) for s, d in zip(series, direct, strict=True))
    return _I_from(ab, gu, gv, *dd)


def V_np(Zxi: np.ndarray) -> np.ndarray:
    """``V = Σ Zᵏ/(k+1)!`` ``[..., 4, 4]`` for so(1,3) components ``Zxi`` ``[..., 6]``."""
    c1, c2, c3, d1, d2, d3 = (Zxi[..., k] for k in range(6))
    I1, I2, I4 = V_coeffs_np(_theta2(c1, c2, c3, d1, d2, d3))
    return _stack(_V_entries(c1, c2, c3, d1, d2, d3, I1, I2, I4), (4, 4))


def N_np(y: np.ndarray) -> np.ndarray:
    """``N(y) = [[y⃗ᵀ, 0], [y₀ I, −ŷ⃗]]`` ``[..., 4, 6]``, so that ``N(y) ζ = Z_ζ y``."""
    y0, y1, y2, y3 = (y[..., k] for k in range(4))
    z = np.zeros_like(y0)
    return _stack((y1, y2, y3, z, z, z, y0, z, z, z, y3, -y2, z, y0, z, -y3, z, y1,
                   z, z, y0, y2, -y1, z), (4, 6))


def _Zt_np(Z: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.stack(_Zt(*(Z[..., k] for k in range(6)), *(t[..., k] for k in range(4))), axis=-1)


# ---------------------------------------------------------------------- the group
class Poincare(SymmetryGroup):
    """The Poincaré group M(1,3) of the paper's relativistic Cosserat rod.

    Elements ``(t; Λ) = [[1, 0ᵀ], [t, Λ]]`` ``[..., 5, 5]`` act on R⁴ by ``x ↦ Λx + t``;
    algebra components ``(y; c; d)`` ``[..., 10]`` (translation first).  See the module
    docstring for the closed forms.
    """

    name = "Poincare"
    dim = 10
    matrix_size = 5
    affine = True
    injectivity_radius = np.pi
    _kernels = kernel_table(globals())
    _point_prefix = "poincare"

    def basis(self) -> np.ndarray:
        """Generators: 4 translations ``{e_μ; 0}``, then ``{0; K_k}``, ``{0; J_k}``; ``(10, 5, 5)``."""
        return self._hat(np.eye(10))

    def defect(self, g) -> np.ndarray:
        """Lorentz defect of ``Λ`` (:meth:`SO13.defect <cartan.groups.so13.SO13.defect>`)
        plus ``‖g[0, :] − (1, 0, 0, 0, 0)‖``.

        Parameters
        ----------
        g : array_like, shape ``[..., 5, 5]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        g = self._element(g)
        e0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
        return lorentz_defect(g[..., 1:, 1:]) + np.linalg.norm(g[..., 0, :] - e0, axis=-1)

    def log_domain_norm(self, xi) -> np.ndarray:
        """Euclidean norm ``|(c; d)|`` of the Lorentz part, shape ``[...]``.

        As for :class:`~cartan.groups.so13.SO13` it bounds the rotation-like angle
        ``|Re θ|``; the translation does not restrict the logarithm.
        """
        return np.linalg.norm(self._algebra(xi)[..., 4:], axis=-1)

    def V(self, Zxi) -> np.ndarray:
        """``V(Z) = Σ_k Zᵏ/(k+1)!``, the translation factor of :meth:`exp`.

        Parameters
        ----------
        Zxi : array_like, shape ``[..., 6]``
            so(1,3) components ``(c; d)``.

        Returns
        -------
        numpy.ndarray, shape ``[..., 4, 4]``
        """
        Zxi = np.asarray(Zxi, dtype=float)
        if Zxi.ndim == 0 or Zxi.shape[-1] != 6:
            raise ValueError(f"Zxi must have shape [..., 6], got {Zxi.shape}")
        return V_np(Zxi)

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 5, 5))
        out[..., 1:, 0] = xi[..., :4]
        out[..., 1:, 1:] = hat_np(xi[..., 4:])
        return out

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return np.concatenate([A[..., 1:, 0], vee_np(A[..., 1:, 1:])], axis=-1)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        Li = inverse_np(g[..., 1:, 1:])
        out = np.zeros(g.shape)
        out[..., 0, 0] = 1.0
        out[..., 1:, 1:] = Li
        out[..., 1:, 0] = -np.einsum("...ij,...j->...i", Li, g[..., 1:, 0])
        return out

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", g[..., 1:, 1:], x) + g[..., 1:, 0]

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        c1, c2, c3, d1, d2, d3 = (xi[..., k] for k in range(4, 10))
        x = _theta2(c1, c2, c3, d1, d2, d3)
        co, sh = exp_coeffs_np(x)
        L = _stack(_lorentz_entries(*_exp_spinor(c1, c2, c3, d1, d2, d3, co, sh)), (4, 4))
        V = _stack(_V_entries(c1, c2, c3, d1, d2, d3, *V_coeffs_np(x)), (4, 4))
        out = np.zeros((*xi.shape[:-1], 5, 5))
        out[..., 0, 0] = 1.0
        out[..., 1:, 1:] = L
        out[..., 1:, 0] = np.einsum("...ij,...j->...i", V, xi[..., :4])
        return out

    def _log(self, g: np.ndarray) -> np.ndarray:
        Zxi = log_np(g[..., 1:, 1:])
        y = np.linalg.solve(V_np(Zxi), g[..., 1:, 0, None])[..., 0]
        return np.concatenate([y, Zxi], axis=-1)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        AdL = Ad_np(g[..., 1:, 1:])
        out = np.zeros((*g.shape[:-2], 10, 10))
        out[..., :4, :4] = g[..., 1:, 1:]
        out[..., 4:, 4:] = AdL
        out[..., :4, 4:] = -N_np(g[..., 1:, 0]) @ AdL
        return out

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 10, 10))
        out[..., :4, :4] = hat_np(xi[..., 4:])
        out[..., :4, 4:] = -N_np(xi[..., :4])
        out[..., 4:, 4:] = ad_np(xi[..., 4:])
        return out

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        y = _Zt_np(xi[..., 4:], eta[..., :4]) - _Zt_np(eta[..., 4:], xi[..., :4])
        return np.concatenate([y, bracket_np(xi[..., 4:], eta[..., 4:])], axis=-1)

    def _Q(self, xi: np.ndarray) -> np.ndarray:
        """Coupling block ``Q`` ``[..., 4, 6]`` of ``dexp`` by a reduced Van Loan exponential
        (exactly ``−½N(y)`` where the Lorentz part is zero: ad_ξ is then nilpotent, ad_ξ² = 0)."""
        lead = xi.shape[:-1]
        out = -0.5 * N_np(xi[..., :4])
        moving = np.any(xi[..., 4:] != 0.0, axis=-1)
        if np.any(moving):
            sub = xi[moving]
            T = np.zeros((sub.shape[0], 16, 16))
            T[:, :4, :4] = hat_np(sub[:, 4:])
            T[:, :4, 4:10] = -N_np(sub[:, :4])
            T[:, 4:10, 4:10] = ad_np(sub[:, 4:])
            T[:, 4:10, 10:] = np.eye(6)
            out[moving] = scipy.linalg.expm(T)[:, :4, 10:]
        return out.reshape(*lead, 4, 6)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 10, 10))
        out[..., :4, :4] = V_np(xi[..., 4:])
        out[..., :4, 4:] = self._Q(xi)
        out[..., 4:, 4:] = dexp_np(xi[..., 4:])
        return out

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        Vi = np.linalg.inv(V_np(xi[..., 4:]))
        Ji = dexp_inv_np(xi[..., 4:])
        out = np.zeros((*xi.shape[:-1], 10, 10))
        out[..., :4, :4] = Vi
        out[..., :4, 4:] = -Vi @ self._Q(xi) @ Ji
        out[..., 4:, 4:] = Ji
        return out


#: Below this size of the Lorentz part, max |c_k|, |d_k| (times τ for 𝓔), dexp⁻¹ and 𝓔 are
#: summed from their series in ad_ξ; above it, from the Van Loan block exponential.  ad_ξ is
#: block triangular with eigenvalues those of the Lorentz part, so the series converge like
#: the scalar ones in |Z| (the translation part enters linearly): truncated after ad⁴ (dexp⁻¹:
#: next Bernoulli term B₆/6! ad⁶ = ad⁶/30240) and after ad⁵ (𝓔: next ad⁶/7!), the remainder is
#: below |Z|⁵·|ξ|/5040 ≈ 2e-14 |ξ| at |Z| = 1e-2.
POINCARE_SERIES_Z = 1e-2


@njit(cache=True)
def _poincare_scaled_ad(xi, tau, A):
    """``A = τ ad_ξ`` (10 × 10); returns max |τZ| over the Lorentz part Z of ξ."""
    poincare_ad_point(xi, A)
    for i in range(10):
        for j in range(10):
            A[i, j] *= tau
    z = 0.0
    for k in range(4, 10):
        z = max(z, abs(tau * xi[k]))
    return z


@njit(cache=True)
def _matmul10(A, B, out):
    for i in range(10):
        for j in range(10):
            s = 0.0
            for k in range(10):
                s += A[i, k] * B[k, j]
            out[i, j] = s


@njit(cache=True)
def poincare_dexp_inv_point(xi, out):
    """``out`` (10, 10) ← dexp⁻¹(ξ) = Σ B_k ad_ξ^k / k!: exactly I − ½ad_ξ for a pure
    translation (ad_ξ² = 0), the series through ad⁴ below :data:`POINCARE_SERIES_Z`, else the
    inverse of the Van Loan block exponential (the string's edges are pure translations)."""
    A = np.empty((10, 10))
    z = _poincare_scaled_ad(xi, 1.0, A)
    if z >= POINCARE_SERIES_Z:
        vanloan_E_point(1.0, A, out)
        out[:, :] = np.linalg.inv(out)
        return
    for i in range(10):
        for j in range(10):
            out[i, j] = (1.0 if i == j else 0.0) - 0.5 * A[i, j]
    if z == 0.0:
        return
    A2 = np.empty((10, 10))
    A4 = np.empty((10, 10))
    _matmul10(A, A, A2)
    _matmul10(A2, A2, A4)
    for i in range(10):
        for j in range(10):
            out[i, j] += A2[i, j] / 12.0 - A4[i, j] / 720.0


@njit(cache=True)
def poincare_E_point(dt, xi, out):
    """``out`` (10, 10) ← 𝓔(Δt, ξ) = Δt·Σ (Δt ad_ξ)^k/(k + 1)!: exactly Δt(I + ½Δt ad_ξ) for a
    pure translation, the series through (Δt ad)⁵ below :data:`POINCARE_SERIES_Z`, else the
    Van Loan block exponential."""
    if _lorentz_zero(xi):  # 𝓔 = Δt I + ½Δt² ad_ξ, ad_ξ = [[0, −N(y)], [0, 0]]: 24 entries
        for i in range(10):
            for j in range(10):
                out[i, j] = dt if i == j else 0.0
        y0, y1, y2, y3 = xi[0], xi[1], xi[2], xi[3]
        ny = (y1, y2, y3, 0.0, 0.0, 0.0,
              y0, 0.0, 0.0, 0.0, y3, -y2,
              0.0, y0, 0.0, -y3, 0.0, y1,
              0.0, 0.0, y0, y2, -y1, 0.0)
        for i in range(4):
            for j in range(6):
                out[i, j + 4] = dt * (0.5 * (-ny[6 * i + j] * dt))
        return
    A = np.empty((10, 10))
    z = _poincare_scaled_ad(xi, dt, A)
    if z >= POINCARE_SERIES_Z:
        poincare_ad_point(xi, A)
        vanloan_E_point(dt, A, out)
        return
    for i in range(10):
        for j in range(10):
            out[i, j] = dt * ((1.0 if i == j else 0.0) + 0.5 * A[i, j])
    if z == 0.0:
        return
    A2 = np.empty((10, 10))
    A3 = np.empty((10, 10))
    A4 = np.empty((10, 10))
    A5 = np.empty((10, 10))
    _matmul10(A, A, A2)
    _matmul10(A2, A, A3)
    _matmul10(A2, A2, A4)
    _matmul10(A4, A, A5)
    for i in range(10):
        for j in range(10):
            out[i, j] += dt * (A2[i, j] / 6.0 + A3[i, j] / 24.0 + A4[i, j] / 120.0 + A5[i, j] / 720.0)


@njit(cache=True)
def poincare_dexp_inv_T_pair_point(xi, v, out, out_neg):
    """``out`` ← dexp⁻¹(ξ)ᵀv and ``out_neg`` ← dexp⁻¹(−ξ)ᵀv (10,): for a pure translation
    (ad_ξ² = 0) ``v ∓ ½ad_ξᵀv`` without a matrix; otherwise from the matrices
    (:func:`poincare_dexp_inv_point`, dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ)."""
    A = np.empty((10, 10))
    poincare_ad_point(xi, A)
    pure = True
    for k in range(4, 10):
        if xi[k] != 0.0:
            pure = False
    if pure:
        for k in range(10):
            s = 0.0
            for j in range(10):
                s += A[j, k] * v[j]
            out[k] = v[k] - 0.5 * s
            out_neg[k] = v[k] + 0.5 * s
        return
    Dm = np.empty((10, 10))
    poincare_dexp_inv_point(xi, Dm)
    for k in range(10):
        s = 0.0
        t = 0.0
        for j in range(10):
            s += Dm[j, k] * v[j]
            t += A[j, k] * v[j]
        out[k] = s
        out_neg[k] = s + t


@njit(cache=True)
def poincare_Ad_T_point(g, v, out):
    """``out`` (10,) ← Ad_gᵀv: for a pure translation g = (t; I), Ad_g = [[I, −N(t)], [0, I]]
    and Ad_gᵀv = {v_y; v_Z − N(t)ᵀv_y} without a matrix; otherwise from :func:`poincare_Ad_point`."""
    if _pure_translation(g):
        y0, y1, y2, y3 = g[1, 0], g[2, 0], g[3, 0], g[4, 0]
        ny = (y1, y2, y3, 0.0, 0.0, 0.0,
              y0, 0.0, 0.0, 0.0, y3, -y2,
              0.0, y0, 0.0, -y3, 0.0, y1,
              0.0, 0.0, y0, y2, -y1, 0.0)
        for k in range(4):
            out[k] = v[k]
        for j in range(6):
            s = 0.0
            for i in range(4):
                s += ny[6 * i + j] * v[i]
            out[4 + j] = v[4 + j] - s
        return
    A = np.empty((10, 10))
    poincare_Ad_point(g, A)
    for k in range(10):
        s = 0.0
        for j in range(10):
            s += A[j, k] * v[j]
        out[k] = s


# ---------------------------------------------------------------------- fused products
# ``g_<op>`` of :data:`cartan.compiled.kernels.FUSED_OPS` (the generated loops' free flow, stage
# velocities and updates): a pure translation (Lorentz part exactly zero, as the string's nodal
# velocities and motions are) in line, where exp, Ad, dexp⁻¹ and 𝓔 are affine in the translation;
# any other element through the point kernels.  ``work`` is unused.


@njit(cache=True, inline='always')
def _matvec10(A, v, out):
    """``out`` (10,) ← ``A v`` for ``A`` (10, 10)."""
    for k in range(10):
        t = 0.0
        for j in range(10):
            t += A[k, j] * v[j]
        out[k] = t


@njit(cache=True, inline='always')
def poincare_coad_exp_point(xi, s, E, work):
    """``E`` (5, 5) ← ``exp(ξ)`` and ``s`` (10,) ← ``Ad_Eᵀ s`` in place: for ``ξ = {y; 0}``,
    ``E = (y; I)`` and ``s_Z ← s_Z − N(y)ᵀ s_y`` (:func:`poincare_Ad_T_point`'s form), else
    :func:`poincare_exp_point` and :func:`poincare_Ad_T_point`."""
    if _lorentz_zero(xi):
        y0, y1, y2, y3 = xi[0], xi[1], xi[2], xi[3]
        _translation_element(y0, y1, y2, y3, E)
        a = _translation_ad_T(y0, y1, y2, y3, s[0], s[1], s[2], s[3])
        for k in range(6):
            s[4 + k] += a[k]
        return
    poincare_exp_point(xi, E)
    out = np.empty(10)
    poincare_Ad_T_point(E, s, out)
    for k in range(10):
        s[k] = out[k]


@njit(cache=True, inline='always')
def poincare_dexp_inv_apply_point(xi, v, out, work):
    """``out`` (10,) ← ``dexp⁻¹(ξ) v``: for ``ξ = {y; 0}`` (ad_ξ² = 0, ad_ξ v = {−N(y)v_Z; 0})
    ``{v_y + ½N(y)v_Z; v_Z}``, else :func:`poincare_dexp_inv_point` times ``v``."""
    if _lorentz_zero(xi):
        n = _translation_N(xi[0], xi[1], xi[2], xi[3], v)
        for k in range(4):
            out[k] = v[k] + 0.5 * n[k]
        for k in range(4, 10):
            out[k] = v[k]
        return
    A = np.empty((10, 10))
    poincare_dexp_inv_point(xi, A)
    _matvec10(A, v, out)


@njit(cache=True, inline='always')
def poincare_E_apply_point(tau, xi, V, out, work):
    """``out[a]`` (10,) ← ``𝓔(τ, ξ) V[a]`` for every row of ``V`` ``(k, 10)``: for ``ξ = {y; 0}``
    (𝓔 = τ(I + ½τ ad_ξ)) ``τ{v_y − ½τN(y)v_Z; v_Z}``, else :func:`poincare_E_point` times the rows."""
    if _lorentz_zero(xi):
        y0, y1, y2, y3 = xi[0], xi[1], xi[2], xi[3]
        for a in range(V.shape[0]):
            n = _translation_N(y0, y1, y2, y3, V[a])
            for k in range(4):
                out[a, k] = tau * (V[a, k] - 0.5 * tau * n[k])
            for k in range(4, 10):
                out[a, k] = tau * V[a, k]
        return
    A = np.empty((10, 10))
    poincare_E_point(tau, xi, A)
    for a in range(V.shape[0]):
        _matvec10(A, V[a], out[a])


@njit(cache=True, inline='always')
def poincare_Ad_inv_apply_point(g, X, out, work):
    """``out[a]`` (10,) ← ``Ad_{g⁻¹} X[a]`` for every row of ``X`` ``(k, 10)``: for ``g = (t; I)``
    (``Ad_{g⁻¹} = [[I, N(t)], [0, I]]``) ``{x_y + N(t)x_Z; x_Z}``, else :func:`poincare_inverse_point`
    and :func:`poincare_Ad_point` times the rows."""
    if _pure_translation(g):
        t0, t1, t2, t3 = g[1, 0], g[2, 0], g[3, 0], g[4, 0]
        for a in range(X.shape[0]):
            n = _translation_N(t0, t1, t2, t3, X[a])
            for k in range(4):
                out[a, k] = X[a, k] + n[k]
            for k in range(4, 10):
                out[a, k] = X[a, k]
        return
    gi = np.empty((5, 5))
    A = np.empty((10, 10))
    _inverse5(g, gi)
    poincare_Ad_point(gi, A)
    for a in range(X.shape[0]):
        _matvec10(A, X[a], out[a])


@njit(cache=True, inline='always')
def poincare_axis_flow_point(k, t, s, acc, work):
    """The free flow along one basis axis: ``E = exp(t b_k)``, ``s ← Ad_Eᵀ s`` and ``acc ← acc E``
    for ``s`` (10,) and ``acc`` (5, 5) in place, without the matrices; ``work`` is unused (the
    scratch of the generic form, ``cartan.compiled.kernels.FUSED_OPS["axis_flow"]``).

    Every axis is closed-form; ``ad_{b_k}`` is sparse, and ``Ad_E = exp(t ad_{b_k})``:

    * a translation ``{e_μ; 0}`` (``k = μ < 4``): ``ad² = 0``, ``E = (t e_μ; I)``, so
      ``Ad_Eᵀ s = s + t ad_{b_k}ᵀ s`` (:func:`poincare_Ad_T_point`: ``s_Z ← s_Z − N(t e_μ)ᵀ s_y``,
      ``N(y)ᵀ s_y = (y⃗ s₀ + y₀ s⃗; y⃗ × s⃗)``) and ``acc``'s translation moves by ``t`` times its
      Lorentz block's column μ;
    * a boost ``{0; K_j}`` (``k = 4 + j``): ``Λ`` boosts the plane ``(e₀, e_{1+j})`` by
      ``cosh t``, ``sinh t``; ``Ad_E`` does the same on the pairs ``(s₀, s_{1+j})``,
      ``(c_p, d_q)`` (sign −) and ``(c_q, d_p)`` (sign +), ``p = j + 1``, ``q = j + 2`` (mod 3);
    * a rotation ``{0; J_j}`` (``k = 7 + j``): ``Λ`` turns the plane ``(e_{1+p}, e_{1+q})`` by
      ``cos t``, ``sin t``, and ``Ad_Eᵀ`` turns ``(s⃗_p, s⃗_q)``, ``(c_p, c_q)`` and
      ``(d_p, d_q)`` back (``Λᵀ``, as SE(3)'s :func:`~cartan.groups.se3.se3_axis_flow_point`).
    """
    j = k - 1 if k < 4 else (k - 4 if k < 7 else k - 7)
    p = j + 1 if j < 2 else 0
    q = j + 2 if j < 1 else j - 1
    if k == 0:
        for i in range(3):
            s[4 + i] -= t * s[1 + i]
        for i in range(1, 5):
            acc[i, 0] += t * acc[i, 1]
        return
    if k < 4:
        s[4 + j] -= t * s[0]
        s[7 + p] += t * s[1 + q]
        s[7 + q] -= t * s[1 + p]
        for i in range(1, 5):
            acc[i, 0] += t * acc[i, 1 + k]
        return
    if k < 7:
        ch, sh = math.cosh(t), math.sinh(t)
        x, y = s[0], s[1 + j]
        s[0], s[1 + j] = ch * x + sh * y, sh * x + ch * y
        x, y = s[4 + p], s[7 + q]
        s[4 + p], s[7 + q] = ch * x - sh * y, ch * y - sh * x
        x, y = s[4 + q], s[7 + p]
        s[4 + q], s[7 + p] = ch * x + sh * y, ch * y + sh * x
        for i in range(1, 5):
            x, y = acc[i, 1], acc[i, 2 + j]
            acc[i, 1], acc[i, 2 + j] = ch * x + sh * y, sh * x + ch * y
        return
    c, sn = math.cos(t), math.sin(t)
    for o in (1, 4, 7):
        x, y = s[o + p], s[o + q]
        s[o + p], s[o + q] = c * x + sn * y, c * y - sn * x
    for i in range(1, 5):
        x, y = acc[i, 2 + p], acc[i, 2 + q]
        acc[i, 2 + p], acc[i, 2 + q] = c * x + sn * y, c * y - sn * x


# ---------------------------------------------------------------------- passes over edges and nodes
# The lattice's generated loops call these (``g_<op>`` of :data:`cartan.compiled.kernels.FUSED_OPS`)
# instead of the forms built from the point kernels: the same arithmetic, without an out-of-line
# call per element, and for the string's edges (pure translations: Λ = I exactly) the closed
# forms of the logarithm and of dexp⁻¹(±ξ)ᵀ.


@njit(cache=True, inline='always')
def poincare_log_chunk_point(G, lo, hi, XI):
    """``XI[e]`` (10,) ← ``log G[e]`` (:func:`poincare_log_point`) for ``lo ≤ e < hi``, ``G``
    ``(E, 5, 5)``, ``XI`` ``(E, 10)``: :func:`_log_chunk`, compiled once and cached."""
    _log_chunk(G, lo, hi, XI)


@njit(cache=True, error_model='numpy')
def _log_chunk(G, lo, hi, XI):
    """A pure translation ``(t; I)`` gives ``{t; 0}`` in line; any other edge
    :func:`poincare_log_point`: its results to the bit."""
    for e in range(max(lo, 0), hi):
        g = G[e]
        if _pure_translation(g):
            XI[e, 0], XI[e, 1], XI[e, 2], XI[e, 3] = g[1, 0], g[2, 0], g[3, 0], g[4, 0]
            for k in range(4, 10):
                XI[e, k] = 0.0
        else:
            poincare_log_point(g, XI[e])


@register_jitable(inline='always')
def _translation_ad_T(y0, y1, y2, y3, v0, v1, v2, v3):
    """The Lorentz part of ``ad_ξᵀ v`` for a pure translation ``ξ = {y; 0}`` (its translation
    part is zero): ``−N(y)ᵀ v_y``, ``N(y) = [[y⃗ᵀ, 0], [y₀ I, −ŷ⃗]]``, each entry the sum of
    :func:`poincare_ad_point`'s two non-zero products in its order: 6 scalars."""
    return (-y1 * v0 + -y0 * v1, -y2 * v0 + -y0 * v2, -y3 * v0 + -y0 * v3,
            y3 * v2 + -y2 * v3, -y3 * v1 + y1 * v3, y2 * v1 + -y1 * v2)


@njit(cache=True, inline='always')
def poincare_dexp_inv_T_pair_chunk_point(XI, Q, scale, lo, hi, VT, VH):
    """``VT[e]`` ← ``s_e dexp⁻¹(ξ_e)ᵀq_e`` and ``VH[e]`` ← ``s_e dexp⁻¹(−ξ_e)ᵀq_e``
    (:func:`poincare_dexp_inv_T_pair_point`) for ``lo ≤ e < hi`` (``XI``, ``Q``, ``VT``, ``VH``
    ``(E, 10)``; ``scale`` ``(E,)`` or empty: 1): :func:`_pair_chunk`, compiled once and cached."""
    _pair_chunk(XI, Q, scale, lo, hi, VT, VH)


@njit(cache=True, error_model='numpy')
def _pair_chunk(XI, Q, scale, lo, hi, VT, VH):
    """A pure translation ``ξ = {y; 0}`` (ad_ξ² = 0): ``dexp⁻¹(±ξ)ᵀq = q ∓ ½ad_ξᵀq`` with
    :func:`_translation_ad_T`, in line; any other edge :func:`poincare_dexp_inv_T_pair_point`.
    The point kernel's values (== ; a zero may differ in sign)."""
    scaled = scale.shape[0] > 0
    out = np.empty(10)
    neg = np.empty(10)
    for e in range(max(lo, 0), hi):
        xi = XI[e]
        q = Q[e]
        f = scale[e] if scaled else 1.0
        if xi[4] == 0.0 and xi[5] == 0.0 and xi[6] == 0.0 and xi[7] == 0.0 and xi[8] == 0.0 and xi[9] == 0.0:
            a = _translation_ad_T(xi[0], xi[1], xi[2], xi[3], q[0], q[1], q[2], q[3])
            for k in range(4):
                VT[e, k] = f * (q[k] - 0.5 * 0.0)
                VH[e, k] = f * (q[k] + 0.5 * 0.0)
            for k in range(6):
                VT[e, 4 + k] = f * (q[4 + k] - 0.5 * a[k])
                VH[e, 4 + k] = f * (q[4 + k] + 0.5 * a[k])
        else:
            poincare_dexp_inv_T_pair_point(xi, q, out, neg)
            for k in range(10):
                VT[e, k] = f * out[k]
                VH[e, k] = f * neg[k]


@njit(cache=True, inline='always')
def poincare_move_chunk_point(Di, Dn, G, tail, head, lo, hi):
    """``G[e]`` ← ``Di[tail[e]] G[e] Dn[head[e]]`` for ``lo ≤ e < hi`` (all ``(·, 5, 5)``): two
    :func:`poincare_compose_point` in line (their results to the bit), :func:`_move_chunk`."""
    _move_chunk(Di, Dn, G, tail, head, lo, hi)


@njit(cache=True, error_model='numpy')
def _move_chunk(Di, Dn, G, tail, head, lo, hi):
    """Where ``Di[tail[e]]``, ``G[e]`` and ``Dn[head[e]]`` are pure translations (the string's
    edges and motions), ``G[e]``'s translation becomes ``(t_i + t_e) + t_j`` and its Lorentz
    block stays the identity: the products' values (their other terms are exact zeros and
    ones)."""
    tmp = np.empty((5, 5))
    for e in range(max(lo, 0), hi):
        a, g, b = Di[tail[e]], G[e], Dn[head[e]]
        if _pure_translation(a) & _pure_translation(g) & _pure_translation(b):
            for r in range(1, 5):
                g[r, 0] = (a[r, 0] + g[r, 0]) + b[r, 0]
            continue
        _compose5(a, g, tmp)
        _compose5(tmp, b, g)


@njit(cache=True, inline='always')
def poincare_frames_chunk_point(Dn, Di, Phi, lo, hi):
    """``Di[i]`` ← ``Dn[i]⁻¹`` for ``lo ≤ i < hi`` and ``Phi[i]`` ← ``Phi[i] Dn[i]`` for the rows
    of ``Phi`` among them: :func:`poincare_inverse_point` and :func:`poincare_compose_point` in
    line (their results to the bit), :func:`_frames_chunk`."""
    _frames_chunk(Dn, Di, Phi, lo, hi)


@njit(cache=True, error_model='numpy')
def _frames_chunk(Dn, Di, Phi, lo, hi):
    """Where ``Dn[i]`` is a pure translation ``(t; I)``: ``Di[i] = (−t; I)`` and ``Phi[i]``'s
    translation ``+= Λ t`` (its Lorentz block unchanged): the products' values (their other
    terms are exact zeros and ones)."""
    tmp = np.empty((5, 5))
    lo = max(lo, 0)
    for i in range(lo, hi):
        d = Dn[i]
        if _pure_translation(d):
            for a in range(5):
                for b in range(5):
                    Di[i, a, b] = 1.0 if a == b else 0.0
            for r in range(1, 5):
                Di[i, r, 0] = -d[r, 0]
        else:
            _inverse5(d, Di[i])
    for i in range(lo, min(hi, Phi.shape[0])):
        d = Dn[i]
        f = Phi[i]
        if _pure_translation(d):
            for r in range(1, 5):
                f[r, 0] = f[r, 0] + f[r, 1] * d[1, 0] + f[r, 2] * d[2, 0] + f[r, 3] * d[3, 0] + f[r, 4] * d[4, 0]
            continue
        for a in range(5):
            for b in range(5):
                tmp[a, b] = f[a, b]
        _compose5(tmp, d, f)
