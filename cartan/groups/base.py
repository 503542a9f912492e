"""The :class:`SymmetryGroup` base: the contract every matrix Lie group in cartan fulfils.

Conventions (paper §II, §III and Appendix "Vector and matrix operations")
--------------------------------------------------------------------------
* A group element is an ``m × m`` real matrix (``matrix_size``); batches are ``[..., m, m]``.
* A Lie-algebra element is stored by its ``r`` components (``dim``) in the group's basis
  ``b_i`` (:meth:`SymmetryGroup.basis`), batches ``[..., r]``.  ``hat`` maps components to the
  matrix ``ξ_i b_i`` and ``vee`` inverts it.  For affine groups the paper puts the
  homogeneous coordinate **first**: ``(a; A) = [[1, 0ᵀ], [a, A]]`` and ``{a; b} = [[0, 0ᵀ],
  [a, b̂]]``, translation components before rotation components.
* A dual element ``Y ∈ 𝔤*`` is stored by its components in the dual basis ``B_i``; the
  pairing is ``⟨C, Y⟩ = C_i Y_i``.  Operators on 𝔤 are ``r × r`` matrices acting on
  components: ``ad(ξ) @ η = [ξ, η]``.  The coadjoint operator follows the paper's sign,
  ``ad*_ξ = −ad_ξᵀ`` (:meth:`coad`), and ``Ad*_g = Ad_gᵀ`` (:meth:`coAd`) so that
  ``Ad*_{exp ξ} = exp(−ad*_ξ)``.
* ``dexp(ξ) = Σ_k ad_ξᵏ/(k+1)! = (e^{ad_ξ} − I)/ad_ξ`` (the "left Jacobian"), so that
  ``d/dt exp(ξ(t)) = hat(dexp(ξ) ξ̇) exp(ξ)``, and the paper's operator (§V)
  ``𝓔(Δt, Y) = ∫₀^Δt Ad_{exp((Δt−s)Y)} ds = Δt · dexp(Δt Y)`` is :meth:`E`.

Implementing a group
--------------------
A subclass sets ``name``, ``dim``, ``matrix_size`` and implements :meth:`basis` and
:meth:`defect`.  Everything else has a correct generic implementation here (matrix
exponential, principal logarithm, Van Loan block exponential for ``dexp`` and ``E``), so a
new matrix group works immediately; closed forms are added by overriding the numpy
reference methods ``_exp``, ``_log``, ``_Ad``, ... and, for speed, by listing numba batch
kernels in ``_kernels`` (``{"exp": kernel, ...}``, each ``kernel(*flat_inputs, out)``; see
:mod:`cartan.groups._batch`).  The public methods validate their input and dispatch to the
kernel when the active backend is ``"numba"`` and a kernel exists, otherwise to the numpy
method: the two paths must compute the same formulas (tests compare them to 1e-14).
"""

from __future__ import annotations

import abc
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
import scipy.linalg

from .._backend import get_backend
from ._batch import run_kernel

__all__ = ["SymmetryGroup"]


def _expm(a: np.ndarray) -> np.ndarray:
    """Batched matrix exponential (scipy's Padé scaling and squaring)."""
    return scipy.linalg.expm(a)


