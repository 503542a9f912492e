"""The special Euclidean group SE(2) of the plane in closed form.

Conventions (the paper's affine form, homogeneous coordinate first)
-------------------------------------------------------------------
* An element is ``g = (a; R) = [[1, 0, 0], [a1, c, −s], [a2, s, c]]`` and acts on the plane by
  ``g·x = R x + a``.
* Algebra components ``ξ = (v1, v2, ω)``: translation first, rotation last (the planar
  Cosserat rod's ``(θ₁, θ₂, π)``), with ``hat(ξ) = [[0, 0, 0], [v1, 0, −ω], [v2, ω, 0]]``; the
  basis is ``b₁ = E₂₁``, ``b₂ = E₃₁``, ``b₃ = E₃₂ − E₂₃`` and ``vee`` returns
  ``(A21, A31, ½(A32 − A23))``.
* With ``J = [[0, −1], [1, 0]]``:

  - ``exp(ξ) = (V(ω) v; R(ω))``, ``V = A I + ωB J``, ``A = sin ω/ω``, ``B = (1 − cos ω)/ω²``;
  - ``log(g)``: ``ω = atan2(g32 − g23, g22 + g33)`` ∈ (−π, π] and ``v = V⁻¹a`` with
    ``V⁻¹ = α I − (ω/2) J``, ``α = (ω/2) cot(ω/2)``;
  - ``Ad_g = [[R, −J a], [0, 1]]``, ``ad_ξ = [[ωJ, −J v], [0, 0]]``,
    ``[ξ, η] = (ω J u − ν J v, 0)`` for ``η = (u, ν)``;
  - ``dexp(ξ) = Σ ad_ξᵏ/(k+1)! = [[V, p], [0, 1]]`` with ``p = −(B I + ωC J) J v``,
    ``C = (ω − sin ω)/ω³``;
  - ``dexp⁻¹(ξ) = [[V⁻¹, q], [0, 1]]`` with ``q = ½ J v + ωc v``,
    ``c = (1 − (ω/2) cot(ω/2))/ω²`` (so that ``α = 1 − ω² c``);
  - ``𝓔(Δt, Y) = Δt·dexp(ΔtY)``.

* :meth:`SE2.log_domain_norm` is the rotation angle ``|ω|``; ``log ∘ exp`` is the identity
  for ``|ω| < π`` whatever the translation.

Numerics
--------
``A``, ``B``, ``C`` and ``c`` are the SO(3) coefficients of :mod:`cartan.groups.so3`
(``so3_exp_coeffs``, ``so3_dexp_coeffs``, ``so3_dexp_inv_coeff`` and their vectorised
forms), evaluated from their Taylor series in ``ω²`` for small angles: both backends use the
same formulas, stable as ω → 0 and up to ω = π.  The rotation block uses ``cos ω``, ``sin ω``
directly.

Kernels
-------
The per-point kernels ``se2_*_point`` are public, allocation-free and
``@njit(cache=True)``; the batch loops ``_*_batch`` map them over ``P`` flattened points and
are listed in :attr:`SE2._kernels`.  The generated compiled loops also bind the fused kernels
(products with ``Ad_gᵀ``, ``dexp(ξ)⁻ᵀ``, ``dexp(ξ)⁻¹``, ``𝓔``, and the one-axis free flow
:func:`se2_axis_flow_point`: a shift or a turn, without the 3 × 3 matrices) and the passes over
edges and nodes of the lattice (``se2_log_chunk_point``, ``se2_dexp_inv_T_pair_chunk_point``,
``se2_move_chunk_point``, ``se2_frames_chunk_point``, ``se2_axial_flow_chunk_point``), each a
function compiled once and cached, the edge passes and the free flow vectorised across their
elements as SE(3)'s are (:mod:`cartan.groups.se3`).  Each gives the point kernels' results to
round-off (``tests/test_se2_chunks.py``).
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
    ATAN_SERIES,
    ATAN_SERIES_X2,
    SMALL_THETA2,
    TAYLOR_CINV,
    _cinv_direct,
    dexp_coeffs_np,
    dexp_inv_coeff_np,
    exp_coeffs_np,
    horner,
    so3_dexp_coeffs,
    so3_dexp_inv_coeff,
    so3_exp_coeffs,
)

__all__ = [
    "SE2",
    "se2_Ad_T_point",
    "se2_Ad_inv_apply_point",
    "se2_Ad_point",
    "se2_E_apply_point",
    "se2_E_point",
    "se2_act_point",
    "se2_ad_point",
    "se2_axial_flow_chunk_point",
    "se2_axis_flow_point",
    "se2_bracket_point",
    "se2_coad_exp_point",
    "se2_compose_point",
    "se2_dexp_inv_T_pair_chunk_point",
    "se2_dexp_inv_T_pair_point",
    "se2_dexp_inv_T_point",
    "se2_dexp_inv_apply_point",
    "se2_dexp_inv_point",
    "se2_dexp_point",
    "se2_exp_point",
    "se2_frames_chunk_point",
    "se2_hat_point",
    "se2_inverse_point",
    "se2_log_chunk_point",
    "se2_log_point",
    "se2_move_chunk_point",
    "se2_vee_point",
]


# ---------------------------------------------------------------------- numba point kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def _zero_affine_row(out):
    out[0, 0] = 0.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0


@njit(cache=True, inline='always')
def _unit_last_row(out):
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = 1.0


@njit(cache=True, inline='always')
def se2_hat_point(xi, out):
    """``out`` (3, 3) ← ``[[0, 0, 0], [v1, 0, −ω], [v2, ω, 0]]`` for ``xi = (v1, v2, ω)``."""
    _zero_affine_row(out)
    out[1, 0] = xi[0]
    out[1, 1] = 0.0
    out[1, 2] = -xi[2]
    out[2, 0] = xi[1]
    out[2, 1] = xi[2]
    out[2, 2] = 0.0


@njit(cache=True, inline='always')
def se2_vee_point(A, out):
    """``out`` (3,) ← ``(A21, A31, ½(A32 − A23))`` for ``A`` (3, 3)."""
    out[0] = A[1, 0]
    out[1] = A[2, 0]
    out[2] = 0.5 * (A[2, 1] - A[1, 2])


@njit(cache=True, inline='always')
def se2_compose_point(g, h, out):
    """``out`` (3, 3) ← ``g h``; ``out`` must not alias the inputs."""
    for i in range(3):
        for j in range(3):
            out[i, j] = g[i, 0] * h[0, j] + g[i, 1] * h[1, j] + g[i, 2] * h[2, j]


@njit(cache=True, inline='always')
def se2_inverse_point(g, out):
    """``out`` (3, 3) ← ``g⁻¹ = (−Rᵀa; Rᵀ)``; ``out`` must not alias ``g``."""
    a1, a2 = g[1, 0], g[2, 0]
    out[0, 0] = 1.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[1, 0] = -(g[1, 1] * a1 + g[2, 1] * a2)
    out[2, 0] = -(g[1, 2] * a1 + g[2, 2] * a2)
    out[1, 1] = g[1, 1]
    out[1, 2] = g[2, 1]
    out[2, 1] = g[1, 2]
    out[2, 2] = g[2, 2]


@njit(cache=True, inline='always')
def se2_act_point(g, x, out):
    """``out`` (2,) ← ``R x + a``."""
    out[0] = g[1, 1] * x[0] + g[1, 2] * x[1] + g[1, 0]
    out[1] = g[2, 1] * x[0] + g[2, 2] * x[1] + g[2, 0]


@njit(cache=True, inline='always')
def se2_exp_point(xi, out):
    """``out`` (3, 3) ← ``exp(hat(ξ)) = (V v; R(ω))`` for ``xi = (v1, v2, ω)``."""
    v1, v2, w = xi[0], xi[1], xi[2]
    a, b = so3_exp_coeffs(w * w)
    wb = w * b
    out[0, 0] = 1.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[1, 0] = a * v1 - wb * v2
    out[2, 0] = wb * v1 + a * v2
    c = np.cos(w)
    s = np.sin(w)
    out[1, 1] = c
    out[1, 2] = -s
    out[2, 1] = s
    out[2, 2] = c


@njit(cache=True, inline='always')
def se2_log_point(g, out):
    """``out`` (3,) ← principal logarithm ``(v1, v2, ω)`` of ``g`` (3, 3), ``|ω| ≤ π``."""
    w = np.arctan2(g[2, 1] - g[1, 2], g[1, 1] + g[2, 2])
    alpha = 1.0 - w * w * so3_dexp_inv_coeff(w * w)
    h = 0.5 * w
    a1, a2 = g[1, 0], g[2, 0]
    out[0] = alpha * a1 + h * a2
    out[1] = alpha * a2 - h * a1
    out[2] = w


@njit(cache=True, inline='always')
def se2_Ad_point(g, out):
    """``out`` (3, 3) ← ``Ad_g = [[R, −J a], [0, 1]]``."""
    out[0, 0] = g[1, 1]
    out[0, 1] = g[1, 2]
    out[0, 2] = g[2, 0]
    out[1, 0] = g[2, 1]
    out[1, 1] = g[2, 2]
    out[1, 2] = -g[1, 0]
    _unit_last_row(out)


@njit(cache=True, inline='always')
def se2_ad_point(xi, out):
    """``out`` (3, 3) ← ``ad_ξ = [[0, −ω, v2], [ω, 0, −v1], [0, 0, 0]]``."""
    out[0, 0] = 0.0
    out[0, 1] = -xi[2]
    out[0, 2] = xi[1]
    out[1, 0] = xi[2]
    out[1, 1] = 0.0
    out[1, 2] = -xi[0]
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = 0.0


@njit(cache=True, inline='always')
def se2_bracket_point(xi, eta, out):
    """``out`` (3,) ← ``[ξ, η] = ad_ξ η``."""
    out[0] = xi[1] * eta[2] - xi[2] * eta[1]
    out[1] = xi[2] * eta[0] - xi[0] * eta[2]
    out[2] = 0.0


@njit(cache=True, inline='always')
def _dexp_scaled(v1, v2, w, s, out):
    """``out`` (3, 3) ← ``s·dexp(v1, v2, w)``."""
    a = so3_exp_coeffs(w * w)[0]
    b, c = so3_dexp_coeffs(w * w)
    wb = w * b
    wc = w * c
    out[0, 0] = s * a
    out[0, 1] = -s * wb
    out[0, 2] = s * (wc * v1 + b * v2)
    out[1, 0] = s * wb
    out[1, 1] = s * a
    out[1, 2] = s * (wc * v2 - b * v1)
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = s


@njit(cache=True, inline='always')
def se2_dexp_point(xi, out):
    """``out`` (3, 3) ← ``dexp(ξ) = [[V, p], [0, 1]]``."""
    _dexp_scaled(xi[0], xi[1], xi[2], 1.0, out)


@njit(cache=True, inline='always')
def se2_dexp_inv_point(xi, out):
    """``out`` (3, 3) ← ``dexp(ξ)⁻¹ = [[V⁻¹, q], [0, 1]]``."""
    v1, v2, w = xi[0], xi[1], xi[2]
    c = so3_dexp_inv_coeff(w * w)
    alpha = 1.0 - w * w * c
    h = 0.5 * w
    wc = w * c
    out[0, 0] = alpha
    out[0, 1] = h
    out[0, 2] = wc * v1 - 0.5 * v2
    out[1, 0] = -h
    out[1, 1] = alpha
    out[1, 2] = wc * v2 + 0.5 * v1
    _unit_last_row(out)


@njit(cache=True, inline='always')
def se2_E_point(dt, xi, out):
    """``out`` (3, 3) ← ``𝓔(Δt, ξ) = Δt·dexp(Δt ξ)`` for scalar ``dt``."""
    _dexp_scaled(dt * xi[0], dt * xi[1], dt * xi[2], dt, out)


# ---------------------------------------------------------------------- fused kernels and passes
# The generated loops bind these (``g_<op>`` of :data:`cartan.compiled.kernels.FUSED_OPS`) instead
# of the forms built there from the 3 × 3 matrices of the point kernels above: the same products,
# without the matrices, and the passes over edges and nodes as functions compiled once and cached.
@njit(cache=True, inline='always')
def se2_Ad_T_point(g, v, out):
    """``out`` (3,) ← ``Ad_gᵀ v = (Rᵀv_t; v_ω + a₂v₁ − a₁v₂)`` for ``g = (a; R)`` (3, 3)."""
    v0, v1, v2 = v[0], v[1], v[2]
    out[0] = g[1, 1] * v0 + g[2, 1] * v1
    out[1] = g[1, 2] * v0 + g[2, 2] * v1
    out[2] = (g[2, 0] * v0 + -g[1, 0] * v1) + v2


@register_jitable(inline='always')
def _dexp_inv_T6(x1, x2, w, c, q0, q1, q2):
    """``dexp(ξ)⁻ᵀ q`` (3 scalars) for ``ξ = (x1, x2, w)`` with ``c`` =
    :func:`so3_dexp_inv_coeff` ``(w²)``: the transpose of :func:`se2_dexp_inv_point`'s matrix
    ``[[α, h, wc x1 − ½x2], [−h, α, wc x2 + ½x1], [0, 0, 1]]`` (``α = 1 − w²c``, ``h = ½w``) on q."""
    alpha = 1.0 - w * w * c
    h = 0.5 * w
    wc = w * c
    return (alpha * q0 + -h * q1, h * q0 + alpha * q1,
            ((wc * x1 - 0.5 * x2) * q0 + (wc * x2 + 0.5 * x1) * q1) + q2)


@register_jitable(inline='always')
def _ad_T_add6(x1, x2, w, q0, q1, q2, o0, o1, o2):
    """``o + ad_ξᵀ q = o + (w q₁, −w q₀, x₂q₀ − x₁q₁)`` (the columns of :func:`se2_ad_point`): with
    ``o = dexp(ξ)⁻ᵀ q``, ``dexp(−ξ)⁻ᵀ q`` (``dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ``), the head term of an edge."""
    return o0 + w * q1, o1 + -w * q0, (o2 + x2 * q0) + -x1 * q1


@njit(cache=True, inline='always')
def se2_dexp_inv_T_point(xi, q, out):
    """``out`` (3,) ← ``dexp(ξ)⁻ᵀ q`` without the matrix (:func:`_dexp_inv_T6`)."""
    w = xi[2]
    out[0], out[1], out[2] = _dexp_inv_T6(xi[0], xi[1], w, so3_dexp_inv_coeff(w * w), q[0], q[1], q[2])


@njit(cache=True, inline='always')
def se2_dexp_inv_T_pair_point(xi, q, out, out_neg):
    """``out`` (3,) ← ``dexp(ξ)⁻ᵀ q`` and ``out_neg`` (3,) ← ``dexp(−ξ)⁻ᵀ q = dexp(ξ)⁻ᵀ q + ad_ξᵀ q``."""
    x1, x2, w = xi[0], xi[1], xi[2]
    q0, q1, q2 = q[0], q[1], q[2]
    o = _dexp_inv_T6(x1, x2, w, so3_dexp_inv_coeff(w * w), q0, q1, q2)
    out[0], out[1], out[2] = o
    out_neg[0], out_neg[1], out_neg[2] = _ad_T_add6(x1, x2, w, q0, q1, q2, o[0], o[1], o[2])


@njit(cache=True, inline='always')
def se2_dexp_inv_apply_point(xi, v, out, work):
    """``out`` (3,) ← ``dexp(ξ)⁻¹ v`` without the matrix (:func:`se2_dexp_inv_point`); ``work`` is unused."""
    x1, x2, w = xi[0], xi[1], xi[2]
    c = so3_dexp_inv_coeff(w * w)
    alpha = 1.0 - w * w * c
    h = 0.5 * w
    wc = w * c
    v0, v1, v2 = v[0], v[1], v[2]
    out[0] = (alpha * v0 + h * v1) + (wc * x1 - 0.5 * x2) * v2
    out[1] = (-h * v0 + alpha * v1) + (wc * x2 + 0.5 * x1) * v2
    out[2] = v2


@njit(cache=True, inline='always')
def se2_Ad_inv_apply_point(g, X, out, work):
    """``out[a]`` (3,) ← ``Ad_{g⁻¹} X[a]`` for every row of ``X`` ``(k, 3)``: with ``g⁻¹ = (b; Rᵀ)``,
    ``b = −Rᵀa`` (:func:`se2_inverse_point`), ``(Rᵀx_t + x_ω (b₂, −b₁); x_ω)``; ``work`` is unused."""
    a1, a2 = g[1, 0], g[2, 0]
    b1 = -(g[1, 1] * a1 + g[2, 1] * a2)
    b2 = -(g[1, 2] * a1 + g[2, 2] * a2)
    for r in range(X.shape[0]):
        x0, x1, x2 = X[r, 0], X[r, 1], X[r, 2]
        out[r, 0] = (g[1, 1] * x0 + g[2, 1] * x1) + b2 * x2
        out[r, 1] = (g[1, 2] * x0 + g[2, 2] * x1) + -b1 * x2
        out[r, 2] = x2


@njit(cache=True, inline='always')
def se2_E_apply_point(dt, xi, V, out, work):
    """``out[a]`` (3,) ← ``𝓔(Δt, ξ) V[a]`` for every row of ``V`` ``(k, 3)``: the entries of
    :func:`se2_E_point` (``Δt·dexp(Δtξ)``) on each row, without the matrix; ``work`` is unused."""
    v1, v2, w = dt * xi[0], dt * xi[1], dt * xi[2]
    a = so3_exp_coeffs(w * w)[0]
    b, c = so3_dexp_coeffs(w * w)
    wb = w * b
    wc = w * c
    e00, e01, e02 = dt * a, -dt * wb, dt * (wc * v1 + b * v2)
    e10, e12 = dt * wb, dt * (wc * v2 - b * v1)
    for r in range(V.shape[0]):
        u0, u1, u2 = V[r, 0], V[r, 1], V[r, 2]
        out[r, 0] = (e00 * u0 + e01 * u1) + e02 * u2
        out[r, 1] = (e10 * u0 + e00 * u1) + e12 * u2
        out[r, 2] = dt * u2


@njit(cache=True, inline='always')
def se2_coad_exp_point(xi, s, E, work):
    """``E`` (3, 3) ← ``exp(ξ)`` (:func:`se2_exp_point`) and ``s`` (3,) ← ``Ad_Eᵀ s`` in place
    (:func:`se2_Ad_T_point`); ``work`` is unused."""
    se2_exp_point(xi, E)
    s0, s1, s2 = s[0], s[1], s[2]
    s[0] = E[1, 1] * s0 + E[2, 1] * s1
    s[1] = E[1, 2] * s0 + E[2, 2] * s1
    s[2] = (E[2, 0] * s0 + -E[1, 0] * s1) + s2


@njit(cache=True, inline='always')
def se2_axis_flow_point(k, t, s, acc, work):
    """The free flow along one basis axis: ``E = exp(t b_k)``, ``s ← Ad_Eᵀ s`` and ``acc ← acc E``
    for ``s`` (3,) and ``acc`` (3, 3) in place, without the matrices; ``work`` is unused.

    A translation along ``e₁`` (``k = 0``) or ``e₂`` (``k = 1``): ``E = (t e_k; I)``, so
    ``Ad_Eᵀ s`` adds ``−t s₁`` (k = 0) or ``t s₀`` (k = 1) to ``s₂``, and ``acc``'s translation moves
    by ``t`` times its rotation's column k.  The rotation (``k = 2``): ``E = (0; R(t))`` with cosine
    ``1 − Bt²`` and sine ``At`` (the coefficients of :func:`so3_exp_coeffs`), ``Ad_Eᵀ s = (Rᵀs_t; s₂)``
    and the two columns of ``acc``'s rotation turn (as :func:`cartan.groups.se3.se3_axis_flow_point`)."""
    if k == 0:
        s[2] -= t * s[1]
        acc[1, 0] += t * acc[1, 1]
        acc[2, 0] += t * acc[2, 1]
        return
    if k == 1:
        s[2] += t * s[0]
        acc[1, 0] += t * acc[1, 2]
        acc[2, 0] += t * acc[2, 2]
        return
    c, sn = _turn_coeffs_series(t) if t * t < SMALL_THETA2 else _turn_coeffs_direct(t)
    s[0], s[1] = _turn(c, sn, s[0], s[1])
    for i in range(1, 3):
        acc[i, 1], acc[i, 2] = _turn(c, sn, acc[i, 1], acc[i, 2])


