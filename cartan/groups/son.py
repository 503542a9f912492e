"""The rotation group SO(n) for any n ≥ 2.

Basis of so(n)
--------------
Write ``i < j`` (0-based) for a coordinate plane and ``E_ab = e_a e_bᵀ``.  The generator of
that plane is

    ``b_(i,j) = s_ij (E_ji − E_ij)``,   ``s_ij = (−1)^(i+j+1)``

(the checkerboard, cofactor-like sign; it does not change when the indices are counted from
1), and the planes are ordered by ``j`` descending, then ``i`` descending::

    (n−2, n−1), (n−3, n−1), ..., (0, n−1),  (n−3, n−2), ..., (0, n−2),  ...,  (0, 1)

* The first ``n − 1`` generators are the ones that move the last basis vector ``e_(n−1)``
  (the reference point of the sphere S^(n−1) in the sigma model, paper §VIII.B):
  ``hat(ξ) e_(n−1) = Σ_(i<n−1) (−1)^(i+n+1) ξ_(n−2−i) e_i``; the remaining
  ``(n−1)(n−2)/2`` are the so(n−1) basis of the first ``n − 1`` coordinates, recursively.
  Hence ``|hat(ξ) e_(n−1)|² = Σ_(k<n−1) ξ_k²``: the sigma model's operator A is
  ``diag(1, ..., 1, 0, ..., 0)`` with ``n − 1`` ones.
* n = 2 gives ``hat(θ) = [[0, −θ], [θ, 0]]`` (:class:`~cartan.groups.so2.SO2`) and n = 3
  gives the paper's so(3) hat map ``[[0, −v3, v2], [v3, 0, −v1], [−v2, v1, 0]]``
  (:class:`~cartan.groups.so3.SO3`): component ``k`` is the rotation in the plane ``(i, j)``
  with ``(i, j, k)`` cyclic.
* ``vee`` is the least-squares inverse ``ξ_k = s_k ½(A_ji − A_ij)``.  The basis is orthogonal
  for the trace form, so ``ad_ξ`` is a real skew matrix in components.

Operations
----------
* ``Ad_g`` is the second compound matrix, ``(Ad_g)_kl = s_k s_l (g_(i_k i_l) g_(j_k j_l) −
  g_(i_k j_l) g_(j_k i_l))`` (closed form for every n), ``ad_ξ`` its derivative and
  ``[ξ, η] = vee(ξ̂η̂ − η̂ξ̂)``.
* n = 2 and n = 3 delegate every operation (numpy and numba) to ``SO2`` and ``SO3``.
* n = 4 uses the isoclinic splitting so(4) = so(3) ⊕ so(3): with ``R⁴ ≅ H`` by
  ``x ↦ x₃ + x₀i + x₁j + x₂k``, ``hat(ξ) x = u x + x w`` for pure quaternions ``u, w``
  (``(u; w) = Cᵀξ/2`` with a constant ``6 × 6`` matrix ``C``, ``CᵀC = 2I``).  Then
  ``exp(ξ) x = p x q`` with ``p = e^u``, ``q = e^w`` (two quaternion exponentials); the log
  recovers ``p ⊗ q`` linearly from the matrix, ``p`` from its largest column, and picks the
  sign of ``(p, q)`` with ``p_w + q_w ≥ 0``, i.e. rotation angles ``|u| + |w|`` and
  ``||u| − |w||`` at most π; ``ad`` is ``2û ⊕ (−2ŵ)``, so ``dexp = C diag(J(2u), J(−2w))Cᵀ/2``
  with the SO(3) left Jacobian ``J`` (and the same for ``dexp⁻¹``).
* n ≥ 5: the SO(3) formulas generalised.  For a real skew ``K`` (``hat(ξ)`` or ``ad_ξ``) an
  even function ``f`` of its rotation angles is ``f(Θ) = V diag(f(θ)) Vᵀ``, from the
  symmetric eigendecomposition ``−K² = V diag(θ²) Vᵀ`` (repeated angles need no care).  Then
  ``exp = I + X A(Θ) + X² B(Θ)`` (``X = hat(ξ)``), ``dexp = I + ad B(Θ) + ad² C(Θ)`` and
  ``dexp⁻¹ = I − ½ ad + ad² c(Θ)`` with the coefficients ``A, B, C, c`` of
  :mod:`cartan.groups.so3` (Taylor series at small angles), so the results keep their
  relative accuracy as θ → 0.  ``log`` returns, when every rotation angle is at most π/3,
  ``K f(Θ)`` with ``K = (R − Rᵀ)/2`` and ``f = arcsin(sin θ)/sin θ`` (accurate as θ → 0),
  and otherwise uses the real Schur form ``R = Z T Zᵀ``, reading each 2 × 2 block's angle with
  ``atan2`` (accurate up to θ → π; an exact −1 eigenvalue pair is given the angle π).  These
  run on the numpy path under both backends.
* :meth:`SO.log_domain_norm` is the largest rotation angle, the spectral norm of
  ``hat(ξ)``; ``log ∘ exp`` is the identity when it is below π.

Kernels
-------
``hat``, ``vee``, ``compose``, ``inverse``, ``act``, ``Ad``, ``ad`` and ``bracket`` have numba
kernels for every n (``son_*_point`` take the index tables of :func:`son_tables`); n = 4 adds
``so4_exp_point``, ``so4_log_point``, ``so4_dexp_point``, ``so4_dexp_inv_point`` and
``so4_E_point``.  For n ≥ 5, ``exp``, ``log``, ``dexp``, ``dexp_inv`` and ``E`` use the numpy
path under both backends.
"""

from __future__ import annotations

import numbers

import numpy as np
import scipy.linalg
from numba import njit
from numba.extending import register_jitable

from .base import SymmetryGroup
from .so2 import SO2, rotation_defect
from .so3 import (
    SO3,
    dexp_coeffs_np,
    dexp_inv_coeff_np,
    exp_coeffs_np,
    so3_dexp_coeffs,
    so3_dexp_inv_coeff,
    so3_exp_coeffs,
)

__all__ = [
    "SO",
    "son_Ad_point",
    "son_act_point",
    "son_ad_point",
    "son_bracket_point",
    "son_compose_point",
    "son_hat_point",
    "son_inverse_point",
    "son_tables",
    "son_vee_point",
    "so4_E_point",
    "so4_dexp_inv_point",
    "so4_dexp_point",
    "so4_exp_point",
    "so4_log_point",
]


