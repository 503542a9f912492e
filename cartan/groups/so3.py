"""The rotation group SO(3) in closed form.

Conventions (paper, Appendix "Vector and matrix operations")
------------------------------------------------------------
* Algebra components ``w = (w1, w2, w3)``; the hat map is
  ``ŵ = [[0, −w3, w2], [w3, 0, −w1], [−w2, w1, 0]]`` so that ``ŵ x = w × x``, and the basis
  is ``b_i = ê_i``.  ``vee`` returns ``½(A32 − A23, A13 − A31, A21 − A12)``, the
  least-squares inverse of ``hat`` (equal to the paper's ``(A32, A13, A21)`` on so(3)).
* ``Ad_R = R`` and ``ad_w = ŵ`` as ``3 × 3`` matrices; ``[u, v] = u × v``.
* ``dexp(w) = Σ_k ad_wᵏ/(k+1)! = J(w) = I + B K + C K²`` (the left Jacobian), ``K = ŵ``,
  with ``B = (1 − cos θ)/θ²`` and ``C = (θ − sin θ)/θ³``; ``dexp⁻¹(w) = I − ½K + c K²`` with
  ``c = (1 − (θ/2) cot(θ/2))/θ²``; ``𝓔(Δt, Y) = Δt·dexp(ΔtY)``.

Numerics
--------
``exp(w) = I + A K + B K²`` with ``A = sin θ/θ`` and ``B = ½(sin(θ/2)/(θ/2))²`` (never
``(1 − cos θ)/θ²`` directly).  Below ``θ = 0.1`` every coefficient is evaluated from its
Taylor series in ``θ²`` (six terms: truncation below 1e-19 relative).  The logarithm goes
through an unnormalised quaternion chosen by the largest-diagonal rule (Shepperd), with
``θ = 2 atan2(|q_v|, |q_w|)``; it is accurate up to and at ``θ = π``, where the sign of the
axis is arbitrary.

Kernels
-------
The arithmetic shared by both backends lives in ``register_jitable`` helpers, so the numpy
reference path and the numba kernels evaluate identical formulas.  The per-point kernels
``so3_*_point`` are public, allocation-free and ``@njit(cache=True)``: compiled step loops
call them directly.  The batch loops ``_*_batch`` map them over ``P`` flattened points and
are listed in :attr:`SO3._kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import register_jitable

from ._batch import kernel_table
from .base import SymmetryGroup

__all__ = [
    "SO3",
    "so3_Ad_inv_apply_point",
    "so3_Ad_point",
    "so3_axis_flow_point",
    "so3_act_point",
    "so3_ad_point",
    "so3_bracket_point",
    "so3_compose_point",
    "so3_dexp_coeffs",
    "so3_dexp_inv_coeff",
    "so3_dexp_inv_T_pair_point",
    "so3_dexp_inv_point",
    "so3_dexp_point",
    "so3_E_apply_point",
    "so3_dexp_inv_apply_point",
    "so3_E_point",
    "so3_exp_coeffs",
    "so3_exp_point",
    "so3_hat_point",
    "so3_inverse_point",
    "so3_log_point",
    "so3_poly_point",
    "so3_vee_point",
]

#: Below this value of θ² the coefficients are evaluated from their Taylor series (θ < 0.1).
SMALL_THETA2 = 0.01

# Taylor coefficients in t = θ², highest power first (for Horner's scheme).
#: sin θ/θ = Σ (−1)ᵏ tᵏ/(2k+1)!
TAYLOR_A = (-1.0 / 39916800.0, 1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0, 1.0)
#: (1 − cos θ)/θ² = Σ (−1)ᵏ tᵏ/(2k+2)!
TAYLOR_B = (-1.0 / 479001600.0, 1.0 / 3628800.0, -1.0 / 40320.0, 1.0 / 720.0, -1.0 / 24.0, 0.5)
#: (θ − sin θ)/θ³ = Σ (−1)ᵏ tᵏ/(2k+3)!
TAYLOR_C = (-1.0 / 6227020800.0, 1.0 / 39916800.0, -1.0 / 362880.0, 1.0 / 5040.0, -1.0 / 120.0,
            1.0 / 6.0)
#: (1 − (θ/2) cot(θ/2))/θ² = Σ (−1)ᵏ⁺¹ B₂ₖ tᵏ⁻¹/(2k)!  (B₂ₖ Bernoulli numbers)
TAYLOR_CINV = (691.0 / 1307674368000.0, 1.0 / 47900160.0, 1.0 / 1209600.0, 1.0 / 30240.0,
               1.0 / 720.0, 1.0 / 12.0)


# ---------------------------------------------------------------------- shared arithmetic
# ``register_jitable`` functions run as plain Python on numpy arrays (the numpy reference
# path) and are compiled into the numba kernels that call them: one set of formulas.
@register_jitable
def horner(t, coeffs):
    """Evaluate the polynomial with coefficients ``coeffs`` (highest power first) at ``t``."""
    acc = 0.0 * t
    for c in coeffs:
        acc = acc * t + c
    return acc


@register_jitable(inline='always')
def cross3(a0, a1, a2, b0, b1, b2):
    """Components of the cross product ``a × b = â b``."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@register_jitable(inline='always')
