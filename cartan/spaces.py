"""Homogeneous configuration spaces X = G/H of Cartan media (paper §II, §III).

A Cartan medium maps each material point to a configuration ``q ∈ X`` of a homogeneous
space on which a symmetry group ``G`` acts transitively.  The kinematics never stores
``q`` directly: a *structure field* ``Φ: W → G`` carries it through the action on a fixed
reference point, ``q = Φ·q_r`` (paper Eq. "x from phi").  When ``r = dim G`` exceeds
``n = dim X`` the structure field is fixed only up to the stabiliser ``H`` of ``q_r``
(``Φ h·q_r = Φ·q_r`` for ``h ∈ H``); choosing ``h`` is choosing a *gauge* (paper §III.E,
"Adapted structure fields").

:class:`HomogeneousSpace` is the contract; the concrete spaces of the paper are

* :class:`Sphere` ``"sphere"``: Sⁿ_r with SO(n+1), ``q_r = r·e_{n+1}``, gauge SO(n) (§VIII.B);
* :class:`Euclidean3` ``"E3"``: E³ with SE(3), ``q_r = 0``, gauge SO(3) (§VII);
* :class:`PointDirector` ``"E3xS2"``: E³ × S² with SE(3), ``q_r = (0, e₃)``, drill gauge (§VI.B);
* :class:`FrameBundleE3` ``"frame-E3"``: F(E³) ≅ SE(3), ``q_r = I₄``, no gauge (§VI.A, §VI.C);
* :class:`SphereFrameBundle` ``"frame-S2"``: F(S²_r) ≅ SO(3), ``q_r = I₃``, no gauge (§VIII.A);
* :class:`MinkowskiFrameBundle` ``"frame-M13"``: F(M^{1,3}) with the Poincaré group,
  ``q_r = I₅``, no gauge (§VIII.C).

Every space is registered through the ``cartan_register_spaces`` hook at the bottom of
this module (entry point ``spaces = "cartan.spaces"``).
"""

from __future__ import annotations

import abc
import math
import numbers
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from .groups.base import SymmetryGroup
from .plugins import hookimpl

__all__ = [
    "FrameBundleE2",
    "HomogeneousSpace",
    "Sphere",
    "Euclidean3",
    "PointDirector",
    "FrameBundleE3",
    "SphereFrameBundle",
    "MinkowskiFrameBundle",
]


# ---------------------------------------------------------------------- groups (lazy)
def _rotation_group(m: int) -> SymmetryGroup:
    """SO(m) with the project's preferred class: SO2, SO3, or the generic SO(n)."""
    if m == 2:
        from .groups.so2 import SO2

        return SO2()
    if m == 3:
        from .groups.so3 import SO3

        return SO3()
    from .groups.son import SO

    return SO(n=m)


def _se3() -> SymmetryGroup:
    from .groups.se3 import SE3

    return SE3()


def _poincare() -> SymmetryGroup:
    from .groups.poincare import Poincare

    return Poincare()