# ---------------------------------------------------------------------- basis tables
@njit(cache=True)
def son_tables(n):
    """Index tables of the so(n) basis.

    Parameters
    ----------
    n : int
        Matrix size, ``n ≥ 2``.

    Returns
    -------
    I, J : numpy.ndarray of int64, shape ``(r,)``
        The plane ``(I[k], J[k])``, ``I[k] < J[k]``, of generator ``k``.
    S : numpy.ndarray, shape ``(r,)``
        Its sign ``(−1)^(I+J+1)``: ``b_k = S[k] (E_JI − E_IJ)``.
    PK : numpy.ndarray of int64, shape ``(n, n)``
        ``PK[a, b]`` is the generator of the plane ``{a, b}`` (0 on the diagonal).
    PS : numpy.ndarray, shape ``(n, n)``
        ``hat(ξ)[a, b] = PS[a, b] ξ[PK[a, b]]`` (``PS`` is 0 on the diagonal).
    """
    r = n * (n - 1) // 2
    I = np.empty(r, np.int64)
    J = np.empty(r, np.int64)
    S = np.empty(r)
    PK = np.zeros((n, n), np.int64)
    PS = np.zeros((n, n))
    k = 0
    for j in range(n - 1, 0, -1):
        for i in range(j - 1, -1, -1):
            s = 1.0 if (i + j + 1) % 2 == 0 else -1.0
            I[k] = i
            J[k] = j
            S[k] = s
            PK[j, i] = k
            PK[i, j] = k
            PS[j, i] = s
            PS[i, j] = -s
            k += 1
    return I, J, S, PK, PS


# ---------------------------------------------------------------------- any n: numba kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def son_hat_point(xi, I, J, S, out):
    """``out`` (n, n) ← ``hat(ξ)`` for ``xi`` (r,) and the tables of :func:`son_tables`."""
    out[:, :] = 0.0
    for k in range(xi.shape[0]):
        out[J[k], I[k]] = S[k] * xi[k]
        out[I[k], J[k]] = -S[k] * xi[k]


@njit(cache=True, inline='always')
def son_vee_point(A, I, J, S, out):
    """``out`` (r,) ← ``S_k ½(A_JI − A_IJ)`` for ``A`` (n, n)."""
    for k in range(out.shape[0]):
        out[k] = S[k] * (0.5 * (A[J[k], I[k]] - A[I[k], J[k]]))


@njit(cache=True, inline='always')
def son_compose_point(g, h, out):
    """``out`` (n, n) ← ``g h``; ``out`` must not alias the inputs."""
    n = g.shape[0]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for m in range(n):
                acc += g[i, m] * h[m, j]
            out[i, j] = acc


@njit(cache=True, inline='always')
def son_inverse_point(g, out):
    """``out`` (n, n) ← ``gᵀ``; ``out`` must not alias ``g``."""
    n = g.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = g[j, i]


@njit(cache=True, inline='always')
def son_act_point(g, x, out):
    """``out`` (n,) ← ``g x``."""
    n = g.shape[0]
    for i in range(n):
        acc = 0.0
        for m in range(n):
            acc += g[i, m] * x[m]
        out[i] = acc


@njit(cache=True, inline='always')
def son_Ad_point(g, I, J, S, out):
    """``out`` (r, r) ← ``Ad_g``, the second compound matrix of ``g`` (n, n) in the basis."""
    r = out.shape[0]
    for k in range(r):
        ik, jk = I[k], J[k]
        for m in range(r):
            il, jl = I[m], J[m]
            out[k, m] = (S[k] * S[m]) * (g[ik, il] * g[jk, jl] - g[ik, jl] * g[jk, il])


@njit(cache=True, inline='always')
def son_ad_point(xi, I, J, S, PK, PS, out):
    """``out`` (r, r) ← ``ad_ξ`` for ``xi`` (r,) (each entry is ``±ξ_m`` or 0)."""
    r = out.shape[0]
    for k in range(r):
        ik, jk = I[k], J[k]
        for m in range(r):
            il, jl = I[m], J[m]
            v = 0.0
            if jk == jl:
                v += PS[ik, il] * xi[PK[ik, il]]
            if ik == il:
                v += PS[jk, jl] * xi[PK[jk, jl]]
            if jk == il:
                v -= PS[ik, jl] * xi[PK[ik, jl]]
            if ik == jl:
                v -= PS[jk, il] * xi[PK[jk, il]]
            out[k, m] = (S[k] * S[m]) * v


@njit(cache=True, inline='always')
def son_bracket_point(xi, eta, I, J, S, PK, PS, out):
    """``out`` (r,) ← ``[ξ, η] = vee(ξ̂η̂ − η̂ξ̂)``."""
    n = PK.shape[0]
    for k in range(out.shape[0]):
        a, b = J[k], I[k]
        z_ab = 0.0
        z_ba = 0.0
        for c in range(n):
            xac = PS[a, c] * xi[PK[a, c]]
            yac = PS[a, c] * eta[PK[a, c]]
            xbc = PS[b, c] * xi[PK[b, c]]
            ybc = PS[b, c] * eta[PK[b, c]]
            xcb = PS[c, b] * xi[PK[c, b]]
            ycb = PS[c, b] * eta[PK[c, b]]
            xca = PS[c, a] * xi[PK[c, a]]
            yca = PS[c, a] * eta[PK[c, a]]
            z_ab += xac * ycb - yac * xcb
            z_ba += xbc * yca - ybc * xca
        out[k] = S[k] * (0.5 * (z_ab - z_ba))


@njit(cache=True)
def _hat_batch(xi, out):
    I, J, S, _, _ = son_tables(out.shape[1])
    for p in range(xi.shape[0]):
        son_hat_point(xi[p], I, J, S, out[p])


