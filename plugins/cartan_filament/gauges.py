"""Adapted frames of a sampled centreline: the Frenet–Serret and Bishop gauges (paper §III.E,
§VII.A).

A filament's structure field Φ = (r; E) on SE(3) is adapted when e₁ is the unit tangent of the
centreline r; what is left is an SO(2) gauge, the rotation of (e₂, e₃) about e₁ (§III.E).  With
the strain X = Φ⁻¹∂_sΦ = {θ; π} (translation first, ∂_s e₁ = π₃e₂ − π₂e₃, §VII.A):

* **Frenet–Serret**: e₂ the principal normal, e₃ = e₁ × e₂ the binormal, so that
  θ = (h, 0, 0) and π = (τ, 0, κ) (κ > 0 the curvature, τ the torsion).  Undefined where
  κ = 0: :func:`frenet_frames` raises a ``ValueError`` naming the node and its arclength.
* **Bishop** (parallel transport): π₁ = 0, so π = (0, π₂, π₃) with π₂² + π₃² = κ²; defined
  on every regular curve.  :func:`bishop_frames` transports the normal from node to node by
  the minimal rotation taking one tangent to the next (the discrete parallel transport of
  discrete elastic rods).

Both return :class:`AdaptedFrames` (positions and frames as columns d₁, d₂, d₃; the 4 × 4
SE(3) elements of the paper's affine convention), which give an
:class:`~cartan.problem.InitialState` directly or through the rods' ``"arrays"`` initial kind.

If a frame E_B is the frame E_F rotated about e₁ by φ(s), E_B = E_F·Rot_{e₁}(φ), then
π_B = Rot_{e₁}(−φ) π_F + φ′e₁; with π_F = (τ, 0, κ) the Bishop condition π_B,1 = 0 is φ′ = −τ:
**the Bishop frame is the Frenet frame turned about the tangent by φ(s) = φ(0) − ∫₀ˢ τ ds**
(right-handed about e₁); :func:`relative_angle` measures φ.

Discretisation: tangents and second derivatives by second-order finite differences of the
samples (centred; one-sided at the ends of an open curve; periodic on a closed one), so the
frames are O(h²) accurate; the discrete parallel transport is the minimal rotation between the
finite-difference tangents.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["GAUGES", "AdaptedFrames", "adapt_frames", "bishop_frames", "curve_derivatives", "frenet_frames",
           "relative_angle", "transport_rotation", "twist_angle"]

#: the gauges of the ``filament`` medium's ``gauge`` parameter
GAUGES: tuple[str, ...] = ("material", "bishop", "frenet")

#: curvature below which the Frenet frame is refused, relative to 1/(arclength of the curve)
KAPPA_MIN = 1e-8


@dataclass
class AdaptedFrames:
    """An adapted frame field along a sampled centreline.

    Attributes
    ----------
    positions : ndarray ``[n, 3]``
        The samples r_i.
    frames : ndarray ``[n, 3, 3]``
        Directors (e₁, e₂, e₃) as columns; e₁ the unit tangent.
    gauge : str
        ``"frenet"`` or ``"bishop"``.
    spacing : float
        Parameter spacing h of the samples.
    closed : bool
        Whether the curve is closed (node n − 1 joins node 0).
    curvature : ndarray ``[n]``
        Curvature κ_i at the nodes (finite differences).
    info : dict
        ``"closure_angle"`` for a closed curve in the Bishop gauge: the angle by which the
        transported frame fails to return to itself after one turn (right-handed about e₁ at
        node 0; 0 for a planar curve); ``"twist"``, the constant π₁ when it is spread.
    """

    positions: np.ndarray
    frames: np.ndarray
    gauge: str
    spacing: float
    closed: bool
    curvature: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def Phi(self) -> np.ndarray:
        """The SE(3) elements ``[n, 4, 4]`` (paper's convention: ``[[1, 0ᵀ], [r, E]]``)."""
        n = self.positions.shape[0]
        Phi = np.zeros((n, 4, 4))
        Phi[:, 0, 0] = 1.0
        Phi[:, 1:, 0] = self.positions
        Phi[:, 1:, 1:] = self.frames
        return Phi

    def initial_state(self, velocity: np.ndarray | None = None):
        """The :class:`~cartan.problem.InitialState` with these frames (and body velocity
        ``velocity`` ``[n, 6]`` or ``[6]``, zero by default).  A closed curve needs a
        periodic grid of n nodes."""
        from cartan.problem import InitialState

        n = self.positions.shape[0]
        N = np.zeros((n, 6)) if velocity is None else np.broadcast_to(np.asarray(velocity, float), (n, 6)).copy()
        return InitialState(Phi=self.Phi, N=N)

    def edge_strains(self) -> np.ndarray:
        """Lattice edge strains X_e = log(Φ_i⁻¹Φ_{i+1})/h ``[E, 6]`` (E = n − 1, or n closed),
        components (θ; π)."""
        from cartan.groups.se3 import SE3

        g = SE3()
        Phi = self.Phi
        head = np.roll(Phi, -1, axis=0) if self.closed else Phi[1:]
        tail = Phi if self.closed else Phi[:-1]
        return g.log(g.compose(g.inverse(tail), head)) / self.spacing


def _check_samples(positions: Any, spacing: float, closed: bool) -> tuple[np.ndarray, float]:
    r = np.asarray(positions, dtype=float)
    if r.ndim != 2 or r.shape[1] != 3:
        raise ValueError(f"positions must have shape (n, 3), got {r.shape}")
    if r.shape[0] < (3 if closed else 4):
        raise ValueError(f"positions needs at least {3 if closed else 4} samples (closed={closed}), got {r.shape[0]}")
    if not np.all(np.isfinite(r)):
        raise ValueError("positions must be finite")
    h = float(spacing)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"spacing must be a finite number > 0, got {spacing!r}")
    return r, h


