"""Per-point kernels and per-chunk loops of the compiled lattice loops.

The passes over the grid live in :mod:`cartan.schemes._lattice_compiled` (and
:mod:`cartan.schemes._lattice_compiled_soa`); here are the group switch, the scalar
SO(3)/SE(3) algebra, and the loops over the edges or nodes of one chunk that the passes call
(:func:`edges_so3`, :func:`edges_se3`, :func:`edges_generic`, :func:`free_flow_nodes`,
:func:`exp_nodes`, :func:`frames_update`).

* **Group switch.**  numba does not cache functions that receive other jitted functions as
  arguments, so the group is a static integer ``gid`` and the ``g_*`` functions dispatch to
  the per-point kernels of :mod:`cartan.groups` (SO(2), SE(2), SO(3), SE(3)); the chunk
  loops branch on ``gid`` once per chunk, not per element.
* **SO(3) and SE(3) in scalar code.**  For elements on the group, SO(3) (the sigma model on
  S², rods on a sphere) and SE(3) (Cosserat rods) work on the matrix entries directly,
  without the matrices of the generic kernels: the logarithm from the quaternion of the
  rotation, ``dexp⁻¹(ξ)ᵀQ`` by cross products (SO(3): ``J⁻ᵀ(p)v = v + ½p × v + c p × (p × v)``;
  SE(3): with Barfoot–Furgale's ``Q`` block), the head term of an edge as ``Ad_Gᵀ`` of its
  tail term (``dexp⁻¹(−ξ)ᵀ = Ad_Gᵀ dexp⁻¹(ξ)ᵀ``), ``exp`` by Rodrigues' formula, and the
  free-flow pieces of ``lie-verlet`` about one body axis as plane rotations.  The
  SO(3)/SE(3) coefficients come from the groups' Taylor series (valid below θ = 0.1; four
  terms below θ² = 10⁻⁴), and ``atan(x)/x`` in the logarithm from its series below x = 1/20;
  the SO(3) edge loop uses the series without branches and recomputes the rare edge
  beyond their range with the closed forms.
* **IEEE division** (``error_model="numpy"``: inf/nan like the reference path, no
  zero-divisor test) in every kernel; small helpers are inlined in numba's IR
  (``inline="always"``) and take and return scalars where they sit in loops meant to be
  fast.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..groups.se2 import (
    se2_Ad_point,
    se2_ad_point,
    se2_compose_point,
    se2_dexp_inv_point,
    se2_E_point,
    se2_exp_point,
    se2_hat_point,
    se2_inverse_point,
    se2_log_point,
)
from ..groups.se3 import (
    TAYLOR_D,
    TAYLOR_E,
    _dexp_coeffs_direct,
    _exp_coeffs3_direct,
    _V_apply,
    se3_Ad_point,
    se3_ad_point,
    se3_compose_point,
    se3_dexp_inv_point,
    se3_E_point,
    se3_exp_point,
    se3_hat_point,
    se3_inverse_point,
    se3_log_point,
)
from ..groups.so2 import (
    so2_Ad_point,
    so2_ad_point,
    so2_compose_point,
    so2_dexp_inv_point,
    so2_E_point,
    so2_exp_point,
    so2_hat_point,
    so2_inverse_point,
    so2_log_point,
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
    _poly_entries,
    cross3,
    horner,
    quat_of_matrix,
    so3_Ad_point,
    so3_ad_point,
    so3_compose_point,
    so3_dexp_inv_point,
    so3_E_point,
    so3_exp_point,
    so3_hat_point,
    so3_inverse_point,
    so3_log_point,
)

GID_SO2 = 0
GID_SE2 = 1
GID_SO3 = 2
GID_SE3 = 3

#: kinds of lie-verlet free-flow pieces: generic (exp and Ad kernels), the SE(3) translations
#: {0, 1, 2}, a rotation about one body axis (SO(3), or SE(3) components 3–5)
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


# ---------------------------------------------------------------------------- group dispatch
@_jit
def g_exp(gid, xi, out):
    if gid == GID_SE3:
        se3_exp_point(xi, out)
    elif gid == GID_SE2:
        se2_exp_point(xi, out)
    elif gid == GID_SO3:
        so3_exp_point(xi, out)
    else:
        so2_exp_point(xi, out)


@_jit
def g_log(gid, g, out):
    if gid == GID_SE3:
        se3_log_point(g, out)
    elif gid == GID_SE2:
        se2_log_point(g, out)
    elif gid == GID_SO3:
        so3_log_point(g, out)
    else:
        so2_log_point(g, out)


@_jit
def g_inverse(gid, g, out):
    if gid == GID_SE3:
        se3_inverse_point(g, out)
    elif gid == GID_SE2:
        se2_inverse_point(g, out)
    elif gid == GID_SO3:
        so3_inverse_point(g, out)
    else:
        so2_inverse_point(g, out)


@_jit
def g_compose(gid, g, h, out):
    if gid == GID_SE3:
        se3_compose_point(g, h, out)
    elif gid == GID_SE2:
        se2_compose_point(g, h, out)
    elif gid == GID_SO3:
        so3_compose_point(g, h, out)
    else:
        so2_compose_point(g, h, out)


@_jit
def g_Ad(gid, g, out):
    if gid == GID_SE3:
        se3_Ad_point(g, out)
    elif gid == GID_SE2:
        se2_Ad_point(g, out)
    elif gid == GID_SO3:
        so3_Ad_point(g, out)
    else:
        so2_Ad_point(g, out)


@_jit
def g_ad(gid, xi, out):
    if gid == GID_SE3:
        se3_ad_point(xi, out)
    elif gid == GID_SE2:
        se2_ad_point(xi, out)
    elif gid == GID_SO3:
        so3_ad_point(xi, out)
    else:
        so2_ad_point(xi, out)


@_jit
def g_hat(gid, xi, out):
    if gid == GID_SE3:
        se3_hat_point(xi, out)
    elif gid == GID_SE2:
        se2_hat_point(xi, out)
    elif gid == GID_SO3:
        so3_hat_point(xi, out)
    else:
        so2_hat_point(xi, out)


@_jit
def g_dexp_inv(gid, xi, out):
    if gid == GID_SE3:
        se3_dexp_inv_point(xi, out)
    elif gid == GID_SE2:
        se2_dexp_inv_point(xi, out)
    elif gid == GID_SO3:
        so3_dexp_inv_point(xi, out)
    else:
        so2_dexp_inv_point(xi, out)


@_inline
def _dexp_slopes(gid, sigma, N, out, tr, M):
    """``out_i = dexp⁻¹(−σ_i) N_i`` at every node (the RKMK stage slopes of the lattice
    loops; ``tr`` r-vector and ``M`` r × r work space)."""
    n, r = N.shape
    for i in range(n):
        for k in range(r):
            tr[k] = -sigma[i, k]
        g_dexp_inv(gid, tr, M)
        for a in range(r):
            acc = 0.0
            for c in range(r):
                acc += M[a, c] * N[i, c]
            out[i, a] = acc


@_jit
def g_E(gid, dt, xi, out):
    if gid == GID_SE3:
        se3_E_point(dt, xi, out)
    elif gid == GID_SE2:
        se2_E_point(dt, xi, out)
    elif gid == GID_SO3:
        so3_E_point(dt, xi, out)
    else:
        so2_E_point(dt, xi, out)


@_jit
def _copy_matrix(src, dst):
    m = src.shape[0]
    for a in range(m):
        for b in range(m):
            dst[a, b] = src[a, b]


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
def _se3_log_at(G, e):
    """:func:`_se3_log12` of the edge element ``G[e]`` (read straight from the batch)."""
    return _se3_log12(G[e, 1, 0], G[e, 2, 0], G[e, 3, 0], G[e, 1, 1], G[e, 1, 2], G[e, 1, 3],
                      G[e, 2, 1], G[e, 2, 2], G[e, 2, 3], G[e, 3, 1], G[e, 3, 2], G[e, 3, 3])


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


@_inline
def _stress3(X0, C, diag, scale, p0, p1, p2, h):
    """``Q = scale·C(ξ/h − X₀)`` for a 3-vector ξ, as 3 scalars."""
    d0, d1, d2 = p0 / h - X0[0], p1 / h - X0[1], p2 / h - X0[2]
    if diag:
        return scale * (C[0, 0] * d0), scale * (C[1, 1] * d1), scale * (C[2, 2] * d2)
    return (scale * (C[0, 0] * d0 + C[0, 1] * d1 + C[0, 2] * d2),
            scale * (C[1, 0] * d0 + C[1, 1] * d1 + C[1, 2] * d2),
            scale * (C[2, 0] * d0 + C[2, 1] * d1 + C[2, 2] * d2))


# ---------------------------------------------------------------------------- fused edge kernels
@_inline
def so3_edge_terms(G, e, X0, C, diag, h, scale, OUT, INC, o):
    """SO(3) force terms of edge ``G[e]`` on the group: ``OUT[o] = J⁻ᵀ(ξ)Q`` (tail) and
    ``INC[o] = RᵀOUT[o]`` (``Ad_Gᵀ``, head), ``ξ = log G_e``, ``Q = scale·C(ξ/h − X₀)``."""
    w0, w1, w2, cinv = _so3_log9(G[e, 0, 0], G[e, 0, 1], G[e, 0, 2], G[e, 1, 0], G[e, 1, 1], G[e, 1, 2],
                                 G[e, 2, 0], G[e, 2, 1], G[e, 2, 2])
    q0, q1, q2 = _stress3(X0, C, diag, scale, w0, w1, w2, h)
    o0, o1, o2 = _jinv_T(w0, w1, w2, cinv, q0, q1, q2)
    OUT[o, 0] = o0
    OUT[o, 1] = o1
    OUT[o, 2] = o2
    INC[o, 0] = G[e, 0, 0] * o0 + G[e, 1, 0] * o1 + G[e, 2, 0] * o2
    INC[o, 1] = G[e, 0, 1] * o0 + G[e, 1, 1] * o1 + G[e, 2, 1] * o2
    INC[o, 2] = G[e, 0, 2] * o0 + G[e, 1, 2] * o1 + G[e, 2, 2] * o2


@_inline
def edge_terms(gid, G, e, X0, C, h, scale, OUT, INC, o, xi, tr, Q, M, M2):
    """Force terms of edge ``G[e]`` by the generic kernels: ``OUT[o] = dexp⁻¹(ξ)ᵀQ`` (on its
    tail node) and ``INC[o] = dexp⁻¹(−ξ)ᵀQ`` (subtracted on its head node), with
    ``ξ = log G_e`` and ``Q = scale·C(ξ/h − X₀)``, ``scale = cell/h`` (``Lattice.internal_force``);
    valid off the group too (``forward-euler``).  ``xi, tr, Q`` (r,) and ``M, M2`` (r, r) are
    work arrays."""
    r = xi.shape[0]
    g_log(gid, G[e], xi)
    for k in range(r):
        tr[k] = xi[k] / h - X0[k]
    for k in range(r):
        acc = 0.0
        for b in range(r):
            acc += C[k, b] * tr[b]
        Q[k] = scale * acc
    g_dexp_inv(gid, xi, M)
    for k in range(r):
        tr[k] = -xi[k]
    g_dexp_inv(gid, tr, M2)
    for a in range(r):
        out = 0.0
        inc = 0.0
        for b in range(r):
            out += M[b, a] * Q[b]
            inc += M2[b, a] * Q[b]
        OUT[o, a] = out
        INC[o, a] = inc


@_inline
def _rotate_block(G, e, s, D, i, j):
    """``B ← R_iᵀ B R_j`` on the 3 × 3 blocks starting at row and column ``s`` (0 for SO(3),
    1 for SE(3))."""
    for a in range(s, s + 3):
        b0 = G[e, a, s] * D[j, s, s] + G[e, a, s + 1] * D[j, s + 1, s] + G[e, a, s + 2] * D[j, s + 2, s]
        b1 = G[e, a, s] * D[j, s, s + 1] + G[e, a, s + 1] * D[j, s + 1, s + 1] + G[e, a, s + 2] * D[j, s + 2, s + 1]
        b2 = G[e, a, s] * D[j, s, s + 2] + G[e, a, s + 1] * D[j, s + 1, s + 2] + G[e, a, s + 2] * D[j, s + 2, s + 2]
        G[e, a, s] = b0
        G[e, a, s + 1] = b1
        G[e, a, s + 2] = b2
    for b in range(s, s + 3):
        m0, m1, m2 = G[e, s, b], G[e, s + 1, b], G[e, s + 2, b]
        G[e, s, b] = D[i, s, s] * m0 + D[i, s + 1, s] * m1 + D[i, s + 2, s] * m2
        G[e, s + 1, b] = D[i, s, s + 1] * m0 + D[i, s + 1, s + 1] * m1 + D[i, s + 2, s + 1] * m2
        G[e, s + 2, b] = D[i, s, s + 2] * m0 + D[i, s + 1, s + 2] * m1 + D[i, s + 2, s + 2] * m2


@_inline
def so3_conjugate(G, e, D, i, j):
    """``G_e ← D_iᵀ G_e D_j`` on SO(3)."""
    _rotate_block(G, e, 0, D, i, j)


@_inline
def se3_conjugate(G, e, D, i, j):
    """``G_e ← D_i⁻¹ G_e D_j`` on SE(3): ``(R_iᵀ(B t_j + b − t_i); R_iᵀ B R_j)`` for
    ``G_e = (b; B)``, ``D = (t; R)``."""
    u0 = G[e, 1, 1] * D[j, 1, 0] + G[e, 1, 2] * D[j, 2, 0] + G[e, 1, 3] * D[j, 3, 0] + G[e, 1, 0] - D[i, 1, 0]
    u1 = G[e, 2, 1] * D[j, 1, 0] + G[e, 2, 2] * D[j, 2, 0] + G[e, 2, 3] * D[j, 3, 0] + G[e, 2, 0] - D[i, 2, 0]
    u2 = G[e, 3, 1] * D[j, 1, 0] + G[e, 3, 2] * D[j, 2, 0] + G[e, 3, 3] * D[j, 3, 0] + G[e, 3, 0] - D[i, 3, 0]
    _rotate_block(G, e, 1, D, i, j)
    G[e, 1, 0] = D[i, 1, 1] * u0 + D[i, 2, 1] * u1 + D[i, 3, 1] * u2
    G[e, 2, 0] = D[i, 1, 2] * u0 + D[i, 2, 2] * u1 + D[i, 3, 2] * u2
    G[e, 3, 0] = D[i, 1, 3] * u0 + D[i, 2, 3] * u1 + D[i, 3, 3] * u2


@_inline
def conjugate_edge(gid, G, e, D, i, j, A1, A2):
    """``G_e ← D_i⁻¹ G_e D_j`` by the generic kernels (``A1, A2`` (m, m) work)."""
    g_inverse(gid, D[i], A1)
    g_compose(gid, A1, G[e], A2)
    g_compose(gid, A2, D[j], G[e])


@_inline
def euler_edge(G, e, D, i, j, A1):
    """Naive matrix Euler drift of one edge, ``G_e ← G_e − D_i G_e + G_e D_j`` with ``D = τN̂``."""
    m = A1.shape[0]
    for a in range(m):
        for b in range(m):
            left = 0.0
            right = 0.0
            for c in range(m):
                left += D[i, a, c] * G[e, c, b]
                right += G[e, a, c] * D[j, c, b]
            A1[a, b] = G[e, a, b] - left + right
    _copy_matrix(A1, G[e])


# ---------------------------------------------------------------------------- per-chunk edge loops
@_inline
def _unravel3(k, s1, s2):
    """Multi-index of flat index ``k`` in a C-ordered ``(·, s1, s2)`` array."""
    i2 = k % s2
    t = k // s2
    return t // s1, t % s1, i2


@_inline
def _next3(i0, i1, i2, s1, s2):
    """The multi-index after ``(i0, i1, i2)`` in a C-ordered ``(·, s1, s2)`` array."""
    i2 += 1
    if i2 == s2:
        i2 = 0
        i1 += 1
        if i1 == s1:
            i1 = 0
            i0 += 1
    return i0, i1, i2


@_inline
def _ends(j0, j1, j2, a, n1, n2, na, st):
    """Tail and head node of the edge at multi-index ``(j0, j1, j2)`` along axis ``a`` of
    ``na`` nodes and node stride ``st`` (the last edge of a periodic axis closes onto index 0)."""
    ja = j0 if a == 0 else (j1 if a == 1 else j2)
    i = (j0 * n1 + j1) * n2 + j2
    return i, (i + st if ja + 1 < na else i - ja * st)


@_jit
def edges_so3(G, lo, hi, a, E1, E2, n1, n2, na, st, D, conj, force, X0, C, diag, h, scale, OUT, INC, off, bad):
    """Edges ``lo ≤ e < hi`` of axis ``a`` on SO(3): (``conj``) ``G_e ← D_iᵀ G_e D_j``, then
    (``force``) their force terms into ``OUT``/``INC`` at ``off + e`` (one loop each over the
    chunk, whose edges stay in the cache).  The force loop has no branches: the logarithm from
    the trace quaternion and the series of ``atan(x)/x`` and of the ``J⁻¹`` coefficient, with
    the full product by C; the edges outside the series' range (θ ≥ 0.1, or a diagonal entry
    above the trace) are flagged in ``bad`` and recomputed with the closed forms."""
    if conj:
        j0, j1, j2 = _unravel3(lo, E1, E2)
        for k in range(hi - lo):
            i, j = _ends(j0, j1, j2, a, n1, n2, na, st)
            so3_conjugate(G, lo + k, D, i, j)
            j0, j1, j2 = _next3(j0, j1, j2, E1, E2)
    if not force:
        return
    c00, c01, c02 = C[0, 0], C[0, 1], C[0, 2]
    c10, c11, c12 = C[1, 0], C[1, 1], C[1, 2]
    c20, c21, c22 = C[2, 0], C[2, 1], C[2, 2]
    x00, x01, x02 = X0[0], X0[1], X0[2]
    hinv = 1.0 / h
    nbad = 0
    for k in range(hi - lo):
        e = lo + k
        o = off + e
        m00, m01, m02 = G[e, 0, 0], G[e, 0, 1], G[e, 0, 2]
        m10, m11, m12 = G[e, 1, 0], G[e, 1, 1], G[e, 1, 2]
        m20, m21, m22 = G[e, 2, 0], G[e, 2, 1], G[e, 2, 2]
        w0, w1, w2, tr, x2, t2, cinv = so3_log_series(m00, m01, m02, m10, m11, m12, m20, m21, m22)
        d0, d1, d2 = w0 * hinv - x00, w1 * hinv - x01, w2 * hinv - x02
        q0 = scale * (c00 * d0 + c01 * d1 + c02 * d2)
        q1 = scale * (c10 * d0 + c11 * d1 + c12 * d2)
        q2 = scale * (c20 * d0 + c21 * d1 + c22 * d2)
        o0, o1, o2 = _jinv_T(w0, w1, w2, cinv, q0, q1, q2)
        OUT[o, 0] = o0
        OUT[o, 1] = o1
        OUT[o, 2] = o2
        INC[o, 0] = m00 * o0 + m10 * o1 + m20 * o2
        INC[o, 1] = m01 * o0 + m11 * o1 + m21 * o2
        INC[o, 2] = m02 * o0 + m12 * o1 + m22 * o2
        flag = (x2 >= ATAN_SERIES_X2) | (t2 >= SMALL_THETA2) | (m00 > tr) | (m11 > tr) | (m22 > tr)
        bad[o] = flag
        nbad += flag
    if nbad:
        for k in range(hi - lo):
            if bad[off + lo + k]:
                so3_edge_terms(G, lo + k, X0, C, diag, h, scale, OUT, INC, off + lo + k)


@_jit
def edges_se3(G, lo, hi, a, E1, E2, n1, n2, na, st, D, conj, force, X0, C, diag, h, scale, OUT, INC, off, XI):
    """:func:`edges_so3` on SE(3), the force terms in two loops over the chunk: the logarithms
    into ``XI [·, 7]`` (at ``off + e``), then the Jacobians (short loop bodies overlap better)."""
    if conj:
        j0, j1, j2 = _unravel3(lo, E1, E2)
        for k in range(hi - lo):
            i, j = _ends(j0, j1, j2, a, n1, n2, na, st)
            se3_conjugate(G, lo + k, D, i, j)
            j0, j1, j2 = _next3(j0, j1, j2, E1, E2)
    if not force:
        return
    for k in range(hi - lo):
        o = off + lo + k
        XI[o, 0], XI[o, 1], XI[o, 2], XI[o, 3], XI[o, 4], XI[o, 5], XI[o, 6] = _se3_log_at(G, lo + k)
    for k in range(hi - lo):
        e = lo + k
        o = off + e
        r0, r1, r2, p0, p1, p2, cinv = XI[o, 0], XI[o, 1], XI[o, 2], XI[o, 3], XI[o, 4], XI[o, 5], XI[o, 6]
        q0, q1, q2, q3, q4, q5 = _stress6(X0, C, diag, scale, r0, r1, r2, p0, p1, p2, h)
        c, dd, ee = _q_coeffs(p0 * p0 + p1 * p1 + p2 * p2)
        o0, o1, o2, o3, o4, o5 = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, dd, ee, q0, q1, q2, q3, q4, q5)
        OUT[o, 0] = o0
        OUT[o, 1] = o1
        OUT[o, 2] = o2
        OUT[o, 3] = o3
        OUT[o, 4] = o4
        OUT[o, 5] = o5
        h0, h1, h2, h3, h4, h5 = _ad_T(G[e, 1, 0], G[e, 2, 0], G[e, 3, 0], G[e, 1, 1], G[e, 1, 2], G[e, 1, 3],
                                       G[e, 2, 1], G[e, 2, 2], G[e, 2, 3], G[e, 3, 1], G[e, 3, 2], G[e, 3, 3],
                                       o0, o1, o2, o3, o4, o5)
        INC[o, 0] = h0
        INC[o, 1] = h1
        INC[o, 2] = h2
        INC[o, 3] = h3
        INC[o, 4] = h4
        INC[o, 5] = h5


@_jit
def edges_generic(gid, G, lo, hi, a, E1, E2, n1, n2, na, st, D, mode, force, X0, C, h, scale, OUT, INC, off,
                  xi, tr, Q, M, M2, A1, A2):
    """:func:`edges_so3` for any group by the generic kernels; ``mode`` 1: ``G_e ← D_i⁻¹G_eD_j``,
    2: ``G_e ← G_e − D_iG_e + G_eD_j`` (``forward-euler``), 0: no drift; the force terms
    evaluate ``dexp⁻¹(−ξ)ᵀQ`` directly (valid off the group)."""
    j0, j1, j2 = _unravel3(lo, E1, E2)
    for k in range(hi - lo):
        e = lo + k
        if mode != 0:
            i, j = _ends(j0, j1, j2, a, n1, n2, na, st)
            if mode == 1:
                conjugate_edge(gid, G, e, D, i, j, A1, A2)
            else:
                euler_edge(G, e, D, i, j, A1)
        if force:
            edge_terms(gid, G, e, X0, C, h, scale, OUT, INC, off + e, xi, tr, Q, M, M2)
        j0, j1, j2 = _next3(j0, j1, j2, E1, E2)


# ---------------------------------------------------------------------------- node kernels
@_jit
def frames_update(gid, Phi, D, lo, hi, A1):
    """``Φ_i ← Φ_i D_i`` for ``lo ≤ i < hi`` (``A1`` (m, m) work)."""
    if gid == GID_SE3:
        for k in range(hi - lo):
            i = lo + k
            for a in range(1, 4):
                x0, x1, x2, x3 = Phi[i, a, 0], Phi[i, a, 1], Phi[i, a, 2], Phi[i, a, 3]
                Phi[i, a, 0] = x1 * D[i, 1, 0] + x2 * D[i, 2, 0] + x3 * D[i, 3, 0] + x0
                Phi[i, a, 1] = x1 * D[i, 1, 1] + x2 * D[i, 2, 1] + x3 * D[i, 3, 1]
                Phi[i, a, 2] = x1 * D[i, 1, 2] + x2 * D[i, 2, 2] + x3 * D[i, 3, 2]
                Phi[i, a, 3] = x1 * D[i, 1, 3] + x2 * D[i, 2, 3] + x3 * D[i, 3, 3]
        return
    for k in range(hi - lo):
        i = lo + k
        g_compose(gid, Phi[i], D[i], A1)
        _copy_matrix(A1, Phi[i])


@_jit
def exp_nodes(gid, tau, N, D, lo, hi, xi):
    """``D_i = exp(τN_i)`` for ``lo ≤ i < hi`` (``xi`` (r,) work of the generic kernels)."""
    if gid == GID_SE3:
        for k in range(hi - lo):
            i = lo + k
            x0, x1, x2 = tau * N[i, 0], tau * N[i, 1], tau * N[i, 2]
            w0, w1, w2 = tau * N[i, 3], tau * N[i, 4], tau * N[i, 5]
            a, b, c = _exp3_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
            R = _poly_entries(w0, w1, w2, a, b, 1.0)
            t = _V_apply(w0, w1, w2, b, c, x0, x1, x2)
            D[i, 0, 0], D[i, 0, 1], D[i, 0, 2], D[i, 0, 3] = 1.0, 0.0, 0.0, 0.0
            D[i, 1, 0], D[i, 1, 1], D[i, 1, 2], D[i, 1, 3] = t[0], R[0], R[1], R[2]
            D[i, 2, 0], D[i, 2, 1], D[i, 2, 2], D[i, 2, 3] = t[1], R[3], R[4], R[5]
            D[i, 3, 0], D[i, 3, 1], D[i, 3, 2], D[i, 3, 3] = t[2], R[6], R[7], R[8]
        return
    if gid == GID_SO3:
        for k in range(hi - lo):
            i = lo + k
            w0, w1, w2 = tau * N[i, 0], tau * N[i, 1], tau * N[i, 2]
            a, b = _rot_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
            R = _poly_entries(w0, w1, w2, a, b, 1.0)
            D[i, 0, 0], D[i, 0, 1], D[i, 0, 2] = R[0], R[1], R[2]
            D[i, 1, 0], D[i, 1, 1], D[i, 1, 2] = R[3], R[4], R[5]
            D[i, 2, 0], D[i, 2, 1], D[i, 2, 2] = R[6], R[7], R[8]
        return
    r = xi.shape[0]
    for k in range(hi - lo):
        i = lo + k
        for c in range(r):
            xi[c] = tau * N[i, c]
        g_exp(gid, xi, D[i])


@_inline
def _plane(k):
    """The plane ``(p, q)`` turned by a rotation about body axis ``k`` (cyclic order)."""
    p = k + 1 if k < 2 else 0
    q = k + 2 if k < 1 else k - 1
    return p, q


@_inline
def _identity(D, i):
    m = D.shape[1]
    for a in range(m):
        for b in range(m):
            D[i, a, b] = 1.0 if a == b else 0.0


@_jit
def free_flow_nodes(gid, S, D, lo, hi, clamped, mass, seq_mask, seq_frac, fac, kinds, axes, dt, xi, tr, M, A1, A2):
    """Palindromic exact free flow of the nodes ``lo ≤ i < hi``, composed into one element
    ``D_i`` per node (``LieVerlet._step``): for each piece p, ``S_i ← Ad*_{exp(τN_p)} S_i`` and
    ``D_i ← D_i exp(τN_p)``; ``D_i = I`` at clamped nodes (zero momentum).  Piece by piece
    over the nodes.

    ``seq_mask, seq_frac``: components and fraction of Δt of each piece; ``fac[p, k] = τ_p/m_k``;
    ``kinds, axes``: the closed-form pieces — :data:`KIND_ROTATION` about body axis
    ``axes[p]`` (SO(3), SE(3)): ``S`` and the columns of ``D`` turned in the plane of the
    axis by cosine ``1 − Bθ²`` and sine ``Aθ``; :data:`KIND_SE3_TRANSLATION`: ``L ← L − a × P``,
    ``t ← t + R a`` —; the others (:data:`KIND_GENERIC`) through the generic exp and Ad
    kernels (``xi, tr`` (r,), ``M`` (r, r), ``A1, A2`` (m, m) work).
    """
    r = S.shape[1]
    for k in range(hi - lo):
        _identity(D, lo + k)
    for p in range(kinds.shape[0]):
        kind = kinds[p]
        if kind == KIND_ROTATION:
            s = 1 if gid == GID_SE3 else 0  # first row/column of the rotation block in D
            c = 3 * s + axes[p]  # the momentum component about the axis
            pp, qq = _plane(axes[p])
            f = fac[p, c]
            for k in range(hi - lo):
                i = lo + k
                if clamped[i]:
                    continue
                th = f * S[i, c]
                q2 = th * th
                a, b = _rot_coeffs(q2)
                cs, sn = 1.0 - b * q2, a * th
                if s == 1:
                    S[i, pp], S[i, qq] = _turn(cs, sn, S[i, pp], S[i, qq])
                S[i, 3 * s + pp], S[i, 3 * s + qq] = _turn(cs, sn, S[i, 3 * s + pp], S[i, 3 * s + qq])
                for row in range(s, s + 3):
                    D[i, row, s + pp], D[i, row, s + qq] = _turn(cs, sn, D[i, row, s + pp], D[i, row, s + qq])
        elif kind == KIND_SE3_TRANSLATION:
            f0, f1, f2 = fac[p, 0], fac[p, 1], fac[p, 2]
            for k in range(hi - lo):
                i = lo + k
                if clamped[i]:
                    continue
                P0, P1, P2 = S[i, 0], S[i, 1], S[i, 2]
                a0, a1, a2 = f0 * P0, f1 * P1, f2 * P2
                c0, c1, c2 = cross3(a0, a1, a2, P0, P1, P2)
                S[i, 3] -= c0
                S[i, 4] -= c1
                S[i, 5] -= c2
                for row in range(1, 4):
                    D[i, row, 0] += D[i, row, 1] * a0 + D[i, row, 2] * a1 + D[i, row, 3] * a2
        else:
            tau = seq_frac[p] * dt
            for k in range(hi - lo):
                i = lo + k
                if clamped[i]:
                    continue
                for q in range(r):
                    xi[q] = tau * (S[i, q] / mass[q]) if seq_mask[p, q] else 0.0
                g_exp(gid, xi, A1)
                g_Ad(gid, A1, M)
                for a in range(r):
                    acc = 0.0
                    for b in range(r):
                        acc += M[b, a] * S[i, b]
                    tr[a] = acc
                for a in range(r):
                    S[i, a] = tr[a]
                g_compose(gid, D[i], A1, A2)
                _copy_matrix(A2, D[i])
