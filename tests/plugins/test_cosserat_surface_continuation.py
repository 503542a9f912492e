"""The ``cosserat-surface`` sphere under the volume pressure in ``cartan.continuation``: the tangent
predictor, det J and the eigenvalue of smallest magnitude use the whole Jacobian, the stencil part
of the frozen force plus the rank-6 mean-position part of ``VolumePressure.jacobian_parts``
(docs/media/cosserat-surface.md, "Pressure"; docs/statics.md, "Continuation").

Against the dense finite-difference Jacobian of the residual at the pressurised equilibrium (slow:
the Newton solve and 2·166 residual evaluations, ~12 s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_cosserat_surface.surface import VolumePressure

import cartan
from cartan.continuation import _eig_min, _log_det, _tangent
from cartan.problem import Problem
from cartan.statics import _Equilibrium, _factorise, _newton, _Point, rigid_gauge_pins


def _dense_jacobian(eq, state, mu, lam, h=1e-6) -> np.ndarray:
    """Central differences of the residual along every unknown (drifts and multipliers), (m, m)."""
    cols = []
    for j in range(eq.m):
        d = np.zeros(eq.m)
        d[j] = h
        plus, minus = eq.residual(*eq.update(state, mu, d), lam), eq.residual(*eq.update(state, mu, -d), lam)
        cols.append((plus - minus) / (2 * h))
    return np.column_stack(cols)


@pytest.mark.slow
def test_continuation_linear_algebra_uses_the_volume_pressure_hessian():
    """Sphere N = 8 (R = 1, h = 0.05, E = 1, ν = 0.3) under the volume pressure −0.01 (w/R ≈ 7 %),
    the equilibrium at λ = 1 (m = 166 unknowns with the pins' reactions).  Against the dense
    central differences of the residual (their error ~1e-10 of the largest entry):

    * log|det J| by the determinant lemma: measured 4e-11 from the dense one, same sign; the
      stencil part alone is off by 0.088 (det 9 % off).  Asserted 1e-6 and > 1e-2.
    * eig_min of sym J: measured 1e-10 relative; the stencil part alone −2.886e-4 against
      −3.120e-4 (7.5 %).  Asserted 1e-6 and > 1e-2.
    * the tangent (unit in the continuation's norm, λ_s = 1): measured 5e-10 of its displacement
      part; the stencil part alone 5.1e-2, the predictor error of the continuation's short last
      step (tests/plugins/test_cosserat_surface_sphere.py's path: 1.9e-4 with the whole Jacobian,
      5.1e-2 with the stencil part).  Asserted 1e-6 and > 1e-2."""
    N, lam = 8, 1.0
    med = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = cartan.Grid((N, N // 2), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    prob = Problem(med, grid, med.initial_state(grid, "sphere"), loads=[VolumePressure(-0.01)])
    pins = {N // 4: [0, 1, 2, 3, 4], (N // 2) * (N // 2) + N // 4: [1]}
    eq = _Equilibrium(prob, pins=rigid_gauge_pins(prob, pins), probe_lam=0.0)

    def move(pt, alpha, d):
        s, u = eq.update(pt.state, pt.mu, d, alpha)
        return _Point(s, u, lam)

    out = _newton(eq, _Point(eq.state0, np.zeros(eq.nmult), lam), residual=lambda pt: eq.residual(pt.state, pt.mu, lam),
                  factorise=lambda pt, offset: _factorise(eq, pt.state, pt.mu, lam, offset), move=move,
                  converged=lambda pt, r: float(np.abs(r).max()) <= 1e-12,
                  scale=np.concatenate([eq.delta_scale, np.zeros(eq.nmult)]), max_iter=30, max_halvings=20, xtol=1e-14)
    assert out.converged
    st, mu = out.point.state, out.point.mu
    K, low = eq.jacobian(st, mu, lam, low_rank=True)
    assert low is not None and low[0].shape == (eq.m, 6)
    D = _dense_jacobian(eq, st, mu, lam)

    sign_d, log_d = np.linalg.slogdet(D)
    sign, logabs = _log_det(K, low)
    assert sign == int(sign_d) and abs(logabs - log_d) <= 1e-6, (sign, logabs, sign_d, log_d)
    assert abs(_log_det(K)[1] - log_d) >= 1e-2

    vals = np.linalg.eigvalsh(0.5 * (D + D.T))
    ref = vals[np.argmin(np.abs(vals))]
    assert abs(_eig_min(K, low=low) - ref) <= 1e-6 * abs(ref)
    assert abs(_eig_min(K) - ref) >= 1e-2 * abs(ref)

    wv = np.concatenate([np.full(eq.nunk, 1.0 / eq.nnode), np.zeros(eq.nmult)])

    def wnorm(u, s):
        return math.sqrt(float(np.sum(wv * u * u)) + s * s)

    f = eq.dlam(st)
    z = np.linalg.solve(np.block([[D, f[:, None]], [np.zeros((1, eq.m)), np.ones((1, 1))]]), np.eye(eq.m + 1)[-1])
    z /= wnorm(z[:-1], z[-1]) * np.sign(z[-1])
    zu = wnorm(z[:-1], 0.0)
    for part, bound in ((low, None), (None, 1e-2)):
        tu, tl = _tangent(K, part, f, wv, 1.0, np.zeros(eq.m), 1.0)
        err = wnorm(tu - z[:-1], tl - z[-1]) / zu
        assert (err <= 1e-6) if bound is None else (err >= bound), (part is None, err)
