"""Compiled point kernels of the elastic string in the temporal gauge (docs/media/relativistic-rod.md §2–§3).

One point (a half-edge of the lattice: a node's momentum with an edge's strain) at a time, the
temporal-gauge forms of :mod:`cartan_relativistic.elastic` for the built-in laws:

* :func:`momentum_hessian_point` — p⃗ = ∂ℓ/∂v⃗ and ∂²ℓ/∂v⃗² at (v⃗, x⃗′);
* :func:`velocity_point` — the inverse Legendre map v⃗(p⃗, x⃗′) = ∂H/∂p⃗ by Newton's method
  (the closed-form Hessian, the Newtonian start c²p⃗/ε(|x⃗′|) held inside 0.9c, steps halved
  while they would leave the light cone, one more step once the correction is below 10⁻¹²
  of max(|v⃗|, 10⁻³c)); False when it does not converge;
* :func:`stress_point` — Q⃗ = ∂H/∂x⃗′ = −∂ℓ/∂x⃗′ at (v⃗, x⃗′), the v⃗ that
  :func:`velocity_point` solved (one Newton solve per half-edge serves both);
* :func:`hamiltonian_point` — H = p⃗·v⃗ − ℓ − μc²;
* :func:`coupled_jacobian_point` — ∂v⃗/∂p⃗ = (∂²ℓ/∂v⃗²)⁻¹ at the v⃗ solved, the Jacobian of the
  Legendre map's inversion in ``implicit-midpoint``'s compiled stage momenta.

These are the point kernels the compiled coupled-Lagrangian path needs from the medium (the
half-edge velocities and stresses of :mod:`cartan.schemes._coupled`): :func:`medium_kernels`
declares them in the contract's form (:class:`cartan.medium.MediumKernels`, over the whole
Poincaré algebra, with :func:`velocity_solve`'s continuation when Newton's method from the
Newtonian start fails), and the lattice's generated loops of ``rkmk4``, ``lie-euler`` and
``forward-euler`` call them (docs/media/relativistic-rod.md §3).  The law enters as ``(kind, params)``
(:func:`law_kernel`): ``kind`` 0 is ``quadratic`` (k), 1 ``quartic`` (k, q); ``mc2`` is μc².
A law without kernels (a registered user law) has none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from cartan.compiled.linalg import solve_augmented

__all__ = ["coupled_jacobian_point", "coupled_stress_point", "coupled_velocity_point", "energy_point",
           "hamiltonian_point", "law_kernel", "law_point", "medium_kernels", "momentum_hessian_point",
           "potential_stress_point", "stress_point", "velocity_batch", "velocity_point", "velocity_solve"]

#: the built-in laws with kernels, by kind
KINDS = ("quadratic", "quartic")


def law_kernel(law: Any) -> tuple[int, np.ndarray] | None:
    """``(kind, params)`` of a built-in law (:meth:`ElasticLaw.quadratic`, :meth:`ElasticLaw.quartic`,
    or made by name while the built-in factory is registered), else None."""
    from . import elastic

    record = getattr(law, "record", None)
    if not record or record.get("name") not in KINDS:
        return None
    name = record["name"]
    if elastic._LAWS.get(name) is not {"quadratic": elastic._quadratic, "quartic": elastic._quartic}[name]:
        return None  # (the name was registered again, to another law)
    keys = ("k",) if name == "quadratic" else ("k", "q")
    return KINDS.index(name), np.array([float(record[k]) for k in keys])


@njit(cache=True)
def law_point(kind, prm, lam):  # pragma: no cover - compiled
    """``(W, W′, W″)`` at the stretch λ: ½k(λ − 1)² (kind 0), + ¼q(λ − 1)⁴ (kind 1)."""
    d = lam - 1.0
    k = prm[0]
    if kind == 0:
        return 0.5 * k * d * d, k * d, k
    q = prm[1]
    return 0.5 * k * d * d + 0.25 * q * d ** 4, k * d + q * d ** 3, k + 3.0 * q * d * d


@njit(cache=True)
def momentum_hessian_point(v, x, kind, prm, mc2, c, p, J):  # pragma: no cover - compiled
    """p⃗ = [ε v⃗/a − T a ∂λ/∂v⃗]/c into ``p`` (3,) and ∂²ℓ/∂v⃗² into ``J`` (3, 3)
    (:func:`cartan_relativistic.elastic.temporal_hessian`); False outside the light cone."""
    return _momentum_hessian(v, x, kind, prm, mc2, c, p, J, np.empty(3))


@njit(cache=True)
def _momentum_hessian(v, x, kind, prm, mc2, c, p, J, dl):  # pragma: no cover - compiled
    """:func:`momentum_hessian_point` with the work array ``dl`` (3,) (∂λ/∂v⃗)."""
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    a2 = c * c - vv
    if not a2 > 0.0:
        return False
    g = 1.0 / a2
    a = math.sqrt(a2)
    b = v[0] * x[0] + v[1] * x[1] + v[2] * x[2]
    lam = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + b * b * g)
    bg = b * g
    for i in range(3):
        dl[i] = bg * (x[i] + bg * v[i]) / lam
    W, T, K = law_point(kind, prm, lam)
    eps = mc2 + W
    for i in range(3):
        p[i] = (eps / a * v[i] - T * a * dl[i]) / c
    for i in range(3):
        for j in range(3):
            eye = 1.0 if i == j else 0.0
            hq = (2.0 * g * x[i] * x[j] + 4.0 * b * g * g * (x[i] * v[j] + v[i] * x[j]) + 2.0 * b * b * g * g * eye
                  + 8.0 * b * b * g ** 3 * v[i] * v[j])
            hl = hq / (2.0 * lam) - dl[i] * dl[j] / lam
            ha = -eye / a - v[i] * v[j] / (a * a * a)
            J[i, j] = -(K * a * dl[i] * dl[j] + T * (dl[i] * (-v[j] / a) + (-v[i] / a) * dl[j]) + T * a * hl
                        + eps * ha) / c
    return True


@njit(cache=True)
def _solve3(J, r, out, A):  # pragma: no cover - compiled
    """``out = J⁻¹r`` (3 × 3, ``A`` (3, 4) work; :func:`cartan.compiled.linalg.solve_augmented`);
    False if singular."""
    for i in range(3):
        for j in range(3):
            A[i, j] = J[i, j]
        A[i, 3] = r[i]
    return solve_augmented(A, out)


@njit(cache=True)
def velocity_point(p, x, kind, prm, mc2, c, iterations, v):  # pragma: no cover - compiled
    """v⃗(p⃗, x⃗′) into ``v`` (3,) by Newton's method (module docstring); False when it fails."""
    lx = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    eps = mc2 + law_point(kind, prm, lx)[0]
    speed = 0.0
    for i in range(3):
        v[i] = p[i] * (c * c / eps)
        speed += v[i] * v[i]
    speed = math.sqrt(speed)
    if speed >= 0.9 * c:
        for i in range(3):
            v[i] *= 0.9 * c / speed
    return _newton_from(p, x, kind, prm, mc2, c, iterations, v)