@njit(cache=True, inline='always')
def se2_axial_flow_chunk_point(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes,
                               coef):
    """The free flow of ``lie-verlet`` at the nodes ``lo ≤ i < hi`` when every piece is axial: piece
    by piece, the times ``t = τ_p (P_p)_kk S_k`` of its directions (zero at clamped nodes and held
    components), then :func:`se2_axis_flow_point` along each, ``S`` ``(n, 3)`` in place and the
    motions ``Dn`` ``(n, 3, 3)`` (rows ``lo … hi − 1``, from the identity); returns whether a node
    moved.  :func:`_axial_flow_chunk`, compiled once and cached: the nodes' momenta and motions as
    one row per entry, each axis flow a branch-free pass over them (as SE(3)'s
    ``se3_axial_flow_chunk_point``); a node whose time is zero is turned or shifted by zero instead
    of being skipped (the same values)."""
    return _axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes, coef)


@njit(cache=True, error_model='numpy')
def _axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes, coef):
    lo = max(lo, 0)
    nb = max(hi - lo, 0)
    # rows: S (0–2), the motion's translation (3–4) and rotation row by row (5–8), from the identity
    F = np.zeros((9, nb))
    T = np.empty((3, nb))
    CS = np.empty(nb)
    SN = np.empty(nb)
    for i0 in range(nb):
        i = lo + i0
        F[0, i0] = S[i, 0]
        F[1, i0] = S[i, 1]
        F[2, i0] = S[i, 2]
        F[5, i0] = 1.0
        F[8, i0] = 1.0
    moved = 0
    for p in range(npieces):
        axial_times(F, T, lo, nb, p, tau, naxes, axes, coef, any_clamped, clamped, any_held, held)
        for c in range(naxes[p]):
            k = axes[p, c]
            moved += count_moved(T, c, nb)
            if k == 0:
                for i0 in range(nb):
                    t = T[c, i0]
                    F[2, i0] -= t * F[1, i0]
                    F[3, i0] += t * F[5, i0]
                    F[4, i0] += t * F[7, i0]
                continue
            if k == 1:
                for i0 in range(nb):
                    t = T[c, i0]
                    F[2, i0] += t * F[0, i0]
                    F[3, i0] += t * F[6, i0]
                    F[4, i0] += t * F[8, i0]
                continue
            turn_coeffs_chunk(T, c, nb, CS, SN)
            for i0 in range(nb):
                cs, sn = CS[i0], SN[i0]
                F[0, i0], F[1, i0] = _turn(cs, sn, F[0, i0], F[1, i0])
                F[5, i0], F[6, i0] = _turn(cs, sn, F[5, i0], F[6, i0])
                F[7, i0], F[8, i0] = _turn(cs, sn, F[7, i0], F[8, i0])
    for i0 in range(nb):
        i = lo + i0
        S[i, 0] = F[0, i0]
        S[i, 1] = F[1, i0]
        S[i, 2] = F[2, i0]
        _store6(Dn, i, F[3, i0], F[4, i0], F[5, i0], F[6, i0], F[7, i0], F[8, i0])
    return moved > 0