@njit(cache=True)
def _vee_batch(A, out):
    I, J, S, _, _ = son_tables(A.shape[1])
    for p in range(A.shape[0]):
        son_vee_point(A[p], I, J, S, out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        son_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        son_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        son_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    I, J, S, _, _ = son_tables(g.shape[1])
    for p in range(g.shape[0]):
        son_Ad_point(g[p], I, J, S, out[p])


@register_jitable(inline='always')
def _n_of_dim(r):
    """The n with ``n(n−1)/2 = r``."""
    n = 2
    while n * (n - 1) // 2 < r:
        n += 1
    return n


@njit(cache=True)
def _ad_batch(xi, out):
    I, J, S, PK, PS = son_tables(_n_of_dim(xi.shape[1]))
    for p in range(xi.shape[0]):
        son_ad_point(xi[p], I, J, S, PK, PS, out[p])


@njit(cache=True)
def _bracket_batch(xi, eta, out):
    I, J, S, PK, PS = son_tables(_n_of_dim(xi.shape[1]))
    for p in range(xi.shape[0]):
        son_bracket_point(xi[p], eta[p], I, J, S, PK, PS, out[p])


# ---------------------------------------------------------------------- n = 4: quaternion tables
def _qmul(a, b):
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return np.array([
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    ])


def _quaternion_tables():
    """Sparse tables of the maps ``(p, q) ↦ (x ↦ p x q)`` and ``ξ ↔ (u; w)`` for n = 4."""
    to_q = np.array([3, 0, 1, 2])  # quaternion component c is the R⁴ coordinate to_q[c]
    unit = np.eye(4)
    # T[a, b, c, d]: entry (a, b) of the matrix of x ↦ e_c x e_d
    T = np.zeros((4, 4, 4, 4))
    for c in range(4):
        for d in range(4):
            for b in range(4):
                col = _qmul(_qmul(unit[c], unit[np.flatnonzero(to_q == b)[0]]), unit[d])
                T[to_q, b, c, d] = col
    # each matrix entry is a sum of four ±p_c q_d, and each p_c q_d of four ±R_ab
    exp_tab = np.zeros((4, 4, 4, 3), np.int64)
    log_tab = np.zeros((4, 4, 4, 3), np.int64)
    for a in range(4):
        for b in range(4):
            cs, ds = np.nonzero(T[a, b])
            exp_tab[a, b] = np.stack([cs, ds, T[a, b, cs, ds].astype(np.int64)], axis=-1)
    for c in range(4):
        for d in range(4):
            As, bs = np.nonzero(T[:, :, c, d])
            log_tab[c, d] = np.stack([As, bs, T[As, bs, c, d].astype(np.int64)], axis=-1)
    I, J, S, _, _ = son_tables(4)
    C = np.zeros((6, 6))
    for a in range(3):
        for col, mat in ((a, T[:, :, a + 1, 0]), (3 + a, T[:, :, 0, a + 1])):
            C[:, col] = S * 0.5 * (mat[J, I] - mat[I, J])
    # rows: ξ_i = su_i u[au_i] + sw_i w[aw_i]; columns: u_a = ½ Σ_m us[a, m] ξ[ur[a, m]]
    au = np.argmax(np.abs(C[:, :3]), axis=1)
    aw = np.argmax(np.abs(C[:, 3:]), axis=1)
    su = C[np.arange(6), au]
    sw = C[np.arange(6), 3 + aw]
    ur = np.array([np.flatnonzero(C[:, a]) for a in range(3)])
    wr = np.array([np.flatnonzero(C[:, 3 + a]) for a in range(3)])
    us = np.array([C[ur[a], a] for a in range(3)])
    ws = np.array([C[wr[a], 3 + a] for a in range(3)])
    return T, C, exp_tab, log_tab, au, su, aw, sw, ur, us, wr, ws


(_Q_T, _Q_C, _Q_EXP, _Q_LOG, _Q_AU, _Q_SU, _Q_AW, _Q_SW,
 _Q_UR, _Q_US, _Q_WR, _Q_WS) = _quaternion_tables()

#: |p_v| ≤ _QLOG_SMALL·p_w selects the series for atan2(|p_v|, p_w)/|p_v|.
_QLOG_SMALL = 1e-4


# ---------------------------------------------------------------------- n = 4: shared arithmetic
@register_jitable(inline='always')
def _poly3(x, y, z, a, b):
    """Entries (row-major) of ``I + a K + b K²``, ``K = hat(x, y, z)`` (the so(3) hat)."""
    xy = x * y
    xz = x * z
    yz = y * z
    return (
        1.0 - b * (y * y + z * z), b * xy - a * z, b * xz + a * y,
        b * xy + a * z, 1.0 - b * (x * x + z * z), b * yz - a * x,
        b * xz - a * y, b * yz + a * x, 1.0 - b * (x * x + y * y),
    )


@register_jitable(inline='always')
def _qlog_factor_series(s, c):
    x = s / c
    x2 = x * x
    return (1.0 / c) * (1.0 + x2 * (-1.0 / 3.0 + x2 * (1.0 / 5.0)))


@register_jitable(inline='always')
def _qlog_factor_direct(s, c):
    return np.arctan2(s, c) / s


# ---------------------------------------------------------------------- n = 4: numba kernels
@njit(cache=True, inline='always')
def _so4_uw(x0, x1, x2, x3, x4, x5):
    """``(u; w) = Cᵀξ/2`` as a 6-tuple."""
    return (0.5 * (x3 - x2), 0.5 * (x1 + x4), 0.5 * (x5 - x0),
            0.5 * (-x2 - x3), 0.5 * (x1 - x4), 0.5 * (-x0 - x5))


@register_jitable(inline='always')
def _so4_xi_out(u0, u1, u2, w0, w1, w2, out):
    """``out`` (6,) ← ``C (u; w)``: the so(4) components of the pair of pure quaternions."""
    out[0] = -u2 - w2
    out[1] = u1 + w1
    out[2] = -u0 - w0
    out[3] = u0 - w0
    out[4] = u1 - w1
    out[5] = u2 - w2


@njit(cache=True, inline='always')
def _qexp(x, y, z):
    t2 = x * x + y * y + z * z
    a = so3_exp_coeffs(t2)[0]
    return (np.cos(np.sqrt(t2)), a * x, a * y, a * z)


@njit(cache=True, inline='always')
def _qlog(q0, q1, q2, q3):
    s = np.sqrt(q1 * q1 + q2 * q2 + q3 * q3)
    if s == 0.0:
        return (np.arctan2(0.0, q0), 0.0, 0.0)
    if s <= _QLOG_SMALL * q0:
        f = _qlog_factor_series(s, q0)
    else:
        f = _qlog_factor_direct(s, q0)
    return (f * q1, f * q2, f * q3)


@njit(cache=True, inline='always')
def so4_exp_point(xi, out):
    """``out`` (4, 4) ← ``exp(hat(ξ))``: the matrix of ``x ↦ e^u x e^w`` for ``xi`` (6,)."""
    uw = _so4_uw(xi[0], xi[1], xi[2], xi[3], xi[4], xi[5])
    p0, p1, p2, p3 = _qexp(uw[0], uw[1], uw[2])
    q0, q1, q2, q3 = _qexp(uw[3], uw[4], uw[5])
    out[0, 0] = p0 * q0 - p1 * q1 + p2 * q2 + p3 * q3
    out[0, 1] = p0 * q3 - p1 * q2 - p2 * q1 - p3 * q0
    out[0, 2] = -p0 * q2 - p1 * q3 + p2 * q0 - p3 * q1
    out[0, 3] = p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2
    out[1, 0] = -p0 * q3 - p1 * q2 - p2 * q1 + p3 * q0
    out[1, 1] = p0 * q0 + p1 * q1 - p2 * q2 + p3 * q3
    out[1, 2] = p0 * q1 - p1 * q0 - p2 * q3 - p3 * q2
    out[1, 3] = p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1
    out[2, 0] = p0 * q2 - p1 * q3 - p2 * q0 - p3 * q1
    out[2, 1] = -p0 * q1 + p1 * q0 - p2 * q3 - p3 * q2
    out[2, 2] = p0 * q0 + p1 * q1 + p2 * q2 - p3 * q3
    out[2, 3] = p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0
    out[3, 0] = -p0 * q1 - p1 * q0 + p2 * q3 - p3 * q2
    out[3, 1] = -p0 * q2 - p1 * q3 - p2 * q0 + p3 * q1
    out[3, 2] = -p0 * q3 + p1 * q2 - p2 * q1 - p3 * q0
    out[3, 3] = p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3


@njit(cache=True, inline='always')
def so4_log_point(R, out):
    """``out`` (6,) ← the principal logarithm of ``R`` (4, 4)."""
    # A[c, d] = p_c q_d, each a quarter of a signed sum of four entries of R
    a00 = 0.25 * (R[0, 0] + R[1, 1] + R[2, 2] + R[3, 3])
    a01 = 0.25 * (R[0, 3] + R[1, 2] - R[2, 1] - R[3, 0])
    a02 = 0.25 * (-R[0, 2] + R[1, 3] + R[2, 0] - R[3, 1])
    a03 = 0.25 * (R[0, 1] - R[1, 0] + R[2, 3] - R[3, 2])
    a10 = 0.25 * (R[0, 3] - R[1, 2] + R[2, 1] - R[3, 0])
    a11 = 0.25 * (-R[0, 0] + R[1, 1] + R[2, 2] - R[3, 3])
    a12 = 0.25 * (-R[0, 1] - R[1, 0] + R[2, 3] + R[3, 2])
    a13 = 0.25 * (-R[0, 2] - R[1, 3] - R[2, 0] - R[3, 1])
    a20 = 0.25 * (R[0, 2] + R[1, 3] - R[2, 0] - R[3, 1])
    a21 = 0.25 * (-R[0, 1] - R[1, 0] - R[2, 3] - R[3, 2])
    a22 = 0.25 * (R[0, 0] - R[1, 1] + R[2, 2] - R[3, 3])
    a23 = 0.25 * (R[0, 3] - R[1, 2] - R[2, 1] + R[3, 0])
    a30 = 0.25 * (-R[0, 1] + R[1, 0] + R[2, 3] - R[3, 2])
    a31 = 0.25 * (-R[0, 2] + R[1, 3] - R[2, 0] + R[3, 1])
    a32 = 0.25 * (-R[0, 3] - R[1, 2] - R[2, 1] - R[3, 0])
    a33 = 0.25 * (R[0, 0] + R[1, 1] - R[2, 2] - R[3, 3])
    # p from the largest column of A
    best = a00 * a00 + a10 * a10 + a20 * a20 + a30 * a30
    p0, p1, p2, p3 = a00, a10, a20, a30
    nd = a01 * a01 + a11 * a11 + a21 * a21 + a31 * a31
    if nd > best:
        best = nd
        p0, p1, p2, p3 = a01, a11, a21, a31
    nd = a02 * a02 + a12 * a12 + a22 * a22 + a32 * a32
    if nd > best:
        best = nd
        p0, p1, p2, p3 = a02, a12, a22, a32
    nd = a03 * a03 + a13 * a13 + a23 * a23 + a33 * a33
    if nd > best:
        best = nd
        p0, p1, p2, p3 = a03, a13, a23, a33
    nrm = np.sqrt(best)
    p0, p1, p2, p3 = p0 / nrm, p1 / nrm, p2 / nrm, p3 / nrm
    q0 = a00 * p0 + a10 * p1 + a20 * p2 + a30 * p3
    q1 = a01 * p0 + a11 * p1 + a21 * p2 + a31 * p3
    q2 = a02 * p0 + a12 * p1 + a22 * p2 + a32 * p3
    q3 = a03 * p0 + a13 * p1 + a23 * p2 + a33 * p3
    nq = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0, q1, q2, q3 = q0 / nq, q1 / nq, q2 / nq, q3 / nq
    # principal branch: half-angles α + β ≤ π.  (p₀ + q₀ has the right sign but is second-order
    # small at a double rotation by ≈ π, where rounding would pick the branch; atan2 is not.)
    alpha = np.arctan2(np.sqrt(p1 * p1 + p2 * p2 + p3 * p3), p0)
    beta = np.arctan2(np.sqrt(q1 * q1 + q2 * q2 + q3 * q3), q0)
    if alpha + beta > np.pi:
        p0, p1, p2, p3 = -p0, -p1, -p2, -p3
        q0, q1, q2, q3 = -q0, -q1, -q2, -q3
    u0, u1, u2 = _qlog(p0, p1, p2, p3)
    w0, w1, w2 = _qlog(q0, q1, q2, q3)
    _so4_xi_out(u0, u1, u2, w0, w1, w2, out)


@njit(cache=True, inline='always')
def _so4_blocks(xi, inverse, s, out):
    """``out`` (6, 6) ← ``s·C diag(F(2u), F(−2w)) Cᵀ/2``, ``F`` = dexp or dexp⁻¹ of so(3)."""
    uw = _so4_uw(s * xi[0], s * xi[1], s * xi[2], s * xi[3], s * xi[4], s * xi[5])
    x, y, z = 2.0 * uw[0], 2.0 * uw[1], 2.0 * uw[2]
    t2 = x * x + y * y + z * z
    if inverse:
        ju = _poly3(x, y, z, -0.5, so3_dexp_inv_coeff(t2))
    else:
        b, c = so3_dexp_coeffs(t2)
        ju = _poly3(x, y, z, b, c)
    x, y, z = -2.0 * uw[3], -2.0 * uw[4], -2.0 * uw[5]
    t2 = x * x + y * y + z * z
    if inverse:
        jw = _poly3(x, y, z, -0.5, so3_dexp_inv_coeff(t2))
    else:
        b, c = so3_dexp_coeffs(t2)
        jw = _poly3(x, y, z, b, c)
    for i in range(6):
        for j in range(6):
            out[i, j] = s * (0.5 * ((_Q_SU[i] * _Q_SU[j]) * ju[3 * _Q_AU[i] + _Q_AU[j]]
                                    + (_Q_SW[i] * _Q_SW[j]) * jw[3 * _Q_AW[i] + _Q_AW[j]]))


@njit(cache=True, inline='always')
def so4_dexp_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ) = C diag(J(2u), J(−2w)) Cᵀ/2``."""
    _so4_blocks(xi, False, 1.0, out)


@njit(cache=True, inline='always')
def so4_dexp_inv_point(xi, out):
    """``out`` (6, 6) ← ``dexp(ξ)⁻¹ = C diag(J⁻¹(2u), J⁻¹(−2w)) Cᵀ/2``."""
    _so4_blocks(xi, True, 1.0, out)


@njit(cache=True, inline='always')
def so4_E_point(dt, xi, out):
    """``out`` (6, 6) ← ``𝓔(Δt, ξ) = Δt·dexp(Δt ξ)`` for scalar ``dt``."""
    _so4_blocks(xi, False, dt, out)


@register_jitable
def _so4_jinv_T_parts(xi, v):
    """The pieces of ``dexp(±ξ)⁻ᵀ v`` on the two so(3) factors: ``(h, ½x × h, c x × (x × h))`` for
    ``x = 2u``, ``h = (Cᵀv/2)_u``, then the same for ``x = −2w``, ``h = (Cᵀv/2)_w``, with ``c`` the
    SO(3) coefficient of ``J⁻¹`` (``dexp(ξ)⁻ᵀ = C diag(J⁻ᵀ(2u), J⁻ᵀ(−2w)) Cᵀ/2``)."""
    uw = _so4_uw(xi[0], xi[1], xi[2], xi[3], xi[4], xi[5])
    hv = _so4_uw(v[0], v[1], v[2], v[3], v[4], v[5])
    x0, x1, x2 = 2.0 * uw[0], 2.0 * uw[1], 2.0 * uw[2]
    cu = so3_dexp_inv_coeff(x0 * x0 + x1 * x1 + x2 * x2)
    h0, h1, h2 = hv[0], hv[1], hv[2]
    s0, s1, s2 = x1 * h2 - x2 * h1, x2 * h0 - x0 * h2, x0 * h1 - x1 * h0
    z0, z1, z2 = x1 * s2 - x2 * s1, x2 * s0 - x0 * s2, x0 * s1 - x1 * s0
    y0, y1, y2 = -2.0 * uw[3], -2.0 * uw[4], -2.0 * uw[5]
    cw = so3_dexp_inv_coeff(y0 * y0 + y1 * y1 + y2 * y2)
    k0, k1, k2 = hv[3], hv[4], hv[5]
    t0, t1, t2 = y1 * k2 - y2 * k1, y2 * k0 - y0 * k2, y0 * k1 - y1 * k0
    r0, r1, r2 = y1 * t2 - y2 * t1, y2 * t0 - y0 * t2, y0 * t1 - y1 * t0
    return (h0 + cu * z0, h1 + cu * z1, h2 + cu * z2, 0.5 * s0, 0.5 * s1, 0.5 * s2,
            k0 + cw * r0, k1 + cw * r1, k2 + cw * r2, 0.5 * t0, 0.5 * t1, 0.5 * t2)


@njit(cache=True, inline='always')
def so4_dexp_inv_T_point(xi, v, out):
    """``out`` (6,) ← ``dexp(ξ)⁻ᵀ v`` without the matrix: ``C diag(J⁻ᵀ(2u), J⁻ᵀ(−2w)) Cᵀv/2``,
    each ``J⁻ᵀ(x)h = h + ½x × h + c x × (x × h)`` (the transpose of :func:`so4_dexp_inv_point`)."""
    e = _so4_jinv_T_parts(xi, v)
    _so4_xi_out(e[0] + e[3], e[1] + e[4], e[2] + e[5], e[6] + e[9], e[7] + e[10], e[8] + e[11], out)


@njit(cache=True, inline='always')
def so4_dexp_inv_T_pair_point(xi, v, out, out_neg):
    """``out`` ← ``dexp(ξ)⁻ᵀ v`` and ``out_neg`` ← ``dexp(−ξ)⁻ᵀ v`` (the odd part changes sign)."""
    e = _so4_jinv_T_parts(xi, v)
    _so4_xi_out(e[0] + e[3], e[1] + e[4], e[2] + e[5], e[6] + e[9], e[7] + e[10], e[8] + e[11], out)
    _so4_xi_out(e[0] - e[3], e[1] - e[4], e[2] - e[5], e[6] - e[9], e[7] - e[10], e[8] - e[11], out_neg)


@njit(cache=True, inline='always')
def so4_compose_point(g, h, out):
    """``out`` (4, 4) ← ``g h``; ``out`` must not alias the inputs."""
    for i in range(4):
        for j in range(4):
            out[i, j] = g[i, 0] * h[0, j] + g[i, 1] * h[1, j] + g[i, 2] * h[2, j] + g[i, 3] * h[3, j]


@njit(cache=True, inline='always')
def so4_inverse_point(g, out):
    """``out`` (4, 4) ← ``gᵀ``; ``out`` must not alias ``g``."""
    for i in range(4):
        for j in range(4):
            out[i, j] = g[j, i]


@njit(cache=True, inline='always')
def so4_Ad_T_point(g, v, out):
    """``out`` (6,) ← ``Ad_gᵀ v = vee(gᵀ v̂ g)`` (``Ad_g`` is orthogonal in the basis of this
    module: ``Ad_gᵀ = Ad_{gᵀ}``), without the matrix."""
    v0, v1, v2, v3, v4, v5 = v[0], v[1], v[2], v[3], v[4], v[5]
    # T = v̂ g
    t00 = -v5 * g[1, 0] + v4 * g[2, 0] - v2 * g[3, 0]
    t01 = -v5 * g[1, 1] + v4 * g[2, 1] - v2 * g[3, 1]
    t02 = -v5 * g[1, 2] + v4 * g[2, 2] - v2 * g[3, 2]
    t03 = -v5 * g[1, 3] + v4 * g[2, 3] - v2 * g[3, 3]
    t10 = v5 * g[0, 0] - v3 * g[2, 0] + v1 * g[3, 0]
    t11 = v5 * g[0, 1] - v3 * g[2, 1] + v1 * g[3, 1]
    t12 = v5 * g[0, 2] - v3 * g[2, 2] + v1 * g[3, 2]
    t13 = v5 * g[0, 3] - v3 * g[2, 3] + v1 * g[3, 3]
    t20 = -v4 * g[0, 0] + v3 * g[1, 0] - v0 * g[3, 0]
    t21 = -v4 * g[0, 1] + v3 * g[1, 1] - v0 * g[3, 1]
    t22 = -v4 * g[0, 2] + v3 * g[1, 2] - v0 * g[3, 2]
    t23 = -v4 * g[0, 3] + v3 * g[1, 3] - v0 * g[3, 3]
    t30 = v2 * g[0, 0] - v1 * g[1, 0] + v0 * g[2, 0]
    t31 = v2 * g[0, 1] - v1 * g[1, 1] + v0 * g[2, 1]
    t32 = v2 * g[0, 2] - v1 * g[1, 2] + v0 * g[2, 2]
    t33 = v2 * g[0, 3] - v1 * g[1, 3] + v0 * g[2, 3]
    # vee(gᵀT), entry (i, j) = column i of g times column j of T
    out[0] = 0.5 * ((g[0, 3] * t02 + g[1, 3] * t12 + g[2, 3] * t22 + g[3, 3] * t32)
                    - (g[0, 2] * t03 + g[1, 2] * t13 + g[2, 2] * t23 + g[3, 2] * t33))
    out[1] = -0.5 * ((g[0, 3] * t01 + g[1, 3] * t11 + g[2, 3] * t21 + g[3, 3] * t31)
                     - (g[0, 1] * t03 + g[1, 1] * t13 + g[2, 1] * t23 + g[3, 1] * t33))
    out[2] = 0.5 * ((g[0, 3] * t00 + g[1, 3] * t10 + g[2, 3] * t20 + g[3, 3] * t30)
                    - (g[0, 0] * t03 + g[1, 0] * t13 + g[2, 0] * t23 + g[3, 0] * t33))
    out[3] = 0.5 * ((g[0, 2] * t01 + g[1, 2] * t11 + g[2, 2] * t21 + g[3, 2] * t31)
                    - (g[0, 1] * t02 + g[1, 1] * t12 + g[2, 1] * t22 + g[3, 1] * t32))
    out[4] = -0.5 * ((g[0, 2] * t00 + g[1, 2] * t10 + g[2, 2] * t20 + g[3, 2] * t30)
                     - (g[0, 0] * t02 + g[1, 0] * t12 + g[2, 0] * t22 + g[3, 0] * t32))
    out[5] = 0.5 * ((g[0, 1] * t00 + g[1, 1] * t10 + g[2, 1] * t20 + g[3, 1] * t30)
                    - (g[0, 0] * t01 + g[1, 0] * t11 + g[2, 0] * t21 + g[3, 0] * t31))


@njit(cache=True)
def _so4_exp_batch(xi, out):
    for p in range(xi.shape[0]):
        so4_exp_point(xi[p], out[p])


@njit(cache=True)
def _so4_log_batch(g, out):
    for p in range(g.shape[0]):
        so4_log_point(g[p], out[p])


@njit(cache=True)
def _so4_dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        so4_dexp_point(xi[p], out[p])


@njit(cache=True)
def _so4_dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        so4_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _so4_E_batch(dt, xi, out):
    for p in range(xi.shape[0]):
        so4_E_point(dt[p], xi[p], out[p])


_GENERIC_KERNELS = {
    "hat": _hat_batch,
    "vee": _vee_batch,
    "compose": _compose_batch,
    "inverse": _inverse_batch,
    "act": _act_batch,
    "Ad": _Ad_batch,
    "ad": _ad_batch,
    "bracket": _bracket_batch,
}
_SO4_KERNELS = {
    **_GENERIC_KERNELS,
    "exp": _so4_exp_batch,
    "log": _so4_log_batch,
    "dexp": _so4_dexp_batch,
    "dexp_inv": _so4_dexp_inv_batch,
    "E": _so4_E_batch,
}


# ---------------------------------------------------------------------- n = 4: numpy
def _so4_uw_np(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u, w)`` ``[..., 3]`` each, with the arithmetic of :func:`_so4_uw`."""
    def half(rows, signs, a):
        return 0.5 * (signs[a, 0] * xi[..., rows[a, 0]] + signs[a, 1] * xi[..., rows[a, 1]])

    u = np.stack([half(_Q_UR, _Q_US, a) for a in range(3)], axis=-1)
    w = np.stack([half(_Q_WR, _Q_WS, a) for a in range(3)], axis=-1)
    return u, w


