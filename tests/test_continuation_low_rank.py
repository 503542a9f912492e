"""Continuation with a load whose Jacobian has a rank-k global part (``Load.jacobian_parts``): the
tangent predictor, det J and the eigenvalue of smallest magnitude use the whole Jacobian
J = K + U Vᵀ (docs/statics.md, "Continuation").

The problem: the pinned–pinned planar column of tests/test_continuation.py (B = 1, L = 1, axial
dead load λ at the end) with a lateral load per unit length λβȳ e_y, ȳ the mean deflection (a
rank-1 global part).  On the straight branch it lowers the first (symmetric) buckling load below
Euler's π²B/L² to the root λ_c of ``1 = βλ g(√λ)``, where ``g(k) = −(1/k²)(1/12 + 1/k² −
2 tan(k/2)/k³)`` is the mean deflection of the beam-column ``y'''' + k²y'' = 1`` with pinned ends;
the stencil part alone (ȳ held) still buckles at π².  The fast tests compare the continuation's
linear algebra against a dense finite-difference Jacobian (n = 21, the column's compiled path);
the slow one runs the continuation.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import cartan
from cartan.continuation import _eig_min, _log_det, _tangent, continuation
from cartan.problem import Load, dead_to_body
from cartan.statics import _Equilibrium, _factorise, _newton, _Point, rigid_gauge_pins

BETA = 12.166833763719623  # λ_c = π²/2 in the continuum
PINS = {"start": (0, 1), "end": (1,)}
E_Y = np.array([0.0, 1.0, 0.0])  # SE(2) algebra (v1, v2, ω): a spatial force along y


def g_mean(lam: float) -> float:
    """Mean deflection of ``y'''' + λ y'' = 1`` on (0, 1), y = y'' = 0 at both ends."""
    k = math.sqrt(lam)
    return -(1.0 / k**2) * (1.0 / 12.0 + 1.0 / k**2 - 2.0 * math.tan(k / 2.0) / k**3)


def critical_load(beta: float) -> float:
    """The root of ``1 = βλ g(√λ)`` in (0, π²) (bisection: g increases to +∞ at π²)."""
    a, b = 1e-6, math.pi**2 * (1.0 - 1e-12)
    for _ in range(200):
        c = 0.5 * (a + b)
        a, b = (c, b) if beta * c * g_mean(c) < 1.0 else (a, c)
    return 0.5 * (a + b)


class MeanDeflectionLoad(Load):
    """Lateral force density β (ȳ + c) e_y (spatial, dead), ȳ = Σ w_i y_i the trapezoidal mean
    deflection of the n nodes, c an offset (an imperfection: the column bends from λ = 0 on).
    It reads every node, so its Jacobian is the frozen force (ȳ held; it turns with the frame
    only) plus the rank-1 part U_i ⊗ V_j, ``U_i = β Ad_Rᵀ e_y``, ``V_j = w_j ∂y_j/∂η_j`` (the
    drift Φ_j exp(η_j) moves node j by R_j (η₁, η₂))."""

    needs_structure_field = True
    local = False

    def __init__(self, beta: float, n: int, offset: float = 0.0):
        self.beta, self.offset = float(beta), float(offset)
        self.weights = np.full(n, 1.0 / (n - 1))
        self.weights[[0, -1]] *= 0.5
        self.group = None

    def bind(self, medium) -> None:
        self.group = medium.group

    def _frozen(self, ybar: float):
        return lambda Phi: self.beta * (ybar + self.offset) * dead_to_body(self.group, Phi, E_Y)

    def force(self, Phi, N, t):
        return self._frozen(float(self.weights @ Phi[:, 2, 0]))(Phi)

    def jacobian_parts(self, Phi, t):
        U = self.beta * dead_to_body(self.group, Phi, E_Y)[..., None]  # [n, 3, 1]
        V = np.zeros_like(U)
        V[:, :2, 0] = self.weights[:, None] * Phi[:, 2, 1:]  # ∂y_j/∂η_j = (R_j)[y, :]
        return self._frozen(float(self.weights @ Phi[:, 2, 0])), U, V


def _column(n: int = 21, beta: float = BETA, offset: float = 0.0) -> cartan.Problem:
    rod = cartan.medium("planar-cosserat-rod", stretch_shear=[1e6, 1e6], bending=1.0, mass=1.0,
                        rotational_inertia=1.0)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Free(), "end": cartan.Free(load=[-1.0, 0.0, 0.0])},
                          loads=[MeanDeflectionLoad(beta, n, offset)])


def _equilibrium(prob: cartan.Problem, lam: float):
    """(system, state, μ) of the equilibrium at the load factor λ reached from the straight column
    (the settle Newton of the continuation, λ held)."""
    eq = _Equilibrium(prob, pins=rigid_gauge_pins(prob, PINS), probe_lam=0.0)
    scale = np.concatenate([eq.delta_scale, np.zeros(eq.nmult)])

    def move(pt, alpha, d):
        s, u = eq.update(pt.state, pt.mu, d, alpha)
        return _Point(s, u, lam)

    out = _newton(eq, _Point(eq.state0, np.zeros(eq.nmult), lam),
                  residual=lambda pt: eq.residual(pt.state, pt.mu, lam),
                  factorise=lambda pt, offset: _factorise(eq, pt.state, pt.mu, lam, offset), move=move,
                  converged=lambda pt, r: float(np.abs(r).max()) <= 1e-10 * lam, scale=scale, max_iter=20,
                  max_halvings=20, xtol=1e-14)
    assert out.converged
    return eq, out.point.state, out.point.mu


def _dense_jacobian(eq, state, mu, lam, h=1e-6) -> np.ndarray:
    """Central differences of the residual along every unknown (drifts and multipliers), (m, m)."""
    cols = []
    for j in range(eq.m):
        d = np.zeros(eq.m)
        d[j] = h
        plus = eq.residual(*eq.update(state, mu, d), lam)
        minus = eq.residual(*eq.update(state, mu, -d), lam)
        cols.append((plus - minus) / (2 * h))
    return np.column_stack(cols)


@pytest.fixture(scope="module")
def straight():
    """The straight equilibrium at λ = 0.75 π², between λ_c ≈ π²/2 and Euler's π²."""
    lam = 0.75 * math.pi**2
    eq, state, mu = _equilibrium(_column(), lam)
    K, low = eq.jacobian(state, mu, lam, low_rank=True)
    return eq, state, mu, lam, K, low, _dense_jacobian(eq, state, mu, lam)


def test_determinant_lemma_sign_matches_dense(straight):
    """det J by the matrix determinant lemma against ``slogdet`` of the dense finite-difference
    Jacobian: same sign, log|det| within 1e-6 (the differences' relative error ~1e-9 per entry,
    summed over m = 66 eigenvalues, measured 3e-9).  At λ = 0 both signs agree; at 0.75 π² the
    whole Jacobian has crossed the critical point λ_c and changed sign, the stencil part has not
    (it crosses at Euler's π²): the stencil-only sign, which the continuation used before, is
    wrong there."""
    eq, state, mu, lam, K, low, D = straight
    assert low is not None and low[0].shape == (eq.m, 1)
    sign_d, log_d = np.linalg.slogdet(D)
    sign, logabs = _log_det(K, low)
    assert sign == int(sign_d) and abs(logabs - log_d) <= 1e-6, (sign, sign_d, logabs, log_d)
    sign0 = _log_det(*eq.jacobian(eq.state0, np.zeros(eq.nmult), 0.0, low_rank=True))[0]
    assert sign == -sign0  # one crossing, λ_c, below 0.75 π²
    assert _log_det(K)[0] == sign0  # the stencil part alone: no crossing yet


def test_eig_min_uses_the_whole_jacobian(straight):
    """The eigenvalue of smallest magnitude of sym J (shift-invert on the Woodbury operator) against
    the dense ``eigh`` of sym(K + U Vᵀ) to 1e-6 relative (round-off of both, ε·‖S‖ ≈ 4e-9 absolute
    on ‖S‖ ~ 4e7, measured 2e-7 relative) and of the symmetrised dense finite-difference Jacobian
    to 1e-5 (measured 5e-8); its eigenvector solves sym J φ = eig φ.  The stencil part alone has
    its eigenvalue of smallest magnitude of the other sign (−0.057 against +0.030 measured): it
    has not crossed λ_c."""
    eq, state, mu, lam, K, low, D = straight
    eig, phi = _eig_min(K, with_vector=True, low=low)
    J = K.toarray() + low[0] @ low[1].T
    S = 0.5 * (J + J.T)
    vals = np.linalg.eigvalsh(S)
    ref = vals[np.argmin(np.abs(vals))]
    assert abs(eig - ref) <= 1e-6 * abs(ref), (eig, ref)
    vals_d = np.linalg.eigvalsh(0.5 * (D + D.T))
    ref_d = vals_d[np.argmin(np.abs(vals_d))]
    assert abs(eig - ref_d) <= 1e-5 * abs(ref_d), (eig, ref_d)
    assert np.linalg.norm(S @ phi - eig * phi) <= 1e-6 * abs(eig) * np.linalg.norm(phi)
    assert _eig_min(K) * ref_d < 0


def test_low_rank_helpers_against_dense_matrices():
    """``_log_det`` (determinant lemma) and ``_eig_min`` (Woodbury shift-invert) on a random sparse
    K (n = 60, symmetric part indefinite) plus a rank-3 part, against dense ``slogdet`` and
    ``eigh`` of K + U Vᵀ: round-off (cond 1.8e3, measured 1e-14, asserted 1e-9 relative).  Badly scaled parts
    (U ~ 1e-6, V ~ 1e6) give the same result; a vanishing part (U = 0, a load at λ = 0) gives the
    sparse computation's own result, bit for bit."""
    import scipy.sparse as sp

    rng = np.random.default_rng(7)
    n, k = 60, 3
    A = sp.random(n, n, density=0.08, random_state=8)
    K = (A + A.T + sp.diags(np.linspace(-3.0, 5.0, n))).tocsc()
    U, V = rng.standard_normal((n, k)), rng.standard_normal((n, k))
    for scale in (1.0, 1e-6):
        low = (scale * U, V / scale)
        J = K.toarray() + U @ V.T
        sign, logabs = _log_det(K, low)
        ref = np.linalg.slogdet(J)
        assert sign == int(ref[0]) and abs(logabs - ref[1]) <= 1e-9 * abs(ref[1]) + 1e-9
        vals = np.linalg.eigvalsh(0.5 * (J + J.T))
        eig = vals[np.argmin(np.abs(vals))]
        assert abs(_eig_min(K, low=low) - eig) <= 1e-9 * abs(eig), (scale, _eig_min(K, low=low), eig)
    zero = (np.zeros((n, k)), V)
    assert _eig_min(K, low=zero) == _eig_min(K)
    assert _log_det(K, zero) == _log_det(K)


def _wnorm(eq, tu, tl, wl):
    return math.sqrt(float(np.sum(tu[: eq.nunk] ** 2)) / eq.nnode + wl * tl * tl)


def test_tangent_solves_with_the_whole_jacobian():
    """The tangent (Woodbury on the bordered LU) against the dense solve of the bordered
    finite-difference system, on the imperfect column (offset c = 0.01) at its equilibrium at
    λ = 0.4 π² (below λ_c, bent: ȳ ≠ 0, and every increment of λ changes ȳ, which feeds back
    through the rank-1 part).  Both unit in the weighted norm ‖δ‖²/n + (λ/λ_s)² of the
    continuation, their difference relative to the displacement part: measured 1.5e-9, asserted
    1e-6 (the differences' error times the conditioning); the stencil part alone (ȳ held) misses
    the feedback ``1/(1 − βλ g)`` of the mean deflection's growth: measured 0.64, asserted > 0.1."""
    lam = 0.4 * math.pi**2
    eq, st, mu = _equilibrium(_column(offset=0.01), lam)
    K, low = eq.jacobian(st, mu, lam, low_rank=True)
    D = _dense_jacobian(eq, st, mu, lam)
    f = eq.dlam(st)
    wv = np.concatenate([np.full(eq.nunk, 1.0 / eq.nnode), np.zeros(eq.nmult)])
    wl = 1.0 / (math.pi**2) ** 2
    tu_prev, tl_prev = np.zeros(eq.m), 1.0
    tu, tl = _tangent(K, low, f, wv, wl, tu_prev, tl_prev)
    B = np.block([[D, f[:, None]], [(wv * tu_prev)[None, :], np.array([[wl * tl_prev]])]])
    z = np.linalg.solve(B, np.eye(eq.m + 1)[-1])
    z /= _wnorm(eq, z[:-1], z[-1], wl) * np.sign(z[-1])
    zu = _wnorm(eq, z[:-1], 0.0, wl)  # the displacement part of the unit tangent
    err = _wnorm(eq, tu - z[:-1], tl - z[-1], wl) / zu
    assert err <= 1e-6, err
    tu0, tl0 = _tangent(K, None, f, wv, wl, tu_prev, tl_prev)
    err0 = _wnorm(eq, tu0 - z[:-1], tl0 - z[-1], wl) / zu
    assert err0 >= 1e-1, err0


@pytest.mark.slow
def test_continuation_finds_the_lowered_critical_load():
    """The continuation locates the bifurcation of the straight column at λ_c of the continuum
    (``1 = βλ g(√λ)``, λ_c = π²/2 at β = 12.17), not at Euler's π² where the stencil part alone
    becomes singular (n = 21: one bifurcation, at 1.002 π², none at λ_c): measured
    relative errors +4.14e-3 (n = 21) and +1.03e-3 (n = 41), order 2.0 (the lattice's bending and
    the trapezoidal mean, both second order); their Richardson extrapolation is within 5.4e-6 of
    λ_c.  Asserted: exactly one critical point below 0.9 π², a bifurcation, order ≥ 1.8, error
    ≤ 1.5e-3 at n = 41 and the extrapolation within 1e-4."""
    lam_c = critical_load(BETA)
    errs = {}
    for n in (21, 41):
        ds = continuation(_column(n), 0.9 * math.pi**2, 0.1, pins=PINS, branch_switch=False)
        assert list(ds["critical_kind"].values) == ["bifurcation"], ds["critical_kind"].values
        errs[n] = float(ds["critical_load"][0]) / lam_c - 1.0
    assert math.log2(errs[21] / errs[41]) >= 1.8, errs
    assert abs(errs[41]) <= 1.5e-3, errs
    assert abs(4 * errs[41] - errs[21]) / 3 <= 1e-4, errs
