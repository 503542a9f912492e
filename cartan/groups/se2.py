"""The special Euclidean group SE(2) of the plane in closed form.

Conventions (the paper's affine form, homogeneous coordinate first)
-------------------------------------------------------------------
* An element is ``g = (a; R) = [[1, 0, 0], [a1, c, −s], [a2, s, c]]`` and acts on the plane by
  ``g·x = R x + a``.
* Algebra components ``ξ = (v1, v2, ω)``: translation first, rotation last (the planar
  Cosserat rod's ``(θ₁, θ₂, π)``), with ``hat(ξ) = [[0, 0, 0], [v1, 0, −ω], [v2, ω, 0]]``; the
  basis is ``b₁ = E₂₁``, ``b₂ = E₃₁``, ``b₃ = E₃₂ − E₂₃`` and ``vee`` returns
  ``(A21, A31, ½(A32 − A23))``.
* With ``J = [[0, −1], [1, 0]]``:

  - ``exp(ξ) = (V(ω) v; R(ω))``, ``V = A I + ωB J``, ``A = sin ω/ω``, ``B = (1 − cos ω)/ω²``;
  - ``log(g)``: ``ω = atan2(g32 − g23, g22 + g33)`` ∈ (−π, π] and ``v = V⁻¹a`` with
    ``V⁻¹ = α I − (ω/2) J``, ``α = (ω/2) cot(ω/2)``;
  - ``Ad_g = [[R, −J a], [0, 1]]``, ``ad_ξ = [[ωJ, −J v], [0, 0]]``,
    ``[ξ, η] = (ω J u − ν J v, 0)`` for ``η = (u, ν)``;
  - ``dexp(ξ) = Σ ad_ξᵏ/(k+1)! = [[V, p], [0, 1]]`` with ``p = −(B I + ωC J) J v``,
    ``C = (ω − sin ω)/ω³``;
  - ``dexp⁻¹(ξ) = [[V⁻¹, q], [0, 1]]`` with ``q = ½ J v + ωc v``,
    ``c = (1 − (ω/2) cot(ω/2))/ω²`` (so that ``α = 1 − ω² c``);
  - ``𝓔(Δt, Y) = Δt·dexp(ΔtY)``.

* :meth:`SE2.log_domain_norm` is the rotation angle ``|ω|``; ``log ∘ exp`` is the identity
  for ``|ω| < π`` whatever the translation.

Numerics
--------
``A``, ``B``, ``C`` and ``c`` are the SO(3) coefficients of :mod:`cartan.groups.so3`
(``so3_exp_coeffs``, ``so3_dexp_coeffs``, ``so3_dexp_inv_coeff`` and their vectorised
forms), evaluated from their Taylor series in ``ω²`` for small angles: both backends use the
same formulas, stable as ω → 0 and up to ω = π.  The rotation block uses ``cos ω``, ``sin ω``
directly.

Kernels
-------
The per-point kernels ``se2_*_point`` are public, allocation-free and
``@njit(cache=True)``; the batch loops ``_*_batch`` map them over ``P`` flattened points and
are listed in :attr:`SE2._kernels`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._batch import kernel_table
from .base import SymmetryGroup
from .so3 import (
    dexp_coeffs_np,
    dexp_inv_coeff_np,
    exp_coeffs_np,
    so3_dexp_coeffs,
    so3_dexp_inv_coeff,
    so3_exp_coeffs,
)

__all__ = [
    "SE2",
    "se2_Ad_point",
    "se2_E_point",
    "se2_act_point",
    "se2_ad_point",
    "se2_bracket_point",
    "se2_compose_point",
    "se2_dexp_inv_point",
    "se2_dexp_point",
    "se2_exp_point",
    "se2_hat_point",
    "se2_inverse_point",
    "se2_log_point",
    "se2_vee_point",
]


# ---------------------------------------------------------------------- numba point kernels
# ``inline='always'``: a kernel and the kernels it calls are compiled into the function that calls
# them (an out-of-line call of a compiled function is opaque to LLVM and costs more than the
# arithmetic of a point kernel); called from Python they compile as usual.
@njit(cache=True, inline='always')
def _zero_affine_row(out):
    out[0, 0] = 0.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0


@njit(cache=True, inline='always')
def _unit_last_row(out):
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = 1.0


@njit(cache=True, inline='always')
def se2_hat_point(xi, out):
    """``out`` (3, 3) ← ``[[0, 0, 0], [v1, 0, −ω], [v2, ω, 0]]`` for ``xi = (v1, v2, ω)``."""
    _zero_affine_row(out)
    out[1, 0] = xi[0]
    out[1, 1] = 0.0
    out[1, 2] = -xi[2]
    out[2, 0] = xi[1]
    out[2, 1] = xi[2]
    out[2, 2] = 0.0


@njit(cache=True, inline='always')
def se2_vee_point(A, out):
    """``out`` (3,) ← ``(A21, A31, ½(A32 − A23))`` for ``A`` (3, 3)."""
    out[0] = A[1, 0]
    out[1] = A[2, 0]
    out[2] = 0.5 * (A[2, 1] - A[1, 2])


@njit(cache=True, inline='always')
def se2_compose_point(g, h, out):
    """``out`` (3, 3) ← ``g h``; ``out`` must not alias the inputs."""
    for i in range(3):
        for j in range(3):
            out[i, j] = g[i, 0] * h[0, j] + g[i, 1] * h[1, j] + g[i, 2] * h[2, j]


@njit(cache=True, inline='always')
def se2_inverse_point(g, out):
    """``out`` (3, 3) ← ``g⁻¹ = (−Rᵀa; Rᵀ)``; ``out`` must not alias ``g``."""
    a1, a2 = g[1, 0], g[2, 0]
    out[0, 0] = 1.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[1, 0] = -(g[1, 1] * a1 + g[2, 1] * a2)
    out[2, 0] = -(g[1, 2] * a1 + g[2, 2] * a2)
    out[1, 1] = g[1, 1]
    out[1, 2] = g[2, 1]
    out[2, 1] = g[1, 2]
    out[2, 2] = g[2, 2]


@njit(cache=True, inline='always')
def se2_act_point(g, x, out):
    """``out`` (2,) ← ``R x + a``."""
    out[0] = g[1, 1] * x[0] + g[1, 2] * x[1] + g[1, 0]
    out[1] = g[2, 1] * x[0] + g[2, 2] * x[1] + g[2, 0]


@njit(cache=True, inline='always')
def se2_exp_point(xi, out):
    """``out`` (3, 3) ← ``exp(hat(ξ)) = (V v; R(ω))`` for ``xi = (v1, v2, ω)``."""
    v1, v2, w = xi[0], xi[1], xi[2]
    a, b = so3_exp_coeffs(w * w)
    wb = w * b
    out[0, 0] = 1.0
    out[0, 1] = 0.0
    out[0, 2] = 0.0
    out[1, 0] = a * v1 - wb * v2
    out[2, 0] = wb * v1 + a * v2
    c = np.cos(w)
    s = np.sin(w)
    out[1, 1] = c
    out[1, 2] = -s
    out[2, 1] = s
    out[2, 2] = c


@njit(cache=True, inline='always')
def se2_log_point(g, out):
    """``out`` (3,) ← principal logarithm ``(v1, v2, ω)`` of ``g`` (3, 3), ``|ω| ≤ π``."""
    w = np.arctan2(g[2, 1] - g[1, 2], g[1, 1] + g[2, 2])
    alpha = 1.0 - w * w * so3_dexp_inv_coeff(w * w)
    h = 0.5 * w
    a1, a2 = g[1, 0], g[2, 0]
    out[0] = alpha * a1 + h * a2
    out[1] = alpha * a2 - h * a1
    out[2] = w


@njit(cache=True, inline='always')
def se2_Ad_point(g, out):
    """``out`` (3, 3) ← ``Ad_g = [[R, −J a], [0, 1]]``."""
    out[0, 0] = g[1, 1]
    out[0, 1] = g[1, 2]
    out[0, 2] = g[2, 0]
    out[1, 0] = g[2, 1]
    out[1, 1] = g[2, 2]
    out[1, 2] = -g[1, 0]
    _unit_last_row(out)


@njit(cache=True, inline='always')
def se2_ad_point(xi, out):
    """``out`` (3, 3) ← ``ad_ξ = [[0, −ω, v2], [ω, 0, −v1], [0, 0, 0]]``."""
    out[0, 0] = 0.0
    out[0, 1] = -xi[2]
    out[0, 2] = xi[1]
    out[1, 0] = xi[2]
    out[1, 1] = 0.0
    out[1, 2] = -xi[0]
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = 0.0


@njit(cache=True, inline='always')
def se2_bracket_point(xi, eta, out):
    """``out`` (3,) ← ``[ξ, η] = ad_ξ η``."""
    out[0] = xi[1] * eta[2] - xi[2] * eta[1]
    out[1] = xi[2] * eta[0] - xi[0] * eta[2]
    out[2] = 0.0


@njit(cache=True, inline='always')
def _dexp_scaled(v1, v2, w, s, out):
    """``out`` (3, 3) ← ``s·dexp(v1, v2, w)``."""
    a = so3_exp_coeffs(w * w)[0]
    b, c = so3_dexp_coeffs(w * w)
    wb = w * b
    wc = w * c
    out[0, 0] = s * a
    out[0, 1] = -s * wb
    out[0, 2] = s * (wc * v1 + b * v2)
    out[1, 0] = s * wb
    out[1, 1] = s * a
    out[1, 2] = s * (wc * v2 - b * v1)
    out[2, 0] = 0.0
    out[2, 1] = 0.0
    out[2, 2] = s


@njit(cache=True, inline='always')
def se2_dexp_point(xi, out):
    """``out`` (3, 3) ← ``dexp(ξ) = [[V, p], [0, 1]]``."""
    _dexp_scaled(xi[0], xi[1], xi[2], 1.0, out)


@njit(cache=True, inline='always')
def se2_dexp_inv_point(xi, out):
    """``out`` (3, 3) ← ``dexp(ξ)⁻¹ = [[V⁻¹, q], [0, 1]]``."""
    v1, v2, w = xi[0], xi[1], xi[2]
    c = so3_dexp_inv_coeff(w * w)
    alpha = 1.0 - w * w * c
    h = 0.5 * w
    wc = w * c
    out[0, 0] = alpha
    out[0, 1] = h
    out[0, 2] = wc * v1 - 0.5 * v2
    out[1, 0] = -h
    out[1, 1] = alpha
    out[1, 2] = wc * v2 + 0.5 * v1
    _unit_last_row(out)


@njit(cache=True, inline='always')
def se2_E_point(dt, xi, out):
    """``out`` (3, 3) ← ``𝓔(Δt, ξ) = Δt·dexp(Δt ξ)`` for scalar ``dt``."""
    _dexp_scaled(dt * xi[0], dt * xi[1], dt * xi[2], dt, out)


# ---------------------------------------------------------------------- numba batch loops
@njit(cache=True)
def _hat_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_hat_point(xi[p], out[p])


@njit(cache=True)
def _vee_batch(A, out):
    for p in range(A.shape[0]):
        se2_vee_point(A[p], out[p])


@njit(cache=True)
def _compose_batch(g, h, out):
    for p in range(g.shape[0]):
        se2_compose_point(g[p], h[p], out[p])


@njit(cache=True)
def _inverse_batch(g, out):
    for p in range(g.shape[0]):
        se2_inverse_point(g[p], out[p])


@njit(cache=True)
def _act_batch(g, x, out):
    for p in range(g.shape[0]):
        se2_act_point(g[p], x[p], out[p])


@njit(cache=True)
def _exp_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_exp_point(xi[p], out[p])


@njit(cache=True)
def _log_batch(g, out):
    for p in range(g.shape[0]):
        se2_log_point(g[p], out[p])


@njit(cache=True)
def _Ad_batch(g, out):
    for p in range(g.shape[0]):
        se2_Ad_point(g[p], out[p])


@njit(cache=True)
def _ad_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_ad_point(xi[p], out[p])


@njit(cache=True)
def _bracket_batch(xi, eta, out):
    for p in range(xi.shape[0]):
        se2_bracket_point(xi[p], eta[p], out[p])


@njit(cache=True)
def _dexp_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_dexp_point(xi[p], out[p])


@njit(cache=True)
def _dexp_inv_batch(xi, out):
    for p in range(xi.shape[0]):
        se2_dexp_inv_point(xi[p], out[p])


@njit(cache=True)
def _E_batch(dt, xi, out):
    for p in range(xi.shape[0]):
        se2_E_point(dt[p], xi[p], out[p])


# ---------------------------------------------------------------------- numpy helpers
def _dexp_np(v1: np.ndarray, v2: np.ndarray, w: np.ndarray, s) -> np.ndarray:
    """Vectorised :func:`_dexp_scaled`: ``s·dexp(v1, v2, w)`` ``[..., 3, 3]``."""
    t2 = w * w
    a = exp_coeffs_np(t2)[0]
    b, c = dexp_coeffs_np(t2)
    wb = w * b
    wc = w * c
    s = np.asarray(s, dtype=float)
    out = np.zeros((*np.broadcast_shapes(w.shape, s.shape), 3, 3))
    out[..., 0, 0] = s * a
    out[..., 0, 1] = -s * wb
    out[..., 0, 2] = s * (wc * v1 + b * v2)
    out[..., 1, 0] = s * wb
    out[..., 1, 1] = s * a
    out[..., 1, 2] = s * (wc * v2 - b * v1)
    out[..., 2, 2] = s
    return out


# ---------------------------------------------------------------------- the group
class SE2(SymmetryGroup):
    """Rigid motions of the plane in the paper's affine form ``(a; R)``, homogeneous coordinate first.

    Elements are ``[..., 3, 3]`` matrices ``[[1, 0, 0], [a1, c, −s], [a2, s, c]]``; algebra
    components are ``ξ = (v1, v2, ω)`` ``[..., 3]`` (translation first, rotation last).  All
    operations are closed-form; see the module docstring for the formulas.
    """

    name = "SE2"
    dim = 3
    matrix_size = 3
    affine = True
    _kernels = kernel_table(globals())
    _point_prefix = "se2"

    def basis(self) -> np.ndarray:
        """Generators ``(E₂₁, E₃₁, E₃₂ − E₂₃)``, shape ``(3, 3, 3)``."""
        return self._hat(np.eye(3))

    def defect(self, g) -> np.ndarray:
        """Distance from SE(2).

        Parameters
        ----------
        g : array_like, shape ``[..., 3, 3]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
            ``‖RᵀR − I‖_F + |det R − 1| + ‖(g11 − 1, g12, g13)‖`` with ``R = g[..., 1:, 1:]``.
        """
        g = self._element(g)
        R = g[..., 1:, 1:]
        orth = np.linalg.norm(np.swapaxes(R, -1, -2) @ R - np.eye(2), axis=(-2, -1))
        det = R[..., 0, 0] * R[..., 1, 1] - R[..., 0, 1] * R[..., 1, 0]
        row = np.sqrt((g[..., 0, 0] - 1.0) ** 2 + g[..., 0, 1] ** 2 + g[..., 0, 2] ** 2)
        return orth + np.abs(det - 1.0) + row

    def log_domain_norm(self, xi) -> np.ndarray:
        """The rotation angle ``|ω|`` of ``xi`` ``[..., 3]`` → ``[...]``."""
        return np.abs(self._algebra(xi)[..., 2])

    # ------------------------------------------------------------------ numpy reference
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 1, 0] = xi[..., 0]
        out[..., 2, 0] = xi[..., 1]
        out[..., 1, 2] = -xi[..., 2]
        out[..., 2, 1] = xi[..., 2]
        return out

    def _vee(self, A: np.ndarray) -> np.ndarray:
        return np.stack([A[..., 1, 0], A[..., 2, 0], 0.5 * (A[..., 2, 1] - A[..., 1, 2])], axis=-1)

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        a1, a2 = g[..., 1, 0], g[..., 2, 0]
        out = np.zeros(g.shape)
        out[..., 0, 0] = 1.0
        out[..., 1, 0] = -(g[..., 1, 1] * a1 + g[..., 2, 1] * a2)
        out[..., 2, 0] = -(g[..., 1, 2] * a1 + g[..., 2, 2] * a2)
        out[..., 1:, 1:] = np.swapaxes(g[..., 1:, 1:], -1, -2)
        return out

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", g[..., 1:, 1:], x) + g[..., 1:, 0]

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
        a, b = exp_coeffs_np(w * w)
        wb = w * b
        c, s = np.cos(w), np.sin(w)
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 0] = 1.0
        out[..., 1, 0] = a * v1 - wb * v2
        out[..., 2, 0] = wb * v1 + a * v2
        out[..., 1, 1] = c
        out[..., 1, 2] = -s
        out[..., 2, 1] = s
        out[..., 2, 2] = c
        return out

    def _log(self, g: np.ndarray) -> np.ndarray:
        w = np.arctan2(g[..., 2, 1] - g[..., 1, 2], g[..., 1, 1] + g[..., 2, 2])
        alpha = 1.0 - w * w * dexp_inv_coeff_np(w * w)
        h = 0.5 * w
        a1, a2 = g[..., 1, 0], g[..., 2, 0]
        return np.stack([alpha * a1 + h * a2, alpha * a2 - h * a1, w], axis=-1)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        out = np.zeros(g.shape)
        out[..., 0, 0] = g[..., 1, 1]
        out[..., 0, 1] = g[..., 1, 2]
        out[..., 0, 2] = g[..., 2, 0]
        out[..., 1, 0] = g[..., 2, 1]
        out[..., 1, 1] = g[..., 2, 2]
        out[..., 1, 2] = -g[..., 1, 0]
        out[..., 2, 2] = 1.0
        return out

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 1] = -xi[..., 2]
        out[..., 0, 2] = xi[..., 1]
        out[..., 1, 0] = xi[..., 2]
        out[..., 1, 2] = -xi[..., 0]
        return out

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        xi, eta = np.broadcast_arrays(xi, eta)
        return np.stack(
            [
                xi[..., 1] * eta[..., 2] - xi[..., 2] * eta[..., 1],
                xi[..., 2] * eta[..., 0] - xi[..., 0] * eta[..., 2],
                np.zeros(xi.shape[:-1]),
            ],
            axis=-1,
        )

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return _dexp_np(xi[..., 0], xi[..., 1], xi[..., 2], 1.0)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        v1, v2, w = xi[..., 0], xi[..., 1], xi[..., 2]
        c = dexp_inv_coeff_np(w * w)
        alpha = 1.0 - w * w * c
        h = 0.5 * w
        wc = w * c
        out = np.zeros((*xi.shape[:-1], 3, 3))
        out[..., 0, 0] = alpha
        out[..., 0, 1] = h
        out[..., 0, 2] = wc * v1 - 0.5 * v2
        out[..., 1, 0] = -h
        out[..., 1, 1] = alpha
        out[..., 1, 2] = wc * v2 + 0.5 * v1
        out[..., 2, 2] = 1.0
        return out

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        return _dexp_np(dt * Y[..., 0], dt * Y[..., 1], dt * Y[..., 2], dt)
