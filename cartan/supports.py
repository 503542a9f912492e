"""Elastic supports and symmetry planes on the faces of a grid (paper §IV.B: potential loads).

A support is a :class:`~cartan.problem.PotentialLoad` that is not multiplied by the load
parameter λ in statics and continuation (:attr:`cartan.problem.Load.scaled` False): stiff
springs, per unit reference volume (chart area for d = 2), holding quantities of the
configuration q = Φ·q_r on the nodes of some faces of the grid and zero elsewhere.  The core
pulls the potential back to a generalised force (paper §IV.B), so a support works with every
scheme and with ``solve_static``'s node-local load Jacobian.

Faces
    ``"u-start"``, ``"u-end"``, ``"v-start"``, ``"v-end"``, ``"w-start"``, ``"w-end"``: the
    first or last layer of nodes along axis 0, 1, 2 of the grid (the ends of a d = 2 chart are
    its edges).  A face must exist for the grid's d (``dim``).

Points
    The supports need a frame-bundle medium on SE(3) whose points are the 4 × 4 matrices
    q = Φ (q_r = I): x = q[1:, 0] the position and R = q[1:, 1:] the frame, whose columns
    R e_i (i = 0, 1, 2) are the *directors*.  Which directors a support holds is the parameter
    ``directors``: by default the third one, p = R e₃, for d = 2 (a shell: the rotation about
    the director is a gauge, paper §VI.B) and all three for d = 1, 3 (a rod, a micropolar solid).

Penalty: the held quantities move by O(reaction/stiffness).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from .medium import check_finite, check_positive
from .problem import PotentialLoad

__all__ = ["FACES", "PenaltySupport", "SymmetrySupport", "face_nodes", "faces_of"]

#: Every face name, two per axis (axis 0, 1, 2 = u, v, w)
FACES: tuple[str, ...] = ("u-start", "u-end", "v-start", "v-end", "w-start", "w-end")


def faces_of(dim: int) -> tuple[str, ...]:
    """The faces of a grid of dimension ``dim`` (1, 2 or 3): ``FACES[:2·dim]``."""
    if isinstance(dim, bool) or dim not in (1, 2, 3):
        raise ValueError(f"dim must be 1, 2 or 3 (the grid's d), got {dim!r}")
    return FACES[: 2 * dim]


def face_nodes(face: str, dim: int) -> tuple[int, tuple]:
    """The axis a face ends and the index of its nodes in a ``(*shape, …)`` array, shape of length ``dim``.

    Parameters
    ----------
    face : str
        One of :func:`faces_of` (``dim``).
    dim : int
        The grid's d.

    Returns
    -------
    (int, tuple)
        The axis (0, 1, 2) and the index tuple (``dim`` entries: 0 or −1 on the axis, ``slice(None)`` elsewhere).
    """
    if face not in faces_of(dim):
        raise ValueError(f"face must be one of {', '.join(faces_of(dim))} for d = {dim}, got {face!r}")
    axis = "uvw".index(face[0])
    idx: list[Any] = [slice(None)] * dim
    idx[axis] = 0 if face.endswith("start") else -1
    return axis, tuple(idx)


def _check_faces(edges: Any, dim: int) -> tuple[str, ...]:
    allowed = faces_of(dim)
    if edges is None:
        return allowed
    edges = (edges,) if isinstance(edges, str) else tuple(edges)
    bad = [e for e in edges if e not in allowed]
    if bad or not edges:
        raise ValueError(f"edges must be a non-empty list of {', '.join(allowed)} (the faces of a d = {dim} grid); "
                         f"got {list(edges)}")
    return edges


def _check_directors(directors: Any, dim: int) -> tuple[int, ...]:
    if directors is None:
        return (2,) if dim == 2 else (0, 1, 2)
    try:
        out = tuple(int(i) for i in np.atleast_1d(directors))
        ok = all(float(i) == j for i, j in zip(np.atleast_1d(directors), out, strict=True))
    except (TypeError, ValueError):
        ok = False
    if not ok or not out or len(set(out)) != len(out) or any(i not in (0, 1, 2) for i in out):
        raise ValueError(f"directors must be a non-empty list of distinct frame columns 0, 1, 2, got {directors!r}")
    return out


class PenaltySupport(PotentialLoad):
    """Elastic face supports: ``U = ½ (x − x̄)ᵀ K (x − x̄) + ½ Σ_i (p_i − p̄_i)ᵀ S (p_i − p̄_i)``
    per unit reference volume (chart area for d = 2).

    x is a node's position and p_i = R e_i its directors, i over ``directors``, all in the
    spatial frame; x̄ and p̄_i the held values (those of the problem's initial state, taken by
    :meth:`attach`, or set by :meth:`hold`).  On the nodes of the listed faces
    K = diag(``position_stiffness``) and S = s Σ t tᵀ, summed over the faces through the node and,
    for each, over its reference tangents t = R̄ e_b, b < d the other axes (R̄e₂ on u-faces and
    R̄e₁ on v-faces of a d = 2 chart): with ``director_stiffness`` s > 0 a held director may turn
    about the face's normal direction but not along the face.  For a shell (d = 2, the director
    p = R e₃ held) it is the *hard* simple support (w = 0, β_s = 0, M_n = 0), s = 0 the soft one.
    Elsewhere U = 0.  A support: not multiplied by the load parameter λ
    (:attr:`cartan.problem.Load.scaled` False).

    Parameters
    ----------
    edges : str or sequence of str, optional
        Faces (:data:`FACES`) of a d = ``dim`` grid; default all of them.
    position_stiffness : array_like, shape ``(3,)``
        Stiffness per unit reference volume of each spatial position component (≥ 0).
    director_stiffness : float
        s ≥ 0 (per unit reference volume).
    dim : int
        The grid's d (1, 2 or 3); default 2.
    directors : sequence of int, optional
        The frame columns held (0, 1, 2); default ``(2,)`` (p = R e₃) for d = 2, ``(0, 1, 2)`` otherwise.
    """

    EDGES: ClassVar[tuple[str, ...]] = FACES[:4]

    scaled = False  # a support: acts at every load level

    def __init__(self, edges: Any = None, position_stiffness: Any = (0.0, 0.0, 1.0), director_stiffness: float = 0.0,
                 *, dim: int = 2, directors: Sequence[int] | None = None):
        faces_of(dim)
        self.dim = int(dim)
        self.edges = _check_faces(edges, self.dim)
        self.directors = _check_directors(directors, self.dim)
        self.k = check_positive("position_stiffness", position_stiffness, allow_zero=True, shape=(3,))
        self.s = float(check_positive("director_stiffness", director_stiffness, allow_zero=True, shape=()))
        self._held: tuple[np.ndarray, ...] | None = None

    def bind(self, medium: Any) -> None:
        super().bind(medium)
        q_r = getattr(medium.space, "q_r", None)
        if q_r is None or np.shape(q_r) != (4, 4) or not np.allclose(q_r, np.eye(4)):
            raise ValueError(f"{type(self).__name__} needs a medium whose points are SE(3) frames q = Φ (q_r = I), "
                             f"not {getattr(medium, 'name', medium)!r}")

    def attach(self, problem: Any) -> None:
        """Hold the problem's initial state, unless :meth:`hold` or an earlier problem set the held
        values: they are the start's, not those of whatever configuration is evaluated first (a
        Jacobian's finite differences may evaluate the load at a displaced state before the start)."""
        if self._held is None:
            Phi = getattr(problem.initial, "Phi", None)
            if Phi is not None and np.shape(Phi)[-2:] == (4, 4):
                self.hold(Phi)

    def _shape(self, Phi: np.ndarray) -> tuple[int, ...]:
        shape = Phi.shape[:-2]
        if Phi.shape[-2:] != (4, 4) or len(shape) != self.dim:
            raise ValueError(f"{type(self).__name__} with dim = {self.dim} needs SE(3) frames of shape "
                             f"(*shape, 4, 4) on a d = {self.dim} grid, got {Phi.shape}")
        return shape

    def _stiffness(self, Phi: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """K and S ``(*shape, 3, 3)``."""
        K = np.zeros((*shape, 3, 3))
        S = np.zeros((*shape, 3, 3))
        for e in self.edges:
            axis, idx = face_nodes(e, self.dim)
            K[idx] = np.diag(self.k)
            for b in range(self.dim):
                if b != axis:
                    t = Phi[idx][..., 1:, 1 + b]   # a reference tangent of the face, R̄ e_b
                    S[idx] += self.s * t[..., :, None] * t[..., None, :]
        return K, S

    def hold(self, Phi: np.ndarray) -> PenaltySupport:
        """Hold the positions and directors of ``Phi`` ``(*shape, 4, 4)`` (returns self)."""
        Phi = np.asarray(Phi, dtype=float)
        K, S = self._stiffness(Phi, self._shape(Phi))
        self._held = (K, S, Phi[..., 1:, 0].copy(), Phi[..., 1:, 1:].copy())
        return self

    def _fields(self, q: np.ndarray) -> tuple[np.ndarray, ...]:
        if self._held is None or self._held[0].shape[:-2] != q.shape[:-2]:
            self.hold(q)
        return self._held

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """U ``[*shape]`` of the configurations q ``[*shape, 4, 4]``."""
        K, S, x, R = self._fields(q)
        cols = [1 + i for i in self.directors]
        dx = q[..., 1:, 0] - x
        dp = q[..., 1:, cols] - R[..., :, list(self.directors)]
        return 0.5 * (np.einsum("...i,...ij,...j->...", dx, K, dx) + np.einsum("...ia,...ij,...ja->...", dp, S, dp))

    def potential_gradient(self, q: np.ndarray) -> np.ndarray:
        """∂U/∂q ``[*shape, 4, 4]``: K(x − x̄) in the position slots, S(p_i − p̄_i) in the held directors'."""
        K, S, x, R = self._fields(q)
        cols = [1 + i for i in self.directors]
        grad = np.zeros(np.shape(q))
        grad[..., 1:, 0] = np.einsum("...ij,...j->...i", K, q[..., 1:, 0] - x)
        grad[..., 1:, cols] = np.einsum("...ij,...ja->...ia", S, q[..., 1:, cols] - R[..., :, list(self.directors)])
        return grad

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "simple-support", "edges": list(self.edges), "position_stiffness": self.k.tolist(),
                "director_stiffness": self.s, "dim": self.dim, "directors": list(self.directors)}


