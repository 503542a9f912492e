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

The functions are plain Python compiled inside the generated modules (their source joins a
loop's fragment, :func:`cartan.compiled.codegen.njit_source`); they are general in ``nb`` and
``c`` and use no module globals.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bt_factor", "bt_solve", "small_inverse"]


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