@register_jitable(inline='always')
def _store6(A, e, a1, a2, r00, r01, r10, r11):
    """``A[e]`` ← the SE(2) element of translation ``(a1, a2)`` and rotation ``[[r00, r01], [r10, r11]]``."""
    A[e, 0, 0] = 1.0
    A[e, 0, 1] = 0.0
    A[e, 0, 2] = 0.0
    A[e, 1, 0] = a1
    A[e, 2, 0] = a2
    A[e, 1, 1] = r00
    A[e, 1, 2] = r01
    A[e, 2, 1] = r10
    A[e, 2, 2] = r11


@register_jitable(inline='always')
def _compose6(ga1, ga2, g00, g01, g10, g11, ha1, ha2, h00, h01, h10, h11):
    """The product of two SE(2) elements given by their 6 entries ``(a1, a2, r00, r01, r10, r11)``:
    :func:`se2_compose_point`'s sums without its products by the exact zeros and ones of the
    first row (the same values; a zero may differ in sign), 6 scalars."""
    return ((ga1 + g00 * ha1) + g01 * ha2, (ga2 + g10 * ha1) + g11 * ha2,
            g00 * h00 + g01 * h10, g00 * h01 + g01 * h11, g10 * h00 + g11 * h10, g10 * h01 + g11 * h11)