def _qexp_np(v: np.ndarray) -> np.ndarray:
    t2 = np.sum(v * v, axis=-1)
    a = exp_coeffs_np(t2)[0]
    return np.concatenate([np.cos(np.sqrt(t2))[..., None], a[..., None] * v], axis=-1)


def _qlog_np(q: np.ndarray) -> np.ndarray:
    q0, qv = q[..., 0], q[..., 1:]
    s = np.sqrt(np.sum(qv * qv, axis=-1))
    small = s <= _QLOG_SMALL * q0
    zero = s == 0.0
    f = np.where(
        small,
        _qlog_factor_series(s, np.where(small, q0, 1.0)),
        _qlog_factor_direct(np.where(small | zero, 1.0, s), q0),
    )
    out = f[..., None] * qv
    out[..., 0] = np.where(zero, np.arctan2(0.0, q0), out[..., 0])
    return out


def _so4_from_uw_np(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    return _Q_SU * u[..., _Q_AU] + _Q_SW * w[..., _Q_AW]


def _so4_exp_np(xi: np.ndarray) -> np.ndarray:
    u, w = _so4_uw_np(xi)
    p, q = _qexp_np(u), _qexp_np(w)
    out = np.zeros((*xi.shape[:-1], 4, 4))
    for m in range(4):
        c, d, sgn = _Q_EXP[..., m, 0], _Q_EXP[..., m, 1], _Q_EXP[..., m, 2]
        out += sgn * (p[..., c] * q[..., d])
    return out


def _so4_log_np(R: np.ndarray) -> np.ndarray:
    A = np.zeros(R.shape)
    for m in range(4):
        a, b, sgn = _Q_LOG[..., m, 0], _Q_LOG[..., m, 1], _Q_LOG[..., m, 2]
        A += sgn * R[..., a, b]
    A *= 0.25
    norms = np.sum(A * A, axis=-2)  # [..., d]
    dstar = np.argmax(norms, axis=-1)
    col = np.take_along_axis(A, dstar[..., None, None], axis=-1)[..., 0]
    p = col / np.sqrt(np.take_along_axis(norms, dstar[..., None], axis=-1))
    q = np.einsum("...cd,...c->...d", A, p)
    q = q / np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    # principal branch α + β ≤ π, tested to first order (see so4_log_point)
    alpha = np.arctan2(np.linalg.norm(p[..., 1:], axis=-1), p[..., 0])
    beta = np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), q[..., 0])
    flip = np.where(alpha + beta > np.pi, -1.0, 1.0)[..., None]
    return _so4_from_uw_np(_qlog_np(flip * p), _qlog_np(flip * q))