@njit(cache=True)
def velocity_solve(p, x, kind, prm, mc2, c, iterations, v):  # pragma: no cover - compiled
    """:func:`velocity_point`, and when it fails the continuation from p⃗ = 0 in 32 stages of
    :func:`cartan_relativistic.elastic.temporal_velocity` (fast motion along the string); False
    when that fails too."""
    if velocity_point(p, x, kind, prm, mc2, c, iterations, v):
        return True
    ps = np.empty(3)
    for i in range(3):
        v[i] = 0.0
    for stage in range(1, 33):
        s = stage / 32.0
        for i in range(3):
            ps[i] = s * p[i]
        if not _newton_from(ps, x, kind, prm, mc2, c, iterations, v):
            return False
    return True


@njit(cache=True)
def _newton_from(p, x, kind, prm, mc2, c, iterations, v):  # pragma: no cover - compiled
    """Newton's method for p⃗(v⃗) = p⃗ from the start ``v`` (3,), in place; False when it fails."""
    P = np.empty(3)
    J = np.empty((3, 3))
    R = np.empty(3)
    dv = np.empty(3)
    dl = np.empty(3)
    A = np.empty((3, 4))
    done = False
    for _ in range(iterations):
        if not _momentum_hessian(v, x, kind, prm, mc2, c, P, J, dl):
            return False
        for i in range(3):
            R[i] = P[i] - p[i]
        if not _solve3(J, R, dv, A):
            return False
        alpha = 1.0
        for _ in range(60):  # stay inside the light cone
            s = 0.0
            for i in range(3):
                w = v[i] - alpha * dv[i]
                s += w * w
            if math.sqrt(s) < c:
                break
            alpha *= 0.5
        for i in range(3):
            v[i] -= alpha * dv[i]
        if done:
            return True
        sv = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        sd = math.sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2])
        done = sd <= 1e-12 * max(sv, 1e-3 * c) and alpha == 1.0
    return False