def curve_derivatives(positions: Any, spacing: float = 1.0, closed: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives of a sampled curve by second-order finite differences.

    Parameters
    ----------
    positions : array_like ``[n, 3]``
        Samples r_i = r(u_i), u_i = i·h.
    spacing : float
        h > 0.
    closed : bool
        Periodic differences (node n − 1 joins node 0).

    Returns
    -------
    (r′, r″) : ndarrays ``[n, 3]``
        Centred differences; second-order one-sided at the ends of an open curve.
    """
    r, h = _check_samples(positions, spacing, closed)
    if closed:
        rp, rm = np.roll(r, -1, axis=0), np.roll(r, 1, axis=0)
        return (rp - rm) / (2 * h), (rp - 2 * r + rm) / h**2
    d1 = np.empty_like(r)
    d2 = np.empty_like(r)
    d1[1:-1] = (r[2:] - r[:-2]) / (2 * h)
    d2[1:-1] = (r[2:] - 2 * r[1:-1] + r[:-2]) / h**2
    d1[0] = (-3 * r[0] + 4 * r[1] - r[2]) / (2 * h)
    d1[-1] = (3 * r[-1] - 4 * r[-2] + r[-3]) / (2 * h)
    d2[0] = (2 * r[0] - 5 * r[1] + 4 * r[2] - r[3]) / h**2
    d2[-1] = (2 * r[-1] - 5 * r[-2] + 4 * r[-3] - r[-4]) / h**2
    return d1, d2


def _arclength(r: np.ndarray, closed: bool) -> np.ndarray:
    seg = np.linalg.norm(np.diff(r, axis=0), axis=-1)
    return np.concatenate([[0.0], np.cumsum(seg)])


def _tangents(rp: np.ndarray, r: np.ndarray, closed: bool) -> np.ndarray:
    speed = np.linalg.norm(rp, axis=-1)
    bad = np.flatnonzero(~(speed > 0))
    if bad.size:
        s = _arclength(r, closed)
        raise ValueError(f"positions: the curve is not regular at node {bad[0]} (arclength s = {s[bad[0]]:.6g}): "
                         "zero tangent")
    return rp / speed[:, None]


def frenet_frames(positions: Any, spacing: float = 1.0, closed: bool = False,
                  kappa_min: float | None = None) -> AdaptedFrames:
    """The Frenet–Serret frame (e₁ tangent, e₂ principal normal, e₃ binormal) of a sampled curve.

    Parameters
    ----------
    positions : array_like ``[n, 3]``
        Samples of the centreline at u_i = i·h (any regular parametrisation).
    spacing : float, default 1
        h > 0 (sets the scale of the curvature only).
    closed : bool, default False
        A closed curve (periodic differences).
    kappa_min : float, optional
        Smallest curvature accepted, ≥ 0 (default 1e-8/ℓ, ℓ the polygon length).

    Returns
    -------
    AdaptedFrames
        ``gauge = "frenet"``; strains θ = (|r′|, 0, 0), π = (τ, 0, κ) to O(h²).

    Raises
    ------
    ValueError
        Where κ ≤ ``kappa_min`` (a straight piece or an inflection: the principal normal is
        undefined there), naming the first such node and its arclength; use
        :func:`bishop_frames` there.
    """
    r, h = _check_samples(positions, spacing, closed)
    rp, rpp = curve_derivatives(r, h, closed)
    t = _tangents(rp, r, closed)
    speed = np.linalg.norm(rp, axis=-1)
    normal = rpp - np.sum(rpp * t, axis=-1)[:, None] * t
    kappa = np.linalg.norm(normal, axis=-1) / speed**2
    s = _arclength(r, closed)
    ell = s[-1] + (np.linalg.norm(r[0] - r[-1]) if closed else 0.0)
    kmin = KAPPA_MIN / ell if kappa_min is None else float(kappa_min)
    if not (np.isfinite(kmin) and kmin >= 0):
        raise ValueError(f"kappa_min must be a finite number ≥ 0, got {kappa_min!r}")
    _frenet_refused(kappa, kmin, s, None)
    n2 = normal / np.linalg.norm(normal, axis=-1)[:, None]
    frames = np.stack([t, n2, np.cross(t, n2)], axis=-1)
    return AdaptedFrames(r, frames, "frenet", h, closed, kappa)


def transport_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The minimal rotations taking the unit vectors ``a`` to ``b`` (rotation about a × b),
    ``[..., 3, 3]``: the discrete parallel transport between consecutive tangents.

    Raises
    ------
    ValueError
        When a = −b somewhere (the transport is undefined: the polygon turns back on itself).
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    c = np.sum(a * b, axis=-1)
    if np.any(c <= -1.0 + 1e-12):
        raise ValueError("consecutive tangents are opposite: the parallel transport is undefined")
    v = np.cross(a, b)
    vx = np.zeros((*v.shape[:-1], 3, 3))
    vx[..., 0, 1], vx[..., 0, 2] = -v[..., 2], v[..., 1]
    vx[..., 1, 0], vx[..., 1, 2] = v[..., 2], -v[..., 0]
    vx[..., 2, 0], vx[..., 2, 1] = -v[..., 1], v[..., 0]
    return np.eye(3) + vx + (vx @ vx) / (1.0 + c)[..., None, None]


def bishop_frames(positions: Any, spacing: float = 1.0, closed: bool = False,
                  normal: Any = None, spread_closure: bool = True) -> AdaptedFrames:
    """The Bishop (parallel-transport) frame of a sampled curve: π₁ = 0.

    Parameters
    ----------
    positions : array_like ``[n, 3]``
        Samples of the centreline at u_i = i·h.
    spacing : float, default 1
        h > 0.
    closed : bool, default False
        A closed curve (periodic differences).  The transported frame need not close: its
        failure to do so after one turn is the closure angle α (``info["closure_angle"]``;
        E_n = E₀·Rot_{e₁}(α); zero for a planar curve, otherwise fixed by the writhe).
    normal : array_like ``(3,)``, optional
        The first normal e₂ at node 0 (projected orthogonally to the tangent); default: the
        Frenet normal at node 0 when κ₀ > 0, else the axis least aligned with the tangent.
    spread_closure : bool, default True
        On a closed curve with α ≠ 0, turn node i about its tangent by −α·i/n, so that the
        frame closes with the constant twist π₁ = −α/(n h) on every edge (to O(h²); a closed curve with
        α ≠ 0 has no periodic frame with π₁ = 0).  False: the parallel-transported frame
        itself, whose closing edge carries the whole twist −α/h.

    Returns
    -------
    AdaptedFrames
        ``gauge = "bishop"``.
    """
    r, h = _check_samples(positions, spacing, closed)
    rp, rpp = curve_derivatives(r, h, closed)
    t = _tangents(rp, r, closed)
    speed = np.linalg.norm(rp, axis=-1)
    curv = rpp - np.sum(rpp * t, axis=-1)[:, None] * t
    kappa = np.linalg.norm(curv, axis=-1) / speed**2
    if normal is None:
        n0 = curv[0] if kappa[0] > KAPPA_MIN else np.eye(3)[int(np.argmin(np.abs(t[0])))]
    else:
        n0 = np.asarray(normal, float)
        if n0.shape != (3,) or not np.all(np.isfinite(n0)):
            raise ValueError(f"normal must be 3 finite numbers, got {normal!r}")
    n0 = n0 - np.dot(n0, t[0]) * t[0]
    if not np.linalg.norm(n0) > 1e-12:
        raise ValueError("normal must not be parallel to the tangent at node 0")
    n0 /= np.linalg.norm(n0)
    P = transport_rotation(t[:-1], t[1:])
    frames = np.empty((r.shape[0], 3, 3))
    e2 = n0
    frames[0] = np.stack([t[0], e2, np.cross(t[0], e2)], axis=-1)
    for i in range(1, r.shape[0]):
        e2 = P[i - 1] @ e2
        e2 = e2 - np.dot(e2, t[i]) * t[i]
        e2 /= np.linalg.norm(e2)
        frames[i] = np.stack([t[i], e2, np.cross(t[i], e2)], axis=-1)
    info: dict[str, Any] = {}
    if closed:
        back = transport_rotation(t[-1], t[0]) @ frames[-1][:, 1]
        ref = frames[0]
        alpha = float(np.arctan2(np.dot(back, ref[:, 2]), np.dot(back, ref[:, 1])))
        info["closure_angle"] = alpha
        if spread_closure and alpha != 0.0:
            phi = -alpha * np.arange(r.shape[0]) / r.shape[0]
            c, s = np.cos(phi), np.sin(phi)
            e2, e3 = frames[:, :, 1].copy(), frames[:, :, 2].copy()
            frames[:, :, 1] = c[:, None] * e2 + s[:, None] * e3
            frames[:, :, 2] = -s[:, None] * e2 + c[:, None] * e3
            info["twist"] = -alpha / (r.shape[0] * h)
    return AdaptedFrames(r, frames, "bishop", h, closed, kappa, info)


def relative_angle(a: AdaptedFrames | np.ndarray, b: AdaptedFrames | np.ndarray) -> np.ndarray:
    """The angle φ_i ∈ (−π, π] of the rotation about the common tangent e₁ that takes frame
    ``a`` to frame ``b`` at each node (E_b = E_a·Rot_{e₁}(φ), right-handed).

    Parameters
    ----------
    a, b : AdaptedFrames or ndarray ``[n, 3, 3]``
        Frames sharing e₁.

    Returns
    -------
    ndarray ``[n]``
    """
    Ea = a.frames if isinstance(a, AdaptedFrames) else np.asarray(a, float)
    Eb = b.frames if isinstance(b, AdaptedFrames) else np.asarray(b, float)
    if Ea.shape != Eb.shape or Ea.shape[-2:] != (3, 3):
        raise ValueError(f"frames must have equal shapes (n, 3, 3), got {Ea.shape} and {Eb.shape}")
    c = np.sum(Eb[..., 1] * Ea[..., 1], axis=-1)
    s = np.sum(Eb[..., 1] * Ea[..., 2], axis=-1)
    return np.arctan2(s, c)


# ---------------------------------------------------------------------------- gauges about given tangents
def _check_gauge(gauge: str) -> str:
    if gauge not in GAUGES:
        raise ValueError(f"gauge must be one of {', '.join(map(repr, GAUGES))}, got {gauge!r}")
    return gauge


def _transported(tangents: np.ndarray, e2_0: np.ndarray) -> np.ndarray:
    """Frames ``[n, 3, 3]`` whose e₁ are the unit ``tangents`` ``[n, 3]`` and whose e₂ is ``e2_0``
    at node 0, carried from node to node by the minimal rotations between consecutive tangents
    (the discrete parallel transport: π₁ = 0 on every edge)."""
    P = transport_rotation(tangents[:-1], tangents[1:])
    frames = np.empty((tangents.shape[0], 3, 3))
    e2 = e2_0
    for i in range(tangents.shape[0]):
        if i:
            e2 = P[i - 1] @ e2
        e2 = e2 - np.dot(e2, tangents[i]) * tangents[i]
        e2 /= np.linalg.norm(e2)
        frames[i] = np.stack([tangents[i], e2, np.cross(tangents[i], e2)], axis=-1)
    return frames


def _frenet_refused(kappa: np.ndarray, kmin: float, s: np.ndarray, where: str | None) -> None:
    """``ValueError`` naming the first node where κ ≤ ``kmin`` (its arclength, how many): for
    :func:`frenet_frames` (``where`` None) or the medium's ``gauge = "frenet"`` (``where`` says
    what was being adapted)."""
    bad = np.flatnonzero(~(kappa > kmin))
    if bad.size:
        i = int(bad[0])
        head, advice = (("", "the Bishop gauge (bishop_frames)") if where is None else
                        ("gauge 'frenet': ", "gauge = 'bishop'"))
        context = "" if where is None else f" ({where})"
        raise ValueError(
            f"{head}the Frenet–Serret frame is undefined where the curvature vanishes{context}: κ = {kappa[i]:.3g} ≤ "
            f"kappa_min = {kmin:.3g} at node {i} (arclength s = {s[i]:.6g}); {bad.size} node(s) affected. Use "
            f"{advice}, defined on every regular curve")


def adapt_frames(positions: Any, frames: Any, gauge: str, spacing: float = 1.0, closed: bool = False,
                 kappa_min: float | None = None) -> np.ndarray:
    """Turn adapted frames about their own tangents into a gauge (paper §III.E: the SO(2) gauge).

    Parameters
    ----------
    positions : array_like ``[n, 3]``
        The centreline samples at u_i = i·h.
    frames : array_like ``[n, 3, 3]``
        Directors as columns; e₁ (the tangent) is kept, (e₂, e₃) are turned about it.
    gauge : str
        ``"material"`` (the frames unchanged), ``"bishop"`` (e₂ of node 0 parallel transported
        along the tangents; on a closed curve the closure angle spread as a constant twist, as
        in :func:`bishop_frames`) or ``"frenet"`` (e₂ the principal normal of the sampled
        curve, second-order differences projected normal to e₁).
    spacing : float
        h > 0.
    closed : bool
        A closed curve (periodic differences and closure).
    kappa_min : float, optional
        ``"frenet"``: smallest curvature accepted (default 1e-8/ℓ, ℓ the polygon length).

    Returns
    -------
    ndarray ``[n, 3, 3]``

    Raises
    ------
    ValueError
        An unknown gauge; ``"frenet"`` where κ ≤ ``kappa_min``, naming the first such node and
        its arclength.
    """
    _check_gauge(gauge)
    E = np.array(frames, dtype=float)
    if gauge == "material":
        return E
    r, h = _check_samples(positions, spacing, closed)
    if E.shape != (r.shape[0], 3, 3):
        raise ValueError(f"frames must have shape ({r.shape[0]}, 3, 3), got {E.shape}")
    t = E[:, :, 0] / np.linalg.norm(E[:, :, 0], axis=-1)[:, None]
    if gauge == "bishop":
        out = _transported(t, E[:, :, 1][0])
        if closed:
            back = transport_rotation(t[-1], t[0]) @ out[-1][:, 1]
            alpha = float(np.arctan2(np.dot(back, out[0][:, 2]), np.dot(back, out[0][:, 1])))
            phi = -alpha * np.arange(r.shape[0]) / r.shape[0]
            c, s = np.cos(phi), np.sin(phi)
            e2, e3 = out[:, :, 1].copy(), out[:, :, 2].copy()
            out[:, :, 1] = c[:, None] * e2 + s[:, None] * e3
            out[:, :, 2] = -s[:, None] * e2 + c[:, None] * e3
        return out
    rp, rpp = curve_derivatives(r, h, closed)
    speed2 = np.sum(rp * rp, axis=-1)
    normal = rpp - np.sum(rpp * t, axis=-1)[:, None] * t
    kappa = np.linalg.norm(normal, axis=-1) / speed2
    s = _arclength(r, closed)
    ell = s[-1] + (np.linalg.norm(r[0] - r[-1]) if closed else 0.0)
    kmin = KAPPA_MIN / ell if kappa_min is None else float(kappa_min)
    _frenet_refused(kappa, kmin, s, "initial centreline")
    n2 = normal / np.linalg.norm(normal, axis=-1)[:, None]
    return np.stack([t, n2, np.cross(t, n2)], axis=-1)


def twist_angle(frames: Any, strains: Any, gauge: str, spacing: float = 1.0, kappa_min: float | None = None,
                length: float | None = None) -> np.ndarray:
    """The angle φ_i of the material frame relative to the gauge frame at each node,
    E_material = E_gauge·Rot_{e₁}(φ) (right-handed about the tangent d₁; paper §III.E).

    Parameters
    ----------
    frames : array_like ``[n, 3, 3]``
        The material directors (d₁, d₂, d₃) as columns, d₁ the tangent.
    strains : array_like ``[n, 6]``
        Nodal strains (θ; π) (the lattice's means of the edge strains).
    gauge : str
        ``"bishop"``: the gauge frame is the material frame of node 0 parallel transported along
        the material tangents (minimal rotations between consecutive d₁), so φ(0) = 0 and
        φ′ = π₁ — φ is the accumulated twist ∫π₁ ds, unwrapped along the nodes.
        ``"frenet"``: the Frenet–Serret frame of the material tangents, whose normal is
        e₂ = (π₃d₂ − π₂d₃)/κ (∂_s d₁ = π₃d₂ − π₂d₃, §VII.A), so φ = atan2(π₂, π₃) ∈ (−π, π].
    spacing : float
        The node spacing h (``"frenet"``: arclengths in the error message).
    kappa_min : float, optional
        ``"frenet"``: the smallest curvature accepted (default 1e-8/``length``).
    length : float, optional
        The filament's length (default (n − 1)·h).

    Returns
    -------
    ndarray ``[n]``

    Raises
    ------
    ValueError
        ``"frenet"`` where κ = √(π₂² + π₃²) ≤ ``kappa_min``, naming the first such node.
    """
    _check_gauge(gauge)
    E = np.asarray(frames, dtype=float)
    X = np.asarray(strains, dtype=float).reshape(E.shape[0], -1)
    if gauge == "material":
        return np.zeros(E.shape[0])
    if gauge == "bishop":
        t = E[:, :, 0] / np.linalg.norm(E[:, :, 0], axis=-1)[:, None]
        return np.unwrap(relative_angle(_transported(t, E[0][:, 1]), E))
    kappa = np.hypot(X[:, 4], X[:, 5])
    ell = (E.shape[0] - 1) * spacing if length is None else float(length)
    kmin = KAPPA_MIN / ell if kappa_min is None else float(kappa_min)
    _frenet_refused(kappa, kmin, spacing * np.arange(E.shape[0]), "twist_angle output")
    return np.arctan2(X[:, 4], X[:, 5])
