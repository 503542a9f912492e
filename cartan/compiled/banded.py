"""Block-tridiagonal linear systems in compiled code: factor once, solve many.

A matrix of ``nb × nb`` blocks of size ``c × c`` whose only nonzero blocks are on the block
diagonal (``diag[e]``), just below it (``sub[e]``, row e, column e − 1; ``sub[0]`` unused) and
just above it (``sup[e]``, row e, column e + 1; ``sup[nb − 1]`` unused) — the multiplier systems
``B P Bᵀ`` of constraints on the edges of a chain of nodes, where each edge's rows touch its
two nodes (:mod:`cartan.integrators.rattle_loop`) — is solved by block Gaussian elimination
without pivoting between blocks (the block Thomas algorithm), in ``O(nb c³)`` operations:

    D'₀ = D₀,  Lₑ = subₑ D'ₑ₋₁⁻¹,  D'ₑ = Dₑ − Lₑ supₑ₋₁        (factor)
    yₑ = bₑ − Lₑ yₑ₋₁;   xₑ = D'ₑ⁻¹(yₑ − supₑ xₑ₊₁)               (solve)

The pivot blocks are inverted by Gauss–Jordan elimination with partial pivoting.  Without
pivoting between blocks the elimination is stable for block diagonally dominant matrices and
for the symmetric positive definite ``B P Bᵀ`` (P symmetric positive definite, B of full row
rank), and close to them (a quasi-Newton matrix ``B₁ P B₀ᵀ`` with B₁ near B₀).

A symmetric positive definite block-tridiagonal matrix (``sup[e] = sub[e + 1]ᵀ``, the
multiplier matrices ``B P Bᵀ`` with P symmetric positive semidefinite and B of full row rank
on the unknowns) is factored by the block Cholesky factorisation instead, which reads the
lower triangle of the diagonal blocks and the blocks below the diagonal only:

    Mₑ = subₑ Lₑ₋₁⁻ᵀ,  Lₑ Lₑᵀ = diagₑ − Mₑ Mₑᵀ                    (factor)
    yₑ = Lₑ⁻¹(bₑ − Mₑ yₑ₋₁);   xₑ = Lₑ⁻ᵀ(yₑ − Mₑ₊₁ᵀ xₑ₊₁)          (solve)

with ``Lₑ`` lower triangular (about a third of the block LU's operations; no pivoting is
needed, a pivot that is not positive says the matrix is not positive definite).

The functions are plain Python compiled inside the generated modules (their source joins a
loop's fragment, :func:`cartan.compiled.codegen.njit_source`); they are general in ``nb`` and
``c`` and use no module globals.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bs_factor", "bs_solve", "bt_factor", "bt_solve", "small_inverse"]


def small_inverse(A, out, M):
    """``out = A⁻¹`` ``(c, c)`` by Gauss–Jordan elimination with partial pivoting, ``M`` scratch of
    at least ``(c, 2c)``; returns False (``out`` undefined) when a pivot is zero or not finite (A
    singular to working precision)."""
    c = A.shape[0]
    for a in range(c):
        for b in range(c):
            M[a, b] = A[a, b]
            M[a, c + b] = 1.0 if a == b else 0.0
    for col in range(c):
        piv = col
        big = abs(M[col, col])
        for a in range(col + 1, c):
            if abs(M[a, col]) > big:
                big = abs(M[a, col])
                piv = a
        if not (big > 0.0) or not np.isfinite(big):
            return False
        if piv != col:
            for b in range(2 * c):
                tmp = M[col, b]
                M[col, b] = M[piv, b]
                M[piv, b] = tmp
        inv = 1.0 / M[col, col]
        for b in range(2 * c):
            M[col, b] *= inv
        for a in range(c):
            if a != col:
                f = M[a, col]
                if f != 0.0:
                    for b in range(2 * c):
                        M[a, b] -= f * M[col, b]
    for a in range(c):
        for b in range(c):
            out[a, b] = M[a, c + b]
    return True


def bt_factor(sub, diag, sup, inv, mult):
    """Factor the block-tridiagonal matrix ``(sub, diag, sup)`` (each ``[nb, c, c]``, not
    modified): ``inv[e] = D'ₑ⁻¹`` and ``mult[e] = Lₑ`` (``[nb, c, c]``, see the module
    docstring).  Returns False when a pivot block is singular to working precision."""
    nb = diag.shape[0]
    c = diag.shape[1]
    work = np.empty((c, c))
    M = np.empty((c, 2 * c))
    if nb == 0:
        return True
    if not small_inverse(diag[0], inv[0], M):
        return False
    for e in range(1, nb):
        for a in range(c):
            for b in range(c):
                s = 0.0
                for k in range(c):
                    s += sub[e, a, k] * inv[e - 1, k, b]
                mult[e, a, b] = s
        for a in range(c):
            for b in range(c):
                s = diag[e, a, b]
                for k in range(c):
                    s -= mult[e, a, k] * sup[e - 1, k, b]
                work[a, b] = s
        if not small_inverse(work, inv[e], M):
            return False
    return True


def bt_solve(sup, inv, mult, rhs, x):
    """``x`` ``[nb, c]`` solving the factored system (:func:`bt_factor`) for ``rhs`` ``[nb, c]``
    (``x`` may be ``rhs``)."""
    nb = inv.shape[0]
    c = inv.shape[1]
    y = np.empty((nb, c))
    for e in range(nb):
        for a in range(c):
            s = rhs[e, a]
            if e > 0:
                for k in range(c):
                    s -= mult[e, a, k] * y[e - 1, k]
            y[e, a] = s
    tmp = np.empty(c)
    for e in range(nb - 1, -1, -1):
        for a in range(c):
            s = y[e, a]
            if e < nb - 1:
                for k in range(c):
                    s -= sup[e, a, k] * x[e + 1, k]
            tmp[a] = s
        for a in range(c):
            s = 0.0
            for k in range(c):
                s += inv[e, a, k] * tmp[k]
            x[e, a] = s


def bs_factor(sub, diag, L, M):
    """Block Cholesky factorisation of the symmetric block-tridiagonal matrix with the lower
    triangles of ``diag`` ``[nb, c, c]`` on the diagonal and ``sub`` ``[nb, c, c]`` below it
    (``sub[0]`` unused; the blocks above are ``sub[e + 1]ᵀ``; neither is modified):
    ``L[e]`` ``[nb, c, c]`` the lower-triangular Cholesky factors ``Lₑ`` of the module
    docstring with the reciprocals ``1/(Lₑ)_aa`` on their diagonal (its strict upper triangle
    is not referenced), ``M[e] = subₑ Lₑ₋₁⁻ᵀ`` (``M[0]`` unused).  Returns False when a pivot
    is not positive and finite (the matrix is not positive definite to working precision);
    allocates nothing."""
    nb = diag.shape[0]
    c = diag.shape[1]
    for e in range(nb):
        if e > 0:  # M_e = sub_e L_{e-1}^{-T}: each row m solves L_{e-1} mᵀ = sub_e[a]ᵀ
            for a in range(c):
                for b in range(c):
                    s = sub[e, a, b]
                    for k in range(b):
                        s -= L[e - 1, b, k] * M[e, a, k]
                    M[e, a, b] = s * L[e - 1, b, b]
        for a in range(c):  # the lower triangle of diag_e − M_e M_eᵀ into L[e]
            for b in range(a + 1):
                s = diag[e, a, b]
                if e > 0:
                    for k in range(c):
                        s -= M[e, a, k] * M[e, b, k]
                L[e, a, b] = s
        for b in range(c):  # in place, column by column
            d = L[e, b, b]
            for k in range(b):
                d -= L[e, b, k] * L[e, b, k]
            if not (d > 0.0) or not np.isfinite(d):
                return False
            r = 1.0 / np.sqrt(d)
            L[e, b, b] = r
            for a in range(b + 1, c):
                s = L[e, a, b]
                for k in range(b):
                    s -= L[e, a, k] * L[e, b, k]
                L[e, a, b] = s * r
    return True


def bs_solve(L, M, rhs, x):
    """``x`` ``[nb, c]`` solving the system factored by :func:`bs_factor` for ``rhs``
    ``[nb, c]`` (``x`` may be ``rhs``: each entry of ``rhs`` is read before the same entry of
    ``x`` is written); allocates nothing."""
    nb = L.shape[0]
    c = L.shape[1]
    for e in range(nb):  # forward: y_e = L_e^{-1}(b_e − M_e y_{e−1}), into x
        for a in range(c):
            s = rhs[e, a]
            if e > 0:
                for k in range(c):
                    s -= M[e, a, k] * x[e - 1, k]
            for k in range(a):
                s -= L[e, a, k] * x[e, k]
            x[e, a] = s * L[e, a, a]
    for e in range(nb - 1, -1, -1):  # backward: x_e = L_e^{-T}(y_e − M_{e+1}ᵀ x_{e+1})
        for a in range(c - 1, -1, -1):
            s = x[e, a]
            if e < nb - 1:
                for k in range(c):
                    s -= M[e + 1, k, a] * x[e + 1, k]
            for k in range(a + 1, c):
                s -= L[e, k, a] * x[e, k]
            x[e, a] = s * L[e, a, a]
