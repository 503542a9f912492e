"""The proper orthochronous Lorentz group SO⁺(1,3) in closed form (SL(2,C) spinor form).

Conventions (paper, section "Relativistic Cosserat rods")
----------------------------------------------------------
* Minkowski metric ``η = diag(−1, 1, 1, 1)``; a group element is a real ``4 × 4`` matrix
  ``Λ`` with ``Λᵀ η Λ = η``, ``det Λ = 1`` and ``Λ₀₀ ≥ 1``; it acts linearly on R⁴.
* Algebra components ``ξ = (c₁, c₂, c₃, d₁, d₂, d₃)``, boost ``c`` first, rotation ``d``
  second, for the paper's ``Z = [c; d] = [[0, cᵀ], [c, d̂]]`` with the so(3) hat map
  ``d̂ = [[0, −d₃, d₂], [d₃, 0, −d₁], [−d₂, d₁, 0]]``.  The basis is ``b₀..b₂`` the boosts
  ``K_k`` and ``b₃..b₅`` the rotations ``J_k``.
* Brackets: ``[ξ₁, ξ₂] = (d₁ × c₂ + c₁ × d₂ ; d₁ × d₂ − c₁ × c₂)``.

Complex structure
-----------------
so(1,3) ≅ so(3, C) ≅ sl(2, C) as real Lie algebras through the complex 3-vector
``w = d + i c``: the bracket above is exactly the complex cross product ``w₁ × w₂``.  Every
operator that commutes with the complex structure (``ad``, ``Ad``, ``dexp``, ``dexp⁻¹``) is
a complex ``3 × 3`` matrix ``M = M_r + i M_i`` and acts on the real components ``(c; d)`` as
the ``6 × 6`` matrix ``[[M_r, M_i], [−M_i, M_r]]``.  The complex angle is ``θ`` with
``θ² = w·w = |d|² − |c|² + 2i c·d`` (bilinear, not Hermitian); writing ``θ = b + ia`` the
eigenvalues of ``Z`` are ``±a`` (boost-like) and ``±ib`` (rotation-like).  *Null* generators
have ``θ² = 0`` with ``w ≠ 0`` (``|c| = |d|``, ``c ⊥ d``): ``Z`` is nilpotent there.

* ``exp``: the spinor ``A = exp(−i w·σ/2) = cos(θ/2) I − i (sin(θ/2)/θ) w·σ ∈ SL(2, C)``
  and ``Λ^μ_ν = ½ tr(σ_μ A σ_ν A†)`` (``σ₀ = I``), written through the products
  ``p_a p̄_b`` of ``A = Σ p_a σ_a`` like the quaternion form of a rotation matrix, so entries
  that vanish with ``w`` carry no cancellation.  Both coefficients are entire functions
  of ``θ²``; they are summed from their Taylor series when ``|θ²| < 1``, so null and
  near-null generators keep full accuracy (an eigen-projector form divides by differences of
  eigenvalues and fails there).
* ``ad_ξ = hat_C(w)``; ``dexp = J(w) = I + B K + C K²``, ``K = hat_C(w)``,
  ``B = (1 − cos θ)/θ² = 2 (sin(θ/2)/θ)²``, ``C = (θ − sin θ)/θ³``;
  ``dexp⁻¹ = I − ½K + D K²``, ``D = (1 − (θ/2) cot(θ/2))/θ²``: the SO(3) left Jacobian,
  complexified.  All three coefficients are even functions of ``θ`` evaluated by series in
  ``θ²`` when ``|θ²| < 1``.  ``𝓔(Δt, Y) = Δt·dexp(ΔtY)`` (paper §V).
* ``Ad_Λ``: with ``u = Λ e₀`` and ``v_k = Λ e_k``,
  ``(M_r)_{ik} = Λ₀₀ Λ_{ik} − Λ_{i0} Λ_{0k}`` and ``M_i[:, k] = u⃗ × v⃗_k`` (spatial parts).
* ``log``: the Gram matrix ``P_ab = conj(p_a) p_b`` of the spinor ``A = Σ p_a σ_a`` is
  *linear* in ``Λ`` (the analogue of the quaternion-from-matrix formulas); its row with the
  largest diagonal gives ``p`` up to a phase, which ``det A = p₀² − p⃗·p⃗ = 1`` fixes up to
  sign, and the sign is chosen with ``Re p₀ ≥ 0`` (principal branch).  With ``q⃗ = i p⃗``,
  ``s² = q⃗·q⃗ = sin²(θ/2)``, ``w = 2 (φ/s) q⃗`` where ``φ = θ/2``: ``φ/s = asin(s)/s`` by
  its series in ``s²`` for ``|s²| < 0.04``, ``−i log(√(1 − s²) + is)/s`` for
  ``|s²| ≤ 1/2`` and ``−i log(p₀ + is)/s`` beyond, choosing the root ``s`` with
  ``|p₀ + is| ≥ 1``.

Domain of the logarithm
-----------------------
``log ∘ exp`` is the identity exactly when the rotation-like angle ``|Re θ|`` (principal
square root of ``w·w``; :func:`rotation_angle_np`) is below π; boost rapidities are
unrestricted.  Since ``|θ|² = |w·w| ≤ |w|² = |c|² + |d|²``, the Euclidean norm ``|ξ|``
bounds ``|Re θ|``: :meth:`SO13.log_domain_norm` is ``|ξ|`` and
:attr:`SO13.injectivity_radius` is π: a sufficient condition which, unlike ``|Re θ|``,
also measures boosts (and so the size of ``Λ``) and null generators (``θ = 0`` at any size).  The
representation ``Λ`` of a boost of rapidity ``ζ`` has entries ``~ cosh ζ``, so rounding of
``Λ`` alone limits ``Ad`` and ``log`` to an absolute accuracy ``~ ε cosh ζ`` in some
directions; ``cos``/``sin`` of the complex angle overflow beyond ``ζ ≈ 700``.

Kernels
-------
Shared arithmetic lives in ``register_jitable`` helpers so the numpy reference path and the
numba kernels evaluate the same formulas.  The per-point kernels ``so13_*_point`` are
allocation-free ``@njit(cache=True)`` functions; the batch loops ``_*_batch`` map them over
flattened points and are listed in :attr:`SO13._kernels` (all operations: hat, vee,
compose, inverse, act, exp, log, Ad, ad, bracket, dexp, dexp_inv, E).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ._batch import kernel_table
from .base import SymmetryGroup

__all__ = [
    "SO13",
    "ETA",
    "so13_Ad_point",
    "so13_E_point",
    "so13_act_point",
    "so13_ad_point",
    "so13_bracket_point",
    "so13_compose_point",
    "so13_dexp_coeffs",
    "so13_dexp_inv_coeff",
    "so13_dexp_inv_point",
    "so13_dexp_point",
    "so13_exp_coeffs",
    "so13_exp_point",
    "so13_hat_point",
    "so13_inverse_point",
    "so13_log_point",
    "so13_spinor_log",
    "so13_vee_point",
]

#: The Minkowski metric diag(−1, 1, 1, 1).
ETA = np.array([-1.0, 1.0, 1.0, 1.0])

#: Below this modulus of θ² the coefficient functions are summed from their Taylor series.
SERIES_RADIUS = 1.0
#: Below this modulus of s² = sin²(θ/2) the logarithm uses the series of asin(s)/s.
LOG_SERIES_RADIUS = 0.04
#: Up to this modulus of s² the logarithm takes cos(θ/2) = √(1 − s²) rather than the
#: measured spinor component (better conditioned away from θ = π).
LOG_ROOT_RADIUS = 0.5


def _taylor(coeffs) -> tuple[float, ...]:
    """Coefficients (lowest power first, exact fractions) → floats, highest power first."""
    return tuple(float(c) for c in reversed(coeffs))


def _fact(n: int) -> int:
    return math.factorial(n)


def _bernoulli_even(nmax: int) -> list[Fraction]:
    """``B₂, B₄, …, B₂ₙₘₐₓ`` (exact) from the standard recursion."""
    B = [Fraction(1)]
    for m in range(1, 2 * nmax + 1):
        B.append(-sum(Fraction(math.comb(m + 1, k)) * B[k] for k in range(m)) / (m + 1))
    return [B[2 * n] for n in range(1, nmax + 1)]


# Taylor coefficients in x = θ², highest power first (Horner).
#: cos(θ/2) = Σ (−1)ᵏ xᵏ / (4ᵏ (2k)!)
TAYLOR_COS_HALF = _taylor([Fraction((-1) ** k, 4**k * _fact(2 * k)) for k in range(11)])
#: sin(θ/2)/θ = Σ (−1)ᵏ xᵏ / (2·4ᵏ (2k+1)!)
TAYLOR_SINC_HALF = _taylor([Fraction((-1) ** k, 2 * 4**k * _fact(2 * k + 1)) for k in range(11)])
#: (1 − cos θ)/θ² = Σ (−1)ᵏ xᵏ/(2k+2)!
TAYLOR_B = _taylor([Fraction((-1) ** k, _fact(2 * k + 2)) for k in range(11)])
#: (θ − sin θ)/θ³ = Σ (−1)ᵏ xᵏ/(2k+3)!
TAYLOR_C = _taylor([Fraction((-1) ** k, _fact(2 * k + 3)) for k in range(11)])
#: (1 − (θ/2) cot(θ/2))/θ² = Σₙ |B₂ₙ| xⁿ⁻¹/(2n)!  (radius of convergence |θ| = 2π)
TAYLOR_D = _taylor([abs(b) / _fact(2 * n) for n, b in enumerate(_bernoulli_even(15), start=1)])
#: asin(s)/s = Σ (2k)! s²ᵏ / (4ᵏ (k!)² (2k+1))
TAYLOR_ASINC = _taylor(
    [Fraction(_fact(2 * k), 4**k * _fact(k) ** 2 * (2 * k + 1)) for k in range(14)]
)


# ---------------------------------------------------------------------- shared arithmetic
@register_jitable
def horner(t, coeffs):
    """Evaluate the polynomial with coefficients ``coeffs`` (highest power first) at ``t``."""
    acc = 0.0 * t
    for c in coeffs:
        acc = acc * t + c
    return acc


@register_jitable
def _theta2(c1, c2, c3, d1, d2, d3):
    """``θ² = w·w`` for ``w = d + ic`` (complex, bilinear)."""
    return (d1 * d1 + d2 * d2 + d3 * d3 - c1 * c1 - c2 * c2 - c3 * c3) + 2j * (
        c1 * d1 + c2 * d2 + c3 * d3
    )


@register_jitable
def _exp_coeffs_direct(x):
    th = np.sqrt(x)
    h = 0.5 * th
    return np.cos(h), np.sin(h) / th


@register_jitable
def _exp_coeffs_series(x):
    return horner(x, TAYLOR_COS_HALF), horner(x, TAYLOR_SINC_HALF)


@register_jitable
def _dexp_coeffs_direct(x):
    th = np.sqrt(x)
    sh = np.sin(0.5 * th) / th
    return 2.0 * sh * sh, (th - np.sin(th)) / (th * x)


@register_jitable
def _dexp_inv_direct(x):
    h = 0.5 * np.sqrt(x)
    return (1.0 - h * np.cos(h) / np.sin(h)) / x


@register_jitable
def _phi_entries(p0, p1, p2, p3, r0, r1, r2, r3):
    """Row-major entries of the real ``4 × 4`` matrix of ``X ↦ ½(A X B† + B X A†)``.

    ``A = Σ p_a σ_a`` and ``B = Σ r_a σ_a`` (``σ₀ = I``) act on ``X = x^μ σ_μ``; for ``B = A``
    this is the Lorentz matrix ``Λ^μ_ν = ½ tr(σ_μ A σ_ν A†)`` of the spinor ``A``.  Written
    through ``S_ab = ½(p_a r̄_b + r_a p̄_b)`` (the analogue of the quaternion form of a
    rotation matrix), the entries that vanish with ``p⃗`` carry no cancellation.
    """
    s00 = (p0 * r0.conjugate()).real
    s11 = (p1 * r1.conjugate()).real
    s22 = (p2 * r2.conjugate()).real
    s33 = (p3 * r3.conjugate()).real
    s01 = p0 * r1.conjugate() + r0 * p1.conjugate()
    s02 = p0 * r2.conjugate() + r0 * p2.conjugate()
    s03 = p0 * r3.conjugate() + r0 * p3.conjugate()
    s12 = p1 * r2.conjugate() + r1 * p2.conjugate()
    s13 = p1 * r3.conjugate() + r1 * p3.conjugate()
    s23 = p2 * r3.conjugate() + r2 * p3.conjugate()
    return (
        s00 + s11 + s22 + s33, s01.real + s23.imag, s02.real - s13.imag, s03.real + s12.imag,
        s01.real - s23.imag, s00 + s11 - s22 - s33, s12.real - s03.imag, s13.real + s02.imag,
        s02.real + s13.imag, s12.real + s03.imag, s00 - s11 + s22 - s33, s23.real - s01.imag,
        s03.real - s12.imag, s13.real - s02.imag, s23.real + s01.imag, s00 - s11 - s22 + s33,
    )


@register_jitable
def _lorentz_entries(p0, p1, p2, p3):
    """Row-major entries of ``Λ(A)`` for the spinor ``A = p₀ I + p⃗·σ``."""
    return _phi_entries(p0, p1, p2, p3, p0, p1, p2, p3)


@register_jitable
def _exp_spinor(c1, c2, c3, d1, d2, d3, co, sh):
    """``p`` of ``A = exp(−i w·σ/2)`` from ``co = cos(θ/2)``, ``sh = sin(θ/2)/θ``."""
    k = -1j * sh
    return co, k * (d1 + 1j * c1), k * (d2 + 1j * c2), k * (d3 + 1j * c3)


@register_jitable
def _poly3_entries(w1, w2, w3, x, al, be):
    """Row-major entries of ``I + al K + be K²``, ``K = hat(w)`` complex, ``x = w·w``.

    Uses ``K² = w wᵀ − x I``.
    """
    return (
        1.0 + be * (w1 * w1 - x), be * w1 * w2 - al * w3, be * w1 * w3 + al * w2,
        be * w2 * w1 + al * w3, 1.0 + be * (w2 * w2 - x), be * w2 * w3 - al * w1,
        be * w3 * w1 - al * w2, be * w3 * w2 + al * w1, 1.0 + be * (w3 * w3 - x),
    )


@register_jitable
def _Ad_entries(l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23, l30, l31, l32, l33):
    """Row-major entries of ``M_r`` and ``M_i`` (``Ad_Λ = [[M_r, M_i], [−M_i, M_r]]``)."""
    u1, u2, u3 = l10, l20, l30
    mr = (
        l00 * l11 - l10 * l01, l00 * l12 - l10 * l02, l00 * l13 - l10 * l03,
        l00 * l21 - l20 * l01, l00 * l22 - l20 * l02, l00 * l23 - l20 * l03,
        l00 * l31 - l30 * l01, l00 * l32 - l30 * l02, l00 * l33 - l30 * l03,
    )
    # column k: u⃗ × v⃗_k with v⃗_k = (l1k, l2k, l3k)
    mi = (
        u2 * l31 - u3 * l21, u2 * l32 - u3 * l22, u2 * l33 - u3 * l23,
        u3 * l11 - u1 * l31, u3 * l12 - u1 * l32, u3 * l13 - u1 * l33,
        u1 * l21 - u2 * l11, u1 * l22 - u2 * l12, u1 * l23 - u2 * l13,
    )
    return mr, mi


@register_jitable
def _gram_row(case, l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23, l30, l31, l32,
              l33):
    """Row ``case`` of ``4 P``, ``P_ab = conj(p_a) p_b`` (linear in ``Λ``)."""
    if case == 0:
        return (l00 + l11 + l22 + l33 + 0j, (l01 + l10) + 1j * (l23 - l32),
                (l02 + l20) + 1j * (l31 - l13), (l03 + l30) + 1j * (l12 - l21))
    if case == 1:
        return ((l01 + l10) - 1j * (l23 - l32), l00 + l11 - l22 - l33 + 0j,
                (l12 + l21) + 1j * (l30 - l03), (l13 + l31) + 1j * (l02 - l20))
    if case == 2:
        return ((l02 + l20) - 1j * (l31 - l13), (l12 + l21) - 1j * (l30 - l03),
                l00 - l11 + l22 - l33 + 0j, (l23 + l32) + 1j * (l10 - l01))
    return ((l03 + l30) - 1j * (l12 - l21), (l13 + l31) - 1j * (l02 - l20),
            (l23 + l32) - 1j * (l10 - l01), l00 - l11 - l22 + l33 + 0j)


@register_jitable
def _spinor_from_row(r0, r1, r2, r3, rdiag):
    """Spinor ``p`` (up to sign) from a row ``4 P_a·`` of the Gram matrix, ``rdiag = 4 P_aa``.

    The row fixes ``p`` up to a phase; ``p₀² − p⃗·p⃗ = 1`` fixes the phase up to sign.  The
    moduli are taken from the row (linear in ``Λ``), so only the phase involves the
    cancellation-prone bilinear form.
    """
    k = 0.5 / np.sqrt(rdiag)
    t0 = k * r0
    t1 = k * r1
    t2 = k * r2
    t3 = k * r3
    nu = t0 * t0 - t1 * t1 - t2 * t2 - t3 * t3
    an = np.abs(nu)
    ph = np.sqrt(nu.conjugate() / (an + (an == 0.0)))
    return t0 * ph, t1 * ph, t2 * ph, t3 * ph


@register_jitable
def _asinc_direct(q0, s):
    """``φ/s`` with ``φ = −i log(q₀ + i s)``; the caller picks the root ``s``."""
    return -1j * np.log(q0 + 1j * s) / s


# ---------------------------------------------------------------------- numba point kernels
@njit(cache=True)
def so13_exp_coeffs(x):
    """``(cos(θ/2), sin(θ/2)/θ)`` as functions of the complex ``x = θ²``."""
    if abs(x) < SERIES_RADIUS:
        return _exp_coeffs_series(x)
    return _exp_coeffs_direct(x)


@njit(cache=True)
def so13_dexp_coeffs(x):
    """``(B, C) = ((1 − cos θ)/θ², (θ − sin θ)/θ³)`` as functions of the complex ``x = θ²``."""
    if abs(x) < SERIES_RADIUS:
        return horner(x, TAYLOR_B), horner(x, TAYLOR_C)
    return _dexp_coeffs_direct(x)


@njit(cache=True)
def so13_dexp_inv_coeff(x):
    """``D = (1 − (θ/2) cot(θ/2))/θ²`` as a function of the complex ``x = θ²``."""
    if abs(x) < SERIES_RADIUS:
        return horner(x, TAYLOR_D)
    return _dexp_inv_direct(x)


@njit(cache=True)
def so13_hat_point(xi, out):
    """``out`` (4, 4) ← ``Z = [[0, cᵀ], [c, d̂]]`` for ``xi = (c; d)`` (6,)."""
    c1, c2, c3, d1, d2, d3 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    out[0, 0] = 0.0
    out[0, 1] = c1
    out[0, 2] = c2
    out[0, 3] = c3
    out[1, 0] = c1
    out[1, 1] = 0.0
    out[1, 2] = -d3
    out[1, 3] = d2
    out[2, 0] = c2
    out[2, 1] = d3
    out[2, 2] = 0.0
    out[2, 3] = -d1
    out[3, 0] = c3
    out[3, 1] = -d2
    out[3, 2] = d1
    out[3, 3] = 0.0


@njit(cache=True)
def so13_vee_point(A, out):
    """``out`` (6,) ← least-squares components of ``A`` (4, 4): symmetric boost part and
    antisymmetric spatial part."""
    out[0] = 0.5 * (A[0, 1] + A[1, 0])
    out[1] = 0.5 * (A[0, 2] + A[2, 0])
    out[2] = 0.5 * (A[0, 3] + A[3, 0])
    out[3] = 0.5 * (A[3, 2] - A[2, 3])
    out[4] = 0.5 * (A[1, 3] - A[3, 1])
    out[5] = 0.5 * (A[2, 1] - A[1, 2])


@njit(cache=True)
def so13_compose_point(g, h, out):
    """``out`` (4, 4) ← ``g h``; ``out`` must not alias the inputs."""
    for i in range(4):
        for j in range(4):
            out[i, j] = g[i, 0] * h[0, j] + g[i, 1] * h[1, j] + g[i, 2] * h[2, j] + g[i, 3] * h[3, j]


@njit(cache=True)
def so13_inverse_point(g, out):
    """``out`` (4, 4) ← ``Λ⁻¹ = η Λᵀ η``; ``out`` must not alias ``g``."""
    for i in range(4):
        for j in range(4):
            out[i, j] = ETA[i] * ETA[j] * g[j, i]


@njit(cache=True)
def so13_act_point(g, x, out):
    """``out`` (4,) ← ``Λ x``."""
    for i in range(4):
        out[i] = g[i, 0] * x[0] + g[i, 1] * x[1] + g[i, 2] * x[2] + g[i, 3] * x[3]


@njit(cache=True)
def _fill4(e, out):
    for i in range(4):
        for j in range(4):
            out[i, j] = e[4 * i + j]


@njit(cache=True)
def _fill_complex_op(e_r, e_i, s, out):
    """``out`` (6, 6) ← ``s [[M_r, M_i], [−M_i, M_r]]`` from row-major 3 × 3 entries."""
    for i in range(3):
        for j in range(3):
            r = s * e_r[3 * i + j]
            m = s * e_i[3 * i + j]
            out[i, j] = r
            out[i, j + 3] = m
            out[i + 3, j] = -m
            out[i + 3, j + 3] = r


@njit(cache=True)
def _fill_complex_poly(e, s, out):
    """``out`` (6, 6) ← real form of ``s M`` from the 9 complex entries of ``M``."""
    for i in range(3):
        for j in range(3):
            z = e[3 * i + j]
            r = s * z.real
            m = s * z.imag
            out[i, j] = r
            out[i, j + 3] = m
            out[i + 3, j] = -m
            out[i + 3, j + 3] = r


@njit(cache=True)
def so13_exp_point(xi, out):
    """``out`` (4, 4) ← ``exp(Z)`` by the spinor form, for ``xi = (c; d)`` (6,)."""
    c1, c2, c3, d1, d2, d3 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    co, sh = so13_exp_coeffs(_theta2(c1, c2, c3, d1, d2, d3))
    p0, p1, p2, p3 = _exp_spinor(c1, c2, c3, d1, d2, d3, co, sh)
    _fill4(_lorentz_entries(p0, p1, p2, p3), out)


@njit(cache=True)
def so13_spinor_log(p0, p1, p2, p3):
    """Principal ``w = d + ic`` of the spinor ``A = p₀ I + p⃗·σ`` (any overall sign).

    Returns the three complex components of ``w``.
    """
    if p0.real < 0.0 or (p0.real == 0.0 and p0.imag < 0.0):
        p0, p1, p2, p3 = -p0, -p1, -p2, -p3
    q1, q2, q3 = 1j * p1, 1j * p2, 1j * p3
    s2 = q1 * q1 + q2 * q2 + q3 * q3
    if abs(s2) < LOG_SERIES_RADIUS:
        f = horner(s2, TAYLOR_ASINC)
    else:
        q0 = np.sqrt(1.0 - s2) if abs(s2) <= LOG_ROOT_RADIUS else p0
        s = np.sqrt(s2)
        if abs(q0 + 1j * s) < 1.0:
            s = -s
        f = _asinc_direct(q0, s)
    f2 = 2.0 * f
    return f2 * q1, f2 * q2, f2 * q3


@njit(cache=True)
def so13_log_point(g, out):
    """``out`` (6,) ← principal logarithm ``(c; d)`` of ``Λ = g`` (4, 4)."""
    l00, l01, l02, l03 = g[0, 0], g[0, 1], g[0, 2], g[0, 3]
    l10, l11, l12, l13 = g[1, 0], g[1, 1], g[1, 2], g[1, 3]
    l20, l21, l22, l23 = g[2, 0], g[2, 1], g[2, 2], g[2, 3]
    l30, l31, l32, l33 = g[3, 0], g[3, 1], g[3, 2], g[3, 3]
    diag0 = l00 + l11 + l22 + l33
    diag1 = l00 + l11 - l22 - l33
    diag2 = l00 - l11 + l22 - l33
    diag3 = l00 - l11 - l22 + l33
    case = 0
    best = diag0
    if diag1 > best:
        case = 1
        best = diag1
    if diag2 > best:
        case = 2
        best = diag2
    if diag3 > best:
        case = 3
        best = diag3
    r0, r1, r2, r3 = _gram_row(case, l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23,
                               l30, l31, l32, l33)
    p0, p1, p2, p3 = _spinor_from_row(r0, r1, r2, r3, best)
    w1, w2, w3 = so13_spinor_log(p0, p1, p2, p3)
    out[0] = w1.imag
    out[1] = w2.imag
    out[2] = w3.imag
    out[3] = w1.real
    out[4] = w2.real
    out[5] = w3.real


@njit(cache=True)
def so13_Ad_point(g, out):
    """``out`` (6, 6) ← ``Ad_Λ`` for ``Λ = g`` (4, 4)."""
    mr, mi = _Ad_entries(g[0, 0], g[0, 1], g[0, 2], g[0, 3], g[1, 0], g[1, 1], g[1, 2], g[1, 3],
                         g[2, 0], g[2, 1], g[2, 2], g[2, 3], g[3, 0], g[3, 1], g[3, 2], g[3, 3])
    _fill_complex_op(mr, mi, 1.0, out)


@njit(cache=True)
def so13_ad_point(xi, out):
    """``out`` (6, 6) ← ``ad_ξ = [[d̂, ĉ], [−ĉ, d̂]]``."""
    c1, c2, c3, d1, d2, d3 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    hr = (0.0, -d3, d2, d3, 0.0, -d1, -d2, d1, 0.0)
    hi = (0.0, -c3, c2, c3, 0.0, -c1, -c2, c1, 0.0)
    _fill_complex_op(hr, hi, 1.0, out)


@njit(cache=True)
def so13_bracket_point(u, v, out):
    """``out`` (6,) ← ``[u, v] = (d_u × c_v + c_u × d_v ; d_u × d_v − c_u × c_v)``."""
    a1, a2, a3, b1, b2, b3 = u[0], u[1], u[2], u[3], u[4], u[5]
    e1, e2, e3, f1, f2, f3 = v[0], v[1], v[2], v[3], v[4], v[5]
    out[0] = (b2 * e3 - b3 * e2) + (a2 * f3 - a3 * f2)
    out[1] = (b3 * e1 - b1 * e3) + (a3 * f1 - a1 * f3)
    out[2] = (b1 * e2 - b2 * e1) + (a1 * f2 - a2 * f1)
    out[3] = (b2 * f3 - b3 * f2) - (a2 * e3 - a3 * e2)
    out[4] = (b3 * f1 - b1 * f3) - (a3 * e1 - a1 * e3)
    out[5] = (b1 * f2 - b2 * f1) - (a1 * e2 - a2 * e1)


@njit(cache=True)
def _dexp_scaled(xi, dt, out):
    c1, c2, c3 = dt * xi[0], dt * xi[1], dt * xi[2]
    d1, d2, d3 = dt * xi[3], dt * xi[4], dt * xi[5]
    x = _theta2(c1, c2, c3, d1, d2, d3)
    b, c = so13_dexp_coeffs(x)
    e = _poly3_entries(d1 + 1j * c1, d2 + 1j * c2, d3 + 1j * c3, x, b, c)
    _fill_complex_poly(e, dt, out)


@njit(cache=True)
def so13_dexp_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ)``, the real form of ``J(w) = I + B K + C K²``."""
    _dexp_scaled(xi, 1.0, out)


