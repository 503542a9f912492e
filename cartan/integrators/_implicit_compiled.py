"""Compiled stage residual of ``implicit-midpoint`` (``cartan.integrators.implicit``).

One evaluation of the stage residual (paper §V; the discrete Lagrangian of the module
docstring of :mod:`cartan.integrators.implicit`)::

    R(ξ) = dexp⁻¹_ξᵀ μ − Δt B(ξ)ᵀ W_{k+½} − S_k,   μ = m ξ/Δt,   B(ξ) = (I + Ad_{exp(ξ/2)})⁻¹,
    W_{k+½} = W(Φ_k exp(ξ/2), ξ/Δt)

is one numba call: the drift of a copy of the step's configuration to the midpoint
``Φ_k exp(ξ/2)``, the scheme's force there, and the ``r × r`` algebra of every node.  The
drift and the force are the kernels of the compiled step loops of the scheme
(:mod:`cartan.schemes._lattice_compiled` for the lattice, d = 1, 2, 3;
:mod:`cartan.schemes._collocation_compiled` for collocation, d = 1) with the plan those loops
use (:meth:`~cartan.schemes.base.Scheme.compiled_plan`), so the problems that qualify are the ones the compiled
loops run (``docs/performance.md``): SO(2), SE(2), SO(3), SE(3); a quadratic potential;
damping, body-frame uniform forces, constant fields, end loads and clamps.  The loads of such
plans do not depend on time, so the midpoint time ``t_k + Δt/2`` is not needed.

The formulas are those of ``ImplicitMidpoint._residual`` (the numpy reference, which uses
``Scheme.drift``, ``Scheme.force`` and the batched group operations); the two differ by
round-off: the compiled drift and force differ from the numpy ones as the compiled loops do,
``B(ξ)ᵀW`` is solved in closed form on SO(3) and SE(3) (:func:`_nodes`) and by Gaussian
elimination with partial pivoting on SO(2) and SE(2) instead of LAPACK, and the sums run in
another order.  :class:`StageResidual` holds the work arrays (allocated once per scheme and
grid) and the step's configuration, so that no state is copied per evaluation.

Newton's iteration around the residual uses two more compiled pieces: :class:`LUSolve`, the
substitutions of a SuperLU factorisation, and :func:`weighted_norm`, the kinetic-energy norms.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from .._backend import get_backend
from ..groups.so3 import cross3
from ..schemes._collocation_compiled import drift_once as _collocation_drift
from ..schemes._collocation_compiled import force_once as _collocation_force
from ..schemes._lattice_compiled import (
    CHUNK,
    I_D,
    I_ECH,
    I_GID,
    I_MASS,
    _chunk_scratch,
    _cinv,
    _exp_drift_nd,
    _force_once,
    _jinv_T,
    _q_coeffs,
    _rot_coeffs,
    _se3_dexp_inv_T,
)
from ..schemes._lattice_compiled_kernels import GID_SE2, GID_SE3, GID_SO2, GID_SO3, g_Ad, g_dexp_inv, g_exp

__all__ = ["LUSolve", "StageResidual", "stage_residual", "weighted_norm"]

_jit = njit(cache=True, error_model="numpy")
_inline = njit(inline="always", error_model="numpy")


# ---------------------------------------------------------------------------- per-node algebra
@_jit
def _in_domain(gid: int, xi: np.ndarray, radius: float) -> bool:
    """Whether every node's ξ ``[n, r]`` is inside the injectivity radius of exp (the groups'
    ``log_domain_norm``: the rotation angle, ``|ω|`` of SE(3) and SO(3), ``|θ|`` of SE(2), SO(2))."""
    n = xi.shape[0]
    for i in range(n):
        if gid == GID_SE3:
            a = np.sqrt(xi[i, 3] * xi[i, 3] + xi[i, 4] * xi[i, 4] + xi[i, 5] * xi[i, 5])
        elif gid == GID_SE2:
            a = abs(xi[i, 2])
        elif gid == GID_SO2:
            a = abs(xi[i, 0])
        else:
            a = np.sqrt(xi[i, 0] * xi[i, 0] + xi[i, 1] * xi[i, 1] + xi[i, 2] * xi[i, 2])
        if not a < radius:  # also NaN
            return False
    return True


@_jit
def _solve_transposed(A: np.ndarray, w: np.ndarray, out: np.ndarray, M: np.ndarray) -> None:
    """``out = (I + A)⁻ᵀ w`` for one ``r × r`` matrix ``A`` by Gaussian elimination with partial
    pivoting (``M`` ``[r, r + 1]`` work: the augmented matrix)."""
    r = w.shape[0]
    for a in range(r):
        for b in range(r):
            M[a, b] = A[b, a]
        M[a, a] += 1.0
        M[a, r] = w[a]
    for k in range(r):
        p = k
        big = abs(M[k, k])
        for a in range(k + 1, r):
            v = abs(M[a, k])
            if v > big:
                big = v
                p = a
        if p != k:
            for b in range(k, r + 1):
                tmp = M[k, b]
                M[k, b] = M[p, b]
                M[p, b] = tmp
        piv = M[k, k]
        for a in range(k + 1, r):
            f = M[a, k] / piv
            if f != 0.0:
                for b in range(k + 1, r + 1):
                    M[a, b] -= f * M[k, b]
    for a in range(r - 1, -1, -1):
        acc = M[a, r]
        for b in range(a + 1, r):
            acc -= M[a, b] * out[b]
        out[a] = acc / M[a, a]


@_inline
def _half_cayley(p0: float, p1: float, p2: float, w0: float, w1: float, w2: float) -> tuple:
    """``(I + Rᵀ)⁻¹ w = ½(w + κ p × w)`` for ``R = exp(p̂)``, ``κ = tan(θ/2)/θ = B/A`` (θ = |p|,
    ``A = sin θ/θ``, ``B = (1 − cos θ)/θ²``): ``Rᵀ = exp(−p̂)`` is the Cayley transform of
    ``−κp̂``, so ``I + Rᵀ = 2(I + κp̂)⁻¹``.  Here θ = |ω|/2 < π/2 (ξ inside the injectivity
    radius), so A > 0."""
    a, b = _rot_coeffs(p0 * p0 + p1 * p1 + p2 * p2)
    k = b / a
    c = cross3(p0, p1, p2, w0, w1, w2)
    return 0.5 * (w0 + k * c[0]), 0.5 * (w1 + k * c[1]), 0.5 * (w2 + k * c[2])


@_jit
def _nodes(gid: int, mass: np.ndarray, xi: np.ndarray, N: np.ndarray, D: np.ndarray, W: np.ndarray,
           S: np.ndarray, dt: float, mu: np.ndarray, BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray,
           A: np.ndarray, M: np.ndarray) -> None:
    """Per node: ``μ = m N``, ``BW = (I + Ad_D)⁻ᵀ W`` (``D = exp(ξ/2)``), ``Dmu = dexp⁻¹_ξᵀ μ``
    and ``R = Dmu − Δt BW − S``; all ``[n, r]`` but ``D`` ``[n, m, m]``; ``A`` ``[r, r]`` and
    ``M`` ``[r, r + 1]`` work.

    SE(3) and SO(3) in scalar code: with ``D = (t; Q)`` and ``Ad_D = [[Q, t̂Q], [0, Q]]``,
    ``(I + Ad_D)ᵀ`` is block lower triangular, ``BW = (y₁; (I + Qᵀ)⁻¹(W₂ + Qᵀ(t × y₁)))`` with
    ``y₁ = (I + Qᵀ)⁻¹W₁`` (:func:`_half_cayley`, ``Q = exp(ω̂/2)``), and ``dexp⁻¹_ξᵀ`` is
    ``_se3_dexp_inv_T`` / ``_jinv_T`` of the compiled loops.  SE(2), SO(2): the matrix kernels
    and :func:`_solve_transposed`.
    """
    n, r = xi.shape
    for i in range(n):
        for k in range(r):
            mu[i, k] = N[i, k] * mass[k]
    if gid == GID_SE3:
        for i in range(n):
            r0, r1, r2, p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2], xi[i, 3], xi[i, 4], xi[i, 5]
            h0, h1, h2 = 0.5 * p0, 0.5 * p1, 0.5 * p2
            y0, y1, y2 = _half_cayley(h0, h1, h2, W[i, 0], W[i, 1], W[i, 2])
            c = cross3(D[i, 1, 0], D[i, 2, 0], D[i, 3, 0], y0, y1, y2)
            u0 = W[i, 3] + D[i, 1, 1] * c[0] + D[i, 2, 1] * c[1] + D[i, 3, 1] * c[2]
            u1 = W[i, 4] + D[i, 1, 2] * c[0] + D[i, 2, 2] * c[1] + D[i, 3, 2] * c[2]
            u2 = W[i, 5] + D[i, 1, 3] * c[0] + D[i, 2, 3] * c[1] + D[i, 3, 3] * c[2]
            y3, y4, y5 = _half_cayley(h0, h1, h2, u0, u1, u2)
            BW[i, 0], BW[i, 1], BW[i, 2], BW[i, 3], BW[i, 4], BW[i, 5] = y0, y1, y2, y3, y4, y5
            t2 = p0 * p0 + p1 * p1 + p2 * p2
            cq, dq, eq = _q_coeffs(t2)
            o = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, _cinv(t2), cq, dq, eq,
                                mu[i, 0], mu[i, 1], mu[i, 2], mu[i, 3], mu[i, 4], mu[i, 5])
            for k in range(6):
                Dmu[i, k] = o[k]
                R[i, k] = o[k] - dt * BW[i, k] - S[i, k]
        return
    if gid == GID_SO3:
        for i in range(n):
            p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2]
            y = _half_cayley(0.5 * p0, 0.5 * p1, 0.5 * p2, W[i, 0], W[i, 1], W[i, 2])
            o = _jinv_T(p0, p1, p2, _cinv(p0 * p0 + p1 * p1 + p2 * p2), mu[i, 0], mu[i, 1], mu[i, 2])
            for k in range(3):
                BW[i, k] = y[k]
                Dmu[i, k] = o[k]
                R[i, k] = o[k] - dt * y[k] - S[i, k]
        return
    for i in range(n):
        g_Ad(gid, D[i], A)
        _solve_transposed(A, W[i], BW[i], M)
        g_dexp_inv(gid, xi[i], A)
        for k in range(r):
            acc = 0.0
            for j in range(r):
                acc += A[j, k] * mu[i, j]
            Dmu[i, k] = acc
            R[i, k] = acc - dt * BW[i, k] - S[i, k]


@_jit
def momentum_update(gid: int, xi: np.ndarray, mu: np.ndarray, W: np.ndarray, BW: np.ndarray, dt: float,
                    out: np.ndarray) -> None:
    """The end-of-step momentum ``S_{k+1} = dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)`` per node into ``out``
    (all ``[n, r]``)."""
    n, r = xi.shape
    A = np.empty((r, r))
    v = np.empty(r)
    for i in range(n):
        if gid == GID_SE3:
            p0, p1, p2 = xi[i, 3], xi[i, 4], xi[i, 5]
            t2 = p0 * p0 + p1 * p1 + p2 * p2
            cq, dq, eq = _q_coeffs(t2)
            o = _se3_dexp_inv_T(-xi[i, 0], -xi[i, 1], -xi[i, 2], -p0, -p1, -p2, _cinv(t2), cq, dq, eq,
                                mu[i, 0], mu[i, 1], mu[i, 2], mu[i, 3], mu[i, 4], mu[i, 5])
            for k in range(6):
                out[i, k] = o[k] + dt * (W[i, k] - BW[i, k])
            continue
        if gid == GID_SO3:
            p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2]
            o3 = _jinv_T(-p0, -p1, -p2, _cinv(p0 * p0 + p1 * p1 + p2 * p2), mu[i, 0], mu[i, 1], mu[i, 2])
            for k in range(3):
                out[i, k] = o3[k] + dt * (W[i, k] - BW[i, k])
            continue
        for k in range(r):
            v[k] = -xi[i, k]
        g_dexp_inv(gid, v, A)
        for k in range(r):
            acc = 0.0
            for j in range(r):
                acc += A[j, k] * mu[i, j]
            out[i, k] = acc + dt * (W[i, k] - BW[i, k])


# ---------------------------------------------------------------------------- lattice
@_jit
def lattice_residual(P: tuple, G0s: tuple, Phi0: np.ndarray, Gs: tuple, Phi: np.ndarray, S: np.ndarray,
                     xi: np.ndarray, dt: float, radius: float, N: np.ndarray, W: np.ndarray, mu: np.ndarray,
                     BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray, D: np.ndarray, scr: tuple, A: np.ndarray,
                     M: np.ndarray) -> bool:
    """The stage residual on the lattice; False (nothing computed) when ξ is outside the
    domain of dexp⁻¹.

    ``G0s``/``Phi0``: the step's edges (one ``[ne_α, m, m]`` per axis) and frames ``[n or 1,
    m, m]``, read only; ``Gs``/``Phi``: work copies, left at the midpoint; ``S``, ``xi``
    ``[n, r]``; outputs ``N = ξ/Δt``, ``W``, ``mu``, ``BW``, ``Dmu``, ``R`` ``[n, r]`` and
    ``D = exp(ξ/2)`` ``[n, m, m]``; ``scr`` the drift's chunk scratch (as
    ``cartan.schemes._lattice_compiled._exp_drift`` makes it), ``A``, ``M`` as :func:`_nodes`.
    """
    gid = P[I_GID]
    if not _in_domain(gid, xi, radius):
        return False
    for a in range(len(Gs)):
        Gs[a][...] = G0s[a]
    Phi[...] = Phi0
    n, r = xi.shape
    empty = np.empty((0, r))
    _exp_drift_nd(P, Gs, Phi, xi, 0.5, D, empty, empty, scr)  # Φ ← Φ exp(ξ/2), D = exp(ξ/2)
    for i in range(n):
        for k in range(r):
            N[i, k] = xi[i, k] / dt
    _force_once(P, Gs, Phi, N, W, True)
    _nodes(gid, P[I_MASS], xi, N, D, W, S, dt, mu, BW, Dmu, R, A, M)
    return True


@_jit
def lattice_drift(P: tuple, Gs: tuple, Phi: np.ndarray, xi: np.ndarray, tau: float, D: np.ndarray,
                  scr: tuple) -> None:
    """The drift ``Φ ← Φ exp(τξ)`` of the edges ``Gs`` and frames ``Phi`` in place (``D`` work)."""
    empty = np.empty((0, xi.shape[1]))
    _exp_drift_nd(P, Gs, Phi, xi, tau, D, empty, empty, scr)


# ---------------------------------------------------------------------------- collocation
@_jit
def collocation_residual(P: tuple, Dc: tuple, X0: np.ndarray, Phi0: np.ndarray, X: np.ndarray, Phi: np.ndarray,
                         S: np.ndarray, xi: np.ndarray, dt: float, radius: float, N: np.ndarray, W: np.ndarray,
                         mu: np.ndarray, BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray, D: np.ndarray,
                         A: np.ndarray, M: np.ndarray) -> bool:
    """The stage residual of the collocation scheme (as :func:`lattice_residual`): ``X0`` ``[n, r]``
    and ``Phi0`` the step's strains and frames (read only), ``X``, ``Phi`` work copies left at
    the midpoint."""
    gid = P[I_GID]
    if not _in_domain(gid, xi, radius):
        return False
    X[...] = X0
    Phi[...] = Phi0
    _collocation_drift(P, Dc, X, Phi, xi, 0.5, True)  # X, Φ at Φ exp(ξ/2)
    n, r = xi.shape
    v = np.empty(r)
    for i in range(n):
        for k in range(r):
            N[i, k] = xi[i, k] / dt
            v[k] = 0.5 * xi[i, k]
        g_exp(gid, v, D[i])
    _collocation_force(P, Dc, X, Phi, N, W)
    _nodes(gid, P[I_MASS], xi, N, D, W, S, dt, mu, BW, Dmu, R, A, M)
    return True


# ---------------------------------------------------------------------------- Newton's linear solve, norms
@_jit
def _lu_solve(Lp: np.ndarray, Li: np.ndarray, Lx: np.ndarray, Ld: np.ndarray, Up: np.ndarray, Ui: np.ndarray,
              Ux: np.ndarray, Ud: np.ndarray, perm_r: np.ndarray, perm_c: np.ndarray, b: np.ndarray, x: np.ndarray,
              y: np.ndarray) -> None:
    """``x = A⁻¹b`` from SuperLU's factors ``Pr A Pc = L U``: the strictly lower and upper parts
    of L and U as CSC arrays with their diagonals ``Ld``, ``Ud``; ``Pr b`` placed at ``perm_r``,
    ``x = Pc z`` read at ``perm_c``.  One forward and one back substitution by columns, ``y``
    ``(n,)`` work."""
    n = b.shape[0]
    for i in range(n):
        y[perm_r[i]] = b[i]
    for j in range(n):
        yj = y[j] / Ld[j]
        y[j] = yj
        for p in range(Lp[j], Lp[j + 1]):
            y[Li[p]] -= Lx[p] * yj
    for j in range(n - 1, -1, -1):
        yj = y[j] / Ud[j]
        y[j] = yj
        for p in range(Up[j], Up[j + 1]):
            y[Ui[p]] -= Ux[p] * yj
    for i in range(n):
        x[i] = y[perm_c[i]]


class LUSolve:
    """The solve of a ``scipy.sparse.linalg.splu`` factorisation in compiled code (the same
    factors; the substitutions in another order than SuperLU's, so round-off apart the same
    solution).  ``solve(b)`` for ``b`` ``(n,)`` returns a new array, as ``SuperLU.solve``."""

    def __init__(self, lu: Any):
        import scipy.sparse as sp

        def parts(T: Any, k: int) -> tuple:
            T = sp.csc_matrix(T)
            off = sp.csc_matrix(sp.tril(T, -1) if k < 0 else sp.triu(T, 1))
            return (off.indptr.astype(np.int64), off.indices.astype(np.int64),
                    np.ascontiguousarray(off.data, dtype=np.float64),
                    np.ascontiguousarray(T.diagonal(), dtype=np.float64))

        self.shape = lu.shape
        self._args = (*parts(lu.L, -1), *parts(lu.U, 1), np.ascontiguousarray(lu.perm_r, np.int64),
                      np.ascontiguousarray(lu.perm_c, np.int64))
        self._work = np.empty(lu.shape[0])

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty(self.shape[0])
        _lu_solve(*self._args, np.ascontiguousarray(b, dtype=np.float64), x, self._work)
        return x


@_jit
def weighted_norm(w: np.ndarray, idx: np.ndarray, y: np.ndarray) -> float:
    """``sqrt(Σ_k w_k y[idx_k]²)`` for ``y`` flattened (the kinetic-energy norms of the Newton
    iteration over the unknowns ``idx``)."""
    acc = 0.0
    for k in range(idx.shape[0]):
        v = y[idx[k]]
        acc += w[k] * (v * v)
    return np.sqrt(acc)


# ---------------------------------------------------------------------------- Python glue
def _contiguous(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` reshaped to ``shape``, without a copy when it is a C-contiguous float64 array."""
    return np.ascontiguousarray(a, dtype=np.float64).reshape(shape)


