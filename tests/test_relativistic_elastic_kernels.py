"""The compiled point kernels of the elastic string (plugins/cartan_relativistic/elastic_kernels.py)
against the numpy closed forms of cartan_relativistic.elastic (docs/media/relativistic-rod.md §2).

Slow: the kernels compile (numba) on a fresh cache.  2000 random subluminal points (|v⃗| < 0.6c,
stretches 0.8–1.3) per built-in law: p⃗, ∂²ℓ/∂v⃗², Q⃗ and H are the same formulas in the same order
of operations up to regrouping (agreement to 1e-13 of their scale, round-off); the inverse
Legendre map is Newton's method converged to round-off, so its residual p⃗(v⃗) − p⃗ and its
difference from the numpy solve are at 1e-12 of the scale.
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_relativistic import elastic as E
from cartan_relativistic import elastic_kernels as K
from cartan_relativistic.elastic import ElasticLaw

MU, C = 1.0, 1.0


def _points(n: int = 2000, seed: int = 1):
    rng = np.random.default_rng(seed)
    x = np.stack([rng.uniform(0.8, 1.3, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n)], -1)
    v = rng.normal(size=(n, 3))
    v *= (rng.uniform(0.0, 0.6, n) / np.linalg.norm(v, axis=-1))[:, None]
    return v, x


def test_law_kernel_names_only_the_built_in_laws():
    assert K.law_kernel(ElasticLaw.quadratic(0.25))[0] == 0
    kind, prm = K.law_kernel(ElasticLaw.quartic(0.25, 0.5))
    assert kind == 1 and np.array_equal(prm, [0.25, 0.5])
    bare = ElasticLaw(lambda lam: 0 * lam, lambda lam: 0 * lam, lambda lam: 0 * lam + 1.0)
    assert K.law_kernel(bare) is None


@pytest.mark.slow
@pytest.mark.parametrize("law", [ElasticLaw.quadratic(0.25), ElasticLaw.quartic(0.25, 0.5)], ids=repr)
def test_point_kernels_match_the_closed_forms(law):
    kind, prm = K.law_kernel(law)
    fns = law.functions(MU, C)
    v, x = _points()
    n = v.shape[0]
    p = E.temporal_momentum(v, x, fns, C)
    J = E.temporal_hessian(v, x, fns, C)
    Q = E.temporal_stress(v, x, fns, C)
    H = np.sum(p * v, axis=-1) - E.temporal_lagrangian(v, x, fns, C) - MU * C * C
    pk, Jk, Qk, Hk = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty(n)
    for i in range(n):
        assert K.momentum_hessian_point(v[i], x[i], kind, prm, MU * C * C, C, pk, Jk)
        assert np.abs(pk - p[i]).max() <= 1e-13 * np.abs(p[i]).max() + 1e-16
        assert np.abs(Jk - J[i]).max() <= 1e-13 * np.abs(J[i]).max()
        K.stress_point(v[i], x[i], kind, prm, MU * C * C, C, Qk)
        assert np.abs(Qk - Q[i]).max() <= 1e-13 * (np.abs(Q[i]).max() + 1e-3)
        Hk[i] = K.hamiltonian_point(p[i], v[i], x[i], kind, prm, MU * C * C, C)
    assert np.abs(Hk - H).max() <= 1e-13
    V, ok = np.empty_like(p), np.empty(n, dtype=np.bool_)
    K.velocity_batch(p, x, kind, prm, MU * C * C, C, 40, V, ok)
    assert ok.all()
    scale = np.abs(p).max()
    assert np.abs(E.temporal_momentum(V, x, fns, C) - p).max() <= 1e-12 * scale
    assert np.abs(V - E.temporal_velocity(p, x, fns, C)).max() <= 1e-12
    # outside the light cone the Legendre map has no preimage: Newton reports failure, never a
    # superluminal velocity
    out = np.empty(3)
    assert not K.velocity_point(np.array([50.0, 0.0, 0.0]), x[0], kind, prm, MU * C * C, C, 40, out) or (
        np.linalg.norm(out) < C)
