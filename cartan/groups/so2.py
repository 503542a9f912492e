"""The rotation group SO(2) in closed form.

Conventions
-----------
* One algebra component ``θ``; ``hat(θ) = [[0, −θ], [θ, 0]]`` (the single basis element
  ``b = [[0, −1], [1, 0]]``) and ``vee(A) = ½(A21 − A12)``, the least-squares inverse of
  ``hat``.
* ``exp(θ) = [[cos θ, −sin θ], [sin θ, cos θ]]`` and ``log(R) = atan2(R21 − R12, R11 + R22)``
  ∈ (−π, π] (accurate up to and at θ = π; for a matrix slightly off the group it returns
  the angle of its nearest rotation-dilation).
* The group is abelian: ``Ad_R = 1``, ``ad_θ = 0``, ``[θ, φ] = 0``, ``dexp = dexp⁻¹ = 1`` and
  ``𝓔(Δt, Y) = Δt`` (all as ``1 × 1`` matrices).

Kernels
-------
The per-point kernels ``so2_*_point`` are public, allocation-free and
``@njit(cache=True)``; the batch loops ``_*_batch`` map them over ``P`` flattened points and
are listed in :attr:`SO2._kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._batch import kernel_table
from .base import SymmetryGroup

__all__ = [
    "SO2",
    "so2_Ad_point",
    "so2_E_point",
    "so2_act_point",
    "so2_ad_point",
    "so2_bracket_point",
    "so2_compose_point",
    "so2_dexp_inv_point",
    "so2_dexp_point",
    "so2_exp_point",
    "so2_hat_point",
    "so2_inverse_point",
    "so2_log_point",
    "so2_vee_point",
]


# ---------------------------------------------------------------------- numba point kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def so2_hat_point(xi, out):
    """``out`` (2, 2) ← ``hat(θ)`` for ``xi`` (1,)."""
    out[0, 0] = 0.0
    out[0, 1] = -xi[0]
    out[1, 0] = xi[0]
    out[1, 1] = 0.0


@njit(cache=True, inline='always')
def so2_vee_point(A, out):
    """``out`` (1,) ← ``½(A21 − A12)`` for ``A`` (2, 2)."""
    out[0] = 0.5 * (A[1, 0] - A[0, 1])


@njit(cache=True, inline='always')
def so2_exp_point(xi, out):
    """``out`` (2, 2) ← the rotation by ``θ = xi[0]``."""
    c = np.cos(xi[0])
    s = np.sin(xi[0])
    out[0, 0] = c
    out[0, 1] = -s
    out[1, 0] = s
    out[1, 1] = c


@njit(cache=True, inline='always')
def so2_log_point(R, out):
    """``out`` (1,) ← ``atan2(R21 − R12, R11 + R22)`` ∈ (−π, π] for ``R`` (2, 2)."""
    out[0] = np.arctan2(R[1, 0] - R[0, 1], R[0, 0] + R[1, 1])


@njit(cache=True, inline='always')
def so2_compose_point(R1, R2, out):
    """``out`` (2, 2) ← ``R1 R2``; ``out`` must not alias the inputs."""
    for i in range(2):
        for j in range(2):
            out[i, j] = R1[i, 0] * R2[0, j] + R1[i, 1] * R2[1, j]


@njit(cache=True, inline='always')
def so2_inverse_point(R, out):
    """``out`` (2, 2) ← ``Rᵀ``; ``out`` must not alias ``R``."""
    out[0, 0] = R[0, 0]
    out[0, 1] = R[1, 0]
    out[1, 0] = R[0, 1]
    out[1, 1] = R[1, 1]


@njit(cache=True, inline='always')
def so2_act_point(R, x, out):
    """``out`` (2,) ← ``R x``."""
    out[0] = R[0, 0] * x[0] + R[0, 1] * x[1]
    out[1] = R[1, 0] * x[0] + R[1, 1] * x[1]


@njit(cache=True, inline='always')
def so2_Ad_point(R, out):
    """``out`` (1, 1) ← ``Ad_R = 1``."""
    out[0, 0] = 1.0


@njit(cache=True, inline='always')
def so2_ad_point(xi, out):
    """``out`` (1, 1) ← ``ad_θ = 0``."""
    out[0, 0] = 0.0


@njit(cache=True, inline='always')
def so2_bracket_point(xi, eta, out):
    """``out`` (1,) ← ``[θ, φ] = 0``."""
    out[0] = 0.0


@njit(cache=True, inline='always')
def so2_dexp_point(xi, out):
    """``out`` (1, 1) ← ``dexp(θ) = 1``."""
    out[0, 0] = 1.0


@njit(cache=True, inline='always')
def so2_dexp_inv_point(xi, out):
    """``out`` (1, 1) ← ``dexp(θ)⁻¹ = 1``."""
    out[0, 0] = 1.0


@njit(cache=True, inline='always')
def so2_E_point(dt, xi, out):
    """``out`` (1, 1) ← ``𝓔(Δt, Y) = Δt`` for scalar ``dt``."""
    out[0, 0] = dt


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        so2_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        so2_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        so2_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        so2_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        so2_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        so2_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        so2_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        so2_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        so2_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(xi, eta, out):
    for p in range(xi.shape[0]):
        so2_bracket_point(xi[p], eta[p], out[p])


@njit(cache=True)
def _dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        so2_dexp_point(xi[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        so2_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _E_batch(dt, xi, out):
    for p in range(xi.shape[0]):
        so2_E_point(dt[p], xi[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def rotation_defect(R: np.ndarray) -> np.ndarray:
    """``‖RᵀR − I‖_F + |det R − 1|`` for square matrices ``R`` ``[..., n, n]`` → ``[...]``."""
    n = R.shape[-1]
    orth = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(n), axis=(-2, -1))
    return orth + np.abs(np.linalg.det(R) - 1.0)


def _ones(lead: tuple[int, ...], value: float = 1.0) -> np.ndarray:
    return np.full((*lead, 1, 1), value)


# ---------------------------------------------------------------------- the group
class SO2(SymmetryGroup):
    """Rotations of the plane: ``R ∈ R^{2×2}``, ``RᵀR = I``, ``det R = 1``; algebra so(2) ≅ R.

    The algebra component ``θ`` ``[..., 1]`` is the rotation angle; ``hat(θ) = [[0, −θ],
    [θ, 0]]``.  Every operation is closed-form (see the module docstring).
    """

    name = "SO2"
    dim = 1
    matrix_size = 2
    _kernels = kernel_table(globals())
    _point_prefix = "so2"

    def basis(self) -> np.ndarray:
        """The generator ``b = [[0, −1], [1, 0]]``, shape ``(1, 2, 2)``."""
        return np.array([[[0.0, -1.0], [1.0, 0.0]]])

    def defect(self, g) -> np.ndarray:
        """Distance from SO(2): ``‖gᵀg − I‖_F + |det g − 1|``.

        Parameters
        ----------
        g : array_like, shape ``[..., 2, 2]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
        """
        return rotation_defect(self._element(g))

    def log_domain_norm(self, xi) -> np.ndarray:
        """The rotation angle ``|θ|`` of ``xi`` ``[..., 1]`` → ``[...]``."""
        return np.abs(self._algebra(xi)[..., 0])

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 2, 2))
        out[..., 0, 1] = -xi[..., 0]
        out[..., 1, 0] = xi[..., 0]
        return out

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return 0.5 * (A[..., 1, 0] - A[..., 0, 1])[..., None]

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        return np.swapaxes(g, -1, -2).copy()

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", g, x)

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        c, s = np.cos(xi[..., 0]), np.sin(xi[..., 0])
        out = np.empty((*xi.shape[:-1], 2, 2))
        out[..., 0, 0] = c
        out[..., 0, 1] = -s
        out[..., 1, 0] = s
        out[..., 1, 1] = c
        return out

    def _log(self, g: np.ndarray) -> np.ndarray:
        return np.arctan2(g[..., 1, 0] - g[..., 0, 1], g[..., 0, 0] + g[..., 1, 1])[..., None]

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        return _ones(g.shape[:-2])

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        return _ones(xi.shape[:-1], 0.0)

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        return np.zeros(np.broadcast_shapes(xi.shape, eta.shape))

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return _ones(xi.shape[:-1])

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        return _ones(xi.shape[:-1])

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        lead = np.broadcast_shapes(dt.shape, Y.shape[:-1])
        return np.broadcast_to(dt, lead)[..., None, None].copy()
