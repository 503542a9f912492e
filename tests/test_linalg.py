"""Small dense solves of compiled kernels (:mod:`cartan.compiled.linalg`).

``solve_augmented`` is Gaussian elimination with partial pivoting, used per node by the groups
(Poincaré's logarithm), the relativistic string's Newton step and the residual of
``implicit-midpoint`` (``(I + Ad_{exp(ξ/2)})⁻ᵀ W``, :mod:`cartan.integrators.newton`), which
reads its False on a zero or NaN pivot.  The bound on the residual is the backward
error of partial pivoting, ``‖A x − b‖ ≤ c n ε ‖A‖ ‖x‖`` with a small growth factor on these
well-conditioned systems (c = 8 here).
"""

from __future__ import annotations

import numpy as np
import pytest

from cartan.compiled.linalg import solve_augmented

EPS = np.finfo(float).eps


def _solve(A: np.ndarray, b: np.ndarray) -> tuple[bool, np.ndarray, np.ndarray]:
    Mw = np.ascontiguousarray(np.column_stack([A, b]), dtype=float)
    out = np.full(A.shape[0], np.nan)
    ok = solve_augmented(Mw, out)
    return bool(ok), out, Mw


@pytest.mark.parametrize("n", [1, 3, 6, 10])
def test_solves_random_systems_to_the_backward_error_of_pivoting(n):
    rng = np.random.default_rng(n)
    for _ in range(5):
        A = rng.standard_normal((n, n)) + 0.5 * n * np.eye(n)
        b = rng.standard_normal(n)
        ok, x, _ = _solve(A, b)
        assert ok
        bound = 8 * n * EPS * np.linalg.norm(A, 2) * np.linalg.norm(x)
        assert np.linalg.norm(A @ x - b) <= bound
        ref = np.linalg.solve(A, b)
        assert np.allclose(x, ref, rtol=1e3 * n * EPS * np.linalg.cond(A), atol=0.0)


def test_a_zero_leading_entry_needs_the_row_swap():
    """Without pivoting the first step divides by zero; with it the answer is exact."""
    A = np.array([[0.0, 1.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 4.0]])
    ok, x, _ = _solve(A, np.array([3.0, 4.0, 8.0]))
    assert ok and np.array_equal(x, [2.0, 3.0, 2.0])


@pytest.mark.parametrize("A", [
    np.array([[1.0, 2.0], [2.0, 4.0]]),  # rank 1: the second pivot is exactly 0
    np.array([[0.0, 1.0, 2.0], [0.0, 3.0, 4.0], [0.0, 5.0, 6.0]]),  # a zero column
    np.array([[1.0, np.nan], [0.0, 1.0]]),  # a NaN reaches the second pivot
], ids=["rank-1", "zero-column", "nan"])
def test_a_zero_or_nan_pivot_returns_false(A):
    ok, _, _ = _solve(A, np.ones(A.shape[0]))
    assert not ok