@njit(cache=True, inline='always')
def se2_move_chunk_point(Di, Dn, G, tail, head, lo, hi):
    """``G[e]`` ← ``Di[tail[e]] G[e] Dn[head[e]]`` for ``lo ≤ e < hi`` (all ``(·, 3, 3)``): two
    :func:`se2_compose_point` in scalar code (:func:`_compose6`), :func:`_move_chunk`, compiled
    once and cached."""
    _move_chunk(Di, Dn, G, tail, head, lo, hi)


@njit(cache=True, error_model='numpy')
def _move_chunk(Di, Dn, G, tail, head, lo, hi):
    for e in range(max(lo, 0), hi):
        i, j = tail[e], head[e]
        t = _compose6(Di[i, 1, 0], Di[i, 2, 0], Di[i, 1, 1], Di[i, 1, 2], Di[i, 2, 1], Di[i, 2, 2],
                      G[e, 1, 0], G[e, 2, 0], G[e, 1, 1], G[e, 1, 2], G[e, 2, 1], G[e, 2, 2])
        o = _compose6(t[0], t[1], t[2], t[3], t[4], t[5],
                      Dn[j, 1, 0], Dn[j, 2, 0], Dn[j, 1, 1], Dn[j, 1, 2], Dn[j, 2, 1], Dn[j, 2, 2])
        _store6(G, e, o[0], o[1], o[2], o[3], o[4], o[5])


