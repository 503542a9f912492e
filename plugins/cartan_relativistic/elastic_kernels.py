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
* :func:`hamiltonian_point` — H = p⃗·v⃗ − ℓ − μc².

These are the point kernels a compiled coupled-Lagrangian path needs from the medium (the
half-edge velocities and stresses of :mod:`cartan.schemes._coupled`); no compiled loop calls
them yet — the medium steps on the numpy path.  The law enters as ``(kind, params)``
(:func:`law_kernel`): ``kind`` 0 is ``quadratic`` (k), 1 ``quartic`` (k, q); ``mc2`` is μc².
A law without kernels (a registered user law) has none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from cartan.compiled.linalg import solve_augmented

__all__ = ["hamiltonian_point", "law_kernel", "law_point", "momentum_hessian_point", "stress_point",
           "velocity_batch", "velocity_point"]

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
