"""Scalar SO(3)/SE(3) kernels of the structure-of-arrays SE(3) rod loops.

The loops live in :mod:`cartan.schemes._lattice_compiled_soa` (the dispatch in
:mod:`cartan.schemes._lattice_compiled`); here are the chunking of the grid, the SO(3)/SE(3)
coefficients and the scalar algebra those loops inline.

* **SE(3) in scalar code.**  For elements on the group the kernels work on the matrix
  entries directly: the logarithm from the quaternion of the rotation, ``dexp⁻¹(ξ)ᵀQ`` by
  cross products (with Barfoot–Furgale's ``Q`` block), the head term of an edge as ``Ad_Gᵀ``
  of its tail term (``dexp⁻¹(−ξ)ᵀ = Ad_Gᵀ dexp⁻¹(ξ)ᵀ``), and the free-flow pieces of
  ``lie-verlet`` about one body axis as plane rotations.  The SO(3)/SE(3) coefficients come
  from the groups' Taylor series (valid below θ = 0.1; four terms below θ² = 10⁻⁴), and
  ``atan(x)/x`` in the logarithm from its series below x = 1/20; the closed forms beyond.
* **IEEE division** (``error_model="numpy"``: inf/nan like the reference path, no
  zero-divisor test) in every kernel; small helpers are inlined in numba's IR
  (``inline="always"``) and take and return scalars where they sit in loops meant to be
  fast.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..groups.se3 import (
    TAYLOR_D,
    TAYLOR_E,
    _dexp_coeffs_direct,
    _exp_coeffs3_direct,
    _V_apply,
)
from ..groups.so3 import (
    SMALL_THETA2,
    TAYLOR_A,
    TAYLOR_B,
    TAYLOR_C,
    TAYLOR_CINV,
    _cinv_direct,
    _exp_coeffs_direct,
    _log_factor_direct,
    cross3,
    horner,
    quat_of_matrix,
)

#: kinds of lie-verlet free-flow pieces: generic (no closed form: the generated loops run them),
#: the SE(3) translations {0, 1, 2}, a rotation about one body axis (SE(3) components 3–5)
KIND_GENERIC = 0
KIND_SE3_TRANSLATION = 1
KIND_ROTATION = 2

#: every kernel: cached, and IEEE division (inf/nan like numpy, no zero-divisor test, which
#: would also keep LLVM from vectorising the loops); helpers are inlined in numba's IR, so
#: that large ones do not leave calls inside loops that LLVM would otherwise vectorise
_jit = njit(cache=True, error_model="numpy")
_inline = njit(inline="always", error_model="numpy")

#: nodes or edges per chunk of the compiled passes (each chunk is one unit of work of a
#: thread, with its own work arrays and partial sums)
CHUNK = 1024

#: below this θ², four Taylor terms of the SO(3)/SE(3) coefficients are exact to < 1e-21
SERIES4_THETA2 = 1e-4
_A4, _B4, _C4, _D4, _E4, _CINV4 = (c[-4:] for c in (TAYLOR_A, TAYLOR_B, TAYLOR_C, TAYLOR_D, TAYLOR_E, TAYLOR_CINV))
#: atan(x)/x = Σ (−1)ᵏ x²ᵏ/(2k+1), highest power first: below x² = 1/400 nine terms reach 1e-19
ATAN_SERIES = (1.0 / 17.0, -1.0 / 15.0, 1.0 / 13.0, -1.0 / 11.0, 1.0 / 9.0, -1.0 / 7.0, 1.0 / 5.0, -1.0 / 3.0, 1.0)
ATAN_SERIES_X2 = 1.0 / 400.0
#: below x² = 1e-5 the first five terms suffice (truncation < 1e-21)
ATAN_SERIES5 = ATAN_SERIES[-5:]
ATAN_SERIES5_X2 = 1e-5


# ---------------------------------------------------------------------------- chunks
@_inline
def _chunk(c, n):
    """The indices ``lo ≤ i < hi`` of chunk ``c`` of ``n`` nodes or edges; ``lo ≥ 0`` is stated
    (``max``), so that LLVM drops the negative-index test of numba's indexing from the loops
    over the chunk and vectorises them."""
    lo = max(c * CHUNK, 0)
    return lo, min(lo + CHUNK, n)


@_inline
def so3_log_series(m00, m01, m02, m10, m11, m12, m20, m21, m22):
    """The rotation vector of ``M`` from its trace quaternion ``(1 + tr M, vee(M − Mᵀ))`` by the
    arctangent series (for the vectorised edge loops, branch-free): ``(w0, w1, w2, tr, x2, t2,
    cinv)`` with ``x2`` the squared tangent ratio, ``t2 = |w|²`` and ``cinv`` the ``J⁻¹``
    coefficient.  Valid (to round-off) for ``x2 < ATAN_SERIES_X2``, ``t2 < SMALL_THETA2`` and
    a trace dominating the diagonal; the callers flag the other edges for the closed forms."""
    tr = m00 + m11 + m22
    qw = 1.0 + tr
    qx, qy, qz = m21 - m12, m02 - m20, m10 - m01
    x2 = (qx * qx + qy * qy + qz * qz) / (qw * qw)
    f = (2.0 / qw) * horner(x2, ATAN_SERIES)
    w0, w1, w2 = f * qx, f * qy, f * qz
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    return w0, w1, w2, tr, x2, t2, horner(t2, TAYLOR_CINV)


@_jit
def _sum_parts(PART, nch):
    """The chunks' partial sums added in chunk order: ``(−Σ damping power, Σ external power,
    ΣS, Σw S²/m)``."""
    a = 0.0
    b = 0.0
    s = 0.0
    k = 0.0
    for c in range(nch):
        a += PART[c, 0]
        b += PART[c, 1]
        s += PART[c, 2]
        k += PART[c, 3]
    return 0.0 - a, b, s, k


# ---------------------------------------------------------------------------- SO(3)/SE(3) coefficients
@_inline
def _cinv(t2):
    """``so3_dexp_inv_coeff``: ``c = (1 − (θ/2)cot(θ/2))/θ²``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _CINV4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_CINV)
    return _cinv_direct(t2)