@njit(cache=True, inline='always')
def se2_frames_chunk_point(Dn, Di, Phi, lo, hi):
    """``Di[i]`` ← ``Dn[i]⁻¹`` (:func:`se2_inverse_point`) for ``lo ≤ i < hi``, and ``Phi[i]`` ←
    ``Phi[i] Dn[i]`` (:func:`se2_compose_point`) for the rows of ``Phi`` among them (``Phi``
    ``(f, 3, 3)``, f = n or 1): in scalar code, :func:`_frames_chunk`, compiled once and cached."""
    _frames_chunk(Dn, Di, Phi, lo, hi)


@njit(cache=True, error_model='numpy')
def _frames_chunk(Dn, Di, Phi, lo, hi):
    lo = max(lo, 0)
    for i in range(lo, hi):
        se2_inverse_point(Dn[i], Di[i])
    for i in range(lo, min(hi, Phi.shape[0])):
        o = _compose6(Phi[i, 1, 0], Phi[i, 2, 0], Phi[i, 1, 1], Phi[i, 1, 2], Phi[i, 2, 1], Phi[i, 2, 2],
                      Dn[i, 1, 0], Dn[i, 2, 0], Dn[i, 1, 1], Dn[i, 1, 2], Dn[i, 2, 1], Dn[i, 2, 2])
        _store6(Phi, i, o[0], o[1], o[2], o[3], o[4], o[5])


