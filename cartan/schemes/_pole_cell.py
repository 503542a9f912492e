"""The pole cell of a glued chart (``Lattice(problem, pole="cap")``; docs/media/cosserat-surface.md,
"The closed sphere").

Chord-length strains
    Every edge's strain is ``X″ = (θ·|p|/|v|, π)`` with ``hX = log G = (v, ω)`` (v = hθ, ω = hπ)
    and p the translation of G (the chord, tail frame): the logarithm's tangent direction with
    the chord's length, so that a membrane tension puts no moment on the edge's ends.  The rest
    strains are those of the reference, alike.  With ``V(x″)`` and ``Q = ∂V/∂x″`` (x″ = hX″,
    s = |p|/|v|), ``∂V/∂v = s q − |p|(q·v)/|v|³ v`` goes back to the nodes through dexp⁻¹ as a
    logarithm's stress does, and ``f = ∂V/∂p = (q·v)/(|v||p|) p`` acts as (f, p × f = 0) on the
    tail and (−R_Gᵀf, 0) on the head (R_G the rotation of G).
The cap
    The disc θ < θ₀ between a pole row and its pole, of chart radius h_v/2 in a Cartesian chart of
    the pole (the glued axis' unit), replaces the 2N corners that use a glued edge.  The N stored
    glued edges of a pole are its diameters, directions n_k = (cos φ_k, sin φ_k), φ_k = 2πk/N;
    each gives (X_k = x″_k/h_v) a_k = θ_k·θ_k, b_k = θ_k·(π_k2, −π_k1, 0), γ_k = θ_k3, fitted by
    least squares to the metric ``C = (1/N) Σ a_k(4n_kn_kᵀ − I)``, the curvature K likewise from
    b_k and the shear ``g = (2/N) Σ γ_k n_k``.  The cap's energy is ``W·U(X_p; X_p⁰)``,
    W = πh_v²/4, U the medium's own density at the pole strain X_p built from (C, K, g):
    θ_α = (L_α, g_α) with ``LLᵀ = C − ggᵀ`` (Cholesky), π_β = (−s_β2, s_β1, 0) with the rows
    s_β of ``S = K L⁻ᵀ`` — so that θ_α·θ_β = C_αβ, θ_α3 = g_α and θ_α·(π_β2, −π_β1, 0) = K_αβ —
    and X_p⁰ built alike from the reference.  Its gradient is exact (reverse mode through the
    Cholesky factor, the fit and the chord strains).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..scatter import scatter_add

#: the lattice's pole treatments of a glued chart (``Lattice(problem, pole=...)``)
POLES = ("corners", "cap")


def chord_strains(G: np.ndarray, group: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x″, ξ, p)`` of SE(3) edge elements ``G [..., 4, 4]``: the chord-length strains
    ``x″ = hX″ [..., 6]`` (module docstring), the logarithms ``ξ = log G [..., 6]`` and the chords
    ``p [..., 3]``."""
    xi = group.log(G)
    p = G[..., 1:, 0]
    s = np.linalg.norm(p, axis=-1) / np.linalg.norm(xi[..., :3], axis=-1)
    x2 = xi.copy()
    x2[..., :3] *= s[..., None]
    return x2, xi, p