class SymmetrySupport(PenaltySupport):
    """A symmetry plane (or a plane support) on faces:
    ``U = ½ k (n·(x − x̄))² + ½ s Σ_i (n·(p_i − p̄_i))²`` per unit reference volume on the nodes
    of the listed faces, 0 elsewhere.

    n is a fixed spatial unit vector, x a node's position and p_i = R e_i its directors, i over
    ``directors``; x̄ and p̄_i the held values (those of the problem's initial state, taken by
    :meth:`attach`, or set by :meth:`hold`).  On a symmetry plane through the held nodes with normal n, a
    mirror-symmetric deformation has n·u = 0 and keeps every frame vector that lies in the
    plane in it: the rotation is about n, so the tangential moment and the transverse force
    through the plane vanish by symmetry and need no condition.

    * All three directors held (default for d = 1, 3; a rod, a micropolar solid):
      Σ_i (n·(R − R̄)e_i)² = |Rᵀn − R̄ᵀn|² = 2(1 − n·R R̄ᵀ n), zero exactly when R R̄ᵀ is a rotation
      about n (at any angle).
    * The director p = R e₃ alone (default for d = 2): a shell, whose drill (the rotation about
      p) is a gauge (paper §VI.B), so holding the director holds every rotation a symmetry plane
      constrains; U = ½ k (n·(x − x̄))² + ½ s (n·(p − p̄))².

    A support: not scaled by the load parameter λ (:attr:`cartan.problem.Load.scaled` False); a
    penalty, as :class:`PenaltySupport`.

    Parameters
    ----------
    edges : str or sequence of str, optional
        Faces (:data:`FACES`) of a d = ``dim`` grid; default all of them.
    normal : str or array_like, shape ``(3,)``
        ``"x"``, ``"y"``, ``"z"`` or a non-zero spatial vector (normalised).
    position_stiffness : float
        k ≥ 0, per unit reference volume.
    director_stiffness : float
        s ≥ 0, per unit reference volume.
    dim : int
        The grid's d (1, 2 or 3); default 2.
    directors : sequence of int, optional
        The frame columns held (0, 1, 2); default ``(2,)`` for d = 2, ``(0, 1, 2)`` otherwise.
    """

    AXES: ClassVar[dict[str, tuple[float, float, float]]] = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0),
                                                             "z": (0.0, 0.0, 1.0)}

    def __init__(self, edges: Any = None, normal: Any = "x", position_stiffness: float = 1.0,
                 director_stiffness: float = 1.0, *, dim: int = 2, directors: Sequence[int] | None = None):
        if isinstance(normal, str):
            if normal not in self.AXES:
                raise ValueError(f"normal must be 'x', 'y', 'z' or a non-zero vector (3,), got {normal!r}")
            n = np.array(self.AXES[normal])
        else:
            n = check_finite("normal", normal, (3,))
            if not np.linalg.norm(n) > 0.0:
                raise ValueError(f"normal must be 'x', 'y', 'z' or a non-zero vector (3,), got {normal!r}")
        self.normal = n / np.linalg.norm(n)
        k = float(check_positive("position_stiffness", position_stiffness, allow_zero=True, shape=()))
        super().__init__(edges, np.zeros(3), director_stiffness, dim=dim, directors=directors)
        self.kn = k

    def _stiffness(self, Phi: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        mask = np.zeros(shape)
        for e in self.edges:
            mask[face_nodes(e, self.dim)[1]] = 1.0
        nn = np.outer(self.normal, self.normal)
        return mask[..., None, None] * (self.kn * nn), mask[..., None, None] * (self.s * nn)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "symmetry", "edges": list(self.edges), "normal": self.normal.tolist(),
                "position_stiffness": self.kn, "director_stiffness": self.s, "dim": self.dim,
                "directors": list(self.directors)}