# ---------------------------------------------------------------------- parameter checks
def _check_int(value: Any, what: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{what} must be an integer ≥ {minimum}, got {value!r}")
    return int(value)


def _check_positive(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{what} must be a finite real number > 0, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{what} must be a finite real number > 0, got {value!r}")
    return v


# ---------------------------------------------------------------------- geometry helpers
def _minimal_rotation(b: np.ndarray) -> np.ndarray:
    """The geodesic rotation of SO(k) taking ``e_k`` to the unit vector ``b`` ``[..., k]``.

    It is the rotation by the angle ``θ = ∠(e_k, b)`` in the plane spanned by ``e_k`` and
    ``b`` (fixing the orthogonal complement): with ``b = (s·u, c)``, ``|u| = 1``,
    ``R = I + s(u e_kᵀ − e_k uᵀ) + (c − 1)(u uᵀ + e_k e_kᵀ)``.  Its last column is ``b``
    exactly.  The formula involves no division by ``1 + c``, so it is accurate up to and
    at the antipode ``b = −e_k``, where the plane is undefined and ``u = e₁`` is used: the
    rotation by π in the (e₁, e_k) plane, ``diag(−1, 1, …, 1, −1)``.
    """
    k = b.shape[-1]
    bp = b[..., :-1]
    c = b[..., -1]
    scale = np.max(np.abs(bp), axis=-1, keepdims=True)
    degenerate = scale == 0.0
    w = np.where(degenerate, 0.0, bp / np.where(degenerate, 1.0, scale))
    w[..., 0] = np.where(degenerate[..., 0], 1.0, w[..., 0])
    u = w / np.linalg.norm(w, axis=-1, keepdims=True)
    R = np.broadcast_to(np.eye(k), (*b.shape[:-1], k, k)).copy()
    R[..., :-1, :-1] += (c - 1.0)[..., None, None] * (u[..., :, None] * u[..., None, :])
    R[..., :-1, -1] = bp
    R[..., -1, :-1] = -bp
    R[..., -1, -1] = c
    return R


def _nearest_rotation(A: np.ndarray) -> np.ndarray:
    """Nearest proper rotation (Frobenius norm) to each ``[..., k, k]`` matrix (polar factor)."""
    U, _, Vt = np.linalg.svd(A)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0.0, 1.0, d)
    U = U.copy()
    U[..., :, -1] *= d[..., None]
    return U @ Vt


def _rotation_defect(A: np.ndarray) -> np.ndarray:
    """``‖AᵀA − I‖_F + |det A − 1|`` for ``[..., k, k]``: zero exactly on SO(k)."""
    k = A.shape[-1]
    gram = np.swapaxes(A, -1, -2) @ A - np.eye(k)
    return np.linalg.norm(gram, axis=(-2, -1)) + np.abs(np.linalg.det(A) - 1.0)


def _embed(blocks: np.ndarray, size: int, offset: int) -> np.ndarray:
    """Place ``[..., k, k]`` blocks into zero ``[..., size, size]`` matrices at ``(offset, offset)``."""
    k = blocks.shape[-1]
    out = np.zeros((*blocks.shape[:-2], size, size))
    out[..., offset : offset + k, offset : offset + k] = blocks
    return out


_ETA = np.diag([-1.0, 1.0, 1.0, 1.0])


# ====================================================================== base class
class HomogeneousSpace(abc.ABC):
    """A homogeneous space X of dimension n on which a symmetry group G acts transitively.

    This docstring is the contract every configuration space of cartan fulfils (paper
    §II "Notation", §III "Kinematics").  Points, group elements and algebra components are
    float64 arrays vectorised over leading (batch) axes.

    Attributes
    ----------
    name : str
        Registry name (``"sphere"``, ``"E3"``, ...), class attribute.
    group : SymmetryGroup
        The symmetry group G (an instance), of dimension ``r = group.dim`` and matrix size
        ``m = group.matrix_size``.
    dim : int
        n = dim X, with ``n ≤ r``.
    point_shape : tuple of int
        Shape of one point: ``(k,)`` for vector configurations (a point of Sⁿ ⊂ R^{n+1},
        of E³, ...), ``(k, k)`` for matrix configurations (frames, identified with group
        elements).  A batch of points is ``[..., *point_shape]``.
    q_r : numpy.ndarray, shape ``point_shape``
        The reference configuration of paper Eq. "x from phi": ``q = Φ·q_r``.  A fresh
        copy on every access.
    gauge_dim : int
        ``r − n``, the dimension of the stabiliser H of ``q_r`` (the gauge freedom of the
        structure field, paper §III.E).
    tol : float
        Tolerance of :meth:`validate` on :meth:`defect` (class attribute, may be changed
        per instance).

    Methods
    -------
    act(g, q)
        The action ``g·q`` of G on X, ``g`` ``[..., m, m]``, ``q`` ``[..., *point_shape]``;
        batch axes broadcast.  Shapes are checked (``ValueError`` naming the argument);
        membership is not (see :meth:`validate`).
    infinitesimal_action(xi, q)
        ``ρ(ξ) q = d/dε (exp(εξ)·q)`` at ε = 0 (paper Eq. "dx"), ``xi`` ``[..., r]``.
    defect(q)
        Distance of ``q`` from X by its defining relation (e.g. ``||q|/radius − 1|`` on
        a sphere); zero to round-off on X.
    validate(q, what="q")
        ``q`` as a float array after checking shape, finiteness and ``defect ≤ tol``;
        a ``ValueError`` naming ``what`` otherwise.
    project(q)
        A point of X close to ``q`` (nearest point where that is cheap, e.g. normalisation
        on the sphere, polar factor for rotation frames); exact points are unchanged to
        round-off.  Used to remove drift.
    lift(q, gauge=None)
        A structure field ``Φ`` ``[..., m, m]`` with ``act(Φ, q_r) == q`` to round-off for
        points on the space (``q`` is validated; spaces whose section needs a unit vector
        use its normalisation, frame bundles return ``Φ = q`` itself).
        ``Φ = Φ₀(q)·exp(gauge · stabiliser_basis())``, where ``Φ₀`` is the
        space's fixed section (documented per class) and ``gauge`` ``[..., gauge_dim]``
        holds components in the stabiliser basis (``None``: zero).  The gauge batch
        shape must broadcast to the batch shape of ``q``: one Φ per point.
    stabiliser_basis()
        ``(gauge_dim, r)`` algebra components of generators of the stabiliser algebra
        𝔥 of ``q_r``: ``act(exp(t h), q_r) == q_r`` for every row ``h``.
    jacobian(Phi), pullback(Phi, f)
        ``J_i = d/dε (Φ exp(ε b_i))·q_r`` ``[..., r, *point_shape]`` and the dual
        components ``⟨f, J_i⟩`` ``[..., r]`` of a configuration-space covector ``f``: the
        pull-back to 𝔤* of paper §IV.B (Eq. "body force in terms of G") used to turn
        ``−∂U/∂q`` into a generalised body force ``T``.
    sample(shape=(), rng=None, scale=1.0)
        Points ``exp(ξ)·q_r`` for Gaussian ``ξ`` with standard deviation ``scale``.

    Notes
    -----
    Subclasses set ``name``, ``dim``, ``point_shape``, ``group`` and implement
    :meth:`_apply` (the action formula for a matrix ``[..., m, m]``; it must be *linear in
    the matrix*, so that applying an algebra matrix gives the infinitesimal action),
    :meth:`_reference`, :meth:`_section` (the gauge-zero lift), :meth:`defect`,
    :meth:`project` and, when ``gauge_dim > 0``, :meth:`_stabiliser`.
    """

    name: ClassVar[str] = ""
    group: SymmetryGroup
    dim: int
    point_shape: tuple[int, ...]
    tol: float = 1e-8

    # ------------------------------------------------------------------ subclass hooks
    @abc.abstractmethod
    def _apply(self, M: np.ndarray, q: np.ndarray) -> np.ndarray:
        """The action formula for a matrix ``M`` ``[..., m, m]`` (group or algebra element)."""

    @abc.abstractmethod
    def _reference(self) -> np.ndarray:
        """The reference point ``q_r``, shape ``point_shape``."""

    @abc.abstractmethod
    def _section(self, q: np.ndarray) -> np.ndarray:
        """Gauge-zero structure field Φ₀(q) ``[..., m, m]`` for validated points ``q``."""

    @abc.abstractmethod
    def defect(self, q: Any) -> np.ndarray:
        """Distance of ``q`` ``[..., *point_shape]`` from the space, shape ``[...]``."""

    @abc.abstractmethod
    def project(self, q: Any) -> np.ndarray:
        """A point of the space close to ``q`` (exact points unchanged to round-off)."""

    def _stabiliser(self) -> np.ndarray:
        """Stabiliser generators as components, ``(gauge_dim, r)``; override if gauge_dim > 0."""
        return np.zeros((0, self.group.dim))

    # ------------------------------------------------------------------ basics
    @property
    def q_r(self) -> np.ndarray:
        return np.array(self._reference(), dtype=float)

    @property
    def gauge_dim(self) -> int:
        return self.group.dim - self.dim

    def _params(self) -> dict[str, Any]:
        return {}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self._params() == other._params()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, tuple(sorted(self._params().items()))))

    # ------------------------------------------------------------------ validation
    def _points(self, q: Any, what: str = "q") -> np.ndarray:
        """``q`` as float with a shape check (``[..., *point_shape]``)."""
        try:
            a = np.asarray(q, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{what} must be a real array of points of {self!r}: {exc}") from None
        k = len(self.point_shape)
        if a.ndim < k or a.shape[a.ndim - k :] != self.point_shape:
            shape = ", ".join(str(s) for s in self.point_shape)
            raise ValueError(f"{what} must have shape [..., {shape}] for {self!r}, got {a.shape}")
        return a

    def _elements(self, g: Any, what: str = "g") -> np.ndarray:
        a = np.asarray(g, dtype=float)
        m = self.group.matrix_size
        if a.ndim < 2 or a.shape[-2:] != (m, m):
            raise ValueError(
                f"{what} must have shape [..., {m}, {m}] (elements of {self.group.name}) "
                f"for {self!r}, got {a.shape}"
            )
        return a

    def _check_points(self, a: np.ndarray, what: str) -> None:
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what} contains non-finite values (NaN or inf)")
        d = self.defect(a)
        if np.any(d > self.tol):
            worst = float(np.max(d))
            raise ValueError(
                f"{what} is not on {self!r}: {self._defect_meaning()} deviates by {worst:.3g}, "
                f"more than the tolerance tol={self.tol:g}"
            )

    def _defect_meaning(self) -> str:
        return "the defining relation"

    def validate(self, q: Any, what: str = "q") -> np.ndarray:
        """Return ``q`` as a float array after checking its shape, finiteness and that it lies
        on the space within :attr:`tol`; raise ``ValueError`` naming ``what`` otherwise."""
        a = self._points(q, what)
        self._check_points(a, what)
        return a

    def contains(self, q: Any) -> np.ndarray:
        """Boolean ``[...]``: finite and ``defect(q) ≤ tol``."""
        a = self._points(q)
        k = len(self.point_shape)
        finite = np.all(np.isfinite(a), axis=tuple(range(a.ndim - k, a.ndim)))
        with np.errstate(invalid="ignore"):
            return finite & (np.nan_to_num(self.defect(a), nan=np.inf) <= self.tol)

    # ------------------------------------------------------------------ action
    def act(self, g: Any, q: Any) -> np.ndarray:
        """The action ``g·q``: ``g`` ``[..., m, m]``, ``q`` ``[..., *point_shape]`` (broadcast)."""
        return self._apply(self._elements(g), self._points(q))

    def infinitesimal_action(self, xi: Any, q: Any) -> np.ndarray:
        """``ρ(ξ)q = d/dε exp(εξ)·q |₀`` for components ``xi`` ``[..., r]`` (a tangent vector at q)."""
        return self._apply(self.group.hat(xi), self._points(q))

    # ------------------------------------------------------------------ structure fields
    def stabiliser_basis(self) -> np.ndarray:
        """Generators of the stabiliser algebra 𝔥 of ``q_r`` as components, ``(gauge_dim, r)``."""
        return self._stabiliser_cached.copy()

    @cached_property
    def _stabiliser_cached(self) -> np.ndarray:
        H = np.asarray(self._stabiliser(), dtype=float)
        if H.shape != (self.gauge_dim, self.group.dim):
            raise ValueError(
                f"{type(self).__name__}._stabiliser() has shape {H.shape}, "
                f"expected {(self.gauge_dim, self.group.dim)}"
            )
        return H

    def lift(self, q: Any, gauge: Any = None) -> np.ndarray:
        """A structure field Φ ``[..., m, m]`` with ``act(Φ, q_r) == q`` (paper Eq. "x from phi").

        Parameters
        ----------
        q : array_like, shape ``[..., *point_shape]``
            Points of the space (validated: within :attr:`tol` of it).
        gauge : array_like, shape ``[..., gauge_dim]``, optional
            Stabiliser components selecting Φ among the structure fields through q:
            ``Φ = Φ₀(q) exp(gauge · stabiliser_basis())`` (paper §III.E).  ``None`` means
            zero.  Its batch shape must broadcast to the batch shape of ``q``.

        Returns
        -------
        numpy.ndarray, shape ``[..., m, m]``
        """
        a = self.validate(q, "q")
        phi = self._section(a)
        batch = phi.shape[:-2]
        if gauge is None:
            return phi
        g = np.asarray(gauge, dtype=float)
        if g.ndim == 0 or g.shape[-1] != self.gauge_dim:
            raise ValueError(
                f"gauge must have shape [..., {self.gauge_dim}] (gauge_dim of {self!r}), got {g.shape}"
            )
        if not np.all(np.isfinite(g)):
            raise ValueError("gauge contains non-finite values (NaN or inf)")
        try:
            ok = np.broadcast_shapes(g.shape[:-1], batch) == batch
        except ValueError:
            ok = False
        if not ok:
            raise ValueError(
                f"gauge batch shape {g.shape[:-1]} does not broadcast to the batch shape {batch} of q"
            )
        if self.gauge_dim == 0:
            return phi
        h = self.group.exp(g @ self._stabiliser_cached)
        return np.asarray(self.group.compose(phi, h))

    def jacobian(self, Phi: Any) -> np.ndarray:
        """``J_i = d/dε (Φ exp(ε b_i))·q_r |₀ = ρ(Φ b_i) q_r``, shape ``[..., r, *point_shape]``."""
        P = self._elements(Phi, "Phi")
        basis = self.group.hat(np.eye(self.group.dim))  # (r, m, m)
        return self._apply(P[..., None, :, :] @ basis, self._reference())

    def pullback(self, Phi: Any, f: Any) -> np.ndarray:
        """Dual components ``T_i = ⟨f, J_i⟩`` ``[..., r]`` of a covector ``f`` ``[..., *point_shape]``.

        With ``f = −∂U/∂q`` this is the generalised body force of a configurational potential
        ``U(q)`` (paper §IV.B, ``T_i = Tr[𝒯Φb_i]``).
        """
        J = self.jacobian(Phi)
        fa = self._points(f, "f")
        k = len(self.point_shape)
        axes = tuple(range(-k, 0))
        return np.sum(J * np.expand_dims(fa, axis=-k - 1), axis=axes)

    def sample(self, shape: tuple[int, ...] | int = (), rng: Any = None, scale: float = 1.0) -> np.ndarray:
        """Points ``exp(ξ)·q_r`` with ``ξ ~ N(0, scale²)`` componentwise, ``[*shape, *point_shape]``."""
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        rng = np.random.default_rng(rng)
        xi = scale * rng.standard_normal((*shape, self.group.dim))
        return self._apply(self.group.exp(xi), self._reference())