#: edges per block of the edge passes (:func:`se2_log_chunk_point`,
#: :func:`se2_dexp_inv_T_pair_chunk_point`): their structure-of-arrays scratch stays in the L1 cache
SOA_BLOCK = 256


@njit(cache=True, inline='always')
def se2_log_chunk_point(G, lo, hi, XI):
    """``XI[e]`` (3,) ← ``log G[e]`` (:func:`se2_log_point`) for ``lo ≤ e < hi``, ``G`` ``(E, 3, 3)``,
    ``XI`` ``(E, 3)``: :func:`_log_chunk`, compiled once and cached."""
    _log_chunk(G, lo, hi, XI)


@njit(cache=True, error_model='numpy')
def _log_chunk(G, lo, hi, XI):
    """In blocks of :data:`SOA_BLOCK` edges: the angle ``ω = atan2(y, x)`` (``y = g₃₂ − g₂₃``,
    ``x = g₂₂ + g₃₃``) as ``(y/x)·atan(u)/u`` with ``u = y/x`` and ``atan(u)/u`` from
    :data:`cartan.groups.so3.ATAN_SERIES`, and ``V⁻¹``'s coefficient from its series, in one
    branch-free loop that LLVM vectorises; the edges that series does not cover (``u² ≥ 1/400``,
    a turn of 0.1 rad or more, or ``x ≤ 0``) taken again by :func:`se2_log_point`.  Its results
    to round-off (``atan(u)/u`` from its series instead of ``atan2``)."""
    A = np.empty((6, SOA_BLOCK))
    bad = np.empty(SOA_BLOCK, dtype=np.bool_)
    lo = max(lo, 0)
    for c0 in range(lo, hi, SOA_BLOCK):
        nb = min(hi - c0, SOA_BLOCK)
        for e0 in range(nb):
            e = c0 + e0
            A[0, e0] = G[e, 2, 1] - G[e, 1, 2]
            A[1, e0] = G[e, 1, 1] + G[e, 2, 2]
            A[2, e0] = G[e, 1, 0]
            A[3, e0] = G[e, 2, 0]
        nbad = 0
        for e0 in range(nb):
            y, x, a1, a2 = A[0, e0], A[1, e0], A[2, e0], A[3, e0]
            u = y / x
            u2 = u * u
            w = u * horner(u2, ATAN_SERIES)
            w2 = w * w
            alpha = 1.0 - w2 * horner(w2, TAYLOR_CINV)
            h = 0.5 * w
            A[0, e0] = alpha * a1 + h * a2
            A[1, e0] = alpha * a2 - h * a1
            A[2, e0] = w
            b = (u2 >= ATAN_SERIES_X2) | (x <= 0.0)
            bad[e0] = b
            nbad += b
        store_block(A, c0, nb, 3, XI)
        if nbad:
            for e0 in range(nb):
                if bad[e0]:
                    se2_log_point(G[c0 + e0], XI[c0 + e0])