class SymmetryGroup(abc.ABC):
    """A matrix Lie group G ⊂ GL(m) with Lie algebra 𝔤 of dimension r.

    Attributes
    ----------
    name : str
        Registry name, e.g. ``"SO3"``.
    dim : int
        r, the dimension of the Lie algebra (number of components of ξ).
    matrix_size : int
        m, the size of the matrices representing group elements.
    space_dim : int
        Dimension of the vector space the group acts on naturally (:meth:`act`): m for
        linear groups, m − 1 for affine groups whose homogeneous coordinate comes first.
    affine : bool
        True when the matrices have the affine form ``[[1, 0ᵀ], [a, A]]``.
    injectivity_radius : float
        Radius (in the norm of :meth:`log_domain_norm`) inside which ``log ∘ exp`` is the
        identity.
    """

    name: ClassVar[str] = ""
    dim: int
    matrix_size: int
    affine: bool = False
    injectivity_radius: float = np.pi
    #: numba batch kernels by operation name; absent operations use the numpy path.
    _kernels: ClassVar[dict[str, Any]] = {}

    #: prefix of the module's numba point kernels ``<prefix>_<op>_point`` (see :meth:`point_kernels`)
    _point_prefix: ClassVar[str] = ""

    def point_kernels(self):
        """The group's numba point kernels, for the generated compiled loops, or None.

        Returns a :class:`cartan.compiled.codegen.Fragment` that binds, as globals of a
        generated module, ``g_<op>`` for every operation of
        :data:`cartan.compiled.kernels.GROUP_OPS` with the signatures

        ``g_exp(xi, out)``, ``g_log(g, out)``, ``g_compose(g, h, out)``, ``g_inverse(g, out)``,
        ``g_hat(xi, out)``, ``g_Ad(g, out)``, ``g_ad(xi, out)``, ``g_dexp_inv(xi, out)``,
        ``g_E(dt, xi, out)`` — ``xi`` ``(r,)``, ``g`` ``(m, m)``, matrices of operators
        ``(r, r)``, every result written into ``out``.  The default finds
        ``<prefix>_<op>_point`` in the group class's module (:attr:`_point_prefix`); a group
        without them (None) runs on the numpy and per-call kernel paths only.
        """
        if not self._point_prefix:
            return None
        from ..compiled.kernels import GROUP_OPS, group_fragment

        return group_fragment(type(self).__module__, self._point_prefix, GROUP_OPS)

    # ------------------------------------------------------------------ contract
    @abc.abstractmethod
    def basis(self) -> np.ndarray:
        """Generators ``b_i`` of 𝔤 as matrices, shape ``(r, m, m)``; they define :meth:`hat`."""

    @abc.abstractmethod
    def defect(self, g: np.ndarray) -> np.ndarray:
        """Distance of ``g`` from the group by its defining relation.

        Parameters
        ----------
        g : array_like, shape ``[..., m, m]``

        Returns
        -------
        numpy.ndarray, shape ``[...]``
            e.g. ``‖RᵀR − I‖_F`` for rotations; zero (to round-off) exactly on G.
        """

    def log_domain_norm(self, xi: np.ndarray) -> np.ndarray:
        """Norm compared with :attr:`injectivity_radius`; default: the rotation angle |ξ|."""
        return np.linalg.norm(np.asarray(xi, dtype=float), axis=-1)

    # ------------------------------------------------------------------ basics
    @property
    def space_dim(self) -> int:
        return self.matrix_size - 1 if self.affine else self.matrix_size

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.__dict__.get("n") == other.__dict__.get("n")

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.__dict__.get("n")))

    @cached_property
    def _basis(self) -> np.ndarray:
        b = np.asarray(self.basis(), dtype=float)
        r, m = self.dim, self.matrix_size
        if b.shape != (r, m, m):
            raise ValueError(f"{type(self).__name__}.basis() has shape {b.shape}, expected {(r, m, m)}")
        return b

    @cached_property
    def _dual(self) -> np.ndarray:
        """Left inverse of the flattened basis, shape ``(m*m, r)``: ``vee(A) = A.ravel() @ _dual``."""
        return np.linalg.pinv(self._basis.reshape(self.dim, -1))

    # ------------------------------------------------------------------ validation
    def _algebra(self, xi: Any, what: str = "xi") -> np.ndarray:
        a = np.asarray(xi, dtype=float)
        if a.ndim == 0 or a.shape[-1] != self.dim:
            raise ValueError(
                f"{what} must have shape [..., {self.dim}] for {self.name}, got {a.shape}"
            )
        return a

    def _element(self, g: Any, what: str = "g") -> np.ndarray:
        a = np.asarray(g, dtype=float)
        m = self.matrix_size
        if a.ndim < 2 or a.shape[-2:] != (m, m):
            raise ValueError(f"{what} must have shape [..., {m}, {m}] for {self.name}, got {a.shape}")
        return a

    def _point(self, x: Any, what: str = "x") -> np.ndarray:
        a = np.asarray(x, dtype=float)
        if a.ndim == 0 or a.shape[-1] != self.space_dim:
            raise ValueError(
                f"{what} must have shape [..., {self.space_dim}] for {self.name}, got {a.shape}"
            )
        return a

    def _call(self, op: str, args: tuple[np.ndarray, ...], core_ndims: tuple[int, ...],
              out_core: tuple[int, ...]) -> np.ndarray:
        kernel = self._kernels.get(op) if get_backend() == "numba" else None
        if kernel is None:
            return getattr(self, "_" + op)(*args)
        return run_kernel(kernel, out_core, args, core_ndims)

    # ------------------------------------------------------------------ public API
    def hat(self, xi: Any) -> np.ndarray:
        """Matrix ``ξ_i b_i`` of algebra components ``xi`` ``[..., r]`` → ``[..., m, m]``."""
        m = self.matrix_size
        return self._call("hat", (self._algebra(xi),), (1,), (m, m))

    def vee(self, A: Any) -> np.ndarray:
        """Components ``[..., r]`` of an algebra matrix ``A`` ``[..., m, m]`` (inverse of hat)."""
        return self._call("vee", (self._element(A, "A"),), (2,), (self.dim,))

    def identity(self, shape: tuple[int, ...] | int = ()) -> np.ndarray:
        """Identity element broadcast to ``[*shape, m, m]``."""
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        return np.broadcast_to(np.eye(self.matrix_size), (*shape, self.matrix_size, self.matrix_size)).copy()

    def compose(self, g: Any, h: Any) -> np.ndarray:
        """Group product ``g h`` of ``[..., m, m]`` batches (broadcast)."""
        m = self.matrix_size
        return self._call("compose", (self._element(g), self._element(h, "h")), (2, 2), (m, m))

    def inverse(self, g: Any) -> np.ndarray:
        """Group inverse ``g⁻¹`` ``[..., m, m]``."""
        m = self.matrix_size
        return self._call("inverse", (self._element(g),), (2,), (m, m))

    def act(self, g: Any, x: Any) -> np.ndarray:
        """Natural action on the vector space of dimension :attr:`space_dim`.

        Linear groups: ``g x``.  Affine groups ``(a; A)``: ``A x + a``.
        ``g`` is ``[..., m, m]``, ``x`` is ``[..., space_dim]``; the result is ``[..., space_dim]``.
        """
        return self._call("act", (self._element(g), self._point(x)), (2, 1), (self.space_dim,))

    def exp(self, xi: Any) -> np.ndarray:
        """Exponential map ``exp(hat(ξ))``: ``[..., r]`` → ``[..., m, m]``."""
        m = self.matrix_size
        return self._call("exp", (self._algebra(xi),), (1,), (m, m))

    def log(self, g: Any) -> np.ndarray:
        """Principal logarithm: ``[..., m, m]`` → components ``[..., r]`` (inverse of exp
        inside the injectivity radius)."""
        return self._call("log", (self._element(g),), (2,), (self.dim,))

    def Ad(self, g: Any) -> np.ndarray:
        """Adjoint representation ``Ad_g`` as an ``r × r`` matrix: ``Ad_g ξ = vee(g hat(ξ) g⁻¹)``."""
        r = self.dim
        return self._call("Ad", (self._element(g),), (2,), (r, r))

    def coAd(self, g: Any) -> np.ndarray:
        """Coadjoint representation on 𝔤* in components, ``Ad*_g = Ad_gᵀ`` ``[..., r, r]``."""
        return np.swapaxes(self.Ad(g), -1, -2)

    def ad(self, xi: Any) -> np.ndarray:
        """Adjoint of the algebra, ``ad_ξ η = [ξ, η]``, as ``[..., r, r]``."""
        r = self.dim
        return self._call("ad", (self._algebra(xi),), (1,), (r, r))

    def coad(self, xi: Any) -> np.ndarray:
        """The paper's dual adjoint ``ad*_ξ = −ad_ξᵀ`` (Appendix), ``[..., r, r]``."""
        return -np.swapaxes(self.ad(xi), -1, -2)

    def bracket(self, xi: Any, eta: Any) -> np.ndarray:
        """Lie bracket ``[ξ, η] = vee(ξ̂η̂ − η̂ξ̂)`` of two ``[..., r]`` batches."""
        return self._call("bracket", (self._algebra(xi), self._algebra(eta, "eta")), (1, 1), (self.dim,))

    def dexp(self, xi: Any) -> np.ndarray:
        """``dexp_ξ = Σ_k ad_ξᵏ/(k+1)!`` as ``[..., r, r]`` (left Jacobian of exp)."""
        r = self.dim
        return self._call("dexp", (self._algebra(xi),), (1,), (r, r))

    def dexp_inv(self, xi: Any) -> np.ndarray:
        """Inverse of :meth:`dexp`, ``[..., r, r]`` (defined inside the injectivity radius)."""
        r = self.dim
        return self._call("dexp_inv", (self._algebra(xi),), (1,), (r, r))

    def E(self, dt: Any, Y: Any) -> np.ndarray:
        """The paper's ``𝓔(Δt, Y) = ∫₀^Δt Ad_{exp((Δt−s)Y)} ds = Δt·dexp(ΔtY)`` (§V).

        Parameters
        ----------
        dt : float or array_like, broadcastable to the batch shape of ``Y``
        Y : array_like, shape ``[..., r]``

        Returns
        -------
        numpy.ndarray, shape ``[..., r, r]``
        """
        r = self.dim
        return self._call("E", (np.asarray(dt, dtype=float), self._algebra(Y, "Y")), (0, 1), (r, r))

    def E_vanloan(self, dt: Any, Y: Any) -> np.ndarray:
        """𝓔(Δt, Y) by the Van Loan block exponential ``expm([[Δt ad_Y, Δt I], [0, 0]])``.

        Valid for any matrix group; the closed forms are tested against it.
        """
        Y = self._algebra(Y, "Y")
        dt = np.asarray(dt, dtype=float)
        r = self.dim
        adY = self._ad(Y)
        lead = np.broadcast_shapes(dt.shape, adY.shape[:-2])
        dt_ = np.broadcast_to(dt, lead)[..., None, None]
        big = np.zeros((*lead, 2 * r, 2 * r))
        big[..., :r, :r] = dt_ * np.broadcast_to(adY, (*lead, r, r))
        big[..., :r, r:] = dt_ * np.eye(r)
        return _expm(big)[..., :r, r:]

    # ------------------------------------------------------------------ numpy reference
    # Generic implementations, correct for any matrix group given basis().  Subclasses
    # override them with closed forms; they are the "numpy" backend.
    def _hat(self, xi: np.ndarray) -> np.ndarray:
        return np.einsum("...i,ijk->...jk", xi, self._basis)

    def _vee(self, A: np.ndarray) -> np.ndarray:
        m = self.matrix_size
        return A.reshape(*A.shape[:-2], m * m) @ self._dual

    def _compose(self, g: np.ndarray, h: np.ndarray) -> np.ndarray:
        return g @ h

    def _inverse(self, g: np.ndarray) -> np.ndarray:
        return np.linalg.inv(g)

    def _act(self, g: np.ndarray, x: np.ndarray) -> np.ndarray:
        if self.affine:
            return np.einsum("...ij,...j->...i", g[..., 1:, 1:], x) + g[..., 1:, 0]
        return np.einsum("...ij,...j->...i", g, x)

    def _exp(self, xi: np.ndarray) -> np.ndarray:
        return _expm(self._hat(xi))

    def _log(self, g: np.ndarray) -> np.ndarray:
        flat = g.reshape(-1, self.matrix_size, self.matrix_size)
        out = np.empty((flat.shape[0], self.dim))
        for k, gk in enumerate(flat):
            out[k] = self._vee(np.real(scipy.linalg.logm(gk)))
        return out.reshape(*g.shape[:-2], self.dim)

    def _Ad(self, g: np.ndarray) -> np.ndarray:
        ginv = self._inverse(g)
        conj = g[..., None, :, :] @ self._basis @ ginv[..., None, :, :]  # [..., r(col), m, m]
        return np.swapaxes(self._vee(conj), -1, -2)

    def _ad(self, xi: np.ndarray) -> np.ndarray:
        X = self._hat(xi)[..., None, :, :]
        cols = self._vee(X @ self._basis - self._basis @ X)  # [..., r(col), r]
        return np.swapaxes(cols, -1, -2)

    def _bracket(self, xi: np.ndarray, eta: np.ndarray) -> np.ndarray:
        X, Y = self._hat(xi), self._hat(eta)
        return self._vee(X @ Y - Y @ X)

    def _dexp(self, xi: np.ndarray) -> np.ndarray:
        return self.E_vanloan(1.0, xi)

    def _dexp_inv(self, xi: np.ndarray) -> np.ndarray:
        return np.linalg.inv(self._dexp(xi))

    def _E(self, dt: np.ndarray, Y: np.ndarray) -> np.ndarray:
        dt = np.asarray(dt, dtype=float)
        return dt[..., None, None] * self._dexp(dt[..., None] * Y)
