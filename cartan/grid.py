"""Material grids: d = 1, 2, 3 axes, each open or periodic, uniformly spaced.

A :class:`Grid` discretises the material base space M (paper §III) by nodes at
``u_k = k·h`` along each axis.  An open axis of length L with n nodes has spacing
``h = L/(n−1)`` and n − 1 edges; a periodic axis has ``h = L/n`` and n edges, the last one
joining node n − 1 back to node 0.  Edges along axis α join node ``i`` to its successor
along α (paper's charts, §III.D).

A **glued** axis (``glued[α] = β``) closes a chart over poles, as colatitude closes the sphere
S¹ × [0, π] (paper §VII.B): its n nodes are staggered, ``u_k = (k + ½)h`` with ``h = L/n``, so
that no node sits on an end, and each end of a line along α continues across the end onto the
line half way round the periodic axis β (index ``i_β + n_β/2``, n_β even).  Such an axis has
n + 1 edges per line: edge 0 comes from the ghost of node 0 beyond the start (node 0 of the
opposite line), edge n goes to the ghost of node n − 1 beyond the end.  The frame the ghost is
seen in (a constant group element, the chart's turn across the end) belongs to the initial
state (:class:`~cartan.problem.InitialState` ``glue``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

AXIS_NAMES = ("u", "v", "w")


def _tuple(x, d: int, what: str) -> tuple:
    if np.isscalar(x):
        return (x,) * d
    x = tuple(x)
    if len(x) != d:
        raise ValueError(f"{what} must have {d} entries (one per axis), got {len(x)}")
    return x


@dataclass(frozen=True)
class Grid:
    """A uniform tensor-product grid on the material base space.

    Parameters
    ----------
    shape : int or sequence of int
        Number of nodes along each axis (d = len(shape) ∈ {1, 2, 3}); ≥ 2 per open axis,
        ≥ 3 per periodic axis.
    length : float or sequence of float
        Reference (material) length L₀ of each axis, > 0.
    periodic : bool or sequence of bool
        Whether each axis is periodic (a closed rod, a torus).
    glued : None or sequence of (int or None)
        Per axis, None (default) or the index β of the periodic axis across whose half-turn the
        axis's ends are glued (module docstring; d = 2 or 3, n_β even, the axis itself open).

    Attributes
    ----------
    d : int
        Material dimension.
    spacing : tuple of float
        h along each axis.
    """

    shape: tuple[int, ...]
    length: tuple[float, ...] = field(default=(1.0,))
    periodic: tuple[bool, ...] = field(default=(False,))
    glued: tuple[int | None, ...] | None = None

    def __init__(self, shape: int | Sequence[int], length: float | Sequence[float] = 1.0,
                 periodic: bool | Sequence[bool] = False, glued: Sequence[int | None] | None = None):
        shape_t = (shape,) if np.isscalar(shape) else tuple(shape)
        d = len(shape_t)
        if d not in (1, 2, 3):
            raise ValueError(f"shape must have 1, 2 or 3 axes, got {d}")
        lengths = _tuple(length, d, "length")
        for k, L in enumerate(lengths):
            if isinstance(L, (bool, np.bool_, str, bytes)) or not isinstance(L, (int, float, np.integer, np.floating)):
                raise ValueError(f"length[{k}] must be a finite number > 0, got {L!r}")
        length_t = tuple(float(v) for v in lengths)
        flags = _tuple(periodic, d, "periodic")
        for k, p in enumerate(flags):
            if not isinstance(p, (bool, np.bool_)):
                raise ValueError(f"periodic[{k}] must be True or False, got {p!r}")
        periodic_t = tuple(bool(v) for v in flags)
        for k, (n, L, p) in enumerate(zip(shape_t, length_t, periodic_t)):
            if (isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, float, np.integer, np.floating))
                    or not np.isfinite(n) or int(n) != n or n < (3 if p else 2)):
                raise ValueError(
                    f"shape[{k}] must be an integer ≥ {3 if p else 2} for a {'periodic' if p else 'open'} "
                    f"axis, got {n}"
                )
            if not np.isfinite(L) or L <= 0:
                raise ValueError(f"length[{k}] must be finite and > 0, got {L}")
        object.__setattr__(self, "shape", tuple(int(n) for n in shape_t))
        object.__setattr__(self, "length", length_t)
        object.__setattr__(self, "periodic", periodic_t)
        object.__setattr__(self, "glued", _check_glued(glued, self.shape, periodic_t))

    def is_glued(self, axis: int) -> bool:
        """Whether ``axis`` is glued across its ends (module docstring)."""
        return self.glued is not None and self.glued[axis] is not None

    @property
    def d(self) -> int:
        return len(self.shape)

    @property
    def size(self) -> int:
        """Total number of nodes."""
        return int(np.prod(self.shape))

    @property
    def spacing(self) -> tuple[float, ...]:
        return tuple(L / (n if p or self.is_glued(a) else n - 1)
                     for a, (n, L, p) in enumerate(zip(self.shape, self.length, self.periodic)))

    @property
    def axis_names(self) -> tuple[str, ...]:
        return AXIS_NAMES[: self.d]

    def coordinates(self, axis: int = 0) -> np.ndarray:
        """Material coordinates ``u_k = k h`` of the nodes along ``axis`` (``(k + ½)h`` on a glued
        axis), shape ``(n_axis,)``."""
        return (np.arange(self.shape[axis]) + (0.5 if self.is_glued(axis) else 0.0)) * self.spacing[axis]

    def edge_shape(self, axis: int) -> tuple[int, ...]:
        """Shape of the array of edges along ``axis``."""
        s = list(self.shape)
        if self.is_glued(axis):
            s[axis] += 1
        elif not self.periodic[axis]:
            s[axis] -= 1
        return tuple(s)

    def edge_coordinates(self, axis: int = 0) -> np.ndarray:
        """Material coordinates of edge midpoints along ``axis``."""
        n = self.edge_shape(axis)[axis]
        return (np.arange(n) + (0.0 if self.is_glued(axis) else 0.5)) * self.spacing[axis]

    def node_weights(self) -> np.ndarray:
        """Quadrature weights of the nodes (trapezoidal; ∑ = ∏ L), shape ``self.shape``.

        These are the lumped masses per unit density of the lattice scheme: interior nodes
        carry h, ends of open axes h/2.
        """
        w = np.ones(self.shape)
        for axis, (n, h, p) in enumerate(zip(self.shape, self.spacing, self.periodic)):
            wa = np.full(n, h)
            if not p and not self.is_glued(axis):
                wa[0] = wa[-1] = h / 2
            shape = [1] * self.d
            shape[axis] = n
            w = w * wa.reshape(shape)
        return w

    def to_dict(self) -> dict:
        out = {"shape": list(self.shape), "length": list(self.length), "periodic": list(self.periodic)}
        if self.glued is not None:
            out["glued"] = [-1 if b is None else int(b) for b in self.glued]
        return out


def _check_glued(glued, shape: tuple[int, ...], periodic: tuple[bool, ...]) -> tuple[int | None, ...] | None:
    """The validated ``glued`` declaration of a grid (see :class:`Grid`); None when no axis is glued."""
    if glued is None:
        return None
    d = len(shape)
    if isinstance(glued, str | bytes) or not hasattr(glued, "__len__") or len(glued) != d:
        raise ValueError(f"glued must be None or a list of {d} entries (None or an axis index per axis), "
                         f"got {glued!r}")
    out: list[int | None] = []
    for a, b in enumerate(glued):
        if b is None or (isinstance(b, int | np.integer) and not isinstance(b, bool) and b < 0):
            out.append(None)
            continue
        if isinstance(b, bool) or not isinstance(b, int | np.integer) or not 0 <= b < d or b == a:
            raise ValueError(f"glued[{a}] must be None or the index of another axis in [0, {d - 1}], got {b!r}")
        if periodic[a]:
            raise ValueError(f"glued[{a}]: a glued axis is open (periodic[{a}] must be False)")
        if not periodic[b] or shape[b] % 2:
            raise ValueError(f"glued[{a}] = {b}: the ends are glued half way round axis {b}, which must be periodic "
                             f"with an even number of nodes (shape[{b}] = {shape[b]}, periodic[{b}] = {periodic[b]})")
        out.append(int(b))
    return tuple(out) if any(b is not None for b in out) else None