def chord_forces(G: np.ndarray, xi: np.ndarray, p: np.ndarray, Qe: np.ndarray,
                 group: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(out, inc)`` ``[E, 6]``: with ``Qe = ∂V/∂x″ [E, 6]`` per edge, the generalised force on
    the tail is ``out`` and on the head ``−inc`` (module docstring; flat edges, G ``[E, 4, 4]``)."""
    v, q = xi[:, :3], Qe[:, :3]
    nv, npn = np.linalg.norm(v, axis=-1), np.linalg.norm(p, axis=-1)
    qv = np.sum(q * v, axis=-1)
    Qlog = Qe.copy()  # ∂V/∂ξ
    Qlog[:, :3] = (npn / nv)[:, None] * q - (npn / nv**3 * qv)[:, None] * v
    f = (qv / (nv * npn))[:, None] * p  # ∂V/∂p, along p: p × f = 0
    out = np.einsum("...ji,...j->...i", group.dexp_inv(xi), Qlog)
    inc = np.einsum("...ji,...j->...i", group.dexp_inv(-xi), Qlog)
    out[:, :3] += f
    inc[:, :3] += np.einsum("kji,kj->ki", G[:, 1:, 1:], f)
    return out, inc


def pole_strain(C: np.ndarray, K: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The pole strain ``X_p [2, 6]`` of a metric C ``[2, 2]``, a curvature K ``[2, 2]`` and a shear
    g ``[2]`` (module docstring)."""
    L = np.linalg.cholesky(C - np.outer(g, g))
    S = K @ np.linalg.inv(L).T
    X = np.zeros((2, 6))
    X[:, :2] = L
    X[:, 2] = g
    X[:, 3] = -S[:, 1]
    X[:, 4] = S[:, 0]
    return X


def pole_strain_vjp(C: np.ndarray, K: np.ndarray, g: np.ndarray,
                    Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(C̄, K̄, ḡ)``: the gradient of ``Q : X_p(C, K, g)`` (Q ``[2, 6]``) with respect to the
    symmetric C and K as (11, 12, 22) ``[3]`` (12 moving both off-diagonal entries) and g ``[2]``."""
    Cp = C - np.outer(g, g)
    L = np.linalg.cholesky(Cp)
    Li = np.linalg.inv(L)
    Lb = Q[:, :2].copy()  # ∂/∂L (lower entries used)
    gb = Q[:, 2].copy()
    Sb = np.stack([Q[:, 4], -Q[:, 3]], axis=-1)  # ∂/∂S
    Kb = Sb @ Li  # S = K M, M = L⁻ᵀ: K̄ = S̄ Mᵀ
    Mb = K.T @ Sb
    Lb -= Li.T @ Mb.T @ Li.T  # M = L⁻ᵀ: dM = −L⁻ᵀdLᵀL⁻ᵀ
    L11, L21, L22 = L[0, 0], L[1, 0], L[1, 1]
    c12 = Cp[0, 1]
    b11, b21, b22 = Lb[0, 0], Lb[1, 0], Lb[1, 1]
    cb22 = b22 / (2.0 * L22)
    b21 = b21 - b22 * L21 / L22
    cb12 = b21 / L11
    b11 = b11 - b21 * c12 / L11**2
    cb11 = b11 / (2.0 * L11)
    gb[0] += -2.0 * g[0] * cb11 - g[1] * cb12
    gb[1] += -g[0] * cb12 - 2.0 * g[1] * cb22
    return (np.array([cb11, cb12, cb22]), np.array([Kb[0, 0], Kb[0, 1] + Kb[1, 0], Kb[1, 1]]), gb)


class PoleCap:
    """The two caps of a lattice's glued axis (module docstring, "The cap"), built once from the
    reference; :meth:`energy_grad` evaluates them at the glued edges' chord-length strains."""

    def __init__(self, lattice: Any):
        grid = lattice.grid
        self.medium = lattice.medium
        #: the glued axis (the caps' edges are its first and last along it)
        self.axis = a = next(k for k in range(grid.d) if grid.is_glued(k))
        N = grid.shape[grid.glued[a]]
        phi = 2.0 * np.pi * np.arange(N) / N
        self.n = n = np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # [N, 2]
        self.P = (4.0 * n[:, :, None] * n[:, None, :] - np.eye(2)) / N  # [N, 2, 2]: C = Σ a_k P_k
        self.hv = float(lattice.h[a])
        self.W = np.pi * self.hv**2 / 4.0
        es = grid.edge_shape(a)
        idx = np.arange(int(np.prod(es))).reshape(es)
        #: the flat glued edges of each pole, in the order of the periodic axis [N] (two poles)
        self.rings = [np.take(idx, [0], axis=a).ravel(), np.take(idx, [es[a] - 1], axis=a).ravel()]
        X0 = lattice.edge_rest_strains(a)[..., a, :].reshape(-1, lattice.group.dim)
        #: the pole rest strains [2, 6] of each pole
        self.X0p = [pole_strain(*self.fit(X0[e])) for e in self.rings]

    def fit(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(C, K, g) fitted to a ring's strains ``X [N, 6]`` (module docstring)."""
        a = np.sum(X[:, :3] ** 2, axis=-1)
        b = X[:, 0] * X[:, 4] - X[:, 1] * X[:, 3]
        C = np.einsum("k,kab->ab", a, self.P)
        K = np.einsum("k,kab->ab", b, self.P)
        g = 2.0 / X.shape[0] * self.n.T @ X[:, 2]
        return C, K, g

    def energy_grad(self, x2: np.ndarray, want: bool = True) -> tuple[float, np.ndarray | None]:
        """The caps' energy ``Σ W·U`` and its gradient ``∂V/∂x″ [E, 6]`` (None unless ``want``)
        for the chord-length strains ``x2 = x″ [E, 6]`` of the glued axis' flat edges."""
        V = 0.0
        grad = np.zeros_like(x2) if want else None
        N = self.n.shape[0]
        for ring, X0p in zip(self.rings, self.X0p, strict=True):
            X = x2[ring] / self.hv
            C, K, g = self.fit(X)
            Xp = pole_strain(C, K, g)
            V += self.W * float(self.medium.potential_at(Xp[None], X0p[None])[0])
            if not want:
                continue
            Q = self.W * np.asarray(self.medium.stress_at(Xp[None], X0p[None]))[0]
            cb, kb, gb = pole_strain_vjp(C, K, g, Q)
            da = cb[0] * self.P[:, 0, 0] + cb[1] * self.P[:, 0, 1] + cb[2] * self.P[:, 1, 1]
            db = kb[0] * self.P[:, 0, 0] + kb[1] * self.P[:, 0, 1] + kb[2] * self.P[:, 1, 1]
            dX = np.zeros_like(X)
            dX[:, :3] = 2.0 * da[:, None] * X[:, :3]
            dX[:, 0] += db * X[:, 4]
            dX[:, 4] += db * X[:, 0]
            dX[:, 1] -= db * X[:, 3]
            dX[:, 3] -= db * X[:, 1]
            dX[:, 2] += 2.0 / N * self.n @ gb
            grad[ring] += dX / self.hv
        return V, grad


def check_pole(lattice: Any, pole: str) -> str:
    """The validated ``pole`` of a lattice (:data:`POLES`): ``"cap"`` needs a coupled d = 2 SE(3)
    lattice with a glued axis and a reference configuration."""
    if pole not in POLES:
        raise ValueError(f"pole must be one of {', '.join(map(repr, POLES))}, got {pole!r}")
    if pole == "cap":
        grid = lattice.grid
        if grid.d != 2 or not any(grid.is_glued(k) for k in range(grid.d)) or not lattice.coupled:
            raise ValueError("pole = 'cap' needs a d = 2 chart with a glued axis (a surface closed over poles) "
                             f"and a medium whose energy couples the axes; got d = {grid.d}, glued = {grid.glued}")
        if getattr(lattice.group, "name", None) != "SE3":
            raise ValueError(f"pole = 'cap' needs the group SE3 (chord-length strains), got {lattice.group.name!r}")
        if lattice.problem.reference is None:
            raise ValueError("pole = 'cap' needs a reference configuration (the rest strains of the caps)")
    return pole


def cap(lattice: Any) -> PoleCap:
    """The lattice's :class:`PoleCap`, built once."""
    held = lattice.__dict__.get("_pole_cap")
    if held is None:
        held = lattice._pole_cap = PoleCap(lattice)
    return held


def corner_strains(lattice: Any, state: Any) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per axis ``(x″, ξ, p)`` of the flat edges (:func:`chord_strains`)."""
    g = lattice.group
    return [chord_strains(state.arrays[lattice._key(a)].reshape(-1, 4, 4), g) for a in range(lattice.grid.d)]


def corner_force(lattice: Any, state: Any) -> np.ndarray:
    """The internal force ``[*shape, 6]`` of a lattice with the caps: the exact gradient of the
    corners' and the caps' energy in the chord-length strains (module docstring)."""
    L, g = lattice, lattice.group
    c, h, d = L.corners(), L.h, L.grid.d
    xs = corner_strains(L, state)
    Xc = np.stack([xs[a][0][c["edge"][:, a]] / h[a] for a in range(d)], axis=1)
    Q = L.medium.stress_at(Xc, c["X0"])
    F = np.zeros((int(np.prod(L.grid.shape)), g.dim))
    caps = cap(L)
    for a, (x2, xi, p) in enumerate(xs):
        Qe = np.zeros_like(x2)
        scatter_add(Qe, c["edge"][:, a], (c["weight"] / h[a])[:, None] * Q[:, a, :])
        if a == caps.axis:
            Qe += caps.energy_grad(x2)[1]
        out, inc = chord_forces(state.arrays[L._key(a)].reshape(-1, 4, 4), xi, p, Qe, g)
        scatter_add(F, c["tail"][a], L.from_ghosts(out, c["ghost_tail"][a], a))
        scatter_add(F, c["head"][a], -L.from_ghosts(inc, c["ghost_head"][a], a))
    return F.reshape(*L.grid.shape, g.dim)
