"""Dependent strain-constraint rows in the statics: detected at the start (a pivot of the LU of B Bᵀ)
and regularised in the Newton matrix (cartan.statics._rows_dependent, REG_CONSTRAINTS)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import cartan
from cartan.statics import _Equilibrium, _rows_dependent


def test_rows_dependent_on_small_matrices():
    rng = np.random.default_rng(0)
    B = rng.normal(size=(4, 9))
    assert not _rows_dependent(sp.csr_matrix(B))
    B[3] = B[0] - 2.0 * B[1] + 0.5 * B[2]     # a combination of the others
    assert _rows_dependent(sp.csr_matrix(B))
    assert _rows_dependent(sp.csr_matrix(rng.normal(size=(5, 4))))   # more rows than columns
    assert not _rows_dependent(sp.csr_matrix((0, 3)))


@pytest.mark.parametrize(("faces", "dependent"), [(("u-start", "u-end", "v-start", "v-end"), True),
                                                  (("u-start", "u-end", "v-start"), False)])
def test_kirchhoff_love_plate_clamped_all_round_has_one_dependent_row(faces, dependent):
    """θ_e,3 = 0 on a plate clamped on all four faces: one dependent row (rank 59 of 60 rows at
    n = 7, by a dense SVD here); three clamped faces: independent."""
    medium = cartan.medium("kirchhoff-love", E=1.0, poisson=0.3, thickness=0.01)
    grid = cartan.Grid((7, 7), length=(1.0, 1.0))
    problem = cartan.Problem(medium, grid, medium.initial_state(grid, "flat"), {f: cartan.Clamped() for f in faces})
    eq = _Equilibrium(problem)
    B = eq._constraint_matrix(eq.state0).toarray()
    s = np.linalg.svd(B, compute_uv=False)
    assert (int(np.sum(s > 1e-10 * s[0])) < B.shape[0]) is dependent
    assert eq.dependent_constraints is dependent