@njit(cache=True)
def so13_dexp_inv_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ)⁻¹``, the real form of ``I − ½K + D K²``."""
    c1, c2, c3, d1, d2, d3 = xi[0], xi[1], xi[2], xi[3], xi[4], xi[5]
    x = _theta2(c1, c2, c3, d1, d2, d3)
    e = _poly3_entries(d1 + 1j * c1, d2 + 1j * c2, d3 + 1j * c3, x, -0.5, so13_dexp_inv_coeff(x))
    _fill_complex_poly(e, 1.0, out)


@njit(cache=True)
def so13_E_point(dt, Y, out):
    """``out`` (6, 6) ← ``𝓔(Δt, Y) = Δt·dexp(ΔtY)`` for scalar ``dt``."""
    _dexp_scaled(Y, dt, out)


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        so13_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        so13_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        so13_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        so13_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        so13_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        so13_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        so13_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        so13_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        so13_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(u, v, out):
    for p in range(u.shape[0]):
        so13_bracket_point(u[p], v[p], out[p])


@njit(cache=True)
def _dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        so13_dexp_point(xi[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        so13_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _E_batch(dt, Y, out):
    for p in range(Y.shape[0]):
        so13_E_point(dt[p], Y[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def _split(xi: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(xi[..., k] for k in range(6))


def _unpack4(g: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(g[..., i, j] for i in range(4) for j in range(4))


def _stack(entries, shape: tuple[int, int]) -> np.ndarray:
    e = np.broadcast_arrays(*entries)
    return np.stack(e, axis=-1).reshape(*e[0].shape, *shape)


def _where(small: np.ndarray, x: np.ndarray, series, direct):
    """Evaluate ``series`` where ``small`` and ``direct`` (on a safe argument) elsewhere."""
    safe = np.where(small, 1.0 + 0j, x)
    s = series(x)
    d = direct(safe)
    if isinstance(s, tuple):
        return tuple(np.where(small, a, b) for a, b in zip(s, d, strict=True))
    return np.where(small, s, d)


def exp_coeffs_np(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`so13_exp_coeffs` for complex ``x = θ²`` of any shape."""
    return _where(np.abs(x) < SERIES_RADIUS, x, _exp_coeffs_series, _exp_coeffs_direct)


