"""The Poincaré passes of the generated lattice operators against the Poincaré point kernels.

``poincare_log_chunk_point`` and ``poincare_dexp_inv_T_pair_chunk_point`` (the edges'
logarithms and both ends' terms of the edge stresses: closed forms for pure translations, the
string's edges) and ``poincare_move_chunk_point``, ``poincare_frames_chunk_point`` (the update
by the nodes' motions) run over many edges or nodes at once; each is compared with the point
kernel it replaces, applied element by element, on pure translations and on general elements
mixed in the same call.

Tolerances: every pass takes the point kernels' operations in the same order (the closed forms
of a pure translation keep the two non-zero products of each entry of ``ad_ξᵀq`` in the
kernel's order and drop exact zeros), so they agree exactly (``==``, under which a zero of either
sign is equal).
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import check_move_and_frames_passes

from cartan.groups import poincare as pc


def _algebra(count: int, seed: int, pure: bool = False) -> np.ndarray:
    """``ξ [count, 10]``: every third a pure translation (``pure``: every one), the others with a
    Lorentz part of size up to 0.5 (both sides of the kernels' series threshold 1e-2)."""
    rng = np.random.default_rng(seed)
    xi = rng.standard_normal((count, 10))
    xi[:, 4:] *= 10.0 ** rng.uniform(-4, np.log10(0.5), (count, 1))
    xi[:: 1 if pure else 3, 4:] = 0.0
    return xi


def _elements(count: int, seed: int, pure: bool = False) -> np.ndarray:
    xi = _algebra(count, seed, pure)
    G = np.empty((count, 5, 5))
    for e in range(count):
        pc.poincare_exp_point(xi[e], G[e])
    return G


def test_log_pass_equals_the_point_logarithm():
    G = _elements(90, seed=0)
    assert sum(pc._pure_translation(g) for g in G) >= 30  # the closed form is exercised
    ref = np.empty((90, 10))
    for e in range(90):
        pc.poincare_log_point(G[e], ref[e])
    got = np.full_like(ref, np.nan)
    pc.poincare_log_chunk_point(G, 0, 7, got)
    pc.poincare_log_chunk_point(G, 7, 90, got)
    assert np.array_equal(got, ref)


def test_pair_pass_equals_the_point_kernel():
    xi = _algebra(90, seed=1)
    Q = np.random.default_rng(2).standard_normal(xi.shape)
    scale = np.random.default_rng(3).uniform(0.5, 2.0, 90)
    out, neg = np.empty(10), np.empty(10)
    for s in (scale, np.empty(0)):
        VT, VH = np.full_like(xi, np.nan), np.full_like(xi, np.nan)
        pc.poincare_dexp_inv_T_pair_chunk_point(xi, Q, s, 0, 90, VT, VH)
        for e in range(90):
            pc.poincare_dexp_inv_T_pair_point(xi[e], Q[e], out, neg)
            f = s[e] if s.size else 1.0
            assert np.array_equal(VT[e], f * out) and np.array_equal(VH[e], f * neg)


@pytest.mark.parametrize("pure", [False, True])
def test_move_and_frames_passes_equal_the_products(pure):
    """General elements (every third a pure translation), and pure translations only (the edge
    update's closed form)."""
    Dn = _elements(30, seed=4, pure=pure)
    G = _elements(45, seed=5, pure=pure)
    Phi = _elements(30, seed=6)
    Phi[::2, 1:, 0] = 0.0  # some frames at the origin: a zero translation
    check_move_and_frames_passes(pc.poincare_frames_chunk_point, pc.poincare_move_chunk_point,
                                 pc.poincare_inverse_point, pc.poincare_compose_point, Dn, G, Phi, seed=7)