# ====================================================================== concrete spaces
class Sphere(HomogeneousSpace):
    """The n-sphere ``Sⁿ_r = {q ∈ R^{n+1} : |q| = r}`` acted on by SO(n+1) (paper §VIII.B).

    Parameters
    ----------
    n : int, default 2
        Dimension of the sphere, ``n ≥ 1``.
    radius : float, default 1
        Radius ``r > 0``.

    Notes
    -----
    * Group: SO(2) for n = 1, SO(3) for n = 2, ``SO(n+1)`` otherwise; the action is the
      matrix–vector product ``g·q = g q``.
    * Reference point: ``q_r = r·e_{n+1}`` (the last basis vector, the paper's ``n₀`` of the
      sigma model §VIII.B and ``p = (0 0 1)ᵀ`` of the filament on S², §III.E).
    * Section ``Φ₀(q)``: the minimal (geodesic) rotation taking ``e_{n+1}`` to ``q/|q|``, the
      rotation in the plane of the two vectors.  At the antipode ``q = −r e_{n+1}`` the plane
      is undefined and the rotation by π in the (e₁, e_{n+1}) plane,
      ``diag(−1, 1, …, 1, −1)``, is used (the limit from the e₁ side).
    * Gauge: the stabiliser of ``q_r`` is the SO(n) rotating the first n coordinates; the gauge
      holds its algebra components in the basis of the corresponding group (SO2, SO3 or
      SO(n)), embedded in the top-left block: ``Φ = Φ₀(q)·diag(exp_{SO(n)}(gauge), 1)``.
      ``gauge_dim = n(n−1)/2`` (0 for the circle).  With cartan's so(n+1) basis
      (:mod:`cartan.groups.son`) these generators are the *last* n(n−1)/2 components, so
      :meth:`stabiliser_basis` is ``eye(r)[n:]``.
    * :meth:`defect` is the relative radial deviation ``||q|/r − 1|``.
    """

    name: ClassVar[str] = "sphere"

    def __init__(self, n: int = 2, radius: float = 1.0):
        self.n = _check_int(n, "n (dimension of the sphere)", 1)
        self.radius = _check_positive(radius, "radius")
        self.group = _rotation_group(self.n + 1)
        self.dim = self.n
        self.point_shape = (self.n + 1,)

    def _params(self) -> dict[str, Any]:
        return {"n": self.n, "radius": self.radius}

    def _defect_meaning(self) -> str:
        return "|q|/radius (must be 1)"

    def _apply(self, M: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", M, q)

    def _reference(self) -> np.ndarray:
        e = np.zeros(self.n + 1)
        e[-1] = self.radius
        return e

    def defect(self, q: Any) -> np.ndarray:
        a = self._points(q)
        return np.abs(np.linalg.norm(a, axis=-1) / self.radius - 1.0)

    def project(self, q: Any) -> np.ndarray:
        a = self._points(q)
        norm = np.linalg.norm(a, axis=-1, keepdims=True)
        if np.any(norm == 0.0) or not np.all(np.isfinite(a)):
            raise ValueError("q cannot be projected onto the sphere: zero or non-finite vector")
        return self.radius * a / norm

    def _section(self, q: np.ndarray) -> np.ndarray:
        return _minimal_rotation(q / np.linalg.norm(q, axis=-1, keepdims=True))

    def _stabiliser(self) -> np.ndarray:
        if self.n == 1:
            return np.zeros((0, self.group.dim))
        sub = _rotation_group(self.n)
        return self.group.vee(_embed(sub.hat(np.eye(sub.dim)), self.n + 1, 0))


class Euclidean3(HomogeneousSpace):
    """Euclidean space E³ acted on by SE(3) (paper §VII.A filaments, §VII.B surfaces).

    Notes
    -----
    * Points are positions ``x`` ``[..., 3]``; ``(a; A)·x = A x + a``.
    * Reference point ``q_r = 0``; section ``Φ₀(x) = (x; I)``.
    * Gauge: the stabiliser of the origin is SO(3), ``gauge_dim = 3``; ``gauge`` holds so(3)
      components (SO3's hat convention, the paper's hat map), ``Φ = (x; exp(ĝauge))``.  A
      rotation matrix may be given instead with ``lift(x, rotation=R)``.
    """

    name: ClassVar[str] = "E3"

    def __init__(self) -> None:
        self.group = _se3()
        self.dim = 3
        self.point_shape = (3,)

    def _apply(self, M: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", M[..., 1:, 1:], q) + M[..., 1:, 0]

    def _reference(self) -> np.ndarray:
        return np.zeros(3)

    def defect(self, q: Any) -> np.ndarray:
        a = self._points(q)
        return np.where(np.all(np.isfinite(a), axis=-1), 0.0, np.inf)

    def project(self, q: Any) -> np.ndarray:
        return self._points(q).copy()

    def _section(self, q: np.ndarray) -> np.ndarray:
        phi = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4)).copy()
        phi[..., 1:, 0] = q
        return phi

    def _stabiliser(self) -> np.ndarray:
        so3 = _rotation_group(3)
        return self.group.vee(_embed(so3.hat(np.eye(3)), 4, 1))

    def lift(self, q: Any, gauge: Any = None, *, rotation: Any = None) -> np.ndarray:
        """Structure field ``(x; R)`` for positions ``x``; see :meth:`HomogeneousSpace.lift`.

        ``gauge`` ``[..., 3]`` are so(3) components of R; alternatively ``rotation``
        ``[..., 3, 3]`` gives R directly (checked to be a rotation within :attr:`tol`).
        """
        if rotation is None:
            return super().lift(q, gauge)
        if gauge is not None:
            raise ValueError("give either gauge (so(3) components) or rotation (matrices), not both")
        phi = self._section(self.validate(q, "q"))
        R = np.asarray(rotation, dtype=float)
        if R.ndim < 2 or R.shape[-2:] != (3, 3):
            raise ValueError(f"rotation must have shape [..., 3, 3], got {R.shape}")
        if not np.all(np.isfinite(R)) or np.any(_rotation_defect(R) > self.tol):
            raise ValueError("rotation must hold proper rotation matrices (RᵀR = I, det R = 1)")
        batch = phi.shape[:-2]
        try:
            ok = np.broadcast_shapes(R.shape[:-2], batch) == batch
        except ValueError:
            ok = False
        if not ok:
            raise ValueError(
                f"rotation batch shape {R.shape[:-2]} does not broadcast to the batch shape {batch} of q"
            )
        phi[..., 1:, 1:] = R
        return phi


