"""Scalar SO(3)/SE(3) kernels of the structure-of-arrays SE(3) rod loops.

The loops live in :mod:`cartan.schemes._lattice_compiled_soa` (the dispatch in
:mod:`cartan.schemes._lattice_compiled`); here are the chunking of the grid, the SO(3)/SE(3)
coefficients and the scalar algebra those loops inline.

* **What is left here.**  The SE(3) arithmetic of the loops (the branch-free logarithm,
  ``dexp⁻¹(ξ)ᵀQ``, ``Ad_Gᵀ``, the products and the free flow's plane turns) is the scalar
  kernels of :mod:`cartan.groups.se3`, shared with the group's passes; here are the closed-form
  logarithm of an element turning by θ ≥ 0.1 (:func:`_se3_log12`, ``atan(x)/x`` from its series
  below x = 1/20), the SE(3) exponential's coefficients (four Taylor terms below θ² = 10⁻⁴), the
  quadratic stress of an edge and the chunks' partial sums.
* **IEEE division** (``error_model="numpy"``: inf/nan like the reference path, no
  zero-divisor test) in every kernel; small helpers are inlined in numba's IR
  (``inline="always"``) and take and return scalars where they sit in loops meant to be
  fast.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..groups.se3 import (
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
    _log_factor_direct,
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
_A4, _B4, _C4, _CINV4 = (c[-4:] for c in (TAYLOR_A, TAYLOR_B, TAYLOR_C, TAYLOR_CINV))
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
def _exp3_coeffs(t2):
    """``se3_exp_coeffs``: ``(A, B, C)``, ``C = (θ − sin θ)/θ³``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _A4), horner(t2, _B4), horner(t2, _C4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)
    return _exp_coeffs3_direct(t2)


# ---------------------------------------------------------------------------- SO(3)/SE(3) scalar algebra


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

