"""Small dense linear algebra for compiled kernels.

Kernels of groups and media solve tiny systems per point (a 3 × 3 Newton step, a 4 × 4 block
of a group's logarithm); numba's ``np.linalg.solve`` calls LAPACK with allocations and a
``gesv`` per call, which costs more than the arithmetic at these sizes.  The functions here
work in place on a caller's array and allocate nothing.
"""

from __future__ import annotations

from numba import njit

__all__ = ["solve_augmented"]


@njit(cache=True)
def solve_augmented(A, out):  # pragma: no cover - compiled
    """``out`` (n,) ← the solution of ``A[:, :n] x = A[:, n]``, by Gaussian elimination with
    partial pivoting; ``A`` (n, n + 1) is overwritten.  Returns False (``out`` undefined) when
    a pivot is zero or NaN (an infinite entry is not detected: it gives non-finite or wrong
    values in ``out``)."""
    n = A.shape[0]
    for k in range(n):
        piv = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > abs(A[piv, k]):
                piv = i
        if not abs(A[piv, k]) > 0.0:
            return False
        if piv != k:
            for j in range(n + 1):
                A[k, j], A[piv, j] = A[piv, j], A[k, j]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            for j in range(k, n + 1):
                A[i, j] -= f * A[k, j]
    for i in range(n - 1, -1, -1):
        s = A[i, n]
        for j in range(i + 1, n):
            s -= A[i, j] * out[j]
        out[i] = s / A[i, i]
    return True