class PointDirector(HomogeneousSpace):
    """E³ × S², a position and a unit director, acted on by SE(3) (paper §VI.B Cosserat surfaces).

    Notes
    -----
    * Points are ``q = (x, p)`` stored as ``[..., 6]``: position ``x = q[..., :3]``, unit
      director ``p = q[..., 3:]``; ``(a; A)·(x, p) = (A x + a, A p)`` (the paper's
      ``q = (r, pˢ)``, ``Φ q_r = q``).
    * Reference point ``q_r = (0, e₃)`` (the paper's choice ``p = (0 0 1)ᵀ``, so that the
      director is the third frame vector, ``pˢ = e₃``).
    * Section ``Φ₀(q) = (x; R₀(p))`` with ``R₀`` the minimal rotation taking e₃ to p (as on
      :class:`Sphere`; at ``p = −e₃`` the rotation by π about e₂, ``diag(−1, 1, −1)``).
    * Gauge: the drill rotation about the director, ``gauge_dim = 1``: ``gauge = θ`` gives
      ``Φ = Φ₀(q)·(0; R_{e₃}(θ))``, i.e. the frame ``(e₁ e₂ e₃) = R₀(p) R_{e₃}(θ)`` (rotated
      by θ about p, right-handed).
    * :meth:`defect` is ``||p| − 1|``.
    """

    name: ClassVar[str] = "E3xS2"

    def __init__(self) -> None:
        self.group = _se3()
        self.dim = 5
        self.point_shape = (6,)

    def _defect_meaning(self) -> str:
        return "the director length |p| (must be 1)"

    def _apply(self, M: np.ndarray, q: np.ndarray) -> np.ndarray:
        A = M[..., 1:, 1:]
        x = np.einsum("...ij,...j->...i", A, q[..., :3]) + M[..., 1:, 0]
        p = np.einsum("...ij,...j->...i", A, q[..., 3:])
        return np.concatenate(np.broadcast_arrays(x, p), axis=-1)

    def _reference(self) -> np.ndarray:
        return np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])

    def defect(self, q: Any) -> np.ndarray:
        a = self._points(q)
        return np.abs(np.linalg.norm(a[..., 3:], axis=-1) - 1.0)

    def project(self, q: Any) -> np.ndarray:
        a = self._points(q)
        norm = np.linalg.norm(a[..., 3:], axis=-1, keepdims=True)
        if np.any(norm == 0.0) or not np.all(np.isfinite(a)):
            raise ValueError("q cannot be projected onto E3xS2: zero or non-finite director")
        return np.concatenate([a[..., :3], a[..., 3:] / norm], axis=-1)

    def _section(self, q: np.ndarray) -> np.ndarray:
        p = q[..., 3:]
        phi = np.broadcast_to(np.eye(4), (*q.shape[:-1], 4, 4)).copy()
        phi[..., 1:, 0] = q[..., :3]
        phi[..., 1:, 1:] = _minimal_rotation(p / np.linalg.norm(p, axis=-1, keepdims=True))
        return phi

    def _stabiliser(self) -> np.ndarray:
        drill = np.zeros((1, 4, 4))
        drill[0, 1, 2], drill[0, 2, 1] = -1.0, 1.0  # {0; e₃}: ê₃ in the rotation block
        return self.group.vee(drill)

    @staticmethod
    def position(q: Any) -> np.ndarray:
        """Position ``x = q[..., :3]``."""
        return np.asarray(q, dtype=float)[..., :3]

    @staticmethod
    def director(q: Any) -> np.ndarray:
        """Director ``p = q[..., 3:]``."""
        return np.asarray(q, dtype=float)[..., 3:]