@njit(cache=True, inline='always')
def se2_dexp_inv_T_pair_chunk_point(XI, Q, scale, lo, hi, VT, VH):
    """``VT[e]`` ← ``s_e dexp(ξ_e)⁻ᵀ q_e`` and ``VH[e]`` ← ``s_e dexp(−ξ_e)⁻ᵀ q_e``
    (:func:`se2_dexp_inv_T_pair_point`) for ``lo ≤ e < hi`` (``XI``, ``Q``, ``VT``, ``VH``
    ``(E, 3)``; ``scale`` ``(E,)`` or empty: 1): :func:`_dexp_inv_T_pair_chunk`, compiled once and
    cached."""
    _dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH)


@njit(cache=True, error_model='numpy')
def _dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH):
    """In blocks of :data:`SOA_BLOCK` edges: the coefficient ``c`` of ``V⁻¹`` from its series
    everywhere and from its closed form where ``ω² ≥ SMALL_THETA2`` (the branches of
    :func:`so3_dexp_inv_coeff`), then one branch-free loop that LLVM vectorises: the coefficients
    and operations of :func:`se2_dexp_inv_T_pair_point`, its results to the bit."""
    A = np.empty((6, SOA_BLOCK))
    B = np.empty((6, SOA_BLOCK))
    K = np.empty(SOA_BLOCK)
    lo = max(lo, 0)
    scaled = scale.shape[0] > 0
    for c0 in range(lo, hi, SOA_BLOCK):
        nb = min(hi - c0, SOA_BLOCK)
        load_pair_block(XI, Q, c0, nb, 3, A)
        nbad = 0
        for e0 in range(nb):
            t2 = A[2, e0] * A[2, e0]
            nbad += t2 >= SMALL_THETA2
            K[e0] = horner(t2, TAYLOR_CINV)
        if nbad:
            for e0 in range(nb):
                t2 = A[2, e0] * A[2, e0]
                if t2 >= SMALL_THETA2:
                    K[e0] = _cinv_direct(t2)
        for e0 in range(nb):
            x1, x2, w, q0, q1, q2 = A[0, e0], A[1, e0], A[2, e0], A[3, e0], A[4, e0], A[5, e0]
            o = _dexp_inv_T6(x1, x2, w, K[e0], q0, q1, q2)
            h = _ad_T_add6(x1, x2, w, q0, q1, q2, o[0], o[1], o[2])
            B[0, e0], B[1, e0], B[2, e0] = o
            B[3, e0], B[4, e0], B[5, e0] = h
        store_scaled_pair_block(B, scale, scaled, c0, nb, 3, VT, VH)


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        se2_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        se2_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        se2_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        se2_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        se2_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        se2_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(xi, eta, out):
    for p in range(xi.shape[0]):
        se2_bracket_point(xi[p], eta[p], out[p])