def _exp_coeffs_direct(t2):
    th = np.sqrt(t2)
    h = 0.5 * th
    sh = np.sin(h) / h
    return np.sin(th) / th, 0.5 * sh * sh


@register_jitable(inline='always')
def _exp_coeffs_series(t2):
    return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B)


@register_jitable(inline='always')
def _C_direct(t2):
    th = np.sqrt(t2)
    return (th - np.sin(th)) / (th * t2)


@register_jitable(inline='always')
def _cinv_direct(t2):
    h = 0.5 * np.sqrt(t2)
    return (1.0 - h * np.cos(h) / np.sin(h)) / t2


@register_jitable(inline='always')
def _poly_entries(x, y, z, a, b, s):
    """Entries (row-major) of ``s (I + a K + b K²)``, ``K = hat(x, y, z)``."""
    xy = x * y
    xz = x * z
    yz = y * z
    return (
        s * (1.0 - b * (y * y + z * z)), s * (b * xy - a * z), s * (b * xz + a * y),
        s * (b * xy + a * z), s * (1.0 - b * (x * x + z * z)), s * (b * yz - a * x),
        s * (b * xz - a * y), s * (b * yz + a * x), s * (1.0 - b * (x * x + y * y)),
    )


@register_jitable(inline='always')
def _quat_from_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22, case):
    """Unnormalised quaternion ``4 q_k q`` of a rotation matrix, ``k`` the chosen ``case``.

    ``case`` 0 uses the trace, 1–3 the diagonal entries (largest-diagonal rule); the
    chosen component equals ``1 + 2·max − tr ≥ 1``, so the result is never zero.
    """
    if case == 0:
        return 1.0 + r00 + r11 + r22, r21 - r12, r02 - r20, r10 - r01
    if case == 1:
        return r21 - r12, 1.0 + r00 - r11 - r22, r01 + r10, r02 + r20
    if case == 2:
        return r02 - r20, r01 + r10, 1.0 - r00 + r11 - r22, r12 + r21
    return r10 - r01, r02 + r20, r12 + r21, 1.0 - r00 - r11 + r22


@register_jitable
def quat_of_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """The unit quaternion ``(w, x, y, z)`` of a rotation matrix with ``w ≥ 0``, from the largest
    of the trace and the diagonal entries (Shepperd's choice: accurate for every angle)."""
    case = 0
    best = r00 + r11 + r22
    if r00 > best:
        case = 1
        best = r00
    if r11 > best:
        case = 2
        best = r11
    if r22 > best:
        case = 3
    qw, qx, qy, qz = _quat_from_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22, case)
    if qw < 0.0:
        return -qw, -qx, -qy, -qz
    return qw, qx, qy, qz


@register_jitable(inline='always')
def _log_factor_series(s, c):
    """``θ/|q_v|`` for ``|q_v| ≤ 1e-4 |q_w|``: ``(2/c) atan(x)/x``, ``x = s/c``."""
    x = s / c
    x2 = x * x
    return (2.0 / c) * (1.0 + x2 * (-1.0 / 3.0 + x2 * (1.0 / 5.0)))


@register_jitable(inline='always')
def _log_factor_direct(s, c):
    return 2.0 * np.arctan2(s, c) / s


#: |q_v| ≤ LOG_SMALL_RATIO·|q_w| selects the series for θ/|q_v| (θ ≲ 2e-4).
LOG_SMALL_RATIO = 1e-4