class _GroupAsSpace(HomogeneousSpace):
    """A frame bundle identified with its group (``r = n``, ``q_r = I``, ``lift(q) = q``)."""

    def __init__(self) -> None:
        m = self.group.matrix_size
        self.dim = self.group.dim
        self.point_shape = (m, m)

    def _apply(self, M: np.ndarray, q: np.ndarray) -> np.ndarray:
        return M @ q

    def _reference(self) -> np.ndarray:
        return np.eye(self.group.matrix_size)

    def _section(self, q: np.ndarray) -> np.ndarray:
        return q.copy()


class _EuclideanFrameBundle(_GroupAsSpace):
    """F(Eᵏ) ≅ SE(k): trihedrons ``(r, E)`` as ``[[1, 0ᵀ], [r, E]]`` (homogeneous coordinate
    first), acted on by matrix product; ``q_r = I``, ``Φ = q``."""

    def defect(self, q: Any) -> np.ndarray:
        a = self._points(q)
        row = a[..., 0, :] - np.eye(self.group.matrix_size)[0]
        return _rotation_defect(a[..., 1:, 1:]) + np.linalg.norm(row, axis=-1)

    def _defect_meaning(self) -> str:
        return "the frame [[1, 0], [r, E]] (E a rotation)"

    def project(self, q: Any) -> np.ndarray:
        a = self._points(q).copy()
        a[..., 0, :] = np.eye(self.group.matrix_size)[0]
        a[..., 1:, 1:] = _nearest_rotation(a[..., 1:, 1:])
        return a

    @staticmethod
    def position(q: Any) -> np.ndarray:
        """Position ``r = q[..., 1:, 0]``."""
        return np.asarray(q, dtype=float)[..., 1:, 0]

    @staticmethod
    def frame(q: Any) -> np.ndarray:
        """Frame ``E = (e₁ … e_k) = q[..., 1:, 1:]`` (directors as columns)."""
        return np.asarray(q, dtype=float)[..., 1:, 1:]


