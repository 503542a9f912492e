"""Whether a discrete configuration still resolves its shape (the blow-up message's diagnosis).

A grid resolves a configuration when the frames of neighbouring nodes differ by a small
rotation.  The discrete strain of an edge is ``log(Φ_i⁻¹Φ_j)/h`` (paper §VI.C); as the rotation
angle between neighbours approaches π, that logarithm becomes ill-conditioned and then
ambiguous (the two rotations by ±π agree), so no time step, however small, keeps the run
stable: the shape needs more nodes.  A closed rod on 8 nodes starts at 2π/8 ≈ 0.79 rad per
edge and blows up when a wave drives an edge to ≈ 3 rad, at any Δt within the CFL estimate.

:func:`under_resolved` measures the largest rotation angle between neighbouring frames along
each axis (the rotational block of the relative frame: ``Φ`` itself for SO(n), its linear
block for the affine groups SE(2), SE(3) and the Poincaré group) and names it when it exceeds
:data:`LIMIT`; it says nothing for groups whose linear block is not a rotation (Lorentz boosts).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LIMIT", "largest_edge_rotation", "under_resolved"]

#: the neighbour rotation (rad) from which a blow-up message points at the resolution: half of
#: π, where the edge logarithm's condition number (θ/2)/tan(θ/2) has already grown to ≈ 1.3
#: and grows without bound as θ → π
LIMIT = math.pi / 2


def _rotation_block(Phi: np.ndarray, affine: bool) -> np.ndarray:
    return Phi[..., 1:, 1:] if affine else Phi


def largest_edge_rotation(scheme, state) -> tuple[float, int] | None:
    """The largest rotation angle between neighbouring frames, and its axis.

    Parameters
    ----------
    scheme : Scheme
        Any scheme with ``frames(state)`` ``[*shape, m, m]`` and a grid.
    state : State

    Returns
    -------
    (float, int) or None
        ``(θ_max in [0, π], axis)``; None when the frames are not finite, the linear block is
        not orthogonal (SO(1,3)), or the grid has a single node along every axis.
    """
    try:
        Phi = np.asarray(scheme.frames(state), dtype=float)
    except Exception:  # a configuration the reference cannot reconstruct: no diagnosis
        return None
    if not np.all(np.isfinite(Phi)):
        return None
    R = _rotation_block(Phi, bool(getattr(scheme.group, "affine", False)))
    k = R.shape[-1]
    eye = np.eye(k)
    if np.max(np.abs(np.swapaxes(R, -1, -2) @ R - eye), initial=0.0) > 1e-6:
        return None
    grid = scheme.grid
    best: tuple[float, int] | None = None
    for axis in range(grid.d):
        if grid.shape[axis] < 2:
            continue
        Ra = np.moveaxis(R, axis, 0)
        nxt = np.roll(Ra, -1, axis=0) if grid.periodic[axis] else Ra[1:]
        cur = Ra if grid.periodic[axis] else Ra[:-1]
        rel = np.swapaxes(cur, -1, -2) @ nxt
        # the angles of a rotation are the arguments of its eigenvalues
        angles = np.abs(np.angle(np.linalg.eigvals(rel.reshape(-1, k, k))))
        theta = float(np.max(angles, initial=0.0))
        if best is None or theta > best[0]:
            best = (theta, axis)
    return best


def under_resolved(scheme, state, limit: float = LIMIT) -> str | None:
    """A sentence naming an under-resolved shape, or None.

    Parameters
    ----------
    scheme : Scheme
    state : State
        Typically the last good state of a run that blew up.
    limit : float
        The neighbour rotation (rad) from which the shape counts as under-resolved.

    Returns
    -------
    str or None
        E.g. ``"the shape is under-resolved: neighbouring frames turn by up to 3.04 rad along
        axis 0 (n = 8 nodes), near π where the edge strain log(Φ_i⁻¹Φ_j)/h is no longer
        defined; refine the grid (more nodes) rather than Δt"``.
    """
    found = largest_edge_rotation(scheme, state)
    if found is None or found[0] < limit:
        return None
    theta, axis = found
    n = scheme.grid.shape[axis]
    return (f"the shape is under-resolved: neighbouring frames turn by up to {theta:.3g} rad along axis {axis} "
            f"(n = {n} nodes), near π where the edge strain log(Φ_i⁻¹Φ_j)/h is no longer defined; "
            "refine the grid (more nodes) rather than Δt")