#: atan(x)/x = Σ (−1)ᵏ x²ᵏ/(2k+1), highest power first: below x² = 1/400 (θ < 0.1) nine
#: terms leave a truncation below 1e-24 (the branch-free logarithm of the edge passes)
ATAN_SERIES = (1.0 / 17.0, -1.0 / 15.0, 1.0 / 13.0, -1.0 / 11.0, 1.0 / 9.0, -1.0 / 7.0, 1.0 / 5.0, -1.0 / 3.0, 1.0)
#: the range of :data:`ATAN_SERIES` in x² = (|q_v|/q_w)²
ATAN_SERIES_X2 = 1.0 / 400.0


@register_jitable(inline='always')
def so3_log_trace_series(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """``(w0, w1, w2, bad)``: the rotation vector of ``R`` by the arithmetic of
    :func:`so3_log_point` in its trace case — the quaternion ``(1 + tr R, vee(R − Rᵀ))``,
    ``w = (2/q_w)(atan(x)/x) q_v`` with ``x = |q_v|/q_w`` — with ``atan(x)/x`` from
    :data:`ATAN_SERIES` instead of ``atan2``, and no branch (so that a loop of it vectorises).
    ``bad`` says that it is not :func:`so3_log_point`'s result to round-off: outside the trace
    case (a diagonal entry above the trace) or ``x² ≥ ATAN_SERIES_X2`` (θ ≥ 0.1); a NaN entry
    gives NaN and not ``bad``.  The same formulas as ``so3_log_point`` off the group too (where
    forward Euler takes the edges), since both read the same quaternion."""
    tr = r00 + r11 + r22
    qw = 1.0 + tr
    qx, qy, qz = r21 - r12, r02 - r20, r10 - r01
    x2 = (qx * qx + qy * qy + qz * qz) / (qw * qw)
    f = (2.0 / qw) * horner(x2, ATAN_SERIES)
    bad = (x2 >= ATAN_SERIES_X2) | (r00 > tr) | (r11 > tr) | (r22 > tr)
    return f * qx, f * qy, f * qz, bad


# ---------------------------------------------------------------------- numba point kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def so3_exp_coeffs(t2):
    """``(A, B) = (sin θ/θ, (1 − cos θ)/θ²)`` as functions of ``t2 = θ²``."""
    if t2 < SMALL_THETA2:
        return _exp_coeffs_series(t2)
    return _exp_coeffs_direct(t2)


@njit(cache=True, inline='always')
def so3_dexp_coeffs(t2):
    """``(B, C) = ((1 − cos θ)/θ², (θ − sin θ)/θ³)``, the coefficients of ``J = I + BK + CK²``."""
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)
    return _exp_coeffs_direct(t2)[1], _C_direct(t2)


@njit(cache=True, inline='always')
def so3_dexp_inv_coeff(t2):
    """``c = (1 − (θ/2) cot(θ/2))/θ²``, the coefficient of ``J⁻¹ = I − ½K + cK²``."""
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_CINV)
    return _cinv_direct(t2)


@njit(cache=True, inline='always')
def so3_poly_point(x, y, z, a, b, s, out):
    """Fill ``out`` (3, 3) with ``s (I + a K + b K²)``, ``K = hat(x, y, z)``."""
    e = _poly_entries(x, y, z, a, b, s)
    out[0, 0] = e[0]
    out[0, 1] = e[1]
    out[0, 2] = e[2]
    out[1, 0] = e[3]
    out[1, 1] = e[4]
    out[1, 2] = e[5]
    out[2, 0] = e[6]
    out[2, 1] = e[7]
    out[2, 2] = e[8]


@njit(cache=True, inline='always')
def so3_hat_point(w, out):
    """``out`` (3, 3) ← ``ŵ`` for ``w`` (3,)."""
    out[0, 0] = 0.0
    out[0, 1] = -w[2]
    out[0, 2] = w[1]
    out[1, 0] = w[2]
    out[1, 1] = 0.0
    out[1, 2] = -w[0]
    out[2, 0] = -w[1]
    out[2, 1] = w[0]
    out[2, 2] = 0.0