class FrameBundleE3(_EuclideanFrameBundle):
    """The frame bundle F(E³) ≅ SE(3) (paper §VI.A Cosserat solids, §VI.C rods).

    Notes
    -----
    * Points are trihedrons ``(r, E)`` stored as the 4×4 matrices ``[[1, 0ᵀ], [r, E]]`` of
      Eq. "matrix rep of SE(3)" (homogeneous coordinate first), ``E`` a proper rotation.
    * The action is the matrix product, ``(a; A)·(r, E) = (A r + a, A E)``.
    * ``q_r = I₄`` (the paper's ``D = 1``), so ``Φ = q``: ``lift(q) = q``, ``gauge_dim = 0``.
    * :meth:`defect`: ``‖EᵀE − I‖_F + |det E − 1| + ‖first row − (1, 0, 0, 0)‖``.
    """

    name: ClassVar[str] = "frame-E3"

    def __init__(self) -> None:
        self.group = _se3()
        super().__init__()


class FrameBundleE2(_EuclideanFrameBundle):
    """The frame bundle F(E²) ≅ SE(2) of the plane (planar rods; the r → ∞ limit of F(S²_r)).

    Points are the 3×3 matrices ``[[1, 0, 0], [r₁, c, −s], [r₂, s, c]]`` (position r and
    directors ``e₁ = (c, s)``, ``e₂ = (−s, c)`` as columns), homogeneous coordinate first as
    in :mod:`cartan.groups.se2`; the action is the matrix product, ``q_r = I₃``, ``Φ = q``.
    """

    name: ClassVar[str] = "frame-E2"

    def __init__(self) -> None:
        from .groups.se2 import SE2

        self.group = SE2()
        super().__init__()