@njit(cache=True)
def _dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_dexp_point(xi[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _E_batch(dt, xi, out):
    for p in range(xi.shape[0]):
        se2_E_point(dt[p], xi[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def _dexp_np(v1: np.ndarray, v2: np.ndarray, w: np.ndarray, s) -> np.ndarray:
    """Vectorised :func:`_dexp_scaled`: ``s·dexp(v1, v2, w)`` ``[..., 3, 3]``."""
    t2 = w * w
    a = exp_coeffs_np(t2)[0]
    b, c = dexp_coeffs_np(t2)
    wb = w * b
    wc = w * c
    s = np.asarray(s, dtype=float)
    out = np.zeros((*np.broadcast_shapes(w.shape, s.shape), 3, 3))
    out[..., 0, 0] = s * a
    out[..., 0, 1] = -s * wb
    out[..., 0, 2] = s * (wc * v1 + b * v2)
    out[..., 1, 0] = s * wb
    out[..., 1, 1] = s * a
    out[..., 1, 2] = s * (wc * v2 - b * v1)
    out[..., 2, 2] = s
    return out


# ---------------------------------------------------------------------- the group
class SE2(SymmetryGroup):
    """Rigid motions of the plane in the paper's affine form ``(a; R)``, homogeneous coordinate first.

    Elements are ``[..., 3, 3]`` matrices ``[[1, 0, 0], [a1, c, −s], [a2, s, c]]``; algebra
    components are ``ξ = (v1, v2, ω)`` ``[..., 3]`` (translation first, rotation last).  All
    operations are closed-form; see the module docstring for the formulas.
    """

    name = "SE2"
    dim = 3
    matrix_size = 3
    affine = True
    _kernels = kernel_table(globals())
    _point_prefix = "se2"

    def basis(self) -> np.ndarray:
        """Generators ``(E₂₁, E₃₁, E₃₂ − E₂₃)``, shape ``(3, 3, 3)``."""
        return self._hat(np.eye(3))

    def defect(self, g) -> np.ndarray:
        """Distance from SE(2).

        Parameters
        ----------
        g : array_like, shape ``[..., 3, 3]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
            ``‖RᵀR − I‖_F + |det R − 1| + ‖(g11 − 1, g12, g13)‖`` with ``R = g[..., 1:, 1:]``.
        """
        g = self._element(g)
        R = g[..., 1:, 1:]
        orth = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(2), axis=(-2, -1))
        det = R[..., 0, 0] * R[..., 1, 1] - R[..., 0, 1] * R[..., 1, 0]
        row = np.sqrt((g[..., 0, 0] - 1.0) ** 2 + g[..., 0, 1] ** 2 + g[..., 0, 2] ** 2)
        return orth + np.abs(det - 1.0) + row

    def log_domain_norm(self, xi) -> np.ndarray:
        """The rotation angle ``|ω|`` of ``xi`` ``[..., 3]`` → ``[...]``."""
        return np.abs(self._algebra(xi)[..., 2])

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 1, 0] = xi[..., 0]
        out[..., 2, 0] = xi[..., 1]
        out[..., 1, 2] = -xi[..., 2]
        out[..., 2, 1] = xi[..., 2]
        return out

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return np.stack([A[..., 1, 0], A[..., 2, 0], 0.5 * (A[..., 2, 1] - A[..., 1, 2])], axis=-1)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        a1, a2 = g[..., 1, 0], g[..., 2, 0]
        out = np.zeros(g.shape)
        out[..., 0, 0] = 1.0
        out[..., 1, 0] = -(g[..., 1, 1] * a1 + g[..., 2, 1] * a2)
        out[..., 2, 0] = -(g[..., 1, 2] * a1 + g[..., 2, 2] * a2)
        out[..., 1:, 1:] = np.swapaxes(g[..., 1:, 1:], -1, -2)
        return out

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", g[..., 1:, 1:], x) + g[..., 1:, 0]

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
        a, b = exp_coeffs_np(w * w)
        wb = w * b
        c, s = np.cos(w), np.sin(w)
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 0] = 1.0
        out[..., 1, 0] = a * v1 - wb * v2
        out[..., 2, 0] = wb * v1 + a * v2
        out[..., 1, 1] = c
        out[..., 1, 2] = -s
        out[..., 2, 1] = s
        out[..., 2, 2] = c
        return out

    def _log(self, g: np.ndarray) -> np.ndarray:
        w = np.arctan2(g[..., 2, 1] - g[..., 1, 2], g[..., 1, 1] + g[..., 2, 2])
        alpha = 1.0 - w * w * dexp_inv_coeff_np(w * w)
        h = 0.5 * w
        a1, a2 = g[..., 1, 0], g[..., 2, 0]
        return np.stack([alpha * a1 + h * a2, alpha * a2 - h * a1, w], axis=-1)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        out = np.zeros(g.shape)
        out[..., 0, 0] = g[..., 1, 1]
        out[..., 0, 1] = g[..., 1, 2]
        out[..., 0, 2] = g[..., 2, 0]
        out[..., 1, 0] = g[..., 2, 1]
        out[..., 1, 1] = g[..., 2, 2]
        out[..., 1, 2] = -g[..., 1, 0]
        out[..., 2, 2] = 1.0
        return out

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 1] = -xi[..., 2]
        out[..., 0, 2] = xi[..., 1]
        out[..., 1, 0] = xi[..., 2]
        out[..., 1, 2] = -xi[..., 0]
        return out

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        xi, eta = np.broadcast_arrays(xi, eta)
        return np.stack(
            [
                xi[..., 1] * eta[..., 2] - xi[..., 2] * eta[..., 1],
                xi[..., 2] * eta[..., 0] - xi[..., 0] * eta[..., 2],
                np.zeros(xi.shape[:-1]),
            ],
            axis=-1,
        )

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return _dexp_np(xi[..., 0], xi[..., 1], xi[..., 2], 1.0)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
        c = dexp_inv_coeff_np(w * w)
        alpha = 1.0 - w * w * c
        h = 0.5 * w
        wc = w * c
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 0] = alpha
        out[..., 0, 1] = h
        out[..., 0, 2] = wc * v1 - 0.5 * v2
        out[..., 1, 0] = -h
        out[..., 1, 1] = alpha
        out[..., 1, 2] = wc * v2 + 0.5 * v1
        out[..., 2, 2] = 1.0
        return out

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        return _dexp_np(dt * Y[..., 0], dt * Y[..., 1], dt * Y[..., 2], dt)