@njit(cache=True)
def stress_point(v, x, kind, prm, mc2, c, Q):  # pragma: no cover - compiled
    """Q⃗ = (T a/(c λ))(x⃗′ + (B/A) v⃗) into ``Q`` (3,) (:func:`~cartan_relativistic.elastic.temporal_stress`)."""
    a2 = c * c - (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    g = 1.0 / a2
    b = v[0] * x[0] + v[1] * x[1] + v[2] * x[2]
    lam = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + b * b * g)
    T = law_point(kind, prm, lam)[1]
    f = T * math.sqrt(a2) / (c * lam)
    for i in range(3):
        Q[i] = f * (x[i] + b * g * v[i])


@njit(cache=True)
def hamiltonian_point(p, v, x, kind, prm, mc2, c):  # pragma: no cover - compiled
    """H = p⃗·v⃗ − ℓ(v⃗, x⃗′) − μc², ℓ = −ε(λ)√(c² − v²)/c."""
    a2 = c * c - (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    b = v[0] * x[0] + v[1] * x[1] + v[2] * x[2]
    lam = math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + b * b / a2)
    eps = mc2 + law_point(kind, prm, lam)[0]
    return p[0] * v[0] + p[1] * v[1] + p[2] * v[2] + eps * math.sqrt(a2) / c - mc2


@njit(cache=True)
def velocity_batch(P, X, kind, prm, mc2, c, iterations, V, ok):  # pragma: no cover - compiled
    """:func:`velocity_point` over points ``P``, ``X`` ``[n, 3]`` into ``V`` ``[n, 3]`` and ``ok`` ``[n]``."""
    for i in range(P.shape[0]):
        ok[i] = velocity_point(P[i], X[i], kind, prm, mc2, c, iterations, V[i])


# ---------------------------------------------------------------------------- the medium's kernels
# The contract's point kernels (cartan.medium.MediumKernels) over the Poincaré algebra, r = 10,
# d = 1: X ``(1, 10)`` with x⃗′ = X[0, 1:4], S and N ``(10,)`` with p⃗ = S[1:4], v⃗ = N[1:4], and the
# parameters ``prm`` = (kind, μc², c, Newton iterations, law parameters…) of :func:`medium_kernels`.

@njit(cache=True)
def energy_point(X, X0, prm):  # pragma: no cover - compiled
    """U(X) = H(0, X) = W(|x⃗′|) (``ElasticRelativisticRod.potential``)."""
    x = X[0, 1:4]
    return law_point(int(prm[0]), prm[4:], math.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]))[0]