def dexp_coeffs_np(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`so13_dexp_coeffs`."""
    return _where(np.abs(x) < SERIES_RADIUS, x, lambda t: (horner(t, TAYLOR_B), horner(t, TAYLOR_C)),
                  _dexp_coeffs_direct)


def dexp_inv_coeff_np(x: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so13_dexp_inv_coeff`."""
    return _where(np.abs(x) < SERIES_RADIUS, x, lambda t: horner(t, TAYLOR_D), _dexp_inv_direct)


def complex_op_np(mr, mi, s=1.0) -> np.ndarray:
    """``s [[M_r, M_i], [−M_i, M_r]]`` ``[..., 6, 6]`` from row-major ``3 × 3`` entry tuples."""
    Mr = _stack(mr, (3, 3))
    Mi = _stack(mi, (3, 3))
    s = np.asarray(s, dtype=float)[..., None, None]
    top = np.concatenate([Mr, Mi], axis=-1)
    bottom = np.concatenate([-Mi, Mr], axis=-1)
    return s * np.concatenate([top, bottom], axis=-2)


def complex_poly_np(e, s=1.0) -> np.ndarray:
    """Real ``[..., 6, 6]`` form of ``s M`` from the 9 complex entries of ``M``."""
    return complex_op_np(tuple(z.real for z in e), tuple(z.imag for z in e), s)


def spinor_log_np(p0, p1, p2, p3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised :func:`so13_spinor_log`."""
    flip = (p0.real < 0.0) | ((p0.real == 0.0) & (p0.imag < 0.0))
    sg = np.where(flip, -1.0, 1.0)
    p0 = sg * p0
    q1, q2, q3 = 1j * sg * p1, 1j * sg * p2, 1j * sg * p3
    s2 = q1 * q1 + q2 * q2 + q3 * q3
    a2 = np.abs(s2)
    small = a2 < LOG_SERIES_RADIUS
    q0 = np.where(a2 <= LOG_ROOT_RADIUS, np.sqrt(1.0 - s2), p0)
    s = np.sqrt(np.where(small, 1.0 + 0j, s2))
    s = np.where(np.abs(q0 + 1j * s) < 1.0, -s, s)
    f = np.where(small, horner(s2, TAYLOR_ASINC), _asinc_direct(q0, s))
    f2 = 2.0 * f
    return f2 * q1, f2 * q2, f2 * q3


def log_np(g: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so13_log_point`: ``[..., 4, 4]`` → ``[..., 6]``."""
    lead = g.shape[:-2]
    L = _unpack4(g.reshape(-1, 4, 4))
    l00, l11, l22, l33 = L[0], L[5], L[10], L[15]
    diags = np.stack([l00 + l11 + l22 + l33, l00 + l11 - l22 - l33, l00 - l11 + l22 - l33,
                      l00 - l11 - l22 + l33])
    case = np.argmax(diags, axis=0)
    best = np.max(diags, axis=0)
    row = np.zeros((4, case.size), dtype=complex)
    for k in range(4):
        sel = case == k
        row[:, sel] = np.stack(_gram_row(k, *(e[sel] for e in L)))
    p = _spinor_from_row(row[0], row[1], row[2], row[3], best)
    w = np.stack(spinor_log_np(*p), axis=-1)
    return np.concatenate([w.imag, w.real], axis=-1).reshape(*lead, 6)


def exp_np(xi: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so13_exp_point`: ``[..., 6]`` → ``[..., 4, 4]``."""
    c1, c2, c3, d1, d2, d3 = _split(xi)
    co, sh = exp_coeffs_np(_theta2(c1, c2, c3, d1, d2, d3))
    return _stack(_lorentz_entries(*_exp_spinor(c1, c2, c3, d1, d2, d3, co, sh)), (4, 4))


def Ad_np(g: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so13_Ad_point`: ``[..., 4, 4]`` → ``[..., 6, 6]``."""
    return complex_op_np(*_Ad_entries(*_unpack4(g)))


def hat_np(xi: np.ndarray) -> np.ndarray:
    """``Z = [[0, cᵀ], [c, d̂]]`` for ``xi`` ``[..., 6]`` → ``[..., 4, 4]``."""
    c1, c2, c3, d1, d2, d3 = _split(xi)
    z = np.zeros_like(c1)
    return _stack((z, c1, c2, c3, c1, z, -d3, d2, c2, d3, z, -d1, c3, -d2, d1, z), (4, 4))


def vee_np(A: np.ndarray) -> np.ndarray:
    """Least-squares components ``[..., 6]`` of ``A`` ``[..., 4, 4]``."""
    return 0.5 * np.stack([A[..., 0, 1] + A[..., 1, 0], A[..., 0, 2] + A[..., 2, 0],
                           A[..., 0, 3] + A[..., 3, 0], A[..., 3, 2] - A[..., 2, 3],
                           A[..., 1, 3] - A[..., 3, 1], A[..., 2, 1] - A[..., 1, 2]], axis=-1)


def inverse_np(g: np.ndarray) -> np.ndarray:
    """``η Λᵀ η`` for ``g`` ``[..., 4, 4]``."""
    return ETA[:, None] * ETA[None, :] * np.swapaxes(g, -1, -2)


def ad_np(xi: np.ndarray) -> np.ndarray:
    """``ad_ξ`` ``[..., 6, 6]``."""
    c1, c2, c3, d1, d2, d3 = _split(xi)
    z = np.zeros_like(c1)
    return complex_op_np((z, -d3, d2, d3, z, -d1, -d2, d1, z), (z, -c3, c2, c3, z, -c1, -c2, c1, z))


def bracket_np(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``[u, v]`` of broadcast ``[..., 6]`` arrays."""
    cu, du, cv, dv = u[..., :3], u[..., 3:], v[..., :3], v[..., 3:]
    return np.concatenate([np.cross(du, cv) + np.cross(cu, dv), np.cross(du, dv) - np.cross(cu, cv)],
                          axis=-1)


def dexp_np(xi: np.ndarray, dt=1.0) -> np.ndarray:
    """``dt·dexp(dt ξ)`` ``[..., 6, 6]`` (vectorised :func:`so13_E_point`)."""
    dt = np.asarray(dt, dtype=float)
    c1, c2, c3, d1, d2, d3 = (dt * e for e in _split(xi))
    x = _theta2(c1, c2, c3, d1, d2, d3)
    b, c = dexp_coeffs_np(x)
    return complex_poly_np(_poly3_entries(d1 + 1j * c1, d2 + 1j * c2, d3 + 1j * c3, x, b, c), dt)


def dexp_inv_np(xi: np.ndarray) -> np.ndarray:
    """``dexp(ξ)⁻¹`` ``[..., 6, 6]``."""
    c1, c2, c3, d1, d2, d3 = _split(xi)
    x = _theta2(c1, c2, c3, d1, d2, d3)
    e = _poly3_entries(d1 + 1j * c1, d2 + 1j * c2, d3 + 1j * c3, x, -0.5, dexp_inv_coeff_np(x))
    return complex_poly_np(e)


def lorentz_defect(g: np.ndarray) -> np.ndarray:
    """``‖ΛᵀηΛ − η‖_F + |det Λ − 1| + max(0, −Λ₀₀)`` for ``g`` ``[..., 4, 4]``."""
    G = np.swapaxes(g, -1, -2) @ (ETA[:, None] * g)
    return (np.linalg.norm(G - np.diag(ETA), axis=(-2, -1)) + np.abs(np.linalg.det(g) - 1.0)
            + np.maximum(0.0, -g[..., 0, 0]))


def rotation_angle_np(xi: np.ndarray) -> np.ndarray:
    """Rotation-like angle ``Re θ ≥ 0``, ``θ = √(w·w)`` principal, for ``xi`` ``[..., 6]``."""
    return np.sqrt(_theta2(*_split(xi))).real


# ---------------------------------------------------------------------- the group
class SO13(SymmetryGroup):
    """The Lorentz group SO⁺(1,3) of the paper's relativistic Cosserat rod.

    Elements are ``4 × 4`` matrices ``Λ`` with ``ΛᵀηΛ = η``, ``η = diag(−1, 1, 1, 1)``,
    acting on R⁴ by ``x ↦ Λx``; algebra components are ``ξ = (c; d)`` ``[..., 6]`` (boost
    first) for ``Z = [[0, cᵀ], [c, d̂]]``.  All operations are closed-form through the
    isomorphism so(1,3) ≅ sl(2, C) (see the module docstring); the logarithm is principal
    for rotation-like angles ``|Re θ| < π``, in particular for ``|ξ| < π``
    (:meth:`log_domain_norm`).
    """

    name = "SO13"
    dim = 6
    matrix_size = 4
    affine = False
    injectivity_radius = np.pi
    _kernels = kernel_table(globals())
    _point_prefix = "so13"

    def basis(self) -> np.ndarray:
        """Generators ``(K₁, K₂, K₃, J₁, J₂, J₃)``, shape ``(6, 4, 4)``."""
        return hat_np(np.eye(6))

    def defect(self, g) -> np.ndarray:
        """Distance from SO⁺(1,3): ``‖ΛᵀηΛ − η‖_F + |det Λ − 1| + max(0, −Λ₀₀)``.

        The last two terms detect the improper and the non-orthochronous components.

        Parameters
        ----------
        g : array_like, shape ``[..., 4, 4]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        return lorentz_defect(self._element(g))

    def log_domain_norm(self, xi) -> np.ndarray:
        """Euclidean norm ``|ξ| = (|c|² + |d|²)^½``, shape ``[...]``.

        It bounds the rotation-like angle ``|Re θ|`` (``θ² = w·w``, ``w = d + ic``) that
        decides the principal branch, so ``log ∘ exp`` is the identity below
        :attr:`injectivity_radius` (π); see the module docstring.
        """
        return np.linalg.norm(self._algebra(xi), axis=-1)

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        return hat_np(xi)

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return vee_np(A)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        return inverse_np(g)

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", g, x)

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        return exp_np(xi)

    def _log(self, g: np.ndarray) -> np.ndarray:
        return log_np(g)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        return Ad_np(g)

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        return ad_np(xi)

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        return bracket_np(xi, eta)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return dexp_np(xi)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        return dexp_inv_np(xi)

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        return dexp_np(Y, dt)