def _so4_blocks_np(xi: np.ndarray, inverse: bool, s) -> np.ndarray:
    s = np.asarray(s, dtype=float)
    u, w = _so4_uw_np(s[..., None] * xi)
    blocks = []
    for v in (2.0 * u, -2.0 * w):
        x, y, z = v[..., 0], v[..., 1], v[..., 2]
        t2 = x * x + y * y + z * z
        if inverse:
            e = _poly3(x, y, z, -0.5, dexp_inv_coeff_np(t2))
        else:
            e = _poly3(x, y, z, *dexp_coeffs_np(t2))
        blocks.append(np.stack(np.broadcast_arrays(*e), axis=-1))  # [..., 9]
    ju, jw = blocks
    out = ((_Q_SU[:, None] * _Q_SU[None, :]) * ju[..., 3 * _Q_AU[:, None] + _Q_AU[None, :]]
           + (_Q_SW[:, None] * _Q_SW[None, :]) * jw[..., 3 * _Q_AW[:, None] + _Q_AW[None, :]])
    return s[..., None, None] * (0.5 * out)


# ---------------------------------------------------------------------- n ≥ 5: numpy
def _spectral(V: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``V diag(f) Vᵀ`` for ``V`` ``[..., m, m]`` and ``f`` ``[..., m]``."""
    return (V * f[..., None, :]) @ np.swapaxes(V, -1, -2)


def _even_spectrum(K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectral data of a real skew ``K`` ``[..., m, m]`` through the symmetric ``M = −K²``.

    Returns ``M``, ``t2`` ``[..., m]`` (the squared rotation angles, clamped at 0) and the
    orthogonal ``V`` with ``M = V diag(t2) Vᵀ``.  An even function ``f(θ)`` of the
    eigenvalues ``±iθ`` of ``K`` is then ``V diag(f) Vᵀ``: degenerate angles need no care.
    """
    M = -(K @ K)
    t2, V = np.linalg.eigh(M)
    return M, np.maximum(t2, 0.0), V


def _log_schur(R: np.ndarray) -> np.ndarray:
    """Principal logarithm (skew matrix) of one rotation ``R`` (n, n) by its real Schur form."""
    n = R.shape[0]
    T, Z = scipy.linalg.schur(R, output="real")
    Lt = np.zeros((n, n))
    negative = []
    k = 0
    while k < n:
        if k + 1 < n and T[k + 1, k] != 0.0:
            th = np.arctan2(T[k + 1, k] - T[k, k + 1], T[k, k] + T[k + 1, k + 1])
            Lt[k + 1, k] = th
            Lt[k, k + 1] = -th
            k += 2
        else:
            if T[k, k] < 0.0:
                negative.append(k)
            k += 1
    for a, b in zip(negative[0::2], negative[1::2], strict=False):
        Lt[b, a] = np.pi
        Lt[a, b] = -np.pi
    return Z @ Lt @ Z.T


# ---------------------------------------------------------------------- the group
class SO(SymmetryGroup):
    """Rotations of Rⁿ, ``R ∈ R^{n×n}``, ``RᵀR = I``, ``det R = 1``, for any ``n ≥ 2``.

    Parameters
    ----------
    n : int
        Dimension of the rotated space (``n ≥ 2``); the algebra has ``r = n(n−1)/2``
        components ``[..., r]`` and elements are ``[..., n, n]`` matrices.

    Notes
    -----
    The basis ordering (generators moving ``e_(n−1)`` first, reducing to the paper's so(3)
    hat map for n = 3) and the algorithms per n are described in :mod:`cartan.groups.son`.
    """

    name = "SO"

    def __init__(self, n: int) -> None:
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 2:
            raise ValueError(f"SO(n) needs an integer n >= 2, got n={n!r}")
        n = int(n)
        self.n = n
        self.dim = n * (n - 1) // 2
        self.matrix_size = n
        self._I, self._J, self._S, self._PK, self._PS = son_tables(n)
        if n == 2:
            self._impl: SymmetryGroup | None = SO2()
        elif n == 3:
            self._impl = SO3()
        else:
            self._impl = None

    def point_kernels(self):
        """Point kernels for the generated loops (see
        :meth:`~cartan.groups.base.SymmetryGroup.point_kernels`): those of SO(2) and SO(3) for
        n = 2, 3; for n = 4 the closed forms of this module, with the basis tables of
        :func:`son_tables` frozen into the generated module; None for n ≥ 5."""
        if self._impl is not None:
            return self._impl.point_kernels()
        if self.n != 4:
            return None
        from ..compiled.codegen import Fragment

        here = __name__
        imports = {"g_exp": (here, "so4_exp_point"), "g_log": (here, "so4_log_point"),
                   "g_dexp_inv": (here, "so4_dexp_inv_point"), "g_E": (here, "so4_E_point"),
                   "g_compose": (here, "so4_compose_point"), "g_inverse": (here, "so4_inverse_point"),
                   "g_Ad_T": (here, "so4_Ad_T_point"), "g_dexp_inv_T": (here, "so4_dexp_inv_T_point"),
                   "g_dexp_inv_T_pair": (here, "so4_dexp_inv_T_pair_point"),
                   "_son_hat": (here, "son_hat_point"), "_son_Ad": (here, "son_Ad_point"),
                   "_son_ad": (here, "son_ad_point")}
        constants = {"SON_I": self._I, "SON_J": self._J, "SON_S": self._S, "SON_PK": self._PK,
                     "SON_PS": self._PS}
        source = """
def g_hat(xi, out):
    _son_hat(xi, SON_I, SON_J, SON_S, out)


def g_Ad(g, out):
    _son_Ad(g, SON_I, SON_J, SON_S, out)


def g_ad(xi, out):
    _son_ad(xi, SON_I, SON_J, SON_S, SON_PK, SON_PS, out)
"""
        from ..compiled.kernels import with_fused

        return with_fused(Fragment(imports=imports, constants=constants, source=source))

    @property
    def _kernels(self) -> dict:
        """The numba batch kernels for this n (those of SO2 and SO3 for n = 2, 3)."""
        if self._impl is not None:
            return self._impl._kernels
        return _SO4_KERNELS if self.n == 4 else _GENERIC_KERNELS

    def __repr__(self) -> str:
        return f"SO(n={self.n})"

    def basis(self) -> np.ndarray:
        """Generators ``b_k = S_k (E_(J_k I_k) − E_(I_k J_k))``, shape ``(r, n, n)``."""
        return self._hat_tables(np.eye(self.dim))

    def defect(self, g) -> np.ndarray:
        """Distance from SO(n): ``‖gᵀg − I‖_F + |det g − 1|``.

        Parameters
        ----------
        g : array_like, shape ``[..., n, n]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        return rotation_defect(self._element(g))

    def log_domain_norm(self, xi) -> np.ndarray:
        """Largest rotation angle of ``exp(xi)``, the spectral norm of ``hat(xi)``.

        Parameters
        ----------
        xi : array_like, shape ``[..., r]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
            ``|θ|`` for n = 2, ``|ξ|`` for n = 3, ``|u| + |w|`` for n = 4, otherwise the
            largest ``|λ|`` of the eigenvalues ``iλ`` of ``hat(ξ)``.
        """
        xi = self._algebra(xi)
        if self._impl is not None:
            return self._impl.log_domain_norm(xi)
        if self.n == 4:
            u, w = _so4_uw_np(xi)
            return np.linalg.norm(u, axis=-1) + np.linalg.norm(w, axis=-1)
        X = self._hat_tables(xi)
        return np.sqrt(np.maximum(np.linalg.eigvalsh(-(X @ X))[..., -1], 0.0))

    # ------------------------------------------------------------------ helpers
    def _hat_tables(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], self.n, self.n))
        out[..., self._J, self._I] = self._S * xi
        out[..., self._I, self._J] = -self._S * xi
        return out

    def _vee_tables(self, A: np.ndarray) -> np.ndarray:
        return self._S * (0.5 * (A[..., self._J, self._I] - A[..., self._I, self._J]))

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._hat(xi)
        return self._hat_tables(xi)

    def _vee(self, A: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._vee(A)
        return self._vee_tables(A)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._compose(g, h)
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._inverse(g)
        return np.swapaxes(g, -1, -2).copy()

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._act(g, x)
        return np.einsum("...ij,...j->...i", g, x)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._Ad(g)
        I, J, S = self._I, self._J, self._S
        Ik, Jk, Il, Jl = I[:, None], J[:, None], I[None, :], J[None, :]
        comp = g[..., Ik, Il] * g[..., Jk, Jl] - g[..., Ik, Jl] * g[..., Jk, Il]
        return (S[:, None] * S[None, :]) * comp

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._ad(xi)
        I, J, S = self._I, self._J, self._S
        Ik, Jk, Il, Jl = I[:, None], J[:, None], I[None, :], J[None, :]
        X = self._hat_tables(xi)
        v = (
            np.where(Jk == Jl, X[..., Ik, Il], 0.0)
            + np.where(Ik == Il, X[..., Jk, Jl], 0.0)
            - np.where(Jk == Il, X[..., Ik, Jl], 0.0)
            - np.where(Ik == Jl, X[..., Jk, Il], 0.0)
        )
        return (S[:, None] * S[None, :]) * v

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._bracket(xi, eta)
        X, Y = self._hat_tables(xi), self._hat_tables(eta)
        return self._vee_tables(X @ Y - Y @ X)

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._exp(xi)
        if self.n == 4:
            return _so4_exp_np(xi)
        # exp(X) = I + X A(Θ) + X² B(Θ): A = sin θ/θ, B = (1 − cos θ)/θ² applied to −X² = Θ²
        X = self._hat_tables(xi)
        M, t2, V = _even_spectrum(X)
        a, b = exp_coeffs_np(t2)
        return np.eye(self.n) + X @ _spectral(V, a) - M @ _spectral(V, b)

    def _log(self, g: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._log(g)
        if self.n == 4:
            return _so4_log_np(g)
        n = self.n
        flat = g.reshape(-1, n, n)
        A = 0.5 * (flat - np.swapaxes(flat, -1, -2))
        Ssym = 0.5 * (flat + np.swapaxes(flat, -1, -2))
        # every rotation angle ≤ π/3  ⇔  every eigenvalue cos θ of the symmetric part ≥ ½
        small = np.linalg.eigvalsh(Ssym)[:, 0] >= 0.5
        L = np.empty_like(flat)
        if small.any():
            # log R = A·f(Θ) with f = θ/sin θ = arcsin(x)/x, x = sin θ, −A² = V diag(x²) Vᵀ
            As = A[small]
            _, x2, V = _even_spectrum(As)
            x = np.sqrt(np.minimum(x2, 1.0))
            f = np.arcsin(x) / np.where(x > 0.0, x, 1.0)
            L[small] = As @ _spectral(V, np.where(x > 0.0, f, 1.0))
        for k in np.flatnonzero(~small):
            L[k] = _log_schur(flat[k])
        return self._vee_tables(L).reshape(*g.shape[:-2], self.dim)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._dexp(xi)
        if self.n == 4:
            return _so4_blocks_np(xi, False, 1.0)
        # dexp = I + ad B(Θ) + ad² C(Θ), B = (1 − cos θ)/θ², C = (θ − sin θ)/θ³, −ad² = Θ²
        ad = self._ad(xi)
        M, t2, V = _even_spectrum(ad)
        b, c = dexp_coeffs_np(t2)
        return np.eye(self.dim) + ad @ _spectral(V, b) - M @ _spectral(V, c)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._dexp_inv(xi)
        if self.n == 4:
            return _so4_blocks_np(xi, True, 1.0)
        # dexp⁻¹ = I − ½ad + ad² c(Θ), c = (1 − (θ/2) cot(θ/2))/θ²
        ad = self._ad(xi)
        M, t2, V = _even_spectrum(ad)
        return np.eye(self.dim) - 0.5 * ad - M @ _spectral(V, dexp_inv_coeff_np(t2))

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        if self._impl is not None:
            return self._impl._E(dt, Y)
        dt = np.asarray(dt, dtype=float)
        if self.n == 4:
            return _so4_blocks_np(Y, False, dt)
        return dt[..., None, None] * self._dexp(dt[..., None] * Y)
