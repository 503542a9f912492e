"""Rigid motions left free by a static problem's supports (``cartan.solve_static``).

A rigid motion of a Cartan medium is the group's left action, ``Φ_i → exp(εξ) Φ_i`` with one
ξ ∈ 𝔤 for every node: it leaves every left-invariant strain ``X = Φ⁻¹∂Φ`` and every lattice
edge ``G_e = Φ_i⁻¹Φ_j`` unchanged (paper §II–III), so the internal forces do not see it.  In the
statics' drift coordinates ``Φ_i ← Φ_i exp(η_i)`` it is the drift field

    η_i(ξ) = Ad_{Φ_i⁻¹} ξ,

one vector ``η(ξ)`` over all nodes per basis element of 𝔤.  A rigid motion is *unsupported*
when nothing in the problem resists it:

1. the supports do not block it: the components the lattice holds (clamped and driven ends,
   :class:`~cartan.problem.Held` components, :class:`~cartan.problem.Symmetry` faces) vanish
   on η(ξ), and so do the bordered rows of the Newton matrix (pins, strain constraints, held
   functionals) applied to it; gauge components (:meth:`~cartan.medium.Medium.gauge_mask`) are
   left out, they are no motion;
2. the Jacobian does not resist it: its internal part along η vanishes against the magnitudes
   it cancels (``‖K η‖ ≤ RIGID_STIFFNESS_TOL · ‖|K| |η|‖``; a non-trivial holonomy of a periodic
   axis resists the rigid motions that do not commute with it), and so does the loads' part
   against its own size row by row (``‖S⁻¹K_L η‖ ≤ RIGID_LOAD_TOL · ‖S η‖``, ``s_i² = Σ_j
   |K_L,ij|``): a load that stiffens the motion — a foundation, a tether, a penalty support
   however soft against the medium, a volume pressure, a dead load's moment arm — resists it.

Both tests are exact in kind: the free directions are the null space of a small matrix
(``rows × dim 𝔤``) and of ``dim 𝔤`` products with K.  Along a free direction the Newton
matrix is singular in exact arithmetic (its LU seldom finds the zero pivot, so the solve would
return an equilibrium plus an arbitrary rigid motion); :func:`cartan.solve_static` therefore
raises a ``ValueError`` when the external loads have power along a free direction (no
equilibrium exists: an unbalanced resultant or moment) and otherwise warns once with
:class:`UnsupportedRigidMotion`, naming the directions; by default it then holds each by a bordered
row, its mean over the nodes at zero (:class:`RigidMotionGauge`), so the result is defined.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constraints import HeldFunctional

__all__ = ["RigidMotionGauge", "RigidMotions", "UnsupportedRigidMotion", "describe_motion", "rigid_drifts",
           "rigid_gauges", "unsupported_rigid_motions"]

#: σ below which a unit drift field of rigid motion is not blocked by the held components and
#: the bordered rows (each row normalised): a held component of one node among N has σ ≳ 1/√N,
#: an unblocked direction σ at the round-off of the rows (≲ 1e-14)
RIGID_BLOCK_TOL = 1e-9
#: ‖K η‖/‖|K| |η|‖ below which the internal part of the Jacobian (or a medium's analytic Jacobian)
#: does not resist a rigid motion η: a rigid motion gives its round-off and truncation (measured
#: ≤ 1e-11 by central differences with fd_step = 1e-6: rods, rings, shells, a planar toy rod); a
#: holonomy that does not commute with the motion O(1)
RIGID_STIFFNESS_TOL = 1e-9
#: ‖K_L η‖/‖|K_L| |η|‖ below which the loads' own Jacobian K_L (supports included) does not resist
#: a rigid motion: a load that stiffens it gives O(1) (a dead force's moment arm, a penalty spring
#: however soft against the medium), one that does not gives the round-off of its central
#: differences (ε/fd_step ≈ 1e-10)
RIGID_LOAD_TOL = 1e-6
#: |F·η| / (‖F‖‖η‖) above which the external loads have power along a free rigid motion
RIGID_POWER_TOL = 1e-8


class UnsupportedRigidMotion(RuntimeWarning):
    """The supports of a static problem leave a rigid motion free (:func:`cartan.solve_static`):
    the equilibrium is determined up to that motion only.  Hold it with a pin or a
    :class:`~cartan.problem.Held` component (``pins={node: components}``, ``pins="rigid"`` for a
    free body)."""


@dataclass
class RigidMotions:
    """The rigid motions a problem's supports and Jacobian leave free.

    Attributes
    ----------
    directions : array ``(k, r)``
        The free directions ξ ∈ 𝔤 (spatial, the left action ``exp(εξ)Φ``) in the group's basis,
        one per row (:func:`describe_motion`'s readable basis of their span), each of unit drift
        ``‖η(ξ)‖ = 1`` on the live components.
    drifts : array ``(nnode, r, k)``
        Their drift fields η(ξ), each of unit norm.
    names : list of str
        Each direction in words (:func:`describe_motion`).
    power : array ``(k,)``
        The external loads' power ``F_ext·η`` along each direction.
    power_scale : float
        ``‖F_ext‖ max_k ‖η_k‖`` on the unknowns, the bound of ``|F_ext·η|``.
    stiffness : array
        ``‖K η‖/‖|K| |η|‖`` along the singular directions of the rigid motions the supports do not
        block, largest first (free below :data:`RIGID_STIFFNESS_TOL`; a diagnostic).
    """

    directions: np.ndarray
    drifts: np.ndarray
    names: list[str] = field(default_factory=list)
    power: np.ndarray = field(default_factory=lambda: np.zeros(0))
    power_scale: float = 0.0
    stiffness: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def count(self) -> int:
        return int(self.directions.shape[0])

    @property
    def loaded(self) -> bool:
        """Whether the external loads have power along a free direction (no equilibrium)."""
        return bool(self.count) and float(np.max(np.abs(self.power))) > RIGID_POWER_TOL * max(self.power_scale, 1e-300)

    def loaded_direction(self) -> np.ndarray:
        """The free direction along which the loads' power is largest ``(r,)``: ``Σ_k P_k ξ_k``."""
        xi = self.power @ self.directions
        return xi / max(float(np.linalg.norm(xi)), 1e-300)


def rigid_drifts(group: Any, Phi: np.ndarray) -> np.ndarray:
    """The drift fields ``η_i = Ad_{Φ_i⁻¹} ξ`` of the basis elements ξ = e_j of 𝔤.

    Parameters
    ----------
    group : Group
    Phi : array ``(nnode, m, m)``
        The nodes' frames.

    Returns
    -------
    array ``(nnode, r, r)``
        ``[i, :, j]`` = η_i(e_j), body components: ``Φ_i exp(ε η_i) = exp(ε e_j) Φ_i``.
    """
    return np.asarray(group.Ad(group.inverse(Phi)), dtype=float)


def _rref(B: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """The reduced row echelon form of the rows of ``B`` ``(k, n)`` (same row space, k rows)."""
    A = np.array(B, dtype=float)
    k, n = A.shape
    row = 0
    for col in range(n):
        if row >= k:
            break
        p = row + int(np.argmax(np.abs(A[row:, col])))
        if abs(A[p, col]) <= tol:
            continue
        A[[row, p]] = A[[p, row]]
        A[row] /= A[row, col]
        for i in range(k):
            if i != row:
                A[i] -= A[i, col] * A[row]
        row += 1
    return A


def _fmt(v: np.ndarray) -> str:
    v = np.where(np.abs(v) < 5e-7, 0.0, v)
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def describe_motion(group: Any, xi: np.ndarray) -> str:
    """A rigid motion ξ ∈ 𝔤 (spatial) in words.

    On an affine group of the plane or of space (SE(2), SE(3)): ``"translation along (1, 0, 0)"``,
    ``"rotation about (0, 0, 1) through (x, y, z)"`` (through the point of the axis nearest the
    origin; a screw when ξ also translates along the axis), ``"rotation about the point (x, y)"``
    in the plane; on SO(3) ``"rotation about (0, 1, 0)"``; otherwise the Lie-algebra vector in the
    group's basis.

    Parameters
    ----------
    group : Group
    xi : array ``(r,)``

    Returns
    -------
    str
    """
    xi = np.asarray(xi, dtype=float)
    scale = float(np.max(np.abs(xi)))
    if not scale > 0.0:
        return "no motion"
    A = np.asarray(group.hat(xi), dtype=float)
    if not getattr(group, "affine", False) and A.shape == (3, 3) and np.allclose(A, -A.T):
        w = np.array([A[2, 1], A[0, 2], A[1, 0]])  # so(3): a rotation of space about w
        return f"rotation about {_fmt(w / np.linalg.norm(w))}"
    if not getattr(group, "affine", False) or group.matrix_size not in (3, 4):
        return f"{group.name} Lie-algebra direction ξ = {_fmt(xi / scale)}"
    v, W = A[1:, 0], A[1:, 1:]  # the spatial velocity of a point x: W x + v
    if float(np.max(np.abs(W))) <= 1e-9 * scale:
        return f"translation along {_fmt(v / np.linalg.norm(v))}"
    if group.matrix_size == 3:
        w = W[1, 0]
        p = np.array([-v[1], v[0]]) / w  # W p + v = 0
        return f"rotation about the point {_fmt(p)}"
    w = np.array([W[2, 1], W[0, 2], W[1, 0]])
    w2 = float(w @ w)
    p = np.cross(w, v) / w2  # the point of the axis nearest the origin
    pitch = float(w @ v) / w2
    axis = w / np.sqrt(w2)
    text = f"rotation about {_fmt(axis)} through {_fmt(p)}"
    if abs(pitch) > 1e-9 * max(1.0, float(np.linalg.norm(p))):
        text = f"screw about {_fmt(axis)} through {_fmt(p)} with pitch {pitch:.6g}"
    return text


def _nice_basis(group: Any, xi: np.ndarray) -> np.ndarray:
    """A readable basis ``(k, r)`` of the span of the rows of ``xi``: on SE(2)/SE(3) the
    translations first (reduced echelon form of their directions), then rotations about the
    coordinate-like axes; otherwise the reduced echelon form."""
    k, r = xi.shape
    if not k:
        return xi
    xi = xi / np.max(np.abs(xi), axis=1, keepdims=True)
    if not getattr(group, "affine", False) or group.matrix_size not in (3, 4):
        return _rref(xi)
    nt = group.matrix_size - 1  # the translation components come first in the affine basis
    # the coefficients c with c·xi[:, nt:] = 0: left null space of the rotation block
    u, s2, _ = np.linalg.svd(xi[:, nt:], full_matrices=True)
    rank2 = int(np.sum(s2 > 1e-9 * max(float(s2[0]) if s2.size else 0.0, 1e-300)))
    trans = u[:, rank2:].T @ xi
    trans = _rref(trans) if trans.size else trans
    rots = u[:, :rank2].T @ xi
    if rots.size:
        if trans.size:  # remove the translations in the span from the rotations' velocities
            tb = np.linalg.qr(trans[:, :nt].T)[0]
            rots[:, :nt] -= (rots[:, :nt] @ tb) @ tb.T
        order = list(range(nt, r)) + list(range(nt))
        rots = _rref(rots[:, order])[:, np.argsort(order)]
    out = np.vstack([m for m in (trans, rots) if m.size])
    return out / np.max(np.abs(out), axis=1, keepdims=True)


def _right_svd(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The singular values (padded with zeros to k) and the right singular vectors ``(k, k)`` of
    ``A`` ``(n, k)``, without the ``n × n`` left factor (n may be every node's component)."""
    n, k = A.shape
    if n < k:
        A = np.vstack([A, np.zeros((k - n, k))])
    _, sv, vh = np.linalg.svd(A, full_matrices=False)
    return sv, vh


def _unresisted(X: Any, low: tuple[np.ndarray, np.ndarray] | None, H: np.ndarray, tol: float,
                per_row: bool) -> tuple[np.ndarray, np.ndarray]:
    """The combinations of the drifts ``H`` ``(n, k)`` that ``X + U Vᵀ`` ``(n, n)`` does not resist.

    Without ``per_row``: ``‖X H y‖ ≤ tol · max_j ‖|X| |H e_j|‖`` for unit y (H orthonormal), the
    magnitudes whose cancellation ``X H`` is (a medium's internal forces, which a rigid motion
    leaves unchanged: their Jacobian's round-off, or a holonomy's O(1)).  With ``per_row``
    (the loads): scaled per row and column by ``s_i = √(Σ_j |X_ij|)`` (the rank-k part
    included), so that a stiffness far below the largest one still counts against its own size
    (a soft spring on one translation beside stiff ones on the others): ``‖S⁻¹ X H y‖ ≤ tol
    ‖S H y‖`` on the rows and columns a load acts on (a generalised singular value problem, by
    the SVD of ``S H`` there); a combination that moves none of them is unresisted.

    Returns
    -------
    Y : array ``(k, k')``
        The coefficients of the unresisted combinations, orthonormal.
    ratio : array ``(k,)``
        The (generalised) singular values over their bound, largest first (unresisted below 1).
    """
    k = H.shape[1]
    absX = abs(X)
    XH = X @ H
    if low is not None:
        XH = XH + low[0] @ (low[1].T @ H)
    if per_row:
        size = np.maximum(np.asarray(absX.sum(axis=1)).ravel(), np.asarray(absX.sum(axis=0)).ravel())
        if low is not None:
            aU, aV = np.abs(low[0]), np.abs(low[1])
            size = size + np.maximum(aU @ aV.sum(axis=0), aV @ aU.sum(axis=0))
        acted = np.flatnonzero(size > 0.0)  # the rows and columns a load acts on
        if not acted.size:
            return np.eye(k), np.zeros(k)
        sc = np.sqrt(size[acted])
        sig, Wt = _right_svd(H[acted] * sc[:, None])
        moved = int(np.sum(sig > 1e-12 * max(float(sig[0]) if sig.size else 0.0, 1e-300)))
        untouched = Wt[moved:].T  # combinations that move no loaded component: unresisted
        if not moved:
            return np.eye(k), np.zeros(k)
        Rinv = Wt[:moved].T / sig[:moved]  # [k, moved]: S H Rinv orthonormal on the acted rows
        M, bound = (XH[acted] / sc[:, None]) @ Rinv, tol
        sv, vh = _right_svd(M)
        ratio = np.concatenate([sv, np.zeros(moved - sv.size)]) / bound
        Y = np.hstack([untouched, Rinv @ vh[int(np.sum(ratio > 1.0)):].T])
        Y = np.linalg.qr(Y)[0] if Y.shape[1] else Y
        return Y, np.concatenate([ratio, np.zeros(k - moved)])
    mag = absX @ np.abs(H)
    if low is not None:
        mag = mag + np.abs(low[0]) @ (np.abs(low[1]).T @ np.abs(H))
    bound = tol * max(float(np.max(np.linalg.norm(mag, axis=0), initial=0.0)), 1e-300)
    sv, vh = _right_svd(XH)
    ratio = np.concatenate([sv, np.zeros(k - sv.size)]) / bound
    return vh[int(np.sum(ratio > 1.0)):].T, ratio


def unsupported_rigid_motions(eq: Any, J: Any, low: tuple[np.ndarray, np.ndarray] | None,
                              external: np.ndarray, loads: Callable[[], Any] | None = None) -> RigidMotions:
    """The rigid motions a static problem leaves free (module docstring).

    Parameters
    ----------
    eq : cartan.statics._Equilibrium
        The problem on its lattice: the unknowns, the held components, the bordered rows.
    J : sparse matrix ``(m, m)``
        The Newton matrix at the start (:meth:`cartan.statics._Equilibrium.jacobian`).
    low : (U, V) arrays ``(m, k)`` or None
        The loads' rank-k part of the Jacobian (``J + U Vᵀ``).
    external : array ``(nunk,)``
        The external nodal forces on the unknowns (the λ-scaled loads).
    loads : callable, optional
        ``loads()``: the part of J's stiffness block that the loads make (supports included),
        sparse ``(nunk, nunk)``, or None when J does not separate it (a medium's analytic
        Jacobian).  Called only when some rigid motion is not blocked by the supports.  With it
        the test 2. is made apart on the internal part (against its own magnitudes, to
        :data:`RIGID_STIFFNESS_TOL`) and on the loads' part with the rank-k part (to
        :data:`RIGID_LOAD_TOL`): a support far softer than the medium (a spring holding an
        otherwise free translation at 1e-8 of the membrane stiffness) still resists.

    Returns
    -------
    RigidMotions
    """
    import scipy.sparse as sp

    g = eq.g
    r, nnode, nunk = eq.r_dim, eq.nnode, eq.nunk
    msize = g.matrix_size
    Phi = eq.sch.frames(eq.state0).reshape(nnode, msize, msize)
    eta = rigid_drifts(g, Phi)  # [nnode, r(component), r(basis)]
    live = np.broadcast_to(np.asarray(eq.sch.live, dtype=bool), (nnode, r))
    eta = eta * live[..., None]  # gauge components are no motion
    # an orthonormal basis of the drift fields (the rigid motions that move a live component)
    U, S, Vt = np.linalg.svd(eta.reshape(nnode * r, r), full_matrices=False)
    rank = int(np.sum(S > 1e-12 * max(float(S[0]), 1e-300)))
    empty = RigidMotions(np.zeros((0, r)), np.zeros((nnode, r, 0)))
    if rank == 0 or nunk == 0:
        return empty
    U = U[:, :rank]
    to_xi = Vt[:rank].T / S[:rank]  # [r, rank]: ξ of the unit drift fields U
    unknown = eq.unknown_flat.ravel()
    held = (~eq.unknown_flat & live).ravel()
    J = sp.csr_matrix(J)
    v = np.zeros((eq.m, rank))
    v[:nunk] = U[unknown]
    Jv = J @ v
    if low is not None:
        Jv = Jv + low[0] @ (low[1].T @ v)
    # 1. the supports: held components and the bordered rows (pins, strain constraints, held functionals)
    blocks = [U[held]]
    if eq.nmult:
        rows = J[nunk:, :nunk]
        norms = np.sqrt(np.asarray(rows.multiply(rows).sum(axis=1)).ravel())
        ok = norms > 0.0
        blocks.append(Jv[nunk:][ok] / norms[ok, None])
    A = np.vstack(blocks)
    if A.shape[0]:
        s, vh = _right_svd(A)
        free = vh[int(np.sum(s > RIGID_BLOCK_TOL)):].T  # [rank, k0]
    else:
        free = np.eye(rank)
    if not free.shape[1]:
        return empty
    # 2. the Jacobian: K η on the unknowns, the internal part and the loads' part apart
    K = J[:nunk, :nunk]
    H = v[:nunk] @ free  # the drifts on the unknowns [nunk, k0], orthonormal over all nodes
    KL = loads() if loads is not None else None
    if KL is None:  # the whole Jacobian (a medium's analytic one: the loads inside)
        parts = [(K, low, RIGID_STIFFNESS_TOL, False)]
    else:
        KL = sp.csr_matrix(KL)
        parts = [(K - KL, None, RIGID_STIFFNESS_TOL, False), (KL, low, RIGID_LOAD_TOL, True)]
    soft = np.eye(H.shape[1])
    ratios = []
    for X, lowX, tol, per_row in parts:
        Y, ratio = _unresisted(X, None if lowX is None else (lowX[0][:nunk], lowX[1][:nunk]), H @ soft, tol,
                               per_row)
        soft = soft @ Y
        ratios.append(ratio)
        if not soft.shape[1]:
            break
    ratio = np.concatenate(ratios)
    if not soft.shape[1]:
        empty.stiffness = ratio
        return empty
    coeff = free @ soft  # [rank, k]: the free directions in the basis U
    xi = (to_xi @ coeff).T  # [k, r]
    xi = _nice_basis(g, xi)
    # the readable basis's drift fields, each of unit norm
    drift = np.einsum("nij,kj->nik", eta, xi).reshape(nnode * r, -1)
    names = [describe_motion(g, x) for x in xi]
    directions = xi / np.linalg.norm(drift, axis=0)[:, None]
    drifts = drift / np.linalg.norm(drift, axis=0)
    d_unk = drifts[unknown]
    power = external @ d_unk
    # the bound ‖F‖‖η‖ of F·η (a drift that vanishes where the loads act makes Σ|F_i||η_i| no scale)
    power_scale = float(np.linalg.norm(external)) * float(np.max(np.linalg.norm(d_unk, axis=0), initial=0.0))
    return RigidMotions(directions, drifts.reshape(nnode, r, -1), names, power, power_scale, ratio)


class RigidMotionGauge(HeldFunctional):
    """The mean of a free rigid motion held at zero: one bordered row of the statics' Newton
    matrix (:class:`~cartan.constraints.HeldFunctional`, ``solve_static(rigid_gauge=True)``).

    ``C(Φ) = Σ_i ⟨η_i, log(Φ⁰_i⁻¹ Φ_i)⟩`` with η the unit drift field of the free direction at
    the start Φ⁰ (:class:`RigidMotions`), held at C₀ = 0: along the rigid motion ``exp(εξ)Φ⁰``
    ``C = ε + O(ε²)``, so the row removes the motion from the Newton matrix's null space, and its
    multiplier is the loads' power along it (zero at a balanced equilibrium).  The gradient is
    exact: along the drift ``Φ_i ← Φ_i exp(δ_i)``, ``∂ log(Φ⁰_i⁻¹Φ_i)/∂δ_i = dexp⁻¹(−ζ_i)``,
    ``ζ_i = log(Φ⁰_i⁻¹Φ_i)``.

    Parameters
    ----------
    group : Group
    Phi0 : array ``(*shape, m, m)``
        The frames at the start.
    drift : array ``(*shape, r)``
        η, zero on gauge components.
    scale : float
        The row's unit s (the solve holds ``|C| ≤ tol·s``).
    name : str
    """

    def __init__(self, group: Any, Phi0: np.ndarray, drift: np.ndarray, scale: float, name: str):
        super().__init__(target=0.0, scale=scale, name=name)
        self.group = group
        self.Phi0_inv = np.asarray(group.inverse(np.asarray(Phi0, dtype=float)))
        self.drift = np.asarray(drift, dtype=float)

    def _zeta(self, scheme: Any, state: Any) -> np.ndarray:
        return np.asarray(self.group.log(self.group.compose(self.Phi0_inv, scheme.frames(state))))

    def value(self, scheme: Any, state: Any) -> float:
        return float(np.sum(self.drift * self._zeta(scheme, state)))

    def round_off_scale(self, scheme: Any, state: Any) -> float:
        """``Σ_i |η_i|₁ max|Φ⁰_i⁻¹| max|Φ_i|``: the size of the terms of C, whose round-off the
        statics' residual floor counts (C itself is 0 at the solution)."""
        Phi = np.asarray(scheme.frames(state))
        r = self.drift.shape[-1]
        size = (np.max(np.abs(self.Phi0_inv), axis=(-2, -1)) * np.max(np.abs(Phi), axis=(-2, -1)))
        return float(np.sum(np.abs(self.drift).reshape(-1, r).sum(axis=1) * size.ravel()))

    def gradient(self, scheme: Any, state: Any) -> np.ndarray:
        """``dexp⁻¹(−ζ_i)ᵀ η_i`` ``[*shape, r]``."""
        T = np.asarray(self.group.dexp_inv(-self._zeta(scheme, state)))  # [*shape, r, r]
        return np.einsum("...ji,...j->...i", T, self.drift)


def rigid_gauges(eq: Any, rigid: RigidMotions) -> list[RigidMotionGauge]:
    """One :class:`RigidMotionGauge` per free direction of ``rigid`` on the problem of ``eq``
    (the rows' unit: the largest grid length, at least 1, as the pins')."""
    msize = eq.g.matrix_size
    Phi0 = eq.sch.frames(eq.state0).reshape(*eq.shape, msize, msize)
    return [RigidMotionGauge(eq.g, Phi0, rigid.drifts[:, :, k].reshape(*eq.shape, eq.r_dim), eq.length,
                             f"rigid_motion_{k}") for k in range(rigid.count)]