@njit(cache=True, inline='always')
def so3_vee_point(A, out):
    """``out`` (3,) ← ``½(A32 − A23, A13 − A31, A21 − A12)`` for ``A`` (3, 3)."""
    out[0] = 0.5 * (A[2, 1] - A[1, 2])
    out[1] = 0.5 * (A[0, 2] - A[2, 0])
    out[2] = 0.5 * (A[1, 0] - A[0, 1])


@njit(cache=True, inline='always')
def so3_compose_point(R1, R2, out):
    """``out`` (3, 3) ← ``R1 R2``; ``out`` must not alias the inputs."""
    for i in range(3):
        for j in range(3):
            out[i, j] = R1[i, 0] * R2[0, j] + R1[i, 1] * R2[1, j] + R1[i, 2] * R2[2, j]


@njit(cache=True, inline='always')
def so3_inverse_point(R, out):
    """``out`` (3, 3) ← ``Rᵀ``; ``out`` must not alias ``R``."""
    for i in range(3):
        for j in range(3):
            out[i, j] = R[j, i]


@njit(cache=True, inline='always')
def so3_act_point(R, x, out):
    """``out`` (3,) ← ``R x``."""
    for i in range(3):
        out[i] = R[i, 0] * x[0] + R[i, 1] * x[1] + R[i, 2] * x[2]


@njit(cache=True, inline='always')
def so3_Ad_T_point(R, v, out):
    """``out`` (3,) ← ``Ad_Rᵀ v = Rᵀ v``."""
    for j in range(3):
        out[j] = R[0, j] * v[0] + R[1, j] * v[1] + R[2, j] * v[2]


