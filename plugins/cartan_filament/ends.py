"""Prescribed end rotations of a filament (or any rod on SE(3)) in the statics.

``cartan.solve_static`` holds a clamped end, and the rotation components (3, 4, 5) of a pinned
node, at the starting configuration. An end turned by a prescribed rotation is therefore a
starting configuration whose end frame is turned: :func:`turned_end` returns it, and

* ``Clamped()`` at that end prescribes its position and its turned frame;
* ``Free()`` with ``pins={"end": (3, 4, 5)}`` prescribes the turned frame only (the position
  free, the reaction moment in ``reaction``) — the end rotation of the elastica, or a twist
  φ about the axis (uniform twist φ/L, torque Cφ/L);
* a rotation growing along a path is a sequence of solves, each started from the last
  equilibrium with its end turned by the next increment (``initial=turned_end(ds, Δ)``).

Two clamped ends of a straight inextensible filament leave its axial force undetermined
(the n − 1 length constraints between two held positions are dependent: any tension is in
equilibrium), and the Jacobian is singular; hold one of the ends in rotation only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cartan.problem import InitialState

__all__ = ["rotation_matrix", "turned_end"]


def rotation_matrix(rotation: Any) -> np.ndarray:
    """exp of the rotation vector ``rotation`` ``(3,)`` (Rodrigues), ``(3, 3)``.

    Raises
    ------
    ValueError
        ``rotation`` not three finite numbers.
    """
    w = np.asarray(rotation, dtype=float)
    if w.shape != (3,) or not np.all(np.isfinite(w)):
        raise ValueError(f"rotation must be a rotation vector of three finite numbers (radians), got {rotation!r}")
    a = float(np.linalg.norm(w))
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if a < 1e-12:
        return np.eye(3) + W
    return np.eye(3) + np.sin(a) / a * W + (1.0 - np.cos(a)) / a**2 * (W @ W)


def _frames(start: Any) -> np.ndarray:
    if isinstance(start, InitialState):
        Phi = np.asarray(start.Phi, dtype=float)
    elif hasattr(start, "data_vars"):  # a Dataset of solve_static or simulate: its last frame
        if "position" not in start or "frame" not in start:
            raise ValueError("start: a Dataset needs the variables position and frame (a run of an SE(3) rod)")
        pos = np.asarray(start["position"].isel(time=-1), dtype=float)
        Phi = np.zeros((*pos.shape[:-1], 4, 4))
        Phi[..., 0, 0] = 1.0
        Phi[..., 1:, 0] = pos
        Phi[..., 1:, 1:] = np.asarray(start["frame"].isel(time=-1), dtype=float)
    else:
        Phi = np.asarray(start, dtype=float)
    if Phi.ndim != 3 or Phi.shape[1:] != (4, 4):
        raise ValueError(f"start: the frames of a rod on SE(3), [n, 4, 4], got shape {Phi.shape}")
    return Phi.copy()


def turned_end(start: Any, rotation: Any, end: str | int = "end", frame: str = "body") -> InitialState:
    """The starting configuration ``start`` with the frame of one end turned by ``rotation``.

    Parameters
    ----------
    start : InitialState, array ``[n, 4, 4]`` or Dataset
        The frames Φ (SE(3), the paper's affine convention: position in column 0); a Dataset
        of ``solve_static`` or ``simulate``: its last frame.
    rotation : array_like ``(3,)``
        Rotation vector ω (radians): the end's rotation R becomes R·exp(ω̂) (``frame="body"``,
        ω in the end's directors: (ω₁, 0, 0) twists about the tangent d₁) or exp(ω̂)·R
        (``frame="spatial"``). Its position is kept.
    end : "start", "end" or int
        The node turned (an int: any node index).
    frame : "body" or "spatial"

    Returns
    -------
    InitialState
        Frames only (no velocity); give it to ``cartan.Problem`` or as ``initial=`` of
        ``cartan.solve_static`` (which holds clamped ends and pins at it).

    Raises
    ------
    ValueError
        Bad ``rotation``, ``end`` (allowed: "start", "end", −n ≤ i < n) or ``frame``.
    """
    Phi = _frames(start)
    n = Phi.shape[0]
    if isinstance(end, str):
        if end not in ("start", "end"):
            raise ValueError(f"end must be 'start', 'end' or a node index {-n}..{n - 1}, got {end!r}")
        node = 0 if end == "start" else n - 1
    elif isinstance(end, int | np.integer) and not isinstance(end, bool) and -n <= int(end) < n:
        node = int(end) % n
    else:
        raise ValueError(f"end must be 'start', 'end' or a node index {-n}..{n - 1}, got {end!r}")
    if frame not in ("body", "spatial"):
        raise ValueError(f"frame must be 'body' or 'spatial', got {frame!r}")
    R = rotation_matrix(rotation)
    E = Phi[node, 1:, 1:]
    Phi[node, 1:, 1:] = E @ R if frame == "body" else R @ E
    return InitialState(Phi=Phi)
