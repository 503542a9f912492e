"""Point kernels for any matrix group, for the operations a group does not give in closed form.

``dexp`` and 𝓔 by the Van Loan block exponential (the numpy reference's
:meth:`~cartan.groups.base.SymmetryGroup.E_vanloan`): ``expm([[Δt ad_ξ, Δt I], [0, 0]])`` has
``𝓔(Δt, ξ) = Δt·dexp(Δtξ)`` as its upper-right block; ``dexp⁻¹`` is its inverse.  The matrix
exponential is Higham's scaling and squaring with the [13/13] Padé approximant (SIAM J. Matrix
Anal. Appl. 26, 2005), accurate to a few ulps of ‖·‖ like scipy's ``expm``.  They cost
microseconds per point, against tens of nanoseconds for the closed forms of SO(3) or SE(3): a
group that is used in earnest provides closed forms (``<prefix>_dexp_inv_point``,
``<prefix>_E_point``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["expm_point", "vanloan_E_point"]

_PADE13 = np.array([64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
                    129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
                    40840800.0, 960960.0, 16380.0, 182.0, 1.0])
_THETA13 = 5.371920351148152


@njit(cache=True)
def expm_point(A, out):  # pragma: no cover - compiled
    """``out`` ← exp(A) for a square float64 matrix ``A`` (Padé [13/13], scaling and squaring)."""
    n = A.shape[0]
    norm = 0.0
    for j in range(n):
        s = 0.0
        for i in range(n):
            s += abs(A[i, j])
        norm = max(norm, s)
    scale = 0
    if norm > _THETA13:
        scale = int(math.ceil(math.log2(norm / _THETA13)))
    B = A * (0.5 ** scale)
    eye = np.eye(n)
    B2 = B @ B
    B4 = B2 @ B2
    B6 = B4 @ B2
    b = _PADE13
    U = B @ (B6 @ (b[13] * B6 + b[11] * B4 + b[9] * B2) + b[7] * B6 + b[5] * B4 + b[3] * B2 + b[1] * eye)
    V = B6 @ (b[12] * B6 + b[10] * B4 + b[8] * B2) + b[6] * B6 + b[4] * B4 + b[2] * B2 + b[0] * eye
    R = np.ascontiguousarray(np.linalg.solve(V - U, V + U))
    for _ in range(scale):
        R = R @ R
    out[:, :] = R


@njit(cache=True)
def vanloan_E_point(dt, adxi, out):  # pragma: no cover - compiled
    """``out`` (r, r) ← 𝓔(Δt, ξ) from ``adxi`` = ad_ξ (r, r): the upper-right block of
    ``expm([[Δt ad_ξ, Δt I], [0, 0]])``."""
    r = adxi.shape[0]
    big = np.zeros((2 * r, 2 * r))
    for i in range(r):
        for j in range(r):
            big[i, j] = dt * adxi[i, j]
        big[i, r + i] = dt
    E = np.empty((2 * r, 2 * r))
    expm_point(big, E)
    for i in range(r):
        for j in range(r):
            out[i, j] = E[i, r + j]