@njit(cache=True, inline='always')
def so3_dexp_inv_T_point(w, v, out):
    """``out`` (3,) ← ``J⁻ᵀ(w) v = v + ½ w × v + c w × (w × v)`` (the transpose of
    :func:`so3_dexp_inv_point`), without the matrix."""
    c = so3_dexp_inv_coeff(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    u0, u1, u2 = cross3(w[0], w[1], w[2], v[0], v[1], v[2])
    z0, z1, z2 = cross3(w[0], w[1], w[2], u0, u1, u2)
    out[0], out[1], out[2] = v[0] + 0.5 * u0 + c * z0, v[1] + 0.5 * u1 + c * z1, v[2] + 0.5 * u2 + c * z2


@njit(cache=True, inline='always')
def so3_dexp_inv_T_pair_point(w, v, out, out_neg):
    """``out`` (3,) ← ``J⁻ᵀ(w) v`` and ``out_neg`` (3,) ← ``J⁻ᵀ(−w) v = v − ½ w × v + c w × (w × v)``:
    both ends of an edge from one set of products."""
    c = so3_dexp_inv_coeff(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    u0, u1, u2 = cross3(w[0], w[1], w[2], v[0], v[1], v[2])
    z0, z1, z2 = cross3(w[0], w[1], w[2], u0, u1, u2)
    e0, e1, e2 = v[0] + c * z0, v[1] + c * z1, v[2] + c * z2
    out[0], out[1], out[2] = e0 + 0.5 * u0, e1 + 0.5 * u1, e2 + 0.5 * u2
    out_neg[0], out_neg[1], out_neg[2] = e0 - 0.5 * u0, e1 - 0.5 * u1, e2 - 0.5 * u2


@njit(cache=True, inline='always')
def so3_dexp_inv_apply_point(w, v, out, work):
    """``out`` (3,) ← ``J⁻¹(w) v = v − ½ w × v + c w × (w × v)`` (:func:`so3_dexp_inv_point`)
    without the matrix; ``work`` is unused (the scratch of the generic form)."""
    c = so3_dexp_inv_coeff(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    u0, u1, u2 = cross3(w[0], w[1], w[2], v[0], v[1], v[2])
    z0, z1, z2 = cross3(w[0], w[1], w[2], u0, u1, u2)
    out[0], out[1], out[2] = v[0] - 0.5 * u0 + c * z0, v[1] - 0.5 * u1 + c * z1, v[2] - 0.5 * u2 + c * z2


@njit(cache=True, inline='always')
def so3_Ad_inv_apply_point(R, X, out, work):
    """``out[a]`` (3,) ← ``Ad_{R⁻¹} X[a] = Rᵀ X[a]`` for every row of ``X`` ``(k, 3)``; ``work``
    is unused (the scratch of the generic form)."""
    for a in range(X.shape[0]):
        x0, x1, x2 = X[a, 0], X[a, 1], X[a, 2]
        for j in range(3):
            out[a, j] = R[0, j] * x0 + R[1, j] * x1 + R[2, j] * x2


@njit(cache=True, inline='always')
def so3_E_apply_point(dt, w, V, out, work):
    """``out[a]`` (3,) ← ``𝓔(Δt, w) V[a] = Δt (v + B u × v + C u × (u × v))``, ``u = Δt w``, for
    every row ``v`` of ``V`` ``(k, 3)``, without the matrix (:func:`so3_E_point`); ``work`` is
    unused."""
    x, y, z = dt * w[0], dt * w[1], dt * w[2]
    b, c = so3_dexp_coeffs(x * x + y * y + z * z)
    for a in range(V.shape[0]):
        v0, v1, v2 = V[a, 0], V[a, 1], V[a, 2]
        u0, u1, u2 = cross3(x, y, z, v0, v1, v2)
        z0, z1, z2 = cross3(x, y, z, u0, u1, u2)
        out[a, 0] = dt * (v0 + b * u0 + c * z0)
        out[a, 1] = dt * (v1 + b * u1 + c * z1)
        out[a, 2] = dt * (v2 + b * u2 + c * z2)


@njit(cache=True, inline='always')
def so3_Ad_point(R, out):
    """``out`` (3, 3) ← ``Ad_R = R``."""
    for i in range(3):
        for j in range(3):
            out[i, j] = R[i, j]


@njit(cache=True, inline='always')
def so3_ad_point(w, out):
    """``out`` (3, 3) ← ``ad_w = ŵ``."""
    so3_hat_point(w, out)


@njit(cache=True, inline='always')
def so3_bracket_point(u, v, out):
    """``out`` (3,) ← ``[u, v] = u × v``."""
    c = cross3(u[0], u[1], u[2], v[0], v[1], v[2])
    out[0] = c[0]
    out[1] = c[1]
    out[2] = c[2]


@njit(cache=True, inline='always')
def so3_exp_point(w, out):
    """``out`` (3, 3) ← ``exp(ŵ) = I + A K + B K²`` for ``w`` (3,)."""
    x, y, z = w[0], w[1], w[2]
    a, b = so3_exp_coeffs(x * x + y * y + z * z)
    so3_poly_point(x, y, z, a, b, 1.0, out)


@njit(cache=True, inline='always')
def so3_log_point(R, out):
    """``out`` (3,) ← principal logarithm ``w`` of ``R`` (3, 3), ``|w| ≤ π``."""
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    qw, qx, qy, qz = quat_of_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22)
    s = np.sqrt(qx * qx + qy * qy + qz * qz)
    if s <= LOG_SMALL_RATIO * qw:
        f = _log_factor_series(s, qw)
    else:
        f = _log_factor_direct(s, qw)
    out[0] = f * qx
    out[1] = f * qy
    out[2] = f * qz


@njit(cache=True, inline='always')
def so3_dexp_point(w, out):
    """``out`` (3, 3) ← ``dexp(w) = J(w) = I + B K + C K²``."""
    x, y, z = w[0], w[1], w[2]
    b, c = so3_dexp_coeffs(x * x + y * y + z * z)
    so3_poly_point(x, y, z, b, c, 1.0, out)


@njit(cache=True, inline='always')
def so3_dexp_inv_point(w, out):
    """``out`` (3, 3) ← ``dexp(w)⁻¹ = I − ½K + c K²``."""
    x, y, z = w[0], w[1], w[2]
    c = so3_dexp_inv_coeff(x * x + y * y + z * z)
    so3_poly_point(x, y, z, -0.5, c, 1.0, out)


@njit(cache=True, inline='always')
def so3_E_point(dt, w, out):
    """``out`` (3, 3) ← ``𝓔(Δt, w) = Δt·dexp(Δt w)`` for scalar ``dt``."""
    x, y, z = dt * w[0], dt * w[1], dt * w[2]
    b, c = so3_dexp_coeffs(x * x + y * y + z * z)
    so3_poly_point(x, y, z, b, c, dt, out)


@njit(cache=True, inline='always')
def so3_axis_flow_point(k, t, s, acc, work):
    """The free flow about one basis axis: ``E = exp(t b_k)``, ``s ← Ad_Eᵀ s = Eᵀ s`` and
    ``acc ← acc E``, for ``s`` (3,) and ``acc`` (3, 3) in place (``k`` in 0..2, ``t`` the angle),
    without the matrix.  ``E`` turns the plane ``(e_p, e_q)``, ``p = k + 1``, ``q = k + 2``
    (mod 3), by cosine ``1 − Bt²`` and sine ``At`` (:func:`so3_exp_coeffs`, the entries of
    :func:`so3_exp_point` at ``w = t e_k``); ``work`` is unused (the scratch of the generic
    form, ``cartan.compiled.kernels.FUSED_OPS["axis_flow"]``)."""
    a, b = so3_exp_coeffs(t * t)
    c, sn = 1.0 - b * (t * t), a * t
    p = k + 1 if k < 2 else 0
    q = k + 2 if k < 1 else k - 1
    x, y = s[p], s[q]
    s[p], s[q] = c * x + sn * y, c * y - sn * x
    for i in range(3):
        x, y = acc[i, p], acc[i, q]
        acc[i, p], acc[i, q] = c * x + sn * y, c * y - sn * x


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(w, out):
    for p in range(w.shape[0]):
        so3_hat_point(w[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        so3_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        so3_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        so3_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        so3_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(w, out):
    for p in range(w.shape[0]):
        so3_exp_point(w[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        so3_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        so3_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(w, out):
    for p in range(w.shape[0]):
        so3_ad_point(w[p], out[p])


@njit(cache=True)
def _bracket_batch(u, v, out):
    for p in range(u.shape[0]):
        so3_bracket_point(u[p], v[p], out[p])


@njit(cache=True)
def _dexp_batch(w, out):
    for p in range(w.shape[0]):
        so3_dexp_point(w[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(w, out):
    for p in range(w.shape[0]):
        so3_dexp_inv_point(w[p], out[p])


@njit(cache=True)
def _E_batch(dt, w, out):
    for p in range(w.shape[0]):
        so3_E_point(dt[p], w[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def exp_coeffs_np(t2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`so3_exp_coeffs`: ``(A, B)`` for ``t2 = θ²`` of any shape."""
    small = t2 < SMALL_THETA2
    safe = np.where(small, 1.0, t2)
    a_s, b_s = _exp_coeffs_series(t2)
    a_d, b_d = _exp_coeffs_direct(safe)
    return np.where(small, a_s, a_d), np.where(small, b_s, b_d)


def dexp_coeffs_np(t2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised :func:`so3_dexp_coeffs`: ``(B, C)`` for ``t2 = θ²``."""
    small = t2 < SMALL_THETA2
    safe = np.where(small, 1.0, t2)
    b = np.where(small, horner(t2, TAYLOR_B), _exp_coeffs_direct(safe)[1])
    c = np.where(small, horner(t2, TAYLOR_C), _C_direct(safe))
    return b, c


def dexp_inv_coeff_np(t2: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so3_dexp_inv_coeff`: ``c`` for ``t2 = θ²``."""
    small = t2 < SMALL_THETA2
    safe = np.where(small, 1.0, t2)
    return np.where(small, horner(t2, TAYLOR_CINV), _cinv_direct(safe))


def poly_np(x, y, z, a, b, s) -> np.ndarray:
    """Vectorised :func:`so3_poly_point`: ``s (I + a K + b K²)``, shape ``[..., 3, 3]``."""
    e = np.broadcast_arrays(*_poly_entries(x, y, z, a, b, s))
    return np.stack(e, axis=-1).reshape(*e[0].shape, 3, 3)


def hat_np(w: np.ndarray) -> np.ndarray:
    """``ŵ`` for ``w`` ``[..., 3]`` → ``[..., 3, 3]``."""
    out = np.zeros((*w.shape[:-1], 3, 3))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def vee_np(A: np.ndarray) -> np.ndarray:
    """``½(A32 − A23, A13 − A31, A21 − A12)`` for ``A`` ``[..., 3, 3]`` → ``[..., 3]``."""
    return 0.5 * np.stack(
        [A[..., 2, 1] - A[..., 1, 2], A[..., 0, 2] - A[..., 2, 0], A[..., 1, 0] - A[..., 0, 1]],
        axis=-1,
    )


def matmul3_np(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` of broadcast ``[..., 3, 3]`` arrays, summed in the kernels' order."""
    return (A[..., :, 0:1] * B[..., 0:1, :] + A[..., :, 1:2] * B[..., 1:2, :]
            + A[..., :, 2:3] * B[..., 2:3, :])


def matvec3_np(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for ``A`` ``[..., 3, 3]`` and ``x`` ``[..., 3]``, summed in the kernels' order."""
    return (A[..., :, 0] * x[..., None, 0] + A[..., :, 1] * x[..., None, 1]
            + A[..., :, 2] * x[..., None, 2])


def cross_np(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u × v`` of broadcast ``[..., 3]`` arrays, same arithmetic as :func:`cross3`."""
    return np.stack(cross3(u[..., 0], u[..., 1], u[..., 2], v[..., 0], v[..., 1], v[..., 2]), axis=-1)


def log_np(R: np.ndarray) -> np.ndarray:
    """Vectorised :func:`so3_log_point`: ``[..., 3, 3]`` → ``[..., 3]``."""
    lead = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    r = [[R[:, i, j] for j in range(3)] for i in range(3)]
    flat = (r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2])
    case = np.argmax(np.stack([r[0][0] + r[1][1] + r[2][2], r[0][0], r[1][1], r[2][2]]), axis=0)
    q = np.zeros((4, R.shape[0]))
    for k in range(4):
        sel = case == k
        q[:, sel] = np.stack(_quat_from_matrix(*(e[sel] for e in flat), k))
    q *= np.where(q[0] < 0.0, -1.0, 1.0)
    qw = q[0]
    s = np.sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    small = s <= LOG_SMALL_RATIO * qw
    f = np.where(
        small,
        _log_factor_series(s, np.where(small, qw, 1.0)),
        _log_factor_direct(np.where(small, 1.0, s), qw),
    )
    return np.moveaxis(f * q[1:], 0, -1).reshape(*lead, 3)


# ---------------------------------------------------------------------- the group
class SO3(SymmetryGroup):
    """Rotations of R³: ``R ∈ R^{3×3}``, ``RᵀR = I``, ``det R = 1``; algebra so(3) ≅ R³.

    Algebra components ``w`` ``[..., 3]`` map to ``ŵ`` by the paper's hat map (Appendix
    "Vector and matrix operations").  All operations are closed-form; see the module
    docstring for the formulas and their small-angle treatment.
    """

    name = "SO3"
    dim = 3
    matrix_size = 3
    _kernels = kernel_table(globals())
    _point_prefix = "so3"

    def basis(self) -> np.ndarray:
        """Generators ``b_i = ê_i``, shape ``(3, 3, 3)``."""
        return hat_np(np.eye(3))

    def defect(self, g) -> np.ndarray:
        """Orthogonality defect ``‖gᵀg − I‖_F``.

        Parameters
        ----------
        g : array_like, shape ``[..., 3, 3]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        g = self._element(g)
        return np.linalg.norm(np.swapaxes(g, -1, -2) @ g - np.eye(3), axis=(-2, -1))

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        return hat_np(xi)

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return vee_np(A)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return matmul3_np(g, h)

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        return np.swapaxes(g, -1, -2).copy()

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return matvec3_np(g, x)

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        x, y, z = xi[..., 0], xi[..., 1], xi[..., 2]
        a, b = exp_coeffs_np(x * x + y * y + z * z)
        return poly_np(x, y, z, a, b, 1.0)

    def _log(self, g: np.ndarray) -> np.ndarray:
        return log_np(g)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        return g.copy()

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        return hat_np(xi)

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        return cross_np(xi, eta)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        x, y, z = xi[..., 0], xi[..., 1], xi[..., 2]
        b, c = dexp_coeffs_np(x * x + y * y + z * z)
        return poly_np(x, y, z, b, c, 1.0)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        x, y, z = xi[..., 0], xi[..., 1], xi[..., 2]
        c = dexp_inv_coeff_np(x * x + y * y + z * z)
        return poly_np(x, y, z, -0.5, c, 1.0)

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        x, y, z = dt * Y[..., 0], dt * Y[..., 1], dt * Y[..., 2]
        b, c = dexp_coeffs_np(x * x + y * y + z * z)
        return poly_np(x, y, z, b, c, dt)
