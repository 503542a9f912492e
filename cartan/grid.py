"""Material grids: d = 1, 2, 3 axes, each open or periodic, uniformly spaced.

A :class:`Grid` discretises the material base space M (paper §III) by nodes at
``u_k = k·h`` along each axis.  An open axis of length L with n nodes has spacing
``h = L/(n−1)`` and n − 1 edges; a periodic axis has ``h = L/n`` and n edges, the last one
joining node n − 1 back to node 0.  Edges along axis α join node ``i`` to its successor
along α (paper's charts, §III.D).
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

    def __init__(self, shape: int | Sequence[int], length: float | Sequence[float] = 1.0,
                 periodic: bool | Sequence[bool] = False):
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

    @property
    def d(self) -> int:
        return len(self.shape)

    @property
    def size(self) -> int:
        """Total number of nodes."""
        return int(np.prod(self.shape))

    @property
    def spacing(self) -> tuple[float, ...]:
        return tuple(L / (n if p else n - 1) for n, L, p in zip(self.shape, self.length, self.periodic))

    @property
    def axis_names(self) -> tuple[str, ...]:
        return AXIS_NAMES[: self.d]

    def coordinates(self, axis: int = 0) -> np.ndarray:
        """Material coordinates ``u_k = k h`` of the nodes along ``axis``, shape ``(n_axis,)``."""
        return np.arange(self.shape[axis]) * self.spacing[axis]

    def edge_shape(self, axis: int) -> tuple[int, ...]:
        """Shape of the array of edges along ``axis``."""
        s = list(self.shape)
        if not self.periodic[axis]:
            s[axis] -= 1
        return tuple(s)

    def edge_coordinates(self, axis: int = 0) -> np.ndarray:
        """Material coordinates of edge midpoints along ``axis``."""
        n = self.edge_shape(axis)[axis]
        return (np.arange(n) + 0.5) * self.spacing[axis]

    def node_weights(self) -> np.ndarray:
        """Quadrature weights of the nodes (trapezoidal; ∑ = ∏ L), shape ``self.shape``.

        These are the lumped masses per unit density of the lattice scheme: interior nodes
        carry h, ends of open axes h/2.
        """
        w = np.ones(self.shape)
        for axis, (n, h, p) in enumerate(zip(self.shape, self.spacing, self.periodic)):
            wa = np.full(n, h)
            if not p:
                wa[0] = wa[-1] = h / 2
            shape = [1] * self.d
            shape[axis] = n
            w = w * wa.reshape(shape)
        return w

    def to_dict(self) -> dict:
        return {"shape": list(self.shape), "length": list(self.length), "periodic": list(self.periodic)}