class StageResidual:
    """The compiled stage residual of one scheme (work arrays allocated once).

    Use :func:`stage_residual` to get one (or None when the scheme has no compiled plan).
    :meth:`bind` takes the step's state; :meth:`__call__` evaluates ``R(ξ)`` and its pieces;
    :meth:`midpoint` gives the midpoint state (for the powers) and :meth:`advance` performs
    the end of the step.
    """

    def __init__(self, scheme: Any, kind: str, plan: Any):
        self.scheme = scheme
        self.kind = kind
        self.plan = plan
        group = scheme.group
        self.gid = int(plan[I_GID] if kind == "lattice" else plan[0][I_GID])
        self.radius = float(group.injectivity_radius)
        self.shape = (*scheme.grid.shape, group.dim)
        n, r, m = scheme.grid.size, group.dim, group.matrix_size
        self.n, self.r, self.m = n, r, m
        self.frame_key = "Phi" if scheme.track else "Phi_root"
        nf = n if scheme.track else 1
        self.Phi = np.empty((nf, m, m))
        self.D = np.empty((n, m, m))
        self.A = np.empty((r, r))
        self.M = np.empty((r, r + 1))
        if kind == "lattice":
            self.keys = tuple(scheme._key(a) for a in range(scheme.grid.d))
            nch = max((n + CHUNK - 1) // CHUNK, int(plan[I_ECH][plan[I_D]]))
            self.scr = _chunk_scratch(nch, r, m, 0)
            self.Gs: tuple | None = None  # allocated at the first bind (edge shapes)
        else:
            self.keys = ("X",)
            self.X = np.empty((n, r))
        self._base: tuple | None = None

    def accepts(self, state: Any) -> bool:
        """Whether ``state`` has the layout the kernels read (the scheme's configuration arrays)."""
        if set(state.arrays) != {*self.keys, self.frame_key} or np.shape(state.S) != self.shape:
            return False
        return self.kind == "lattice" or np.shape(state.arrays["X"]) == (self.n, 1, self.r)

    def bind(self, state: Any) -> None:
        """Take the step's configuration and momentum (read, never modified; not copied when
        they are C-contiguous float64 arrays)."""
        n, r, m = self.n, self.r, self.m
        Phi0 = _contiguous(state.arrays[self.frame_key], self.Phi.shape)
        S = _contiguous(state.S, (n, r))
        if self.kind == "lattice":
            G0s = tuple(_contiguous(state.arrays[k], (-1, m, m)) for k in self.keys)
            if self.Gs is None or any(g.shape != h.shape for g, h in zip(self.Gs, G0s, strict=True)):
                self.Gs = tuple(np.empty_like(g) for g in G0s)
            self._base = (G0s, Phi0, S)
        else:
            self._base = (_contiguous(state.arrays["X"], (n, r)), Phi0, S)

    def __call__(self, xi: np.ndarray, dt: float) -> dict[str, np.ndarray] | None:
        """``{"R", "W", "BW", "mu", "Dmu"}`` (new ``[*shape, r]`` arrays) at ξ ``[*shape, r]``
        for the bound state, or None when ξ is outside the domain of dexp⁻¹."""
        if self._base is None:
            raise RuntimeError("StageResidual.bind(state) must be called before evaluating")
        n, r = self.n, self.r
        x = _contiguous(xi, (n, r))
        out = {k: np.empty((n, r)) for k in ("N", "W", "mu", "BW", "Dmu", "R")}
        if self.kind == "lattice":
            G0s, Phi0, S = self._base
            ok = lattice_residual(self.plan, G0s, Phi0, self.Gs, self.Phi, S, x, float(dt), self.radius, out["N"],
                                  out["W"], out["mu"], out["BW"], out["Dmu"], out["R"], self.D, self.scr, self.A,
                                  self.M)
        else:
            X0, Phi0, S = self._base
            P, Dc = self.plan
            ok = collocation_residual(P, Dc, X0, Phi0, self.X, self.Phi, S, x, float(dt), self.radius, out["N"],
                                      out["W"], out["mu"], out["BW"], out["Dmu"], out["R"], self.D, self.A, self.M)
        if not ok:
            return None
        del out["N"]
        return {k: v.reshape(self.shape) for k, v in out.items()}

    def drifted(self, state: Any, xi: np.ndarray, tau: float) -> dict[str, np.ndarray]:
        """The configuration arrays of ``state`` drifted by ``Φ ← Φ exp(τξ)`` (the scheme's exact
        drift), as new arrays; ``state`` is not modified."""
        n, r, m = self.n, self.r, self.m
        x = _contiguous(xi, (n, r))
        Phi = np.array(state.arrays[self.frame_key], dtype=np.float64, order="C")
        Phi3 = Phi.reshape(self.Phi.shape)
        out = {self.frame_key: Phi}
        if self.kind == "lattice":
            Gs = tuple(np.array(state.arrays[k], dtype=np.float64, order="C") for k in self.keys)
            lattice_drift(self.plan, tuple(g.reshape(-1, m, m) for g in Gs), Phi3, x, float(tau), self.D, self.scr)
            out.update(zip(self.keys, Gs, strict=True))
        else:
            X = np.array(state.arrays["X"], dtype=np.float64, order="C")
            P, Dc = self.plan
            _collocation_drift(P, Dc, X.reshape(n, r), Phi3, x, float(tau), True)
            out["X"] = X
        return out

    def midpoint(self, state: Any, xi: np.ndarray) -> Any:
        """A copy of ``state`` at the midpoint configuration ``Φ exp(ξ/2)`` (for the powers)."""
        mid = state.copy()
        mid.arrays.update(self.drifted(state, xi, 0.5))
        return mid

    def advance(self, state: Any, xi: np.ndarray, res: dict[str, np.ndarray], dt: float) -> None:
        """End of the step: ``S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)`` from the pieces ``res`` of the
        converged residual, and ``Φ ← Φ exp(ξ)`` into new arrays."""
        n, r = self.n, self.r
        S_new = np.empty((n, r))
        momentum_update(self.gid, _contiguous(xi, (n, r)), _contiguous(res["mu"], (n, r)),
                        _contiguous(res["W"], (n, r)), _contiguous(res["BW"], (n, r)), float(dt), S_new)
        state.arrays.update(self.drifted(state, xi, 1.0))
        state.S = S_new.reshape(self.shape)


def stage_residual(scheme: Any) -> StageResidual | None:
    """The compiled stage residual of ``scheme``, or None: the numpy backend, a scheme other
    than ``lattice`` and ``collocation``, a problem without a compiled plan (the plan of the
    compiled step loops, :meth:`~cartan.schemes.base.Scheme.compiled_plan`), or a medium
    whose momentum is not the base ``m N``."""
    from ..medium import Medium
    from ..schemes.collocation import Collocation
    from ..schemes.lattice import Lattice

    if get_backend() != "numba":
        return None
    if type(scheme.medium).momentum is not Medium.momentum:
        return None
    if isinstance(scheme, Lattice):
        kind, module = "lattice", "_lattice_compiled"
    elif isinstance(scheme, Collocation) and scheme.grid.d == 1:
        kind, module = "collocation", "_collocation_compiled"
    else:
        return None
    plan = scheme.compiled_plan(module)
    if plan is None:
        return None
    return StageResidual(scheme, kind, plan)