class SphereFrameBundle(_GroupAsSpace):
    """The frame bundle F(S²_r) ≅ SO(3) of the sphere of radius r (paper §VIII.A).

    Parameters
    ----------
    radius : float, default 1
        Sphere radius ``r > 0``.

    Notes
    -----
    * Points are orthonormal frames ``R = (e₁ e₂ e₃)`` ``[..., 3, 3]``: the centreline point
      is ``r·e₃`` (:meth:`centreline`) and ``e₁, e₂`` span its tangent plane (the paper writes
      ``q = (e₁ e₂ r)`` with ``q_r = (d₁ d₂ r d₃)``; storing the frame itself keeps the
      action a matrix product for every radius).
    * The action is ``g·R = g R``; ``q_r = I₃``, ``lift(R) = R``, ``gauge_dim = 0``.
    """

    name: ClassVar[str] = "frame-S2"

    def __init__(self, radius: float = 1.0):
        self.radius = _check_positive(radius, "radius")
        self.group = _rotation_group(3)
        super().__init__()

    def _params(self) -> dict[str, Any]:
        return {"radius": self.radius}

    def _defect_meaning(self) -> str:
        return "the frame R (RᵀR = I, det R = 1)"

    def defect(self, q: Any) -> np.ndarray:
        return _rotation_defect(self._points(q))

    def project(self, q: Any) -> np.ndarray:
        return _nearest_rotation(self._points(q))

    def centreline(self, R: Any) -> np.ndarray:
        """Centreline points ``r·e₃ = r·R[..., :, 2]``, shape ``[..., 3]``."""
        return self.radius * self._points(R, "R")[..., :, 2]

    def position(self, q: Any) -> np.ndarray:
        """Position of the material point in E³: the centreline ``r·e₃`` (output and plots)."""
        return self.centreline(q)

    @staticmethod
    def frame(q: Any) -> np.ndarray:
        """Directors ``(e₁ e₂ e₃) = R`` as columns."""
        return np.asarray(q, dtype=float)