@njit(cache=True)
def potential_stress_point(X, X0, prm, Q):  # pragma: no cover - compiled
    """Q = ∂U/∂X: :func:`stress_point` at v⃗ = 0 on slots 1–3, zero elsewhere (``stress``)."""
    for k in range(Q.shape[1]):
        Q[0, k] = 0.0
    stress_point(np.zeros(3), X[0, 1:4], int(prm[0]), prm[4:], prm[1], prm[2], Q[0, 1:4])


@njit(cache=True)
def coupled_velocity_point(S, X, prm, N):  # pragma: no cover - compiled
    """N = (c, v⃗(p⃗, x⃗′), 0₆) (``velocity_at``) by :func:`velocity_solve`; False when it fails."""
    for k in range(N.shape[0]):
        N[k] = 0.0
    N[0] = prm[2]
    return velocity_solve(S[1:4], X[0, 1:4], int(prm[0]), prm[4:], prm[1], prm[2], int(prm[3]), N[1:4])


@njit(cache=True)
def coupled_stress_point(S, X, N, prm, Q):  # pragma: no cover - compiled
    """Q = ∂H/∂X(S, X): :func:`stress_point` at v⃗ = N[1:4] on slots 1–3, zero elsewhere (``stress_with``)."""
    for k in range(Q.shape[1]):
        Q[0, k] = 0.0
    stress_point(N[1:4], X[0, 1:4], int(prm[0]), prm[4:], prm[1], prm[2], Q[0, 1:4])


@njit(cache=True)
def coupled_jacobian_point(S, X, N, prm, J):  # pragma: no cover - compiled
    """J = ∂N/∂S(S, X) = ∂²H/∂S²: (∂²ℓ/∂v⃗²)⁻¹ (:func:`momentum_hessian_point` at v⃗ = N[1:4]) on slots
    1–3, zero elsewhere (the gauge slot 0 is c, the others zero); False outside the light cone or
    where the Hessian is singular."""
    for a in range(J.shape[0]):
        for b in range(J.shape[1]):
            J[a, b] = 0.0
    H = np.empty((3, 3))
    if not momentum_hessian_point(N[1:4], X[0, 1:4], int(prm[0]), prm[4:], prm[1], prm[2], np.empty(3), H):
        return False
    col = np.empty(3)
    e = np.zeros(3)
    A = np.empty((3, 4))
    for b in range(3):
        e[b] = 1.0
        if not _solve3(H, e, col, A):
            return False
        e[b] = 0.0
        for a in range(3):
            J[1 + a, 1 + b] = col[a]
    return True


@njit(cache=True)
def proper_time_rate_point(N, prm, out):  # pragma: no cover - compiled
    """dτ/dt = √(1 − |v⃗|²/c²) at one node, v⃗ = N[1:4], into ``out[0]`` (the rate of the
    accumulator ``proper_time``, ``accumulator_rates``; in its floating-point order)."""
    c = prm[2]
    s = N[1] * N[1] + N[2] * N[2] + N[3] * N[3]
    out[0] = math.sqrt(max(1.0 - s / (c * c), 0.0))


#: Newton iterations of the compiled Legendre map (as :func:`cartan_relativistic.elastic.temporal_velocity`)
ITERATIONS = 40


def medium_kernels(law: Any, mu: float, c: float):
    """The :class:`cartan.medium.MediumKernels` of the elastic string with the law ``law``
    (potential and coupled kernels with ∂N/∂S, the rate of the proper time, parameters (kind, μc², c,
    iterations, law parameters…)),
    or None for a law without kernels (:func:`law_kernel`)."""
    from cartan.medium import MediumKernels

    found = law_kernel(law)
    if found is None:
        return None
    kind, prm = found
    params = np.concatenate([[float(kind), float(mu) * float(c) ** 2, float(c), float(ITERATIONS)], prm])
    return MediumKernels(energy_point, potential_stress_point, params, coupled_velocity=coupled_velocity_point,
                         coupled_stress=coupled_stress_point, accumulator_rate=proper_time_rate_point,
                         coupled_jacobian=coupled_jacobian_point)
