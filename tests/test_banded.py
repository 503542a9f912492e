"""The block-tridiagonal solvers of :mod:`cartan.compiled.banded` against numpy.

The functions are plain Python that the generated modules compile
(:mod:`cartan.integrators.rattle_loop`); here they run uncompiled on small matrices (no numba
compilation: the compiled path is exercised by ``tests/test_rattle_compiled.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from cartan.compiled.banded import bs_factor, bs_solve, bt_factor, bt_solve


def _spd_blocks(rng, nb: int, c: int):
    """``B P Bᵀ`` ``(nb·c, nb·c)`` with B block-bidiagonal (each block row of c rows touches two
    nodes of c unknowns, as the constraint rows of a chain) and P diagonal positive: symmetric
    positive definite and block-tridiagonal; and its blocks ``(sub, diag, sup)``."""
    n = nb * c
    B = np.zeros((n, n + c))
    for e in range(nb):
        B[e * c:(e + 1) * c, e * c:(e + 2) * c] = rng.standard_normal((c, 2 * c))
    A = B @ np.diag(rng.uniform(0.5, 2.0, n + c)) @ B.T
    sub, dia, sup = (np.zeros((nb, c, c)) for _ in range(3))
    for e in range(nb):
        dia[e] = A[e * c:(e + 1) * c, e * c:(e + 1) * c]
        if e > 0:
            sub[e] = A[e * c:(e + 1) * c, (e - 1) * c:e * c]
            sup[e - 1] = A[(e - 1) * c:e * c, e * c:(e + 1) * c]
    return A, sub, dia, sup


@pytest.mark.parametrize(("nb", "c"), [(1, 1), (1, 3), (6, 3), (12, 2), (5, 4)])
def test_block_cholesky_solves_random_spd_band_matrices(nb, c):
    """``bs_factor``/``bs_solve`` against ``numpy.linalg.solve`` on random SPD block-tridiagonal
    matrices (condition numbers up to ≈ 1e5 here): the relative error is bounded by
    κ·ε·(a small multiple), 1e-14·κ; in place (``x`` = ``rhs``) the same numbers; and the same
    solution as the block LU (``bt_factor``/``bt_solve``) to that bound."""
    rng = np.random.default_rng(100 * nb + c)
    A, sub, dia, sup = _spd_blocks(rng, nb, c)
    L, M = np.zeros((nb, c, c)), np.zeros((nb, c, c))
    low = dia.copy()
    for e in range(nb):  # only the lower triangles of the diagonal blocks are read
        low[e][np.triu_indices(c, 1)] = np.nan
    assert bs_factor(sub, low, L, M)
    kappa = np.linalg.cond(A)
    for _ in range(3):
        b = rng.standard_normal((nb, c))
        x = np.empty_like(b)
        bs_solve(L, M, b, x)
        ref = np.linalg.solve(A, b.ravel())
        assert np.max(np.abs(x.ravel() - ref)) <= 1e-14 * kappa * np.max(np.abs(ref))
        inplace = b.copy()
        bs_solve(L, M, inplace, inplace)
        assert np.array_equal(inplace, x)
        inv, mult, y = np.zeros((nb, c, c)), np.zeros((nb, c, c)), np.empty_like(b)
        assert bt_factor(sub, dia, sup, inv, mult)
        bt_solve(sup, inv, mult, b, y)
        assert np.max(np.abs(x - y)) <= 1e-14 * kappa * np.max(np.abs(ref))


def test_block_cholesky_refuses_an_indefinite_matrix():
    """A pivot that is not positive (an indefinite or singular matrix, or a NaN) makes
    ``bs_factor`` return False, at the first block or later."""
    rng = np.random.default_rng(7)
    _, sub, dia, _ = _spd_blocks(rng, 6, 3)
    L, M = np.zeros((6, 3, 3)), np.zeros((6, 3, 3))
    for e, bad in ((0, -1.0), (4, -1.0), (3, 0.0), (2, np.nan)):
        d = dia.copy()
        d[e] *= bad
        assert not bs_factor(sub, d, L, M), (e, bad)
    assert bs_factor(sub, dia, L, M)