@_inline
def _rot_coeffs(t2):
    """``so3_exp_coeffs``: ``(A, B) = (sin θ/θ, (1 − cos θ)/θ²)``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _A4), horner(t2, _B4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B)
    return _exp_coeffs_direct(t2)


@_inline
def _exp3_coeffs(t2):
    """``se3_exp_coeffs``: ``(A, B, C)``, ``C = (θ − sin θ)/θ³``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _A4), horner(t2, _B4), horner(t2, _C4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)
    return _exp_coeffs3_direct(t2)


@_inline
def _q_coeffs(t2):
    """The coefficients ``(C, D, E)`` of Barfoot–Furgale's block (``se3_dexp_coeffs`` without B)."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _C4), horner(t2, _D4), horner(t2, _E4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_C), horner(t2, TAYLOR_D), horner(t2, TAYLOR_E)
    _, c, d, e = _dexp_coeffs_direct(t2)
    return c, d, e


# ---------------------------------------------------------------------------- SO(3)/SE(3) scalar algebra
@_inline
def _q_block(r0, r1, r2, p0, p1, p2, c, d, e, v0, v1, v2):
    """``Q v`` for Barfoot–Furgale's block ``Q = ½P + C(KP + PK + KPK) + D(K²P + PK² − 3KPK)
    + E(KPK² + K²PK)`` (``P = r̂``, ``K = p̂``), grouped as
    ``½u₁ + Cu₂ + Du₃ + K(y + Kz)`` with ``u_k = P Kᵏ⁻¹v``, ``y = Cu₁ + (C − 3D)u₂ + Eu₃``,
    ``z = Du₁ + Eu₂``: seven cross products."""
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


@_inline
def _jinv_T(p0, p1, p2, cinv, v0, v1, v2):
    """``J⁻¹(p)ᵀ v = v + ½ p × v + c p × (p × v)`` (= ``dexp⁻¹(p)ᵀ v`` on SO(3))."""
    u = cross3(p0, p1, p2, v0, v1, v2)
    z = cross3(p0, p1, p2, u[0], u[1], u[2])
    return v0 + 0.5 * u[0] + cinv * z[0], v1 + 0.5 * u[1] + cinv * z[1], v2 + 0.5 * u[2] + cinv * z[2]


@_inline
def _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, d, e, F0, F1, F2, M0, M1, M2):
    """``dexp⁻¹(ξ)ᵀ (F; M)`` for ``ξ = (r; p)``: with ``dexp⁻¹ = [[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]``
    and ``Q(ξ)ᵀ = Q(−ξ)``, it is ``(J⁻ᵀF; J⁻ᵀ(M − Q(−ξ) J⁻ᵀF))``."""
    o0, o1, o2 = _jinv_T(p0, p1, p2, cinv, F0, F1, F2)
    q = _q_block(-r0, -r1, -r2, -p0, -p1, -p2, c, d, e, o0, o1, o2)
    o3, o4, o5 = _jinv_T(p0, p1, p2, cinv, M0 - q[0], M1 - q[1], M2 - q[2])
    return o0, o1, o2, o3, o4, o5


@_inline
def _so3_log9(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """``log R`` as 3 scalars and the coefficient ``c`` of ``J⁻¹``: ``so3_log_point`` on
    scalars, with the quaternion factor ``θ/|q_v| = (2/q_w) atan(x)/x`` from its series for
    ``x = |q_v|/q_w < 1/20``."""
    qw, qx, qy, qz = quat_of_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    v2 = qx * qx + qy * qy + qz * qz
    w2 = qw * qw
    if v2 < ATAN_SERIES5_X2 * w2:
        f = (2.0 / qw) * horner(v2 / w2, ATAN_SERIES5)
    elif v2 < ATAN_SERIES_X2 * w2:
        f = (2.0 / qw) * horner(v2 / w2, ATAN_SERIES)
    else:
        f = _log_factor_direct(np.sqrt(v2), qw)
    w0, w1, w2 = f * qx, f * qy, f * qz
    return w0, w1, w2, _cinv(w0 * w0 + w1 * w1 + w2 * w2)


@_inline
def _se3_log12(b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """``log (b; R)`` as 6 scalars ``(a1; a2)`` and the coefficient ``c`` of ``J⁻¹(a2)``:
    :func:`cartan.groups.se3.se3_log_point` on scalars (see :func:`_so3_log9`)."""
    w0, w1, w2, c = _so3_log9(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    t = _V_apply(w0, w1, w2, -0.5, c, b0, b1, b2)
    return t[0], t[1], t[2], w0, w1, w2, c


@_inline
def _ad_T(b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22, o0, o1, o2, o3, o4, o5):
    """``Ad_Gᵀ (o_t; o_r) = (Mᵀo_t; Mᵀ(o_r − b × o_t))`` for ``G = (b; M)``."""
    x0, x1, x2 = cross3(b0, b1, b2, o0, o1, o2)
    v0, v1, v2 = o3 - x0, o4 - x1, o5 - x2
    return (m00 * o0 + m10 * o1 + m20 * o2, m01 * o0 + m11 * o1 + m21 * o2, m02 * o0 + m12 * o1 + m22 * o2,
            m00 * v0 + m10 * v1 + m20 * v2, m01 * v0 + m11 * v1 + m21 * v2, m02 * v0 + m12 * v1 + m22 * v2)


@_inline
def _edge_terms6(r0, r1, r2, p0, p1, p2, cinv, c, d, e, q0, q1, q2, q3, q4, q5,
                 b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22):
    """SE(3) tail term ``dexp⁻¹(ξ)ᵀQ`` and head term ``Ad_Gᵀ`` of it for ``G = (b; M)``: 12 scalars."""
    o0, o1, o2, o3, o4, o5 = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, d, e, q0, q1, q2, q3, q4, q5)
    h = _ad_T(b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22, o0, o1, o2, o3, o4, o5)
    return o0, o1, o2, o3, o4, o5, h[0], h[1], h[2], h[3], h[4], h[5]


@_inline
def _turn(cs, sn, x, y):
    """Components of ``Rᵀ(x, y)`` for a plane rotation R by (cos, sin) = (cs, sn)."""
    return cs * x + sn * y, -sn * x + cs * y


@_inline
def _stress6(X0, C, diag, scale, r0, r1, r2, p0, p1, p2, h):
    """``Q = scale·C(ξ/h − X₀)`` for a 6-vector ξ = (r; p), as 6 scalars (the product of C and
    the strain first, then the scale, as ``Lattice.internal_force`` rounds them)."""
    d0, d1, d2 = r0 / h - X0[0], r1 / h - X0[1], r2 / h - X0[2]
    d3, d4, d5 = p0 / h - X0[3], p1 / h - X0[4], p2 / h - X0[5]
    if diag:
        return (scale * (C[0, 0] * d0), scale * (C[1, 1] * d1), scale * (C[2, 2] * d2),
                scale * (C[3, 3] * d3), scale * (C[4, 4] * d4), scale * (C[5, 5] * d5))
    return (scale * (C[0, 0] * d0 + C[0, 1] * d1 + C[0, 2] * d2 + C[0, 3] * d3 + C[0, 4] * d4 + C[0, 5] * d5),
            scale * (C[1, 0] * d0 + C[1, 1] * d1 + C[1, 2] * d2 + C[1, 3] * d3 + C[1, 4] * d4 + C[1, 5] * d5),
            scale * (C[2, 0] * d0 + C[2, 1] * d1 + C[2, 2] * d2 + C[2, 3] * d3 + C[2, 4] * d4 + C[2, 5] * d5),
            scale * (C[3, 0] * d0 + C[3, 1] * d1 + C[3, 2] * d2 + C[3, 3] * d3 + C[3, 4] * d4 + C[3, 5] * d5),
            scale * (C[4, 0] * d0 + C[4, 1] * d1 + C[4, 2] * d2 + C[4, 3] * d3 + C[4, 4] * d4 + C[4, 5] * d5),
            scale * (C[5, 0] * d0 + C[5, 1] * d1 + C[5, 2] * d2 + C[5, 3] * d3 + C[5, 4] * d4 + C[5, 5] * d5))