class MinkowskiFrameBundle(_GroupAsSpace):
    """The frame bundle F(M^{1,3}) of Minkowski space, acted on by the Poincaré group (§VIII.C).

    Notes
    -----
    * Points are events with inertial frames ``(r, E)`` stored as the 5×5 matrices
      ``[[1, 0ᵀ], [r, E]]`` (homogeneous coordinate first, time coordinate next), with
      ``Eᵀ η E = η``, ``η = diag(−1, 1, 1, 1)``, ``det E = 1`` and ``E₀₀ > 0`` (proper
      orthochronous: the component of the identity, the one ``exp`` reaches).
    * The action is the matrix product, ``(t; Λ)·(r, E) = (Λ r + t, Λ E)``.
    * ``q_r = I₅`` (the paper's ``D = 1``), ``lift(q) = q``, ``gauge_dim = 0``.
    * :meth:`defect`: ``‖EᵀηE − η‖_F/(‖E‖²_F/4) + |det E − 1| + ‖first row − e₀‖``, plus
      ``1 + |E₀₀|`` when ``E₀₀ ≤ 0``.  :meth:`project` is the η-Gram–Schmidt retraction
      of the columns of E (not a nearest point; exact frames are unchanged).
    """

    name: ClassVar[str] = "frame-M13"

    def __init__(self) -> None:
        self.group = _poincare()
        super().__init__()

    def _defect_meaning(self) -> str:
        return "the frame [[1, 0], [r, E]] (EᵀηE = η, det E = 1, E₀₀ > 0)"

    def defect(self, q: Any) -> np.ndarray:
        a = self._points(q)
        E = a[..., 1:, 1:]
        gram = np.swapaxes(E, -1, -2) @ _ETA @ E - _ETA
        scale = np.maximum(1.0, np.sum(E * E, axis=(-2, -1)) / 4.0)
        row = np.linalg.norm(a[..., 0, :] - np.eye(5)[0], axis=-1)
        d = np.linalg.norm(gram, axis=(-2, -1)) / scale + np.abs(np.linalg.det(E) - 1.0) + row
        e00 = E[..., 0, 0]
        return d + np.where(e00 > 0.0, 0.0, 1.0 + np.abs(e00))

    def project(self, q: Any) -> np.ndarray:
        a = self._points(q).copy()
        if not np.all(np.isfinite(a)):
            raise ValueError("q cannot be projected onto frame-M13: non-finite values")
        a[..., 0, :] = np.eye(5)[0]
        E = a[..., 1:, 1:]
        cols = [E[..., :, k].copy() for k in range(4)]
        for k in range(4):
            for j in range(k):
                cols[k] -= (_mink(cols[k], cols[j]) / _mink(cols[j], cols[j]))[..., None] * cols[j]
            nrm = _mink(cols[k], cols[k]) * (-1.0 if k == 0 else 1.0)
            if np.any(nrm <= 0.0):
                kind = "time-like" if k == 0 else "space-like"
                raise ValueError(f"q cannot be projected onto frame-M13: column {k} of E is not {kind}")
            cols[k] = cols[k] / np.sqrt(nrm)[..., None]
        cols[0] = cols[0] * np.where(cols[0][..., 0] < 0.0, -1.0, 1.0)[..., None]
        F = np.stack(cols, axis=-1)
        cols[3] = cols[3] * np.sign(np.linalg.det(F))[..., None]
        a[..., 1:, 1:] = np.stack(cols, axis=-1)
        return a


def _mink(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Minkowski product ``⟨x, y⟩ = −x₀y₀ + x⃗·y⃗`` over the last axis."""
    return -x[..., 0] * y[..., 0] + np.sum(x[..., 1:] * y[..., 1:], axis=-1)


# ====================================================================== plugin hook
@hookimpl
def cartan_register_spaces(register):
    """Register the built-in homogeneous spaces."""
    register("sphere", Sphere)
    register("E3", Euclidean3)
    register("E3xS2", PointDirector)
    register("frame-E3", FrameBundleE3)
    register("frame-E2", FrameBundleE2)
    register("frame-S2", SphereFrameBundle)
    register("frame-M13", MinkowskiFrameBundle)
