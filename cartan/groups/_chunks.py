"""Pieces shared by the closed-form chunk passes of SE(2) and SE(3).

The plane turn (:func:`_turn` with its cosine and sine, :func:`_turn_coeffs_series` and
:func:`_turn_coeffs_direct`), and the steps of the passes that do the same arithmetic in both
groups, whatever the dimension ``d`` of the algebra: the times of one piece of ``lie-verlet``'s
axial flow (:func:`axial_times`), the count of the nodes it moves (:func:`count_moved`), the
cosines and sines of a rotation's times (:func:`turn_coeffs_chunk`), and the loads and stores of
the edge passes' blocks (:func:`load_pair_block`, :func:`store_block`,
:func:`store_scaled_pair_block`).  All are inlined into the passes (``inline='always'``), so each
group's pass is compiled once, with ``d`` a constant, as if written out.
"""

from __future__ import annotations

from numba.extending import register_jitable

from .so3 import SMALL_THETA2, TAYLOR_A, TAYLOR_B, _exp_coeffs_direct, horner


@register_jitable(inline='always')
def _turn(cs, sn, x, y):
    """``(x, y)`` turned by the plane rotation of cosine ``cs`` and sine ``sn``:
    ``(cs x + sn y, cs y − sn x)`` (the components in the turned basis)."""
    return cs * x + sn * y, cs * y - sn * x


@register_jitable(inline='always')
def _turn_coeffs_series(t):
    """``(cos t, sin t)`` as ``(1 − Bt², At)`` with ``A``, ``B`` from their series (t² < 0.01)."""
    t2 = t * t
    return 1.0 - horner(t2, TAYLOR_B) * t2, horner(t2, TAYLOR_A) * t


@register_jitable(inline='always')
def _turn_coeffs_direct(t):
    """``(cos t, sin t)`` as ``(1 − Bt², At)`` with ``A``, ``B`` in closed form (t ≠ 0)."""
    t2 = t * t
    a, b = _exp_coeffs_direct(t2)
    return 1.0 - b * t2, a * t


@register_jitable(inline='always')
def axial_times(F, T, lo, nb, p, tau, naxes, axes, coef, any_clamped, clamped, any_held, held):
    """``T[c, i0]`` ← the time ``τ_p (P_p)_kk S_k`` of direction ``k = axes[p, c]`` of piece ``p``
    at node ``i = lo + i0`` (``S_k`` the row ``F[k]``), zero where the node is clamped or the
    component held; every time of the piece first, as its flows leave its ``S`` alone."""
    taup = tau[p]
    for c in range(naxes[p]):
        k = axes[p, c]
        cp = coef[p, c]
        for i0 in range(nb):
            i = lo + i0
            t = taup * (cp * F[k, i0])
            T[c, i0] = 0.0 if (any_clamped and clamped[i]) or (any_held and held[i, k]) else t


@register_jitable(inline='always')
def count_moved(T, c, nb):
    """How many of the times ``T[c, :nb]`` are not zero."""
    moved = 0
    for i0 in range(nb):
        moved += T[c, i0] != 0.0
    return moved


@register_jitable(inline='always')
def turn_coeffs_chunk(T, c, nb, CS, SN):
    """``CS[i0]``, ``SN[i0]`` ← the cosine and sine of the times ``T[c, i0]``: the series everywhere
    (one branch-free loop), then the closed forms where ``t² ≥ SMALL_THETA2``."""
    nbad = 0
    for i0 in range(nb):
        t = T[c, i0]
        nbad += t * t >= SMALL_THETA2
        CS[i0], SN[i0] = _turn_coeffs_series(t)
    if nbad:
        for i0 in range(nb):
            t = T[c, i0]
            if t * t >= SMALL_THETA2:
                CS[i0], SN[i0] = _turn_coeffs_direct(t)


@register_jitable(inline='always')
def load_pair_block(X, Y, c0, nb, d, A):
    """Rows ``0 … d − 1`` of ``A`` ← ``X[c0 + e0]`` and rows ``d … 2d − 1`` ← ``Y[c0 + e0]`` in
    column ``e0 < nb`` (one row per entry: a block of an edge pass)."""
    for e0 in range(nb):
        e = c0 + e0
        for k in range(d):
            A[k, e0] = X[e, k]
            A[k + d, e0] = Y[e, k]


@register_jitable(inline='always')
def store_block(B, c0, nb, d, X):
    """``X[c0 + e0, k]`` ← ``B[k, e0]`` for ``k < d``, ``e0 < nb``."""
    for e0 in range(nb):
        e = c0 + e0
        for k in range(d):
            X[e, k] = B[k, e0]


@register_jitable(inline='always')
def store_scaled_pair_block(B, scale, scaled, c0, nb, d, VT, VH):
    """``VT[e]`` ← ``s_e`` times rows ``0 … d − 1`` of ``B`` and ``VH[e]`` ← ``s_e`` times rows
    ``d … 2d − 1`` in column ``e0 = e − c0 < nb``, ``s_e = scale[e]`` if ``scaled``, else 1."""
    for e0 in range(nb):
        e = c0 + e0
        s = scale[e] if scaled else 1.0
        for k in range(d):
            VT[e, k] = s * B[k, e0]
            VH[e, k] = s * B[k + d, e0]

